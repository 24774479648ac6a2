"""Networks and checkpoints shared by `aerobench train bc` and `aerobench train ppo`, and the `bc` / `ppo` policies.

One actor serves both algorithms, so a BC checkpoint initialises the PPO actor as is. The actor maps the normalized
inputs its `InputSpec` selects (`inputs.py`: task state fields by default, optionally proprio fields, what the policy
computes from them in its heading frame, the instruction and a short history; plus, in the image variant, features
of RGB-D cameras, `camera_input.py`) to a *normalized* flight (and arm) action and, last, the gripper: with the default `gripper: "binary"` a logit (> 0: close), because the gripper is
an open/close command (the expert only ever sends -1 or +1), so `act` sends -1 or +1; with `"continuous"` a
regressed value like the other dimensions. `act` unnormalizes with the checkpoint's statistics and clamps to [-1, 1].

A checkpoint folder holds (`CHECKPOINT_FILES`):

    config.json          format, algorithm (bc | ppo), model shape, platform, and the training config
    model.safetensors    the networks' weights (`actor.*`; PPO adds `critic.*` and `log_std`)
    normalization.json   state and action mean / std the actor was trained with
    starts.json          the episode starts of the training data (`provenance`), for the held-out check
    train_state.pt       optimizer state, step counters and RNG states, for resuming (not needed to act)

Image inputs: per camera, RGB and depth (2 cm levels) reduced to `image_size` pixels (`camera_input`). A policy
reads a tier of inputs (`aerobench.tiers`): `privileged` if any task state field, else `vision`; a blind control
(`model["blind"]`) is the same network with its cameras blanked, at training and at acting.
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import torch
from torch import nn

from .. import tiers
from .camera_input import IMAGE_CHANNELS
from .inputs import InputSpec
from .instruction import BUCKETS
from .observer import ActorObserver
from .provenance import TrainingStarts, read_starts, write_starts
from .registry import register_policy

CHECKPOINT_FORMAT = "aerobench-learned-v2"  # v2: input spec and binary gripper head (v1 read absolute positions)
CONFIG_FILE = "config.json"
WEIGHTS_FILE = "model.safetensors"
NORMALIZATION_FILE = "normalization.json"
TRAIN_STATE_FILE = "train_state.pt"
CHECKPOINT_FILES = (CONFIG_FILE, WEIGHTS_FILE, NORMALIZATION_FILE)
CHECKPOINT_SUBDIR = "checkpoint"  # a training run's OUT/checkpoint
ALGORITHMS = ("bc", "ppo")
CAMERAS = ("drone_front", "drone_hand", "drone_own")
CAMERA_ENCODERS = ("shared", "separate")  # one CNN for every camera, or one per camera
ENCODER_HEADS = ("flatten", "keypoints")  # a camera CNN's maps to features (`CameraEncoder`)
STD_FLOOR = 1e-2  # a constant dimension (e.g. an always-open gripper command) must not divide by ~0
UINT8_MAX = 255.0
GRIPPER_MODES = ("binary", "continuous")


# ── inputs ────────────────────────────────────────────────────────────────────────────────────────────────────────


def is_close(gripper: torch.Tensor) -> torch.Tensor:
    """The gripper command as a close label (1: close): the env's u_g < 0 closes the fingers."""
    return (gripper < 0).float()


def env_action(actor_out: torch.Tensor, normalizer: Normalizer, gripper: str, close: torch.Tensor | None = None,
               close_threshold: float = 0.5) -> torch.Tensor:
    """The env action `(N, A)` in [-1, 1] from the actor's output: continuous dimensions unnormalized; a binary
    gripper sent as -1 (close) or +1 (open), from `close` (0/1, e.g. sampled by PPO) or else closed where the
    predicted probability of "close" exceeds `close_threshold` (0.5: the logit's sign)."""
    action = normalizer.unaction(actor_out).clamp(-1.0, 1.0)
    if gripper == "binary":
        logit_threshold = math.log(close_threshold / (1.0 - close_threshold))  # 0.0 at 0.5: the sign, exactly
        close = (actor_out[:, -1] > logit_threshold).float() if close is None else close
        action = torch.cat([action[:, :-1], (1.0 - 2.0 * close)[:, None]], dim=-1)
    return action


# ── networks ──────────────────────────────────────────────────────────────────────────────────────────────────────


def mlp(sizes: list[int], out_gain: float = 1.0) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i in range(len(sizes) - 1):
        linear = nn.Linear(sizes[i], sizes[i + 1])
        last = i == len(sizes) - 2
        nn.init.orthogonal_(linear.weight, out_gain if last else 2**0.5)  # CleanRL's layer_init
        nn.init.zeros_(linear.bias)
        layers += [linear] if last else [linear, nn.Tanh()]
    return nn.Sequential(*layers)


class SpatialSoftmax(nn.Module):
    """Each feature map as the expected image position of its activation (Levine et al. 2016; robomimic's and
    Diffusion Policy's image head): `(N, C, h, w)` -> `(N, 2C)` keypoints in [-1, 1], where a thing is in the image."""

    def forward(self, features: torch.Tensor, spread_out: list | None = None) -> torch.Tensor:
        """`spread_out`, if given, receives how concentrated each map's attention is `(N, C)`: its RMS distance from
        the keypoint (image half-widths), small where the map found its thing, about 0.9 for a flat map."""
        n, c, h, w = features.shape
        attention = torch.softmax(features.flatten(2), -1).view(n, c, h, w)
        ys = torch.linspace(-1.0, 1.0, h, device=features.device)
        xs = torch.linspace(-1.0, 1.0, w, device=features.device)
        along_x, along_y = attention.sum(2), attention.sum(3)
        x, y = (along_x * xs).sum(-1), (along_y * ys).sum(-1)
        if spread_out is not None:
            variance = (along_x * xs**2).sum(-1) - x**2 + (along_y * ys**2).sum(-1) - y**2
            spread_out.append(variance.clamp_min(0.0).sqrt())
        return torch.cat([x, y], -1)


class CameraEncoder(nn.Module):
    """A small CNN: stride-2 3x3 convolutions, then to `feature_dim` features through a linear layer over the flattened
    maps (`head="flatten"`), or over the maps' keypoints (`head="keypoints"`: a 1x1 convolution to `keypoints` maps
    of the last convolution's resolution, `SpatialSoftmax`)."""

    def __init__(self, image_size: int, channels: tuple[int, ...], feature_dim: int, head: str = "flatten",
                 keypoints: int = 32):
        super().__init__()
        layers, c_in = [], IMAGE_CHANNELS
        for c_out in channels:
            layers += [nn.Conv2d(c_in, c_out, 3, stride=2, padding=1), nn.ReLU()]
            c_in = c_out
        self.conv = nn.Sequential(*layers)
        side = image_size // 2 ** len(channels)
        if head == "keypoints":
            self.head = nn.Sequential(nn.Conv2d(c_in, keypoints, 1), SpatialSoftmax(),
                                      nn.Linear(2 * keypoints, feature_dim), nn.ReLU())
        else:
            self.head = nn.Sequential(nn.Flatten(), nn.Linear(c_in * side * side, feature_dim), nn.ReLU())

    def forward(self, images: torch.Tensor, film: torch.Tensor | None = None,
                keypoints_out: list | None = None, spread_out: list | None = None) -> torch.Tensor:
        """`film` `(N, 2 * sum(channels))`: a scale and a shift per channel of each convolution (FiLM, Perez et al.
        2018), applied before its ReLU, so the instruction decides which things the maps respond to.
        `keypoints_out` (keypoint head only) receives the keypoints `(N, 2K)` (x of each map, then y of each), and
        `spread_out` (with it) their attention's spread `(N, K)` (`SpatialSoftmax`)."""
        if film is None:
            x = self.conv(images)
        else:
            x, start = images, 0
            for layer in self.conv:
                x = layer(x)
                if isinstance(layer, nn.Conv2d):
                    c = layer.out_channels
                    gamma, beta = film[:, start:start + c], film[:, start + c:start + 2 * c]
                    x = x * (1.0 + gamma[:, :, None, None]) + beta[:, :, None, None]
                    start += 2 * c
        if keypoints_out is None:
            return self.head(x)
        if not isinstance(self.head[1], SpatialSoftmax):
            raise ValueError("keypoints need the keypoint head (--encoder-head keypoints)")
        keypoints = self.head[1](self.head[0](x), spread_out)  # the head is maps -> keypoints -> features
        keypoints_out.append(keypoints)
        return self.head[3](self.head[2](keypoints))


class Trunk(nn.Module):
    """Normalized state (+ camera features, + the instruction's embedding) -> an MLP's output; the actor and the
    critic are each one of these. Inputs: "state" `(N, S)`, one float `(N, 4, s, s)` image per camera (absent for a
    blind control: its cameras read zeros) and "instruction" word ids `(N, W)` (`instruction.py`)."""

    def __init__(self, model: dict, out_dim: int, out_gain: float):
        super().__init__()
        self.cameras = tuple(model["cameras"])
        self.blind, self.image_size = bool(model.get("blind", False)), model["image_size"]
        self.separate = model.get("camera_encoder", "shared") == "separate"
        in_dim = model["state_dim"]
        if self.cameras:
            def encoder() -> CameraEncoder:
                return CameraEncoder(model["image_size"], tuple(model["cnn_channels"]), model["feature_dim"],
                                     model.get("encoder_head", "flatten"))

            if self.separate:
                self.encoders = nn.ModuleDict({c: encoder() for c in self.cameras})
            else:
                self.encoder = encoder()
            in_dim += model["feature_dim"] * len(self.cameras)
        self.instruction_dim = int(model.get("instruction_dim", 0))
        if self.instruction_dim:
            self.words = nn.EmbeddingBag(BUCKETS, self.instruction_dim, mode="mean", padding_idx=0)
            in_dim += self.instruction_dim
        self.film = None
        if model.get("film", False):  # the instruction scales and shifts the camera CNN's channels (RT-1's FiLM)
            self.film = nn.Linear(self.instruction_dim, 2 * sum(model["cnn_channels"]))
            nn.init.zeros_(self.film.weight)  # starts as the unconditioned CNN
            nn.init.zeros_(self.film.bias)
        self.mlp = mlp([in_dim, *model["hidden"], out_dim], out_gain)
        aux_dim = int(model.get("aux_dim", 0))
        # Training-time targets predicted from the same features (`aerobench train bc --aux-fields`); never an input.
        self.aux = nn.Linear(in_dim, aux_dim) if aux_dim else None

    def forward(self, inputs: dict[str, torch.Tensor]) -> torch.Tensor:
        return self.mlp(self.embed(inputs))

    def embed(self, inputs: dict[str, torch.Tensor], keypoints: dict[str, torch.Tensor] | None = None,
              spreads: dict[str, torch.Tensor] | None = None) -> torch.Tensor:
        """The features the MLP reads: the state, each camera's features and the instruction's embedding.
        `keypoints`, if given, receives each camera's encoder keypoints `(N, 2K)` (keypoint head only), and `spreads`
        (with it) how concentrated each keypoint's attention is `(N, K)`."""
        parts = [inputs["state"]]
        n = inputs["state"].shape[0]
        words = self.words(inputs["instruction"]) if self.instruction_dim else None
        film = self.film(words) if self.film is not None else None
        if self.cameras:
            shape = (n, IMAGE_CHANNELS, self.image_size, self.image_size)
            images = [inputs[c] if not self.blind else inputs["state"].new_zeros(shape) for c in self.cameras]
            found: list[torch.Tensor] | None = None if keypoints is None else []
            spread: list[torch.Tensor] | None = None if keypoints is None or spreads is None else []
            if self.separate:
                parts += [self.encoders[c](x, film, found, spread) for c, x in zip(self.cameras, images)]
            else:  # one encoder pass for all cameras; each camera's features keep their slot
                batch_film = None if film is None else film.repeat(len(self.cameras), 1)
                parts += list(self.encoder(torch.cat(images, 0), batch_film, found, spread).split(n, 0))
            if keypoints is not None:
                keypoints.update(zip(self.cameras, found if self.separate else found[0].split(n, 0)))
            if spread is not None:
                spreads.update(zip(self.cameras, spread if self.separate else spread[0].split(n, 0)))
        if words is not None:
            parts.append(words)
        return torch.cat(parts, -1)


def make_actor(model: dict) -> Trunk:
    return Trunk(model, model["action_dim"], out_gain=0.01)  # small initial actions (CleanRL's actor init)


def make_critic(model: dict) -> Trunk:
    return Trunk({**model, "aux_dim": 0}, 1, out_gain=1.0)  # auxiliary targets are the actor's


def model_spec(state_dim: int, action_dim: int, hidden: tuple[int, ...], inputs: InputSpec,
               cameras: tuple[str, ...] = (), image_size: int = 64, cnn_channels: tuple[int, ...] = (16, 32, 32),
               feature_dim: int = 64, gripper: str = "binary", blind: bool = False, camera_encoder: str = "shared",
               instruction_dim: int = 0, encoder_head: str = "flatten", aux_dim: int = 0, film: bool = False) -> dict:
    """The JSON description of the networks a checkpoint holds (enough to rebuild them). `state_dim` counts the
    selected input values of all history frames; `instruction_dim` > 0 embeds the instruction (`inputs.instruction`);
    `aux_dim` > 0 adds a linear head for auxiliary training targets (not read when acting); `film` conditions the
    camera CNN on the instruction's embedding."""
    unknown = [c for c in cameras if c not in CAMERAS]
    if unknown:
        raise ValueError(f"unknown cameras {unknown}; valid: {', '.join(CAMERAS)}")
    if cameras and image_size % 2 ** len(cnn_channels):
        raise ValueError(f"image_size {image_size} must be divisible by {2 ** len(cnn_channels)}")
    if gripper not in GRIPPER_MODES:
        raise ValueError(f"unknown gripper head {gripper!r}; valid: {', '.join(GRIPPER_MODES)}")
    if camera_encoder not in CAMERA_ENCODERS:
        raise ValueError(f"--camera-encoder must be one of {', '.join(CAMERA_ENCODERS)}, got {camera_encoder!r}")
    if encoder_head not in ENCODER_HEADS:
        raise ValueError(f"--encoder-head must be one of {', '.join(ENCODER_HEADS)}, got {encoder_head!r}")
    if blind and not cameras:
        raise ValueError("a blind control blanks the cameras of a camera policy: give it cameras")
    if inputs.instruction != (instruction_dim > 0):
        raise ValueError("the instruction is read with an embedding: instruction_dim > 0 exactly when inputs read it")
    if film and not (cameras and instruction_dim):
        raise ValueError("--film conditions the camera CNN on the instruction: it needs --images and the instruction")
    return {"state_dim": state_dim, "action_dim": action_dim, "hidden": list(hidden), "cameras": list(cameras),
            "image_size": image_size, "cnn_channels": list(cnn_channels), "feature_dim": feature_dim,
            "inputs": inputs.as_dict(), "gripper": gripper, "blind": blind, "camera_encoder": camera_encoder,
            "instruction_dim": instruction_dim, "encoder_head": encoder_head, "aux_dim": aux_dim,
            "film": film}


def model_features(model: dict) -> list[str]:
    """The LeRobot feature keys a checkpoint's model reads (a blind control's cameras are not read)."""
    cameras = [] if model.get("blind") else model["cameras"]
    return InputSpec.from_dict(model["inputs"]).features() + [f"{prefix}{c}" for c in cameras
                                                              for prefix in (tiers.IMAGES, tiers.DEPTH)]


def model_tier(model: dict) -> str:
    """The input tier (`aerobench.tiers`) of a checkpoint's model."""
    return tiers.tier_of(model_features(model))


class Normalizer(nn.Module):
    """State and action mean / std (buffers, so they move with the model and never train)."""

    def __init__(self, stats: dict):
        super().__init__()
        for key in ("state_mean", "state_std", "action_mean", "action_std"):
            self.register_buffer(key, torch.tensor(stats[key], dtype=torch.float32))

    def state(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.state_mean) / self.state_std

    def action(self, a: torch.Tensor) -> torch.Tensor:
        return (a - self.action_mean) / self.action_std

    def unaction(self, a: torch.Tensor) -> torch.Tensor:
        return a * self.action_std + self.action_mean

    def as_dict(self) -> dict:
        return {k: getattr(self, k).tolist() for k in ("state_mean", "state_std", "action_mean", "action_std")}


def normalization_stats(states: torch.Tensor, actions: torch.Tensor, gripper: str = "binary") -> dict:
    """Mean / std (floored at `STD_FLOOR`) of `(T, S)` states and `(T, A)` actions; a binary gripper's logit is not
    normalized (mean 0, std 1)."""
    action_mean, action_std = actions.mean(0), actions.std(0, unbiased=False).clamp_min(STD_FLOOR)
    if gripper == "binary":
        action_mean[-1], action_std[-1] = 0.0, 1.0
    return {
        "state_mean": states.mean(0).tolist(), "state_std": states.std(0, unbiased=False).clamp_min(STD_FLOOR).tolist(),
        "action_mean": action_mean.tolist(), "action_std": action_std.tolist(),
    }


def identity_stats(state_dim: int, action_dim: int) -> dict:
    return {"state_mean": [0.0] * state_dim, "state_std": [1.0] * state_dim,
            "action_mean": [0.0] * action_dim, "action_std": [1.0] * action_dim}


# ── checkpoint folders ────────────────────────────────────────────────────────────────────────────────────────────


def resolve_checkpoint(checkpoint: str | Path | None, policy: str = "bc") -> Path:
    """The checkpoint folder: given it, or a training run's OUT (its `checkpoint/`). One-line errors otherwise."""
    need = ", ".join(CHECKPOINT_FILES)
    if not checkpoint:
        raise ValueError(f"--policy {policy} needs --checkpoint DIR (an `aerobench train {policy}` output folder or "
                         f"its checkpoint/ holding {need})")
    path = Path(checkpoint).expanduser()
    for candidate in (path, path / CHECKPOINT_SUBDIR):
        if all((candidate / f).is_file() for f in CHECKPOINT_FILES):
            return candidate
    raise ValueError(f"no aerobench bc/ppo checkpoint at {path}: the folder (or its {CHECKPOINT_SUBDIR}/) must hold "
                     f"{need}, written by `aerobench train bc|ppo --out DIR`")


def read_config(path: Path) -> dict:
    try:
        config = json.loads((path / CONFIG_FILE).read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path / CONFIG_FILE} is not valid JSON ({e}); re-run the training to rewrite it") from None
    if config.get("format") == "aerobench-learned-v1":
        raise ValueError(f"{path} is a checkpoint of an older aerobench (absolute-position inputs, regressed gripper); "
                         f"retrain it with `aerobench train bc|ppo` on a re-exported dataset")
    if config.get("format") != CHECKPOINT_FORMAT or config.get("algorithm") not in ALGORITHMS:
        raise ValueError(f"{path / CONFIG_FILE} is not an aerobench bc/ppo checkpoint config "
                         f"(format {CHECKPOINT_FORMAT!r}, algorithm one of {', '.join(ALGORITHMS)})")
    return config


def save_checkpoint(folder: Path, config: dict, weights: dict[str, torch.Tensor], normalization: dict,
                    train_state: dict | None = None, starts: TrainingStarts | None = None) -> Path:
    """Write a complete checkpoint into `folder/checkpoint`, atomically: a crash leaves the old one or the new one."""
    from safetensors.torch import save_file

    folder.mkdir(parents=True, exist_ok=True)
    final, tmp, old = folder / CHECKPOINT_SUBDIR, folder / ".checkpoint-tmp", folder / ".checkpoint-old"
    if tmp.exists():
        _rmtree(tmp)
    tmp.mkdir()
    (tmp / CONFIG_FILE).write_text(json.dumps({"format": CHECKPOINT_FORMAT, **config}, indent=2, sort_keys=True))
    save_file({k: v.detach().cpu().contiguous() for k, v in weights.items()}, str(tmp / WEIGHTS_FILE))
    (tmp / NORMALIZATION_FILE).write_text(json.dumps(normalization, indent=2))
    if train_state is not None:
        torch.save(train_state, tmp / TRAIN_STATE_FILE)
    if starts is not None:
        write_starts(tmp, starts)
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    if old.exists():
        _rmtree(old)
    return final


def recover_checkpoint(folder: Path) -> Path | None:
    """The run's last complete checkpoint (repairing a crash between the two renames of `save_checkpoint`)."""
    final, old = folder / CHECKPOINT_SUBDIR, folder / ".checkpoint-old"
    if not final.exists() and old.exists():
        old.rename(final)
    return final if final.exists() else None


def _rmtree(path: Path) -> None:
    import shutil

    shutil.rmtree(path)


def load_weights(path: Path) -> dict[str, torch.Tensor]:
    from safetensors.torch import load_file

    return load_file(str(path / WEIGHTS_FILE))


def load_actor(path: Path) -> tuple[dict, Trunk, Normalizer]:
    """(config, actor, normalizer) of a checkpoint folder; the actor is in eval mode on the CPU."""
    config = read_config(path)
    actor = make_actor(config["model"])
    weights = load_weights(path)
    actor_weights = {k.removeprefix("actor."): v for k, v in weights.items() if k.startswith("actor.")}
    try:
        actor.load_state_dict(actor_weights)
    except RuntimeError as e:
        raise ValueError(f"{path / WEIGHTS_FILE} does not match the model in {path / CONFIG_FILE}: "
                         f"{str(e).splitlines()[0]}") from None
    normalizer = Normalizer(json.loads((path / NORMALIZATION_FILE).read_text()))
    return config, actor.eval(), normalizer


@functools.lru_cache(maxsize=4)
def _cached_actor(path: Path, mtime_ns: int, device: str = "cpu") -> tuple[dict, Trunk, Normalizer]:
    """The runner builds a policy per batch: load once per process, checkpoint version and device (the env's, so a
    control step on physx_cuda never leaves the GPU)."""
    config, actor, normalizer = load_actor(path)
    return config, actor.to(device), normalizer.to(device)


# ── the policies ──────────────────────────────────────────────────────────────────────────────────────────────────


class LearnedPolicy:
    """The deterministic actor (the Gaussian's mean and the gripper's more likely command for PPO) of a `bc` or `ppo`
    checkpoint, on a batch of envs."""

    algorithm = "bc"

    def __init__(self, env, checkpoint: str | None = None, **_):
        self.name = self.algorithm
        path, _ = self.checked_config(checkpoint)
        self.device = env.device
        config, self.actor, self.normalizer = _cached_actor(path, (path / WEIGHTS_FILE).stat().st_mtime_ns,
                                                            str(self.device))
        model = config["model"]
        self.gripper = model["gripper"]
        # the release decision's threshold on P(close) (checkpoint config `model.close_threshold`; 0.5 by default)
        self.close_threshold = float(model.get("close_threshold", 0.5))
        if not 0.0 < self.close_threshold < 1.0:
            raise ValueError(f"{path / CONFIG_FILE}: model.close_threshold must be between 0 and 1, "
                             f"got {self.close_threshold}")
        self.observer = ActorObserver(model, self.device)
        self.path, self.state_dim = path, model["state_dim"]
        self.env = env
        self.config = config
        if model["action_dim"] != env.platform.action_dim:
            raise ValueError(f"checkpoint {path} acts with {model['action_dim']} values; the {env.platform.name} "
                             f"platform takes {env.platform.action_dim} (train on a dataset of the same platform)")

    @classmethod
    def checked_config(cls, checkpoint: str | None) -> tuple[Path, dict]:
        path = resolve_checkpoint(checkpoint, cls.algorithm)
        config = read_config(path)
        if config["algorithm"] != cls.algorithm:
            raise ValueError(f"checkpoint {path} holds a {config['algorithm']} policy; use --policy {config['algorithm']}")
        return path, config

    @classmethod
    def needs_images(cls, checkpoint: str | None) -> bool:
        """Whether the actor reads the cameras (a blind control does not); also the early check of the checkpoint
        (before any env is built)."""
        model = cls.checked_config(checkpoint)[1]["model"]
        return bool(model["cameras"]) and not model.get("blind", False)

    @classmethod
    def input_tier(cls, checkpoint: str | None) -> str:
        """The checkpoint's input tier (`aerobench.tiers`), from what its model reads."""
        return model_tier(cls.checked_config(checkpoint)[1]["model"])

    @classmethod
    def input_features(cls, checkpoint: str | None) -> list[str]:
        return model_features(cls.checked_config(checkpoint)[1]["model"])

    @classmethod
    def training_starts(cls, checkpoint: str) -> TrainingStarts:
        """The episode starts the checkpoint trained on (its `starts.json`)."""
        return read_starts(resolve_checkpoint(checkpoint, cls.algorithm))

    def reset(self, env_idx: torch.Tensor) -> None:
        """Episodes restart in `env_idx`: their history frames (and first states, instruction) are renewed."""
        self.observer.reset(env_idx)

    def observe(self, obs) -> dict[str, torch.Tensor]:
        """The actor's (normalized) inputs for the current observation; advances the history."""
        raw = self.observer.observe(self.env, obs)
        if raw["state"].shape[-1] != self.state_dim:
            raise ValueError(f"checkpoint {self.path} reads {self.state_dim} input values; the env gives "
                             f"{raw['state'].shape[-1]} (train on the same platform)")
        return {**raw, "state": self.normalizer.state(raw["state"])}

    @torch.no_grad()
    def act(self, obs) -> torch.Tensor:
        action = env_action(self.actor(self.observe(obs)), self.normalizer, self.gripper,
                            close_threshold=self.close_threshold)
        return self.observer.to_env(action, obs)


@register_policy("bc")
class BCPolicy(LearnedPolicy):
    """Behaviour cloning from `aerobench train bc`."""

    algorithm = "bc"


@register_policy("ppo")
class PPOPolicy(LearnedPolicy):
    """PPO's actor mean from `aerobench train ppo`."""

    algorithm = "ppo"
