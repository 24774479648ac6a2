"""The TidyHouse apartment: four rooms in two rows, joined by doorways, furnished with tables, counters, a sofa, open
shelves and cabinets.

Plan (before a random quarter turn): a bottom row with the living room and the dining room (random order) joined by a
wide opening, a top row with the bedroom and a study (or, for `scenes.home`, the kitchen), each reached through a
doorway from the room below it. Room sizes, doorway positions, furniture choice, sizes, places and colours, and the
light come from the rng. Doorways are 1.3-1.5 m wide and 2.1-2.25 m tall: the X500 with its rotor disks is 0.64 m
across and needs margin on both sides.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .articulated import fixture_boxes
from .furniture import (
    FABRIC_COLORS,
    FLOOR_COLORS,
    PAINT_COLORS,
    STONE_COLORS,
    WALL_COLORS,
    WALL_THICKNESS_M,
    WOOD_COLORS,
    Opening,
    Piece,
    Placer,
    bed,
    boxes_array,
    cabinet,
    chair,
    counter,
    fitted_supports,
    free_point,
    pick_color,
    random_lighting,
    shelf_unit,
    slab,
    sofa,
    support_nav_points,
    table,
    turn_layout,
    wall,
    wardrobe,
)
from .kitchen import CEILING_HEIGHT_M, KITCHEN_DEPTH_M, KITCHEN_WIDTH_M, Furnishing, furnish_kitchen
from .layout import Box, Doorway, Room, SceneLayout, Vec2, Vec3

ROOM_WIDTH_M = {  # the bottom row draws from these; the top row splits the same width, each room >= its minimum
    "living room": (4.6, 5.8),
    "dining room": (3.8, 4.8),
    "bedroom": (3.6, 4.6),
    "study": (3.2, 4.2),
    "kitchen": KITCHEN_WIDTH_M,
}
BOTTOM_DEPTH_M = (4.2, 5.2)
TOP_DEPTH_M = (3.8, 4.8)
PARTITION_M = 0.10
DOOR_WIDTH_M = (1.3, 1.5)  # >= 0.64 m drone + margin
DOOR_HEIGHT_M = (2.1, 2.25)
OPENING_WIDTH_M = (1.6, 2.4)  # the living / dining room opening
HOUSEHOLD_KINDS = ("table", "counter", "shelf", "cabinet")
MIN_SUPPORTS = 6


def generate_apartment(rng: np.random.Generator) -> SceneLayout:
    """Living room, dining room, bedroom and study (TidyHouse)."""
    return generate_rooms(rng, with_kitchen=False)


def generate_rooms(rng: np.random.Generator, with_kitchen: bool) -> SceneLayout:
    """The apartment; `with_kitchen` puts the kitchen (fridge, drawer) where the study would be."""
    for _ in range(20):
        layout = _try_rooms(rng, with_kitchen)
        if layout is not None:
            return layout
    raise RuntimeError("apartment generation failed 20 times in a row; the room size ranges are too tight")


def _try_rooms(rng: np.random.Generator, with_kitchen: bool) -> SceneLayout | None:
    bottom = ["living room", "dining room"]
    top = ["bedroom", "kitchen" if with_kitchen else "study"]
    rng.shuffle(bottom)
    rng.shuffle(top)
    widths = {name: rng.uniform(*ROOM_WIDTH_M[name]) for name in bottom}
    width = widths[bottom[0]] + PARTITION_M + widths[bottom[1]]
    # the top row splits the same width; each of its rooms gets at least its minimum
    lo_t, hi_t = ROOM_WIDTH_M[top[0]][0], width - PARTITION_M - ROOM_WIDTH_M[top[1]][0]
    if lo_t > hi_t:
        return None
    widths[top[0]] = rng.uniform(lo_t, hi_t)
    widths[top[1]] = width - PARTITION_M - widths[top[0]]
    yb = rng.uniform(*BOTTOM_DEPTH_M)
    yt = rng.uniform(*(KITCHEN_DEPTH_M if with_kitchen else TOP_DEPTH_M))
    depth, ceiling = yb + PARTITION_M + yt, rng.uniform(*CEILING_HEIGHT_M)
    xs, xt, ym = widths[bottom[0]] + PARTITION_M / 2, widths[top[0]] + PARTITION_M / 2, yb + PARTITION_M / 2
    h = PARTITION_M / 2
    rooms = {
        bottom[0]: Room(bottom[0], (0.0, 0.0), (xs - h, yb)),
        bottom[1]: Room(bottom[1], (xs + h, 0.0), (width, yb)),
        top[0]: Room(top[0], (0.0, ym + h), (xt - h, depth)),
        top[1]: Room(top[1], (xt + h, ym + h), (width, depth)),
    }

    # Doorways: bottom-left <-> top-left and bottom-right <-> top-right through the middle partition, and the wide
    # living / dining opening through the bottom partition. A 0.35 m wall stub keeps them off the junctions.
    dw = [rng.uniform(*DOOR_WIDTH_M) for _ in range(2)]
    dh = [rng.uniform(*DOOR_HEIGHT_M) for _ in range(2)]
    left_end, right_start = min(xs, xt) - h, max(xs, xt) + h
    door_x = [
        rng.uniform(0.35 + dw[0] / 2, left_end - 0.35 - dw[0] / 2),
        rng.uniform(right_start + 0.35 + dw[1] / 2, width - 0.35 - dw[1] / 2),
    ]
    ow, oh = rng.uniform(*OPENING_WIDTH_M), rng.uniform(2.1, min(2.4, ceiling - 0.2))
    oy = rng.uniform(0.4 + ow / 2, yb - 0.4 - ow / 2)
    wall_color = pick_color(rng, WALL_COLORS)
    boxes: list[Box] = _structure(rooms, width, depth, ceiling, wall_color, rng)
    boxes += wall("partition_middle", (0.0, ym), (width, ym), ceiling, wall_color,
                  [Opening(door_x[0], dw[0], dh[0]), Opening(door_x[1], dw[1], dh[1])], PARTITION_M)
    boxes += wall("partition_bottom", (xs, 0.0), (xs, yb), ceiling, wall_color, [Opening(oy, ow, oh)], PARTITION_M)
    boxes += wall("partition_top", (xt, ym + h), (xt, depth), ceiling, wall_color, (), PARTITION_M)

    placers = {name: Placer(room) for name, room in rooms.items()}
    for x, w, lower, upper in ((door_x[0], dw[0], bottom[0], top[0]), (door_x[1], dw[1], bottom[1], top[1])):
        placers[lower].reserve((x, yb - 0.5), (w / 2 + 0.25, 0.5))
        placers[upper].reserve((x, ym + h + 0.5), (w / 2 + 0.25, 0.5))
    placers[bottom[0]].reserve((xs - h - 0.5, oy), (0.5, ow / 2 + 0.25))
    placers[bottom[1]].reserve((xs + h + 0.5, oy), (0.5, ow / 2 + 0.25))
    doorways = (
        Doorway((door_x[0], ym, 1.5), (bottom[0], top[0]), dw[0]),
        Doorway((door_x[1], ym, 1.5), (bottom[1], top[1]), dw[1]),
        Doorway((xs, oy, 1.5), (bottom[0], bottom[1]), ow),
    )
    nav: dict[str, Vec3] = {
        f"the doorway to the {top[0]}": doorways[0].center,
        f"the doorway to the {top[1]}": doorways[1].center,
        "the doorway to the dining room": doorways[2].center,
    }

    pieces: list[Piece] = []
    furnishing = Furnishing()
    for name, room in rooms.items():
        if name == "kitchen":
            kitchen = furnish_kitchen(rng, room, placers[name], ceiling)
            if kitchen is None:
                return None
            furnishing = kitchen
            pieces += kitchen.pieces
            continue
        furnished = ROOM_FURNISHERS[name](rng, room, placers[name])
        if furnished is None:
            return None
        pieces += furnished
    for piece in pieces:
        boxes += piece.boxes
    boxes += furnishing.boxes
    obstacles = boxes_array(boxes + [b for f in furnishing.fixtures for b in fixture_boxes(f, 0.0)])
    supports = fitted_supports([s for p in pieces for s in p.supports], obstacles) + tuple(furnishing.supports)
    household = [s for s in supports if s.kind in HOUSEHOLD_KINDS]
    if len(household) < MIN_SUPPORTS or len({s.room for s in household}) < 2:
        return None

    lo, hi = (0.0, 0.0, 0.0), (width, depth, ceiling)
    nav.update(furnishing.nav_points)
    for name, room in rooms.items():
        centre = ((room.lo[0] + room.hi[0]) / 2, (room.lo[1] + room.hi[1]) / 2, 1.5)
        point = free_point(centre, obstacles, (*room.lo, 0.0), (*room.hi, ceiling))
        if point is None:
            return None
        nav[f"the {name}"] = point
    nav.update(support_nav_points(supports, obstacles, lo, hi))
    layout = SceneLayout(
        name="home" if with_kitchen else "apartment", boxes=tuple(boxes), supports=supports,
        rooms=tuple(rooms[n] for n in bottom + top), workspace_lo=lo, workspace_hi=hi, nav_points=nav,
        fixtures=tuple(furnishing.fixtures), doorways=doorways, **random_lighting(rng),
    )
    return turn_layout(turn_layout(layout, 0, (-width / 2, -depth / 2)), int(rng.integers(4)))


def _structure(rooms: dict[str, Room], width: float, depth: float, ceiling: float, wall_color, rng) -> list[Box]:
    """Per-room floors, one ceiling, the outer walls."""
    t, h = WALL_THICKNESS_M, PARTITION_M / 2
    boxes = []
    for name, room in rooms.items():
        palette = FLOOR_COLORS[3:] if name == "kitchen" else FLOOR_COLORS[:3]
        lo, hi = (room.lo[0] - h, room.lo[1] - h), (room.hi[0] + h, room.hi[1] + h)
        boxes.append(slab(f"floor_{name.replace(' ', '_')}", lo, hi, 0.0, 0.1, pick_color(rng, palette), "floor"))
    boxes.append(slab("ceiling", (-t, -t), (width + t, depth + t), ceiling + 0.1, 0.1, (0.95, 0.95, 0.94), "ceiling"))
    boxes += wall("wall_south", (-t, -t / 2), (width + t, -t / 2), ceiling, wall_color)
    boxes += wall("wall_north", (-t, depth + t / 2), (width + t, depth + t / 2), ceiling, wall_color)
    boxes += wall("wall_west", (-t / 2, 0.0), (-t / 2, depth), ceiling, wall_color)
    boxes += wall("wall_east", (width + t / 2, 0.0), (width + t / 2, depth), ceiling, wall_color)
    return boxes


SIDES = ("south", "north", "west", "east")


def _front_of(piece: Piece, distance: float) -> Vec2:
    return (piece.center[0] + distance * math.cos(piece.yaw), piece.center[1] + distance * math.sin(piece.yaw))


def _living_room(rng: np.random.Generator, room: Room, placer: Placer) -> list[Piece] | None:
    """Sofa with a coffee table in front of it; a TV cabinet, a bookshelf standing out from a wall, a side table."""
    out, wood = [], pick_color(rng, WOOD_COLORS)
    d, w = rng.uniform(0.9, 1.0), rng.uniform(1.8, 2.4)
    spot = placer.against_wall(rng, d, w, SIDES)
    if spot is None:
        return None
    couch = placer.add(sofa("sofa", room.name, *spot, d, w, rng.uniform(0.42, 0.48), pick_color(rng, FABRIC_COLORS), "the sofa"))
    out.append(couch)
    td, tw = rng.uniform(0.5, 0.65), rng.uniform(0.9, 1.2)
    center, yaw = _front_of(couch, d / 2 + 0.45 + td / 2), couch.yaw + rng.uniform(-0.08, 0.08)
    if placer.fits(center, (td / 2, tw / 2), yaw, wall_gap=0.4, gap=0.3):
        spot = (center, yaw)
    elif (spot := placer.free_standing(rng, td, tw, yaw_jitter=0.1)) is None:
        return None
    out.append(placer.add(table("coffee_table", room.name, *spot, td, tw, rng.uniform(0.42, 0.5), wood, wood, "the coffee table")))
    cd, cw = rng.uniform(0.64, 0.72), rng.uniform(1.2, 1.8)
    if spot := placer.against_wall(rng, cd, cw, SIDES):
        color = pick_color(rng, PAINT_COLORS)
        out.append(placer.add(cabinet("tv_cabinet", room.name, *spot, cd, cw, rng.uniform(0.5, 0.7), color, wood, "the TV cabinet")))
    sd, sw = rng.uniform(0.38, 0.42), rng.uniform(0.8, 1.3)
    if spot := placer.against_wall(rng, sd, sw, SIDES, side_on=True):
        height, boards, color = rng.uniform(0.95, 1.25), int(rng.integers(2, 4)), pick_color(rng, WOOD_COLORS)
        out.append(placer.add(shelf_unit("bookshelf", room.name, *spot, sd, sw, height, boards, color, "the top of the bookshelf")))
    st = rng.uniform(0.45, 0.55)
    if spot := placer.free_standing(rng, st, st, wall_gap=0.4, yaw_jitter=0.2):
        out.append(placer.add(table("side_table", room.name, *spot, st, st, rng.uniform(0.5, 0.62), wood, wood, "the side table")))
    return out


def _dining_room(rng: np.random.Generator, room: Room, placer: Placer) -> list[Piece] | None:
    """A dining table with chairs, a sideboard, often a counter."""
    out, wood = [], pick_color(rng, WOOD_COLORS)
    d, w, height = rng.uniform(0.85, 1.0), rng.uniform(1.4, 2.0), rng.uniform(0.72, 0.78)
    spot = placer.free_standing(rng, d + 2 * 0.42, w, wall_gap=0.5, yaw_jitter=0.05)  # room for the chairs
    if spot is None:
        return None
    center, yaw = spot
    dining = table("dining_table", room.name, center, yaw, d, w, height, wood, wood, "the dining table")
    out.append(placer.add(Piece(dining.name, dining.boxes, dining.supports, center, (d / 2 + 0.42, w / 2), yaw, height)))
    c, s = math.cos(yaw), math.sin(yaw)
    chair_color = pick_color(rng, WOOD_COLORS)
    for side in (1.0, -1.0):  # chairs along the long sides, facing the table
        for k, along in enumerate([-w / 4, w / 4] if w >= 1.6 else [0.0]):
            lx = side * (d / 2 + 0.2)
            pos = (center[0] + c * lx - s * along, center[1] + s * lx + c * along)
            out.append(chair(f"dining_chair_{int(side > 0)}{k}", room.name, pos, yaw + (math.pi if side > 0 else 0.0), chair_color))
    bd, bw = rng.uniform(0.64, 0.72), rng.uniform(1.2, 1.8)
    if spot := placer.against_wall(rng, bd, bw, SIDES):
        color = pick_color(rng, PAINT_COLORS + WOOD_COLORS)
        out.append(placer.add(cabinet("sideboard", room.name, *spot, bd, bw, rng.uniform(0.8, 0.95), color, wood, "the sideboard")))
    if rng.random() < 0.7:
        cd, cw = rng.uniform(0.64, 0.7), rng.uniform(1.2, 2.0)
        if spot := placer.against_wall(rng, cd, cw, SIDES):
            base, top = pick_color(rng, PAINT_COLORS), pick_color(rng, STONE_COLORS)
            out.append(placer.add(counter("dining_counter", room.name, *spot, cd, cw, rng.uniform(0.9, 1.05), base, top, "the dining room counter")))
    return out


def _bedroom(rng: np.random.Generator, room: Room, placer: Placer) -> list[Piece] | None:
    """A bed against a wall, a dresser, often a wardrobe (tall, no support) and a bedside table."""
    out = []
    length, w = rng.uniform(2.0, 2.1), rng.uniform(1.4, 1.8)
    spot = placer.against_wall(rng, length, w, SIDES)
    if spot is None:
        return None
    out.append(placer.add(bed("bed", room.name, *spot, length, w, pick_color(rng, WOOD_COLORS), pick_color(rng, FABRIC_COLORS))))
    dd, dw = rng.uniform(0.64, 0.7), rng.uniform(0.9, 1.4)
    if spot := placer.against_wall(rng, dd, dw, SIDES):
        body, top = pick_color(rng, WOOD_COLORS + PAINT_COLORS), pick_color(rng, WOOD_COLORS)
        out.append(placer.add(cabinet("dresser", room.name, *spot, dd, dw, rng.uniform(0.8, 1.0), body, top, "the dresser")))
    if rng.random() < 0.6:
        ww = rng.uniform(1.0, 1.6)
        if spot := placer.against_wall(rng, 0.6, ww, SIDES):
            out.append(placer.add(wardrobe("wardrobe", room.name, *spot, 0.6, ww, rng.uniform(2.0, 2.2), pick_color(rng, WOOD_COLORS + PAINT_COLORS))))
    if rng.random() < 0.7:
        st, wood = rng.uniform(0.45, 0.55), pick_color(rng, WOOD_COLORS)
        if spot := placer.free_standing(rng, st, st, wall_gap=0.4, yaw_jitter=0.1):
            out.append(placer.add(table("bedside_table", room.name, *spot, st, st, rng.uniform(0.5, 0.6), wood, wood, "the bedside table")))
    return out


def _study(rng: np.random.Generator, room: Room, placer: Placer) -> list[Piece] | None:
    """A desk, a filing cabinet, often a low open shelf."""
    out, wood = [], pick_color(rng, WOOD_COLORS)
    dd, dw = rng.uniform(0.65, 0.75), rng.uniform(1.1, 1.5)
    if spot := placer.against_wall(rng, dd, dw, SIDES):
        out.append(placer.add(table("desk", room.name, *spot, dd, dw, rng.uniform(0.72, 0.76), wood, pick_color(rng, PAINT_COLORS), "the desk")))
    fd, fw = rng.uniform(0.64, 0.7), rng.uniform(0.5, 0.8)
    if spot := placer.against_wall(rng, fd, fw, SIDES):
        body, top = pick_color(rng, PAINT_COLORS), pick_color(rng, PAINT_COLORS)
        out.append(placer.add(cabinet("filing_cabinet", room.name, *spot, fd, fw, rng.uniform(0.7, 1.0), body, top, "the filing cabinet")))
    if rng.random() < 0.6:
        sd, sw = rng.uniform(0.38, 0.42), rng.uniform(0.8, 1.2)
        if spot := placer.against_wall(rng, sd, sw, SIDES, side_on=True):
            out.append(placer.add(shelf_unit("low_shelf", room.name, *spot, sd, sw, rng.uniform(0.8, 1.0), 2, pick_color(rng, WOOD_COLORS),
                                             "the top of the low shelf")))
    return out


ROOM_FURNISHERS: dict[str, Callable[[np.random.Generator, Room, Placer], list[Piece] | None]] = {
    "living room": _living_room,
    "dining room": _dining_room,
    "bedroom": _bedroom,
    "study": _study,
}
