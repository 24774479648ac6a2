"""A simple procedural room: floor, four walls and a table, for flight tests and the demo."""

from __future__ import annotations

from dataclasses import dataclass

import sapien
from mani_skill.envs.scene import ManiSkillScene
from mani_skill.utils.structs import Actor

WALL_THICKNESS_M = 0.1


@dataclass(frozen=True)
class RoomLayout:
    width_m: float = 6.0
    depth_m: float = 6.0
    height_m: float = 3.0
    floor_color: tuple[float, float, float] = (0.55, 0.5, 0.45)
    wall_color: tuple[float, float, float] = (0.86, 0.85, 0.82)
    table_center_m: tuple[float, float] = (1.6, 1.6)
    table_half_size_m: tuple[float, float, float] = (0.5, 0.35, 0.38)


def _static_box(scene: ManiSkillScene, name: str, center, half_size, color) -> Actor:
    builder = scene.create_actor_builder()
    pose = sapien.Pose(p=list(center))
    builder.add_box_collision(pose=pose, half_size=list(half_size))
    builder.add_box_visual(pose=pose, half_size=list(half_size), material=color)
    builder.initial_pose = sapien.Pose()
    return builder.build_static(name=name)


def build_room(scene: ManiSkillScene, layout: RoomLayout = RoomLayout()) -> dict[str, Actor]:
    """Floor at z = 0, walls around the origin, a table in one corner. Returns the actors by name."""
    w, d, h, t = layout.width_m / 2, layout.depth_m / 2, layout.height_m, WALL_THICKNESS_M
    actors = {"floor": _static_box(scene, "floor", (0, 0, -t / 2), (w + t, d + t, t / 2), layout.floor_color)}
    for name, center, half in (
        ("wall_north", (0, d + t / 2, h / 2), (w + t, t / 2, h / 2)),
        ("wall_south", (0, -d - t / 2, h / 2), (w + t, t / 2, h / 2)),
        ("wall_east", (w + t / 2, 0, h / 2), (t / 2, d, h / 2)),
        ("wall_west", (-w - t / 2, 0, h / 2), (t / 2, d, h / 2)),
    ):
        actors[name] = _static_box(scene, name, center, half, layout.wall_color)
    tx, ty = layout.table_center_m
    hx, hy, hz = layout.table_half_size_m
    actors["table"] = _static_box(scene, "table", (tx, ty, hz), (hx, hy, hz), (0.45, 0.3, 0.2))
    return actors
