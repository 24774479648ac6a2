"""`AerialEnv`: the ManiSkill base class every aerobench env derives from.

It owns what all tasks share: the platform agent (`platform="gripper" | "arm"`), the controller variant
(`controller="payload-aware" | "nominal"`), the spec's 240 Hz physics / 20 Hz control, the once-per-control-step
hand-off of payload signals to the flight controller, and the evaluation condition (`condition=`, `conditions/`:
the physical ones through the body controller, the camera noise and motion blur on the frames a policy reads here).
Tasks fill the usual ManiSkill hooks.
"""

from __future__ import annotations

import gc
import os

import numpy as np
import sapien
import torch
from mani_skill.envs.sapien_env import BaseEnv
from mani_skill.sensors.camera import Camera
from mani_skill.utils.structs.types import SceneConfig, SimConfig

from .agents import AGENT_UIDS, AerialAgent
from .conditions import ConditionSet, resolve_condition
from .conditions.runtime import ConditionRuntime
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

    A process-wide effect, so no env constructor calls it: the processes that own their lifetime and build envs one
    after another call it (the rollout runner, PPO's envs). `AEROBENCH_FREEZE_HEAP=0` switches it off.
    """
    global _heap_frozen
    if _heap_frozen or os.environ.get("AEROBENCH_FREEZE_HEAP", "1") == "0":
        return
    _heap_frozen = True
    import torch._dynamo  # noqa: F401 - loaded by the first compiled physics step anyway
    import torch._inductor.compile_fx  # noqa: F401

    gc.collect()
    gc.freeze()


class AerialEnv(BaseEnv):
    """Base of aerobench envs. Args (besides ManiSkill's): `platform`, `controller`, `physx_solver`, `rendering`
    ("rasterized" or "ray-traced": every camera through SAPIEN's ray tracer; needs a ray-tracing GPU), `condition`
    (names of evaluation conditions, `conditions.CONDITIONS`, as a tuple or "a,b"; default none: today's physics),
    `rotor_statistics` (also record whether the rotors are saturated at each control step: `flight_statistics`).

    Every random draw of a reset comes from `episode_rng` (`episode_rng.py`: one generator per env, seeded by that
    env's episode seed), never from torch's global generator, which ManiSkill seeds with env 0's seed only. The
    conditions draw from their own per-env streams (`conditions.runtime`), never from those."""

    SUPPORTED_ROBOTS = list(AGENT_UIDS.values())
    agent: AerialAgent
    # whether the env has a task observation and a carried object for the sensor and payload conditions to act on
    supports_task_conditions = False
    # whether the env makes its lights and surfaces from layouts, for the lighting and surface colour conditions
    supports_scene_conditions = False
    condition_runtime: ConditionRuntime | None = None

    def __init__(self, *args, platform: str = "gripper", controller: str = "payload-aware",
                 physx_solver: str | None = None, rendering: str = DEFAULT_RENDERING,
                 condition: str | tuple[str, ...] | None = (), rotor_statistics: bool = False, **kwargs):
        self.condition: ConditionSet | None = resolve_condition(condition)
        self.rotor_statistics = bool(rotor_statistics)
        if self.condition is not None and not self.supports_task_conditions and (
                self.condition.senses or self.condition.payload_mass_scale is not None):
            raise ValueError(f"{type(self).__name__} has no policy observation or carried object for the sensor and "
                             f"payload conditions; use them with the skill envs")
        if self.condition is not None and self.condition.changes_scene and not self.supports_scene_conditions:
            raise ValueError(f"{type(self).__name__} does not build its scene from layouts for the lighting and "
                             f"surface colour conditions; use them with the skill envs")
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
        super().__init__(*args, robot_uids=AGENT_UIDS[self.platform.name], **kwargs)

    def flight_statistics(self) -> dict[str, torch.Tensor]:
        """Per-step flight signals that cost a side computation, only where asked (`rotor_statistics=True`, as
        `aerobench eval` does): "rotor_saturated" `(N,)`, whether the controller's rotor thrusts are clipped now."""
        if not self.rotor_statistics:
            return {}
        return {"rotor_saturated": self.agent.body_controller.rotor_saturated()}

    @property
    def _default_sim_config(self) -> SimConfig:
        return SimConfig(sim_freq=PHYSICS_HZ, control_freq=CONTROL_HZ, spacing=20.0,
                         scene_config=SceneConfig(enable_tgs=self.physx_solver == "tgs"))

    def _set_episode_rng(self, seed, env_idx):
        """ManiSkill's episode seeds, and each reset env's own generator (`episode_rng`) restarted at its new seed;
        under a condition, its streams restarted too and the new episodes' draws made (`conditions.runtime`)."""
        super()._set_episode_rng(seed, env_idx)
        rows = env_idx.tolist() if isinstance(env_idx, torch.Tensor) else np.atleast_1d(env_idx).tolist()
        runtime = self._condition_runtime()
        if seed is None and not self._enhanced_determinism:
            if runtime is not None:
                runtime.start_episodes(rows)  # each env's condition streams continue, as `episode_rng`'s do
            return  # ManiSkill keeps the old episode seeds: each env's stream continues
        seeds = np.atleast_1d(self._episode_seed)
        if len(seeds) == self.num_envs:
            seeds = seeds[rows]
        elif len(seeds) != len(rows):  # a partial reset may give one seed per env it resets
            raise ValueError(f"{len(seeds)} seeds for a reset of {len(rows)} of {self.num_envs} envs; give one per env")
        if getattr(self, "episode_rng", None) is None:
            self.episode_rng = EpisodeRNG(self.num_envs, self.device)
        self.episode_rng.seed(rows, seeds.tolist())
        if runtime is not None:
            runtime.seed(rows, seeds.tolist())
            runtime.start_episodes(rows)

    def _condition_runtime(self) -> ConditionRuntime | None:
        """The condition's runtime (made at the first reset, when the env knows its size and device); None without
        a condition."""
        if self.condition is not None and self.condition_runtime is None:
            self.condition_runtime = ConditionRuntime(self.condition, self.platform, self.num_envs, self.device,
                                                      self.condition_surfaces)
        return self.condition_runtime

    def condition_surfaces(self) -> torch.Tensor | None:
        """The static boxes the surface conditions see (`conditions.proximity`), `(N, B, 8)`; None: a floor at z = 0
        alone. Skill envs give their layouts' boxes."""
        return None

    def _load_agent(self, options: dict, initial_agent_poses=None, build_separate: bool = False):
        super()._load_agent(options, sapien.Pose(), build_separate)
        runtime = self._condition_runtime()
        if runtime is not None and runtime.physics is not None:  # every control mode's body controller runs it
            for controller in self.agent.controllers.values():
                controller.controllers["body"].conditioned = runtime.physics

    def payload_signals(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None:
        """(is_grasped, is_set_down, object_mass) for the carried object, `(N,)` each; None when there is no object.

        `is_set_down` must flag only the placement support carrying the object (see `control.payload`).
        """
        return None

    def get_instruction(self, env: int = 0) -> str:
        """The language instruction of env `env` (task envs override this)."""
        return ""

    def _before_control_step(self):
        if self.condition_runtime is not None:
            self.condition_runtime.before_control_step(self._elapsed_steps)
        signals = self.payload_signals()
        if signals is not None:
            self.agent.body_controller.update_payload(*signals)

    def _get_obs_sensor_data(self, apply_texture_transforms: bool = True) -> dict:
        # under camera noise or motion blur the frames a policy reads (ManiSkill's uint8 RGB and int16 depth); the raw
        # float textures (apply_texture_transforms=False) and every other image pass through
        data = super()._get_obs_sensor_data(apply_texture_transforms)
        if self.condition is None or not self.condition.changes_frames or not apply_texture_transforms:
            return data
        motion = self.camera_motion() if self.condition.motion_blur is not None else None
        return self._condition_runtime().camera_frames(data, self._elapsed_steps, motion)

    def camera_motion(self) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
        """Per mounted camera: its angular velocity `(N, 3)` in its own OpenCV frame (x right, y down, z forward; the
        mount link's world angular velocity turned by the camera's world-to-camera rotation) and its intrinsics
        `(N, 3, 3)`, at the last render. A camera on no link does not turn."""
        out, link_omega = {}, {}
        for uid, sensor in self.scene.sensors.items():
            if not isinstance(sensor, Camera) or sensor.entity is None:
                continue
            key = id(sensor.entity)
            if key not in link_omega:  # the onboard cameras share the airframe: one read
                link_omega[key] = sensor.entity.angular_velocity
            world_to_camera = sensor.camera.get_extrinsic_matrix()[:, :3, :3].to(link_omega[key].device)
            out[uid] = ((world_to_camera @ link_omega[key][..., None])[..., 0], sensor.camera.get_intrinsic_matrix())
        return out

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
