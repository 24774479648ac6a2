"""Where an episode starts: batched samplers an `AeroSkillEnv` uses in `_sample_episode` (supports, points on them,
a collision-free drone start near an anchor, the object and the distractors), over the envs being reset.

A mixin of `AeroSkillEnv`: it reads the env's packed supports and boxes (`supports`, `support_counts`,
`static_boxes`, `built`), workspace, platform, agent, distractor actors and start proxy points. Every random draw comes
from `episode_rng` (`envs/episode_rng.py`), once per env being reset, so an env's start depends on its episode seed
only, never on its row or the batch.
"""

from __future__ import annotations

import math

import torch
from mani_skill.utils.structs import Actor, Pose

from ..agents.airframe import FINGER_JOINT_NAMES
from ..geometry import is_pose_free, points_clear_of_boxes
from ..scenes import articulated

SUPPORT_KINDS = ("table", "counter", "shelf", "cabinet", "sofa", "vehicle", "fridge_shelf", "drawer")
START_DISTANCE_M = (0.5, 1.0)  # spec: skill episodes start 0.5-1 m from the target
START_CLEARANCE_M = 0.10  # drone proxy points this far from any box at the start
START_CANDIDATES = 96
SIGHT_POINTS = 12  # per leg of a start's line of sight to its anchor
SIGHT_SKIP_M = 0.10  # a handle stands a few cm off its door: the line of sight is checked from 10 cm out
PARKING_DEPTH_M = -2.0  # distractors that find no room wait under the floor


def support_contains(row: torch.Tensor, xy: torch.Tensor, margin: float = 0.0) -> torch.Tensor:
    """`(M,)` whether each point `xy` `(M, 2)` lies over its support `row` `(M, 9)` (a row of the env's packed
    `supports`: centre x, y, half extents, surface height, yaw, ...), at least `margin` inside its edges."""
    d = xy - row[:, 0:2]
    c, s = torch.cos(-row[:, 5]), torch.sin(-row[:, 5])
    local = torch.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], -1)
    return (local.abs() <= row[:, 2:4] - margin).all(-1)


class EpisodeStarts:
    """Batched episode-start sampling for `AeroSkillEnv` (see the module docstring)."""

    def sample_supports(self, env_idx: torch.Tensor, kinds: tuple[str, ...]) -> tuple[torch.Tensor, torch.Tensor]:
        """A random support of one of `kinds` per env: `(M,)` index and `(M,)` ok flag (False: the layout has none)."""
        table = self.supports[env_idx]
        kind_ids = torch.tensor([SUPPORT_KINDS.index(k) for k in kinds if k in SUPPORT_KINDS], device=self.device)
        allowed = (table[..., 7] > 0.5) & (table[..., 6][..., None] == kind_ids).any(-1)
        ok = allowed.any(-1)
        weights = allowed.float() + (~ok)[:, None].float()  # any row stays samplable; ok says whether it is valid
        # each env draws over its own layout's supports, not the batch's padded width (the draw's length is part of
        # what it takes from the env's stream)
        widths = [max(self.support_counts[i], 1) for i in env_idx.tolist()]
        rows = weights.cpu()  # the draws are made on the CPU (`episode_rng`): one copy, not one per env
        index = self.episode_rng.multinomial(env_idx, [w[:width] for w, width in zip(rows, widths)])
        return index, ok

    def sample_on_support(self, env_idx: torch.Tensor, index: torch.Tensor, margin: torch.Tensor) -> torch.Tensor:
        """A uniform point `(M, 3)` on each chosen support, `margin` `(M,)` inside its edges, at the surface height."""
        row = self.supports[env_idx, index]
        half = (row[:, 2:4] - margin[:, None]).clamp_min(0.0)
        local = (self.episode_rng.rand(env_idx, 2) * 2 - 1) * half
        c, s = torch.cos(row[:, 5]), torch.sin(row[:, 5])
        xy = row[:, 0:2] + torch.stack([c * local[:, 0] - s * local[:, 1], s * local[:, 0] + c * local[:, 1]], -1)
        return torch.cat([xy, row[:, 4:5]], dim=-1)

    def inside_support(self, env_idx: torch.Tensor, index: torch.Tensor, xy: torch.Tensor, margin: float = 0.0) -> torch.Tensor:
        return support_contains(self.supports[env_idx, index], xy, margin)

    def obstacle_boxes(self, env_idx: torch.Tensor | None = None) -> torch.Tensor:
        """Packed static boxes plus the fixtures (fridge, drawer) in their current state, for the given envs (all
        by default)."""
        boxes = self.static_boxes
        if self.built.fixtures:
            names = list(self.built.fixtures)
            boxes = torch.cat([boxes, articulated.packed_fixture_boxes(names, [self.built.fixtures[n] for n in names])], 1)
        return boxes if env_idx is None else boxes[env_idx]

    def sample_start(
        self,
        env_idx: torch.Tensor,
        anchor: torch.Tensor,
        min_tcp_height: torch.Tensor,
        face_anchor: bool = False,
        carried_points: torch.Tensor | None = None,
        distance: tuple[float, float] = START_DISTANCE_M,
        reject=None,
        from_airframe: bool = False,
        heading: torch.Tensor | None = None,
        within_cone: tuple[torch.Tensor, float] | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """A collision-free level start with the tool centre point `distance` from `anchor` `(M, 3)`.

        Returns the airframe position `(M, 3)`, heading `(M,)` and whether a free start was found `(M,)`.
        `carried_points` `(M, Q, 3)` are points of a held object relative to the tool centre point (world axes);
        `reject(tcp (M, K, 3)) -> (M, K)` vetoes candidates; `from_airframe` measures the distance from the
        airframe centre instead of the tool centre point (navigation targets); `heading` `(M,)` fixes the yaw;
        `within_cone` (axis `(M, 3)`, min cosine) keeps the start in front of the anchor (a door's outward normal) and
        in plain view of it: no box on the line from the anchor to the tool centre point and on to the airframe (a
        fridge in a corner has a partition wall 0.5 m beside it, which the cone alone lets a start stand behind).
        """
        m, k = len(env_idx), START_CANDIDATES
        dev = self.device
        direction = self.episode_rng.randn(env_idx, k, 3)
        direction[..., 2] = direction[..., 2].abs() * 0.6  # starts from level to well above the target
        direction = direction / torch.linalg.norm(direction, dim=-1, keepdim=True)
        if within_cone is not None:  # mirror candidates behind the anchor to its front
            axis, _ = within_cone
            along = (direction * axis[:, None]).sum(-1, keepdim=True)
            direction = torch.where(along < 0, direction - 2 * along * axis[:, None], direction)
        dist = distance[0] + self.episode_rng.rand(env_idx, k, 1) * (distance[1] - distance[0])
        tcp = anchor[:, None, :] + dist * direction
        yaw = (self.episode_rng.rand(env_idx, k) * 2 - 1) * math.pi  # drawn even where overridden: same stream
        offset = torch.tensor(self.platform.grasp_point_m, device=dev)
        if face_anchor:  # the arm reaches forward: look at the anchor
            to_anchor = anchor[:, None, :2] - tcp[..., :2]
            yaw = torch.atan2(to_anchor[..., 1], to_anchor[..., 0])
        if heading is not None:
            yaw = heading[:, None].expand(m, k)
        c, s = torch.cos(yaw), torch.sin(yaw)
        rotated = torch.stack([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1], offset[2].expand_as(c)], -1)
        if from_airframe:
            airframe, tcp = tcp, tcp + rotated
        else:
            airframe = tcp - rotated
        boxes = self.obstacle_boxes(env_idx)
        free = is_pose_free(airframe, yaw, boxes, self.start_proxy_points, START_CLEARANCE_M + self.proxy_radius)
        lo, hi = self.workspace_lo[env_idx][:, None], self.workspace_hi[env_idx][:, None]
        free &= (airframe[..., :2] > lo[..., :2] + 0.4).all(-1) & (airframe[..., :2] < hi[..., :2] - 0.4).all(-1)
        free &= (airframe[..., 2] > lo[..., 2] + self.safety.min_altitude_m + 0.1)
        free &= airframe[..., 2] < hi[..., 2] - self.safety.ceiling_margin_m - 0.2
        free &= tcp[..., 2] >= min_tcp_height[:, None]
        if reject is not None:
            free &= ~reject(tcp)
        if within_cone is not None:
            axis, min_cos = within_cone
            free &= (direction * axis[:, None]).sum(-1) >= min_cos
            t = torch.linspace(0.0, 1.0, SIGHT_POINTS, device=dev)[None, None, :, None]
            to_tcp = anchor[:, None, None, :] + (SIGHT_SKIP_M + t * (dist[..., None] - SIGHT_SKIP_M)) * direction[:, :, None]
            to_airframe = tcp[:, :, None] + t * (airframe - tcp)[:, :, None]
            sight = torch.cat([to_tcp, to_airframe], dim=2)
            free &= points_clear_of_boxes(sight.reshape(m, -1, 3), boxes, 0.0).reshape(m, k, -1).all(-1)
        if carried_points is not None:
            pts = (tcp[:, :, None, :] + carried_points[:, None]).reshape(m, -1, 3)
            free &= points_clear_of_boxes(pts, boxes, START_CLEARANCE_M).reshape(m, k, -1).all(-1)
        ok = free.any(-1)
        pick = torch.argmax(free.int(), dim=-1)
        rows = torch.arange(m, device=dev)
        return airframe[rows, pick], yaw[rows, pick], ok

    def set_drone(self, env_idx: torch.Tensor, position: torch.Tensor, yaw: torch.Tensor, finger_half_opening=None) -> None:
        qpos = self.agent.robot.get_qpos().clone()
        new = self.agent.hover_qpos(position, yaw)
        if finger_half_opening is not None:
            for name in FINGER_JOINT_NAMES:
                new[:, self.agent.robot.active_joints_map[name].active_index[0]] = finger_half_opening
        qpos[env_idx] = new
        self.agent.robot.set_qpos(qpos)
        self.agent.robot.set_qvel(torch.zeros_like(qpos))

    def place_object(self, actor: Actor, env_idx: torch.Tensor, bottom: torch.Tensor, yaw: torch.Tensor) -> None:
        """Upright at `bottom` `(M, 3)` (origin at the object's bottom centre) with heading `yaw`."""
        q = torch.stack([torch.cos(yaw / 2), torch.zeros_like(yaw), torch.zeros_like(yaw), torch.sin(yaw / 2)], -1)
        actor.set_pose(Pose.create_from_pq(p=bottom + torch.tensor([0, 0, 0.002], device=self.device), q=q))
        actor.set_linear_velocity(torch.zeros(len(env_idx), 3, device=self.device))
        actor.set_angular_velocity(torch.zeros(len(env_idx), 3, device=self.device))

    def place_distractors(self, env_idx: torch.Tensor, avoid: torch.Tensor | list[torch.Tensor],
                          kinds: tuple[str, ...]) -> None:
        """Distractors on random supports, away from each point of `avoid` (`(M, 3)` each: the target, and in a chain
        every place goal too) and from each other."""
        placed = list(avoid) if isinstance(avoid, (list, tuple)) else [avoid]
        nowhere = torch.full((len(env_idx), 3), 1e6, device=self.device)  # a parked distractor blocks no spot
        for i, actor in enumerate(self.distractors):
            index, ok = self.sample_supports(env_idx, kinds)
            parked = torch.tensor([0.0, 0.0, PARKING_DEPTH_M - i], device=self.device).expand(len(env_idx), 3)
            best, found = parked, torch.zeros(len(env_idx), dtype=torch.bool, device=self.device)
            for _ in range(8):  # a few tries, the last clear one stands; with none it stays parked, never on the goal
                point = self.sample_on_support(env_idx, index, torch.full((len(env_idx),), 0.12, device=self.device))
                clear = torch.stack([torch.linalg.norm((point - p)[:, :2], dim=-1) for p in placed]).min(0).values > 0.25
                best = torch.where((clear & ok)[:, None], point, best)
                found |= clear & ok
            self.place_object(actor, env_idx, best, (self.episode_rng.rand(env_idx) * 2 - 1) * math.pi)
            placed.append(torch.where(found[:, None], best, nowhere))
