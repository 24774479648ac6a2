"""The physics step under a physical condition: the controller's laws as they are, then the condition between the
commanded rotor thrusts and the wrench the airframe feels.

With no condition the body controller runs the fused, compiled step (`control.fused`) and nothing here is called.
With one it runs this instead, every physics step, eagerly (about 10 ms more per control step on a 2-core CPU,
docs/robustness.md: acceptable for evaluation; the fused path never pays it). The same laws
(`control.fused.physics_step`: flight cascade, allocation clipped at the nominal f_max, arm servos and feedforward)
give the commanded rotor thrusts; then, per rotor:
  thrust = lag(saturate(command, headroom)) x ground ratio x ceiling ratio        (motors.py, proximity.py)
and the airframe's wrench about O is the rotors' (`rotor_wrench_world` of those thrusts) + wind drag (wind.py) +
wall suction at each hub (proximity.py), turned into joint efforts by the same Q = J^T W.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch

from ..control.flight import rotor_wrench_world
from ..control.fused import FusedPhysicsStep, physics_step
from ..control.virtual_joints import NUM_VIRTUAL_JOINTS, joint_efforts_from_wrench
from ..platforms import PHYSICS_DT, PlatformSpec
from .motors import first_order_lag, lag_gain, saturate
from .proximity import ceiling_effect_ratio, ground_effect_ratio, rotor_surroundings, wall_suction
from .registry import ConditionSet
from .wind import airframe_drag


class ConditionedPhysics:
    """The state a physical condition carries between physics steps (rotor thrusts under lag, the wind the runtime
    sets each control step) and the step itself (`efforts`). `surfaces()` gives the env's packed static boxes
    `(N, B, 8)` or None (a floor plane at z = 0 alone)."""

    def __init__(self, condition: ConditionSet, platform: PlatformSpec, num_envs: int, device: torch.device | str,
                 surfaces: Callable[[], torch.Tensor | None]):
        self.condition, self.platform, self.surfaces = condition, platform, surfaces
        rotors = platform.rotors
        self.radius_m, self.max_thrust_n, self.mass_kg = rotors.disk_radius_m, rotors.max_thrust_n, platform.total_mass_kg
        self.rotor_height_m = rotors.height_m
        self.hubs_body = torch.tensor([(x, y, rotors.height_m) for x, y in rotors.positions_xy], device=device)
        lag = condition.motor_lag
        self.gains = (lag_gain(PHYSICS_DT, lag.time_constant_up_s), lag_gain(PHYSICS_DT, lag.time_constant_down_s)) \
            if lag is not None else None
        self.thrusts = torch.zeros(num_envs, len(rotors.positions_xy), device=device)  # the lagged rotors' thrusts
        self.fresh = torch.ones(num_envs, dtype=torch.bool, device=device)  # a new episode: rotors start at command
        self.wind = torch.zeros(num_envs, 3, device=device)  # world wind velocity, set per control step (runtime)
        self.last_thrusts: torch.Tensor | None = None  # the rotors' thrusts of the last step (diagnostics, tests)

    def reset(self, mask: torch.Tensor) -> None:
        """New episodes in `mask` `(N,)`: their rotors start at their first command."""
        self.fresh = self.fresh | mask

    def surroundings(self, rotation: torch.Tensor, position: torch.Tensor) -> tuple[torch.Tensor, ...] | None:
        """The hubs `(N, 4, 3)` and `proximity.rotor_surroundings` of them, or None without a surface model."""
        c = self.condition
        if c.ground is None and c.ceiling is None and c.wall is None:
            return None
        hubs = position[:, None] + (rotation[:, None] @ self.hubs_body[None, :, :, None])[..., 0]
        return hubs, *rotor_surroundings(hubs, self.surfaces())

    def rotor_thrusts(self, command: torch.Tensor, around: tuple[torch.Tensor, ...] | None) -> torch.Tensor:
        """The thrusts `(N, 4)` the rotors produce for the controller's `command` `(N, 4)`: the motor response, then
        the surfaces below and above each hub (`around`: `surroundings`)."""
        c = self.condition
        thrusts = command
        if c.headroom is not None:
            thrusts = saturate(thrusts, self.max_thrust_n, c.headroom.thrust_scale)
        if self.gains is not None:
            lagged = first_order_lag(self.thrusts, thrusts, *self.gains)
            thrusts = torch.where(self.fresh[:, None], thrusts, lagged)
            self.thrusts, self.fresh = thrusts, torch.zeros_like(self.fresh)
        if c.ground is not None:
            thrusts = thrusts * ground_effect_ratio(around[1], self.radius_m, c.ground)
        if c.ceiling is not None:
            thrusts = thrusts * ceiling_effect_ratio(around[2], self.radius_m, c.ceiling)
        return thrusts

    def external_wrench(self, thrusts: torch.Tensor, rotation: torch.Tensor, position: torch.Tensor,
                        velocity: torch.Tensor, around: tuple[torch.Tensor, ...] | None
                        ) -> tuple[torch.Tensor, torch.Tensor] | None:
        """Force and torque about O (world, `(N, 3)` each) that are not the rotors' thrust: wind drag, wall suction;
        None without them."""
        c = self.condition
        if c.wind is None and c.wall is None:
            return None
        force, torque = torch.zeros_like(velocity), torch.zeros_like(velocity)
        if c.wind is not None:
            drag, drag_torque = airframe_drag(velocity, self.wind, rotation, self.mass_kg, self.rotor_height_m, c.wind)
            force, torque = force + drag, torque + drag_torque
        if c.wall is not None:
            hubs, _, _, distance, direction = around
            pull = (wall_suction(distance, self.radius_m, c.wall) * thrusts)[..., None] * direction  # (N, 4, 3)
            force = force + pull.sum(1)
            torque = torque + torch.linalg.cross(hubs - position[:, None], pull).sum(1)
        return force, torque

    def efforts(self, step: FusedPhysicsStep, q: torch.Tensor, qd: torch.Tensor,
                inputs: Sequence[torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The controller joints' efforts `(N, 6 [+ arm])`, the new integral xi and desired heading, for the
        controller's joint positions and velocities `q`, `qd` and the rest of its inputs as `FusedPhysicsStep` takes
        them (commands, memory, yaw-sync flags [, arm target, contact mode])."""
        result = physics_step(q, qd, *inputs[:8], step.params, step.arm, *inputs[8:])
        rotation, position, velocity = result.rotation, q[:, :3], qd[:, :3]
        around = self.surroundings(rotation, position)
        thrusts = self.rotor_thrusts(result.rotor_thrusts, around)
        self.last_thrusts = thrusts
        force, torque = rotor_wrench_world(thrusts, rotation, step.params.allocation)
        external = self.external_wrench(thrusts, rotation, position, velocity, around)
        if external is not None:
            force, torque = force + external[0], torque + external[1]
        efforts = joint_efforts_from_wrench(q[:, :NUM_VIRTUAL_JOINTS], force, torque)
        if result.efforts.shape[1] > NUM_VIRTUAL_JOINTS:  # the arm's servo torques, as the laws computed them
            efforts = torch.cat([efforts, result.efforts[:, NUM_VIRTUAL_JOINTS:]], dim=-1)
        return efforts, result.xi, result.yaw_des
