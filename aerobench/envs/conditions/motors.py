"""Rotor response: first-order motor lag and reduced thrust headroom, between the controller's commanded rotor thrusts
and the thrusts the rotors produce.

- Lag: each rotor's thrust follows its command as a first-order system, T' = T + (1 - exp(-dt / tau)) (T_cmd - T)
  (exact for a command held over the physics step), with tau_up while spinning up and tau_down while spinning down,
  as the PX4 Gazebo motor model (`gazebo_motor_model`, the X500's `timeConstantUp` / `timeConstantDown`) does.
- Headroom: the rotors saturate at `thrust_scale` times the platform's maximum thrust (a sagging battery: thrust
  ~ voltage^2); the controller still allocates against the nominal maximum, as it does not know.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class MotorLag:
    time_constant_up_s: float
    time_constant_down_s: float

    def __post_init__(self):
        if self.time_constant_up_s < 0 or self.time_constant_down_s < 0:
            raise ValueError("motor time constants are >= 0 s")


@dataclass(frozen=True)
class ThrustHeadroom:
    thrust_scale: float  # the rotors' real maximum over the platform's nominal `max_thrust_n`

    def __post_init__(self):
        if not 0 < self.thrust_scale <= 1:
            raise ValueError("thrust_scale is in (0, 1]")


def lag_gain(dt: float, time_constant_s: float) -> float:
    """1 - exp(-dt / tau): the share of the gap to the command a first-order rotor closes in `dt` (1 without lag)."""
    return 1.0 - math.exp(-dt / time_constant_s) if time_constant_s > 0 else 1.0


def first_order_lag(thrust: torch.Tensor, command: torch.Tensor, gain_up: float, gain_down: float) -> torch.Tensor:
    """The rotors' thrusts `(N, 4)` one physics step later, from `thrust` towards `command` (`lag_gain` per way)."""
    gain = torch.where(command > thrust, gain_up, gain_down)
    return thrust + gain * (command - thrust)


def saturate(command: torch.Tensor, max_thrust_n: float, thrust_scale: float) -> torch.Tensor:
    """The commanded rotor thrusts, clipped at what the rotors can give: `thrust_scale * max_thrust_n`."""
    return command.clamp(0.0, thrust_scale * max_thrust_n)
