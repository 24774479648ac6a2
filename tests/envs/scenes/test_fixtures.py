"""Scenes in SAPIEN (physx_cpu, 240 Hz): built layouts hold objects on their supports, the fridge and drawer
articulations match their geometry helpers, and their joint friction breaks away at the spec's handle forces
(spec appendix "Robot platforms": about 7 N for the fridge door, 2.5 N for the drawer)."""

import math
import types

import numpy as np
import pytest
import sapien
import torch
from mani_skill.envs.sapien_env import BaseEnv
from mani_skill.utils.structs import Pose
from mani_skill.utils.structs.types import SimConfig

from aerobench.envs.objects import build_object, get_object
from aerobench.envs.platforms import CONTROL_HZ, PHYSICS_HZ
from aerobench.envs.scenes import generate_layout
from aerobench.envs.scenes.articulated import (
    DRAWER_HANDLE_GAP_M,
    DRAWER_HANDLE_HEIGHT_M,
    DRAWER_HANDLE_LENGTH_M,
    FRICTION_DRIVE_DAMPING,
    FRIDGE_HANDLE_GAP_M,
    FRIDGE_HANDLE_WIDTH_M,
    fixture_box_tensor,
    fixture_boxes,
    get_fixture_spec,
    handle_frame,
    handle_grasp_point,
    normalized_progress,
    packed_fixture_boxes,
    q_bar,
    set_progress,
)
from aerobench.envs.scenes.build import build_layouts, place_fixtures
from aerobench.envs.scenes.layout import ArticulatedFixture


class SceneTestEnv(BaseEnv):
    """A robot-less env that builds the given layouts, drops a can on each of `drops` (supports) and runs `push`
    (if set) before every physics step."""

    SUPPORTED_REWARD_MODES = ("none",)

    def __init__(self, *args, layouts, drops=(), open_drawer=False, **kwargs):
        self.layouts, self.drops, self.open_drawer, self.push = layouts, drops, open_drawer, None
        super().__init__(*args, robot_uids="none", **kwargs)

    @property
    def _default_sim_config(self):
        return SimConfig(sim_freq=PHYSICS_HZ, control_freq=CONTROL_HZ)

    def _load_scene(self, options):
        self.built = build_layouts(self.scene, self.layouts)
        can = get_object("tomato_soup_can")
        self.objects = [build_object(self.scene, can, f"can_{k}", sapien.Pose(p=[0, 0, -2.0 - k])) for k in range(len(self.drops))]

    def _initialize_episode(self, env_idx, options):
        place_fixtures(self.built, env_idx)
        if self.open_drawer and "drawer" in self.built.fixtures:
            self.built.fixtures["drawer"].set_qpos(torch.tensor([[get_fixture_spec("drawer").q_limits[1]]]))
        for obj, s in zip(self.objects, self.drops):
            obj.set_pose(Pose.create_from_pq(p=torch.tensor([[*s.center, s.height + 0.02]])))

    def _before_simulation_step(self):
        if self.push is not None:
            self.push()

    def get_state_dict(self):
        return self.scene.get_sim_state()  # ManiSkill 3.0.1's default also asks the (absent) agent for its controller


def make_env(layout, **kwargs) -> SceneTestEnv:
    env = SceneTestEnv(layouts=[layout], obs_mode="none", reward_mode="none", render_backend="none", sim_backend="physx_cpu", **kwargs)
    env.reset(seed=0)
    return env


@pytest.fixture(scope="module")
def kitchen_env():
    env = make_env(generate_layout("kitchen", np.random.default_rng(3)))
    yield env
    env.close()


def drop_targets(layout):
    """One support of each kind (the drawer opened), in layout order."""
    seen, out = set(), []
    for s in layout.supports:
        if s.kind not in seen:
            seen.add(s.kind)
            out.append(s)
    return out


# --------------------------------------------------------------------------------------------------------------------
# Building layouts
# --------------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("scene", ["apartment", "kitchen", "street", "home"])
def test_built_scene_holds_objects_on_its_supports(scene):
    layout = generate_layout(scene, np.random.default_rng(11))
    targets = drop_targets(layout)
    env = make_env(layout, drops=targets, open_drawer=True)
    try:
        assert [a.name for a in env.built.static_actors] == ["layout_0"]
        assert set(env.built.fixtures) == {f.name for f in layout.fixtures}
        shapes = env.built.static_actors[0]._objs[0].find_component_by_type(sapien.physx.PhysxRigidStaticComponent)
        assert len(shapes.collision_shapes) == len(layout.boxes)  # ceilings collide too
        for _ in range(20):  # 1 s
            env.step(None)
        for obj, s in zip(env.objects, targets):
            p = obj.pose.p[0]
            assert float(p[2]) == pytest.approx(s.height, abs=0.005), s.name
            assert math.dist(p[:2].tolist(), s.center) < 0.02, s.name
            assert float(torch.linalg.norm(obj.linear_velocity[0])) < 0.01, s.name
    finally:
        env.close()


def test_build_layouts_checks_its_inputs():
    kitchen, street = (generate_layout(n, np.random.default_rng(0)) for n in ("kitchen", "street"))
    with pytest.raises(ValueError, match="one layout per env: got 1 layouts for 2 envs"):
        build_layouts(types.SimpleNamespace(num_envs=2), [kitchen])
    with pytest.raises(ValueError, match=r"layout 1 \(street\) has fixtures \[\] but layout 0 has \['fridge', 'drawer'\]"):
        build_layouts(types.SimpleNamespace(num_envs=2), [kitchen, street])


def test_place_fixtures_resets_pose_and_closes(kitchen_env):
    env, layout = kitchen_env, kitchen_env.layouts[0]
    for art in env.built.fixtures.values():
        art.set_qpos(torch.tensor([[0.3]]))
        art.set_root_pose(Pose.create_from_pq(p=torch.tensor([[5.0, 5.0, 0.0]])))
    place_fixtures(env.built, torch.tensor([0]))
    for f in layout.fixtures:
        art = env.built.fixtures[f.name]
        assert torch.allclose(art.root_pose.p[0], torch.tensor(f.position, dtype=torch.float32), atol=1e-5)
        assert float(art.get_qpos()[0, 0]) == 0.0 and float(art.get_qvel()[0, 0]) == 0.0


# --------------------------------------------------------------------------------------------------------------------
# Fixture geometry
# --------------------------------------------------------------------------------------------------------------------
def handle_box(name):
    return next(p for p in get_fixture_spec(name).parts if p.name == "handle")


def test_fixture_dimensions_follow_the_spec():
    fridge, drawer = get_fixture_spec("fridge"), get_fixture_spec("drawer")
    bar = handle_box("fridge")
    assert 2 * bar.half_size[1] == pytest.approx(FRIDGE_HANDLE_WIDTH_M) == pytest.approx(0.050)  # across the door face
    assert 0.040 <= FRIDGE_HANDLE_GAP_M <= 0.045
    assert bar.center[2] - bar.half_size[2] == pytest.approx(0.9) and bar.center[2] + bar.half_size[2] == pytest.approx(1.5)
    assert fridge.q_limits == (0.0, 1.9) and fridge.kind == "hinge"
    assert fridge.half_width_m == pytest.approx(0.35) and fridge.front_x_m - fridge.back_x_m < 0.8
    assert max(p.center[2] + p.half_size[2] for p in fridge.parts) == pytest.approx(1.8)
    bar = handle_box("drawer")
    assert 2 * bar.half_size[2] == pytest.approx(DRAWER_HANDLE_HEIGHT_M) == pytest.approx(0.024)
    assert 2 * bar.half_size[1] == pytest.approx(DRAWER_HANDLE_LENGTH_M) == pytest.approx(0.30)
    assert 0.035 <= DRAWER_HANDLE_GAP_M <= 0.040 and bar.center[2] == pytest.approx(0.75)
    assert drawer.q_limits == (0.0, 0.4) and drawer.kind == "slide"
    assert drawer.half_width_m == pytest.approx(0.30) and max(p.center[2] + p.half_size[2] for p in drawer.parts) == pytest.approx(0.9)


@pytest.mark.parametrize("name", ["fridge", "drawer"])
def test_handle_frame_follows_the_handle_box(name):
    spec = get_fixture_spec(name)
    rng = np.random.default_rng(0)
    for _ in range(5):
        fixture = ArticulatedFixture(name, spec.kind, (*rng.uniform(-3, 3, 2), 0.0), float(rng.uniform(-math.pi, math.pi)), "kitchen")
        q = float(rng.uniform(*spec.q_limits))
        box = next(b for b in fixture_boxes(fixture, q) if b.name.endswith("/handle"))
        root_p = torch.tensor([fixture.position], dtype=torch.float64)
        root_q = torch.tensor([[math.cos(fixture.yaw / 2), 0, 0, math.sin(fixture.yaw / 2)]], dtype=torch.float64)
        q_t = torch.tensor([q], dtype=torch.float64)
        point, normal, axis = handle_frame(name, root_p, root_q, q_t)
        assert torch.allclose(point[0], torch.tensor(box.center, dtype=torch.float64), atol=1e-9)
        assert torch.allclose(normal[0], torch.tensor([math.cos(box.yaw), math.sin(box.yaw), 0.0], dtype=torch.float64), atol=1e-9)
        assert abs(float(axis[0] @ normal[0])) < 1e-9
        packed = fixture_box_tensor(name, root_p, root_q, q_t)[0]  # the batched twin of fixture_boxes
        expected = torch.tensor([[*b.center, *b.half_size, b.yaw, 1.0] for b in fixture_boxes(fixture, q)], dtype=torch.float64)
        assert torch.allclose(packed[:, :6], expected[:, :6], atol=1e-9)
        assert torch.allclose(torch.remainder(packed[:, 6] - expected[:, 6] + math.pi, 2 * math.pi), torch.tensor(math.pi, dtype=torch.float64))
    q = torch.tensor(spec.q_limits)
    assert q_bar(name, q).tolist() == [0.0, 1.0]


@pytest.mark.parametrize("name", ["fridge", "drawer"])
def test_articulation_matches_the_geometry(kitchen_env, name):
    env = kitchen_env
    spec, art = get_fixture_spec(name), env.built.fixtures[name]
    joint = art.joints_map[spec.joint_name]._objs[0]
    assert joint.get_friction() == 0.0 and joint.get_damping() == pytest.approx(FRICTION_DRIVE_DAMPING)
    assert joint.get_force_limit() == pytest.approx(spec.breakaway_effort)
    assert np.allclose(joint.get_limits(), [spec.q_limits])
    link = art.links_map[spec.moving_link]
    origin = spec.hinge_point if spec.kind == "hinge" else (0.0, 0.0, 0.0)
    local = [a - b for a, b in zip(spec.handle_center, origin)]
    for progress in (0.0, 0.3, 1.0):
        set_progress(art, torch.tensor([0]), torch.tensor([progress]))
        assert float(normalized_progress(art)[0]) == pytest.approx(progress, abs=1e-6)
        sapien_point = (link._objs[0].entity_pose * sapien.Pose(p=local)).p
        assert np.allclose(handle_grasp_point(name, art)[0].numpy(), sapien_point, atol=1e-5)
        packed = packed_fixture_boxes([name], [art])
        assert packed.shape == (1, len(spec.parts), 8)
        handle = packed[0, [p.name for p in spec.parts].index("handle")]
        assert np.allclose(handle[:3].numpy(), sapien_point, atol=1e-5)
    place_fixtures(env.built, torch.tensor([0]))


# --------------------------------------------------------------------------------------------------------------------
# Joint friction: breakaway at the spec's handle force
# --------------------------------------------------------------------------------------------------------------------
def ramp_handle_force(env, name: str, peak_fraction: float = 1.6, seconds: float = 3.0) -> np.ndarray:
    """Push along the handle's outward normal with a force rising linearly from 0 to `peak_fraction` x the
    breakaway force; returns rows (force N, handle displacement m) per physics step."""
    spec, art = get_fixture_spec(name), env.built.fixtures[name]
    link = art.links_map[spec.moving_link]._objs[0]
    place_fixtures(env.built, torch.tensor([0]))

    def handle():
        return handle_frame(name, art.root_pose.p, art.root_pose.q, art.get_qpos()[:, 0])

    start = handle()[0][0].clone()
    rate = peak_fraction * spec.breakaway_force_n / seconds
    log = []

    def push():
        force = rate * len(log) / PHYSICS_HZ
        point, normal, _ = handle()
        link.add_force_at_point((force * normal[0]).numpy(), point[0].numpy())  # pull: opens the door / drawer
        log.append((force, float(torch.linalg.norm(point[0] - start))))

    env.push = push
    try:
        for _ in range(int(seconds * CONTROL_HZ)):
            env.step(None)
    finally:
        env.push = None
        place_fixtures(env.built, torch.tensor([0]))
    return np.array(log)


@pytest.mark.parametrize("name", ["fridge", "drawer"])
def test_joint_breaks_away_at_the_spec_handle_force(kitchen_env, name):
    target = get_fixture_spec(name).breakaway_force_n
    log = ramp_handle_force(kitchen_env, name)
    force, moved = log[:, 0], log[:, 1]
    assert moved[force <= 0.8 * target].max() < 1e-3  # held still below 0.8x
    first = force[np.argmax(moved > 1e-3)]  # the handle has moved 1 mm
    assert 0.95 * target < first < 1.3 * target
    assert moved[np.searchsorted(force, 1.3 * target)] > 5e-3  # and clearly moves above 1.3x


@pytest.mark.gpu
def test_parallel_envs_each_get_their_layout_and_fixture_pose():
    layouts = [generate_layout("home", np.random.default_rng(seed)) for seed in range(4)]
    env = SceneTestEnv(layouts=layouts, obs_mode="none", reward_mode="none", render_backend="none", sim_backend="physx_cuda", num_envs=4)
    env.reset(seed=0)
    try:
        assert [a.name for a in env.built.static_actors] == [f"layout_{i}" for i in range(4)]
        for _ in range(5):
            env.step(None)
        for name, art in env.built.fixtures.items():
            expected = torch.tensor([L.fixture(name).position for L in layouts], dtype=torch.float32)
            assert torch.allclose(art.root_pose.p.cpu(), expected, atol=1e-4)
            assert torch.allclose(art.get_qpos().cpu(), torch.zeros(4, 1), atol=1e-4)  # closed, held by the friction drive
    finally:
        env.close()
