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
        rows = torch.arange(self.points.shape[0], device=self.points.device)
        last = self.index >= self.length - 1
        current = self.points[rows, self.index.clamp(max=self.capacity - 1)]
        passed = (~last) & (torch.linalg.norm(position - current, dim=-1) < PASS_RADIUS_M)
        self.index = self.index + passed.long()
        current = self.points[rows, self.index.clamp(max=self.capacity - 1)]
        return current, self.index >= self.length - 1
