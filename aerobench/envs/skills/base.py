"""`AeroSkillEnv`: what the five skill envs and the sequential env share.

A skill env = a task setting's procedural scene (one layout per parallel env), its objects, the platform, one or
more `SkillEvaluator`s (pick, place, nav, open/close; the interface in `evaluator.py`) and the episode sampler of its first skill.
Per control step the env reads the simulation once (joints, poses, contacts), computes the shared signals from those
reads (`signals.shared_signals`, one compiled call on a CPU) into a `StepContext`, lets the active evaluator add its
own, latches failures, and hands the payload / contact-mode switches to the flight controller.

Args (besides ManiSkill's `num_envs`, `obs_mode`, `sim_backend`, ...): `setting` (TidyHouse | PrepareGroceries |
PackageDelivery | LongHorizonRearrangement), `object` (one of the setting's objects; default: sampled per env),
`platform` (gripper | arm; default per skill), `controller` (payload-aware | nominal), `num_distractors`,
`real_assets` ("ycb": YCB meshes for the objects), `assets_dir` (see `assets.py`) and `condition` (evaluation
conditions, `conditions/`: every kind applies here, the sensor ones to the proprioceptive and task state, the payload
ones to the target object's built mass, the lighting and surface colours to the lights and boxes built from the
layouts, the camera noise and blur to the frames). `reset(options=...)` takes
`"object"` or `"objects"` (one per env) with `"reconfigure": True` to choose the objects of the next layout.
On one CPU env the layout is regenerated every episode; with parallel envs (GPU) each env keeps its layout until
`reset(options={"reconfigure": True})` (ManiSkill's `reconfiguration_freq` overrides either default).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import sapien
import torch
from mani_skill.sensors.camera import CameraConfig
from mani_skill.utils import sapien_utils
from mani_skill.utils.structs import Actor, Pose

from ...accel import Kernel
from ..agents.airframe import FINGER_JOINT_NAMES, VIRTUAL_LINK_NAMES
from ..assets import YCB_IDS, parse_real_assets, replicacad_dir, ycb_model_dir
from ..base_env import AerialEnv
from ..checks import FailureCause, SafetyLimits, verdict_kernel
from ..conditions.runtime import SURFACE_STREAM, stream_generator
from ..conditions.sensors import proprio_with_estimate
from ..contacts import ContactReader, ContactReadout
from ..control.arm import arm_point_positions_body
from ..control.virtual_joints import AirframeState
from ..geometry import drone_proxy_points_body, free_view_point, min_distance_to_boxes, pack_boxes
from ..objects import ObjectSpec, build_object, get_object
from ..observations import GRASP_CONFIRM_STEPS, heading_frame
from ..poses import linear_velocity_of, raw_pose_of, raw_quats_of
from ..scenes import generate_layout
from ..scenes.build import BuiltScene, build_layouts, light_layouts, place_fixtures
from ..scenes.layout import SceneLayout, Support
from ..scenes.room_routes import RoomRoutes
from ..signals import ENVELOPE_FLAGS, TARGET_INPUT, SharedSignals, SignalConstants, signals_kernel
from ..tasks import DEFAULT_PLATFORM, SKILLS, TaskSetting, get_setting
from .evaluator import SkillEvaluator
from .markers import build_marker, place_marker
from .starts import PARKING_DEPTH_M, SUPPORT_KINDS, EpisodeStarts


@dataclass
class StepContext:
    """Everything evaluators read at one control step, computed once by the env. `(N, ...)` tensors."""

    state: AirframeState
    readout: ContactReadout
    speed: torch.Tensor
    angular_speed: torch.Tensor
    nontarget_force: torch.Tensor
    airframe_force: torch.Tensor
    gripper_opening: torch.Tensor
    gripper_command: torch.Tensor  # last commanded opening in [-1, 1]
    tcp: torch.Tensor  # (N, 3)
    tcp_pose: Pose  # the tool centre point's full pose (tcp is its position)
    opening_dirs: torch.Tensor  # (N, 2, 3) each finger's opening direction
    # the target object (None without one)
    object_pose: Pose | None = None
    object_rotation: torch.Tensor | None = None
    object_velocity: torch.Tensor | None = None
    object_bottom_z: torch.Tensor | None = None
    grasp_point: torch.Tensor | None = None  # (N, 3) world position of the object's planned grasp point
    is_grasped: torch.Tensor | None = None  # both fingers >= GRASP_FORCE_N along their opening directions
    is_grasp_held: torch.Tensor | None = None  # both fingers > HELD_FORCE_N (spec's transport criterion)
    is_supported: torch.Tensor | None = None  # something other than the fingers carries >= 30% of its weight
    is_upright: torch.Tensor | None = None
    signals: SharedSignals | None = None  # everything above and the base signals of `evaluate()`, as computed


class AeroSkillEnv(EpisodeStarts, AerialEnv):
    """Base of AeroPick/Place/Nav/Open/Close and AeroSequential. Subclasses set `skill` and `_make_evaluators`."""

    SUPPORTED_OBS_MODES = ("state", "state_dict", "none", "sensor_data", "rgb", "depth", "rgbd")
    SUPPORTED_REWARD_MODES = ("sparse", "none")
    skill: str = ""
    uses_object = True
    safety = SafetyLimits()
    supports_task_conditions = True
    supports_scene_conditions = True

    def __init__(
        self,
        *args,
        setting: str = "TidyHouse",
        object: str | None = None,  # noqa: A002  (the spec's kwarg name)
        platform: str | None = None,
        num_distractors: int = 2,
        reconfiguration_freq: int | None = None,
        real_assets: str | tuple[str, ...] = (),
        assets_dir: str | None = None,
        **kwargs,
    ):
        self.real_assets = parse_real_assets(real_assets)
        self.assets_dir = assets_dir
        if "replicacad" in self.real_assets:
            replicacad_dir(assets_dir)  # one-line error: missing, or not supported yet
        self.setting: TaskSetting = get_setting(setting)
        self._check_setting()
        if object is not None:
            self.setting.check_object(object)
        self.object_name = object
        self.num_distractors = int(num_distractors) if self.uses_object else 0
        if reconfiguration_freq is None:
            reconfiguration_freq = 1 if kwargs.get("num_envs", 1) == 1 else 0
        super().__init__(
            *args, platform=platform or self._default_platform(), reconfiguration_freq=reconfiguration_freq, **kwargs
        )

    def _check_setting(self) -> None:
        self.setting.check_skill(self.skill)

    def _default_platform(self) -> str:
        return DEFAULT_PLATFORM[self.skill]

    # ----------------------------------------------------------------------------------------------------------------
    # Scene
    # ----------------------------------------------------------------------------------------------------------------
    def _load_scene(self, options: dict):
        seeds = [int(s) for s in np.atleast_1d(self._episode_seed)]
        rngs = [np.random.default_rng(s) for s in seeds]
        self.layouts: list[SceneLayout] = [generate_layout(self.setting.scene, rng) for rng in rngs]
        surfaces = self.condition.surface_colours if self.condition is not None else None
        if surfaces is not None:  # from their own stream: the layouts and the starts stay the nominal ones
            self.layouts = [surfaces.recolour(layout, stream_generator(seed, SURFACE_STREAM))
                            for layout, seed in zip(self.layouts, seeds)]
        self.built: BuiltScene = build_layouts(self.scene, self.layouts)
        self.static_boxes = pack_boxes([layout.boxes for layout in self.layouts], self.device)
        self.workspace_lo = torch.tensor([layout.workspace_lo for layout in self.layouts], device=self.device)
        self.workspace_hi = torch.tensor([layout.workspace_hi for layout in self.layouts], device=self.device)
        self.room_routes = RoomRoutes.pack(self.layouts, self.device)
        self._pack_supports()
        self.target: Actor | None = None
        self.target_specs: list[ObjectSpec] = []
        self.distractors: list[Actor] = []
        if self.uses_object:
            requested = options.get("objects") or ([options["object"]] * self.num_envs if options.get("object") else None)
            if requested is not None:
                if len(requested) != self.num_envs:
                    raise ValueError(f"options['objects'] needs one object per env ({self.num_envs}), got {len(requested)}")
                for name in requested:
                    self.setting.check_object(name)
            names = list(requested) if requested else [self.object_name or str(rng.choice(self.setting.objects)) for rng in rngs]
            self.target_specs = [get_object(n) for n in names]  # the classes' nominal masses (what the controller knows)
            scale = self.condition.payload_mass_scale if self.condition is not None else None
            built = [replace(s, mass_kg=s.mass_kg * scale) for s in self.target_specs] if scale else self.target_specs
            self.target = self._build_per_env(built, "target")
            for slot in range(self.num_distractors):
                others = [[o for o in self.setting.objects if o != n] or [n] for n in names]
                specs = [get_object(str(rng.choice(pool))) for rng, pool in zip(rngs, others)]
                self.distractors.append(self._build_per_env(specs, f"distractor_{slot}"))
            self._object_tensors()
        rig = self.scene.create_actor_builder()
        rig.initial_pose = sapien.Pose(p=[0, 0, 2])
        self.camera_rig = rig.build_kinematic(name="camera_rig")
        self.proxy_points, self.proxy_radius = drone_proxy_points_body(self.platform)
        self.proxy_points = self.proxy_points.to(self.device)
        self.start_proxy_points = self.proxy_points
        if self.platform.arm is not None:  # starts also keep the arm (at its rest pose) clear of the furniture
            arm = arm_point_positions_body(torch.tensor([self.platform.arm.working_pose_rad]), self.platform.arm)
            extra = torch.cat([arm[k] for k in ("elbow", "wrist", "grasp")], 0).to(self.device)
            self.start_proxy_points = torch.cat([self.proxy_points, extra], 0)
        self.evaluators = self._make_evaluators()
        assert all(ev.skill in SKILLS for ev in self.evaluators)
        # the goals only the simulator knows, shown to the cameras (visual only: the physics does not see them)
        self.goal_markers = [(ev, build_marker(self.scene, ev.marker, f"goal_marker_{k}"))
                             for k, ev in enumerate(self.evaluators) if ev.marker is not None]

    def _build_per_env(self, specs: list[ObjectSpec], name: str) -> Actor:
        def mesh(spec: ObjectSpec):
            use_ycb = "ycb" in self.real_assets and spec.name in YCB_IDS
            return ycb_model_dir(spec.name, self.assets_dir) if use_ycb else None

        actors = [
            build_object(
                self.scene, spec, f"{name}_{i}", sapien.Pose(p=[0, 0, PARKING_DEPTH_M - i]), scene_idxs=[i], mesh_dir=mesh(spec)
            )
            for i, spec in enumerate(specs)
        ]
        return Actor.merge(actors, name=name)

    def _object_tensors(self) -> None:
        def t(values):
            return torch.tensor(values, dtype=torch.float32, device=self.device)

        specs = self.target_specs
        self.target_mass = t([s.mass_kg for s in specs])
        # the mass the simulation gives it (a payload condition scales it; the controller is fed `target_mass`)
        scale = self.condition.payload_mass_scale if self.condition is not None else None
        self.target_physical_mass = self.target_mass * scale if scale else self.target_mass
        self.target_height = t([s.height_m for s in specs])
        self.target_grasp_width = t([s.grasp_width_m for s in specs])
        self.target_radius = t([s.footprint_radius_m for s in specs])
        self.target_half_extent = t([s.half_extent_m for s in specs])  # (N, 2), along the object's x and y
        self.target_grasp_point = t([s.grasp_point_m for s in specs])  # (N, 3), object frame
        # a bowl is grasped anywhere on its rim (the pick plans the rim point along its heading): its planned grasp
        # point is the rim circle through `target_grasp_point` (radius = its x, height = its z), not the +x point
        self.target_grasps_rim = torch.tensor([s.shape == "bowl" for s in specs], dtype=torch.bool, device=self.device)

    def _pack_supports(self) -> None:
        width = max(len(layout.supports) for layout in self.layouts)
        packed = torch.zeros(self.num_envs, max(width, 1), 9)
        for i, layout in enumerate(self.layouts):
            for j, s in enumerate(layout.supports):
                kind = SUPPORT_KINDS.index(s.kind) if s.kind in SUPPORT_KINDS else -1
                packed[i, j] = torch.tensor([*s.center, *s.half_size, s.height, s.yaw, kind, 1.0, min(s.clear_height, 1e3)])
        # columns: cx, cy, hx, hy, height, yaw, kind, valid, free height above
        self.supports = packed.to(self.device)
        self.support_counts = [len(layout.supports) for layout in self.layouts]  # each env's own rows of `supports`

    def support_of(self, env: int, index: int) -> Support:
        return self.layouts[env].supports[index]

    def condition_surfaces(self) -> torch.Tensor | None:
        return getattr(self, "static_boxes", None)  # the layouts' floors, walls, ceiling and furniture

    def _load_lighting(self, options: dict):
        lighting = self.condition.lighting if self.condition is not None else None  # made here, for the build
        layouts = self.layouts if lighting is None else [lighting.relight(layout) for layout in self.layouts]
        light_layouts(self.scene, layouts, shadow=self.enable_shadow)
        fill = [0.4, 0.4, 0.4]
        self.scene.add_directional_light([0, 0, -1], fill if lighting is None else lighting.light_colour(fill))

    @property
    def _default_human_render_camera_configs(self):
        # Third-person view for videos and pictures, riding on a kinematic rig that `aim_render_camera` places in
        # free space near the drone at every reset (a fixed pose would sit inside some layout's wall).
        return CameraConfig("render_camera", sapien.Pose(), 384, 384, math.radians(70), 0.01, 30, mount=self.camera_rig)

    def aim_render_camera(self, env_idx: torch.Tensor) -> None:
        """Put the third-person camera 1.6-2.2 m from the drone, above it, in free space, looking at it."""
        target = self.agent.airframe_state().position[env_idx] + torch.tensor([0.0, 0.0, -0.2], device=self.device)
        best_eye = free_view_point(target, self.obstacle_boxes(env_idx), self.workspace_lo[env_idx],
                                   self.workspace_hi[env_idx])
        poses = [sapien_utils.look_at(e.tolist(), t.tolist()) for e, t in zip(best_eye.cpu(), target.cpu())]
        raw = torch.cat([p.raw_pose for p in poses], 0).to(self.device)
        self.camera_rig.set_pose(Pose.create(raw))

    def _after_reconfigure(self, options):
        names = [link.name for link in self.agent.robot.links if link.name not in VIRTUAL_LINK_NAMES]
        self.monitored_links = names
        self.contacts = ContactReader(
            self.scene, self.agent.robot, names, FINGER_JOINT_NAMES, self.target, self._handle_links()
        )
        const = SignalConstants(
            tcp_offset=self.agent.tcp_offset, finger_idx=tuple(names.index(n) for n in FINGER_JOINT_NAMES),
            airframe_idx=names.index("airframe"), proxy_radius=float(self.proxy_radius), safety=self.safety,
            has_target=self.target is not None, virtual_joints=self.agent.joint_indices["virtual"],
            finger_joints=self.agent.joint_indices["fingers"], arm_joints=self.agent.joint_indices["arm"],
        )
        self._signals_kernel = signals_kernel(const, self.device)  # one per process and kind of env: compiled once
        self._verdicts: dict[tuple[int, ...], Kernel] = {}  # `checks.verdict` kernels by the causes flagged
        # constants read at every control step, made once: evaluator 0's index (a single-skill env's subtask) and
        # "not set down" (the payload switch's input where no evaluator reports a set-down)
        self._evaluator_zero = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        self._not_set_down = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)

    def _handle_links(self) -> list:
        """Fixture links whose handles the fingers may pinch (Open/Close)."""
        return []

    # ----------------------------------------------------------------------------------------------------------------
    # Episode
    # ----------------------------------------------------------------------------------------------------------------
    def _initialize_episode(self, env_idx: torch.Tensor, options: dict):
        place_fixtures(self.built, env_idx)
        n = self.num_envs
        if not hasattr(self, "_fail_cause") or self._fail_cause.shape[0] != n:
            self._fail_cause = torch.zeros(n, dtype=torch.long, device=self.device)
            self._episode_step = torch.zeros(n, dtype=torch.long, device=self.device)
            self.init_failed = torch.zeros(n, dtype=torch.bool, device=self.device)
            self.instructions = [""] * n
            self._gripper_command = torch.ones(n, device=self.device)
            self._grasp_streak = torch.zeros(n, dtype=torch.long, device=self.device)
            self.starts_held = torch.zeros(n, dtype=torch.bool, device=self.device)
        self._fail_cause[env_idx] = 0
        self._grasp_streak[env_idx] = 0
        self.starts_held[env_idx] = False  # set by starts that put the object in the jaws (Place)
        self._episode_step[env_idx] = 0
        commanded = self._gripper_command.clone()  # a new tensor: a step context holds the one it read
        commanded[env_idx] = 1.0
        self._gripper_command = commanded
        self.init_failed[env_idx] = ~self._sample_episode(env_idx)
        for evaluator, marker in self.goal_markers:
            place_marker(marker, evaluator.marker, *evaluator.marker_position(env_idx))
        if self.target is not None:  # where the object started: "knocked" (failure analysis) is measured from here
            if not hasattr(self, "_object_start_p") or self._object_start_p.shape[0] != n:
                self._object_start_p = torch.zeros(n, 3, device=self.device)
                self._object_start_q = torch.zeros(n, 4, device=self.device)
            pose = self.target.pose
            self._object_start_p[env_idx] = pose.p[env_idx].clone()
            self._object_start_q[env_idx] = pose.q[env_idx].clone()
        self.aim_render_camera(env_idx)
        self._signals_step = -1

    def _sample_episode(self, env_idx: torch.Tensor) -> torch.Tensor:
        """Place objects and the drone for a new episode; return `(M,)` whether a feasible start was found."""
        raise NotImplementedError

    def _make_evaluators(self) -> list:
        raise NotImplementedError

    def active_evaluator_index(self) -> torch.Tensor:
        """Which evaluator scores each env now, `(N,)`; a single-skill env always uses evaluator 0 (one tensor of the
        env's, handed out at every step: read it, do not write into it)."""
        return self._evaluator_zero

    def evaluator_masks(self, active: torch.Tensor) -> list[tuple[SkillEvaluator, torch.Tensor | None]]:
        """Each evaluator with the mask `(N,)` of the envs it scores now (`active`: `active_evaluator_index()`), or
        None for a single-skill env's one evaluator, which scores every env (its trackers skip the masking ops)."""
        if len(self.evaluators) == 1:
            return [(self.evaluators[0], None)]
        return [(evaluator, active == k) for k, evaluator in enumerate(self.evaluators)]

    # ----------------------------------------------------------------------------------------------------------------
    # Signals
    # ----------------------------------------------------------------------------------------------------------------
    def _after_control_step(self):
        self._episode_step += 1
        # the key of the step's cached signals: a count on the host (a sum of ManiSkill's elapsed-step tensor costs a
        # reduction and a sync at each of the step's half a dozen `evaluate()` calls)
        self._control_steps = getattr(self, "_control_steps", 0) + 1

    def current_step_context(self) -> StepContext:
        """This control step's shared context (airframe state, tool centre point, contacts, object), computed once
        per control step with `evaluate()`: the observation and the expert read it instead of querying the agent
        again (each query is a few dozen small tensor ops, paid several times per step otherwise)."""
        self.evaluate()
        return self._ctx

    def signal_inputs(self) -> tuple[list[torch.Tensor], ContactReadout]:
        """This step's reads of the simulation and the env's constants, as `signals.shared_signals` takes them, and
        the contact readout among them."""
        agent = self.agent
        q, qd = agent.joint_state()
        readout = self.contacts.read()
        tensors = [
            q, qd, raw_pose_of(agent.grasp_link), raw_quats_of(agent.finger_links),
            readout.link_forces, readout.finger_on_target, readout.target_net, self.workspace_lo, self.workspace_hi, self.proxy_points, self.obstacle_boxes(),
        ]
        if self.target is not None:
            tensors += [raw_pose_of(self.target), linear_velocity_of(self.target), self.target_grasp_point,
                        self.target_grasps_rim, self.target_physical_mass, self._object_start_p, self._object_start_q,
                        self._grasp_streak, self.starts_held, self._episode_step]
        return tensors, readout

    def step_context(self) -> StepContext:
        tensors, readout = self.signal_inputs()
        s = SharedSignals.from_flat(self._signals_kernel(*tensors))
        ctx = StepContext(
            state=AirframeState(s.position, s.velocity, s.rotation, s.angular_velocity_body),
            readout=readout,
            speed=s.speed,
            angular_speed=s.angular_speed,
            nontarget_force=s.nontarget_force,
            airframe_force=s.airframe_force,
            gripper_opening=s.gripper_opening,
            gripper_command=self._gripper_command,  # replaced, never written in place (`_step_action`, resets)
            tcp=s.tcp,
            tcp_pose=Pose(raw_pose=s.tcp_pose),
            opening_dirs=s.opening_dirs,
            signals=s,
        )
        if self.target is not None:
            object_pose, ctx.object_velocity = tensors[TARGET_INPUT : TARGET_INPUT + 2]
            ctx.object_pose, ctx.object_rotation = Pose(raw_pose=object_pose), s.object_rotation
            ctx.object_bottom_z = object_pose[:, 2]
            ctx.grasp_point, ctx.is_grasped, ctx.is_grasp_held = s.grasp_point, s.is_grasped, s.is_grasp_held
            ctx.is_supported, ctx.is_upright = s.is_supported, s.is_upright
        return ctx

    def evaluate(self) -> dict:
        """All per-step signals, `(N,)` tensors; computed once per control step (ManiSkill may call this again): a
        reset, or setting `_signals_step` to -1 after moving bodies without a step, computes them again."""
        step_id = getattr(self, "_control_steps", 0)
        if getattr(self, "_signals_step", -1) == step_id and hasattr(self, "_signals"):
            return self._signals
        ctx = self._ctx = self.step_context()
        s = ctx.signals
        if s.grasp_streak is not None:  # the grasp streak is one of the shared signals (held starts confirmed)
            self._grasp_streak = s.grasp_streak
        envelope = {flag: getattr(s, flag) for flag in ENVELOPE_FLAGS}
        active = self.active_evaluator_index()
        info: dict[str, torch.Tensor] = {
            "tilt": s.tilt,
            "altitude": s.altitude,
            "speed": ctx.speed,
            "angular_speed": ctx.angular_speed,
            # roll-pitch angular speed and the vertical velocity-error integral (spec appendix "Payload-Aware Flight
            # Control" logs both during the carry)
            "tilt_rate": s.tilt_rate,
            "integral_z": self.agent.body_controller.memory.xi[:, 2].clone(),
            "tcp_height": ctx.tcp[:, 2],
            "nontarget_contact_force": ctx.nontarget_force,
            "airframe_contact_force": ctx.airframe_force,
            "gripper_opening": ctx.gripper_opening,
            "min_obstacle_clearance": s.clearance,
            "init_failed": self.init_failed.clone(),
            "subtask_index": active,
            **envelope,
            **self.flight_statistics(),
        }
        if ctx.object_pose is not None:
            info.update(
                is_grasped=ctx.is_grasped,
                is_grasp_held=ctx.is_grasp_held,
                grasp_force_left=s.grasp_forces[:, 0],
                grasp_force_right=s.grasp_forces[:, 1],
                object_height=ctx.object_bottom_z,
                object_speed=s.object_speed,
                is_object_upright=ctx.is_upright,
                is_object_supported=ctx.is_supported,
                tcp_to_grasp_point=s.tcp_to_grasp_point,
                # since the episode started: how far the object moved and how much it turned (spec "Failure Analysis")
                object_displacement=s.object_displacement,
                object_rotation=s.object_turn,
            )
        successes: list[torch.Tensor] = []
        flags: list[tuple[FailureCause, torch.Tensor]] = []
        for evaluator, mine in self.evaluator_masks(active):
            signals, skill_success, skill_flags = evaluator.update(ctx, mine)
            if mine is None:  # the only evaluator: active in every env
                info.update(signals)
                successes.append(skill_success)
                flags += skill_flags
                continue
            for key, value in signals.items():
                # an evaluator's own signals read as False / 0 in envs where another subtask is active
                info[key] = torch.where(mine, value, info[key] if key in info else torch.zeros_like(value))
            successes.append(mine & skill_success)
            flags += [(cause, mine & flag) for cause, flag in skill_flags]
        success = successes[0] if len(successes) == 1 else torch.stack(successes).any(0)
        flags += [
            (FailureCause.TILT, envelope["fail_tilt"]),
            (FailureCause.LOW, envelope["fail_low"]),
            (FailureCause.HIGH, envelope["fail_high"]),
            (FailureCause.WORKSPACE, envelope["fail_workspace"]),
        ]
        # the first failure latched, and success where none (`checks.verdict`: one compiled call on a CPU)
        causes = tuple(int(cause) for cause, _ in flags)
        kernel = self._verdicts.get(causes)
        if kernel is None:
            kernel = self._verdicts[causes] = verdict_kernel(causes, self.device)
        self._fail_cause, info["fail"], info["success"], reward = kernel(
            self._fail_cause, self._overall_success(success), *[flag for _, flag in flags])
        info["fail_cause"] = self._fail_cause.clone()
        info["is_success"] = info["success"]
        self._sparse_reward = (info["success"], reward)
        self._signals, self._signals_step = info, step_id
        return info

    def compute_sparse_reward(self, obs, action, info: dict) -> torch.Tensor:
        """ManiSkill's sparse reward (1 on success, -1 on failure, else 0); for this step's own signals, as the step's
        verdict computed it with them."""
        cached = getattr(self, "_sparse_reward", None)
        if cached is not None and info.get("success") is cached[0]:
            return cached[1]
        return super().compute_sparse_reward(obs, action, info)

    def _overall_success(self, active_success: torch.Tensor) -> torch.Tensor:
        return active_success

    def robot_clearance(self, points: torch.Tensor) -> torch.Tensor:
        """Clearance `(N,)` of the robot's proxy `points` `(N, P, 3)` (world) from the scene's boxes, less the proxy
        radius. Every box is measured: culling the far ones first (exact, by the 1-Lipschitz bound) doubled the cost
        on a CPU, where a step's few dozen small ops cost their dispatch, not their elements."""
        return min_distance_to_boxes(points, self.obstacle_boxes()) - self.proxy_radius

    # ----------------------------------------------------------------------------------------------------------------
    # Controller hand-offs, observations, instruction
    # ----------------------------------------------------------------------------------------------------------------
    def _step_action(self, action):
        if action is not None:
            a = torch.as_tensor(action, device=self.device, dtype=torch.float32)
            a = a if a.ndim == 2 else a[None]
            self._gripper_command = a[:, -1].clone()
        return super()._step_action(action)

    def payload_signals(self):
        if self.target is None:
            return None
        info = self.evaluate()
        return info["is_grasped"], info.get("is_set_down", self._not_set_down), self.target_mass

    def _before_control_step(self):
        super()._before_control_step()
        if self.platform.arm is not None and "is_handle_pinched" in self.evaluate():
            self.agent.body_controller.set_contact_mode(self.evaluate()["is_handle_pinched"])

    def _get_obs_agent(self):
        # the agent's `get_proprioception`, computed with the step's shared signals
        proprio = self.current_step_context().signals.proprio
        if self.condition is not None and self.condition.senses:
            proprio = proprio_with_estimate(proprio, self.sensed_airframe_state())
        return {"state": proprio}

    def sensed_airframe_state(self) -> AirframeState:
        """The airframe state a policy reads under a sensor condition: delayed and noisy (`conditions.sensors`)."""
        return self.condition_runtime.sensed(self.current_step_context().state, self._elapsed_steps)

    def _get_obs_extra(self, info: dict):
        # as ManiSkill's PickCube: the tool centre point's pose in every mode (the proprio state's forward kinematics),
        # the object and the goals only in the state modes
        ctx = self.current_step_context()
        extra = {"tcp_pose": ctx.tcp_pose.raw_pose}
        if "state" in self.obs_mode:
            if ctx.object_pose is not None:
                extra["object_pose"] = ctx.object_pose.raw_pose
            for evaluator in self.evaluators:
                extra.update(evaluator.privileged_obs())
        return extra

    def task_state(self) -> torch.Tensor:
        """`(N, 31)` task state (`(N, 34)` with the arm) in the layout of `observations.TASK_STATE_FIELDS`: the active
        skill's relative goal geometry, the grasp confirmation and the flight state, for state-based policies."""
        self.evaluate()  # the step's context (computed once per control step)
        ctx, n = self._ctx, self.num_envs
        active = self.active_evaluator_index()
        goal, goal_point = torch.zeros(n, 3, device=self.device), torch.zeros(n, 3, device=self.device)
        heading_error, progress = torch.zeros(n, device=self.device), torch.zeros(n, device=self.device)
        skill = torch.zeros(n, dtype=torch.long, device=self.device)
        confirmed = self._grasp_streak >= GRASP_CONFIRM_STEPS  # the target object's; a handle's from its evaluator
        for evaluator, mine in self.evaluator_masks(active):  # every evaluator's features, kept where it is active
            mine = torch.ones_like(active, dtype=torch.bool) if mine is None else mine
            f = evaluator.goal_features(ctx)
            goal = torch.where(mine[:, None], f.goal_pos, goal)
            goal_point = torch.where(mine[:, None], f.goal_point, goal_point)
            heading_error = torch.where(mine, f.heading_error, heading_error)
            progress = torch.where(mine, f.progress, progress)
            if f.grasp_confirmed is not None:
                confirmed = torch.where(mine, f.grasp_confirmed, confirmed)
            skill = torch.where(mine, SKILLS.index(evaluator.skill), skill)
        state = ctx.state
        # the policy's own motion: under a sensor condition the sensed estimate (the goal vectors stay exact)
        own = self.sensed_airframe_state() if self.condition is not None and self.condition.senses else state
        zeros = torch.zeros(n, 3, device=self.device)
        doorway, ahead = self.room_routes.next_doorway(state.position, goal_point)
        parts = [
            (skill[:, None] == torch.arange(len(SKILLS), device=self.device)).float(),  # one_hot checks its range: a sync
            goal,
            heading_frame(goal, state.yaw),
            ctx.object_pose.p - ctx.tcp if ctx.object_pose is not None else zeros,
            heading_error[:, None],
            progress[:, None],
            confirmed.float()[:, None],
            own.velocity,
            own.angular_velocity_body,
            -own.rotation[:, 2, :2],  # gravity (0, 0, -1) in the body frame: -R^T e_z, its x and y
            (own.position[:, 2] - self.workspace_lo[:, 2])[:, None],
            (self.grasp_side_room if ctx.object_pose is not None else torch.zeros(n, device=self.device))[:, None],
            ahead.float()[:, None],
            torch.where(ahead[:, None], doorway - state.position, zeros),
        ]
        if self.platform.arm is not None:
            parts.append(self.agent.arm_qpos())
        return torch.cat(parts, dim=-1).float()

    @property
    def grasp_side_room(self) -> torch.Tensor:
        """`(N,)` the room each open finger leaves beside the target object across its grasp: how exactly a grasp
        from above must be aligned."""
        return ((self.platform.gripper.max_opening_m - self.target_grasp_width) / 2).clamp_min(0.0)

    def get_instruction(self, env: int = 0) -> str:
        return self.instructions[env]

    def skill_instruction(self, env: int = 0) -> str:
        """The instruction of the skill active in env `env`: a chain's current stage ("place the bowl on ..."), a
        single-skill env's whole instruction (a per-skill policy's language input; one host read of the stage)."""
        if len(self.evaluators) == 1:
            return self.instructions[env]
        return self.evaluators[int(self.active_evaluator_index()[env])].instruction(env)

    @property
    def task_description(self) -> str:
        return self.instructions[0]
