"""Wind: a constant field plus Dryden turbulence, felt by the airframe as drag from its air-relative velocity.

Turbulence (MIL-F-8785C, 1980, Sec. 3.7.2, low-altitude form; also MIL-HDBK-1797, 1997): below 1000 ft the
length scales are L_w = h and L_u = L_v = h / (0.177 + 0.000823 h)^1.2 (feet), the intensities sigma_w = 0.1 W20
and sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4, with W20 the wind speed at 20 ft. The Dryden shaping
filter of the longitudinal component is first order, H_u(s) = sigma_u sqrt(2 L_u / (pi V)) / (1 + (L_u / V) s);
each component here is that first-order (Gauss-Markov) process with its own sigma and L, stepped exactly at the
control rate: x' = a x + sigma sqrt(1 - a^2) n, a = exp(-V dt / L), n ~ N(0, 1), which keeps the variance sigma^2
and the correlation time L / V (V the mean wind, Taylor's frozen-turbulence hypothesis for a hovering vehicle). The
lateral and vertical Dryden filters are second order; the first-order form is an approximation there.

Drag (`airframe_drag`): the rotor drag of Faessler, Franchi & Scaramuzza (IEEE RA-L 2018), F = -m R D R^T v_rel
with D = diag(d_xy, d_xy, d_z), acting in the rotor plane (so it also turns the airframe about its centre O, the
plane lying `height` above O), plus parasitic drag -1/2 rho C_D A |v_rel| v_rel at O. v_rel = v - w.

Onset: the wind (mean and turbulence) is scaled by min(t / onset, 1) over an episode's first `onset_s` seconds
(`constants.WIND_ONSET_S`), so an episode starts in calm air as the nominal one does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from .constants import (
    AIR_DENSITY_KGPM3,
    DRYDEN_LENGTH_BASE,
    DRYDEN_LENGTH_SLOPE_PER_FT,
    DRYDEN_SIGMA_W_PER_W20,
    FEET_PER_M,
    FLIGHT_ALTITUDE_M,
    PARASITIC_DRAG_AREA_M2,
    ROTOR_DRAG_XY_PER_S,
    ROTOR_DRAG_Z_PER_S,
    WIND_ONSET_S,
)


@dataclass(frozen=True)
class WindModel:
    """A wind condition: a mean wind of `mean_speed_mps` from a heading drawn per episode, plus Dryden turbulence of
    intensity `w20_mps` (0: steady wind) at `altitude_m`, and the airframe's drag coefficients."""

    mean_speed_mps: float
    w20_mps: float = 0.0
    altitude_m: float = FLIGHT_ALTITUDE_M
    rotor_drag_xy_per_s: float = ROTOR_DRAG_XY_PER_S
    rotor_drag_z_per_s: float = ROTOR_DRAG_Z_PER_S
    parasitic_drag_area_m2: float = PARASITIC_DRAG_AREA_M2
    air_density_kgpm3: float = AIR_DENSITY_KGPM3
    onset_s: float = WIND_ONSET_S

    def __post_init__(self):
        if self.w20_mps > 0 and self.mean_speed_mps <= 0:
            raise ValueError("Dryden turbulence is advected by the mean wind: give it a positive mean speed")

    def turbulence(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """(sigma_u, sigma_v, sigma_w) m/s and (L_u, L_v, L_w) m."""
        return dryden_low_altitude(self.altitude_m, self.w20_mps)

    def correlation(self, dt: float) -> tuple[float, float, float]:
        """a = exp(-V dt / L) per component for a control step `dt`."""
        _, lengths = self.turbulence()
        return tuple(math.exp(-self.mean_speed_mps * dt / length) for length in lengths)


def dryden_low_altitude(altitude_m: float, w20_mps: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The Dryden model's low-altitude intensities and length scales (MIL-F-8785C): ((sigma_u, sigma_v, sigma_w) in
    m/s, (L_u, L_v, L_w) in m) at height `altitude_m` for a wind of `w20_mps` at 20 ft."""
    h_ft = altitude_m * FEET_PER_M
    base = DRYDEN_LENGTH_BASE + DRYDEN_LENGTH_SLOPE_PER_FT * h_ft
    length_uv = h_ft / base**1.2 / FEET_PER_M
    sigma_w = DRYDEN_SIGMA_W_PER_W20 * w20_mps
    sigma_uv = sigma_w / base**0.4
    return (sigma_uv, sigma_uv, sigma_w), (length_uv, length_uv, altitude_m)


def gauss_markov_step(x: torch.Tensor, white: torch.Tensor, a: torch.Tensor, sigma: torch.Tensor) -> torch.Tensor:
    """One exact step of a first-order Gauss-Markov process with stationary std `sigma` and correlation `a`:
    x' = a x + sigma sqrt(1 - a^2) n (all broadcast; `white` standard normal)."""
    return a * x + sigma * torch.sqrt(1.0 - a * a) * white


def wind_world(mean_speed: float, heading: torch.Tensor, turbulence_uvw: torch.Tensor,
               strength: torch.Tensor | float = 1.0) -> torch.Tensor:
    """The wind velocity in the world frame `(N, 3)`: the mean wind blowing towards `heading` `(N,)` (rad, about +z)
    plus turbulence `(N, 3)` in the wind's axes (u along the mean wind, v to its left, w up), times `strength`
    (`(N,)` or a number: the onset)."""
    c, s = torch.cos(heading), torch.sin(heading)
    u = mean_speed + turbulence_uvw[:, 0]
    v, w = turbulence_uvw[:, 1], turbulence_uvw[:, 2]
    wind = torch.stack([c * u - s * v, s * u + c * v, w], dim=-1)
    return wind * (strength[:, None] if isinstance(strength, torch.Tensor) else strength)


def onset(step: torch.Tensor, onset_steps: float) -> torch.Tensor:
    """The wind's strength at control step `step` `(N,)` of an episode: min(step / onset_steps, 1)."""
    if onset_steps <= 0:
        return torch.ones_like(step, dtype=torch.float32)
    return (step.float() / onset_steps).clamp(0.0, 1.0)


def airframe_drag(
    velocity: torch.Tensor, wind: torch.Tensor, rotation: torch.Tensor, mass_kg: float, rotor_height_m: float,
    model: WindModel,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The drag force `(N, 3)` (world) and its torque about the airframe centre O `(N, 3)` (world) for the airframe
    moving at `velocity` through air moving at `wind` (both world, m/s), with body-to-world `rotation` `(N, 3, 3)`."""
    v_rel = velocity - wind
    v_body = (rotation * v_rel[:, :, None]).sum(1)  # R^T v_rel
    coefficients = v_body.new_tensor([model.rotor_drag_xy_per_s, model.rotor_drag_xy_per_s, model.rotor_drag_z_per_s])
    rotor = -mass_kg * (rotation @ (coefficients * v_body)[:, :, None])[:, :, 0]
    speed = torch.linalg.norm(v_rel, dim=-1, keepdim=True)
    parasitic = -0.5 * model.air_density_kgpm3 * model.parasitic_drag_area_m2 * speed * v_rel
    lever = rotor_height_m * rotation[:, :, 2]  # the rotor plane's centre relative to O (world)
    return rotor + parasitic, torch.linalg.cross(lever, rotor)
