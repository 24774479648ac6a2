"""Procedural layouts (pure): determinism, variety, and the invariants every seed must keep.

Geometry checks here are written independently of the generators' own placement helpers where that matters: the hover
check samples the real rotor-disk rims, the doorway check slices the boxes at many heights.
"""

import math
from functools import cache

import numpy as np
import pytest
import torch

from aerobench.envs.platforms import GRIPPER_PLATFORM
from aerobench.envs.scenes import SCENE_GENERATORS, generate_layout
from aerobench.envs.scenes.articulated import fixture_boxes, fixture_keepout_boxes, get_fixture_spec
from aerobench.envs.scenes.furniture import box_aabbs, boxes_array, boxes_overlap, point_box_distance, rects_overlap
from aerobench.envs.scenes.layout import Doorway, Room, SceneLayout
from aerobench.envs.scenes.room_routes import RoomRoutes, first_doorways

SCENES = ("apartment", "kitchen", "street", "home")
SEEDS = range(50)
PICK_PLACE_KINDS = ("table", "counter", "shelf", "cabinet", "sofa", "vehicle")
STRUCTURE = ("floor", "wall", "ceiling")


@cache
def layouts(scene: str) -> tuple:
    return tuple(generate_layout(scene, np.random.default_rng(seed)) for seed in SEEDS)


def slice_distance(x: float, y: float, z: float, boxes) -> float:
    """Horizontal distance from (x, y) to the cross-sections at height z of the boxes that reach z."""
    arr = boxes_array([b for b in boxes if b.center[2] - b.half_size[2] < z < b.center[2] + b.half_size[2]])
    if len(arr) == 0:
        return math.inf
    d = np.array([x, y]) - arr[:, :2]
    c, s = np.cos(arr[:, 6]), np.sin(arr[:, 6])
    local = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], -1)
    q = np.abs(local) - arr[:, 3:5]
    return float((np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(-1), 0)).min())


def rotor_rim_points(x: float, y: float, z: float, samples: int = 16) -> np.ndarray:
    """Rim points of the four rotor disks of a level X500 centred at (x, y), heading along +x (rooms are axis-aligned)."""
    r = GRIPPER_PLATFORM.rotors
    a = np.linspace(0, 2 * np.pi, samples, endpoint=False) + np.pi / samples  # includes points near the axes
    pts = [(x + px + r.disk_radius_m * np.cos(t), y + py + r.disk_radius_m * np.sin(t), z) for px, py in r.positions_xy for t in a]
    return np.array(pts)


def overlapping_pairs(boxes, tolerance: float = 0.01) -> list[tuple[str, str]]:
    """Pairs of boxes from different pieces that interpenetrate by more than `tolerance` (floors, wall-wall and
    wall-ceiling junctions excluded)."""
    boxes = [b for b in boxes if b.kind != "floor"]
    aabb = box_aabbs(boxes_array(boxes))
    lo, hi = aabb[:, :3], aabb[:, 3:]
    deep = ((np.minimum(hi[:, None], hi[None]) - np.maximum(lo[:, None], lo[None])) > tolerance).all(-1)
    out = []
    for i, j in zip(*np.nonzero(np.triu(deep, 1))):
        a, b = boxes[i], boxes[j]
        if a.name.split("/")[0] == b.name.split("/")[0] or {a.kind, b.kind} <= {"wall", "ceiling"}:
            continue
        if boxes_overlap(a, b, -tolerance):
            out.append((a.name, b.name))
    return out


# --------------------------------------------------------------------------------------------------------------------
# Registry, determinism, variety
# --------------------------------------------------------------------------------------------------------------------
def test_registry_names_the_four_scenes():
    assert tuple(SCENE_GENERATORS) == SCENES
    with pytest.raises(ValueError, match=r"unknown scene 'garage'; valid scenes: apartment, kitchen, street, home"):
        generate_layout("garage", np.random.default_rng(0))


@pytest.mark.parametrize("scene", SCENES)
def test_same_seed_same_layout_different_seed_different_layout(scene):
    a = generate_layout(scene, np.random.default_rng(123))
    assert a == generate_layout(scene, np.random.default_rng(123))
    assert a != generate_layout(scene, np.random.default_rng(124))
    assert a.name == scene


@pytest.mark.parametrize("scene", SCENES)
def test_layouts_vary_across_seeds(scene):
    sizes = {tuple(round(v, 2) for v in (*L.workspace_hi, *L.workspace_lo)) for L in layouts(scene)}
    supports = {tuple(sorted(s.name for s in L.supports)) for L in layouts(scene)}
    colors = {L.boxes[0].color for L in layouts(scene)}
    lights = {L.sun_direction for L in layouts(scene)}
    assert len(sizes) == len(SEEDS) and len(colors) > 10 and len(lights) == len(SEEDS)
    if scene != "street":
        assert len(supports) > 3


# --------------------------------------------------------------------------------------------------------------------
# Invariants over many seeds
# --------------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("scene", SCENES)
def test_structure_floor_at_zero_walls_ceiling(scene):
    for L in layouts(scene):
        kinds = {b.kind for b in L.boxes}
        assert set(STRUCTURE) <= kinds
        floors = [b for b in L.boxes if b.kind == "floor"]
        assert min(b.top for b in floors) == pytest.approx(0.0, abs=1e-9) and max(b.top for b in floors) < 0.01
        assert L.workspace_lo[2] == 0.0
        if scene != "street":
            assert 2.6 <= L.workspace_hi[2] <= 2.8
            ceiling = min(b.center[2] - b.half_size[2] for b in L.boxes if b.kind == "ceiling")
            assert ceiling == pytest.approx(L.workspace_hi[2])


@pytest.mark.parametrize("scene", SCENES)
def test_supports_usable(scene):
    for L in layouts(scene):
        arr = boxes_array(list(L.boxes) + [b for f in L.fixtures for b in fixture_boxes(f, 0.0)])
        assert len({s.name for s in L.supports}) == len(L.supports), "support names must be unique"
        for s in L.supports:
            assert 0.4 <= s.height <= 1.3, s
            assert min(s.half_size) * 2 >= 0.25 - 1e-9, s
            c, sn = math.cos(s.yaw), math.sin(s.yaw)
            for sx in (-1, 1):
                for sy in (-1, 1):
                    x = s.center[0] + c * sx * s.half_size[0] - sn * sy * s.half_size[1]
                    y = s.center[1] + sn * sx * s.half_size[0] + c * sy * s.half_size[1]
                    assert L.workspace_lo[0] < x < L.workspace_hi[0] and L.workspace_lo[1] < y < L.workspace_hi[1], s
            if s.kind in ("fridge_shelf", "drawer"):
                continue
            assert s.kind in PICK_PLACE_KINDS and s.clear_height >= 0.9, s
            # a level X500 hovering anywhere over it, disks 0.3-0.85 m above the surface, touches nothing
            g = np.linspace(-1, 1, 3)
            lx, ly = (v.ravel() for v in np.meshgrid(g * s.half_size[0], g * s.half_size[1]))
            rims = np.concatenate([
                rotor_rim_points(s.center[0] + c * x - sn * y, s.center[1] + sn * x + c * y, s.height + dz)
                for x, y in zip(lx, ly) for dz in (0.3, 0.6, 0.85)
            ])
            near = (np.abs(arr[:, :2] - np.array(s.center)).max(-1) < 4.0) & (arr[:, 2] + arr[:, 5] > s.height + 0.2)
            assert point_box_distance(rims, arr[near]).min(initial=np.inf) > 0.0, (L.name, s.name)


def _numpy_rects_overlap(a, b, gap=0.0) -> bool:
    """The separating-axis test with numpy 2-vectors, as `rects_overlap` was first written."""
    (ca, ha, ya), (cb, hb, yb) = a, b
    ha = (ha[0] + gap, ha[1] + gap)
    d = np.array([cb[0] - ca[0], cb[1] - ca[1]])
    axes_a = [np.array([math.cos(ya), math.sin(ya)]), np.array([-math.sin(ya), math.cos(ya)])]
    axes_b = [np.array([math.cos(yb), math.sin(yb)]), np.array([-math.sin(yb), math.cos(yb)])]
    for axis in axes_a + axes_b:
        ra = sum(h * abs(float(axis @ u)) for h, u in zip(ha, axes_a))
        rb = sum(h * abs(float(axis @ u)) for h, u in zip(hb, axes_b))
        if abs(float(axis @ d)) >= ra + rb:
            return False
    return True


def test_the_rectangle_test_in_plain_floats_decides_as_the_numpy_one():
    """`rects_overlap` works on Python floats (a layout makes thousands of tests); each of its decisions, and so the
    layout each seed gives, is the numpy version's. Footprints on a 0.1 m grid, at quarter turns and touching,
    put many tests on the boundary, where a different rounding would flip them."""
    rng = np.random.default_rng(0)

    def rect():
        yaw = float(rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2, rng.uniform(-math.pi, math.pi)]))
        grid = rng.random() < 0.5
        centre = tuple(float(round(v, 1)) if grid else float(v) for v in rng.uniform(-2.0, 2.0, 2))
        half = tuple(float(round(v, 1)) if grid else float(v) for v in rng.uniform(0.1, 1.0, 2))
        return centre, half, yaw

    decisions = []
    for _ in range(20000):
        a, b, gap = rect(), rect(), float(rng.choice([0.0, 0.02, 0.4]))
        decisions.append(rects_overlap(a, b, gap))
        assert decisions[-1] == _numpy_rects_overlap(a, b, gap), (a, b, gap)
    assert 0.1 < np.mean(decisions) < 0.9  # both answers were tested


@pytest.mark.parametrize("scene", SCENES)
def test_no_furniture_interpenetrates(scene):
    for L in layouts(scene):
        assert overlapping_pairs(L.boxes) == []


@pytest.mark.parametrize("scene", SCENES)
def test_nav_points_free_and_inside(scene):
    required = {
        "apartment": ("the living room", "the bedroom", "the dining room"),
        "kitchen": ("the kitchen", "the fridge", "the kitchen drawer"),
        "street": ("the building entrance", "the cabinet by the door", "the lobby", "the vehicle"),
        "home": ("the living room", "the bedroom", "the dining room", "the kitchen", "the fridge", "the kitchen drawer"),
    }[scene]
    for L in layouts(scene):
        assert set(required) <= set(L.nav_points)
        pts = np.array(list(L.nav_points.values()))
        solid = list(L.boxes) + [b for f in L.fixtures for b in fixture_boxes(f, 0.0)]
        assert point_box_distance(pts, boxes_array(solid)).min() >= 0.5
        lo, hi = np.array(L.workspace_lo), np.array(L.workspace_hi)
        assert ((pts > lo) & (pts < hi)).all()
        for room in L.rooms:
            if room.name != "street":
                assert L.nav_points[f"the {room.name}"][2] == pytest.approx(1.5)


@pytest.mark.parametrize("scene,width,height", [("apartment", 1.3, 2.1), ("home", 1.3, 2.1), ("street", 1.4, 2.2)])
def test_doorways_wide_and_tall_enough(scene, width, height):
    for L in layouts(scene):
        doorways = {k: v for k, v in L.nav_points.items() if k.startswith("the doorway to")}
        assert len(doorways) == (3 if scene != "street" else 1)
        for name, (x, y, _) in doorways.items():
            for z in np.arange(0.05, height, 0.1):
                assert slice_distance(x, y, z, L.boxes) >= width / 2 - 1e-6, (L.name, name, z)


@pytest.mark.parametrize("scene", SCENES)
def test_doorways_join_the_rooms_and_routes_pass_them_in_order(scene):
    """Every doorway sits in the wall between its two rooms (in neither rectangle, within a wall's thickness of both)
    and is the nav point of the same name; the room graph is connected, and the route between two rooms that share
    no doorway starts through a doorway of the first (the apartment's top rooms: three doorways apart)."""
    for L in layouts(scene):
        rooms = {r.name: r for r in L.rooms}
        assert len(L.doorways) == {"kitchen": 0, "street": 1}.get(scene, 3)
        assert all(door.center in L.nav_points.values() for door in L.doorways)
        for door in L.doorways:
            x, y, _ = door.center
            for name in door.rooms:
                r = rooms[name]
                assert not (r.lo[0] < x < r.hi[0] and r.lo[1] < y < r.hi[1])
                gap = max(r.lo[0] - x, x - r.hi[0], r.lo[1] - y, y - r.hi[1])
                assert 0.0 <= gap <= 0.15, (L.name, name, gap)
        hops = first_doorways(L)
        n = len(L.rooms)
        assert len(hops) == n * (n - 1)
        for (a, b), door in hops.items():
            assert L.rooms[a].name in L.doorways[door].rooms
            if L.rooms[b].name in L.doorways[door].rooms:
                assert hops[(b, a)] == door  # adjacent rooms: the shared doorway either way
        routes = RoomRoutes.pack([L])
        for (a, b), door in hops.items():
            ra, rb = L.rooms[a], L.rooms[b]
            start = torch.tensor([[(ra.lo[0] + ra.hi[0]) / 2, (ra.lo[1] + ra.hi[1]) / 2, 1.0]])
            goal = torch.tensor([[(rb.lo[0] + rb.hi[0]) / 2, (rb.lo[1] + rb.hi[1]) / 2, 1.0]])
            point, ahead = routes.next_doorway(start, goal)
            assert bool(ahead[0]) and point[0].tolist() == pytest.approx(list(L.doorways[door].center))
            point, ahead = routes.next_doorway(start, start + 0.1)  # the same room: no doorway
            assert not bool(ahead[0]) and point[0].tolist() == [0.0, 0.0, 0.0]
        outside = torch.tensor([[L.workspace_hi[0] + 5.0, L.workspace_hi[1] + 5.0, 1.0]])
        inside = torch.tensor([[(L.rooms[0].lo[0] + L.rooms[0].hi[0]) / 2, (L.rooms[0].lo[1] + L.rooms[0].hi[1]) / 2, 1.0]])
        assert routes.room_of(torch.cat([inside, outside])).tolist() == [0, len(L.rooms)]
        assert not bool(routes.next_doorway(outside, inside)[1][0])


def test_a_rooms_route_is_the_fewest_doorways():
    """Hand-made: a corridor of three rooms A - B - C; from A to C the first doorway is A-B's, from C to A B-C's."""
    rooms = (Room("A", (0.0, 0.0), (2.0, 2.0)), Room("B", (2.1, 0.0), (4.0, 2.0)), Room("C", (4.1, 0.0), (6.0, 2.0)))
    doors = (Doorway((2.05, 1.0, 1.5), ("A", "B"), 1.0), Doorway((4.05, 1.0, 1.5), ("B", "C"), 1.0))
    L = SceneLayout("corridor", (), (), rooms, (0.0, 0.0, 0.0), (6.0, 2.0, 3.0), doorways=doors)
    assert first_doorways(L) == {(0, 1): 0, (0, 2): 0, (1, 0): 0, (1, 2): 1, (2, 1): 1, (2, 0): 1}
    point, ahead = RoomRoutes.pack([L, L]).next_doorway(torch.tensor([[1.0, 1.0, 1.0], [5.0, 1.0, 1.0]]),
                                                         torch.tensor([[5.0, 1.5, 0.5], [1.0, 0.5, 0.8]]))
    assert ahead.tolist() == [True, True]
    assert torch.allclose(point, torch.tensor([[2.05, 1.0, 1.5], [4.05, 1.0, 1.5]]))


@pytest.mark.parametrize("scene", ("apartment", "home"))
def test_apartment_rooms_and_supports(scene):
    for L in layouts(scene):
        rooms = {r.name for r in L.rooms}
        assert {"living room", "bedroom", "dining room"} <= rooms
        household = [s for s in L.supports if s.kind in ("table", "counter", "shelf", "cabinet")]
        assert len(household) >= 6 and len({s.room for s in household}) >= 2
        assert {s.kind for s in household} >= {"table", "cabinet"}
        assert all(s.name.startswith("the ") for s in L.supports)
    kinds = {s.kind for L in layouts(scene) for s in L.supports}
    assert {"table", "counter", "shelf", "cabinet", "sofa"} <= kinds


@pytest.mark.parametrize("scene", ("kitchen", "home"))
def test_kitchen_fixtures_with_free_space_in_front(scene):
    for L in layouts(scene):
        assert [(f.name, f.kind) for f in L.fixtures] == [("fridge", "hinge"), ("drawer", "slide")]
        assert len(L.supports_of(("fridge_shelf",))) == 3 and len(L.supports_of(("drawer",))) == 1
        assert any(s.name == "the kitchen counter" for s in L.supports)
        assert any(s.name in ("the kitchen island", "the kitchen table") for s in L.supports)
        solid = [b for b in L.boxes if b.kind != "floor"]
        for f in L.fixtures:
            spec = get_fixture_spec(f.name)
            swing, front = fixture_keepout_boxes(f)
            assert front.half_size[0] * 2 >= 1.5
            assert overlapping_pairs(solid + [front], tolerance=0.005) == []
            for q in np.linspace(*spec.q_limits, 7):  # the door / drawer never hits anything over its range
                assert overlapping_pairs(solid + list(fixture_boxes(f, float(q))), tolerance=0.005) == []
        fridge, drawer = (fixture_boxes(f, 0.0) for f in L.fixtures)
        assert overlapping_pairs(list(fridge) + list(drawer)) == []


def test_street_delivery_route():
    for L in layouts("street"):
        cabinet = next(s for s in L.supports if s.name == "the cabinet by the door")
        vehicle = L.supports_of(("vehicle",))
        assert cabinet.kind == "cabinet" and cabinet.room == "lobby" and len(vehicle) == 1
        over = L.nav_points["the cabinet by the door"]
        assert 0.7 <= over[2] - cabinet.height <= 0.9 and math.dist(over[:2], cabinet.center) < 0.5
        entrance, doorway = L.nav_points["the building entrance"], L.nav_points["the doorway to the lobby"]
        assert entrance[2] == pytest.approx(1.6) and 1.0 <= math.dist(entrance[:2], doorway[:2]) <= 1.2
        # the cabinet stands beside the doorway, inside
        assert math.dist(cabinet.center, doorway[:2]) < 2.5
        assert {r.name for r in L.rooms} == {"street", "lobby"}
