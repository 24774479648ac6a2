"""Furniture, walls and the placement geometry the scene generators share. Pure: numbers in, `layout` data out.

A piece is built in its own frame: origin on the floor at the middle of its footprint, local x out of its front (the
side one uses it from), local y along its width, so `yaw` turns the front to (cos yaw, sin yaw) like the fixtures.
Each piece function returns a `Piece`: its boxes (named "<piece>/<part>"), the supports it offers (the top area
shrunk `SUPPORT_MARGIN_M` from the edges) and its footprint.

Support usability (`fit_support`): a quadrotor must be able to hover over any point of a support with its rotor disks
`HOVER_DISK_CLEARANCE_M` above the surface. The X500's disks reach `ROTOR_REACH_M` from the airframe centre along its
body axes; flying with those axes along the room's (axis-aligned) walls, its footprint is a square of that half size. So a support is
shrunk until that square, swept from the surface up to `CLEAR_HEIGHT_M`, touches no box; supports left smaller than
`MIN_SUPPORT_SIDE_M` are dropped. This is why wall-backed supports are deep (>= 0.64 m) and open shelves stand free.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np

from ..platforms import GRIPPER_PLATFORM
from .layout import Box, Color, Doorway, Room, SceneLayout, Support, Vec2, Vec3

SUPPORT_MARGIN_M = 0.05  # usable top area starts this far in from the furniture's edges
# Scene requirements of the benchmark issue: the disks hover 0.35 m above a support while picking / placing on it, and
# pick / place supports keep 0.9 m free above them (no shelf board right above).
HOVER_DISK_CLEARANCE_M = 0.35
CLEAR_HEIGHT_M = 0.9
ROTOR_REACH_M = GRIPPER_PLATFORM.rotors.arm_m + GRIPPER_PLATFORM.rotors.disk_radius_m + 0.01  # 0.321 m + 1 cm
MIN_SUPPORT_SIDE_M = 0.25
NAV_CLEARANCE_M = 0.5  # nav points: at least this far from every box
WALL_THICKNESS_M = 0.12
FIT_STEP_M = 0.04

WALL_COLORS: tuple[Color, ...] = ((0.90, 0.89, 0.85), (0.85, 0.87, 0.88), (0.93, 0.90, 0.82), (0.80, 0.84, 0.78), (0.88, 0.82, 0.78))
FLOOR_COLORS: tuple[Color, ...] = ((0.55, 0.42, 0.30), (0.66, 0.55, 0.42), (0.45, 0.36, 0.28), (0.70, 0.70, 0.68), (0.50, 0.50, 0.52))
WOOD_COLORS: tuple[Color, ...] = ((0.55, 0.38, 0.22), (0.72, 0.56, 0.38), (0.38, 0.26, 0.16), (0.82, 0.72, 0.55), (0.30, 0.22, 0.18))
PAINT_COLORS: tuple[Color, ...] = ((0.95, 0.95, 0.93), (0.20, 0.22, 0.25), (0.55, 0.62, 0.58), (0.35, 0.45, 0.60), (0.78, 0.72, 0.62))
FABRIC_COLORS: tuple[Color, ...] = ((0.35, 0.40, 0.48), (0.55, 0.30, 0.25), (0.45, 0.47, 0.42), (0.70, 0.66, 0.58), (0.25, 0.32, 0.30))
STONE_COLORS: tuple[Color, ...] = ((0.85, 0.85, 0.83), (0.25, 0.25, 0.27), (0.62, 0.60, 0.56), (0.90, 0.88, 0.82))
VEHICLE_COLORS: tuple[Color, ...] = ((0.75, 0.10, 0.10), (0.15, 0.25, 0.55), (0.92, 0.92, 0.92), (0.20, 0.20, 0.22), (0.35, 0.45, 0.30))


def pick_color(rng: np.random.Generator, palette: Sequence[Color], jitter: float = 0.03) -> Color:
    """A palette colour with a little per-channel jitter, so no two scenes look exactly alike."""
    base = np.asarray(palette[int(rng.integers(len(palette)))])
    return tuple(float(v) for v in np.clip(base + rng.uniform(-jitter, jitter, 3), 0.0, 1.0))  # type: ignore[return-value]


def random_lighting(rng: np.random.Generator, outdoor: bool = False) -> dict[str, tuple[float, float, float]]:
    """Ambient light, sun direction and colour for `SceneLayout` (indoor: dimmer ambient, warmer or cooler light)."""
    level = rng.uniform(0.35, 0.5) if outdoor else rng.uniform(0.22, 0.38)
    tint = rng.uniform(-0.03, 0.03, 3)
    azimuth, elevation = rng.uniform(-math.pi, math.pi), rng.uniform(math.radians(35), math.radians(70))
    warmth = rng.uniform(-0.08, 0.08)
    return dict(
        ambient_light=tuple(float(level + t) for t in tint),
        sun_direction=(
            float(math.cos(azimuth) * math.cos(elevation)),
            float(math.sin(azimuth) * math.cos(elevation)),
            float(-math.sin(elevation)),
        ),
        sun_color=(float(min(1.0, 0.95 + warmth)), 0.95, float(min(1.0, 0.95 - warmth))),
    )


@dataclass(frozen=True)
class Piece:
    """A placed piece of furniture: boxes, supports, and its footprint (piece frame: x depth, y width)."""

    name: str
    boxes: tuple[Box, ...]
    supports: tuple[Support, ...]
    center: Vec2
    half_size: Vec2
    yaw: float
    height: float


class _Frame:
    """Local-to-env placement of one piece; parts and supports are given by local corner coordinates."""

    def __init__(self, name: str, room: str, center: Vec2, yaw: float, kind: str = "furniture"):
        self.name, self.room, self.center, self.yaw, self.kind = name, room, center, yaw, kind
        self.boxes: list[Box] = []
        self.supports: list[Support] = []

    def _to_env(self, x: float, y: float) -> Vec2:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return (self.center[0] + c * x - s * y, self.center[1] + s * x + c * y)

    def box(self, part: str, lo: Vec3, hi: Vec3, color: Color) -> None:
        cx, cy = self._to_env((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2)
        half = ((hi[0] - lo[0]) / 2, (hi[1] - lo[1]) / 2, (hi[2] - lo[2]) / 2)
        self.boxes.append(Box(f"{self.name}/{part}", (cx, cy, (lo[2] + hi[2]) / 2), half, self.yaw, color, self.kind))

    def support(self, name: str, kind: str, lo: Vec2, hi: Vec2, height: float) -> None:
        m = SUPPORT_MARGIN_M
        half = ((hi[0] - lo[0]) / 2 - m, (hi[1] - lo[1]) / 2 - m)
        center = self._to_env((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2)
        self.supports.append(Support(name, kind, self.room, center, half, height, self.yaw))

    def piece(self, depth: float, width: float, height: float) -> Piece:
        return Piece(self.name, tuple(self.boxes), tuple(self.supports), self.center, (depth / 2, width / 2), self.yaw, height)


# --------------------------------------------------------------------------------------------------------------------
# Pieces. Arguments: name (box prefix), room, center, yaw, sizes in metres, colours, the support's phrase.
# --------------------------------------------------------------------------------------------------------------------
def table(
    name: str, room: str, center: Vec2, yaw: float, depth: float, width: float, height: float,
    top_color: Color, leg_color: Color, support_name: str, kind: str = "table",
) -> Piece:
    f, d, w, t, leg = _Frame(name, room, center, yaw), depth / 2, width / 2, 0.04, 0.025
    f.box("top", (-d, -w, height - t), (d, w, height), top_color)
    for i, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        x, y = sx * (d - 0.04 - leg), sy * (w - 0.04 - leg)
        f.box(f"leg_{i}", (x - leg, y - leg, 0.0), (x + leg, y + leg, height - t), leg_color)
    f.support(support_name, kind, (-d, -w), (d, w), height)
    return f.piece(depth, width, height)


def counter(
    name: str, room: str, center: Vec2, yaw: float, depth: float, width: float, height: float,
    base_color: Color, top_color: Color, support_name: str, kind: str = "counter",
) -> Piece:
    """A base cabinet run with a stone top that overhangs the front by 3 cm; `kind="cabinet"` for sideboards."""
    f, d, w, t = _Frame(name, room, center, yaw), depth / 2, width / 2, 0.04
    f.box("plinth", (-d, -w + 0.02, 0.0), (d - 0.09, w - 0.02, 0.10), (0.18, 0.18, 0.18))
    f.box("base", (-d, -w, 0.10), (d - 0.03, w, height - t), base_color)
    f.box("top", (-d, -w, height - t), (d, w, height), top_color)
    f.support(support_name, kind, (-d, -w), (d, w), height)
    return f.piece(depth, width, height)


def cabinet(
    name: str, room: str, center: Vec2, yaw: float, depth: float, width: float, height: float,
    body_color: Color, top_color: Color, support_name: str,
) -> Piece:
    """A closed cabinet (sideboard, dresser, TV stand) on short feet, with a handle rail across the front."""
    f, d, w, t = _Frame(name, room, center, yaw), depth / 2, width / 2, 0.03
    for i, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        x, y = sx * (d - 0.05), sy * (w - 0.05)
        f.box(f"foot_{i}", (x - 0.025, y - 0.025, 0.0), (x + 0.025, y + 0.025, 0.08), (0.15, 0.15, 0.15))
    f.box("body", (-d, -w, 0.08), (d - 0.01, w, height - t), body_color)
    f.box("top", (-d, -w, height - t), (d, w, height), top_color)
    f.box("handle_rail", (d - 0.01, -w + 0.1, height - 0.15), (d, w - 0.1, height - 0.12), (0.6, 0.6, 0.62))
    f.support(support_name, "cabinet", (-d, -w), (d, w), height)
    return f.piece(depth, width, height)


def sofa(
    name: str, room: str, center: Vec2, yaw: float, depth: float, width: float, seat_height: float,
    color: Color, support_name: str,
) -> Piece:
    f, d, w = _Frame(name, room, center, yaw), depth / 2, width / 2
    back_t, arm_t, back_h, arm_h = 0.2, 0.18, seat_height + 0.42, seat_height + 0.16
    shade = tuple(0.85 * c for c in color)
    f.box("base", (-d, -w, 0.0), (d, w, seat_height - 0.14), shade)
    f.box("cushion", (-d + back_t, -w + arm_t, seat_height - 0.14), (d, w - arm_t, seat_height), color)
    f.box("back", (-d, -w, seat_height - 0.14), (-d + back_t, w, back_h), shade)
    f.box("arm_left", (-d + back_t, w - arm_t, seat_height - 0.14), (d, w, arm_h), shade)
    f.box("arm_right", (-d + back_t, -w, seat_height - 0.14), (d, -w + arm_t, arm_h), shade)
    f.support(support_name, "sofa", (-d + back_t, -w + arm_t), (d, w - arm_t), seat_height)
    return f.piece(depth, width, back_h)


def shelf_unit(
    name: str, room: str, center: Vec2, yaw: float, depth: float, width: float, height: float, boards: int,
    color: Color, support_name: str,
) -> Piece:
    """An open shelf unit (no back, usable from both faces). Only its TOP board is a support: the boards below have
    less than `CLEAR_HEIGHT_M` above them."""
    f, d, w, t = _Frame(name, room, center, yaw), depth / 2, width / 2, 0.025
    f.box("side_left", (-d, w - t, 0.0), (d, w, height - t), color)
    f.box("side_right", (-d, -w, 0.0), (d, -w + t, height - t), color)
    f.box("top", (-d, -w, height - t), (d, w, height), color)
    for i in range(boards):
        z = 0.06 + i * (height - 0.06) / boards
        f.box(f"board_{i}", (-d, -w + t, z), (d, w - t, z + t), color)
    f.support(support_name, "shelf", (-d, -w), (d, w), height)
    return f.piece(depth, width, height)


def bed(name: str, room: str, center: Vec2, yaw: float, length: float, width: float, frame_color: Color, sheet_color: Color) -> Piece:
    """Front (local +x) is the foot end; the headboard stands at the back against a wall. Not a support."""
    f, d, w = _Frame(name, room, center, yaw), length / 2, width / 2
    f.box("frame", (-d, -w, 0.0), (d, w, 0.32), frame_color)
    f.box("mattress", (-d + 0.06, -w + 0.03, 0.32), (d - 0.03, w - 0.03, 0.52), sheet_color)
    f.box("headboard", (-d, -w, 0.32), (-d + 0.06, w, 1.05), frame_color)
    f.box("pillow", (-d + 0.1, -w + 0.15, 0.52), (-d + 0.45, w - 0.15, 0.62), (0.95, 0.95, 0.95))
    return f.piece(length, width, 1.05)


def wardrobe(name: str, room: str, center: Vec2, yaw: float, depth: float, width: float, height: float, color: Color) -> Piece:
    f, d, w = _Frame(name, room, center, yaw), depth / 2, width / 2
    f.box("body", (-d, -w, 0.0), (d - 0.02, w, height), color)
    f.box("door_left", (d - 0.02, 0.005, 0.05), (d, w - 0.01, height - 0.05), tuple(0.92 * c for c in color))
    f.box("door_right", (d - 0.02, -w + 0.01, 0.05), (d, -0.005, height - 0.05), tuple(0.92 * c for c in color))
    return f.piece(depth, width, height)


def chair(name: str, room: str, center: Vec2, yaw: float, color: Color) -> Piece:
    """A dining chair facing local +x (its backrest at the back). Seat 0.46 m, backrest 0.9 m. Not a support."""
    f, s = _Frame(name, room, center, yaw), 0.21
    for i, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        x, y = sx * (s - 0.03), sy * (s - 0.03)
        f.box(f"leg_{i}", (x - 0.02, y - 0.02, 0.0), (x + 0.02, y + 0.02, 0.42), color)
    f.box("seat", (-s, -s, 0.42), (s, s, 0.46), color)
    f.box("back", (-s, -s, 0.46), (-s + 0.04, s, 0.90), color)
    return f.piece(2 * s, 2 * s, 0.90)


def pickup_truck(
    name: str, room: str, center: Vec2, yaw: float, length: float, width: float, bed_height: float, color: Color,
    support_name: str,
) -> Piece:
    """A pickup: cab at the front (local +x), open cargo bed behind it whose floor is a "vehicle" support."""
    f = _Frame(name, room, center, yaw, kind="vehicle")
    d, w, cab, wall = length / 2, width / 2, length * 0.45, 0.06
    dark = (0.08, 0.08, 0.09)
    for i, x in enumerate((d - 0.85, -d + 0.85)):
        for j, y in enumerate((w - 0.14, -w + 0.14)):
            f.box(f"wheel_{i}{j}", (x - 0.36, y - 0.13, 0.0), (x + 0.36, y + 0.13, 0.72), dark)
    f.box("chassis", (-d, -w + 0.02, 0.40), (d, w - 0.02, bed_height), color)
    f.box("hood", (d - 0.95, -w, bed_height), (d, w, bed_height + 0.22), color)
    f.box("cabin", (d - cab, -w, bed_height), (d - 0.95, w, bed_height + 0.95), color)
    f.box("windshield", (d - 0.97, -w + 0.08, bed_height + 0.35), (d - 0.95, w - 0.08, bed_height + 0.88), (0.15, 0.2, 0.25))
    top = bed_height + 0.45
    f.box("bed_left", (-d, w - wall, bed_height), (d - cab, w, top), color)
    f.box("bed_right", (-d, -w, bed_height), (d - cab, -w + wall, top), color)
    f.box("tailgate", (-d, -w + wall, bed_height), (-d + wall, w - wall, top), color)
    f.support(support_name, "vehicle", (-d + wall, -w + wall), (d - cab, w - wall), bed_height)
    return f.piece(length, width, bed_height + 0.95)


# --------------------------------------------------------------------------------------------------------------------
# Structure: walls with doorways, floors, ceilings
# --------------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Opening:
    """A doorway in a wall: centre measured along the wall from its start, width, height."""

    offset: float
    width: float
    height: float


def wall(
    name: str, start: Vec2, end: Vec2, height: float, color: Color, openings: Sequence[Opening] = (),
    thickness: float = WALL_THICKNESS_M,
) -> tuple[Box, ...]:
    """A straight wall centred on the segment start-end, split around its doorways (with lintels above them)."""
    length = math.dist(start, end)
    yaw = math.atan2(end[1] - start[1], end[0] - start[0])
    f = _Frame(name, "", ((start[0] + end[0]) / 2, (start[1] + end[1]) / 2), yaw, kind="wall")
    t, cursor = thickness / 2, -length / 2
    for i, o in enumerate(sorted(openings, key=lambda o: o.offset)):
        a, b = o.offset - o.width / 2 - length / 2, o.offset + o.width / 2 - length / 2
        if a - cursor > 1e-6:
            f.box(f"segment_{i}", (cursor, -t, 0.0), (a, t, height), color)
        f.box(f"lintel_{i}", (a, -t, o.height), (b, t, height), color)
        cursor = b
    if length / 2 - cursor > 1e-6:
        f.box("segment_end", (cursor, -t, 0.0), (length / 2, t, height), color)
    return tuple(f.boxes)


def slab(name: str, lo: Vec2, hi: Vec2, z_top: float, thickness: float, color: Color, kind: str) -> Box:
    """A horizontal slab (floor, ceiling, road) whose top face is at `z_top`."""
    center = ((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, z_top - thickness / 2)
    return Box(name, center, ((hi[0] - lo[0]) / 2, (hi[1] - lo[1]) / 2, thickness / 2), 0.0, color, kind)


def room_shell(
    prefix: str, lo: Vec2, hi: Vec2, height: float, wall_color: Color, floor_color: Color,
    openings: Mapping[str, Sequence[Opening]] | None = None, ceiling_color: Color = (0.95, 0.95, 0.94),
    thickness: float = WALL_THICKNESS_M,
) -> tuple[Box, ...]:
    """Floor (top at z = 0), ceiling (bottom at `height`) and four walls outside the interior rectangle lo-hi.

    `openings` per side ("south", "north", "west", "east"); offsets are measured from the interior's west (for the
    south and north walls) or south (west and east walls) edge.
    """
    t, (x0, y0), (x1, y1) = thickness, lo, hi
    openings = openings or {}

    def along(side: str, extra: float) -> list[Opening]:
        return [Opening(o.offset + extra, o.width, o.height) for o in openings.get(side, ())]

    return (
        slab(f"{prefix}floor", (x0 - t, y0 - t), (x1 + t, y1 + t), 0.0, 0.1, floor_color, "floor"),
        slab(f"{prefix}ceiling", (x0 - t, y0 - t), (x1 + t, y1 + t), height + 0.1, 0.1, ceiling_color, "ceiling"),
        *wall(f"{prefix}wall_south", (x0 - t, y0 - t / 2), (x1 + t, y0 - t / 2), height, wall_color, along("south", t), t),
        *wall(f"{prefix}wall_north", (x0 - t, y1 + t / 2), (x1 + t, y1 + t / 2), height, wall_color, along("north", t), t),
        *wall(f"{prefix}wall_west", (x0 - t / 2, y0), (x0 - t / 2, y1), height, wall_color, along("west", 0.0), t),
        *wall(f"{prefix}wall_east", (x1 + t / 2, y0), (x1 + t / 2, y1), height, wall_color, along("east", 0.0), t),
    )


# --------------------------------------------------------------------------------------------------------------------
# Geometry on boxes (numpy): distances, footprint overlap, support fitting, free points
# --------------------------------------------------------------------------------------------------------------------
def boxes_array(boxes: Sequence[Box]) -> np.ndarray:
    """`(B, 7)`: centre xyz, half sizes xyz, yaw."""
    if not boxes:
        return np.zeros((0, 7))
    return np.array([[*b.center, *b.half_size, b.yaw] for b in boxes], dtype=np.float64)


def point_box_distance(points: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Signed distance from points `(P, 3)` to oriented boxes `(B, 7)`: `(P, B)`, negative inside."""
    d = points[:, None, :] - boxes[None, :, 0:3]
    c, s = np.cos(boxes[:, 6]), np.sin(boxes[:, 6])
    local = np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1], d[..., 2]], axis=-1)
    q = np.abs(local) - boxes[None, :, 3:6]
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)


def box_aabbs(boxes: np.ndarray) -> np.ndarray:
    """`(B, 6)` axis-aligned bounds: xlo, ylo, zlo, xhi, yhi, zhi."""
    c, s = np.abs(np.cos(boxes[:, 6])), np.abs(np.sin(boxes[:, 6]))
    ex = c * boxes[:, 3] + s * boxes[:, 4]
    ey = s * boxes[:, 3] + c * boxes[:, 4]
    ext = np.stack([ex, ey, boxes[:, 5]], axis=-1)
    return np.concatenate([boxes[:, 0:3] - ext, boxes[:, 0:3] + ext], axis=-1)


def rects_overlap(a: tuple[Vec2, Vec2, float], b: tuple[Vec2, Vec2, float], gap: float = 0.0) -> bool:
    """Whether two oriented rectangles (centre, half size, yaw) come closer than `gap` (separating axis test;
    `gap` inflates `a`, so corners count as square)."""
    # plain floats: a layout makes thousands of these tests, and a 2-vector in numpy costs microseconds an op. A
    # product of two 2-vectors is `x0 * y0 + x1 * y1`, the very sum numpy's dot makes of them (no fused multiply-add:
    # checked on random vectors), so every test, and so every layout a seed gives, is what it was with numpy.
    (ca, ha, ya), (cb, hb, yb) = a, b
    ha = (ha[0] + gap, ha[1] + gap)
    dx, dy = cb[0] - ca[0], cb[1] - ca[1]
    axes_a = ((math.cos(ya), math.sin(ya)), (-math.sin(ya), math.cos(ya)))
    axes_b = ((math.cos(yb), math.sin(yb)), (-math.sin(yb), math.cos(yb)))
    for ax, ay in axes_a + axes_b:
        ra = sum(h * abs(ax * ux + ay * uy) for h, (ux, uy) in zip(ha, axes_a))
        rb = sum(h * abs(ax * ux + ay * uy) for h, (ux, uy) in zip(hb, axes_b))
        if abs(ax * dx + ay * dy) >= ra + rb:
            return False
    return True


def boxes_overlap(a: Box, b: Box, gap: float = 0.0) -> bool:
    """Oriented boxes (yaw only) closer than `gap`: vertical ranges and footprints both overlap."""
    if a.center[2] - a.half_size[2] >= b.center[2] + b.half_size[2] + gap:
        return False
    if b.center[2] - b.half_size[2] >= a.center[2] + a.half_size[2] + gap:
        return False
    return rects_overlap((a.center[:2], a.half_size[:2], a.yaw), (b.center[:2], b.half_size[:2], b.yaw), gap)


def _hover_valid(points: np.ndarray, height: float, aabbs: np.ndarray) -> np.ndarray:
    """Whether the drone's footprint square over each point `(P, 2)` is free from the disk height band up to the
    clear height above a surface at `height`."""
    z_lo, z_hi = height + HOVER_DISK_CLEARANCE_M - 0.1, height + CLEAR_HEIGHT_M
    band = aabbs[(aabbs[:, 2] < z_hi) & (aabbs[:, 5] > z_lo)]
    if len(band) == 0:
        return np.ones(len(points), dtype=bool)
    r = ROTOR_REACH_M
    hit = (
        (points[:, None, 0] + r > band[None, :, 0]) & (points[:, None, 0] - r < band[None, :, 3])
        & (points[:, None, 1] + r > band[None, :, 1]) & (points[:, None, 1] - r < band[None, :, 4])
    )
    return ~hit.any(axis=1)


def clear_height(support: Support, aabbs: np.ndarray) -> float:
    """Free height above a support's area: to the lowest box bottom above it (inf when nothing is above); `aabbs`
    are the boxes' bounds (`box_aabbs`)."""
    c, s = abs(math.cos(support.yaw)), abs(math.sin(support.yaw))
    ex = c * support.half_size[0] + s * support.half_size[1]
    ey = s * support.half_size[0] + c * support.half_size[1]
    over = (
        (aabbs[:, 0] < support.center[0] + ex) & (aabbs[:, 3] > support.center[0] - ex)
        & (aabbs[:, 1] < support.center[1] + ey) & (aabbs[:, 4] > support.center[1] - ey)
        & (aabbs[:, 2] >= support.height - 1e-6)
    )
    return float(aabbs[over, 2].min() - support.height) if over.any() else math.inf


def fit_support(support: Support, aabbs: np.ndarray) -> Support | None:
    """Shrink a support until a hovering quadrotor clears every box over all of it (module docstring); None if
    less than `MIN_SUPPORT_SIDE_M` a side is left or something sits lower than `CLEAR_HEIGHT_M` above it. `aabbs`
    are the boxes' bounds (`box_aabbs`)."""
    hx, hy = support.half_size
    if min(hx, hy) * 2 < MIN_SUPPORT_SIDE_M:
        return None
    xs = np.linspace(-hx, hx, max(2, int(math.ceil(2 * hx / FIT_STEP_M)) + 1))
    ys = np.linspace(-hy, hy, max(2, int(math.ceil(2 * hy / FIT_STEP_M)) + 1))
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    c, s = math.cos(support.yaw), math.sin(support.yaw)
    pts = np.stack([support.center[0] + c * gx - s * gy, support.center[1] + s * gx + c * gy], axis=-1)
    valid = _hover_valid(pts.reshape(-1, 2), support.height, aabbs).reshape(gx.shape)
    i0, i1, j0, j1 = 0, len(xs) - 1, 0, len(ys) - 1
    while not valid[i0 : i1 + 1, j0 : j1 + 1].all():
        bad = ~valid[i0 : i1 + 1, j0 : j1 + 1]
        edges = [bad[0].sum(), bad[-1].sum(), bad[:, 0].sum(), bad[:, -1].sum()]
        if max(edges) == 0:  # blocked only inside: cut from the side nearest to the blocked cells
            ii, jj = np.nonzero(bad)
            edges = [-ii.min(), ii.max() - len(bad), -jj.min(), jj.max() - bad.shape[1]]
        k = int(np.argmax(edges))
        i0, i1, j0, j1 = i0 + (k == 0), i1 - (k == 1), j0 + (k == 2), j1 - (k == 3)
        if xs[i1] - xs[i0] < MIN_SUPPORT_SIDE_M or ys[j1] - ys[j0] < MIN_SUPPORT_SIDE_M:
            return None
    lx, ly = (xs[i0] + xs[i1]) / 2, (ys[j0] + ys[j1]) / 2
    fitted = replace(
        support,
        center=(float(support.center[0] + c * lx - s * ly), float(support.center[1] + s * lx + c * ly)),
        half_size=(float((xs[i1] - xs[i0]) / 2), float((ys[j1] - ys[j0]) / 2)),
    )
    above = clear_height(fitted, aabbs)
    if above < CLEAR_HEIGHT_M:
        return None
    return replace(fitted, clear_height=above)


def free_point(
    target: Vec3, boxes: np.ndarray, lo: Vec3, hi: Vec3, clearance: float = NAV_CLEARANCE_M + 0.05,
    max_shift: float = 1.5, toward: Vec2 | None = None,
) -> Vec3 | None:
    """The point nearest to `target` at the same height that is `clearance` from every box and inside the bounds.

    Candidates lie on a 5 cm grid in growing squares; with `toward` (a unit vector), the search is a line that way.
    """
    step = 0.05
    n = int(max_shift / step)
    if toward is not None:
        cand = np.array([[target[0] + k * step * toward[0], target[1] + k * step * toward[1]] for k in range(n + 1)])
    else:
        dx, dy = _square_search_offsets(n, step)
        cand = np.stack([target[0] + dx, target[1] + dy], axis=-1)
    pts = np.concatenate([cand, np.full((len(cand), 1), target[2])], axis=-1)
    inside = (
        (pts[:, 0] > lo[0] + clearance) & (pts[:, 0] < hi[0] - clearance)
        & (pts[:, 1] > lo[1] + clearance) & (pts[:, 1] < hi[1] - clearance)
    )
    pts = pts[inside]
    if len(boxes):  # only boxes that can come within `clearance` of some candidate matter
        reach = clearance + max_shift + 0.05
        aabbs = box_aabbs(boxes)
        near = (
            (aabbs[:, 0] < target[0] + reach) & (aabbs[:, 3] > target[0] - reach)
            & (aabbs[:, 1] < target[1] + reach) & (aabbs[:, 4] > target[1] - reach)
            & (aabbs[:, 2] < target[2] + clearance) & (aabbs[:, 5] > target[2] - clearance)
        )
        boxes = boxes[near]
    for start in range(0, len(pts), 256):  # nearest candidates first; most targets are free at once
        chunk = pts[start : start + 256]
        ok = point_box_distance(chunk, boxes).min(axis=1) >= clearance if len(boxes) else np.ones(len(chunk), bool)
        if ok.any():
            p = chunk[int(np.argmax(ok))]
            return (float(p[0]), float(p[1]), float(p[2]))
    return None


@lru_cache(maxsize=8)
def _square_search_offsets(n: int, step: float) -> tuple[np.ndarray, np.ndarray]:
    """`free_point`'s grid offsets (x, y) in search order: growing squares, nearest first within each. The same for
    every call with the same grid (a layout makes dozens of calls), so made once; read-only."""
    g = np.arange(-n, n + 1) * step
    gx, gy = np.meshgrid(g, g, indexing="ij")
    order = np.argsort(np.maximum(np.abs(gx), np.abs(gy)).ravel() * 10 + np.hypot(gx, gy).ravel(), kind="stable")
    offsets = gx.ravel()[order], gy.ravel()[order]
    for a in offsets:
        a.flags.writeable = False
    return offsets


# --------------------------------------------------------------------------------------------------------------------
# Placement inside a room, and turning whole layouts
# --------------------------------------------------------------------------------------------------------------------
@dataclass
class Placer:
    """Places pieces in a rectangular room interior: `gap` between furniture footprints, and out of reserved regions
    (doorway approaches, fixture swing and front space), which are themselves free space."""

    room: Room
    gap: float = 0.4
    placed: list[tuple[Vec2, Vec2, float]] = field(default_factory=list)  # footprints: centre, half size, yaw
    reserved: list[tuple[Vec2, Vec2, float]] = field(default_factory=list)

    def reserve(self, center: Vec2, half: Vec2, yaw: float = 0.0) -> None:
        self.reserved.append((center, half, yaw))

    def fits(self, center: Vec2, half: Vec2, yaw: float, wall_gap: float = 0.02, gap: float | None = None) -> bool:
        c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
        ex, ey = c * half[0] + s * half[1], s * half[0] + c * half[1]
        (x0, y0), (x1, y1) = self.room.lo, self.room.hi
        if center[0] - ex < x0 + wall_gap - 1e-9 or center[0] + ex > x1 - wall_gap + 1e-9:
            return False
        if center[1] - ey < y0 + wall_gap - 1e-9 or center[1] + ey > y1 - wall_gap + 1e-9:
            return False
        g = self.gap if gap is None else gap
        rect = (center, half, yaw)
        return not any(rects_overlap(rect, r, g) for r in self.placed) and not any(
            rects_overlap(rect, r, 0.02) for r in self.reserved
        )

    def against_wall(self, rng: np.random.Generator, depth: float, width: float, sides: Sequence[str], side_on: bool = False,
                     tries: int = 40, wall_gap: float = 0.02) -> tuple[Vec2, float] | None:
        """A free spot with the piece's back (or, `side_on`, its side) against one of `sides` (north/south/east/west)."""
        (x0, y0), (x1, y1) = self.room.lo, self.room.hi
        for _ in range(tries):
            side = sides[int(rng.integers(len(sides)))]
            yaw = {"south": math.pi / 2, "north": -math.pi / 2, "west": 0.0, "east": math.pi}[side]
            # the extent of the piece measured away from the wall and along it
            out, along = (width, depth) if side_on else (depth, width)
            if side_on:
                yaw += math.pi / 2 * (1 if rng.random() < 0.5 else -1)
            if side in ("south", "north"):
                if x1 - x0 < along + 2 * wall_gap:
                    continue
                x = rng.uniform(x0 + along / 2 + wall_gap, x1 - along / 2 - wall_gap)
                y = y0 + wall_gap + out / 2 if side == "south" else y1 - wall_gap - out / 2
            else:
                if y1 - y0 < along + 2 * wall_gap:
                    continue
                y = rng.uniform(y0 + along / 2 + wall_gap, y1 - along / 2 - wall_gap)
                x = x0 + wall_gap + out / 2 if side == "west" else x1 - wall_gap - out / 2
            if self.fits((x, y), (depth / 2, width / 2), yaw, wall_gap):
                return (float(x), float(y)), float(yaw)
        return None

    def free_standing(self, rng: np.random.Generator, depth: float, width: float, wall_gap: float = 0.6,
                      yaw_jitter: float = 0.0, tries: int = 40, gap: float | None = None) -> tuple[Vec2, float] | None:
        (x0, y0), (x1, y1) = self.room.lo, self.room.hi
        for _ in range(tries):
            yaw = float(rng.integers(2)) * math.pi / 2 + rng.uniform(-yaw_jitter, yaw_jitter)
            x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
            if self.fits((float(x), float(y)), (depth / 2, width / 2), yaw, wall_gap, gap):
                return (float(x), float(y)), yaw
        return None

    def add(self, piece: Piece) -> Piece:
        self.placed.append((piece.center, piece.half_size, piece.yaw))
        return piece


def turn_layout(layout: SceneLayout, quarter_turns: int, shift: Vec2 = (0.0, 0.0)) -> SceneLayout:
    """The same scene turned by `quarter_turns` x 90 degrees about the origin, then shifted (rooms stay axis-aligned)."""
    a = (quarter_turns % 4) * math.pi / 2
    c, s = round(math.cos(a)), round(math.sin(a))

    def pt(x: float, y: float) -> Vec2:
        return (c * x - s * y + shift[0], s * x + c * y + shift[1])

    def yaw(v: float) -> float:
        return math.remainder(v + a, 2 * math.pi)

    def rect(lo, hi):
        p, q = pt(lo[0], lo[1]), pt(hi[0], hi[1])
        return (min(p[0], q[0]), min(p[1], q[1])), (max(p[0], q[0]), max(p[1], q[1]))

    lo, hi = rect(layout.workspace_lo, layout.workspace_hi)
    sx, sy = layout.sun_direction[:2]
    return replace(
        layout,
        boxes=tuple(replace(b, center=(*pt(*b.center[:2]), b.center[2]), yaw=yaw(b.yaw)) for b in layout.boxes),
        supports=tuple(replace(sp, center=pt(*sp.center), yaw=yaw(sp.yaw)) for sp in layout.supports),
        rooms=tuple(Room(r.name, *rect(r.lo, r.hi)) for r in layout.rooms),
        workspace_lo=(lo[0], lo[1], layout.workspace_lo[2]),
        workspace_hi=(hi[0], hi[1], layout.workspace_hi[2]),
        nav_points={k: (*pt(*v[:2]), v[2]) for k, v in layout.nav_points.items()},
        fixtures=tuple(replace(f, position=(*pt(*f.position[:2]), f.position[2]), yaw=yaw(f.yaw)) for f in layout.fixtures),
        doorways=tuple(Doorway((*pt(*d.center[:2]), d.center[2]), d.rooms, d.width) for d in layout.doorways),
        sun_direction=(c * sx - s * sy, s * sx + c * sy, layout.sun_direction[2]),
    )


def support_nav_points(supports: Sequence[Support], boxes: np.ndarray, lo: Vec3, hi: Vec3, above: float = 0.8) -> dict[str, Vec3]:
    """A flight target about `above` over each pick / place support, named like the support, where one is free
    within 0.5 m (none for fridge shelves and the drawer: those are reached from the front)."""
    out = {}
    for s in supports:
        if s.kind in ("fridge_shelf", "drawer"):
            continue
        z = min(s.height + above, hi[2] - NAV_CLEARANCE_M - 0.1)
        p = free_point((s.center[0], s.center[1], z), boxes, lo, hi, max_shift=0.5)
        if p is not None:
            out[s.name] = p
    return out


def fitted_supports(candidates: Sequence[Support], boxes: np.ndarray) -> tuple[Support, ...]:
    """`fit_support` over a list, dropping the unusable ones."""
    aabbs = box_aabbs(boxes)  # once for the list: the same boxes for every support
    return tuple(f for f in (fit_support(s, aabbs) for s in candidates) if f is not None)

