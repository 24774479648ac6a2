"""Route planner: the drone's real footprint at its held heading, climbs beside walls, the box prefilter."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from aerobench.envs.geometry import drone_proxy_points_body
from aerobench.envs.platforms import GRIPPER_PLATFORM
from aerobench.expert.planner import CLEARANCE_M, SLAB_ABOVE_M, RoutePlanner, _cells_near_boxes, _rect_distance_2d

ROTORS = GRIPPER_PLATFORM.rotors
REACH = ROTORS.arm_m * math.sqrt(2) + ROTORS.disk_radius_m  # the any-heading disk
BELOW = -GRIPPER_PLATFORM.grasp_point_m[2] + 0.03 + 0.05  # gripper plus a held object's grasp height
LO, HI = (-3.0, -3.0, 0.0), (3.0, 3.0, 2.7)


def wall(x: float, y_lo: float, y_hi: float, height: float = 2.7) -> list[float]:
    """A full-height 0.1 m partition along y at `x` (center, half sizes, yaw)."""
    return [x, (y_lo + y_hi) / 2, height / 2, 0.05, (y_hi - y_lo) / 2, height / 2, 0.0]


def footprint(heading: float = 0.0) -> np.ndarray:
    c, s = math.cos(heading), math.sin(heading)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    hanging = np.array([(0.0, 0.0, -BELOW)] + [(0.06 * math.cos(a), 0.06 * math.sin(a), -BELOW) for a in (0, 1.57, 3.14, 4.71)])
    return np.concatenate([drone_proxy_points_body(GRIPPER_PLATFORM)[0].numpy() @ rot.T, hanging])


def planner(boxes: list[list[float]], heading: float | None = 0.0) -> RoutePlanner:
    fp = None if heading is None else footprint(heading)
    return RoutePlanner(np.array(boxes, dtype=np.float64), LO, HI, REACH, BELOW, fp)


def route_clearance(p: RoutePlanner, start: np.ndarray, route: list[np.ndarray]) -> float:
    points = [start] + list(route)
    worst = math.inf
    for a, b in zip(points[:-1], points[1:]):
        for t in np.linspace(0, 1, 40):
            worst = min(worst, p.clearance(a + t * (b - a)))
    return worst


def test_footprint_grid_passes_a_doorway_the_any_heading_disk_does_not():
    # partition at x = 0 with a 1.0 m doorway: on the 0.1 m grid the disk (0.39 m + 0.08 m clearance) finds no free
    # cell in it, the level footprint (0.32 m + 0.08 m) does
    boxes = [wall(0.0, -3.0, -0.5), wall(0.0, 0.5, 3.0)]
    start, goal = np.array([-1.5, -1.5, 1.3]), np.array([1.5, 1.5, 1.3])
    assert planner(boxes, heading=None).plan(start, goal) is None
    route = planner(boxes).plan(start, goal)
    assert route is not None and np.allclose(route[-1], goal)
    assert route_clearance(planner(boxes), start, route) > CLEARANCE_M - 0.01


def test_climb_beside_a_wall_keeps_the_clearance_the_drone_has():
    # hovering 0.06 m (less than CLEARANCE_M) beside a wall, behind a partition: the route climbs there, then leaves
    boxes = [wall(1.0, -3.0, 3.0, height=1.0), wall(-0.8, -3.0, 3.0)]
    rim = ROTORS.arm_m + ROTORS.disk_radius_m
    start = np.array([-0.8 + 0.05 + rim + 0.06, 0.0, 1.3])
    goal = np.array([2.0, 0.0, 1.3])
    p = planner(boxes)
    assert p.clearance(start) < CLEARANCE_M
    route = p.plan(start, goal)
    assert route is not None
    assert route_clearance(p, start, route) >= p.clearance(start) - 0.01


def test_no_route_from_a_start_touching_a_wall():
    boxes = [wall(1.0, -3.0, 3.0, height=1.0), wall(-0.8, -3.0, 3.0)]
    rim = ROTORS.arm_m + ROTORS.disk_radius_m
    start = np.array([-0.8 + 0.05 + rim + 0.005, 0.0, 1.3])
    assert planner(boxes).plan(start, np.array([2.0, 0.0, 1.3])) is None


@pytest.mark.parametrize("heading", [None, 0.0, 0.7])
def test_box_prefilter_matches_the_full_check(heading):
    rng = np.random.default_rng(0)
    boxes = np.concatenate([rng.uniform(-2.5, 2.5, (30, 3)) * [1, 1, 0.5] + [0, 0, 1.2],
                            rng.uniform(0.05, 0.6, (30, 3)), rng.uniform(-3, 3, (30, 1))], -1)
    fp = None if heading is None else footprint(heading)
    filtered = RoutePlanner(boxes, LO, HI, REACH, BELOW, fp)
    unfiltered = RoutePlanner(boxes, LO, HI, REACH, BELOW, fp)
    unfiltered._boxes_near = lambda a, b, clearance: boxes
    segments = rng.uniform([-2.5, -2.5, 0.8], [2.5, 2.5, 2.2], (80, 2, 3))
    results = [filtered.segment_free(a, b) for a, b in segments]
    assert results == [unfiltered.segment_free(a, b) for a, b in segments]
    assert any(results) and not all(results)


@pytest.mark.parametrize("heading", [None, 0.0, 0.7])
def test_the_occupancy_grid_tests_each_box_near_its_cells_and_blocks_what_testing_every_pair_blocks(heading):
    rng = np.random.default_rng(1)
    boxes = np.concatenate([rng.uniform(-3.2, 3.2, (15, 3)) * [1, 1, 0.5] + [0, 0, 1.2],
                            rng.uniform(0.02, 0.8, (15, 3)), rng.uniform(-3, 3, (15, 1))], -1)
    p = planner(list(boxes), heading)
    offsets = np.zeros((1, 2)) if heading is None else np.unique(np.round(p.footprint[:, :2], 4), axis=0)
    margin = REACH + CLEARANCE_M if heading is None else CLEARANCE_M
    for z in (1.3, 2.1):
        xs, ys, blocked = p._occupancy(z)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        cells = np.stack([gx.ravel(), gy.ravel()], -1)
        in_slab = (boxes[:, 2] + boxes[:, 5] > z - BELOW) & (boxes[:, 2] - boxes[:, 5] < z + SLAB_ABOVE_M)
        every_pair = np.zeros(len(cells), dtype=bool)
        for offset in offsets:
            every_pair |= _rect_distance_2d(cells + offset, boxes[in_slab]).min(-1) < margin
        inside = _cells_near_boxes(xs, ys, boxes[in_slab], offsets, margin).ravel()
        assert np.array_equal(inside, every_pair) and 0.05 < every_pair.mean() < 0.95
        assert np.array_equal(blocked.ravel() & ~every_pair, blocked.ravel() & ~inside)  # the rest: workspace edge


def test_a_transport_whose_goal_is_blocked_for_what_hangs_below_ends_a_little_higher():
    # A counter whose top (1.0 m) the hanging object reaches at the goal: no descent, so no route to the goal itself;
    # the nav expert ends its route at the first lift within the nav's reach that has one (a tall box over a drawer)
    from aerobench.envs.skills.nav import NAV_REACH_M
    from aerobench.expert.nav import GOAL_LIFTS_M, NavExpert

    counter = [0.0, 1.0, 0.5, 0.6, 0.3, 0.5, 0.0]
    start, goal = np.array([0.0, -1.5, 1.4]), np.array([0.0, 1.0, 1.0 + BELOW - 0.01])
    p = planner([counter])
    assert p.plan(start, goal) is None
    nav = type("Nav", (), {"_planner": lambda self, i, h: p})()
    heading, route = NavExpert._plan(nav, 0, start, goal, 0.0)
    assert route is not None and heading == 0.0
    lift = route[-1][2] - goal[2]
    assert min(abs(lift - x) for x in GOAL_LIFTS_M[1:]) < 1e-9 and lift < NAV_REACH_M
    assert np.allclose(route[-1][:2], goal[:2])


def test_a_footprint_keeps_its_own_extent_from_the_workspace_edge_not_the_any_heading_reach():
    # the arm platform facing +y reaches 0.47 m ahead but only the rotor disks' 0.32 m sideways: a route to a point
    # 0.45 m from the workspace's west edge, round a partition, exists at that heading; the edge margin used to be
    # the any-heading reach (0.52 m), which left the fridge's pre-grasp point beside a wall without a route
    from aerobench.envs.control.arm import arm_point_positions_body
    from aerobench.envs.platforms import ARM_PLATFORM

    heading = math.pi / 2
    c, s = math.cos(heading), math.sin(heading)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    arm = arm_point_positions_body(torch.tensor([ARM_PLATFORM.arm.working_pose_rad]), ARM_PLATFORM.arm)
    body = np.concatenate([drone_proxy_points_body(ARM_PLATFORM)[0].numpy(), arm["grasp"].numpy()])
    fp = body @ rot.T
    reach = float(np.hypot(*arm["grasp"][0, :2].numpy())) + 0.05
    boxes = np.array([wall(-1.5, -3.0, 1.0)], dtype=np.float64)  # a partition: the straight line is blocked
    start, goal = np.array([0.0, 0.0, 1.3]), np.array([LO[0] + 0.45, 0.0, 1.3])
    assert not RoutePlanner(boxes, LO, HI, reach, 0.05, fp).segment_free(start, goal)
    route = RoutePlanner(boxes, LO, HI, reach, 0.05, fp).plan(start, goal)
    assert route is not None and np.allclose(route[-1], goal)
    # ... and a footprint reaching past the edge still has none
    assert RoutePlanner(boxes, LO, HI, reach, 0.05, fp).plan(start, np.array([LO[0] + 0.30, 0.0, 1.3])) is None
