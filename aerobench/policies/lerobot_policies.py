"""LeRobot policies (ACT, Diffusion Policy, pi0, pi0.5) from a checkpoint folder, behind the batched interface.

`--policy pi0` / `--policy pi05` also take checkpoints of the tiny variants (`pi0_tiny`, `pi05_tiny`: pi_tiny/).

The checkpoint's own processors normalize inputs and unnormalize actions; `select_action` serves action chunks
from the policy's queue. Observations are mapped to the checkpoint's input features by name, the same keys the
dataset export writes: `observation.state`, `observation.images.<camera>` (RGB in [0, 1], CHW) and
`observation.depth.<camera>` (the export's packed 16-bit millimetre image), plus the language `task`.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import torch

from .. import tiers
from ..depth import pack_depth
from ..envs.observations import task_state_in_layout
from .provenance import STARTS_FILE, TrainingStarts, dataset_starts, read_starts, recorded_path
from .registry import register_policy

REQUIRED_FILES = ("config.json", "model.safetensors")
PROCESSOR_FILES = ("policy_preprocessor.json", "policy_postprocessor.json")
# aerobench policy name -> the LeRobot config types its checkpoints may hold (the tiny pi variants: pi_tiny/)
LEROBOT_TYPES = {"act": ("act",), "diffusion": ("diffusion",), "pi0": ("pi0", "pi0_tiny"), "pi05": ("pi05", "pi05_tiny")}
READS_LANGUAGE = ("pi0", "pi05")  # the VLAs tokenize the instruction; ACT and Diffusion Policy do not read it


def resolve_checkpoint(checkpoint: str | None, policy: str) -> Path:
    """The `pretrained_model` folder of a LeRobot checkpoint: given it, a `checkpoints/<step>` folder, or a
    `lerobot-train` output folder (its `checkpoints/last`). Missing pieces are one-line errors."""
    if not checkpoint:
        raise ValueError(f"--policy {policy} needs --checkpoint DIR (a lerobot-train output folder or its "
                         f"checkpoints/<step>/pretrained_model holding {', '.join(REQUIRED_FILES + PROCESSOR_FILES)})")
    path = Path(checkpoint).expanduser()
    for candidate in (path, path / "pretrained_model", path / "checkpoints" / "last" / "pretrained_model"):
        if all((candidate / f).is_file() for f in REQUIRED_FILES):
            missing = [f for f in PROCESSOR_FILES if not (candidate / f).is_file()]
            if missing:
                raise ValueError(f"checkpoint {candidate} lacks {', '.join(missing)} (saved by lerobot-train with the "
                                 f"policy's processors); re-save it with LeRobot >= 0.4")
            return candidate
    raise ValueError(f"no LeRobot checkpoint at {path}: a checkpoint folder holds {', '.join(REQUIRED_FILES + PROCESSOR_FILES)} "
                     f"(lerobot-train writes them to OUTPUT/checkpoints/<step>/pretrained_model)")


def _load_config(path: Path, policy: str):
    import lerobot.policies  # noqa: F401  (importing it registers the policy config types)
    from lerobot.configs.policies import PreTrainedConfig

    from . import pi_tiny  # noqa: F401  (registers pi0_tiny and pi05_tiny)

    config = PreTrainedConfig.from_pretrained(path, local_files_only=True)
    if config.type not in LEROBOT_TYPES[policy]:
        name = next((k for k, types in LEROBOT_TYPES.items() if config.type in types), config.type)
        raise ValueError(f"checkpoint {path} holds a {config.type!r} policy, not {policy!r}; use --policy {name}")
    return config


def _tokenizer_name(path: Path) -> str | None:
    """The tokenizer a checkpoint's preprocessor loads (pi0 / pi0.5), or None."""
    steps = json.loads((path / PROCESSOR_FILES[0]).read_text()).get("steps", [])
    return next((s.get("config", {}).get("tokenizer_name") for s in steps if s.get("registry_name") == "tokenizer_processor"), None)


def _make_processors(config, path: Path, device: str):
    """The checkpoint's processors; a tokenizer that cannot load offline is a one-line error saying what to do."""
    from lerobot.policies.factory import make_pre_post_processors

    try:
        return make_pre_post_processors(
            config, pretrained_path=str(path), preprocessor_overrides={"device_processor": {"device": device}}
        )
    except (OSError, ValueError) as e:
        name = _tokenizer_name(path)
        if not name or Path(name).is_dir():
            raise
        raise ValueError(f"checkpoint {path} tokenizes with {name!r}, which is not a local folder and cannot load "
                         f"offline: put the tokenizer in a folder (for pi0/pi0.5 the PaliGemma tokenizer, `hf download "
                         f"google/paligemma-3b-pt-224 --include 'tokenizer*' --local-dir DIR`) and set \"tokenizer_name\" "
                         f"in {path / PROCESSOR_FILES[0]} to DIR, or start from `aerobench pi-init`") from e


@functools.lru_cache(maxsize=2)
def load_policy(path: Path, kind: str):
    """Config, model and processors of a checkpoint, loaded once per process (the runner builds a policy per batch)."""
    from lerobot.policies.factory import get_policy_class

    config = _load_config(path, kind)
    device = "cuda" if torch.cuda.is_available() else "cpu"
    config.device = device
    preprocess, postprocess = _make_processors(config, path, device)  # before the model: a bad tokenizer fails fast
    model = get_policy_class(config.type).from_pretrained(path, config=config, local_files_only=True)
    model.to(device).eval()
    return config, model, preprocess, postprocess


def lerobot_batch(env, obs, inputs: dict) -> dict:
    """LeRobot input features `inputs` (a checkpoint's `input_features`) from an aerobench observation `(N, ...)`,
    plus `task` (the instructions) and `observation.state`; `env` is the unwrapped aerobench env. Local policies and
    the PolicyServer client (`policies.remote`) build their inputs here."""
    n = env.num_envs
    # observation.state is always passed: LeRobot's ACT reads its device even when it is not an input feature
    out: dict = {"task": [env.get_instruction(i) for i in range(n)], "observation.state": obs["agent"]["state"].float()}
    for key in inputs:
        if key == "observation.state":
            out[key] = obs["agent"]["state"].float()
        elif key == "observation.environment_state":  # the privileged task state (envs.observations), in the
            # layout the checkpoint's dataset had (an older one lacks fields added since)
            width = inputs[key].shape[0]
            out[key] = task_state_in_layout(env.task_state(), env.platform.arm is not None, width)
        elif key.startswith("observation.images."):
            rgb = obs["sensor_data"][key.removeprefix("observation.images.")]["rgb"]
            out[key] = rgb.permute(0, 3, 1, 2).float() / 255.0
        elif key.startswith("observation.depth."):
            depth = obs["sensor_data"][key.removeprefix("observation.depth.")]["depth"][..., 0]
            out[key] = pack_depth(depth).permute(0, 3, 1, 2).float() / 255.0  # on the env's device
        else:
            raise ValueError(f"checkpoint input feature {key!r} is not an aerobench observation")
    return out


class LeRobotPolicy:
    """A LeRobot `PreTrainedPolicy` and its processors, driving a batch of aerobench envs."""

    kind = "act"

    def __init__(self, env, checkpoint: str | None = None, **_):
        self.name = self.kind
        path = resolve_checkpoint(checkpoint, self.kind)
        self.env = env
        config, self.model, self.preprocess, self.postprocess = load_policy(path, self.kind)
        self.device = torch.device(config.device)
        self.inputs = dict(config.input_features)
        action_dim = config.output_features["action"].shape[0]
        if action_dim != env.platform.action_dim:
            raise ValueError(f"checkpoint {path} acts with {action_dim} values; the {env.platform.name} platform takes "
                             f"{env.platform.action_dim} (train on a dataset of the same platform)")

    @classmethod
    def needs_images(cls, checkpoint: str | None) -> bool:
        config = _load_config(resolve_checkpoint(checkpoint, cls.kind), cls.kind)
        return any(k.startswith(("observation.images.", "observation.depth.")) for k in config.input_features)

    @classmethod
    def input_features(cls, checkpoint: str | None) -> list[str]:
        """The feature keys the checkpoint's model reads (`aerobench.tiers`): its input features, and the instruction
        for the VLAs."""
        config = _load_config(resolve_checkpoint(checkpoint, cls.kind), cls.kind)
        return list(config.input_features) + ([tiers.INSTRUCTION] if cls.kind in READS_LANGUAGE else [])

    @classmethod
    def input_tier(cls, checkpoint: str | None) -> str:
        return tiers.tier_of(cls.input_features(checkpoint))

    @classmethod
    def training_starts(cls, checkpoint: str) -> TrainingStarts:
        """The starts the checkpoint carries (`starts.json`, written when a checkpoint is copied away from its data,
        e.g. committed under `leaderboards/checkpoints/`), else those of the dataset its `train_config.json` names
        (lerobot-train writes OUTPUT/checkpoints/<step>/pretrained_model; a relative dataset root is relative to
        where it ran), recorded under the root as it was given."""
        folder = resolve_checkpoint(checkpoint, cls.kind)
        if (folder / STARTS_FILE).is_file():
            return read_starts(folder)
        train_config = folder / "train_config.json"
        if not train_config.is_file():
            return TrainingStarts(untraced=[str(folder)])
        recorded = json.loads(train_config.read_text())
        root = recorded.get("dataset", {}).get("root")
        dataset = recorded_path(root, folder.parents[2], recorded.get("output_dir"))
        return dataset_starts(dataset, source=root) if dataset else TrainingStarts(untraced=[str(folder)])

    # LeRobot keeps one action queue (and observation history) for the whole batch: resetting one env clears every
    # env's, so a runner that resets envs alone (`RolloutSpec.episodes_per_scene`) on a batch refuses this policy
    resets_whole_batch = True

    def reset(self, env_idx: torch.Tensor) -> None:
        self.model.reset()  # clears the action-chunk queue (the runner starts a batch's episodes together)

    def batch(self, obs) -> dict:
        """The checkpoint's input features from an aerobench observation `(N, ...)` (`lerobot_batch`)."""
        return lerobot_batch(self.env, obs, self.inputs)

    @torch.no_grad()
    def act(self, obs) -> torch.Tensor:
        batch = self.preprocess(self.batch(obs))
        action = self.postprocess(self.model.select_action(batch))
        return action.to(self.env.device).float().clamp(-1.0, 1.0)

    @property
    def chunked(self) -> bool:
        """Whether `select_action` plays plain chunks of `n_action_steps` from a queue (ACT, pi0, pi0.5), so
        `act_chunk` gives what it would queue. ACT with temporal ensembling infers at every step instead."""
        config = self.model.config
        return config.type != "diffusion" and getattr(config, "temporal_ensemble_coeff", None) is None

    @property
    def realtime_unsupported(self) -> str | None:
        """Why real-time evaluation (`rollout.realtime`) cannot time this policy, or None."""
        if self.model.config.type == "diffusion":
            return ("--realtime does not model Diffusion Policy: it keeps a history of the observations of every step "
                    "(n_obs_steps), which a policy that is only asked when it is free does not see")
        return None

    @torch.no_grad()
    def act_chunk(self, obs) -> torch.Tensor:
        """`(N, n, A)`: the `n_action_steps` actions `select_action` would queue from this observation, each
        unnormalized and clipped as `act` does with the one it returns."""
        batch = self.preprocess(self.batch(obs))
        chunk = self.model.predict_action_chunk(batch)[:, : self.model.config.n_action_steps]
        actions = torch.stack([self.postprocess(chunk[:, i]) for i in range(chunk.shape[1])], dim=1)
        return actions.to(self.env.device).float().clamp(-1.0, 1.0)


def _register(kind: str) -> None:
    cls = type(f"LeRobot_{kind}", (LeRobotPolicy,), {"kind": kind, "__doc__": f"LeRobot {kind} from a checkpoint."})
    register_policy(kind)(cls)


for _kind in LEROBOT_TYPES:
    _register(_kind)
