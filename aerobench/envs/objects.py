"""Manipulated objects, built from primitives with YCB-like sizes and the spec's masses.

Sources: dimensions from the YCB object set (Calli et al., 2015, object table; rounded to mm). Masses follow the spec
where it constrains them (appendix "Payload-Aware Flight Control"): the three filled cans (master chef, tomato soup,
potted meat) weigh 0.37-0.40 kg and the tomato can 0.37 kg; sugar, pudding and gelatin boxes are empty (at most
0.04 kg); the others keep their YCB mass. The delivery package (PackageDelivery) is a slim parcel sized for the
110 mm gripper. Grasping is by contact only: nothing is ever attached or teleported.

Object frame: origin at the bottom centre, z up. The grasp frame (`grasp_point_m`, fingers closing along the object
x axis) is where the tool centre point sits in a planned grasp: boxes across their narrow side (x), cylinders
across the diameter, the bowl by its rim wall (one finger inside, one outside).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Literal

import sapien
from mani_skill.envs.scene import ManiSkillScene
from mani_skill.utils.structs import Actor

Shape = Literal["cylinder", "box", "bowl"]
OBJECT_FRICTION = 0.6  # printed cardboard / painted tin against the finger pads (PhysX averages the two)
GRASP_MIN_HEIGHT_M = 0.025


@dataclass(frozen=True)
class ObjectSpec:
    """One object class. `size_m`: cylinder (diameter, height); box (x, y, z); bowl (diameter, height, wall)."""

    name: str
    shape: Shape
    size_m: tuple[float, ...]
    mass_kg: float
    color: tuple[float, float, float]
    source: str

    @property
    def height_m(self) -> float:
        return self.size_m[1] if self.shape in ("cylinder", "bowl") else self.size_m[2]

    @property
    def grasp_point_m(self) -> tuple[float, float, float]:
        """Tool centre point of a planned grasp in the object frame (fingers close along object x).

        Half height, but at least 25 mm above the support so the finger tips (20 mm below the TCP) stay clear of it;
        the bowl is pinched 15 mm below its rim, on the wall at +x.
        """
        if self.shape == "bowl":
            diameter, height, wall = self.size_m
            return (diameter / 2 - wall / 2, 0.0, height - 0.015)
        return (0.0, 0.0, max(self.height_m / 2, GRASP_MIN_HEIGHT_M))

    @property
    def footprint_radius_m(self) -> float:
        """Radius of the smallest vertical cylinder around the object (for placing it on supports)."""
        if self.shape == "box":
            return math.hypot(self.size_m[0], self.size_m[1]) / 2
        return self.size_m[0] / 2

    @property
    def half_extent_m(self) -> tuple[float, float]:
        """Half its horizontal extent along its own x (the closing axis) and y."""
        if self.shape == "box":
            return self.size_m[0] / 2, self.size_m[1] / 2
        return self.size_m[0] / 2, self.size_m[0] / 2

    @property
    def grasp_width_m(self) -> float:
        """Width between the pads when grasped: diameter, the box's narrow horizontal side, or the bowl's rim wall."""
        if self.shape == "cylinder":
            return self.size_m[0]
        if self.shape == "box":
            return min(self.size_m[0], self.size_m[1])
        return self.size_m[2]


OBJECTS: Mapping[str, ObjectSpec] = MappingProxyType(
    {
        o.name: o
        for o in (
            ObjectSpec("master_chef_can", "cylinder", (0.102, 0.139), 0.40, (0.15, 0.35, 0.7), "YCB 002; spec filled can"),
            ObjectSpec("cracker_box", "box", (0.060, 0.158, 0.210), 0.411, (0.85, 0.2, 0.15), "YCB 003"),
            ObjectSpec("sugar_box", "box", (0.038, 0.089, 0.175), 0.04, (0.95, 0.9, 0.6), "YCB 004; spec <= 0.04 kg"),
            ObjectSpec("tomato_soup_can", "cylinder", (0.066, 0.101), 0.37, (0.8, 0.1, 0.1), "YCB 005; spec 0.37 kg"),
            ObjectSpec("tuna_fish_can", "cylinder", (0.085, 0.033), 0.171, (0.3, 0.4, 0.8), "YCB 007"),
            ObjectSpec("pudding_box", "box", (0.035, 0.110, 0.089), 0.035, (0.55, 0.35, 0.2), "YCB 008; spec <= 0.04 kg"),
            ObjectSpec("gelatin_box", "box", (0.028, 0.085, 0.073), 0.03, (0.9, 0.3, 0.5), "YCB 009; spec <= 0.04 kg"),
            ObjectSpec("potted_meat_can", "box", (0.050, 0.097, 0.082), 0.37, (0.25, 0.45, 0.75), "YCB 010; spec filled can"),
            # The rim is 16 mm thick (a ceramic bowl): the gripper's 150 N/m drive then pinches it with about 1.2 N
            # per finger, just enough to carry its 0.147 kg, so bowls stay the hard class they are in the spec.
            ObjectSpec("bowl", "bowl", (0.159, 0.053, 0.016), 0.147, (0.85, 0.25, 0.2), "YCB 024 (thick rim)"),
        )
    }
)


PACKAGE = ObjectSpec("package", "box", (0.080, 0.200, 0.120), 0.30, (0.72, 0.55, 0.35), "delivery parcel (nominal)")
ALL_OBJECTS: Mapping[str, ObjectSpec] = MappingProxyType({**OBJECTS, PACKAGE.name: PACKAGE})


def get_object(name: str) -> ObjectSpec:
    try:
        return ALL_OBJECTS[name]
    except KeyError:
        raise ValueError(f"unknown object {name!r}; valid objects: {', '.join(ALL_OBJECTS)}") from None


def _inertia(spec: ObjectSpec) -> list[float]:
    m = spec.mass_kg
    if spec.shape == "box":
        x, y, z = spec.size_m
        return [m * (y * y + z * z) / 12, m * (x * x + z * z) / 12, m * (x * x + y * y) / 12]
    r, h = spec.size_m[0] / 2, spec.size_m[1]
    if spec.shape == "cylinder":
        return [m * (3 * r * r + h * h) / 12, m * (3 * r * r + h * h) / 12, m * r * r / 2]
    return [m * (r * r / 2 + h * h / 3), m * (r * r / 2 + h * h / 3), m * r * r]  # thin-walled bowl


def build_object(
    scene: ManiSkillScene,
    spec: ObjectSpec,
    name: str,
    initial_pose: sapien.Pose | None = None,
    scene_idxs: list[int] | None = None,
    mesh_dir: Path | None = None,
) -> Actor:
    """A dynamic actor whose origin is at the bottom centre of the object (so it rests at z = 0 on a support).

    `scene_idxs` builds it only in those parallel envs (objects differ per env; merge them with `Actor.merge`).
    `mesh_dir`: a YCB model folder (`collision.ply`, `textured.obj`) to use instead of the primitive shape; the
    mesh is shifted so its bounding box's bottom centre is the origin, and the spec's mass is kept.
    """
    builder = scene.create_actor_builder()
    if scene_idxs is not None:
        builder.set_scene_idxs(scene_idxs)
    material = sapien.physx.PhysxMaterial(OBJECT_FRICTION, OBJECT_FRICTION, 0.0)
    h = spec.height_m
    if mesh_dir is not None:
        import trimesh

        bounds = trimesh.load(str(mesh_dir / "collision.ply"), force="mesh").bounds
        offset = sapien.Pose(p=[-(bounds[0][0] + bounds[1][0]) / 2, -(bounds[0][1] + bounds[1][1]) / 2, -bounds[0][2]])
        builder.add_multiple_convex_collisions_from_file(str(mesh_dir / "collision.ply"), pose=offset, material=material)
        builder.add_visual_from_file(str(mesh_dir / "textured.obj"), pose=offset)
    elif spec.shape == "cylinder":
        pose = sapien.Pose(p=[0, 0, h / 2], q=[math.cos(-math.pi / 4), 0, math.sin(-math.pi / 4), 0])  # x -> z
        builder.add_cylinder_collision(pose=pose, radius=spec.size_m[0] / 2, half_length=h / 2, material=material)
        builder.add_cylinder_visual(pose=pose, radius=spec.size_m[0] / 2, half_length=h / 2, material=spec.color)
    elif spec.shape == "box":
        half = [s / 2 for s in spec.size_m]
        pose = sapien.Pose(p=[0, 0, h / 2])
        builder.add_box_collision(pose=pose, half_size=half, material=material)
        builder.add_box_visual(pose=pose, half_size=half, material=spec.color)
    else:  # bowl: a base disk and a ring of wall segments, so a finger fits inside the rim
        diameter, height, wall = spec.size_m
        r = diameter / 2
        base = sapien.Pose(p=[0, 0, wall / 2], q=[math.cos(-math.pi / 4), 0, math.sin(-math.pi / 4), 0])
        builder.add_cylinder_collision(pose=base, radius=0.6 * r, half_length=wall / 2, material=material)
        builder.add_cylinder_visual(pose=base, radius=0.6 * r, half_length=wall / 2, material=spec.color)
        segments = 16
        seg_half_len = r * math.sin(math.pi / segments) + wall / 2
        for i in range(segments):
            a = 2 * math.pi * i / segments
            pose = sapien.Pose(
                p=[(r - wall / 2) * math.cos(a), (r - wall / 2) * math.sin(a), height / 2],
                q=[math.cos(a / 2), 0, 0, math.sin(a / 2)],
            )
            half = [wall / 2, seg_half_len, height / 2]
            builder.add_box_collision(pose=pose, half_size=half, material=material)
            builder.add_box_visual(pose=pose, half_size=half, material=spec.color)
    com = sapien.Pose(p=[0, 0, h / 2 if spec.shape != "bowl" else h / 3])
    builder.set_mass_and_inertia(spec.mass_kg, com, _inertia(spec))
    builder.initial_pose = initial_pose if initial_pose is not None else sapien.Pose()
    return builder.build(name=name)
