"""Geometric route planner over a procedural layout: collision-free flight paths for the drone.

Planning happens once per episode (or chain stage) per env, on the reset path, in numpy; following the route is
batched (`RouteFollower`). A route is a list of waypoints of the airframe centre:
1. the straight segment if the drone's proxy points stay clear of every box along it;
2. otherwise climb (or descend) to a cruise altitude, A* over a 2-D occupancy grid of that altitude slab (8-connected,
   cells blocked where a disk of the drone's reach around the centre meets a box overlapping the slab), shortcut by
   line of sight, then the vertical segment down to the goal. Cruise altitudes are tried from the goal's upwards.
With a known flight heading the grid is blocked by the drone's real footprint at that heading (narrower than the
any-heading disk, so doorways stay open), and the vertical climb from the start / descent to the goal only has to keep
the clearance the drone already has there (it hovers at the start now and must reach the goal anyway).
Returns None when no route exists (the episode start is then infeasible for the expert).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Sequence

import numpy as np
import torch

from ..envs.scenes.layout import Box

CELL_M = 0.10
SEGMENT_STEP_M = 0.05
FINGER_WIDTH_M = 0.015
CLEARANCE_M = 0.08  # proxy points must stay this far from boxes along a straight segment
CRUISE_ALTITUDES_M = (1.3, 1.5, 1.7, 1.9, 2.1, 2.4, 2.7, 3.0)  # tried low to high, within the workspace
SLAB_ABOVE_M = 0.12  # rotor disks are 0.06 m above the centre, plus margin
MAX_EXPANSIONS = 200_000
WORKSPACE_MARGIN_M = 0.05
START_SKIP_M = 0.10  # the drone is at the start: its first 10 cm are not re-checked
HANG_RADIUS_M = 0.06  # the gripper (and a held object) below the drone, as a small ring
MIN_VERTICAL_CLEARANCE_M = 0.02  # a climb / descent next to a wall may keep less than CLEARANCE_M, never less than this
# A turn in place is checked every TURN_STEP_RAD; the footprint must keep TURN_MIN_CLEARANCE_M from the scene.
TURN_STEP_RAD = math.radians(15.0)
TURN_MIN_CLEARANCE_M = 0.03


def boxes_array(boxes: Sequence[Box]) -> np.ndarray:
    return np.array([[*b.center, *b.half_size, b.yaw] for b in boxes], dtype=np.float64).reshape(-1, 7)


def _point_box_distance(points: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(P, 3) points against (B, 7) boxes -> (P, B) signed distance."""
    d = points[:, None, :] - boxes[None, :, :3]
    c, s = np.cos(boxes[:, 6]), np.sin(boxes[:, 6])
    local = np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1], d[..., 2]], -1)
    q = np.abs(local) - boxes[None, :, 3:6]
    return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(-1), 0)


def _rect_distance_2d(points: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    d = points[:, None, :2] - boxes[None, :, :2]
    c, s = np.cos(boxes[:, 6]), np.sin(boxes[:, 6])
    local = np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], -1)
    q = np.abs(local) - boxes[None, :, 3:5]
    return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(-1), 0)


def _cells_near_boxes(xs: np.ndarray, ys: np.ndarray, boxes: np.ndarray, offsets: np.ndarray, margin: float) -> np.ndarray:
    """(len(xs), len(ys)) bool: the grid cells c for which some offset o of `offsets` (O, 2) puts c + o closer than
    `margin` to some box (`_rect_distance_2d`). A box is tested only against the cells its bounding circle, widened
    by `margin` and the offsets' spread, can reach: the same distances as testing every cell against every box, in a
    fraction of the time (a house's boxes each lie near a few per cent of its cells; testing them all cost the
    LongHorizonRearrangement nav planner 3-4 s per plan)."""
    blocked = np.zeros((len(xs), len(ys)), dtype=bool)
    low, high = offsets.min(0), offsets.max(0)
    for box in boxes:
        reach = math.hypot(box[3], box[4]) + margin + CELL_M  # no point farther than this from the centre is near
        i0, i1 = np.searchsorted(xs, box[0] - high[0] - reach), np.searchsorted(xs, box[0] - low[0] + reach, "right")
        j0, j1 = np.searchsorted(ys, box[1] - high[1] - reach), np.searchsorted(ys, box[1] - low[1] + reach, "right")
        if i0 >= i1 or j0 >= j1:
            continue
        gx, gy = np.meshgrid(xs[i0:i1], ys[j0:j1], indexing="ij")
        cells = np.stack([gx.ravel(), gy.ravel()], -1)
        points = (cells[None] + offsets[:, None]).reshape(-1, 2)
        near = (_rect_distance_2d(points, box[None]).reshape(len(offsets), -1) < margin).any(0)
        blocked[i0:i1, j0:j1] |= near.reshape(i1 - i0, j1 - j0)
    return blocked


class RoutePlanner:
    """Plans for one env's layout. `proxy` are the drone's body points (level, any heading is covered by using the
    points' horizontal radius), `below` how far the drone's hanging parts (gripper, held object) reach under the
    centre, `reach` its horizontal radius."""

    def __init__(
        self, boxes: np.ndarray, workspace_lo, workspace_hi, reach: float, below: float, footprint: np.ndarray | None = None
    ):
        self.boxes = boxes
        self.lo, self.hi = np.asarray(workspace_lo, dtype=float), np.asarray(workspace_hi, dtype=float)
        self.reach, self.below = reach, below
        self.footprint = footprint  # (P, 3) offsets of the drone at its flight heading; None: a circle of `reach`

    # straight segments ------------------------------------------------------------------------------------------------
    def _column_points(self, centres: np.ndarray) -> np.ndarray:
        """Sample points of the drone around each centre: its real footprint at the flight heading when known,
        otherwise a cylinder of radius `reach` from `below` to the disks (any heading)."""
        if self.footprint is not None:
            return (centres[:, None, :] + self.footprint[None]).reshape(-1, 3)
        ring = [(self.reach * math.cos(a), self.reach * math.sin(a)) for a in np.linspace(0, 2 * math.pi, 12, endpoint=False)]
        offsets = [(x, y, z) for x, y in ring + [(0.0, 0.0)] for z in (SLAB_ABOVE_M - 0.05, -self.below)]
        offsets += [(0.0, 0.0, -self.below / 2)]
        return (centres[:, None, :] + np.asarray(offsets)[None]).reshape(-1, 3)

    def clearance(self, centre: np.ndarray) -> float:
        """The drone's clearance to the nearest box with its airframe centre at `centre`."""
        if len(self.boxes) == 0:
            return math.inf
        return float(_point_box_distance(self._column_points(centre[None]), self.boxes).min())

    def segment_free(self, a: np.ndarray, b: np.ndarray, skip_start_m: float = 0.0, clearance: float = CLEARANCE_M) -> bool:
        """Whether the drone can fly from `a` to `b`; the first `skip_start_m` are not checked (it is already there)."""
        length = float(np.linalg.norm(b - a))
        n = max(2, int(length / SEGMENT_STEP_M) + 1)
        t = np.linspace(min(skip_start_m / max(length, 1e-9), 1.0), 1, n)
        centres = a[None] + t[:, None] * (b - a)[None]
        boxes = self._boxes_near(a, b, clearance)
        if len(boxes) == 0:
            return True
        return bool(_point_box_distance(self._column_points(centres), boxes).min() > clearance)

    def _boxes_near(self, a: np.ndarray, b: np.ndarray, clearance: float) -> np.ndarray:
        """The boxes a drone flying from `a` to `b` could come within `clearance` of (bounding spheres against the
        segment): most of a house is far from any one segment, and the line-of-sight shortcut checks many."""
        if len(self.boxes) == 0:
            return self.boxes
        ab = b - a
        t = np.clip(((self.boxes[:, :3] - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
        gap = np.linalg.norm(self.boxes[:, :3] - (a + t[:, None] * ab), axis=-1)
        return self.boxes[gap <= np.linalg.norm(self.boxes[:, 3:6], axis=-1) + self._extent + clearance + 0.01]

    @property
    def _extent(self) -> float:
        """Farthest any sampled point of the drone is from its centre."""
        if self.footprint is not None:
            return float(np.linalg.norm(self.footprint, axis=-1).max())
        return math.hypot(self.reach, max(self.below, SLAB_ABOVE_M))

    def _vertical_free(self, a: np.ndarray, b: np.ndarray, at: np.ndarray, skip_start_m: float = 0.0) -> bool:
        """A climb or descent between `a` and `b` at the xy of `at` (the start or the goal, where the drone must be
        anyway): it may keep the clearance the drone has at `at` when that is below CLEARANCE_M (hovering beside a
        wall), but must not come closer to anything than that."""
        clearance = min(CLEARANCE_M, self.clearance(at) - 0.005)
        return clearance >= MIN_VERTICAL_CLEARANCE_M and self.segment_free(a, b, skip_start_m, clearance)

    # grid search -----------------------------------------------------------------------------------------------------
    def _occupancy(self, z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xs = np.arange(self.lo[0] + CELL_M / 2, self.hi[0], CELL_M)
        ys = np.arange(self.lo[1] + CELL_M / 2, self.hi[1], CELL_M)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        cells = np.stack([gx.ravel(), gy.ravel()], -1)
        lo_z, hi_z = z - self.below, z + SLAB_ABOVE_M
        in_slab = (self.boxes[:, 2] + self.boxes[:, 5] > lo_z) & (self.boxes[:, 2] - self.boxes[:, 5] < hi_z)
        if self.footprint is not None:
            # the real footprint at the held heading, as its horizontal outline (the slab covers its heights)
            offsets, margin = np.unique(np.round(self.footprint[:, :2], 4), axis=0), CLEARANCE_M
        else:
            offsets, margin = np.zeros((1, 2)), self.reach + CLEARANCE_M
        blocked = _cells_near_boxes(xs, ys, self.boxes[in_slab], offsets, margin).ravel()
        # the drone stays WORKSPACE_MARGIN_M inside the workspace: with a known heading its footprint's own extent
        # each way (an arm reaching 0.47 m ahead is no reason to keep 0.52 m from a wall beside it), else its reach
        if self.footprint is not None:
            low, high = self.footprint[:, :2].min(0), self.footprint[:, :2].max(0)
        else:
            low, high = np.full(2, -self.reach), np.full(2, self.reach)
        for axis in (0, 1):
            blocked |= cells[:, axis] + low[axis] < self.lo[axis] + WORKSPACE_MARGIN_M
            blocked |= cells[:, axis] + high[axis] > self.hi[axis] - WORKSPACE_MARGIN_M
        return xs, ys, blocked.reshape(len(xs), len(ys))

    @staticmethod
    def _astar(blocked: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]] | None:
        # The drone is at the start and will be at the goal; their cells count as free even when the conservative
        # disk touches a box (the vertical segments to them were checked with the drone's real footprint).
        blocked = blocked.copy()
        blocked[start] = blocked[goal] = False
        moves = [(1, 0, 1.0), (-1, 0, 1.0), (0, 1, 1.0), (0, -1, 1.0)] + [
            (dx, dy, math.sqrt(2)) for dx in (-1, 1) for dy in (-1, 1)
        ]
        openq = [(0.0, 0.0, start)]
        came: dict[tuple[int, int], tuple[int, int]] = {}
        cost = {start: 0.0}
        expansions = 0
        while openq and expansions < MAX_EXPANSIONS:
            _, g, cur = heapq.heappop(openq)
            if cur == goal:
                path = [cur]
                while cur in came:
                    cur = came[cur]
                    path.append(cur)
                return path[::-1]
            if g > cost.get(cur, math.inf):
                continue
            expansions += 1
            for dx, dy, w in moves:
                nxt = (cur[0] + dx, cur[1] + dy)
                if not (0 <= nxt[0] < blocked.shape[0] and 0 <= nxt[1] < blocked.shape[1]) or blocked[nxt]:
                    continue
                ng = g + w
                if ng < cost.get(nxt, math.inf):
                    cost[nxt], came[nxt] = ng, cur
                    h = math.hypot(goal[0] - nxt[0], goal[1] - nxt[1])
                    heapq.heappush(openq, (ng + h, ng, nxt))
        return None

    def _shortcut(self, points: list[np.ndarray]) -> list[np.ndarray]:
        out, i = [points[0]], 0
        while i < len(points) - 1:
            j = len(points) - 1
            while j > i + 1 and not self.segment_free(points[i], points[j]):
                j -= 1
            out.append(points[j])
            i = j
        return out

    def plan(self, start: np.ndarray, goal: np.ndarray) -> list[np.ndarray] | None:
        start, goal = np.asarray(start, float), np.asarray(goal, float)
        if self.segment_free(start, goal, START_SKIP_M):
            return [goal]
        altitudes = sorted({*CRUISE_ALTITUDES_M, float(max(start[2], goal[2]))})
        for z in altitudes:
            if z + SLAB_ABOVE_M > self.hi[2] - 0.1 or z - self.below < self.lo[2] + 0.1:
                continue
            up, over = np.array([start[0], start[1], z]), np.array([goal[0], goal[1], z])
            if not (self._vertical_free(start, up, start, START_SKIP_M) and self._vertical_free(over, goal, goal)):
                continue
            xs, ys, blocked = self._occupancy(z)
            path = self._astar(blocked, _cell(up, xs, ys), _cell(over, xs, ys))
            if path is None:
                continue
            points = [up] + [np.array([xs[i], ys[j], z]) for i, j in path[1:-1]] + [over]
            return self._shortcut(points) + [goal]
        return None


def _cell(p: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> tuple[int, int]:
    return (
        int(np.clip(round((p[0] - xs[0]) / CELL_M), 0, len(xs) - 1)),
        int(np.clip(round((p[1] - ys[0]) / CELL_M), 0, len(ys) - 1)),
    )


def planner_for(
    env, env_index: int, carrying_depth: float = 0.0, heading: float | None = None, arm_q: torch.Tensor | None = None
) -> RoutePlanner:
    """A planner for env `env_index` of an aerobench skill env (its layout boxes plus fixtures in their state now).

    With `heading`, straight segments are checked with the drone's real footprint turned to that heading (rotor-disk
    rims, frame, gripper or arm at `arm_q`, and whatever hangs below), which the expert then keeps while flying.
    """
    boxes = env.obstacle_boxes(torch.tensor([env_index], device=env.device))[0].cpu().numpy()
    boxes = boxes[boxes[:, 7] > 0.5][:, :7].astype(np.float64)
    platform = env.platform
    reach = platform.rotors.arm_m * math.sqrt(2) + platform.rotors.disk_radius_m
    below = -platform.grasp_point_m[2] + 0.03 + carrying_depth
    arm_points, hang_at = [], np.zeros(2)  # the held object hangs under the grasp point
    if platform.arm is not None:
        from ..envs.control.arm import arm_point_positions_body

        q = torch.tensor([platform.arm.working_pose_rad]) if arm_q is None else arm_q.reshape(1, 3).cpu().float()
        fk = {k: v[0].numpy().astype(np.float64) for k, v in arm_point_positions_body(q, platform.arm).items()}
        grasp = fk["grasp"]
        # the open fingers either side of the grasp point (their pads 0-110 mm apart, plus the fingers' width)
        side = platform.gripper.max_opening_m / 2 + FINGER_WIDTH_M
        arm_points = [fk[k] for k in ("shoulder", "elbow", "wrist")] + [grasp] + [
            grasp + np.array([dx, dy, 0.0]) for dx in (-0.04, 0.02) for dy in (-side, side)
        ]
        reach = max(reach, float(np.hypot(grasp[0], grasp[1])) + 0.05)
        below = max(0.05, -grasp[2] + 0.03) + carrying_depth
        hang_at = grasp[:2]
    footprint = None
    if heading is not None:
        pts = [p for p in env.proxy_points.cpu().numpy()] + arm_points
        c, s = math.cos(heading), math.sin(heading)
        rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
        footprint = np.asarray(pts, dtype=np.float64) @ rot.T
        if platform.arm is None or carrying_depth > 0:  # the arm's empty fingers are in `arm_points` already
            # a held object is wider than the bare gripper: its footprint radius rings the hanging column
            hang = max(HANG_RADIUS_M, float(env.target_radius[env_index])) if carrying_depth > 0 else HANG_RADIUS_M
            cx, cy = rot[:2, :2] @ hang_at
            ring = [(cx, cy, -below)] + [(cx + hang * math.cos(a), cy + hang * math.sin(a), -below) for a in (0, 1.57, 3.14, 4.71)]
            footprint = np.concatenate([footprint, np.asarray(ring)])
    return RoutePlanner(
        boxes, env.workspace_lo[env_index].cpu().numpy(), env.workspace_hi[env_index].cpu().numpy(), reach, below, footprint
    )


def can_turn_in_place(planner_at: Callable[[float], RoutePlanner], at: np.ndarray, a: float, b: float) -> bool:
    """Whether the footprint stays clear of the scene while the drone turns in place at `at` from heading a to b
    (the shorter way); `planner_at(heading)` gives the planner for that heading."""
    delta = math.remainder(b - a, 2 * math.pi)
    steps = max(1, int(abs(delta) / TURN_STEP_RAD) + 1)
    return all(planner_at(a + delta * k / steps).clearance(at) > TURN_MIN_CLEARANCE_M for k in range(1, steps + 1))


def route_at_some_heading(
    planner_at: Callable[[float], RoutePlanner], start: np.ndarray, goals: Sequence[np.ndarray], candidates: Sequence[float],
    turn_ok: Callable[[float], bool],
) -> tuple[float, list[np.ndarray] | None]:
    """The first candidate heading with a route from `start` to a goal flown at that heading and for which
    `turn_ok(heading)` holds (the turn in place the expert makes to or from it), with its route (ending at that goal);
    `goals` are alternatives in order of preference, each tried at every heading before the next. Else the first
    candidate and None. The footprint of a drone that holds its heading is narrower than the any-heading disk, but
    one heading may have no route where another does (an arm reaching towards a counter's edge)."""
    planners: dict[float, RoutePlanner] = {}
    turns: dict[float, bool] = {}
    for goal in goals:
        for h in candidates:
            if h not in planners:
                planners[h] = planner_at(h)
            route = planners[h].plan(start, goal)
            if route is not None and h not in turns:
                turns[h] = turn_ok(h)
            if route is not None and turns[h]:
                return h, route
    return candidates[0], None
