"""Sensor noise and delay on the airframe state a policy reads (its own motion: the state estimate).

The estimate of control step t is the true airframe state of step t - k (k control steps of delay; the first state of
the episode until then) with white Gaussian noise of step t: position + sigma_p n, orientation turned by a body-frame
rotation exp(hat(sigma_theta n)), velocity + sigma_v n, body angular velocity + sigma_omega n. It replaces the
airframe's fields of the proprioceptive state (position, orientation, velocity, angular velocity) and of the task state
(velocity, angular velocity, gravity in the body frame, altitude); the fingers, the arm joints and the task state's
goal vectors stay exact (the goal vectors stand for what the policy perceives of its goal, not its own estimate).
The privileged expert reads the simulator directly and is not affected.

A state is one flat `(N, 18)` row: position 3, rotation matrix 9 (row-major), velocity 3, body angular velocity 3.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ..control.so3 import hat
from ..control.virtual_joints import AirframeState

STATE_WIDTH = 18
NOISE_WIDTH = 12  # position, rotation vector, velocity, angular velocity


@dataclass(frozen=True)
class SensorNoise:
    position_sigma_m: float
    attitude_sigma_rad: float
    velocity_sigma_mps: float
    angular_velocity_sigma_rps: float


@dataclass(frozen=True)
class SensorDelay:
    steps: int  # control steps

    def __post_init__(self):
        if not (isinstance(self.steps, int) and self.steps >= 0):
            raise ValueError("a sensor delay is a whole number of control steps >= 0")


def flat_state(position: torch.Tensor, rotation: torch.Tensor, velocity: torch.Tensor,
               angular_velocity_body: torch.Tensor) -> torch.Tensor:
    """The airframe state as one `(N, 18)` row (layout above)."""
    return torch.cat([position, rotation.reshape(-1, 9), velocity, angular_velocity_body], dim=-1)


def airframe_state(flat: torch.Tensor) -> AirframeState:
    """The `(N, 18)` row back as an `AirframeState`."""
    return AirframeState(flat[:, :3], flat[:, 12:15], flat[:, 3:12].reshape(-1, 3, 3), flat[:, 15:18])


def proprio_with_estimate(proprio: torch.Tensor, estimate: AirframeState) -> torch.Tensor:
    """The proprioceptive state (`observations.STATE_FIELDS`) with its airframe fields (position, orientation 6-D,
    velocity, angular velocity: the first 15 values) from `estimate`; fingers and arm joints as they are."""
    orientation_6d = estimate.rotation[:, :, :2].transpose(1, 2).reshape(-1, 6)
    parts = [estimate.position, orientation_6d, estimate.velocity, estimate.angular_velocity_body, proprio[:, 15:]]
    return torch.cat(parts, dim=-1).to(proprio.dtype)


def small_rotation(rotation_vector: torch.Tensor) -> torch.Tensor:
    """exp(hat(r)) for rotation vectors `(N, 3)` (Rodrigues' formula; the identity at r = 0)."""
    angle = torch.linalg.norm(rotation_vector, dim=-1)[:, None, None]
    K = hat(rotation_vector)
    # sin(a)/a and (1 - cos a)/a^2 by their series near 0: exact to float32 for the noise's small angles
    a2 = angle * angle
    sin_term = torch.where(angle > 1e-4, torch.sin(angle) / angle.clamp_min(1e-12), 1.0 - a2 / 6.0)
    cos_term = torch.where(angle > 1e-4, (1.0 - torch.cos(angle)) / a2.clamp_min(1e-24), 0.5 - a2 / 24.0)
    eye = torch.eye(3, dtype=rotation_vector.dtype, device=rotation_vector.device).expand_as(K)
    return eye + sin_term * K + cos_term * (K @ K)


def add_noise(state: torch.Tensor, white: torch.Tensor, model: SensorNoise) -> torch.Tensor:
    """`state` `(N, 18)` with the noise of standard normal `white` `(N, 12)` scaled by the model's sigmas."""
    position = state[:, :3] + model.position_sigma_m * white[:, :3]
    rotation = state[:, 3:12].reshape(-1, 3, 3) @ small_rotation(model.attitude_sigma_rad * white[:, 3:6])
    velocity = state[:, 12:15] + model.velocity_sigma_mps * white[:, 6:9]
    omega = state[:, 15:18] + model.angular_velocity_sigma_rps * white[:, 9:12]
    return flat_state(position, rotation, velocity, omega)


class DelayLine:
    """k control steps of delay for `(N, D)` rows, indexed by each env's step of its episode: at step e a row is
    written to slot e mod (k + 1) and the row of step max(e - k, 0) read back. At step 0 every slot takes the first
    row, so an episode's first k steps read its first state. Writing the same step's row again is harmless, so the
    observation and the task state of one step may both ask."""

    def __init__(self, num_envs: int, width: int, delay_steps: int, device: torch.device | str):
        self.delay = delay_steps
        self.rows = torch.zeros(num_envs, delay_steps + 1, width, device=device)
        self._envs = torch.arange(num_envs, device=device)

    def __call__(self, row: torch.Tensor, step: torch.Tensor) -> torch.Tensor:
        """Write `row` `(N, D)` for the envs' current `step` `(N,)` and return the rows `delay` steps old."""
        if self.delay == 0:
            return row
        slots = self.delay + 1
        fresh = (step == 0)[:, None, None]
        self.rows = torch.where(fresh, row[:, None].expand_as(self.rows), self.rows)
        self.rows[self._envs, step % slots] = row
        return self.rows[self._envs, (step - self.delay).clamp_min(0) % slots]
