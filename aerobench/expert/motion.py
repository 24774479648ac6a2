"""Batched motion primitives of the expert: track a tool-centre-point target and a heading with the velocity
interface, in normalized action units. Pure torch, `(N, ...)` tensors.
"""

from __future__ import annotations

import math

import torch

from ..envs.observations import wrap_angle
from ..envs.platforms import MAX_SPEED_MPS, MAX_YAW_RATE_RPS

POSITION_GAIN = 1.2  # 1/s: velocity command per metre of error (the flight tests' waypoint follower)
YAW_GAIN = 1.5  # 1/s
# A turn in place counts as done within this of its heading: the planner checked the route at that heading, and an
# arm 0.47 m long swept through a turn in flight hits what the route passes (a door).
TURN_TOLERANCE_RAD = math.radians(8.0)


def velocity_towards(error: torch.Tensor, max_speed: torch.Tensor | float, gain: float = POSITION_GAIN) -> torch.Tensor:
    """Proportional velocity `(N, 3)` towards `error` `(N, 3)`, its norm limited to `max_speed` (m/s)."""
    v = gain * error
    speed = torch.linalg.norm(v, dim=-1, keepdim=True).clamp_min(1e-9)
    limit = torch.as_tensor(max_speed, dtype=v.dtype, device=v.device)
    limit = limit[..., None] if limit.dim() == 1 else limit
    return v * torch.clamp(limit / speed, max=1.0)


def yaw_rate_towards(
    yaw: torch.Tensor, yaw_target: torch.Tensor, max_rate: float = MAX_YAW_RATE_RPS, gain: float = YAW_GAIN
) -> torch.Tensor:
    return torch.clamp(gain * wrap_angle(yaw_target - yaw), -max_rate, max_rate)


def flight_action(velocity: torch.Tensor, yaw_rate: torch.Tensor) -> torch.Tensor:
    """`(N, 4)` normalized flight action from m/s and rad/s."""
    return torch.cat([torch.clamp(velocity / MAX_SPEED_MPS, -1, 1), torch.clamp(yaw_rate / MAX_YAW_RATE_RPS, -1, 1)[:, None]], -1)

