"""A LeRobot checkpoint served by LeRobot's own PolicyServer (`lerobot.async_inference`, gRPC), behind the batched
interface: `aerobench eval --policy-server HOST:PORT --policy-type act --checkpoint DIR`.

The client speaks the server's protocol as LeRobot's `RobotClient` does: `Ready`, then `SendPolicyInstructions` (a
pickled `RemotePolicyConfig`: policy type, checkpoint path, the robot's features, actions per chunk, device), then
per request one `SendObservations` (a pickled `TimedObservation`, sent with `must_go` so the server never skips it
as too similar to the last one) and one `GetActions` (a pickled list of `TimedAction`: the chunk). The observation
is the raw robot dict the server expects: the proprioceptive state as one float per named field, each camera's
RGB image (H, W, 3) uint8 under its name, and the instruction as `task`, built from the same LeRobot inputs a local
policy reads (`lerobot_policies.lerobot_batch`).

LeRobot's server builds only `observation.state`, `observation.images.*` and `task` from what a robot sends, so a
checkpoint that reads anything else (the privileged `observation.environment_state`, the packed depth images) is
refused here in one line rather than failing on the server.

Trust: both sides unpickle what the other sends, and unpickling runs whatever code the pickle names. The client
therefore talks to a loopback address unless told that the server is trusted (`trust=True`,
`--trust-policy-server`); see docs/robustness.md.
"""

from __future__ import annotations

import ipaddress
import pickle  # nosec: LeRobot's transport is pickles (see the module docstring on trust)
import time
from dataclasses import dataclass
from pathlib import Path

import torch

from ..envs.observations import state_field_names
from .lerobot_policies import LEROBOT_TYPES, _load_config, lerobot_batch, resolve_checkpoint

READY_TIMEOUT_S = 10.0
LOAD_TIMEOUT_S = 600.0  # the server loads the checkpoint onto its device (a VLA on a GPU: minutes)
ACT_TIMEOUT_S = 120.0
SERVER_INPUTS = ("observation.state", "observation.images.")  # what LeRobot's server builds from a raw observation
START_SERVER = "python -m lerobot.async_inference.policy_server --host=HOST --port=PORT --fps=20 --inference_latency=0"


class PolicyServerError(ConnectionError):
    """The policy server is down, refused the policy, or answered something that is not an action chunk."""


def parse_address(text: str) -> tuple[str, int]:
    """`HOST:PORT` (an IPv6 host in brackets: `[::1]:8080`) -> (host, port)."""
    host, sep, port = text.strip().rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ValueError(f"--policy-server takes HOST:PORT (e.g. 127.0.0.1:8080), got {text!r}")
    return host, int(port)


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a host name other than localhost may resolve anywhere


@dataclass(frozen=True)
class PolicyServerSpec:
    """Where the policy is served: one address per shard (LeRobot's server serves one client at a time: its
    observation queue and its loaded policy are shared by whoever connects), whether a non-loopback server is
    trusted, and the device the server runs the policy on."""

    addresses: tuple[str, ...]
    trust: bool = False
    device: str = "cpu"

    def __post_init__(self):
        if not self.addresses:
            raise ValueError("--policy-server needs at least one HOST:PORT")
        for address in self.addresses:
            host, _ = parse_address(address)
            if not is_loopback(host) and not self.trust:
                raise ValueError(
                    f"--policy-server {address} is not a loopback address: LeRobot's policy server and client exchange "
                    f"pickles, and unpickling runs any code the other side puts in them; pass --trust-policy-server "
                    f"if you trust that server and the network to it (docs/robustness.md)")

    def address_for(self, shard: tuple[int, int]) -> str:
        """The server shard `shard` = (i, k) talks to (one server per shard)."""
        i, k = shard
        if len(self.addresses) != k and len(self.addresses) > 1:
            raise ValueError(f"{len(self.addresses)} policy servers for {k} shards: give one server per worker")
        return self.addresses[i % len(self.addresses)]


def _rpc_error(address: str, what: str, error) -> PolicyServerError:
    code = error.code().name if hasattr(error, "code") else type(error).__name__
    details = (error.details() if hasattr(error, "details") else str(error)) or ""
    details = " ".join(details.split())[:300]  # one line
    if code in ("UNAVAILABLE", "DEADLINE_EXCEEDED"):
        return PolicyServerError(f"no policy server answers at {address} ({code} while {what}): start LeRobot's there "
                                 f"with `{START_SERVER}`; the episodes finished so far are kept, run the same command "
                                 f"again to continue")
    return PolicyServerError(f"the policy server at {address} failed while {what} ({code}: {details})")


class ServerSession:
    """One gRPC channel to one server, the policy it was last told to load, and the observation counter."""

    def __init__(self, address: str):
        import grpc
        from lerobot.transport import services_pb2_grpc  # type: ignore
        from lerobot.transport.utils import grpc_channel_options

        self.address = address
        self.channel = grpc.insecure_channel(address, grpc_channel_options())
        self.stub = services_pb2_grpc.AsyncInferenceStub(self.channel)
        self.loaded: tuple | None = None
        self.timestep = 0
        self._call("connecting", "Ready", None, READY_TIMEOUT_S)

    def _call(self, what: str, method: str, request, timeout_s: float):
        import grpc
        from lerobot.transport import services_pb2  # type: ignore

        try:
            return getattr(self.stub, method)(services_pb2.Empty() if request is None else request, timeout=timeout_s)
        except grpc.RpcError as e:
            raise _rpc_error(self.address, what, e) from None

    def load(self, policy_type: str, path: Path, features: dict, actions_per_chunk: int, device: str) -> None:
        """Tell the server which checkpoint to serve (again only when it changes: loading takes the server a while)."""
        from lerobot.async_inference.helpers import RemotePolicyConfig
        from lerobot.transport import services_pb2  # type: ignore

        key = (policy_type, str(path), repr(features), actions_per_chunk, device)
        if self.loaded == key:
            return
        config = RemotePolicyConfig(policy_type, str(path), features, actions_per_chunk, device)
        self._call(f"loading {path}", "SendPolicyInstructions", services_pb2.PolicySetup(data=pickle.dumps(config)),
                   LOAD_TIMEOUT_S)
        self.loaded = key

    def chunk(self, observation: dict, action_dim: int, max_len: int) -> torch.Tensor:
        """`(n, A)` the server's chunk for one raw observation (1 <= n <= max_len)."""
        from lerobot.async_inference.helpers import TimedAction, TimedObservation
        from lerobot.transport import services_pb2  # type: ignore
        from lerobot.transport.utils import send_bytes_in_chunks

        self.timestep += 1
        t = self.timestep
        sent = pickle.dumps(TimedObservation(timestamp=time.time(), timestep=t, observation=observation, must_go=True))
        self._call(f"sending observation #{t}", "SendObservations",
                   send_bytes_in_chunks(sent, services_pb2.Observation, silent=True), ACT_TIMEOUT_S)
        reply = self._call(f"waiting for the actions of observation #{t}", "GetActions", None, ACT_TIMEOUT_S)
        data = getattr(reply, "data", b"")
        if not data:
            raise PolicyServerError(f"the policy server at {self.address} answered no actions for observation #{t} "
                                    f"(its policy failed on it; the server's log says why)")
        garbage = f"the policy server at {self.address} answered observation #{t} with something that is not an action chunk"
        try:
            actions = pickle.loads(data)  # nosec: a loopback or explicitly trusted server (PolicyServerSpec)
        except Exception as e:  # a pickle can fail in many ways; each is the same fault here
            raise PolicyServerError(f"{garbage} ({type(e).__name__})") from None
        if not (isinstance(actions, list) and 1 <= len(actions) <= max_len
                and all(isinstance(a, TimedAction) and torch.is_tensor(a.get_action()) for a in actions)):
            raise PolicyServerError(f"{garbage} (a {type(actions).__name__}; expected 1 to {max_len} TimedActions)")
        if actions[0].get_timestep() != t:
            raise PolicyServerError(f"{garbage} (it answers observation #{actions[0].get_timestep()}: is another "
                                    f"client using that server?)")
        try:
            chunk = torch.stack([a.get_action().detach().to("cpu", torch.float32).reshape(-1) for a in actions])
        except RuntimeError as e:
            raise PolicyServerError(f"{garbage} (actions of different sizes)") from e
        if chunk.shape[1] != action_dim or not torch.isfinite(chunk).all():
            raise PolicyServerError(f"{garbage} (actions of {chunk.shape[1]} values, expected {action_dim} finite ones)")
        return chunk


_SESSIONS: dict[str, ServerSession] = {}


def session(address: str) -> ServerSession:
    """The process's one session per server (the runner builds a policy per batch; the server keeps its policy)."""
    if address not in _SESSIONS:
        _SESSIONS[address] = ServerSession(address)
    return _SESSIONS[address]


def probe(spec: PolicyServerSpec) -> None:
    """Connect to every server once, so one that is down is a one-line error before any episode runs."""
    for address in spec.addresses:
        session(address)


def served_config(policy: str, checkpoint: str | None):
    """The checkpoint's folder and config, checked for what LeRobot's server can serve."""
    from lerobot.async_inference.constants import SUPPORTED_POLICIES

    if policy not in LEROBOT_TYPES:
        raise ValueError(f"--policy-type takes a LeRobot policy aerobench evaluates ({', '.join(LEROBOT_TYPES)}), "
                         f"got {policy!r}")
    path = resolve_checkpoint(checkpoint, policy)
    config = _load_config(path, policy)
    if config.type not in SUPPORTED_POLICIES:
        raise ValueError(f"checkpoint {path} holds a {config.type!r} policy, which LeRobot's PolicyServer does not "
                         f"serve (it serves {', '.join(SUPPORTED_POLICIES)})")
    if getattr(config, "n_obs_steps", 1) > 1:
        raise ValueError(f"checkpoint {path} reads the last {config.n_obs_steps} observations (n_obs_steps), and "
                         f"LeRobot's PolicyServer gives the policy one per request: evaluate it locally "
                         f"(--policy {policy} without --policy-server)")
    unserved = [k for k in config.input_features if not k.startswith(SERVER_INPUTS)]
    if unserved:
        raise ValueError(f"checkpoint {path} reads {', '.join(unserved)}, which LeRobot's PolicyServer does not build "
                         f"from a robot's observation (only observation.state, observation.images.* and the task): "
                         f"evaluate it locally (--policy {policy} without --policy-server)")
    return path, config


class ServedInputs:
    """How an aerobench observation reaches a checkpoint through LeRobot's server: the robot's features the server
    is told (dataset features: `names` map the raw observation's keys into `observation.state`; images are looked up
    by camera name) and one raw robot observation per env, from the inputs a local policy would get."""

    def __init__(self, env, inputs: dict):
        self.env, self.inputs = env, inputs
        names = state_field_names(env.platform.arm is not None)
        width = inputs["observation.state"].shape[0] if "observation.state" in inputs else len(names)
        self.state_names = names if width == len(names) else [f"state_{i}" for i in range(width)]  # an older layout
        self.cameras = [k.removeprefix("observation.images.") for k in inputs if k.startswith("observation.images.")]

    def features(self) -> dict:
        features = {"observation.state": {"dtype": "float32", "shape": (len(self.state_names),), "names": self.state_names}}
        for cam in self.cameras:
            c, h, w = self.inputs[f"observation.images.{cam}"].shape
            features[f"observation.images.{cam}"] = {"dtype": "image", "shape": (h, w, c),
                                                     "names": ["height", "width", "channels"]}
        return features

    def raw_observations(self, obs) -> list[dict]:
        batch = lerobot_batch(self.env, obs, self.inputs)
        state = batch["observation.state"][:, : len(self.state_names)].cpu()
        raws = []
        for i in range(self.env.num_envs):
            raw: dict = dict(zip(self.state_names, state[i].tolist()))
            for cam in self.cameras:  # back to the camera's uint8 (H, W, 3): the server divides by 255 itself
                image = batch[f"observation.images.{cam}"][i].mul(255.0).round().to(torch.uint8)
                raw[cam] = image.permute(1, 2, 0).cpu().numpy()
            raw["task"] = batch["task"][i]
            raws.append(raw)
        return raws


class RemotePolicy:
    """A LeRobot policy evaluated through LeRobot's PolicyServer. It plays each chunk from a queue as LeRobot's
    `select_action` does (`act`), or hands whole chunks to the real-time wrapper (`act_chunk`)."""

    chunked = True
    resets_whole_batch = True  # one queue of chunks for the batch (`LeRobotPolicy.resets_whole_batch`)

    def __init__(self, env, address: str, policy: str, checkpoint: str | None, device: str = "cpu"):
        self.name, self.env, self.address = policy, env, address
        path, config = served_config(policy, checkpoint)
        self.action_dim = config.output_features["action"].shape[0]
        if self.action_dim != env.platform.action_dim:
            raise ValueError(f"checkpoint {path} acts with {self.action_dim} values; the {env.platform.name} platform "
                             f"takes {env.platform.action_dim} (train on a dataset of the same platform)")
        self.actions_per_chunk = int(getattr(config, "n_action_steps", 1) or 1)
        self.inputs = ServedInputs(env, dict(config.input_features))
        self.session = session(address)
        self.session.load(config.type, path.resolve(), self.inputs.features(), self.actions_per_chunk, device)
        self.queue: list[torch.Tensor] = []

    def reset(self, env_idx: torch.Tensor) -> None:
        self.queue = []

    def act_chunk(self, obs) -> torch.Tensor:
        """`(N, n, A)`: the server's chunk for each env's observation (one round trip per env)."""
        raws = self.inputs.raw_observations(obs)
        chunks = [self.session.chunk(raw, self.action_dim, self.actions_per_chunk) for raw in raws]
        n = min(len(c) for c in chunks)
        return torch.stack([c[:n] for c in chunks]).to(self.env.device).clamp(-1.0, 1.0)

    def act(self, obs) -> torch.Tensor:
        if not self.queue:
            chunk = self.act_chunk(obs)
            self.queue = [chunk[:, i] for i in range(chunk.shape[1])]
        return self.queue.pop(0)
