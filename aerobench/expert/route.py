"""Batched route following: per-env waypoint lists (padded), a pointer, and the current target."""

from __future__ import annotations

import torch

PASS_RADIUS_M = 0.15  # intermediate waypoints count as passed within this distance


class RouteFollower:
    def __init__(self, n: int, device, capacity: int = 64):
        self.points = torch.zeros(n, capacity, 3, device=device)
        self.length = torch.zeros(n, dtype=torch.long, device=device)
        self.index = torch.zeros(n, dtype=torch.long, device=device)
        self.capacity = capacity

    def set(self, env: int, waypoints: list) -> None:
        """Route of env `env` (airframe-centre waypoints, the last one is the goal)."""
        pts = torch.as_tensor([list(map(float, w)) for w in waypoints][: self.capacity], device=self.points.device)
        self.points[env, : len(pts)] = pts
        self.length[env] = len(pts)
        self.index[env] = 0

    def target(self, position: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Current waypoint `(N, 3)` after passing reached intermediate ones, and whether it is the last `(N,)`."""
        current, last, self.index = route_target(self.points, self.length, self.index, position)
        return current, last


def route_target(points: torch.Tensor, length: torch.Tensor, index: torch.Tensor, position: torch.Tensor
                 ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """`RouteFollower.target` as a pure function: the current waypoint `(N, 3)`, whether it is the last `(N,)` and the
    advanced pointer, from the routes `points` `(N, C, 3)`, their `length` and pointer `index` `(N,)`."""
    rows = torch.arange(points.shape[0], device=points.device)
    capacity = points.shape[1]
    last = index >= length - 1
    current = points[rows, index.clamp(max=capacity - 1)]
    passed = (~last) & (torch.linalg.norm(position - current, dim=-1) < PASS_RADIUS_M)
    index = index + passed.long()
    current = points[rows, index.clamp(max=capacity - 1)]
    return current, index >= length - 1, index
