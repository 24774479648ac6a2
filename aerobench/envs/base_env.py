"""`AerialEnv`: the ManiSkill base class every aerobench env derives from.

It owns what all tasks share: the platform agent (`platform="gripper" | "arm"`), the controller variant
(`controller="payload-aware" | "nominal"`), the spec's 240 Hz physics / 20 Hz control, and the once-per-control-step
hand-off of payload signals to the flight controller. Tasks fill the usual ManiSkill hooks.
"""

from __future__ import annotations

import gc
import os

import numpy as np
import sapien
import torch
from mani_skill.envs.sapien_env import BaseEnv
from mani_skill.utils.structs.types import SceneConfig, SimConfig

from .agents import AGENT_UIDS, AerialAgent
from .control.payload import ControllerMode
from .episode_rng import EpisodeRNG
from .platforms import CONTROL_HZ, PHYSICS_HZ, get_platform
from .rendering import DEFAULT_RENDERING, check_rendering, ray_traced_camera_overrides

_heap_frozen = False

# PhysX's contact solver. ManiSkill's default, TGS, lets a pinched object creep out of the jaws below the friction
# limit, the faster the more position iterations: the potted meat can slides 0.13 mm per control step at 15 iterations,
# 0.18 at 50 and none at 4, and the 16 mm bowl rim drops at once; PGS holds both, and the flight figures move by less
# than 0.1 mm (docs/physics.md). `physx_solver="tgs"` (or AEROBENCH_PHYSX_SOLVER=tgs) reproduces rows measured before.
PHYSX_SOLVERS = ("pgs", "tgs")
DEFAULT_PHYSX_SOLVER = "pgs"


def default_physx_solver() -> str:
    """The solver an env uses when none is named: AEROBENCH_PHYSX_SOLVER, else PGS."""
    return check_physx_solver(os.environ.get("AEROBENCH_PHYSX_SOLVER", DEFAULT_PHYSX_SOLVER))


def check_physx_solver(solver: str) -> str:
    solver = str(solver).strip().lower()
    if solver not in PHYSX_SOLVERS:
        raise ValueError(f"physx solver {solver!r}; use one of {', '.join(PHYSX_SOLVERS)} (AEROBENCH_PHYSX_SOLVER)")
    return solver


def freeze_process_heap() -> None:
    """Move every object alive now to the GC's permanent generation, once per process.

    ManiSkill releases the old scene on each reconfigure with a full `gc.collect()`; with torch, dynamo and inductor
    loaded that pass walks ~500k objects and costs ~110 ms on this CPU, two thirds of a one-env reset (a CPU env
    reconfigures every episode). Called before the process builds its first scene, when what is alive is imported
    modules and process state that live as long as the process, so freezing them leaks nothing; later collections
    skip them. The compiler's modules are imported first because the first compiled step would load them.
    """
    global _heap_frozen
    if _heap_frozen:
        return
    _heap_frozen = True
    import torch._dynamo  # noqa: F401 - loaded by the first compiled physics step anyway
    import torch._inductor.compile_fx  # noqa: F401

    gc.collect()
    gc.freeze()


class AerialEnv(BaseEnv):
    """Base of aerobench envs. Args (besides ManiSkill's): `platform`, `controller`, `physx_solver`, `rendering`
    ("rasterized" or "ray-traced": every camera through SAPIEN's ray tracer; needs a ray-tracing GPU).

    Every random draw of a reset comes from `episode_rng` (`episode_rng.py`: one generator per env, seeded by that
    env's episode seed), never from torch's global generator, which ManiSkill seeds with env 0's seed only."""

    SUPPORTED_ROBOTS = list(AGENT_UIDS.values())
    agent: AerialAgent

    def __init__(self, *args, platform: str = "gripper", controller: str = "payload-aware",
                 physx_solver: str | None = None, rendering: str = DEFAULT_RENDERING, **kwargs):
        self.platform = get_platform(platform)
        self.physx_solver = check_physx_solver(physx_solver) if physx_solver else default_physx_solver()
        self.rendering = check_rendering(rendering)
        if self.rendering != "rasterized":
            kwargs["sensor_configs"], kwargs["human_render_camera_configs"] = ray_traced_camera_overrides(
                kwargs.get("sensor_configs"), kwargs.get("human_render_camera_configs"))
        self.controller_mode = ControllerMode.parse(controller)
        if "control_mode" in kwargs and kwargs["control_mode"] is not None:
            raise ValueError("aerobench envs choose their controller with controller='payload-aware'|'nominal'")
        kwargs["control_mode"] = self.controller_mode.value.replace("-", "_")
        # SAPIEN renders on the CPU where torch sees no GPU: ManiSkill's default asks for CUDA and warns per env
        kwargs.setdefault("render_backend", "gpu" if torch.cuda.is_available() else "cpu")
        freeze_process_heap()
        super().__init__(*args, robot_uids=AGENT_UIDS[self.platform.name], **kwargs)

    @property
    def _default_sim_config(self) -> SimConfig:
        return SimConfig(sim_freq=PHYSICS_HZ, control_freq=CONTROL_HZ, spacing=20.0,
                         scene_config=SceneConfig(enable_tgs=self.physx_solver == "tgs"))

    def _set_episode_rng(self, seed, env_idx):
        """ManiSkill's episode seeds, and each reset env's own generator (`episode_rng`) restarted at its new seed."""
        super()._set_episode_rng(seed, env_idx)
        if seed is None and not self._enhanced_determinism:
            return  # ManiSkill keeps the old episode seeds: each env's stream continues
        rows = env_idx.tolist() if isinstance(env_idx, torch.Tensor) else np.atleast_1d(env_idx).tolist()
        seeds = np.atleast_1d(self._episode_seed)
        if len(seeds) == self.num_envs:
            seeds = seeds[rows]
        elif len(seeds) != len(rows):  # a partial reset may give one seed per env it resets
            raise ValueError(f"{len(seeds)} seeds for a reset of {len(rows)} of {self.num_envs} envs; give one per env")
        if getattr(self, "episode_rng", None) is None:
            self.episode_rng = EpisodeRNG(self.num_envs, self.device)
        self.episode_rng.seed(rows, seeds.tolist())

    def _load_agent(self, options: dict, initial_agent_poses=None, build_separate: bool = False):
        super()._load_agent(options, sapien.Pose(), build_separate)

    def payload_signals(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None:
        """(is_grasped, is_set_down, object_mass) for the carried object, `(N,)` each; None when there is no object.

        `is_set_down` must flag only the placement support carrying the object (see `control.payload`).
        """
        return None

    def get_instruction(self, env: int = 0) -> str:
        """The language instruction of env `env` (task envs override this)."""
        return ""

    def _before_control_step(self):
        signals = self.payload_signals()
        if signals is not None:
            self.agent.body_controller.update_payload(*signals)

    def _flatten_raw_obs(self, obs):
        # The "state" observation is a dict of dicts of `(N, ...)` tensors: one hstack of its leaves is what
        # ManiSkill's `flatten_state_dict` makes of it (same order and dtype), without its per-level type checks,
        # conversions and hstacks at every step. Anything else goes to ManiSkill.
        if self._obs_mode == "state":
            leaves = state_leaves(obs)
            if leaves:
                return torch.hstack(leaves)
        return super()._flatten_raw_obs(obs)


def state_leaves(obs: dict, leaves: list[torch.Tensor] | None = None) -> list[torch.Tensor] | None:
    """The tensors of a nested state dict in insertion order, an `(N,)` one as `(N, 1)` (as `flatten_state_dict`
    takes them), appended to `leaves`; None if it holds anything but tensors and dicts, or nothing at all."""
    leaves = [] if leaves is None else leaves
    for value in obs.values():
        if isinstance(value, torch.Tensor):
            leaves.append(value[:, None] if value.ndim == 1 else value)
        elif not isinstance(value, dict) or state_leaves(value, leaves) is None:
            return None
    return leaves or None
