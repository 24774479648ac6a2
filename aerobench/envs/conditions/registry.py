"""The named evaluation conditions as data: name -> version, models and their parameters, source, description.

A condition is a set of models (`MODEL_FIELDS`: wind, ground / ceiling / wall effects, motor lag, thrust headroom,
sensor noise and delay, payload mass scale; and what the cameras see: lighting, surface colours, camera noise, motion
blur);
several names compose when no two set the same model (`resolve_condition`). A condition's `version` is raised
whenever its parameters or its models' equations change, and results record name, version and parameters, so a
row says exactly what it was measured under. No condition (the empty tuple) is today's physics, bit for bit.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, fields
from types import MappingProxyType

from .constants import (
    ANGULAR_VELOCITY_NOISE_RPS,
    ATTITUDE_NOISE_RAD,
    BRIGHT_LIGHT_SCALE,
    DAYLIGHT_K,
    DIM_LIGHT_SCALE,
    DRYDEN_LIGHT_W20_MPS,
    HEAVY_PAYLOAD_SCALE,
    LIGHT_PAYLOAD_SCALE,
    LIPO_FULL_CELL_V,
    LIPO_NOMINAL_CELL_V,
    LOW_SUN_ELEVATION_DEG,
    MOTION_BLUR_EXPOSURE_S,
    MOTION_BLUR_TAPS,
    POSITION_NOISE_M,
    PX4_MOTOR_TIME_CONSTANT_DOWN_S,
    PX4_MOTOR_TIME_CONSTANT_UP_S,
    RGB_NOISE_SIGMA,
    SLOW_MOTOR_TIME_CONSTANT_S,
    STATE_DELAY_STEPS,
    SURFACE_GAIN_CHANGE,
    VELOCITY_NOISE_MPS,
    WARM_LIGHT_K,
)
from .motors import MotorLag, ThrustHeadroom
from .proximity import CeilingEffect, GroundEffect, WallEffect
from .sensors import SensorDelay, SensorNoise
from .visual import (
    CameraNoise,
    Lighting,
    MotionBlur,
    SurfaceColours,
    colour_temperature_tint,
    stereo_depth_rms_per_m,
)
from .wind import WindModel

MODEL_FIELDS = ("wind", "ground", "ceiling", "wall", "motor_lag", "headroom", "sensor_noise", "sensor_delay",
                "payload_mass_scale", "lighting", "surface_colours", "camera_noise", "motion_blur")
PHYSICAL_MODELS = ("wind", "ground", "ceiling", "wall", "motor_lag", "headroom")  # the conditioned physics step's
SCENE_MODELS = ("lighting", "surface_colours")  # applied when the scene is built
FRAME_MODELS = ("camera_noise", "motion_blur")  # applied to each camera frame the policy reads


@dataclass(frozen=True, kw_only=True)
class Models:
    """The models a condition (or a set of them) sets; None: not changed (`MODEL_FIELDS`)."""

    wind: WindModel | None = None
    ground: GroundEffect | None = None
    ceiling: CeilingEffect | None = None
    wall: WallEffect | None = None
    motor_lag: MotorLag | None = None
    headroom: ThrustHeadroom | None = None
    sensor_noise: SensorNoise | None = None
    sensor_delay: SensorDelay | None = None
    payload_mass_scale: float | None = None  # the carried object's real mass over its class's nominal mass
    lighting: Lighting | None = None
    surface_colours: SurfaceColours | None = None
    camera_noise: CameraNoise | None = None
    motion_blur: MotionBlur | None = None


@dataclass(frozen=True)
class Condition(Models):
    """One named condition: its models and what a reader needs to trust it."""

    name: str
    version: int
    description: str
    source: str

    def models(self) -> dict:
        """The models this condition sets, by field name."""
        return {name: getattr(self, name) for name in MODEL_FIELDS if getattr(self, name) is not None}

    def parameters(self) -> dict:
        """The models' parameters as plain JSON values (`{model: {parameter: value}}`, the payload scale a number)."""
        return {name: asdict(model) if hasattr(model, "__dataclass_fields__") else model
                for name, model in self.models().items()}

    def record(self) -> dict:
        """What results files keep of it."""
        return {"name": self.name, "version": self.version, "parameters": self.parameters(), "source": self.source}


@dataclass(frozen=True)
class ConditionSet(Models):
    """Several conditions at once (their models merged); what an env runs under."""

    conditions: tuple[Condition, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.conditions)

    @property
    def senses(self) -> bool:
        """Whether the state estimate a policy reads changes (noise, delay)."""
        return self.sensor_noise is not None or self.sensor_delay is not None

    @property
    def is_physical(self) -> bool:
        """Whether the physics step changes (wind, surfaces, motors)."""
        return any(getattr(self, name) is not None for name in PHYSICAL_MODELS)

    @property
    def is_visual(self) -> bool:
        """Whether what the cameras see changes (lighting, surface colours, camera noise, motion blur); the physics
        does not."""
        return self.changes_scene or self.changes_frames

    @property
    def changes_scene(self) -> bool:
        """Whether the built scene's lights or surfaces change."""
        return any(getattr(self, name) is not None for name in SCENE_MODELS)

    @property
    def changes_frames(self) -> bool:
        """Whether each camera frame the policy reads changes (noise, blur)."""
        return any(getattr(self, name) is not None for name in FRAME_MODELS)

    def records(self) -> list[dict]:
        return [c.record() for c in self.conditions]


def _conditions() -> dict[str, Condition]:
    px4 = "PX4 X500 Gazebo model (gazebo_motor_model timeConstantUp / timeConstantDown)"
    battery_scale = (LIPO_NOMINAL_CELL_V / LIPO_FULL_CELL_V) ** 2
    wind_source = ("MIL-F-8785C (1980) Dryden low-altitude turbulence as first-order Gauss-Markov processes; rotor drag "
                   "after Faessler et al., IEEE RA-L 2018; parasitic drag 1/2 rho C_D A v^2")
    items = [
        Condition("wind_steady_2ms", 1, "a steady 2 m/s wind from a heading drawn per episode (drag on the airframe)",
                  wind_source, wind=WindModel(mean_speed_mps=2.0)),
        Condition("wind_gusty_3ms", 1, "a 3 m/s mean wind with light Dryden turbulence (W20 = 15 kn): gusts of about "
                  "1.5 m/s std along the wind", wind_source, wind=WindModel(mean_speed_mps=3.0,
                                                                             w20_mps=DRYDEN_LIGHT_W20_MPS)),
        Condition("ground_effect", 1, "each rotor's thrust rises near the surface below it (floor, furniture tops)",
                  "Cheeseman & Bennett, ARC R&M 3021, 1955", ground=GroundEffect()),
        Condition("ceiling_effect", 1, "each rotor's thrust rises near the surface above it (ceiling, shelves)",
                  "form of Sanchez-Cuevas, Heredia & Ollero, ICUAS 2017; constants aerobench's", ceiling=CeilingEffect()),
        Condition("wall_effect", 1, "each rotor is sucked towards a wall or furniture side beside it",
                  "suction after Yang et al., arXiv 2509.21496, 2025; inverse-square form and constant aerobench's",
                  wall=WallEffect()),
        Condition("motor_lag", 1, "first-order rotor response, 12.5 ms up / 25 ms down", px4,
                  motor_lag=MotorLag(PX4_MOTOR_TIME_CONSTANT_UP_S, PX4_MOTOR_TIME_CONSTANT_DOWN_S)),
        Condition("motor_lag_slow", 1, "first-order rotor response of 100 ms both ways (a sluggish drive)",
                  f"first-order model as {px4}; time constant aerobench's stress level",
                  motor_lag=MotorLag(SLOW_MOTOR_TIME_CONSTANT_S, SLOW_MOTOR_TIME_CONSTANT_S)),
        Condition("low_headroom", 1, f"maximum rotor thrust x{battery_scale:.3f}: a LiPo at 3.7 V/cell instead of 4.2",
                  "thrust ~ (motor speed)^2 ~ voltage^2 (KV law, momentum theory)",
                  headroom=ThrustHeadroom(battery_scale)),
        Condition("sensor_noise", 1, "white noise on the state estimate the policy reads: 2 cm, 1 deg, 5 cm/s, "
                  "0.02 rad/s", "aerobench's choice, of a good onboard visual-inertial estimate's size",
                  sensor_noise=SensorNoise(POSITION_NOISE_M, ATTITUDE_NOISE_RAD, VELOCITY_NOISE_MPS,
                                           ANGULAR_VELOCITY_NOISE_RPS)),
        Condition("sensor_delay", 1, f"the state estimate the policy reads is {STATE_DELAY_STEPS} control steps "
                  f"({STATE_DELAY_STEPS * 50} ms) old", "aerobench's choice (a camera pipeline's latency)",
                  sensor_delay=SensorDelay(STATE_DELAY_STEPS)),
        Condition("payload_heavy", 1, f"the carried object weighs x{HEAVY_PAYLOAD_SCALE:g} its class's nominal mass; "
                  "the controller feeds the nominal forward", "spec appendix 'Payload-Aware Flight Control' "
                  "(nominal mass feedforward); mismatch aerobench's", payload_mass_scale=HEAVY_PAYLOAD_SCALE),
        Condition("payload_light", 1, f"the carried object weighs x{LIGHT_PAYLOAD_SCALE:g} its class's nominal mass; "
                  "the controller feeds the nominal forward", "spec appendix 'Payload-Aware Flight Control' "
                  "(nominal mass feedforward); mismatch aerobench's", payload_mass_scale=LIGHT_PAYLOAD_SCALE),
    ]
    lights = "SAPIEN's lights scaled and tinted where the scene makes them"
    warm = colour_temperature_tint(WARM_LIGHT_K, DAYLIGHT_K)
    items += [
        Condition("lighting_dim", 1, f"every light of the scene x{DIM_LIGHT_SCALE:g} (no auto-exposure: a darker "
                  "image)", f"{lights}; the scale aerobench's choice", lighting=Lighting(DIM_LIGHT_SCALE)),
        Condition("lighting_bright", 1, f"every light of the scene x{BRIGHT_LIGHT_SCALE:g} (bright surfaces clip)",
                  f"{lights}; the scale aerobench's choice", lighting=Lighting(BRIGHT_LIGHT_SCALE)),
        Condition("lighting_warm", 1, f"every light {WARM_LIGHT_K:g} K (warm-white lamps) seen by a camera balanced "
                  f"for {DAYLIGHT_K:g} K daylight, at equal luminance", "black-body colours from the Planckian locus "
                  "of Kim et al., J. Korean Phys. Soc. 2002, in linear sRGB (IEC 61966-2-1)",
                  lighting=Lighting(tint=warm)),
        Condition("lighting_side", 1, f"the sun {LOW_SUN_ELEVATION_DEG:g} deg over the horizon at the layout's "
                  "azimuth (nominal 35-70 deg): light from the side", f"{lights}; the elevation aerobench's choice",
                  lighting=Lighting(sun_elevation_deg=LOW_SUN_ELEVATION_DEG)),
        Condition("surface_colours", 1, f"each colour of the walls, floor, ceiling and furniture times per-channel "
                  f"gains in [{1 - SURFACE_GAIN_CHANGE:g}, {1 + SURFACE_GAIN_CHANGE:g}] drawn per layout (objects, "
                  "goal marker, fixtures and drone unchanged)", "bounded colour randomisation after Tobin et al., "
                  "IROS 2017; the range aerobench's choice", surface_colours=SurfaceColours(SURFACE_GAIN_CHANGE)),
        Condition("camera_noise", 1, f"white noise on every camera frame: RGB {RGB_NOISE_SIGMA:g} levels of 255, "
                  "depth RMS growing with depth squared as a RealSense D435's (3.6 mm at 1 m, 14 mm at 2 m)",
                  "depth: Intel's D400 tuning white paper (RMS = z^2 subpixel / (focal x baseline)) and D435 "
                  "datasheet; RGB sigma aerobench's choice", camera_noise=CameraNoise(RGB_NOISE_SIGMA,
                                                                                      stereo_depth_rms_per_m())),
        Condition("motion_blur", 1, f"every RGB frame integrated over a {MOTION_BLUR_EXPOSURE_S * 1000:g} ms "
                  "exposure along the camera's rotation", "rotational image flow of Longuet-Higgins & Prazdny, "
                  "Proc. R. Soc. B 1980, box exposure; exposure (a 180-degree shutter at 20 Hz) aerobench's choice",
                  motion_blur=MotionBlur(MOTION_BLUR_EXPOSURE_S, MOTION_BLUR_TAPS)),
    ]
    return {c.name: c for c in items}


CONDITIONS: Mapping[str, Condition] = MappingProxyType(_conditions())


def get_condition(name: str) -> Condition:
    """A named condition; an unknown name is a one-line error listing the valid ones."""
    try:
        return CONDITIONS[name]
    except KeyError:
        raise ValueError(f"unknown condition {name!r}; valid conditions: {', '.join(CONDITIONS)}") from None


def parse_condition_names(condition: str | Iterable[str] | None) -> tuple[str, ...]:
    """`"a,b"`, `("a", "b")` or None as a tuple of names (checked; duplicates refused)."""
    if condition is None:
        return ()
    names = tuple(n.strip() for n in (condition.split(",") if isinstance(condition, str) else condition) if n.strip())
    for name in names:
        get_condition(name)
    if len(set(names)) != len(names):
        raise ValueError(f"condition names repeat: {', '.join(names)}")
    return names


def resolve_condition(condition: str | Iterable[str] | Iterable[Condition] | ConditionSet | None) -> ConditionSet | None:
    """The conditions named (comma-separated or a sequence of names; `Condition`s themselves are taken as they are,
    for research and tests) as one set, or None for none (today's physics)."""
    if condition is None or isinstance(condition, ConditionSet):
        return condition
    items = [condition] if isinstance(condition, str) else list(condition)
    if all(isinstance(c, str) for c in items):
        items = [CONDITIONS[n] for n in parse_condition_names(",".join(items))]
    if not items:
        return None
    merged: dict = {}
    owner: dict[str, str] = {}
    for c in items:
        for model, value in c.models().items():
            if model in merged:
                raise ValueError(f"conditions {owner[model]} and {c.name} both set the {model} model; name one of them")
            merged[model], owner[model] = value, c.name
    return ConditionSet(tuple(items), **merged)


def describe_conditions() -> list[str]:
    """One line per named condition: name, version, parameters, source (what `aerobench conditions` prints)."""
    def number(v) -> str:
        if isinstance(v, (tuple, list)):
            return "(" + ", ".join(number(x) for x in v) + ")"
        return f"{v:g}" if isinstance(v, float) else str(v)

    lines = []
    for c in CONDITIONS.values():
        params = "; ".join(f"{model}: " + (", ".join(f"{k}={number(v)}" for k, v in value.items())
                                           if isinstance(value, dict) else number(value))
                           for model, value in c.parameters().items())
        lines.append(f"{c.name}  v{c.version}  {c.description}  [{params}]  source: {c.source}")
    return lines


assert {f.name for f in fields(ConditionSet)} - {"conditions"} == set(MODEL_FIELDS)
