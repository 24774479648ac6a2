"""The room graph of each env's layout as batched tensors: which doorway a flight from one room to another passes first.

A state-based policy does not see walls. Where its goal lies in another room (PackageDelivery's Place begins on the
street, the cabinet is in the lobby) it needs to know where the opening is, as the cameras would show it; the task
state carries the next doorway on the room route to the goal (`observations`: `doorway_ahead`, `doorway_pos`). That
is scene topology (rooms and the openings between them), not the expert's planned path. The table is built once per
scene from `SceneLayout.rooms` and `.doorways` (a breadth-first search from every room) and looked up per control
step with point-in-rectangle tests, `(num_envs, ...)` throughout.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from .layout import SceneLayout


def first_doorways(layout: SceneLayout) -> dict[tuple[int, int], int]:
    """`{(from room, to room): index of the first doorway on the fewest-doorway route}` over `layout.rooms`
    (indices into `layout.rooms` and `layout.doorways`); rooms that are the same or not connected are absent."""
    index = {room.name: i for i, room in enumerate(layout.rooms)}
    neighbours: dict[int, list[tuple[int, int]]] = {i: [] for i in range(len(layout.rooms))}
    for k, door in enumerate(layout.doorways):
        a, b = (index[name] for name in door.rooms)
        neighbours[a].append((b, k))
        neighbours[b].append((a, k))
    out = {}
    for source in neighbours:
        first = {source: -1}  # room -> the doorway it was first reached through from `source`
        queue = deque([source])
        while queue:
            room = queue.popleft()
            for other, door in neighbours[room]:
                if other not in first:
                    first[other] = door if room == source else first[room]
                    queue.append(other)
        out.update({(source, room): door for room, door in first.items() if room != source})
    return out


@dataclass
class RoomRoutes:
    """Per env: room rectangles `(N, R, 4)` (x lo, y lo, x hi, y hi; padding never contains a point) and, for every
    pair of room slots (slot R: in no room), the first doorway's centre `(N, R+1, R+1, 3)` and whether there is one."""

    rooms: torch.Tensor
    hop: torch.Tensor
    has_hop: torch.Tensor

    @classmethod
    def pack(cls, layouts: Sequence[SceneLayout], device: torch.device | str = "cpu") -> RoomRoutes:
        r = max((len(layout.rooms) for layout in layouts), default=0)
        n = len(layouts)
        rooms = torch.tensor([[1.0, 1.0, -1.0, -1.0]]).repeat(n, max(r, 1), 1)
        hop = torch.zeros(n, r + 1, r + 1, 3)
        has_hop = torch.zeros(n, r + 1, r + 1, dtype=torch.bool)
        for i, layout in enumerate(layouts):
            for j, room in enumerate(layout.rooms):
                rooms[i, j] = torch.tensor([*room.lo, *room.hi])
            for (a, b), door in first_doorways(layout).items():
                hop[i, a, b] = torch.tensor(layout.doorways[door].center)
                has_hop[i, a, b] = True
        return cls(rooms.to(device), hop.to(device), has_hop.to(device))

    def room_of(self, points: torch.Tensor) -> torch.Tensor:
        """`(N,)` the room slot each point `(N, 2 or 3)` is in (by x and y); R where it is in none (a wall, outside)."""
        x, y = points[:, 0, None], points[:, 1, None]
        inside = (x >= self.rooms[..., 0]) & (x <= self.rooms[..., 2]) & (y >= self.rooms[..., 1]) & (y <= self.rooms[..., 3])
        none = torch.full_like(inside[:, :1], True)
        return torch.cat([inside, none], dim=1).long().argmax(dim=1)  # the first room containing it, else slot R

    def next_doorway(self, start: torch.Tensor, goal: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The centre `(N, 3)` of the first doorway on the room route from `start` to `goal` and whether there is one
        `(N,)` (no: the same room, or either point in none); zeros where there is none."""
        rows = torch.arange(start.shape[0], device=start.device)
        a, b = self.room_of(start), self.room_of(goal)
        return self.hop[rows, a, b], self.has_hop[rows, a, b]
