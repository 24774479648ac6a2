"""`AeroFly-v1`: the flight-test env behind `aerobench fly` and the demo.

**Task description.** No task: the platform flies whatever velocity / yaw-rate commands it receives, in a procedural
room (`scene="room"`) or over a bare floor (`scene="empty"`), optionally holding an object in its closed gripper
(`payload="tomato_soup_can"`, mass overridable by `payload_mass_kg`), optionally beside a free-floating rigid body with the same mass and inertia that is
driven by its own copy of the flight controller (`reference_body=True`, CPU only), for the virtual-joint check.

**Randomizations.** None: flight tests are deterministic. The start is level at `start_position`, heading 0.

**Success conditions.** None; the episode never ends by itself. `info` carries the flight signals.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import sapien
import torch
from mani_skill.sensors.camera import CameraConfig
from mani_skill.utils import sapien_utils
from mani_skill.utils.registration import register_env
from mani_skill.utils.structs import Actor, Pose

from ..accel import Kernel
from .agents.airframe import FINGER_JOINT_NAMES, VIRTUAL_LINK_NAMES
from .base_env import AerialEnv
from .control.arm import arm_weight_feedforward_body
from .control.flight import FlightMemory, flight_step
from .control.so3 import matrix_to_quat_wxyz, quat_wxyz_to_matrix
from .control.virtual_joints import AirframeState
from .objects import build_object, get_object
from .poses import raw_pose_of
from .scenes.room import RoomLayout, build_room
from .signals import FlightSignalConstants, FlightSignals, flight_signals_kernel

SCENES = ("room", "empty")
REFERENCE_OFFSET_M = (0.0, 4.0, 0.0)  # the reference body flies this far to the side; it has no collision shapes


@register_env("AeroFly-v1", max_episode_steps=100_000)
class AeroFlyEnv(AerialEnv):
    SUPPORTED_OBS_MODES = ("state", "state_dict", "none", "sensor_data", "rgb", "depth", "rgbd")
    SUPPORTED_REWARD_MODES = ("none",)
    _obs_signals: FlightSignals | None = None  # the step's signals while an observation is assembled
    _flight_kernel: Kernel | None = None  # `signals.flight_signals`, compiled (made at the first read)
    _evaluated: FlightSignals | None = None  # the signals of the last `evaluate()`

    def __init__(
        self,
        *args,
        scene: str = "room",
        payload: str | None = None,
        payload_mass_kg: float | None = None,
        reference_body: bool = False,
        start_position: tuple[float, float, float] = (0.0, 0.0, 1.5),
        **kwargs,
    ):
        if scene not in SCENES:
            raise ValueError(f"unknown scene {scene!r}; valid scenes: {', '.join(SCENES)}")
        self.scene_name = scene
        self.payload_spec = get_object(payload) if payload else None
        if self.payload_spec is not None and payload_mass_kg is not None:
            self.payload_spec = replace(self.payload_spec, mass_kg=float(payload_mass_kg))
        self.reference_body = reference_body
        self.start_position = tuple(float(v) for v in start_position)
        super().__init__(*args, **kwargs)
        if reference_body and self.gpu_sim_enabled:
            raise ValueError("reference_body=True is a CPU check (physx_cpu): it compares against a free rigid body")

    # ----------------------------------------------------------------------------------------------------------------
    # Scene
    # ----------------------------------------------------------------------------------------------------------------
    def _load_scene(self, options: dict):
        if self.scene_name == "room":
            self.room = build_room(self.scene, RoomLayout())
        else:
            self.room = build_room(self.scene, RoomLayout(width_m=40.0, depth_m=40.0, height_m=0.01, table_center_m=(15.0, 15.0)))
        self.payload: Actor | None = None
        if self.payload_spec is not None:
            self.payload = build_object(self.scene, self.payload_spec, "payload", sapien.Pose(p=[0, 0, 0.5]))
        self.reference: Actor | None = None
        if self.reference_body:
            builder = self.scene.create_actor_builder()
            builder.add_box_visual(half_size=[0.2, 0.2, 0.02], material=(0.2, 0.6, 0.3))
            builder.set_mass_and_inertia(1.0, sapien.Pose(), [0.01, 0.01, 0.01])  # replaced in _initialize_episode
            builder.initial_pose = sapien.Pose(p=list(REFERENCE_OFFSET_M))
            self.reference = builder.build(name="reference_body")

    @property
    def _default_human_render_camera_configs(self):
        eye, target = ([-2.3, -2.0, 2.3], [0.0, 0.0, 1.2]) if self.scene_name == "room" else ([-3, -3, 3], [0, 1.5, 1.5])
        return CameraConfig("render_camera", sapien_utils.look_at(eye, target), 400, 300, np.deg2rad(62), 0.01, 50)

    # ----------------------------------------------------------------------------------------------------------------
    # Episode
    # ----------------------------------------------------------------------------------------------------------------
    def _initialize_episode(self, env_idx: torch.Tensor, options: dict):
        n = len(env_idx)
        start = torch.tensor(self.start_position, device=self.device).expand(n, 3)
        qpos = self.agent.hover_qpos(start, torch.zeros(n, device=self.device))
        if self.payload is not None or self.reference is not None:
            width = self.payload_spec.grasp_width_m if self.payload is not None else 0.0
            for name in FINGER_JOINT_NAMES:  # pads on the object (or closed), so the grasp starts held
                qpos[:, self.agent.robot.active_joints_map[name].active_index[0]] = width / 2
        self.agent.robot.set_qpos(qpos)
        self.agent.robot.set_qvel(torch.zeros_like(qpos))
        if self.payload is not None:
            tcp = self.agent.tcp_pose.p[env_idx]
            bottom = tcp - torch.tensor([0, 0, self.payload_spec.height_m / 2], device=self.device)
            self.payload.set_pose(Pose.create_from_pq(p=bottom))
        if self.reference is not None:
            self._init_reference_body()

    def _init_reference_body(self) -> None:
        mass, com_body, inertia_body = articulated_mass_properties(self.agent)
        principal, axes = np.linalg.eigh(inertia_body)
        if np.linalg.det(axes) < 0:
            axes[:, 0] = -axes[:, 0]
        q = matrix_to_quat_wxyz(torch.tensor(axes, dtype=torch.float32)).tolist()
        body = self.reference._bodies[0]
        body.mass = float(mass)
        body.cmass_local_pose = sapien.Pose(p=com_body.tolist(), q=q)
        body.inertia = principal.astype(np.float32)
        body.linear_damping = 0.0
        body.angular_damping = 0.0
        start = np.asarray(self.start_position) + np.asarray(REFERENCE_OFFSET_M)
        self.reference.set_pose(Pose.create_from_pq(p=torch.tensor(start, dtype=torch.float32)[None]))
        self.reference.set_linear_velocity(torch.zeros(1, 3))
        self.reference.set_angular_velocity(torch.zeros(1, 3))
        bc = self.agent.body_controller
        self._reference_memory = FlightMemory.initial(1, bc.params, self.device)
        # The rigid body keeps the arm pose it starts with; its flight loop gets that pose's weight-moment feedforward.
        self._reference_arm_q = self.agent.arm_qpos().clone() if bc.arm is not None else None
        self.reference_telemetry: list[torch.Tensor] = []

    def reference_state(self) -> AirframeState:
        """State of the reference body's frame origin (its "airframe centre"), like `agent.airframe_state()`."""
        body = self.reference._bodies[0]
        pose = body.entity_pose
        R = quat_wxyz_to_matrix(torch.tensor(pose.q, dtype=torch.float32))[None]
        p = torch.tensor(pose.p, dtype=torch.float32)[None]
        com_world = torch.tensor((pose * body.cmass_local_pose).p, dtype=torch.float32)[None]
        v_com = torch.tensor(body.linear_velocity, dtype=torch.float32)[None]
        w = torch.tensor(body.angular_velocity, dtype=torch.float32)[None]
        v_origin = v_com + torch.linalg.cross(w, p - com_world)
        return AirframeState(p, v_origin, R, (R.transpose(-1, -2) @ w[..., None])[..., 0])

    def _before_simulation_step(self):
        if self.reference is None:
            return
        bc = self.agent.body_controller
        state = self.reference_state()
        feedforward = None
        if self._reference_arm_q is not None:
            payload = (self._reference_memory.mass_hat - bc.params.mass).clamp_min(0.0)
            feedforward = arm_weight_feedforward_body(state.rotation, self._reference_arm_q, bc.arm, bc.params.gravity, payload)
        out, self._reference_memory = flight_step(
            state, bc.velocity_cmd, bc.yaw_rate_cmd, self._reference_memory, bc.params, feedforward
        )
        body = self.reference._bodies[0]
        com_world = torch.tensor((body.entity_pose * body.cmass_local_pose).p, dtype=torch.float32)[None]
        torque_com = out.torque_world + torch.linalg.cross(state.position - com_world, out.force_world)
        body.add_force_torque(out.force_world[0].numpy(), torque_com[0].numpy())
        self.reference_telemetry.append(state.position[0].clone())

    # ----------------------------------------------------------------------------------------------------------------
    # Signals
    # ----------------------------------------------------------------------------------------------------------------
    def payload_signals(self):
        if self.payload is None:
            return None
        held = self.agent.is_grasping(self.payload)
        mass = torch.full((self.num_envs,), self.payload_spec.mass_kg, device=self.device)
        return held, torch.zeros_like(held), mass

    def flight_signals(self) -> FlightSignals:
        """The step's altitude, tilt, speed, proprioceptive state and TCP pose, from the joints and the grasp link's
        pose as one compiled call (eager, about 40 small ops: a sizeable share of a hovering step on a CPU)."""
        if self._flight_kernel is None:
            const = FlightSignalConstants(
                tcp_offset=self.agent.tcp_offset, virtual_joints=self.agent.joint_indices["virtual"],
                finger_joints=self.agent.joint_indices["fingers"], arm_joints=self.agent.joint_indices["arm"])
            self._flight_kernel = flight_signals_kernel(const, self.device)
        q, qd = self.agent.joint_state()
        return FlightSignals(*self._flight_kernel(q, qd, raw_pose_of(self.agent.grasp_link)))

    def evaluate(self) -> dict:
        s = self._evaluated = self.flight_signals()
        info = {"altitude": s.altitude, "tilt": s.tilt, "speed": s.speed}
        if self.payload is not None:
            info["is_grasped"] = self.agent.is_grasping(self.payload)
            info["payload_height"] = self.payload.pose.p[:, 2]
        return info

    def get_obs(self, info: dict | None = None, unflattened: bool = False):
        # the agent's and the extra observation come from the same signals: those of the info given, where it is the
        # last evaluation's (as `step` and `reset` pass it), else read now
        last = self._evaluated
        given = info is not None and last is not None and info.get("altitude") is last.altitude
        self._obs_signals = last if given else self.flight_signals()
        try:
            return super().get_obs(info, unflattened)
        finally:
            self._obs_signals = None

    def _get_obs_agent(self):
        s = self._obs_signals if self._obs_signals is not None else self.flight_signals()
        return {"state": s.proprio}

    def _get_obs_extra(self, info: dict):
        s = self._obs_signals if self._obs_signals is not None else self.flight_signals()
        return dict(tcp_pose=s.tcp_pose, airframe_velocity=s.velocity)


def articulated_mass_properties(agent) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass, centre of mass and inertia about it, in the airframe frame, of every non-virtual link (CPU, env 0)."""
    airframe = agent.airframe_link._objs[0]
    T_air = airframe.entity_pose.inv()
    links = [link._objs[0] for link in agent.robot.links if link.name not in VIRTUAL_LINK_NAMES]
    coms, inertias, masses = [], [], []
    for link in links:
        cm = T_air * link.entity_pose * link.cmass_local_pose
        R = quat_wxyz_to_matrix(torch.tensor(cm.q, dtype=torch.float64)).numpy()
        coms.append(np.asarray(cm.p, dtype=np.float64))
        inertias.append(R @ np.diag(np.asarray(link.inertia, dtype=np.float64)) @ R.T)
        masses.append(float(link.mass))
    mass = sum(masses)
    com = sum(m * c for m, c in zip(masses, coms)) / mass
    inertia_about_com = np.zeros((3, 3))
    for m, c, inertia in zip(masses, coms, inertias):
        r = c - com
        inertia_about_com += inertia + m * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
    return mass, com, inertia_about_com
