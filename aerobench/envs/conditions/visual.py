"""What the cameras see: lighting, surface colours, camera noise and motion blur (the visual conditions' models).

Two act on the scene when it is built (its lights, its static surfaces), two on each frame the policy reads:

- `Lighting`: every light of the scene (each env's ambient light and sun, the shared fill light) scaled in intensity
  and tinted (RGB multipliers), and the sun lowered to a given elevation at its own azimuth. Applied where the lights
  are made (`AeroSkillEnv._load_lighting`), so it holds for the whole build; SAPIEN's lights could be changed later,
  but nothing here needs to.
- `SurfaceColours`: the colours of the layout's static boxes (walls, floor, ceiling, furniture; what `build_layouts`
  makes into each env's one static actor) times per-channel gains drawn per colour from the env's own stream, seeded
  by its episode seed (`runtime.SURFACE_STREAM`). Applied at the build, like the layout itself: a one-env CPU run
  builds (and draws) every episode, parallel envs keep theirs until a reconfigure (ManiSkill's place for material
  randomisation, and where the layout's own colours are drawn). The objects, the goal
  marker, the fixtures (fridge, drawer) and the drone keep their colours: an instruction names the object, and the
  marker shows the goal; the condition asks whether the policy still finds them against a different room.
- `CameraNoise`: white Gaussian noise on each RGB pixel and channel (levels of 255) and on depth, whose standard
  deviation grows with the square of the depth as a stereo camera's does (a RealSense D435's).
- `MotionBlur`: each RGB frame integrated over an exposure T ending at the frame while the camera turns at its
  angular velocity omega. A static point's image moves with the rotational flow of a pinhole camera (Longuet-Higgins &
  Prazdny, "The interpretation of a moving retinal image", Proc. R. Soc. Lond. B 208, 1980), in normalised image
  coordinates (x right, y down, optical axis z; omega in that frame):
      x' = x y w_x - (1 + x^2) w_y + y w_z,     y' = (1 + y^2) w_x - x y w_y - x w_z
  so what pixel p saw at time t - s is what the frame shows at p + flow(p) s, and the blurred frame is
      B(p) = 1/K sum_k I(p + flow(p) s_k),  s_k = T k / (K - 1), k = 0..K-1
  (a box exposure, bilinear samples, edges repeated; the rendered frame stands for the scene, so what enters from
  outside the view or from behind an occluder is not seen). With 90 deg cameras at 128 px (focal 64 px) and T = 25
  ms, a 1 rad/s turn streaks 1.6 px at the centre, 3.2 px at the edges. Left out: the translation's flow (focal x
  speed x T / depth, about 1 px at 0.6 m/s and 1 m; it would need each pixel's depth and would smear what is near the
  lens most), and that what moves with the camera (the fingers, a held object) stays sharp: everything in view is
  blurred as if static. Depth is not blurred: the D435's depth imagers are global-shutter with short exposures.

The noise is counter-based: each value is a hash of (the episode's key, the env's control step, the camera, the
element), with the PCG hash of Jarzynski & Olano ("Hash functions for GPU rendering", JCGT 9(3), 2020), two hashes to
a pair of normals (Box-Muller). The key is drawn at the episode's start from the env's own generator
(`runtime.CAMERA_STREAM`), so a batch of N envs sees exactly what N single envs see, the same frame asked twice in a
step gets the same noise, and the step draws nothing from a generator (no loop over envs, no host sync).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, replace
from functools import lru_cache

import torch
from torch.nn import functional as F

from ..scenes.layout import Color, SceneLayout, Vec3
from .constants import (
    D435_BASELINE_M,
    D435_DEPTH_HFOV_DEG,
    D435_DEPTH_WIDTH_PX,
    D435_SUBPIXEL_RMS,
    DAYLIGHT_K,
    PLANCK_X_HIGH,
    PLANCK_X_LOW,
    PLANCK_X_SPLIT_K,
    PLANCK_Y,
    PLANCK_Y_SPLITS_K,
    SRGB_LUMINANCE,
    XYZ_TO_LINEAR_SRGB,
)

UINT32 = 0xFFFFFFFF
RGB_MAX = 255
DEPTH_MAX_MM = 32767  # ManiSkill's depth is int16 millimetres; 0 is "no return"


# --------------------------------------------------------------------------------------------------------------------
# The scene: lights and surfaces
# --------------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Lighting:
    intensity_scale: float = 1.0
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)  # linear RGB multipliers of every light
    sun_elevation_deg: float | None = None  # None: the layout's own sun

    def __post_init__(self):
        if not self.intensity_scale > 0 or len(self.tint) != 3 or min(self.tint) < 0:
            raise ValueError("a lighting model scales the lights by a factor > 0 and tints them by 3 factors >= 0")
        if self.sun_elevation_deg is not None and not 0 < self.sun_elevation_deg <= 90:
            raise ValueError("the sun's elevation is in (0, 90] degrees above the horizon")

    def light_colour(self, colour: Color) -> list[float]:
        """A light's colour (intensity per channel) under this model."""
        return [float(c * self.intensity_scale * t) for c, t in zip(colour, self.tint)]

    def sun_direction(self, direction: Vec3) -> list[float]:
        """The direction the sun shines in (pointing down): its elevation replaced, its azimuth kept."""
        if self.sun_elevation_deg is None:
            return [float(v) for v in direction]
        azimuth = math.atan2(direction[1], direction[0])
        elevation = math.radians(self.sun_elevation_deg)
        return [math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), -math.sin(elevation)]

    def relight(self, layout: SceneLayout) -> SceneLayout:
        """The layout with its ambient light and sun under this model."""
        return replace(layout, ambient_light=tuple(self.light_colour(layout.ambient_light)),
                       sun_color=tuple(self.light_colour(layout.sun_color)),
                       sun_direction=tuple(self.sun_direction(layout.sun_direction)))


def planckian_xy(kelvin: float) -> tuple[float, float]:
    """CIE 1931 chromaticity of a black body at `kelvin` (Kim et al. 2002's cubic splines, 1667-25000 K)."""
    if not 1667 <= kelvin <= 25000:
        raise ValueError("the Planckian locus splines hold for 1667-25000 K")
    a = PLANCK_X_LOW if kelvin <= PLANCK_X_SPLIT_K else PLANCK_X_HIGH
    x = a[0] * 1e9 / kelvin**3 + a[1] * 1e6 / kelvin**2 + a[2] * 1e3 / kelvin + a[3]
    b = PLANCK_Y[sum(kelvin > split for split in PLANCK_Y_SPLITS_K)]
    return x, b[0] * x**3 + b[1] * x**2 + b[2] * x + b[3]


def colour_temperature_tint(kelvin: float, white_kelvin: float = DAYLIGHT_K) -> tuple[float, float, float]:
    """Linear-sRGB multipliers of a light at `kelvin` seen by a camera balanced for `white_kelvin`: the two black
    bodies' linear sRGB (at Y = 1) divided channel by channel, scaled to the luminance of white."""
    def rgb(k: float) -> list[float]:
        x, y = planckian_xy(k)
        xyz = (x / y, 1.0, (1 - x - y) / y)
        return [sum(m * v for m, v in zip(row, xyz)) for row in XYZ_TO_LINEAR_SRGB]

    ratio = [a / b for a, b in zip(rgb(kelvin), rgb(white_kelvin))]
    luminance = sum(w * r for w, r in zip(SRGB_LUMINANCE, ratio))
    return tuple(round(r / luminance, 4) for r in ratio)  # type: ignore[return-value]


@dataclass(frozen=True)
class SurfaceColours:
    gain_change: float  # each channel's gain drawn uniformly in [1 - a, 1 + a]

    def __post_init__(self):
        if not 0 < self.gain_change <= 1:
            raise ValueError("a surface colour gain change is in (0, 1]")

    def gains(self, count: int, generator: torch.Generator) -> torch.Tensor:
        """`(count, 3)` gains, drawn from `generator` (CPU)."""
        return 1.0 + self.gain_change * (2.0 * torch.rand(count, 3, generator=generator, dtype=torch.float64) - 1.0)

    def recolour(self, layout: SceneLayout, generator: torch.Generator) -> SceneLayout:
        """The layout with each distinct colour of its boxes (in order of first use) times its own gains, clipped to
        [0, 1]: boxes that shared a colour (a wall's segments, a piece's parts) still share one."""
        colours = list(dict.fromkeys(box.color for box in layout.boxes))
        gains = self.gains(len(colours), generator).tolist()
        new = {c: tuple(min(1.0, max(0.0, v * g)) for v, g in zip(c, gain)) for c, gain in zip(colours, gains)}
        return replace(layout, boxes=tuple(replace(box, color=new[box.color]) for box in layout.boxes))


# --------------------------------------------------------------------------------------------------------------------
# The frames: noise
# --------------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CameraNoise:
    rgb_sigma: float  # levels of 255
    depth_rms_per_m: float  # depth RMS error = this x depth^2 (m)

    def __post_init__(self):
        if self.rgb_sigma < 0 or self.depth_rms_per_m < 0:
            raise ValueError("camera noise levels are >= 0")


def stereo_depth_rms_per_m(subpixel: float = D435_SUBPIXEL_RMS, baseline_m: float = D435_BASELINE_M,
                           width_px: int = D435_DEPTH_WIDTH_PX, hfov_deg: float = D435_DEPTH_HFOV_DEG) -> float:
    """c of a stereo camera's depth RMS error c z^2 = z^2 s / (f B), f = 1/2 width / tan(HFOV / 2) (pixels)."""
    focal_px = 0.5 * width_px / math.tan(math.radians(hfov_deg) / 2)
    return subpixel / (focal_px * baseline_m)


def pcg_hash(v: torch.Tensor) -> torch.Tensor:
    """Jarzynski & Olano's PCG hash of 32-bit values held in int64 (every product stays below 2^63)."""
    state = (v * 747796405 + 2891336453) & UINT32
    word = (((state >> ((state >> 28) + 4)) ^ state) * 277803737) & UINT32
    return (word >> 22) ^ word


def camera_counter(uid: str) -> int:
    """A camera's fixed 32-bit id in the hash (its name's CRC-32: the same whatever other cameras exist)."""
    return zlib.crc32(uid.encode())


@lru_cache(maxsize=16)
def _element_hashes(count: int, device: torch.device) -> torch.Tensor:
    return pcg_hash(torch.arange(count, device=device))  # the same every frame: made once per size and device


def hashed_normals(keys: torch.Tensor, step: torch.Tensor, camera: int, count: int) -> torch.Tensor:
    """`(N, count)` standard normals for envs with episode keys `keys` `(N,)` at their control `step` `(N,)`:
    element e of pair e // 2 from the hashes of elements 2j and 2j + 1 (Box-Muller); a prefix of a longer draw.
    Nothing crosses between host and device (the camera's hash is a host number)."""
    pairs = (count + 1) // 2
    elements = _element_hashes(2 * pairs, keys.device)
    camera_hash = int(pcg_hash(torch.tensor(camera, dtype=torch.long)))
    frame = pcg_hash((step.long() + camera_hash) & UINT32)
    base = pcg_hash((keys.long() + frame) & UINT32)
    h = pcg_hash((base[:, None] + elements[None]) & UINT32)
    u = ((h >> 8).float() + 0.5) * 2.0**-24  # in (0, 1): 24 bits, exact in float32
    radius = torch.sqrt(-2.0 * torch.log(u[:, 0::2]))
    angle = 2.0 * math.pi * u[:, 1::2]
    return torch.stack([radius * torch.cos(angle), radius * torch.sin(angle)], -1).reshape(len(keys), -1)[:, :count]


def noisy_rgb(rgb: torch.Tensor, white: torch.Tensor, model: CameraNoise) -> torch.Tensor:
    """uint8 `(N, H, W, 3)` plus sigma x `white` (same shape), rounded and clipped to [0, 255]."""
    return (rgb.float() + model.rgb_sigma * white).round().clamp(0, RGB_MAX).to(rgb.dtype)


def noisy_depth(depth_mm: torch.Tensor, white: torch.Tensor, model: CameraNoise) -> torch.Tensor:
    """int16 millimetres `(N, H, W, 1)` plus c z^2 x `white`; a "no return" 0 stays 0 and a return stays >= 1 mm."""
    d = depth_mm.float()
    sigma_mm = model.depth_rms_per_m * (d * d) / 1000.0  # c z^2 in mm with z in mm: c (z/1000)^2 * 1000
    noisy = (d + sigma_mm * white).round().clamp(1, DEPTH_MAX_MM)
    return torch.where(depth_mm > 0, noisy, d).to(depth_mm.dtype)


# --------------------------------------------------------------------------------------------------------------------
# The frames: motion blur
# --------------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MotionBlur:
    exposure_s: float
    taps: int

    def __post_init__(self):
        if not self.exposure_s >= 0 or not (isinstance(self.taps, int) and self.taps >= 2):
            raise ValueError("motion blur needs an exposure >= 0 s and at least 2 taps")


def rotational_flow(omega_camera: torch.Tensor, intrinsic: torch.Tensor, height: int, width: int) -> torch.Tensor:
    """`(N, H, W, 2)` image velocity (pixels/s, along u and v) of static points for cameras turning at
    `omega_camera` `(N, 3)` rad/s in their OpenCV frame (x right, y down, z forward), intrinsics `(N, 3, 3)`; pixel
    (i, j)'s centre at u = j + 1/2, v = i + 1/2 (SAPIEN's principal point is at the image's centre, W/2, H/2)."""
    fx, fy = intrinsic[:, 0, 0, None, None], intrinsic[:, 1, 1, None, None]
    cx, cy = intrinsic[:, 0, 2, None, None], intrinsic[:, 1, 2, None, None]
    u = torch.arange(width, device=intrinsic.device, dtype=intrinsic.dtype)[None, None, :] + 0.5
    v = torch.arange(height, device=intrinsic.device, dtype=intrinsic.dtype)[None, :, None] + 0.5
    x, y = (u - cx) / fx, (v - cy) / fy
    wx, wy, wz = (omega_camera[:, k, None, None].to(intrinsic.dtype) for k in range(3))
    x_rate = x * y * wx - (1 + x * x) * wy + y * wz
    y_rate = (1 + y * y) * wx - x * y * wy - x * wz
    return torch.stack([fx * x_rate, fy * y_rate], -1)


def motion_blur(image: torch.Tensor, flow: torch.Tensor, model: MotionBlur) -> torch.Tensor:
    """`(N, H, W, C)` frames (any dtype) averaged over the exposure along `flow` `(N, H, W, 2)` px/s (module
    docstring); one `grid_sample` over all taps."""
    n, h, w, c = image.shape
    s = torch.linspace(0.0, model.exposure_s, model.taps, device=image.device)
    ys = (torch.arange(h, device=image.device) + 0.5) * (2.0 / h) - 1.0
    xs = (torch.arange(w, device=image.device) + 0.5) * (2.0 / w) - 1.0
    centres = torch.stack(torch.meshgrid(xs, ys, indexing="xy"), -1)  # (H, W, 2) as grid_sample's (x, y)
    flow_grid = torch.stack([flow[..., 0].float() * (2.0 / w), flow[..., 1].float() * (2.0 / h)], -1)
    grid = centres[None, None] + flow_grid[:, None] * s[None, :, None, None, None]  # (N, K, H, W, 2)
    frames = image.permute(0, 3, 1, 2).float()
    taps = F.grid_sample(frames, grid.reshape(n, model.taps * h, w, 2), mode="bilinear", padding_mode="border",
                         align_corners=False)
    blurred = taps.reshape(n, c, model.taps, h, w).mean(2).permute(0, 2, 3, 1)
    if image.dtype.is_floating_point:
        return blurred.to(image.dtype)
    return blurred.round().clamp(torch.iinfo(image.dtype).min, torch.iinfo(image.dtype).max).to(image.dtype)
