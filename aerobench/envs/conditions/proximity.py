"""Surfaces near the rotors: ground effect, ceiling effect and the near-wall effect, from the scene's boxes.

What the models see (`rotor_surroundings`): each rotor's hub as a point (the rotor plane, `RotorSpec.height_m` above
the airframe centre), the env's static boxes (`geometry.pack_boxes`: floors, walls, ceiling, furniture, vehicles,
each an upright box turned about z) and a floor plane at z = 0. Below / above: the vertical distance to the nearest
box top under / box bottom over the hub (a box whose footprint holds the hub's x, y), or to the floor plane. Beside:
the horizontal distance to the nearest box face whose height span holds the hub, and the direction to it. The moving
parts of the fridge and the drawer, the target object and the drone's own arm are not seen. Distances are vertical
(horizontal) whatever the tilt: the models are for a level rotor, and the flight envelope keeps tilts small.

Models (constants and sources in `constants.py`):
- ground effect, Cheeseman & Bennett (1955): T_IGE / T_OGE = 1 / (1 - (R / 4z)^2), z held at >= z_min;
- ceiling effect, the form of Sanchez-Cuevas, Heredia & Ollero (2017): 1 / (1 - (1/k1) (R / (d + k2))^2);
- near-wall effect: a suction force c T (R / d)^2 on the rotor towards the wall, d held at >= d_min (aerobench's
  form after Yang et al. 2025's measurements; see `constants.py`).
The ground and ceiling ratios multiply the rotor's thrust (at the rotor speed its response gives: the rotor is not
re-trimmed for them; the controller's feedback does that); the yaw drag torque follows the thrust, a simplification.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .constants import (
    CEILING_K1,
    CEILING_K2_RADII,
    GROUND_EFFECT_MIN_HEIGHT_RADII,
    SURFACE_FAR_M,
    WALL_MIN_DISTANCE_RADII,
    WALL_SUCTION_COEFFICIENT,
)


@dataclass(frozen=True)
class GroundEffect:
    min_height_radii: float = GROUND_EFFECT_MIN_HEIGHT_RADII


@dataclass(frozen=True)
class CeilingEffect:
    k1: float = CEILING_K1
    k2_radii: float = CEILING_K2_RADII


@dataclass(frozen=True)
class WallEffect:
    coefficient: float = WALL_SUCTION_COEFFICIENT
    min_distance_radii: float = WALL_MIN_DISTANCE_RADII


def ground_effect_ratio(height: torch.Tensor, radius_m: float, model: GroundEffect) -> torch.Tensor:
    """T_IGE / T_OGE = 1 / (1 - (R / 4z)^2) (Cheeseman & Bennett 1955), z the rotor's height above the surface below,
    held at >= min_height_radii R."""
    z = height.clamp_min(model.min_height_radii * radius_m)
    return 1.0 / (1.0 - (radius_m / (4.0 * z)) ** 2)


def ceiling_effect_ratio(distance: torch.Tensor, radius_m: float, model: CeilingEffect) -> torch.Tensor:
    """T_ICE / T_OCE = 1 / (1 - (1/k1) (R / (d + k2 R))^2) (the form of Sanchez-Cuevas et al. 2017), d the rotor's
    distance to the surface above (>= 0)."""
    d = distance.clamp_min(0.0)
    return 1.0 / (1.0 - (radius_m / (d + model.k2_radii * radius_m)) ** 2 / model.k1)


def wall_suction(distance: torch.Tensor, radius_m: float, model: WallEffect) -> torch.Tensor:
    """The suction force towards the wall per newton of rotor thrust: c (R / d)^2, d held at >= d_min."""
    d = distance.clamp_min(model.min_distance_radii * radius_m)
    return model.coefficient * (radius_m / d) ** 2


def rotor_surroundings(
    hubs: torch.Tensor, boxes: torch.Tensor | None, floor_z: float = 0.0
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """For rotor hubs `(N, P, 3)` among packed boxes `(N, B, 8)` (centre, half sizes, yaw, valid; None: the floor
    plane alone): the distance to the surface below `(N, P)`, to the surface above `(N, P)`, to the nearest wall face
    beside `(N, P)` (horizontal), and the unit direction to that face `(N, P, 3)` (zero where there is none).
    `SURFACE_FAR_M` where nothing is there."""
    far = torch.full(hubs.shape[:2], SURFACE_FAR_M, dtype=hubs.dtype, device=hubs.device)
    floor = torch.where(hubs[..., 2] >= floor_z, hubs[..., 2] - floor_z, far)
    if boxes is None or boxes.shape[1] == 0:
        return floor, far, far.clone(), torch.zeros_like(hubs)
    b = boxes[:, None]  # (N, 1, B, 8) against (N, P, 1) coordinates
    c, s = torch.cos(b[..., 6]), torch.sin(b[..., 6])
    dx, dy = hubs[..., 0, None] - b[..., 0], hubs[..., 1, None] - b[..., 1]
    lx, ly = c * dx + s * dy, c * dy - s * dx  # the hub in each box's frame
    hx, hy = b[..., 3], b[..., 4]
    valid = b[..., 7] > 0.5
    over = valid & (lx.abs() <= hx) & (ly.abs() <= hy)
    z = hubs[..., 2, None]
    top, bottom = b[..., 2] + b[..., 5], b[..., 2] - b[..., 5]
    below = torch.where(over & (z >= top), z - top, SURFACE_FAR_M).amin(-1)
    above = torch.where(over & (z <= bottom), bottom - z, SURFACE_FAR_M).amin(-1)
    # beside: the nearest point of the box's footprint, for boxes whose height span holds the hub
    ex, ey = lx.clamp(-hx, hx) - lx, ly.clamp(-hy, hy) - ly  # hub -> nearest footprint point, box frame
    beside = valid & ~over & (z > bottom) & (z < top)
    horizontal = torch.where(beside, torch.sqrt(ex * ex + ey * ey), SURFACE_FAR_M)
    wall, nearest = horizontal.min(-1)
    ex, ey = ex.gather(-1, nearest[..., None])[..., 0], ey.gather(-1, nearest[..., None])[..., 0]
    c, s = c.expand_as(lx).gather(-1, nearest[..., None])[..., 0], s.expand_as(lx).gather(-1, nearest[..., None])[..., 0]
    norm = wall.clamp_min(1e-9)
    direction = torch.stack([(c * ex - s * ey) / norm, (s * ex + c * ey) / norm, torch.zeros_like(ex)], dim=-1)
    direction = torch.where((wall < SURFACE_FAR_M)[..., None], direction, torch.zeros_like(direction))
    return torch.minimum(below, floor), above, wall, direction
