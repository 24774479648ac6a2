"""The PackageDelivery street: a road with a parked pickup, a sidewalk, and a building whose entrance leads into a
small lobby with a cabinet beside the door.

Plan (before a random quarter turn): the street runs along x; the road, then the sidewalk, then the building facade
(outer face at y = 0) with the entrance doorway (1.5-1.9 m wide, 2.25-2.4 m tall, its door swung open into the
lobby); the lobby lies behind it, flanked by the rest of the building. The package rides in the pickup's cargo bed
(a "vehicle" support) and goes onto "the cabinet by the door" (a "cabinet" support inside the lobby, beside the
doorway). Nav points name the building entrance (1 m outside the doorway, 1.6 m up) and a point over the cabinet.
"""

from __future__ import annotations

import math

import numpy as np

from .furniture import (
    PAINT_COLORS,
    VEHICLE_COLORS,
    WALL_COLORS,
    WOOD_COLORS,
    Opening,
    boxes_array,
    cabinet,
    fitted_supports,
    free_point,
    pick_color,
    pickup_truck,
    random_lighting,
    slab,
    support_nav_points,
    table,
    turn_layout,
    wall,
)
from .layout import Box, Doorway, Room, SceneLayout, Vec3

STREET_LENGTH_M = (16.0, 22.0)
ROAD_WIDTH_M = (6.0, 7.5)
SIDEWALK_WIDTH_M = (2.5, 3.5)
FACADE_THICKNESS_M = 0.25
BUILDING_HEIGHT_M = 4.5  # above the workspace ceiling: the drone goes in through the entrance, not over the roof
FLIGHT_CEILING_M = 4.0
LOBBY_WIDTH_M = (5.8, 7.5)
LOBBY_DEPTH_M = (4.0, 5.5)
LOBBY_CEILING_M = (2.8, 3.2)
ENTRANCE_WIDTH_M = (1.5, 1.9)  # spec needs >= 1.4 m
ENTRANCE_HEIGHT_M = (2.25, 2.4)  # spec needs >= 2.2 m
CABINET_JAMB_GAP_M = 0.35  # between the doorway's edge and the cabinet
ENTRANCE_NAV_DISTANCE_M = 1.0
ENTRANCE_NAV_HEIGHT_M = 1.6


def generate_street(rng: np.random.Generator) -> SceneLayout:
    """Road, sidewalk, a pickup with a cargo bed, a building entrance and a lobby cabinet (PackageDelivery)."""
    for _ in range(20):
        layout = _try_street(rng)
        if layout is not None:
            return layout
    raise RuntimeError("street generation failed 20 times in a row")


def _try_street(rng: np.random.Generator) -> SceneLayout | None:
    length, road_w, walk_w = rng.uniform(*STREET_LENGTH_M), rng.uniform(*ROAD_WIDTH_M), rng.uniform(*SIDEWALK_WIDTH_M)
    lobby_w, lobby_d, lobby_h = rng.uniform(*LOBBY_WIDTH_M), rng.uniform(*LOBBY_DEPTH_M), rng.uniform(*LOBBY_CEILING_M)
    t, tw = FACADE_THICKNESS_M, 0.15
    x_lo, x_hi = -length / 2, length / 2
    y_lo, y_back = -walk_w - road_w - 1.0, t + lobby_d
    lx = rng.uniform(x_lo + lobby_w / 2 + 2.0, x_hi - lobby_w / 2 - 2.0)
    lobby = Room("lobby", (lx - lobby_w / 2, t), (lx + lobby_w / 2, y_back))
    street = Room("street", (x_lo, y_lo), (x_hi, 0.0))

    # The doorway, with the cabinet on one side of it and the open door leaf on the other.
    door_w, door_h = rng.uniform(*ENTRANCE_WIDTH_M), rng.uniform(*ENTRANCE_HEIGHT_M)
    cab_d, cab_w, cab_h = rng.uniform(0.64, 0.72), rng.uniform(0.8, 1.2), rng.uniform(0.85, 1.1)
    cabinet_side = 1.0 if rng.random() < 0.5 else -1.0
    need_cab, need_leaf = CABINET_JAMB_GAP_M + cab_w + 0.1, door_w + 0.1
    lo_x = lobby.lo[0] + (need_cab if cabinet_side < 0 else need_leaf) + door_w / 2
    hi_x = lobby.hi[0] - (need_cab if cabinet_side > 0 else need_leaf) - door_w / 2
    if lo_x > hi_x:
        return None
    xd = rng.uniform(lo_x, hi_x)

    brick, plaster = pick_color(rng, ((0.55, 0.30, 0.25), (0.65, 0.60, 0.52), (0.45, 0.45, 0.48))), pick_color(rng, WALL_COLORS)
    boxes: list[Box] = [
        slab("ground", (x_lo, y_lo), (x_hi, 0.0), 0.0, 0.1, pick_color(rng, ((0.42, 0.44, 0.40), (0.35, 0.45, 0.28))), "floor"),
        slab("road", (x_lo, -walk_w - road_w), (x_hi, -walk_w), 0.004, 0.004, pick_color(rng, ((0.22, 0.22, 0.23),)), "floor"),
        slab("sidewalk", (x_lo, -walk_w), (x_hi, 0.0), 0.008, 0.008, pick_color(rng, ((0.68, 0.67, 0.64), (0.6, 0.5, 0.45))), "floor"),
        slab("lobby_floor", (lobby.lo[0] - tw, 0.0), (lobby.hi[0] + tw, y_back + tw), 0.0, 0.1, pick_color(rng, ((0.75, 0.73, 0.70), (0.4, 0.38, 0.36))), "floor"),
        # the floors above the lobby: its ceiling is the underside of a slab up to the roof
        Box("lobby_ceiling", (lx, (t + y_back + tw) / 2, (lobby_h + BUILDING_HEIGHT_M) / 2),
            (lobby_w / 2 + tw, (y_back + tw - t) / 2, (BUILDING_HEIGHT_M - lobby_h) / 2), 0.0, (0.95, 0.95, 0.94), "ceiling"),
    ]
    for k in range(int(length // 3)):  # dashed centre line
        x = x_lo + 1.5 + 3.0 * k
        boxes.append(slab(f"road_marking_{k}", (x - 0.75, -walk_w - road_w / 2 - 0.06), (x + 0.75, -walk_w - road_w / 2 + 0.06), 0.006, 0.002, (0.95, 0.95, 0.9), "floor"))
    boxes += wall("facade", (x_lo, t / 2), (x_hi, t / 2), BUILDING_HEIGHT_M, brick, [Opening(xd - x_lo, door_w, door_h)], t)
    boxes += wall("lobby_wall_west", (lobby.lo[0] - tw / 2, t), (lobby.lo[0] - tw / 2, y_back), lobby_h, plaster, (), tw)
    boxes += wall("lobby_wall_east", (lobby.hi[0] + tw / 2, t), (lobby.hi[0] + tw / 2, y_back), lobby_h, plaster, (), tw)
    boxes += wall("lobby_wall_back", (lobby.lo[0] - tw, y_back + tw / 2), (lobby.hi[0] + tw, y_back + tw / 2), lobby_h, plaster, (), tw)
    for name, a, b in (("building_west", x_lo, lobby.lo[0] - tw), ("building_east", lobby.hi[0] + tw, x_hi)):
        boxes.append(Box(name, ((a + b) / 2, (t + y_back + tw) / 2, BUILDING_HEIGHT_M / 2), ((b - a) / 2, (y_back + tw - t) / 2, BUILDING_HEIGHT_M / 2), 0.0, brick, "wall"))
    jamb = xd - cabinet_side * door_w / 2  # the leaf hangs on the jamb away from the cabinet, opened 90 degrees
    leaf_x = jamb - cabinet_side * 0.025
    boxes.append(Box("entrance_door", (leaf_x, t + door_w / 2, door_h / 2), (0.02, door_w / 2 - 0.01, door_h / 2 - 0.01), 0.0, pick_color(rng, WOOD_COLORS), "wall"))

    cab_x = xd + cabinet_side * (door_w / 2 + CABINET_JAMB_GAP_M + cab_w / 2)
    cab = cabinet("cabinet_by_the_door", "lobby", (cab_x, t + 0.02 + cab_d / 2), math.pi / 2, cab_d, cab_w, cab_h,
                  pick_color(rng, PAINT_COLORS + WOOD_COLORS), pick_color(rng, WOOD_COLORS), "the cabinet by the door")
    pieces = [cab]
    if rng.random() < 0.6:  # a bench along the back wall
        bw = rng.uniform(1.0, 1.6)
        bx = rng.uniform(lobby.lo[0] + bw / 2 + 0.2, lobby.hi[0] - bw / 2 - 0.2)
        wood = pick_color(rng, WOOD_COLORS)
        pieces.append(table("bench", "lobby", (bx, y_back - 0.02 - 0.2), -math.pi / 2, 0.4, bw, 0.45, wood, wood, "the bench"))

    # The pickup in the near lane, a few metres along the street from the entrance, facing either way.
    truck_l, truck_w = rng.uniform(5.0, 5.6), rng.uniform(1.9, 2.0)
    side = 1.0 if rng.random() < 0.5 else -1.0
    tx = float(np.clip(xd + side * rng.uniform(3.0, 6.0), x_lo + truck_l / 2 + 0.5, x_hi - truck_l / 2 - 0.5))
    ty = -walk_w - rng.uniform(1.3, 1.7)
    truck = pickup_truck("pickup", "street", (tx, ty), 0.0 if rng.random() < 0.5 else math.pi, truck_l, truck_w,
                         rng.uniform(0.85, 1.0), pick_color(rng, VEHICLE_COLORS), "the pickup's cargo bed")
    pieces.append(truck)
    busy = (min(xd, tx) - truck_l / 2 - 2.0, max(xd, tx) + truck_l / 2 + 2.0)
    boxes += _street_props(rng, x_lo, x_hi, walk_w, busy)
    for piece in pieces:
        boxes += piece.boxes

    obstacles = boxes_array(boxes)
    candidates = [s for p in pieces for s in p.supports if s.kind in ("cabinet", "vehicle")]
    supports = fitted_supports(candidates, obstacles)
    if {s.kind for s in supports} != {"cabinet", "vehicle"}:
        return None
    lo, hi = (x_lo, y_lo, 0.0), (x_hi, y_back, FLIGHT_CEILING_M)
    nav: dict[str, Vec3] = {
        "the building entrance": (xd, -ENTRANCE_NAV_DISTANCE_M, ENTRANCE_NAV_HEIGHT_M),
        "the doorway to the lobby": (xd, t / 2, 1.5),
    }
    cab_support = next(s for s in supports if s.kind == "cabinet")
    over_cabinet = free_point((*cab_support.center, cab_support.height + 0.8), obstacles, lo, hi, max_shift=0.5, toward=(0.0, 1.0))
    lobby_centre = free_point((lx, (t + y_back) / 2, 1.5), obstacles, (*lobby.lo, 0.0), (*lobby.hi, lobby_h))
    street_point = free_point(((xd + tx) / 2, -walk_w / 2, ENTRANCE_NAV_HEIGHT_M), obstacles, lo, hi)
    if over_cabinet is None or lobby_centre is None or street_point is None:
        return None
    nav.update(support_nav_points(supports, obstacles, lo, hi))
    nav.update({"the cabinet by the door": over_cabinet, "the lobby": lobby_centre, "the street": street_point})
    nav["the vehicle"] = nav.get("the pickup's cargo bed", (tx, ty, 2.0))
    layout = SceneLayout(
        name="street", boxes=tuple(boxes), supports=supports, rooms=(street, lobby), workspace_lo=lo, workspace_hi=hi,
        nav_points=nav, doorways=(Doorway(nav["the doorway to the lobby"], ("street", "lobby"), door_w),),
        **random_lighting(rng, outdoor=True),
    )
    return turn_layout(layout, int(rng.integers(4)))


def _street_props(rng: np.random.Generator, x_lo: float, x_hi: float, walk_w: float, busy: tuple[float, float]) -> list[Box]:
    """Lamp posts and trees along the curb and bins by the facade, outside the stretch the delivery flies over."""
    boxes, k = [], 0
    x = x_lo + rng.uniform(0.8, 2.0)
    while x < x_hi - 0.8:
        if not busy[0] < x < busy[1]:
            y = -walk_w + 0.4
            if rng.random() < 0.5:
                boxes += [
                    Box(f"lamp_{k}/post", (x, y, 1.8), (0.06, 0.06, 1.8), 0.0, (0.2, 0.2, 0.22)),
                    Box(f"lamp_{k}/head", (x, y + 0.25, 3.55), (0.12, 0.3, 0.05), 0.0, (0.85, 0.85, 0.75)),
                ]
            else:
                green = pick_color(rng, ((0.2, 0.45, 0.2), (0.3, 0.5, 0.25)))
                boxes += [
                    Box(f"tree_{k}/trunk", (x, y, 1.1), (0.12, 0.12, 1.1), 0.0, (0.35, 0.25, 0.18)),
                    Box(f"tree_{k}/crown", (x, y, 2.9), (0.8, 0.8, 0.7), 0.0, green),
                ]
            if rng.random() < 0.3:
                boxes.append(Box(f"bin_{k}", (x + 1.0, -0.5, 0.45), (0.25, 0.25, 0.45), 0.0, (0.25, 0.35, 0.3)))
            k += 1
        x += rng.uniform(5.0, 8.0)
    return boxes
