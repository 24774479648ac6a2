"""Cascaded velocity-attitude flight controller and rotor allocation (spec Sec. 3.2, "Cascaded flight control").

Each law is one function, named after the spec's equation it implements (see docs/control.md); `flight_step`
chains them for one physics step. All tensors are `(N, ...)`; gains that the payload switches change per env
(m_hat, k_R, k_w) live in `FlightMemory`, fixed parameters in `FlightParams`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import torch

from ..platforms import GRAVITY, PHYSICS_DT, FlightGains, PlatformSpec, RotorSpec
from .so3 import vee
from .virtual_joints import AirframeState


@dataclass(frozen=True)
class FlightParams:
    """Fixed per-platform controller parameters, as tensors on the simulation device."""

    mass: float  # m0
    gains: FlightGains
    allocation: torch.Tensor  # A, (4, 4): rotor thrusts -> [T, tau_x, tau_y, tau_z] in the body frame
    allocation_inverse: torch.Tensor
    max_rotor_thrust: float
    dt: float = PHYSICS_DT
    gravity: float = GRAVITY

    @classmethod
    def from_platform(cls, platform: PlatformSpec, device: torch.device | str = "cpu") -> FlightParams:
        A = allocation_matrix(platform.rotors, device=device)
        return cls(
            mass=platform.total_mass_kg,
            gains=platform.gains,
            allocation=A,
            allocation_inverse=torch.linalg.inv(A),
            max_rotor_thrust=platform.rotors.max_thrust_n,
        )


@dataclass
class FlightMemory:
    """Controller state carried from one physics step to the next, one row per env."""

    xi: torch.Tensor  # (N, 3) velocity-error integral, m/s^2
    yaw_des: torch.Tensor  # (N,) desired heading, rad
    mass_hat: torch.Tensor  # (N,) feedforward mass, kg
    k_R: torch.Tensor  # (N,) attitude gains
    k_w: torch.Tensor
    grasp_steps: torch.Tensor  # (N,) consecutive grasped control steps (payload switch)
    payload_active: torch.Tensor  # (N,) bool: object mass added to the feedforward
    supported: torch.Tensor  # (N,) bool: the placement support carried the object at the last control step

    @classmethod
    def initial(cls, num_envs: int, params: FlightParams, device: torch.device | str = "cpu") -> FlightMemory:
        def full(value: float) -> torch.Tensor:
            return torch.full((num_envs,), value, dtype=torch.float32, device=device)

        return cls(
            xi=torch.zeros(num_envs, 3, device=device),
            yaw_des=full(0.0),
            mass_hat=full(params.mass),
            k_R=full(params.gains.k_R),
            k_w=full(params.gains.k_w),
            grasp_steps=torch.zeros(num_envs, dtype=torch.long, device=device),
            payload_active=torch.zeros(num_envs, dtype=torch.bool, device=device),
            supported=torch.zeros(num_envs, dtype=torch.bool, device=device),
        )

    def reset(self, mask: torch.Tensor, params: FlightParams, yaw: torch.Tensor | None = None) -> None:
        """Back to the unloaded controller for the envs in `mask` (in place; the memory is per-env bookkeeping)."""
        fresh = FlightMemory.initial(int(mask.shape[0]), params, mask.device)
        if yaw is not None:
            fresh.yaw_des = yaw.to(fresh.yaw_des.dtype)
        for name in self.__dataclass_fields__:
            current, new = getattr(self, name), getattr(fresh, name)
            m = mask.view(-1, *([1] * (current.dim() - 1)))
            setattr(self, name, torch.where(m, new, current))


@dataclass
class FlightOutput:
    """Everything one controller step computes, for the simulator and for telemetry."""

    rotor_thrusts: torch.Tensor  # (N, 4) N, clipped to [0, f_max]
    force_world: torch.Tensor  # (N, 3) rotor force in the world frame
    torque_world: torch.Tensor  # (N, 3) rotor torque about the airframe centre O, world frame
    force_des: torch.Tensor  # (N, 3) f_des
    rotation_des: torch.Tensor  # (N, 3, 3) R_des
    thrust: torch.Tensor  # (N,) T before allocation
    torque_body_cmd: torch.Tensor  # (N, 3) tau before allocation
    velocity_error: torch.Tensor  # (N, 3) e_v


# --------------------------------------------------------------------------------------------------------------------
# The laws, one per spec equation
# --------------------------------------------------------------------------------------------------------------------
def velocity_error_and_integral(
    v_cmd: torch.Tensor, v: torch.Tensor, xi: torch.Tensor, dt: float, limit: float
) -> tuple[torch.Tensor, torch.Tensor]:
    """Eq. (vel): e_v = v_cmd - v, xi <- clip(xi + e_v dt, -limit, limit) per component."""
    e_v = v_cmd - v
    return e_v, torch.clamp(xi + e_v * dt, -limit, limit)


def clip_acceleration(a: torch.Tensor, horizontal_limit: float, vertical_limit: float) -> torch.Tensor:
    """clip_acc: +-horizontal_limit on x and y each, +-vertical_limit on z."""
    limit = a.new_tensor([horizontal_limit, horizontal_limit, vertical_limit])
    return torch.minimum(torch.maximum(a, -limit), limit)


def desired_force(
    mass_hat: torch.Tensor, e_v: torch.Tensor, xi: torch.Tensor, gains: FlightGains, gravity: float = GRAVITY
) -> torch.Tensor:
    """Eq. (force): f_des = m_hat (clip_acc(k_v e_v + xi) + g e_z)."""
    acc = clip_acceleration(gains.velocity_gain * e_v + xi, gains.horizontal_accel_limit, gains.vertical_accel_limit)
    acc[..., 2] += gravity
    return mass_hat[..., None] * acc


def integrate_yaw(yaw_des: torch.Tensor, yaw_rate_cmd: torch.Tensor, dt: float) -> torch.Tensor:
    """psi_des <- psi_des + psi_dot_cmd dt, wrapped to (-pi, pi]."""
    yaw = yaw_des + yaw_rate_cmd * dt
    return torch.atan2(torch.sin(yaw), torch.cos(yaw))


def desired_rotation(force_des: torch.Tensor, yaw_des: torch.Tensor) -> torch.Tensor:
    """R_des with body z along f_des and body x as close as possible to the heading psi_des."""
    b3 = force_des / torch.linalg.norm(force_des, dim=-1, keepdim=True).clamp_min(1e-9)
    heading = torch.stack([torch.cos(yaw_des), torch.sin(yaw_des), torch.zeros_like(yaw_des)], dim=-1)
    b2 = torch.linalg.cross(b3, heading)
    b2 = b2 / torch.linalg.norm(b2, dim=-1, keepdim=True).clamp_min(1e-9)
    b1 = torch.linalg.cross(b2, b3)
    return torch.stack([b1, b2, b3], dim=-1)


def attitude_error(R: torch.Tensor, R_des: torch.Tensor) -> torch.Tensor:
    """SO(3) attitude error e_R = 1/2 vee(R_des^T R - R^T R_des) (body frame); the second term is the first's transpose."""
    M = R_des.transpose(-1, -2) @ R
    return 0.5 * vee(M - M.transpose(-1, -2))


def desired_angular_velocity(R: torch.Tensor, yaw_rate_cmd: torch.Tensor) -> torch.Tensor:
    """omega_des in the body frame: the commanded world yaw rate; the desired tilt is treated as quasi-static."""
    return R[..., 2, :] * yaw_rate_cmd[..., None]  # R^T (psi_dot e_z)


def attitude_torque(
    R: torch.Tensor,
    R_des: torch.Tensor,
    omega_body: torch.Tensor,
    omega_des_body: torch.Tensor,
    k_R: torch.Tensor,
    k_w: torch.Tensor,
) -> torch.Tensor:
    """Eq. (att): tau = -k_R e_R(R, R_des) - k_w (omega - omega_des), body frame."""
    return -k_R[..., None] * attitude_error(R, R_des) - k_w[..., None] * (omega_body - omega_des_body)


def collective_thrust(force_des: torch.Tensor, R: torch.Tensor) -> torch.Tensor:
    """T = f_des^T R e_z: the desired force projected on the current body z axis."""
    return (force_des * R[..., :, 2]).sum(-1)


def allocation_matrix(rotors: RotorSpec, device: torch.device | str = "cpu") -> torch.Tensor:
    """A with [T, tau_x, tau_y, tau_z] = A f for the four rotor thrusts f (body frame, torques about O).

    A thrust f_i at (x_i, y_i) along body z gives a torque (y_i f_i, -x_i f_i); its drag torque is -s_i c_m f_i
    about z for spin direction s_i (+1 counter-clockwise).
    """
    rows = [[1.0] * 4, [], [], []]
    for (x, y), spin in zip(rotors.positions_xy, rotors.spin_directions):
        rows[1].append(y)
        rows[2].append(-x)
        rows[3].append(-spin * rotors.moment_coefficient_m)
    return torch.tensor(rows, dtype=torch.float32, device=device)


def allocate_rotor_thrusts(
    thrust: torch.Tensor, torque_body: torch.Tensor, allocation_inverse: torch.Tensor, max_rotor_thrust: float
) -> torch.Tensor:
    """f = clip(A^-1 [T; tau], 0, f_max) per rotor."""
    wrench = torch.cat([thrust[..., None], torque_body], dim=-1)
    return torch.clamp(wrench @ allocation_inverse.T, 0.0, max_rotor_thrust)


def rotor_wrench_world(
    rotor_thrusts: torch.Tensor, R: torch.Tensor, allocation: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The wrench the (clipped) rotors really produce, about O, rotated to the world frame."""
    body = rotor_thrusts @ allocation.T  # [T, tau_x, tau_y, tau_z]
    force_world = R[..., :, 2] * body[..., :1]  # thrust along body z
    torque_world = (R * body[..., None, 1:]).sum(-1)
    return force_world, torque_world


# --------------------------------------------------------------------------------------------------------------------
# One physics step
# --------------------------------------------------------------------------------------------------------------------
def flight_laws(
    state: AirframeState,
    velocity_cmd: torch.Tensor,
    yaw_rate_cmd: torch.Tensor,
    xi: torch.Tensor,
    yaw_des: torch.Tensor,
    mass_hat: torch.Tensor,
    k_R: torch.Tensor,
    k_w: torch.Tensor,
    params: FlightParams,
    torque_feedforward_body: torch.Tensor | None = None,
) -> tuple[FlightOutput, torch.Tensor, torch.Tensor]:
    """The whole cascade once on plain tensors: what to apply, and the new integral xi and desired heading.

    `torque_feedforward_body` is added to the attitude torque before the yaw limit and the allocation (the arm
    platform's arm weight-moment feedforward). No branch depends on a tensor value (see `fused`).
    """
    g = params.gains
    e_v, xi = velocity_error_and_integral(velocity_cmd, state.velocity, xi, params.dt, g.integral_limit)
    f_des = desired_force(mass_hat, e_v, xi, g, params.gravity)
    yaw_des = integrate_yaw(yaw_des, yaw_rate_cmd, params.dt)
    R_des = desired_rotation(f_des, yaw_des)
    R = state.rotation
    omega_des = desired_angular_velocity(R, yaw_rate_cmd)
    tau = attitude_torque(R, R_des, state.angular_velocity_body, omega_des, k_R, k_w)
    if torque_feedforward_body is not None:
        tau = tau + torque_feedforward_body
    if g.yaw_torque_limit != float("inf"):
        tau[..., 2].clamp_(-g.yaw_torque_limit, g.yaw_torque_limit)
    T = collective_thrust(f_des, R)
    rotor_thrusts = allocate_rotor_thrusts(T, tau, params.allocation_inverse, params.max_rotor_thrust)
    force_world, torque_world = rotor_wrench_world(rotor_thrusts, R, params.allocation)
    return FlightOutput(rotor_thrusts, force_world, torque_world, f_des, R_des, T, tau, e_v), xi, yaw_des


def flight_step(
    state: AirframeState,
    velocity_cmd: torch.Tensor,
    yaw_rate_cmd: torch.Tensor,
    memory: FlightMemory,
    params: FlightParams,
    torque_feedforward_body: torch.Tensor | None = None,
) -> tuple[FlightOutput, FlightMemory]:
    """`flight_laws` with the controller memory: returns what to apply and the updated memory."""
    out, xi, yaw_des = flight_laws(state, velocity_cmd, yaw_rate_cmd, memory.xi, memory.yaw_des, memory.mass_hat,
                                   memory.k_R, memory.k_w, params, torque_feedforward_body)
    return out, replace(memory, xi=xi, yaw_des=yaw_des)


__all__ = [
    "FlightMemory",
    "FlightOutput",
    "FlightParams",
    "allocate_rotor_thrusts",
    "allocation_matrix",
    "attitude_error",
    "attitude_torque",
    "clip_acceleration",
    "collective_thrust",
    "desired_angular_velocity",
    "desired_force",
    "desired_rotation",
    "flight_laws",
    "flight_step",
    "integrate_yaw",
    "rotor_wrench_world",
    "velocity_error_and_integral",
]
