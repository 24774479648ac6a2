"""The two articulated fixtures: a fridge (hinged door, vertical bar handle) and a counter drawer (sliding).

Geometry is data (`FixtureSpec.parts`, boxes in the fixture's root frame at q = 0), so the SAPIEN builder, the
oriented boxes for clearance checks (`fixture_boxes`) and the handle helpers all read one description.

Frames. A fixture's root frame has its origin on the floor at the middle of the carcass front (the plane the closed
door or drawer front lies against), x pointing out of the front, z up; `ArticulatedFixture.position` and `.yaw`
place it in the env frame (the front faces (cos yaw, sin yaw)). SAPIEN joints act along / about the x axis of the
joint frame: the fridge hinge frame is turned x -> z on the carcass's +y front edge (q > 0 swings the door out), the
drawer slides along the root x axis (q > 0 pulls it out). q = 0 is closed for both.

Joint friction. Spec appendix "Robot platforms": starting the fridge door takes about 7 N at the handle and the drawer
about 2.5 N. PhysX's articulation joint friction is a coefficient on the force the joint transmits, not a breakaway
threshold: measured on physx_cpu at 240 Hz, a ramped handle force moves the door at any level (coefficients 0.2-1.0
give slow creep that grows with the force, and no threshold), and the default coefficient 0.05 even locks a
force-limited drive. The fixtures therefore set that coefficient to 0 and use a velocity drive instead (stiffness 0,
target velocity 0, very high damping, force limit = the breakaway effort): the implicit drive holds the joint still
until the load exceeds the limit, then resists with exactly the limit, i.e. Coulomb friction with equal static and
kinetic values. PhysX solves it inside the step (CPU and GPU alike), so nothing has to run per physics step.
`tests/envs/scenes/test_fixtures.py` measures the breakaway with a ramped handle force.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING

import torch

from ..collision import ignore_self_collisions
from ..control.so3 import quat_wxyz_to_matrix
from .layout import ArticulatedFixture, Box, Color, Support, Vec3

if TYPE_CHECKING:
    from mani_skill.envs.scene import ManiSkillScene
    from mani_skill.utils.structs import Articulation, Pose

# Friction drive (see the module docstring). The damping only has to make creep negligible below the breakaway:
# creep speed = load / damping, 1e5 gives < 0.02 mm/s at the handle at 0.8x the breakaway force.
FRICTION_DRIVE_DAMPING = 1e5  # N m s/rad (hinge) or N s/m (slide)
FRONT_FREE_DEPTH_M = 1.5  # free floor in front of each fixture, for an aerial vehicle to hover at its handle
BODY_COLOR: Color = (0.93, 0.93, 0.91)
HANDLE_COLOR: Color = (0.62, 0.63, 0.66)
CABINET_COLOR: Color = (0.86, 0.84, 0.80)


@dataclass(frozen=True)
class FixturePart:
    """One box of a fixture: `link` is "body" (fixed root) or the moving link; root frame at q = 0."""

    name: str
    link: str
    center: Vec3
    half_size: Vec3
    color: Color


def _part(name: str, link: str, lo: Vec3, hi: Vec3, color: Color) -> FixturePart:
    """A part from its corner coordinates (easier to read and check than centres and half sizes)."""
    center = tuple((a + b) / 2 for a, b in zip(lo, hi))
    half = tuple((b - a) / 2 for a, b in zip(lo, hi))
    return FixturePart(name, link, center, half, color)  # type: ignore[arg-type]


@dataclass(frozen=True)
class FixtureSpec:
    """Everything about one fixture type; the same in every env (one articulation serves all parallel envs)."""

    name: str  # "fridge" | "drawer"
    kind: str  # "hinge" | "slide"
    joint_name: str
    moving_link: str
    q_limits: tuple[float, float]
    handle_center: Vec3  # grasp point (the bar's centre), root frame, q = 0
    handle_axis: Vec3  # the bar's long axis, root frame, q = 0
    breakaway_force_n: float  # force at the handle, perpendicular to the front, that starts the joint moving
    moving_mass_kg: float
    open_threshold: float  # spec: q_bar >= 0.75 (refrigerator) / 0.90 (drawer) counts as open
    parts: tuple[FixturePart, ...]
    hinge_point: Vec3 = (0.0, 0.0, 0.0)  # a point on the vertical hinge axis (hinge only), root frame

    @property
    def handle_lever_m(self) -> float:
        """Effort per newton pushed or pulled at the handle along the front normal: the hinge-to-handle distance
        along the door face (hinge), 1 (slide)."""
        if self.kind == "slide":
            return 1.0
        return abs(self.handle_center[1] - self.hinge_point[1])

    @property
    def breakaway_effort(self) -> float:
        """Drive force limit: N m (hinge) or N (slide)."""
        return self.breakaway_force_n * self.handle_lever_m

    @property
    def front_x_m(self) -> float:
        """Root-frame x of the fixture's frontmost point (the handle) when closed."""
        return max(p.center[0] + p.half_size[0] for p in self.parts)

    @property
    def back_x_m(self) -> float:
        return min(p.center[0] - p.half_size[0] for p in self.parts)

    @property
    def half_width_m(self) -> float:
        return max(abs(p.center[1]) + p.half_size[1] for p in self.parts)


# --------------------------------------------------------------------------------------------------------------------
# Fridge: 0.70 w x 0.70 d x 1.80 h (0.65 m carcass + 0.05 m door), hinge on the carcass's +y front edge.
# --------------------------------------------------------------------------------------------------------------------
FRIDGE_WIDTH_M = 0.70
FRIDGE_CARCASS_DEPTH_M = 0.65
FRIDGE_DOOR_THICKNESS_M = 0.05
FRIDGE_HEIGHT_M = 1.80
FRIDGE_WALL_M = 0.04
FRIDGE_SHELF_TOPS_M = (0.50, 0.90, 1.30)  # interior boards; their top faces are the "fridge_shelf" supports
FRIDGE_SHELF_SETBACK_M = 0.02  # the boards' front edges stand this far behind the carcass's front
FRIDGE_SHELF_NAMES = ("the fridge's bottom shelf", "the fridge's middle shelf", "the fridge's top shelf")
FRIDGE_DOOR_MAX_RAD = 1.9
# Spec: a vertical bar 50 mm wide parallel to the closed door face, for a horizontal pinch. The bar stands on two
# posts with a 42 mm gap behind it; it spans 0.9-1.5 m and sits 70 mm in from the door's free edge.
FRIDGE_HANDLE_WIDTH_M = 0.050
FRIDGE_HANDLE_DEPTH_M = 0.020
FRIDGE_HANDLE_GAP_M = 0.042
FRIDGE_HANDLE_Z_M = (0.90, 1.50)
FRIDGE_HANDLE_EDGE_INSET_M = 0.070
FRIDGE_DOOR_MASS_KG = 6.0  # a loaded fridge door weighs 5-10 kg; only its inertia matters (the hinge is vertical)
FRIDGE_BREAKAWAY_N = 7.0  # spec appendix "Robot platforms"


def _fridge_spec() -> FixtureSpec:
    w, d, t, h, wall = FRIDGE_WIDTH_M / 2, FRIDGE_CARCASS_DEPTH_M, FRIDGE_DOOR_THICKNESS_M, FRIDGE_HEIGHT_M, FRIDGE_WALL_M
    body, c = "body", BODY_COLOR
    parts = [
        _part("back", body, (-d, -w, 0.0), (-d + wall, w, h), c),
        _part("side_right", body, (-d + wall, -w, 0.0), (0.0, -w + wall, h), c),
        _part("side_left", body, (-d + wall, w - wall, 0.0), (0.0, w, h), c),
        _part("top", body, (-d + wall, -w + wall, h - wall), (0.0, w - wall, h), c),
        _part("bottom", body, (-d + wall, -w + wall, 0.0), (0.0, w - wall, 0.12), c),
    ]
    for i, top in enumerate(FRIDGE_SHELF_TOPS_M):
        parts.append(_part(f"shelf_{i}", body, (-d + wall, -w + wall, top - 0.02), (-FRIDGE_SHELF_SETBACK_M, w - wall, top), (0.8, 0.85, 0.88)))
    y_bar = -w + FRIDGE_HANDLE_EDGE_INSET_M
    x0 = t + FRIDGE_HANDLE_GAP_M
    x1 = x0 + FRIDGE_HANDLE_DEPTH_M
    z0, z1 = FRIDGE_HANDLE_Z_M
    hw = FRIDGE_HANDLE_WIDTH_M / 2
    parts += [
        _part("door", "door", (0.0, -w, 0.02), (t, w, h - 0.02), c),
        _part("handle", "door", (x0, y_bar - hw, z0), (x1, y_bar + hw, z1), HANDLE_COLOR),
        _part("handle_post_low", "door", (t, y_bar - 0.01, z0), (x0, y_bar + 0.01, z0 + 0.03), HANDLE_COLOR),
        _part("handle_post_high", "door", (t, y_bar - 0.01, z1 - 0.03), (x0, y_bar + 0.01, z1), HANDLE_COLOR),
    ]
    return FixtureSpec(
        name="fridge",
        kind="hinge",
        joint_name="fridge_hinge",
        moving_link="door",
        q_limits=(0.0, FRIDGE_DOOR_MAX_RAD),
        handle_center=((x0 + x1) / 2, y_bar, (z0 + z1) / 2),
        handle_axis=(0.0, 0.0, 1.0),
        breakaway_force_n=FRIDGE_BREAKAWAY_N,
        moving_mass_kg=FRIDGE_DOOR_MASS_KG,
        open_threshold=0.75,  # spec, Open/Close completion checks
        parts=tuple(parts),
        hinge_point=(0.0, w, 0.0),
    )


# --------------------------------------------------------------------------------------------------------------------
# Drawer: a 0.60 w x 0.55 d x 0.90 h counter cabinet with a top drawer (open box) and a closed cupboard below.
# --------------------------------------------------------------------------------------------------------------------
DRAWER_CABINET_WIDTH_M = 0.60
DRAWER_CABINET_DEPTH_M = 0.55
DRAWER_CABINET_HEIGHT_M = 0.90
DRAWER_TRAVEL_M = 0.40
DRAWER_BOX_DEPTH_M = 0.50
DRAWER_BOTTOM_Z_M = (0.632, 0.644)  # the drawer's floor board; its top face is the "drawer" support
# Spec: a horizontal handle 24 mm tall for a vertical pinch; 0.30 m long, 38 mm gap behind it, at 0.75 m.
DRAWER_HANDLE_LENGTH_M = 0.30
DRAWER_HANDLE_HEIGHT_M = 0.024
DRAWER_HANDLE_DEPTH_M = 0.015
DRAWER_HANDLE_GAP_M = 0.038
DRAWER_HANDLE_Z_M = 0.75
DRAWER_MASS_KG = 2.5
DRAWER_BREAKAWAY_N = 2.5  # spec appendix "Robot platforms"
DRAWER_FRONT_THICKNESS_M = 0.02


def _drawer_spec() -> FixtureSpec:
    w, d, h = DRAWER_CABINET_WIDTH_M / 2, DRAWER_CABINET_DEPTH_M, DRAWER_CABINET_HEIGHT_M
    body, c, m = "body", CABINET_COLOR, "drawer"
    f = DRAWER_FRONT_THICKNESS_M
    b0, b1 = DRAWER_BOTTOM_Z_M
    wall, inner = 0.012, w - 0.03  # drawer box: 12 mm boards, 1 cm clear of the carcass sides
    parts = [
        _part("back", body, (-d, -w, 0.0), (-d + 0.02, w, h - 0.03), c),
        _part("side_right", body, (-d + 0.02, -w, 0.0), (0.0, -w + 0.02, h - 0.03), c),
        _part("side_left", body, (-d + 0.02, w - 0.02, 0.0), (0.0, w, h - 0.03), c),
        _part("top", body, (-d, -w, h - 0.03), (f, w, h), c),
        _part("plinth", body, (-d + 0.02, -w + 0.02, 0.0), (-0.04, w - 0.02, 0.10), (0.3, 0.3, 0.3)),
        _part("divider", body, (-d + 0.02, -w + 0.02, 0.60), (0.0, w - 0.02, 0.625), c),
        _part("cupboard_door", body, (0.0, -w + 0.005, 0.10), (f, w - 0.005, 0.60), c),
        _part("front", m, (0.0, -w + 0.005, 0.635), (f, w - 0.005, 0.865), c),
        _part("box_bottom", m, (-DRAWER_BOX_DEPTH_M, -inner, b0), (0.0, inner, b1), c),
        _part("box_side_right", m, (-DRAWER_BOX_DEPTH_M, -inner, b1), (0.0, -inner + wall, 0.83), c),
        _part("box_side_left", m, (-DRAWER_BOX_DEPTH_M, inner - wall, b1), (0.0, inner, 0.83), c),
        _part("box_back", m, (-DRAWER_BOX_DEPTH_M, -inner + wall, b1), (-DRAWER_BOX_DEPTH_M + wall, inner - wall, 0.83), c),
    ]
    x0 = f + DRAWER_HANDLE_GAP_M
    x1 = x0 + DRAWER_HANDLE_DEPTH_M
    hl, hh, zc = DRAWER_HANDLE_LENGTH_M / 2, DRAWER_HANDLE_HEIGHT_M / 2, DRAWER_HANDLE_Z_M
    parts += [
        _part("handle", m, (x0, -hl, zc - hh), (x1, hl, zc + hh), HANDLE_COLOR),
        _part("handle_post_right", m, (f, -hl + 0.005, zc - 0.008), (x0, -hl + 0.02, zc + 0.008), HANDLE_COLOR),
        _part("handle_post_left", m, (f, hl - 0.02, zc - 0.008), (x0, hl - 0.005, zc + 0.008), HANDLE_COLOR),
    ]
    return FixtureSpec(
        name="drawer",
        kind="slide",
        joint_name="drawer_slide",
        moving_link="drawer",
        q_limits=(0.0, DRAWER_TRAVEL_M),
        handle_center=((x0 + x1) / 2, 0.0, zc),
        handle_axis=(0.0, 1.0, 0.0),
        breakaway_force_n=DRAWER_BREAKAWAY_N,
        moving_mass_kg=DRAWER_MASS_KG,
        open_threshold=0.90,  # spec, Open/Close completion checks
        parts=tuple(parts),
    )


FIXTURES: Mapping[str, FixtureSpec] = MappingProxyType({s.name: s for s in (_fridge_spec(), _drawer_spec())})


def get_fixture_spec(name: str) -> FixtureSpec:
    try:
        return FIXTURES[name]
    except KeyError:
        raise ValueError(f"unknown fixture {name!r}; valid fixtures: {', '.join(FIXTURES)}") from None


# --------------------------------------------------------------------------------------------------------------------
# Pure geometry (floats): the fixture as oriented boxes, its supports, the space it needs
# --------------------------------------------------------------------------------------------------------------------
def _rotate(x: float, y: float, yaw: float) -> tuple[float, float]:
    c, s = math.cos(yaw), math.sin(yaw)
    return c * x - s * y, s * x + c * y


def _moving_to_root(spec: FixtureSpec, p: Vec3, q: float) -> tuple[Vec3, float]:
    """A root-frame point of the moving link at q = 0 -> its root-frame position at q, and the link's yaw."""
    if spec.kind == "slide":
        return (p[0] + q, p[1], p[2]), 0.0
    hx, hy, _ = spec.hinge_point
    dx, dy = _rotate(p[0] - hx, p[1] - hy, q)
    return (hx + dx, hy + dy, p[2]), q


def _root_to_env(fixture: ArticulatedFixture, p: Vec3) -> Vec3:
    x, y = _rotate(p[0], p[1], fixture.yaw)
    return (fixture.position[0] + x, fixture.position[1] + y, fixture.position[2] + p[2])


def fixture_boxes(fixture: ArticulatedFixture, q: float) -> tuple[Box, ...]:
    """The fixture at joint position `q` as oriented boxes in the env frame (kind "fixture"; door turned by q)."""
    spec = get_fixture_spec(fixture.name)
    boxes = []
    for part in spec.parts:
        center, yaw = part.center, 0.0
        if part.link != "body":
            center, yaw = _moving_to_root(spec, part.center, q)
        boxes.append(
            Box(f"{fixture.name}/{part.name}", _root_to_env(fixture, center), part.half_size, fixture.yaw + yaw, part.color, "fixture")
        )
    return tuple(boxes)


SUPPORT_EDGE_MARGIN_M = 0.05


def fixture_supports(fixture: ArticulatedFixture, q: float | None = None) -> tuple[Support, ...]:
    """Fridge: its interior shelf boards (kind "fridge_shelf"). Drawer: the drawer's floor where it sticks out of the
    cabinet at `q` (default fully open; kind "drawer"). Shrunk 5 cm from the edges, like every support."""
    spec = get_fixture_spec(fixture.name)
    margin = SUPPORT_EDGE_MARGIN_M
    if spec.kind == "hinge":
        shelves = [p for p in spec.parts if p.name.startswith("shelf_")]
        ceilings = [p.center[2] - p.half_size[2] for p in spec.parts if p.name.startswith("shelf_") or p.name == "top"]
        out = []
        for part, name in zip(shelves, FRIDGE_SHELF_NAMES):
            top = part.center[2] + part.half_size[2]
            above = [z for z in ceilings if z > top - 1e-9]
            cx, cy = _root_to_env(fixture, part.center)[:2]
            half = (part.half_size[0] - margin, part.half_size[1] - margin)
            out.append(Support(name, "fridge_shelf", fixture.room, (cx, cy), half, top, fixture.yaw, min(above) - top))
        return tuple(out)
    q = spec.q_limits[1] if q is None else q
    bottom = next(p for p in spec.parts if p.name == "box_bottom")
    top_front = next(p for p in spec.parts if p.name == "top").center[0] + next(p for p in spec.parts if p.name == "top").half_size[0]
    x0 = max(bottom.center[0] - bottom.half_size[0] + 0.012 + q, top_front) + margin  # inside the back board
    x1 = bottom.center[0] + bottom.half_size[0] + q - margin
    if x1 - x0 < 0.02:
        return ()
    cx, cy = _root_to_env(fixture, ((x0 + x1) / 2, 0.0, 0.0))[:2]
    half = ((x1 - x0) / 2, bottom.half_size[1] - 0.012 - margin)
    return (Support("the kitchen drawer", "drawer", fixture.room, (cx, cy), half, DRAWER_BOTTOM_Z_M[1], fixture.yaw),)


@functools.cache
def swept_bounds(spec: FixtureSpec, samples: int = 24) -> tuple[float, float, float, float]:
    """Root-frame x-y bounds (x_lo, x_hi, y_lo, y_hi) of everything the fixture occupies over its joint range."""
    xs, ys = [], []
    for q in [spec.q_limits[0] + (spec.q_limits[1] - spec.q_limits[0]) * k / (samples - 1) for k in range(samples)]:
        for part in spec.parts:
            for sx in (-1, 1):
                for sy in (-1, 1):
                    corner = (part.center[0] + sx * part.half_size[0], part.center[1] + sy * part.half_size[1], 0.0)
                    if part.link != "body":
                        corner = _moving_to_root(spec, corner, q)[0]
                    xs.append(corner[0])
                    ys.append(corner[1])
    return min(xs), max(xs), min(ys), max(ys)


def fixture_keepout_boxes(fixture: ArticulatedFixture, depth: float = FRONT_FREE_DEPTH_M, height: float = 2.0) -> tuple[Box, Box]:
    """Space that must stay empty, as two boxes in the env frame (kind "keepout"): what the fixture sweeps over its
    joint range (door swing, drawer travel), and `depth` of free floor in front of its closed handle over its width
    and swing plus 0.2 m either side, for an aerial vehicle to hover at the handle."""
    spec = get_fixture_spec(fixture.name)
    x0, x1, y0, y1 = swept_bounds(spec)
    swing_c = _root_to_env(fixture, ((x0 + x1) / 2, (y0 + y1) / 2, height / 2))
    swing = Box(f"{fixture.name}/swing", swing_c, ((x1 - x0) / 2, (y1 - y0) / 2, height / 2), fixture.yaw, kind="keepout")
    f0, f1, g0, g1 = spec.front_x_m, spec.front_x_m + depth, y0 - 0.2, y1 + 0.2
    front_c = _root_to_env(fixture, ((f0 + f1) / 2, (g0 + g1) / 2, height / 2))
    front = Box(f"{fixture.name}/front", front_c, ((f1 - f0) / 2, (g1 - g0) / 2, height / 2), fixture.yaw, kind="keepout")
    return swing, front


def front_point(fixture: ArticulatedFixture, distance: float, z: float) -> Vec3:
    """A point `distance` in front of the fixture's closed front, at height `z` (nav targets)."""
    spec = get_fixture_spec(fixture.name)
    x, y, _ = _root_to_env(fixture, (spec.front_x_m + distance, 0.0, 0.0))
    return (x, y, z)


# --------------------------------------------------------------------------------------------------------------------
# Batched torch helpers (pure: root pose and joint position in, env-frame quantities out)
# --------------------------------------------------------------------------------------------------------------------
def q_bar(name: str, q: torch.Tensor) -> torch.Tensor:
    """Spec: the normalized articulation progress q_bar = (q - q_min) / (q_max - q_min)."""
    lo, hi = get_fixture_spec(name).q_limits
    return (q - lo) / (hi - lo)


def _moving_local(spec: FixtureSpec, points: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """Root-frame points `(P, 3)` of the moving link at q = 0 -> their root-frame positions at q, `(N, P, 3)`."""
    if spec.kind == "slide":
        return points[None] + q[:, None, None] * points.new_tensor([1.0, 0.0, 0.0])
    hinge = points.new_tensor(spec.hinge_point)
    rel = points[None] - hinge
    c, s = torch.cos(q)[:, None], torch.sin(q)[:, None]
    turned = torch.stack([c * rel[..., 0] - s * rel[..., 1], s * rel[..., 0] + c * rel[..., 1], rel[..., 2]], dim=-1)
    return hinge + turned


def _root_rotation(root_quat: torch.Tensor, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor]:
    """Rotation matrices `(N, 3, 3)` and yaw angles `(N,)` of root quaternions (wxyz; fixtures only turn about z)."""
    R = quat_wxyz_to_matrix(root_quat.to(dtype))
    return R, torch.atan2(R[:, 1, 0], R[:, 0, 0])


def handle_frame(
    name: str, root_pos: torch.Tensor, root_quat: torch.Tensor, q: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Grasp point, outward front normal and bar axis of the handle in the env frame, `(N, 3)` each.

    `root_pos` `(N, 3)` and `root_quat` `(N, 4)` wxyz: the fixture's root pose (`articulation.root_pose.p / .q`);
    `q` `(N,)`: the joint position. The grasp point is the bar's centre; the normal points away from the door / drawer
    front (pulling along it opens); the axis is the bar's long axis (vertical on the fridge, horizontal on the drawer).
    """
    spec = get_fixture_spec(name)
    q = q.to(root_pos.dtype)
    R, _ = _root_rotation(root_quat, root_pos.dtype)
    local = _moving_local(spec, root_pos.new_tensor([spec.handle_center]), q)[:, 0]
    turn = q if spec.kind == "hinge" else torch.zeros_like(q)
    c, s, zero = torch.cos(turn), torch.sin(turn), torch.zeros_like(turn)
    normal = torch.stack([c, s, zero], dim=-1)
    ax = root_pos.new_tensor(spec.handle_axis)
    axis = torch.stack([c * ax[0] - s * ax[1], s * ax[0] + c * ax[1], zero + ax[2]], dim=-1)
    to_env = lambda v: torch.einsum("nij,nj->ni", R, v)  # noqa: E731
    return root_pos + to_env(local), to_env(normal), to_env(axis)


def fixture_box_tensor(name: str, root_pos: torch.Tensor, root_quat: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """The fixture's boxes at joint position q, packed like `geometry.pack_boxes`: `(N, P, 8)` rows of centre xyz,
    half sizes xyz, yaw, valid (= 1). The batched twin of `fixture_boxes`."""
    spec = get_fixture_spec(name)
    q = q.to(root_pos.dtype)
    centers = root_pos.new_tensor([p.center for p in spec.parts])
    halves = root_pos.new_tensor([p.half_size for p in spec.parts])
    moving = torch.tensor([p.link != "body" for p in spec.parts], device=root_pos.device)
    local = torch.where(moving[None, :, None], _moving_local(spec, centers, q), centers[None])
    R, yaw = _root_rotation(root_quat, root_pos.dtype)
    env_centers = root_pos[:, None] + torch.einsum("nij,npj->npi", R, local)
    part_yaw = yaw[:, None] + (q[:, None] * moving if spec.kind == "hinge" else torch.zeros_like(moving, dtype=q.dtype))
    n, p = env_centers.shape[:2]
    return torch.cat([env_centers, halves.expand(n, p, 3), part_yaw[..., None], torch.ones(n, p, 1, dtype=q.dtype, device=q.device)], -1)


def yaw_quat(yaw: float) -> list[float]:
    """wxyz quaternion of a turn about +z."""
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


# --------------------------------------------------------------------------------------------------------------------
# SAPIEN / ManiSkill articulation
# --------------------------------------------------------------------------------------------------------------------
def _link_mass_properties(parts: list[FixturePart], mass: float, origin: Vec3):
    """Mass spread over the parts by volume: centre of mass and the inertia tensor about it, in the link frame."""
    import numpy as np

    vols = np.array([8 * p.half_size[0] * p.half_size[1] * p.half_size[2] for p in parts])
    masses = mass * vols / vols.sum()
    centers = np.array([p.center for p in parts]) - np.asarray(origin)
    com = (masses[:, None] * centers).sum(0) / mass
    inertia = np.zeros((3, 3))
    for m, c, p in zip(masses, centers, parts):
        a, b, e = (2 * v for v in p.half_size)
        own = np.diag([m * (b * b + e * e) / 12, m * (a * a + e * e) / 12, m * (a * a + b * b) / 12])
        r = c - com
        inertia += own + m * (r @ r * np.eye(3) - np.outer(r, r))
    return com, inertia


def build_fixture(scene: ManiSkillScene, name: str, root_poses: Pose) -> Articulation:
    """One articulation of fixture `name` for every parallel env, at `root_poses` (batched, one per env).

    The carcass is the fixed root link; the door / drawer is the moving link with the friction drive set up.
    """
    import numpy as np
    import sapien
    import transforms3d

    spec = get_fixture_spec(name)
    builder = scene.create_articulation_builder()
    # The door / drawer runs with mm gaps in its carcass: its links ignore each other through a collision-group bit
    # of their own (ManiSkill's `disable_self_collisions` uses one bit for every articulation, which would also
    # make the drone pass through the fixtures).
    links = {}
    for link_name in ("body", spec.moving_link):
        parent = links.get("body")
        link = builder.create_link_builder(parent)
        link.set_name(link_name)
        origin = spec.hinge_point if (link_name != "body" and spec.kind == "hinge") else (0.0, 0.0, 0.0)
        parts = [p for p in spec.parts if p.link == link_name]
        for p in parts:
            pose = sapien.Pose(p=[a - b for a, b in zip(p.center, origin)])
            link.add_box_collision(pose=pose, half_size=list(p.half_size))
            link.add_box_visual(pose=pose, half_size=list(p.half_size), material=p.color)
        if link_name != "body":
            link.set_joint_name(spec.joint_name)
            if spec.kind == "hinge":
                frame_q = [math.cos(math.pi / 4), 0.0, -math.sin(math.pi / 4), 0.0]  # joint x -> root z
                link.set_joint_properties(
                    "revolute", limits=[list(spec.q_limits)],
                    pose_in_parent=sapien.Pose(p=list(origin), q=frame_q), pose_in_child=sapien.Pose(q=frame_q),
                )
            else:
                link.set_joint_properties("prismatic", limits=[list(spec.q_limits)], pose_in_parent=sapien.Pose(), pose_in_child=sapien.Pose())
            com, inertia = _link_mass_properties(parts, spec.moving_mass_kg, origin)
            principal, axes = np.linalg.eigh(inertia)
            if np.linalg.det(axes) < 0:
                axes[:, 0] = -axes[:, 0]
            link.set_mass_and_inertia(
                spec.moving_mass_kg, sapien.Pose(p=com.tolist(), q=transforms3d.quaternions.mat2quat(axes).tolist()), principal.tolist()
            )
        links[link_name] = link
    builder.initial_pose = root_poses
    articulation = builder.build(name=name, fix_root_link=True)
    ignore_self_collisions(articulation, name)
    for joint in articulation.joints_map[spec.joint_name]._objs:
        joint.set_friction(0.0)  # PhysX's default 0.05 would lock the force-limited drive (module docstring)
        joint.set_drive_properties(0.0, FRICTION_DRIVE_DAMPING, spec.breakaway_effort, "force")
        joint.set_drive_target(np.zeros(1, dtype=np.float32))
        joint.set_drive_velocity_target(np.zeros(1, dtype=np.float32))
    return articulation


# --------------------------------------------------------------------------------------------------------------------
# Built fixtures: the same helpers read straight from the ManiSkill articulations (one joint each)
# --------------------------------------------------------------------------------------------------------------------
MOVING_LINK: Mapping[str, str] = MappingProxyType({name: spec.moving_link for name, spec in FIXTURES.items()})


def normalized_progress(articulation: Articulation) -> torch.Tensor:
    """q_bar `(N,)` of a built fixture."""
    lo, hi = articulation.qlimits[:, 0, 0], articulation.qlimits[:, 0, 1]
    return (articulation.get_qpos()[:, 0] - lo) / (hi - lo)


def handle_grasp_point(name: str, articulation: Articulation) -> torch.Tensor:
    """The handle's grasp point `(N, 3)` of a built fixture, in the env frame."""
    pose = articulation.root_pose
    return handle_frame(name, pose.p, pose.q, articulation.get_qpos()[:, 0])[0]


def front_normal(name: str, articulation: Articulation) -> torch.Tensor:
    """Outward normal `(N, 3)` of the door / drawer front of a built fixture (pulling along it opens)."""
    pose = articulation.root_pose
    return handle_frame(name, pose.p, pose.q, articulation.get_qpos()[:, 0])[1]


def packed_fixture_boxes(names: Sequence[str], articulations: Sequence[Articulation]) -> torch.Tensor:
    """Boxes of the built fixtures in their current state, `(N, P, 8)` like `geometry.pack_boxes` (for clearance)."""
    rows = []
    for name, art in zip(names, articulations):
        pose = art.root_pose
        rows.append(fixture_box_tensor(name, pose.p, pose.q, art.get_qpos()[:, 0]))
    return torch.cat(rows, dim=1)


def set_progress(articulation: Articulation, env_idx: torch.Tensor, progress: torch.Tensor) -> None:
    """Put the joint of envs `env_idx` at q_bar = `progress` `(M,)`, at rest. Call during `_initialize_episode`:
    on the GPU, ManiSkill writes only the envs being reset, so the other rows keep their state."""
    lo, hi = articulation.qlimits[:, 0, 0], articulation.qlimits[:, 0, 1]
    qpos = articulation.get_qpos().clone()
    qpos[env_idx, 0] = lo[env_idx] + progress.to(qpos.dtype) * (hi[env_idx] - lo[env_idx])
    if articulation.scene.gpu_sim_enabled:
        qpos = qpos[articulation.scene._reset_mask[articulation._scene_idxs]]
    articulation.set_qpos(qpos)
    articulation.set_qvel(torch.zeros_like(qpos))
