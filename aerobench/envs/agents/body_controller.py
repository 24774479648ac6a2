"""ManiSkill controller that flies the airframe (and drives the arm) with the pure torch controller.

At every physics step (240 Hz) it reads the six virtual joints, runs the flight controller, and applies the rotor
wrench as joint efforts Q = J^T W; on the arm platform it adds the arm servo torques and the arm weight-moment
feedforward. That per-physics-step work is one fused call (`control.fused`: compiled, no host synchronization);
under a physical evaluation condition (`conditions`) it is the conditioned step instead, a separate eager path
(`conditioned`).
Its action is `[u_x, u_y, u_z, u_psi]` (+ three arm-joint targets) in [-1, 1]; the gripper is a separate ManiSkill
PD mimic controller combined after it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
import torch
from gymnasium import spaces
from mani_skill.agents.controllers.base_controller import BaseController, ControllerConfig

from ..control.arm import normalized_arm_action
from ..control.flight import FlightMemory, FlightOutput
from ..control.fused import fused_physics_step
from ..control.payload import ControllerMode
from ..control.virtual_joints import AirframeState, joint_columns
from ..platforms import MAX_SPEED_MPS, MAX_YAW_RATE_RPS, PlatformSpec

if TYPE_CHECKING:
    from ..conditions.physics import ConditionedPhysics

SATURATION_TOLERANCE = 1e-4  # a rotor within this share of its limit (or of zero) counts as clipped


class AerialBodyController(BaseController):
    config: AerialBodyControllerConfig
    sets_target_qpos = False
    sets_target_qvel = False
    # a physical evaluation condition's step (set by the env; None: the fused step of today's physics, untouched)
    conditioned: ConditionedPhysics | None = None

    def __init__(self, config, articulation, control_freq, sim_freq=None, scene=None):
        super().__init__(config, articulation, control_freq, sim_freq=sim_freq, scene=scene)
        platform = config.platform
        n = self.scene.num_envs
        self.step_fn = fused_physics_step(platform, self.device)
        self.params, self.arm = self.step_fn.params, self.step_fn.arm
        self.mode = ControllerMode.parse(config.mode) if isinstance(config.mode, str) else config.mode
        self.memory = FlightMemory.initial(n, self.params, self.device)
        # the flight command (vx, vy, vz, yaw rate) lives in one buffer that each action overwrites: `set_action` is
        # two ops (clip, scale) instead of a slice and a scalar product per command, about 6 us a control step on a
        # CPU; `velocity_cmd` and `yaw_rate_cmd` are fixed views of it, which the fused step reads
        self._command = torch.zeros(n, 4, device=self.device)
        self._command_scale = torch.tensor([MAX_SPEED_MPS] * 3 + [MAX_YAW_RATE_RPS], device=self.device)
        self.velocity_cmd, self.yaw_rate_cmd = self._command[:, :3], self._command[:, 3]
        # physx_cpu: the buffer's one row as the array `set_action_values` fills, and the scale as host floats
        self._command_row = None if self.scene.gpu_sim_enabled else self._command.numpy()[0]
        self._command_scale_values = self._command_scale.tolist()
        working = platform.arm.working_pose_rad if platform.arm else ()
        self.arm_target = torch.tensor(working, dtype=torch.float32, device=self.device).expand(n, len(working)).clone()
        self.contact_mode = torch.zeros(n, dtype=torch.bool, device=self.device)
        self._needs_yaw_sync = torch.ones(n, dtype=torch.bool, device=self.device)
        # whether `_needs_yaw_sync` may hold a set flag (kept on the host: after the first physics step that consumes
        # the flags they stay clear until a reset, and clearing them again at every 240 Hz step is a wasted op)
        self._yaw_sync_pending = True
        # the fused step's StepResult and the joint state it read (last_output/last_state), kept while telemetry
        # records: otherwise the step returns only the efforts and the controller memory
        self.last_result = None
        idx = self.active_joint_indices.tolist()
        # the controller's joints lead the articulation's (fingers follow): plain slices, no gather/scatter per step,
        # and the lean step reads the whole joint vectors and writes every joint's effort
        self.leading_joints = idx == list(range(len(idx)))
        self._joints = joint_columns(idx, self.device)
        self._qf = None
        self._qf_view: tuple[torch.Tensor, np.ndarray] | None = None  # (the loop's efforts, the array PhysX reads)
        self._efforts_loop: tuple[object, Callable] | None = None  # (the step it is for, `step_fn.efforts_loop`)
        # physx_cpu holds one env: the PhysX articulation itself is read and written every physics step (ManiSkill's
        # batched wrapper around it costs several microseconds per call, a sizeable share of a 240 Hz step)
        self._cpu_articulation = None if self.scene.gpu_sim_enabled else self.articulation._objs[0]
        # ... into the lean loop's own joint buffers, which the compiled step consumes at once (filling two arrays
        # costs about half of two fresh tensors): (q, qd, their numpy views), made at the first lean step
        self._loop_joints: tuple[torch.Tensor, torch.Tensor, np.ndarray, np.ndarray] | None = None
        self.telemetry: list[dict[str, torch.Tensor]] | None = None  # set to [] to record every physics step

    # ----------------------------------------------------------------------------------------------------------------
    # ManiSkill controller interface
    # ----------------------------------------------------------------------------------------------------------------
    def _initialize_action_space(self):
        dim = 4 + (len(self.config.platform.arm.joints) if self.config.platform.arm else 0)
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(dim,), dtype=np.float32)

    def set_drive_property(self):
        # Effort-driven joints: no PhysX drive, no joint friction. Forces come only from `before_simulation_step`.
        for joint in self.joints:
            joint.set_drive_properties(0.0, 0.0, force_limit=0.0)
            joint.set_friction(0.0)

    def reset(self):
        """Called by ManiSkill after `_initialize_episode`; heading sync for reset envs happens at the next step."""
        self._command.zero_()

    def begin_reset(self, mask: torch.Tensor) -> None:
        """Unloaded controller, zero integrators, working arm pose and no contact mode for the envs in `mask`."""
        self.memory.reset(mask, self.params)
        self._needs_yaw_sync |= mask
        self._yaw_sync_pending = True
        self.contact_mode &= ~mask
        if self.arm is not None:
            working = torch.tensor(self.config.platform.arm.working_pose_rad, device=self.device)
            self.arm_target[mask] = working

    def arm_action(self, q_arm: torch.Tensor) -> torch.Tensor:
        """The normalized arm action that commands joint targets `q_arm` (inverse of the mapping in `set_action`)."""
        return normalized_arm_action(q_arm, self.arm.lower, self.arm.upper)

    def set_action(self, action: torch.Tensor):
        action = self._preprocess_action(action)
        action = torch.clamp(action, -1.0, 1.0)
        torch.mul(action if self.arm is None else action[:, :4], self._command_scale, out=self._command)
        if self.arm is not None:
            self._set_arm_target(action[:, 4:7])

    def set_action_values(self, values: Sequence[float]) -> None:
        """`set_action` for the one env of physx_cpu, from its action as host floats (`AerialAgent.set_action`): the
        same float32 numbers without a tensor op for the flight command. A float32 action times a float32 bound is
        exact in double precision, so rounding it once into the float32 buffer gives torch's float32 product."""
        self._command_row[:] = [min(max(v, -1.0), 1.0) * s for v, s in zip(values, self._command_scale_values)]
        if self.arm is not None:
            self._set_arm_target(torch.tensor([values[4:7]], dtype=torch.float32, device=self.device).clamp(-1.0, 1.0))

    def _set_arm_target(self, clipped: torch.Tensor) -> None:
        self.arm_target = self.arm.lower + 0.5 * (clipped + 1.0) * (self.arm.upper - self.arm.lower)

    def joint_state(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The whole articulation's joint positions and velocities `(N, J)` (on physx_cpu straight from PhysX)."""
        cpu = self._cpu_articulation
        if cpu is not None:
            # the batch axis added on the numpy side: half the cost of a torch view (a 240 Hz read)
            return torch.from_numpy(cpu.get_qpos()[None]), torch.from_numpy(cpu.get_qvel()[None])
        return self.articulation.get_qpos(), self.articulation.get_qvel()

    def before_simulation_step(self):
        # No host synchronization in here (no .any(), .item() or branch on a tensor): on physx_cuda it would stall
        # the whole batch at every physics step. tests/envs/control/test_fused.py checks it.
        px = self.scene.px
        if self.scene.gpu_sim_enabled:  # ManiSkill fetches once per control step; the loop needs every physics step
            px.gpu_fetch_articulation_qpos()
            px.gpu_fetch_articulation_qvel()
        if self.conditioned is not None:  # an evaluation condition: its own eager step, apart from the fused one
            self._conditioned_step()
            if self.scene.gpu_sim_enabled:
                px.gpu_apply_articulation_qf()
            return
        cpu = self._cpu_articulation
        lean = self.telemetry is None and self.leading_joints
        if lean and cpu is not None:
            joints = self._loop_joints
            if joints is None:
                q, qd = (t.clone() for t in self.joint_state())
                joints = self._loop_joints = (q, qd, q.numpy()[0], qd.numpy()[0])
            q_all, qd_all, q_np, qd_np = joints
            q_np[:] = cpu.get_qpos()
            qd_np[:] = cpu.get_qvel()
        else:
            q_all, qd_all = self.joint_state()
        m = self.memory
        tensors = [q_all, qd_all, self.velocity_cmd, self.yaw_rate_cmd, m.xi, m.yaw_des, m.mass_hat, m.k_R, m.k_w,
                   self._needs_yaw_sync]
        if self.arm is not None:
            tensors += [self.arm_target, self.contact_mode]
        if lean:
            # the lean step: whole joint vectors in, every joint's effort out (the fingers' zero), nothing else
            loop = self._efforts_loop
            if loop is None or loop[0] is not self.step_fn:  # the first call builds or loads the package
                loop = self._efforts_loop = (self.step_fn, self.step_fn.efforts_loop(tensors))
            efforts, m.xi, m.yaw_des = loop[1](tensors)
            if self._yaw_sync_pending:
                self._needs_yaw_sync.zero_()
                self._yaw_sync_pending = False
            if cpu is not None:
                qf = self._qf_view
                if qf is None or qf[0] is not efforts:  # the loop's own buffer comes back each call: one view of it
                    qf = self._qf_view = (efforts, efforts.numpy()[0])
                cpu.set_qf(qf[1])
            else:
                self.articulation.set_qf(efforts)
        else:
            q, qd = q_all[:, self._joints], qd_all[:, self._joints]
            result = self.step_fn(q, qd, *tensors[2:])
            m.xi, m.yaw_des = result.xi, result.yaw_des
            self._needs_yaw_sync.zero_()
            self._yaw_sync_pending = False
            if self._qf is None or self._qf.shape != q_all.shape:
                self._qf = torch.zeros_like(q_all)  # the finger joints are PhysX-driven and take no effort from here
            self._qf[:, self._joints] = result.efforts
            self.articulation.set_qf(self._qf)
            self.last_result = (result, q, qd)
            if self.telemetry is not None:
                out, state = self.last_output, self.last_state
                self.telemetry.append(
                    {
                        "position": state.position.clone(),
                        "velocity": state.velocity.clone(),
                        "tilt_cos": state.rotation[:, 2, 2].clone(),
                        "yaw_rate": (state.rotation[:, 2, :] * state.angular_velocity_body).sum(-1),
                        "xi": self.memory.xi.clone(),
                        "rotor_thrusts": out.rotor_thrusts.clone(),
                        "mass_hat": self.memory.mass_hat.clone(),
                    }
                )
        if self.scene.gpu_sim_enabled:
            px.gpu_apply_articulation_qf()

    def _conditioned_step(self) -> None:
        """The physics step under a physical condition (`conditions.physics`): the same laws and memory, the
        condition's models between the rotor commands and the wrench; efforts written for the controller's joints."""
        q_all, qd_all = self.joint_state()
        m = self.memory
        inputs = [self.velocity_cmd, self.yaw_rate_cmd, m.xi, m.yaw_des, m.mass_hat, m.k_R, m.k_w, self._needs_yaw_sync]
        if self.arm is not None:
            inputs += [self.arm_target, self.contact_mode]
        efforts, m.xi, m.yaw_des = self.conditioned.efforts(
            self.step_fn, q_all[:, self._joints], qd_all[:, self._joints], inputs)
        self._needs_yaw_sync.zero_()
        self._yaw_sync_pending = False
        qf = torch.zeros_like(q_all)  # the finger joints are PhysX-driven and take no effort from here
        qf[:, self._joints] = efforts
        if self._cpu_articulation is not None:
            self._cpu_articulation.set_qf(qf.numpy()[0])
        else:
            self.articulation.set_qf(qf)

    def rotor_saturated(self) -> torch.Tensor:
        """`(N,)` whether the rotor thrusts the controller would command now (this state, command and memory) are
        clipped: a rotor at zero or at its maximum (under a reduced-headroom condition, the reduced maximum). A side
        computation on copies, sampled once per control step for the statistics (`rotor_statistics`): it changes
        nothing the simulation does."""
        q_all, qd_all = self.joint_state()
        m = self.memory
        extra = (self.arm_target, self.contact_mode) if self.arm is not None else ()
        result = self.step_fn.eager(q_all[:, self._joints], qd_all[:, self._joints], self.velocity_cmd.clone(),
                                    self.yaw_rate_cmd.clone(), m.xi.clone(), m.yaw_des.clone(), m.mass_hat, m.k_R,
                                    m.k_w, torch.zeros_like(self._needs_yaw_sync), *extra)
        headroom = self.conditioned.condition.headroom if self.conditioned is not None else None
        top = self.params.max_rotor_thrust * (headroom.thrust_scale if headroom is not None else 1.0)
        thrusts = result.rotor_thrusts
        return ((thrusts >= top * (1.0 - SATURATION_TOLERANCE)) | (thrusts <= SATURATION_TOLERANCE * top)).any(-1)

    @property
    def last_output(self) -> FlightOutput | None:
        return None if self.last_result is None else self.last_result[0].output()

    @property
    def last_state(self) -> AirframeState | None:
        return None if self.last_result is None else self.last_result[0].state(*self.last_result[1:])

    def get_state(self) -> dict:
        # copies, both ways: the 240 Hz loop updates the memory's xi and yaw_des in place (`efforts_loop`)
        m = self.memory
        return {"xi": m.xi.clone(), "yaw_des": m.yaw_des[:, None].clone(), "mass_hat": m.mass_hat[:, None].clone()}

    def set_state(self, state: dict):
        if state:
            self.memory = replace(self.memory, xi=state["xi"].clone(), yaw_des=state["yaw_des"][:, 0].clone(),
                                  mass_hat=state["mass_hat"][:, 0].clone())
            self._needs_yaw_sync[:] = False

    # ----------------------------------------------------------------------------------------------------------------
    # Signals from the task (once per control step)
    # ----------------------------------------------------------------------------------------------------------------
    def update_payload(self, is_grasped: torch.Tensor, is_set_down: torch.Tensor, object_mass: torch.Tensor) -> None:
        """Payload-aware switches for this control step (no-op on m_hat and gains for the nominal controller)."""
        self.memory = self.step_fn.payload_update(self.memory, is_grasped, is_set_down, object_mass, self.mode)

    def set_contact_mode(self, pinched: torch.Tensor) -> None:
        """Arm platform: limp shoulder and no arm feedforward while pinched; on release the integrator resets."""
        released = self.contact_mode & ~pinched
        if released.any():
            self.memory.xi = torch.where(released[:, None], torch.zeros_like(self.memory.xi), self.memory.xi)
        self.contact_mode = pinched.clone()


@dataclass
class AerialBodyControllerConfig(ControllerConfig):
    platform: PlatformSpec = None
    mode: str = ControllerMode.PAYLOAD_AWARE.value
    joint_names: list[str] = field(default_factory=list)
    controller_cls = AerialBodyController
