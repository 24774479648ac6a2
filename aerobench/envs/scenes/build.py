"""SAPIEN / ManiSkill actors from scene layouts: one static actor per env, one articulation per fixture type.

All boxes of env i's layout (walls, floor, ceiling, furniture, vehicles) become collision + visual shapes of ONE static
actor that exists only in sub-scene i, which keeps the actor count at one per env for GPU batches. Each fixture type
is one ManiSkill articulation across all envs (its dimensions never change); only its root pose differs per env.
"""

from __future__ import annotations

from dataclasses import dataclass

import sapien
import torch
from mani_skill.envs.scene import ManiSkillScene
from mani_skill.utils.structs import Actor, Articulation, Pose

from .articulated import build_fixture, yaw_quat
from .layout import SceneLayout


@dataclass
class BuiltScene:
    """What `build_layouts` made: per-env static actors, fixture articulations by name, and the layouts themselves."""

    static_actors: list[Actor]
    fixtures: dict[str, Articulation]
    layouts: list[SceneLayout]


def _fixture_root_poses(layouts: list[SceneLayout], name: str, env_idx: list[int], device) -> Pose:
    fixtures = [layouts[i].fixture(name) for i in env_idx]
    p = torch.tensor([f.position for f in fixtures], dtype=torch.float32, device=device)
    q = torch.tensor([yaw_quat(f.yaw) for f in fixtures], dtype=torch.float32, device=device)
    return Pose.create_from_pq(p=p, q=q)


def build_layouts(scene: ManiSkillScene, layouts: list[SceneLayout]) -> BuiltScene:
    """Build layout i into env i (call from `_load_scene`). Every layout must hold the same fixture names."""
    if len(layouts) != scene.num_envs:
        raise ValueError(f"build_layouts needs one layout per env: got {len(layouts)} layouts for {scene.num_envs} envs")
    names = [f.name for f in layouts[0].fixtures]
    for i, layout in enumerate(layouts):
        if [f.name for f in layout.fixtures] != names:
            raise ValueError(
                f"layout {i} ({layout.name}) has fixtures {[f.name for f in layout.fixtures]} but layout 0 has {names}; "
                "parallel envs share one articulation per fixture, so build layouts of one scene type together"
            )
    statics = []
    for i, layout in enumerate(layouts):
        builder = scene.create_actor_builder()
        for box in layout.boxes:
            pose = sapien.Pose(p=list(box.center), q=yaw_quat(box.yaw))
            builder.add_box_collision(pose=pose, half_size=list(box.half_size))
            builder.add_box_visual(pose=pose, half_size=list(box.half_size), material=box.color)
        builder.set_scene_idxs([i])
        builder.initial_pose = sapien.Pose()
        statics.append(builder.build_static(name=f"layout_{i}"))
    every_env = list(range(len(layouts)))
    fixtures = {name: build_fixture(scene, name, _fixture_root_poses(layouts, name, every_env, scene.device)) for name in names}
    return BuiltScene(statics, fixtures, list(layouts))


def place_fixtures(built: BuiltScene, env_idx: torch.Tensor) -> None:
    """Put the fixtures of envs `env_idx` at their layout's root pose, closed and at rest.

    Call from `_initialize_episode(env_idx, ...)`: like every ManiSkill setter during a reset, the `(len(env_idx), ...)`
    values go to the envs being reset.
    """
    idx = [int(i) for i in env_idx]
    for name, articulation in built.fixtures.items():
        articulation.set_root_pose(_fixture_root_poses(built.layouts, name, idx, articulation.device))
        zeros = torch.zeros(len(idx), articulation.max_dof, device=articulation.device)
        articulation.set_qpos(zeros)
        articulation.set_qvel(zeros)


def light_layouts(scene: ManiSkillScene, layouts: list[SceneLayout], shadow: bool = False) -> None:
    """Each env's own ambient light and sun (call from `_load_lighting`; only where the scene can render)."""
    for i, layout in enumerate(layouts):
        sub = scene.sub_scenes[0 if scene.parallel_in_single_scene else i]
        sub.render_system.ambient_light = list(layout.ambient_light)
        scene.add_directional_light(list(layout.sun_direction), list(layout.sun_color), shadow=shadow, scene_idxs=[i])
