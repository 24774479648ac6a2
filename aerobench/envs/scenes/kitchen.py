"""The PrepareGroceries kitchen: counters along the walls, an island or table, a fridge and a counter drawer.

`furnish_kitchen` fills a kitchen room in a frame where its back wall is the north wall (+y) and its way in is on the
south side; `generate_kitchen` wraps it in a closed room (turned at random), and `scenes.home` puts it into the
apartment. The fridge stands at the west end of the back counter run, its door opening toward the counters (a drone
pulling the handle swings out over them); the drawer cabinet sits in the run, flush with the counters. Both keep `articulated.FRONT_FREE_DEPTH_M` of free floor in front of their handles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .articulated import (
    DRAWER_CABINET_HEIGHT_M,
    DRAWER_CABINET_WIDTH_M,
    FRIDGE_CARCASS_DEPTH_M,
    FRIDGE_WIDTH_M,
    fixture_boxes,
    fixture_keepout_boxes,
    fixture_supports,
    front_point,
)
from .furniture import (
    FLOOR_COLORS,
    PAINT_COLORS,
    STONE_COLORS,
    WALL_COLORS,
    WOOD_COLORS,
    Opening,
    Piece,
    Placer,
    boxes_array,
    counter,
    fitted_supports,
    free_point,
    pick_color,
    random_lighting,
    room_shell,
    support_nav_points,
    table,
    turn_layout,
)
from .layout import ArticulatedFixture, Box, Room, SceneLayout, Support, Vec3

KITCHEN_WIDTH_M = (4.6, 5.6)
KITCHEN_DEPTH_M = (4.4, 5.2)
CEILING_HEIGHT_M = (2.6, 2.8)
COUNTER_DEPTH_M = (0.64, 0.70)  # deep enough that the drone can hover over the counter's front half (furniture.py)
WALL_GAP_M = 0.02
HINGE_SIDE_GAP_M = 0.35  # beside the fridge's hinge: the open door and its handle swing 0.32 m past the carcass
# beside its free edge: a drone pinching the handle (7 cm in from that edge) spreads its rotor disks 0.25 m past it,
# and the spec's clearance check C wants them >= 3 cm from everything: 0.40 m leaves 12 cm of margin for the approach
FREE_EDGE_WALL_GAP_M = 0.40
UPPER_CABINET_CLEARANCE_M = 0.95  # wall cabinets start this far above the counter (>= furniture.CLEAR_HEIGHT_M)
WALKWAY_M = 0.8  # around the island


@dataclass
class Furnishing:
    """What a room generator adds: furniture pieces, extra boxes, fixtures, fixture supports, nav points."""

    pieces: list[Piece] = field(default_factory=list)
    boxes: list[Box] = field(default_factory=list)
    fixtures: list[ArticulatedFixture] = field(default_factory=list)
    supports: list[Support] = field(default_factory=list)
    nav_points: dict[str, Vec3] = field(default_factory=dict)


def furnish_kitchen(rng: np.random.Generator, room: Room, placer: Placer, ceiling: float) -> Furnishing | None:
    """Fill `room` (back wall north, ceiling at `ceiling`). `placer` already holds the doorway approaches. None if the
    island finds no room (the caller draws again)."""
    (x0, y0), (x1, y1) = room.lo, room.hi
    out = Furnishing()
    depth = rng.uniform(*COUNTER_DEPTH_M)
    height = DRAWER_CABINET_HEIGHT_M  # the drawer cabinet sets the counter height
    base, top = pick_color(rng, PAINT_COLORS + WOOD_COLORS), pick_color(rng, STONE_COLORS)
    south = -math.pi / 2  # yaw of everything on the back wall: fronts face south

    # Fridge at the west end of the back run. Its hinge is on its local +y side, which is world +x when it faces
    # south: the door swings open toward the counters, where a drone holding the handle has room above them.
    fx = x0 + FREE_EDGE_WALL_GAP_M + FRIDGE_WIDTH_M / 2
    fridge = ArticulatedFixture("fridge", "hinge", (fx, y1 - WALL_GAP_M - FRIDGE_CARCASS_DEPTH_M, 0.0), south, room.name)
    run = (fx + FRIDGE_WIDTH_M / 2 + HINGE_SIDE_GAP_M, x1 - WALL_GAP_M)

    # The drawer cabinet inside the run, flush with the counters' base fronts; at least 0.5 m of counter each side.
    w = DRAWER_CABINET_WIDTH_M
    left = rng.uniform(0.5, run[1] - run[0] - w - 0.5)
    xd = run[0] + left + w / 2
    drawer = ArticulatedFixture("drawer", "slide", (xd, y1 - WALL_GAP_M - depth + 0.03, 0.0), south, room.name)
    out.fixtures += [fridge, drawer]
    for fixture in out.fixtures:
        for keep in fixture_keepout_boxes(fixture):
            placer.reserve(keep.center[:2], keep.half_size[:2], keep.yaw)

    segments = [(run[0], xd - w / 2 - 0.005), (xd + w / 2 + 0.005, run[1])]
    names = ["the kitchen counter", "the short counter"]
    if segments[0][1] - segments[0][0] < segments[1][1] - segments[1][0]:
        names.reverse()
    back_y = y1 - WALL_GAP_M - depth / 2
    counters = [
        counter(f"counter_{i}", room.name, ((a + b) / 2, back_y), south, depth, b - a, height, base, top, name)
        for i, ((a, b), name) in enumerate(zip(segments, names))
    ]

    # An L-shaped side run on the east wall, when it leaves the drawer's front free.
    if rng.random() < 0.6:
        length = rng.uniform(1.0, 2.0)
        ys = y1 - WALL_GAP_M - depth - 0.005 - length / 2
        xs, yaw = x1 - WALL_GAP_M - depth / 2, math.pi
        if ys - length / 2 > y0 + 0.5 and placer.fits((xs, ys), (depth / 2, length / 2), yaw, wall_gap=0.0, gap=0.0):
            counters.append(counter("counter_side", room.name, (xs, ys), yaw, depth, length, height, base, top, "the side counter"))
    out.pieces += [placer.add(c) for c in counters]

    # Wall cabinets over the back run: high enough to leave the counters' clear height.
    z0 = height + UPPER_CABINET_CLEARANCE_M
    z1 = min(z0 + 0.7, ceiling - 0.05)
    if z1 - z0 > 0.3:
        split = rng.uniform(run[0] + 0.4, run[1] - 0.4)
        for i, (a, b) in enumerate(((run[0], split), (split, run[1]))):
            out.boxes.append(
                Box(f"upper_cabinets/part_{i}", ((a + b) / 2, y1 - WALL_GAP_M - 0.175, (z0 + z1) / 2),
                    ((b - a) / 2 - 0.003, 0.175, (z1 - z0) / 2), 0.0, base)
            )

    island = _place_island(rng, room, placer)
    if island is None:
        return None
    out.pieces.append(placer.add(island))
    out.supports += [*fixture_supports(fridge), *fixture_supports(drawer)]
    out.nav_points["the fridge"] = front_point(fridge, 1.0, 1.3)
    out.nav_points["the kitchen drawer"] = front_point(drawer, 1.0, 1.2)
    return out


def _place_island(rng: np.random.Generator, room: Room, placer: Placer) -> Piece | None:
    """A kitchen island (counter height) or a kitchen table, shrinking until it fits with walkways around it."""
    as_island = rng.random() < 0.6
    for scale in (1.0, 0.85, 0.7):
        d = rng.uniform(0.8, 1.0) * scale if as_island else rng.uniform(0.75, 0.9) * scale
        w = rng.uniform(1.2, 1.8) * scale
        spot = placer.free_standing(rng, d, w, wall_gap=WALKWAY_M, gap=WALKWAY_M, tries=60)
        if spot is None:
            continue
        (center, yaw) = spot
        if as_island:
            return counter("island", room.name, center, yaw, d, w, 0.9, pick_color(rng, PAINT_COLORS),
                           pick_color(rng, STONE_COLORS), "the kitchen island")
        wood = pick_color(rng, WOOD_COLORS)
        return table("kitchen_table", room.name, center, yaw, d, w, rng.uniform(0.74, 0.78), wood, wood, "the kitchen table")
    return None


def generate_kitchen(rng: np.random.Generator) -> SceneLayout:
    """A kitchen with counters, an island or table, a fridge and a counter drawer (PrepareGroceries)."""
    for _ in range(20):
        layout = _try_kitchen(rng)
        if layout is not None:
            return layout
    raise RuntimeError("kitchen generation failed 20 times in a row; the size ranges leave no room for the island")


def _try_kitchen(rng: np.random.Generator) -> SceneLayout | None:
    width, depth, ceiling = rng.uniform(*KITCHEN_WIDTH_M), rng.uniform(*KITCHEN_DEPTH_M), rng.uniform(*CEILING_HEIGHT_M)
    room = Room("kitchen", (0.0, 0.0), (width, depth))
    door_w = rng.uniform(0.85, 1.0)
    door_x = rng.uniform(0.3 + door_w / 2, width - 0.3 - door_w / 2)
    wall_color = pick_color(rng, WALL_COLORS)
    boxes = list(room_shell("", room.lo, room.hi, ceiling, wall_color, pick_color(rng, FLOOR_COLORS),
                            {"south": [Opening(door_x, door_w, 2.05)]}))
    # The way out stays shut: a closed door in the south wall (the kitchen alone is the whole scene).
    boxes.append(Box("door", (door_x, -0.06, 1.025), (door_w / 2, 0.03, 1.025), 0.0, pick_color(rng, WOOD_COLORS), "wall"))
    placer = Placer(room)
    placer.reserve((door_x, 0.5), (door_w / 2 + 0.2, 0.5))
    furnished = furnish_kitchen(rng, room, placer, ceiling)
    if furnished is None:
        return None
    for piece in furnished.pieces:
        boxes += piece.boxes
    boxes += furnished.boxes
    obstacles = boxes_array(boxes + [b for f in furnished.fixtures for b in fixture_boxes(f, 0.0)])
    supports = fitted_supports([s for p in furnished.pieces for s in p.supports], obstacles) + tuple(furnished.supports)
    lo, hi = (0.0, 0.0, 0.0), (width, depth, ceiling)
    nav = dict(furnished.nav_points)
    centre = free_point((width / 2, depth / 2, 1.5), obstacles, lo, hi)
    if centre is None:
        return None
    nav["the kitchen"] = centre
    nav.update(support_nav_points(supports, obstacles, lo, hi))
    layout = SceneLayout(
        name="kitchen", boxes=tuple(boxes), supports=supports, rooms=(room,), workspace_lo=lo, workspace_hi=hi,
        nav_points=nav, fixtures=tuple(furnished.fixtures), **random_lighting(rng),
    )
    return turn_layout(turn_layout(layout, 0, (-width / 2, -depth / 2)), int(rng.integers(4)))

