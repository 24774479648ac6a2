"""The shared X500 airframe agent: six virtual joints from the world, rotor disks, cameras, the flight controller.

A platform subclass (`gripper_platform`, `arm_platform`) only adds its manipulator links under the airframe and names
its extra joints. Everything is built procedurally from `platforms.py`; no mesh is downloaded.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import sapien
import torch
import transforms3d
from mani_skill.agents.base_agent import BaseAgent
from mani_skill.sensors.camera import CameraConfig
from mani_skill.utils import common, sapien_utils
from mani_skill.utils.structs import Actor, Pose
from sapien.wrapper.articulation_builder import LinkBuilder

from ..collision import ignore_self_collisions
from ..control.payload import ControllerMode
from ..control.so3 import quat_rotate
from ..control.virtual_joints import (
    NUM_VIRTUAL_JOINTS,
    VIRTUAL_JOINT_NAMES,
    AirframeState,
    airframe_state_from_joints,
    joint_columns,
)
from ..observations import proprio_state
from ..platforms import Component, PlatformSpec
from ..poses import pose_of
from .body_controller import AerialBodyController, AerialBodyControllerConfig
from .finger_controller import FingerControllerConfig

# PhysX needs a mass on every link; the virtual links carry a negligible one (0.02% of the airframe in total) and
# no gravity, so the virtual joints add no force of their own.
VIRTUAL_LINK_MASS_KG = 1e-4
VIRTUAL_LINK_INERTIA = 1e-7
WORKSPACE_HALF_EXTENT_M = 100.0  # prismatic joint limits; far outside any scene

FINGER_JOINT_NAMES = ("finger_left", "finger_right")
CONTROL_MODES = tuple(m.value.replace("-", "_") for m in ControllerMode)  # "payload_aware", "nominal"

# Joint frames: SAPIEN joints act along / about the x axis of the joint frame.
_Q_X = [1.0, 0.0, 0.0, 0.0]
_Q_X_TO_Y = [np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)]  # +90 deg about z
_Q_X_TO_MINUS_Y = [np.cos(np.pi / 4), 0.0, 0.0, -np.sin(np.pi / 4)]
_Q_X_TO_Z = [np.cos(np.pi / 4), 0.0, -np.sin(np.pi / 4), 0.0]  # -90 deg about y
_VIRTUAL_JOINTS = (
    ("root_x", "prismatic", _Q_X),
    ("root_y", "prismatic", _Q_X_TO_Y),
    ("root_z", "prismatic", _Q_X_TO_Z),
    ("root_yaw", "revolute", _Q_X_TO_Z),
    ("root_pitch", "revolute", _Q_X_TO_Y),
    ("root_roll", "revolute", _Q_X),
)
assert tuple(j[0] for j in _VIRTUAL_JOINTS) == VIRTUAL_JOINT_NAMES
VIRTUAL_LINK_NAMES = frozenset({"world_anchor"} | {f"{n}_link" for n in VIRTUAL_JOINT_NAMES[:-1]})

AIRFRAME_COLOR = (0.15, 0.15, 0.17)
ROTOR_COLOR = (0.55, 0.58, 0.62)
GRIPPER_COLOR = (0.85, 0.45, 0.1)


@lru_cache(maxsize=32)
def _camera_pose(eye: tuple[float, float, float], target: tuple[float, float, float]) -> torch.Tensor:
    """`sapien_utils.look_at(eye, target)` as a raw pose `(1, 7)`: the onboard cameras' mounts are constants, and
    ManiSkill's look-at (torch ops and a matrix-to-quaternion conversion) cost 4% of a reset at every episode's
    reconfiguration; callers take a copy."""
    return sapien_utils.look_at(eye, target).raw_pose


class NonFiniteActionError(ValueError):
    """An action with NaN or inf entries reached the platform."""


def composite_mass_properties(
    components: tuple[Component, ...], base_inertia: tuple[float, float, float], base_name: str = "x500_body"
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Mass, centre of mass, principal inertia and principal-axes quaternion (wxyz) of rigidly joined components.

    `base_inertia` is the source model's inertia of the component named `base_name` (about its own centre);
    the others carry their own `inertia_kgm2`. Parallel-axis theorem about the composite centre of mass.
    """
    mass = sum(c.mass_kg for c in components)
    com = sum(c.mass_kg * np.asarray(c.position_m) for c in components) / mass
    inertia = np.zeros((3, 3))
    for c in components:
        own = np.diag(base_inertia if c.name == base_name else c.inertia_kgm2)
        r = np.asarray(c.position_m) - com
        inertia += own + c.mass_kg * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
    principal, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    return mass, com, principal, transforms3d.quaternions.mat2quat(axes)


def add_box(link: LinkBuilder, center, half_size, color, collide: bool = True, material=None, quat=_Q_X) -> None:
    pose = sapien.Pose(p=list(center), q=list(quat))
    link.add_box_visual(pose=pose, half_size=list(half_size), material=color)
    if collide:
        link.add_box_collision(pose=pose, half_size=list(half_size), material=material)


class AerialAgent(BaseAgent):
    """Base of both platforms. Class attribute `platform` selects the constants."""

    platform: PlatformSpec
    fix_root_link = True
    # the fingers touch each other and the palm by design: a self-collision bit of the drone's own (collision.py)
    disable_self_collisions = False
    arm_joint_names: tuple[str, ...] = ()
    grasp_link_name: str = "airframe"  # link the fingers and the tool centre point ride on
    _routes: tuple[object, tuple | None] | None = None  # (the mode's controller, `_host_routes` for it)

    # ----------------------------------------------------------------------------------------------------------------
    # Building
    # ----------------------------------------------------------------------------------------------------------------
    def _load_articulation(self, initial_pose=None):
        builder = self.scene.create_articulation_builder()
        parent = builder.create_link_builder()
        parent.set_name("world_anchor")
        parent.set_mass_and_inertia(VIRTUAL_LINK_MASS_KG, sapien.Pose(), [VIRTUAL_LINK_INERTIA] * 3)
        for i, (name, kind, quat) in enumerate(_VIRTUAL_JOINTS):
            link = builder.create_link_builder(parent)
            link.set_name("airframe" if i == len(_VIRTUAL_JOINTS) - 1 else f"{name}_link")
            link.set_joint_name(name)
            limits = [[-WORKSPACE_HALF_EXTENT_M, WORKSPACE_HALF_EXTENT_M]] if kind == "prismatic" else [[-np.inf, np.inf]]
            frame = sapien.Pose(q=quat)
            link.set_joint_properties(kind, limits=limits, pose_in_parent=frame, pose_in_child=frame)
            if i < len(_VIRTUAL_JOINTS) - 1:
                link.set_mass_and_inertia(VIRTUAL_LINK_MASS_KG, sapien.Pose(), [VIRTUAL_LINK_INERTIA] * 3)
            parent = link
        self._build_airframe(parent)
        self._build_manipulator(builder, parent)
        builder.initial_pose = initial_pose if initial_pose is not None else sapien.Pose()
        builder.set_name(self.uid if self._agent_idx is None else f"{self.uid}-agent-{self._agent_idx}")
        self.robot = builder.build(fix_root_link=True)
        ignore_self_collisions(self.robot, "drone")
        self.robot_link_names = [link.name for link in self.robot.get_links()]

    def _build_airframe(self, airframe: LinkBuilder) -> None:
        p = self.platform
        mass, com, principal, quat = composite_mass_properties(p.airframe_components, p.airframe_inertia_kgm2)
        airframe.set_mass_and_inertia(mass, sapien.Pose(p=com.tolist(), q=quat.tolist()), principal.tolist())
        add_box(airframe, (0, 0, 0), (0.07, 0.07, 0.02), AIRFRAME_COLOR)
        r = p.rotors
        for x, y in r.positions_xy:
            arm_len = float(np.hypot(x, y))
            yaw = np.arctan2(y, x)
            add_box(
                airframe, (x / 2, y / 2, 0.0), (arm_len / 2, 0.011, 0.008), AIRFRAME_COLOR,
                quat=[np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)],
            )
            add_box(airframe, (x, y, r.height_m / 2), (0.015, 0.015, r.height_m / 2), AIRFRAME_COLOR, collide=False)
            # Rotor disk: what keeps the airframe away from walls and vertical handles (SAPIEN cylinders lie along x).
            disk = sapien.Pose(p=[x, y, r.height_m], q=_Q_X_TO_Z)
            airframe.add_cylinder_visual(pose=disk, radius=r.disk_radius_m, half_length=r.disk_thickness_m / 2, material=ROTOR_COLOR)
            airframe.add_cylinder_collision(pose=disk, radius=r.disk_radius_m, half_length=r.disk_thickness_m / 2)

    def _build_manipulator(self, builder, airframe: LinkBuilder) -> None:
        raise NotImplementedError

    def _add_fingers(self, builder, palm: LinkBuilder, joint_origin, along_x: bool) -> None:
        """Two prismatic fingers closing along the palm's y axis, pads meeting at y = 0 when closed.

        `along_x`: the fingers extend forward along the palm's x axis (arm platform) instead of down (gripper).
        """
        g = self.platform.gripper
        material = sapien.physx.PhysxMaterial(g.pad_friction, g.pad_friction, 0.0)
        half = g.finger_length_m / 2
        for name, quat, side in ((FINGER_JOINT_NAMES[0], _Q_X_TO_Y, 1.0), (FINGER_JOINT_NAMES[1], _Q_X_TO_MINUS_Y, -1.0)):
            finger = builder.create_link_builder(palm)
            finger.set_name(name)
            finger.set_joint_name(name)
            finger.set_joint_properties(
                "prismatic",
                limits=[[0.0, g.max_opening_m / 2]],
                pose_in_parent=sapien.Pose(p=list(joint_origin), q=quat),
                pose_in_child=sapien.Pose(q=quat),
            )
            center = (half, side * g.finger_thickness_m / 2, 0.0) if along_x else (0.0, side * g.finger_thickness_m / 2, -half)
            size = (half, g.finger_thickness_m / 2, g.finger_width_m / 2) if along_x else (g.finger_width_m / 2, g.finger_thickness_m / 2, half)
            add_box(finger, center, size, GRIPPER_COLOR, material=material)
            ixx = g.finger_mass_kg * (size[1] ** 2 + size[2] ** 2) / 3
            iyy = g.finger_mass_kg * (size[0] ** 2 + size[2] ** 2) / 3
            izz = g.finger_mass_kg * (size[0] ** 2 + size[1] ** 2) / 3
            finger.set_mass_and_inertia(g.finger_mass_kg, sapien.Pose(p=list(center)), [ixx, iyy, izz])

    def _after_loading_articulation(self):
        # Rotor thrust is the only force besides gravity and contacts: no damping anywhere, no gravity on virtual links.
        for link in self.robot.links:
            link.linear_damping = 0.0
            link.angular_damping = 0.0
        for name in VIRTUAL_LINK_NAMES:
            self.robot.links_map[name].disable_gravity = True
        if self.platform.arm is not None:
            for spec in self.platform.arm.joints:
                for joint in self.robot.joints_map[spec.name]._objs:
                    joint.armature = np.array([spec.armature_kgm2], dtype=np.float32)

    def _after_init(self):
        self.airframe_link = self.robot.links_map["airframe"]
        self.grasp_link = self.robot.links_map[self.grasp_link_name]
        self.finger_links = [self.robot.links_map[n] for n in FINGER_JOINT_NAMES]
        def indices(names) -> tuple[int, ...]:
            return tuple(int(self.robot.active_joints_map[n].active_index[0]) for n in names)

        # the virtual joints', the fingers' and the arm's columns of the joint vectors, as indices (e.g. the shared
        # signals' constants) ...
        self.joint_indices = {"virtual": indices(VIRTUAL_JOINT_NAMES), "fingers": indices(FINGER_JOINT_NAMES),
                              "arm": indices(self.arm_joint_names) if self.arm_joint_names else ()}
        self.virtual_joint_indices = torch.tensor(self.joint_indices["virtual"], device=self.device)
        # ... and as the columns read every control step (a slice where they run; no arm: None)
        self.finger_joints = joint_columns(self.joint_indices["fingers"], self.device)
        self.arm_joints = joint_columns(self.joint_indices["arm"], self.device) if self.arm_joint_names else None

    # ----------------------------------------------------------------------------------------------------------------
    # Controllers and sensors
    # ----------------------------------------------------------------------------------------------------------------
    @property
    def _controller_configs(self):
        g = self.platform.gripper
        configs = {}
        for mode in ControllerMode:
            body = AerialBodyControllerConfig(
                joint_names=list(VIRTUAL_JOINT_NAMES) + list(self.arm_joint_names), platform=self.platform, mode=mode.value
            )
            gripper = FingerControllerConfig(
                list(FINGER_JOINT_NAMES),
                lower=0.0,
                upper=g.max_opening_m / 2,
                stiffness=g.drive_stiffness_npm,
                damping=g.drive_damping_nspm,
                force_limit=g.force_limit_n,
                normalize_action=True,
                mimic={FINGER_JOINT_NAMES[1]: {"joint": FINGER_JOINT_NAMES[0]}},
            )
            # balance_passive_force=False keeps gravity on the links: the rotors carry the weight.
            configs[mode.value.replace("-", "_")] = dict(body=body, gripper=gripper, balance_passive_force=False)
        return configs

    @property
    def _sensor_configs(self):
        return [
            CameraConfig(
                uid=c.uid,
                pose=Pose.create(_camera_pose(c.eye_m, c.target_m).clone()),
                width=c.width,
                height=c.height,
                fov=c.fov_rad,
                near=c.near_m,
                far=c.far_m,
                mount=self.robot.links_map[c.link],
            )
            for c in self.platform.cameras
        ]

    @property
    def body_controller(self) -> AerialBodyController:
        return self.controller.controllers["body"]

    def before_simulation_step(self):
        # 240 Hz: only the body controller acts between physics steps (`FingerController.before_simulation_step` is
        # empty), so it is called directly instead of through ManiSkill's loop over the mode's controllers
        self.body_controller.before_simulation_step()

    def set_action(self, action):
        action = common.to_tensor(action, device=self.device)
        routes = self._host_routes()
        if routes is not None and action.shape == routes[0]:
            # physx_cpu: the one env's action is a few host floats, read once; each controller takes its own from
            # them (`set_action_values`) instead of a slice, a clip and a scale as tensor ops, about 10 us a control
            # step (docs/performance.md). A non-finite one goes on to the check below, which names it.
            values = action.tolist()[0]
            if all(map(math.isfinite, values)):
                for controller, start, end in routes[1]:
                    controller.set_action_values(values[start:end])
                return
        batched = action if action.ndim == 2 else action[None]
        # a NaN or an inf anywhere makes the sum non-finite: one reduction finds a finite action (the per-env check
        # runs only for the error message, or where finite values overflow the sum)
        bad = None if math.isfinite(batched.sum()) else ~torch.isfinite(batched).all(dim=-1)
        if bad is not None and bad.any():
            envs = bad.nonzero()[:, 0].tolist()
            raise NonFiniteActionError(
                f"non-finite action (NaN or inf) for env index {envs[0] if len(envs) == 1 else envs}: "
                f"{batched[bad][0].tolist()}; send finite commands in [-1, 1]"
            )
        self.controller.set_action(action)  # what BaseAgent.set_action does after its NaN-only check, checked above

    def _host_routes(self) -> tuple[tuple[int, int], list[tuple[object, int, int]]] | None:
        """On physx_cpu: the action's shape and, per controller of the mode, its columns; None on the GPU."""
        if self.scene.gpu_sim_enabled:
            return None
        controller = self.controller
        cached = self._routes
        if cached is None or cached[0] is not controller:
            parts = [(controller.controllers[uid], start, end) for uid, (start, end) in controller.action_mapping.items()]
            lean = all(hasattr(part, "set_action_values") for part, _, _ in parts)
            shape = (1, *controller.single_action_space.shape)
            cached = self._routes = (controller, (shape, parts) if lean else None)
        return cached[1]

    def reset(self, init_qpos=None):
        super().reset(init_qpos)
        if self.controllers:
            for controller in self.controllers.values():
                controller.controllers["body"].begin_reset(self.scene._reset_mask.clone())

    # ----------------------------------------------------------------------------------------------------------------
    # State and checks
    # ----------------------------------------------------------------------------------------------------------------
    def joint_state(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The articulation's joint positions and velocities `(N, J)` (on physx_cpu read straight from PhysX)."""
        if self.controllers:
            return self.body_controller.joint_state()
        return self.robot.get_qpos(), self.robot.get_qvel()

    def virtual_joints(self, q: torch.Tensor, qd: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The six virtual joints' columns `(N, 6)` of whole joint vectors (a slice where they lead)."""
        if self.controllers and self.body_controller.leading_joints:
            return q[:, :NUM_VIRTUAL_JOINTS], qd[:, :NUM_VIRTUAL_JOINTS]
        idx = self.virtual_joint_indices
        return q[:, idx], qd[:, idx]

    def airframe_state(self) -> AirframeState:
        """Position and velocity of the airframe centre, rotation and body angular velocity, `(N, ...)`."""
        q, qd = self.joint_state()
        controller = self.body_controller if self.controllers else None
        if controller is not None and controller.leading_joints:  # the virtual joints lead: one compiled call
            return controller.step_fn.airframe_state(q, qd)
        idx = self.virtual_joint_indices
        return airframe_state_from_joints(q[:, idx], qd[:, idx])

    def get_proprioception(self, state: AirframeState | None = None) -> dict:
        """The documented proprioceptive state (`observations.STATE_FIELDS`), `(N, 19)` or `(N, 25)` with the arm;
        `state`: this step's airframe state where the caller already has it."""
        q, qd = self.joint_state()
        fingers, arm = self.finger_joints, self.arm_joints
        state = self.airframe_state() if state is None else state
        arm_parts = () if arm is None else (q[:, arm], qd[:, arm])
        return {"state": proprio_state(state, q[:, fingers], qd[:, fingers], *arm_parts)}

    def arm_qpos(self) -> torch.Tensor:
        """Arm joint positions `(N, 3)` (shoulder, elbow, wrist); empty `(N, 0)` on the gripper platform."""
        q = self.robot.get_qpos()
        return q[:, self.arm_joints] if self.arm_joints is not None else q[:, :0]

    def arm_qvel(self) -> torch.Tensor:
        """Arm joint velocities `(N, 3)` (rad/s); empty `(N, 0)` on the gripper platform."""
        qd = self.robot.get_qvel()
        return qd[:, self.arm_joints] if self.arm_joints is not None else qd[:, :0]

    def hover_qpos(self, position: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
        """Full qpos for a level airframe at `position` `(N, 3)` with heading `yaw` `(N,)`, working arm pose, open gripper."""
        n = position.shape[0]
        qpos = torch.zeros(n, self.robot.max_dof, device=self.device)
        idx = self.virtual_joint_indices
        qpos[:, idx[:3]] = position.to(self.device)
        qpos[:, idx[3]] = yaw.to(self.device)
        if self.platform.arm is not None:
            for name, value in zip(self.arm_joint_names, self.platform.arm.working_pose_rad):
                qpos[:, self.robot.active_joints_map[name].active_index[0]] = value
        for name in FINGER_JOINT_NAMES:
            qpos[:, self.robot.active_joints_map[name].active_index[0]] = self.platform.gripper.max_opening_m / 2
        return qpos

    @property
    def tcp_pose(self) -> Pose:
        """Tool centre point (grasp point): the link the fingers ride on, offset to the point between the pads."""
        link = self.grasp_link
        if not self.scene.gpu_sim_enabled and len(link._objs) == 1:  # physx_cpu: one SAPIEN pose product
            pose = link._objs[0].entity_pose * sapien.Pose(p=self._tcp_offset_in_grasp_link)
            return Pose(raw_pose=torch.from_numpy(np.concatenate([pose.p, pose.q]))[None])
        link = pose_of(link)  # the offset is a pure translation: rotate it, keep the link's orientation
        offset = torch.as_tensor(self._tcp_offset_in_grasp_link, dtype=link.p.dtype, device=link.p.device)
        return Pose.create_from_pq(p=link.p + quat_rotate(link.q, offset), q=link.q)

    _tcp_offset_in_grasp_link: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def tcp_offset(self) -> tuple[float, float, float]:
        """The tool centre point in the grasp link's frame, m."""
        return tuple(float(x) for x in self._tcp_offset_in_grasp_link)

    def finger_opening(self) -> torch.Tensor:
        """Distance between the finger pads, m, `(N,)`."""
        return self.joint_state()[0][:, self.finger_joints].sum(-1)

    def finger_contact_forces(self, obj: Actor) -> tuple[torch.Tensor, torch.Tensor]:
        """Contact force vectors `(N, 3)` of the left and right finger on `obj`."""
        return tuple(self.scene.get_pairwise_contact_forces(link, obj) for link in self.finger_links)

    def is_grasping(self, obj: Actor, min_force: float = 0.5, max_angle_deg: float = 85.0) -> torch.Tensor:
        """Both fingers press on `obj` with at least `min_force` N, each roughly along its closing direction."""
        flags = []
        for link, f, sign in zip(self.finger_links, self.finger_contact_forces(obj), (1.0, -1.0)):
            opening_dir = sign * link.pose.to_transformation_matrix()[..., :3, 1]
            angle = common.compute_angle_between(opening_dir, f)
            flags.append((torch.linalg.norm(f, dim=-1) >= min_force) & (torch.rad2deg(angle) <= max_angle_deg))
        return flags[0] & flags[1]
