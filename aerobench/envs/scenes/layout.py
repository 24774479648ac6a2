"""Scene layouts as plain data: what a procedural scene generator returns and what everything else reads.

A layout is generated from a numpy `Generator` (pure and seeded), then built into SAPIEN actors by
`scenes.build.build_layouts`. The same data serves the expert's planner, the clearance checks and the instructions,
so nothing has to query the simulator for furniture geometry. Coordinates are in the env frame (metres, z up, the
floor at z = 0); yaw is about +z.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]
Color = tuple[float, float, float]


@dataclass(frozen=True)
class Box:
    """A static oriented box: wall, floor, furniture part. Used for building, planning and clearance."""

    name: str
    center: Vec3
    half_size: Vec3
    yaw: float = 0.0
    color: Color = (0.7, 0.7, 0.7)
    kind: str = "furniture"  # "floor" | "wall" | "ceiling" | "furniture" | "vehicle" | ...

    @property
    def top(self) -> float:
        return self.center[2] + self.half_size[2]


@dataclass(frozen=True)
class Support:
    """A horizontal surface objects can rest on and be picked from or placed on.

    `center`/`half_size` describe the usable top area (already shrunk by a margin from the furniture's edges),
    `height` the surface's z, `clear_height` the free space above it (inf when nothing is above).
    `name` is the phrase instructions use ("the kitchen counter"), `kind` the category tasks filter on.
    """

    name: str
    kind: str  # "table" | "counter" | "shelf" | "cabinet" | "sofa" | "vehicle" | "fridge_shelf" | "drawer"
    room: str
    center: Vec2
    half_size: Vec2
    height: float
    yaw: float = 0.0
    clear_height: float = math.inf

    def contains(self, x: float, y: float, margin: float = 0.0) -> bool:
        c, s = math.cos(-self.yaw), math.sin(-self.yaw)
        dx, dy = x - self.center[0], y - self.center[1]
        lx, ly = c * dx - s * dy, s * dx + c * dy
        return abs(lx) <= self.half_size[0] - margin and abs(ly) <= self.half_size[1] - margin


@dataclass(frozen=True)
class Room:
    name: str  # "kitchen", "living room", "bedroom", "street", "lobby"
    lo: Vec2
    hi: Vec2


@dataclass(frozen=True)
class Doorway:
    """An opening a drone flies through between two rooms: its centre (mid-wall, at the nav height) and width."""

    center: Vec3
    rooms: tuple[str, str]
    width: float


@dataclass(frozen=True)
class ArticulatedFixture:
    """A fridge (hinged door with a vertical bar handle) or a counter drawer (sliding, horizontal handle).

    `position` places the fixture's root frame: origin on the floor at the middle of the carcass front (see
    `scenes.articulated` for the exact frames); `yaw` turns the fixture so its front faces (cos yaw, sin yaw).
    """

    name: str  # "fridge" | "drawer"
    kind: str  # "hinge" | "slide"
    position: Vec3
    yaw: float
    room: str


@dataclass(frozen=True)
class SceneLayout:
    """Everything a generated scene contains, in the env frame."""

    name: str
    boxes: tuple[Box, ...]
    supports: tuple[Support, ...]
    rooms: tuple[Room, ...]
    workspace_lo: Vec3
    workspace_hi: Vec3
    nav_points: dict[str, Vec3] = field(default_factory=dict)  # named flight targets ("the room entrance")
    fixtures: tuple[ArticulatedFixture, ...] = ()
    doorways: tuple[Doorway, ...] = ()  # the openings joining `rooms` (the room graph the routes follow)
    ambient_light: Color = (0.3, 0.3, 0.3)
    sun_direction: Vec3 = (1.0, 1.0, -1.0)
    sun_color: Color = (1.0, 1.0, 1.0)

    def supports_of(self, kinds: tuple[str, ...]) -> tuple[Support, ...]:
        return tuple(s for s in self.supports if s.kind in kinds)

    def fixture(self, name: str) -> ArticulatedFixture | None:
        return next((f for f in self.fixtures if f.name == name), None)
