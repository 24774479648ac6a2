"""Visual evaluation conditions (`envs/conditions/visual.py`): each model against its formula, the per-env noise
streams batched against single envs, and the env under them: the lights and materials it builds, the frames a policy
reads, and physics untouched. Rendering here is lavapipe on the CPU: two tiny rendered envs, a few steps each."""

from __future__ import annotations

import math

import gymnasium as gym
import pytest
import sapien
import torch
from mani_skill.envs.sapien_env import BaseEnv

import aerobench.envs  # noqa: F401
from aerobench.envs.conditions import CONDITIONS, Condition, resolve_condition
from aerobench.envs.conditions.runtime import SURFACE_STREAM, ConditionRuntime, stream_generator
from aerobench.envs.conditions.visual import (
    CameraNoise,
    Lighting,
    MotionBlur,
    SurfaceColours,
    camera_counter,
    colour_temperature_tint,
    hashed_normals,
    motion_blur,
    noisy_depth,
    noisy_rgb,
    planckian_xy,
    rotational_flow,
    stereo_depth_rms_per_m,
)
from aerobench.envs.control.so3 import hat, quat_wxyz_to_matrix
from aerobench.envs.platforms import GRIPPER_PLATFORM
from aerobench.envs.scenes.layout import Box, SceneLayout
from tests.cli_here import aerobench_here

VISUAL = ("lighting_dim", "lighting_bright", "lighting_warm", "lighting_side", "surface_colours", "camera_noise",
          "motion_blur")
SMALL_CAMERAS = dict(width=32, height=24)  # every onboard camera (a ManiSkill sensor_configs override): cheap renders


def _layout() -> SceneLayout:
    grey, wood = (0.9, 0.89, 0.85), (0.55, 0.38, 0.22)
    boxes = (Box("wall_a", (0, 0, 1), (1, 0.1, 1), color=grey, kind="wall"),
             Box("table", (0, 1, 0.4), (0.5, 0.5, 0.4), color=wood),
             Box("wall_b", (2, 0, 1), (1, 0.1, 1), color=grey, kind="wall"))
    return SceneLayout("test", boxes, (), (), (-1, -1, 0), (3, 3, 2.5), ambient_light=(0.3, 0.3, 0.3),
                       sun_direction=(0.5, -0.5, -0.7071), sun_color=(0.95, 0.95, 0.9))


# --------------------------------------------------------------------------------------------------------------------
# The scene's models
# --------------------------------------------------------------------------------------------------------------------
def test_lighting_scales_and_tints_every_light_and_lowers_the_sun_at_its_azimuth():
    model = Lighting(0.5, (1.2, 1.0, 0.6), 10.0)
    lit = model.relight(_layout())
    assert lit.ambient_light == pytest.approx((0.3 * 0.5 * 1.2, 0.3 * 0.5, 0.3 * 0.5 * 0.6))
    assert lit.sun_color == pytest.approx((0.95 * 0.6, 0.95 * 0.5, 0.9 * 0.3))
    d = lit.sun_direction
    assert math.hypot(*d) == pytest.approx(1.0) and d[2] == pytest.approx(-math.sin(math.radians(10)))
    assert math.atan2(d[1], d[0]) == pytest.approx(math.atan2(-0.5, 0.5))  # the layout's azimuth
    assert lit.boxes == _layout().boxes
    assert Lighting().relight(_layout()) == _layout()  # the identity model changes nothing
    with pytest.raises(ValueError):
        Lighting(0.0)


def test_colour_temperature_follows_the_planckian_locus():
    # CIE standard illuminant A is a 2856 K black body (on the old c2 = 1.435e-2 m K: 2848 K on today's):
    # x = 0.4476, y = 0.4074 (CIE 15:2004); the splines are good to about 1e-3
    assert planckian_xy(2848) == pytest.approx((0.4476, 0.4074), abs=1e-3)
    assert planckian_xy(6500) == pytest.approx((0.3135, 0.3236), abs=1e-3)
    assert colour_temperature_tint(6500) == pytest.approx((1.0, 1.0, 1.0))
    warm = colour_temperature_tint(3000)
    assert warm[0] > 1.0 > warm[1] > warm[2]  # red up, blue down
    assert 0.2126 * warm[0] + 0.7152 * warm[1] + 0.0722 * warm[2] == pytest.approx(1.0, abs=1e-3)  # white's luminance
    assert CONDITIONS["lighting_warm"].lighting.tint == warm


def test_surface_colours_are_bounded_gains_per_colour_from_the_seeded_stream():
    model, layout = SurfaceColours(0.5), _layout()
    first = model.recolour(layout, stream_generator(7, SURFACE_STREAM))
    again = model.recolour(layout, stream_generator(7, SURFACE_STREAM))
    other = model.recolour(layout, stream_generator(8, SURFACE_STREAM))
    assert first == again and first != other
    gains = model.gains(2, stream_generator(7, SURFACE_STREAM))
    assert ((gains >= 0.5) & (gains <= 1.5)).all()
    for box, new in zip(layout.boxes, first.boxes):
        assert new.center == box.center and new.half_size == box.half_size and new.kind == box.kind
    grey_gain, wood_gain = gains.tolist()
    expected_grey = tuple(min(1.0, c * g) for c, g in zip(layout.boxes[0].color, grey_gain))
    assert first.boxes[0].color == pytest.approx(expected_grey) and first.boxes[2].color == first.boxes[0].color
    assert first.boxes[1].color == pytest.approx(tuple(c * g for c, g in zip(layout.boxes[1].color, wood_gain)))


# --------------------------------------------------------------------------------------------------------------------
# The frames' models
# --------------------------------------------------------------------------------------------------------------------
def test_hashed_normals_are_standard_normal_and_independent():
    keys, step = torch.tensor([12345, 99]), torch.tensor([3, 3])
    z = hashed_normals(keys, step, camera_counter("drone_front"), 200_000)
    n = z.shape[1]
    assert abs(z.mean().item()) < 4 / math.sqrt(2 * n) and z.std().item() == pytest.approx(1.0, abs=0.01)
    assert (z.abs() > 3).float().mean().item() == pytest.approx(0.0027, abs=0.001)  # Gaussian tails
    corr = lambda a, b: torch.corrcoef(torch.stack([a, b]))[0, 1].item()  # noqa: E731
    assert abs(corr(z[0], z[1])) < 0.01  # another env's key
    assert abs(corr(z[0, :-1], z[0, 1:])) < 0.01  # neighbouring elements (a Box-Muller pair among them)
    later = hashed_normals(keys, step + 1, camera_counter("drone_front"), n)
    beside = hashed_normals(keys, step, camera_counter("drone_hand"), n)
    assert abs(corr(z[0], later[0])) < 0.01 and abs(corr(z[0], beside[0])) < 0.01
    # a batch draws what single envs draw, and a shorter draw is a prefix of a longer one
    single = hashed_normals(keys[1:], step[1:], camera_counter("drone_front"), 1001)
    assert torch.equal(single[0], z[1, :1001])


def test_camera_noise_adds_its_sigmas_rounds_and_clips():
    model = CameraNoise(4.0, stereo_depth_rms_per_m())
    assert model.depth_rms_per_m == pytest.approx(0.08 / (424 / math.tan(math.radians(43.5)) * 0.05))
    white = hashed_normals(torch.tensor([5]), torch.tensor([0]), 1, 64 * 64 * 4)
    rgb = torch.full((1, 64, 64, 3), 128, dtype=torch.uint8)
    noisy = noisy_rgb(rgb, white[:, :64 * 64 * 3].reshape(rgb.shape), model)
    assert noisy.dtype == torch.uint8 and torch.equal(noisy, (128 + 4 * white[:, :12288].reshape(rgb.shape)).round()
                                                      .to(torch.uint8))
    assert (noisy.float() - 128).std().item() == pytest.approx(4.0, rel=0.05)
    edges = noisy_rgb(torch.tensor([[[[0, 255, 3]]]], dtype=torch.uint8), torch.tensor([[[[-2.0, 2.0, -2.0]]]]), model)
    assert edges.tolist() == [[[[0, 255, 0]]]]
    depth = torch.full((1, 64, 64, 1), 2000, dtype=torch.int16)
    depth[0, 0, 0, 0] = 0  # no return
    d = noisy_depth(depth, white[:, 12288:].reshape(depth.shape), model)
    assert d.dtype == torch.int16 and d[0, 0, 0, 0] == 0
    assert (d.float() - 2000).flatten()[1:].std().item() == pytest.approx(1000 * model.depth_rms_per_m * 4, rel=0.05)
    assert noisy_depth(torch.tensor([[[[1]]]], dtype=torch.int16), torch.tensor([[[[-1e6]]]]), model).item() == 1


def test_rotational_flow_is_the_image_motion_of_a_turning_camera():
    intrinsic = torch.tensor([[[20.0, 0.0, 16.0], [0.0, 18.0, 12.0], [0.0, 0.0, 1.0]]])
    omega = torch.tensor([[0.7, -1.1, 0.4]], dtype=torch.float64)  # rad/s in the camera's (x right, y down, z ahead)
    flow = rotational_flow(omega, intrinsic.double(), 24, 32)
    dt = 1e-6
    turn = torch.linalg.matrix_exp(hat(omega * dt))[0]  # the camera's new orientation in its old frame
    for i, j in ((0, 0), (5, 20), (23, 31), (12, 16)):
        u, v = j + 0.5, i + 0.5
        point = torch.tensor([(u - 16.0) / 20.0, (v - 12.0) / 18.0, 1.0], dtype=torch.float64) * 2.5  # any depth
        seen = turn.T @ point  # a static point in the turned camera's frame
        moved = torch.stack([20.0 * seen[0] / seen[2] + 16.0, 18.0 * seen[1] / seen[2] + 12.0])
        assert ((moved - torch.tensor([u, v], dtype=torch.float64)) / dt).tolist() == pytest.approx(
            flow[0, i, j].tolist(), rel=1e-4, abs=1e-4)


def _bilinear_border(image: torch.Tensor, u: float, v: float) -> torch.Tensor:
    """The frame `(H, W, C)` at continuous pixel coordinates (pixel centres at j + 1/2), edges repeated."""
    h, w, _ = image.shape
    x, y = min(max(u - 0.5, 0.0), w - 1.0), min(max(v - 0.5, 0.0), h - 1.0)
    x0, y0 = min(int(x), w - 2), min(int(y), h - 2)
    ax, ay = x - x0, y - y0
    top = (1 - ax) * image[y0, x0] + ax * image[y0, x0 + 1]
    bottom = (1 - ax) * image[y0 + 1, x0] + ax * image[y0 + 1, x0 + 1]
    return (1 - ay) * top + ay * bottom


def test_motion_blur_is_the_frame_averaged_along_the_flow_over_the_exposure():
    g = torch.Generator().manual_seed(0)
    frame = torch.rand(1, 12, 16, 2, generator=g, dtype=torch.float64).float()
    intrinsic = torch.tensor([[[8.0, 0.0, 8.0], [0.0, 8.0, 6.0], [0.0, 0.0, 1.0]]])
    flow = rotational_flow(torch.tensor([[0.4, 3.0, -1.5]]), intrinsic, 12, 16)
    model = MotionBlur(exposure_s=0.05, taps=5)
    blurred = motion_blur(frame, flow, model)
    times = (0.0, 0.0125, 0.025, 0.0375, 0.05)  # s_k = T k / (K - 1)
    for i in range(12):
        for j in range(16):
            du, dv = flow[0, i, j].tolist()
            samples = [_bilinear_border(frame[0], j + 0.5 + du * s, i + 0.5 + dv * s) for s in times]
            assert blurred[0, i, j].tolist() == pytest.approx(torch.stack(samples).mean(0).tolist(), abs=1e-5)
    still = torch.randint(0, 256, (1, 12, 16, 3), generator=g, dtype=torch.uint8)
    assert torch.equal(motion_blur(still, torch.zeros(1, 12, 16, 2), model), still)  # a still camera: the frame itself
    # a bright column in a camera panning left (content flowing right) streaks back to where it came from (left)
    column = torch.zeros(1, 12, 16, 1)
    column[:, :, 10] = 1.0
    streak = motion_blur(column, torch.tensor([80.0, 0.0]).expand(1, 12, 16, 2), MotionBlur(0.05, 5))[0, 6, :, 0]
    assert streak[6:11].tolist() == pytest.approx([0.2] * 5) and streak[:6].sum() == 0 and streak[11:].sum() == 0


# --------------------------------------------------------------------------------------------------------------------
# Registry and per-env streams
# --------------------------------------------------------------------------------------------------------------------
def test_visual_conditions_are_named_versioned_and_compose_with_the_others():
    for name in VISUAL:
        condition = CONDITIONS[name]
        assert condition.version == 1 and condition.source and condition.parameters()
    both = resolve_condition("wind_steady_2ms,camera_noise,motion_blur,lighting_dim,surface_colours")
    assert both.is_physical and both.is_visual and both.changes_frames and both.changes_scene
    images = resolve_condition("camera_noise")
    assert images.is_visual and images.changes_frames and not images.changes_scene
    assert not images.is_physical and not images.senses
    assert not resolve_condition("wind_steady_2ms").is_visual
    with pytest.raises(ValueError, match="both set the lighting model"):
        resolve_condition("lighting_dim,lighting_warm")
    record = resolve_condition("camera_noise").records()[0]
    assert record["parameters"]["camera_noise"] == {"rgb_sigma": 4.0, "depth_rms_per_m": stereo_depth_rms_per_m()}
    from aerobench.rollout.runner import RolloutSpec

    with pytest.raises(ValueError, match="change what the cameras see, and this run renders no camera"):
        RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=1, record_cameras=False, condition="camera_noise")
    done = aerobench_here("conditions")
    assert done.returncode == 0, done.stderr
    listed = [line.split()[0] for line in done.stdout.splitlines()]
    assert all(name in listed for name in VISUAL)


def test_a_batch_of_two_sees_the_frames_two_single_envs_see():
    condition = resolve_condition("camera_noise,motion_blur")
    g = torch.Generator().manual_seed(1)
    frames = {cam: {"rgb": torch.randint(0, 256, (2, 6, 8, 3), generator=g, dtype=torch.uint8),
                    "depth": torch.randint(0, 4000, (2, 6, 8, 1), generator=g, dtype=torch.int16)}
              for cam in ("drone_front", "drone_hand")}
    motion = {"drone_front": (torch.tensor([[0.3, -2.0, 0.1], [1.0, 0.5, -0.5]]),
                              torch.tensor([[4.0, 0.0, 4.0], [0.0, 4.0, 3.0], [0.0, 0.0, 1.0]]).expand(2, 3, 3))}
    step = torch.tensor([0, 7])

    def seen(rows: list[int], seeds: list[int]) -> dict:
        runtime = ConditionRuntime(condition, GRIPPER_PLATFORM, len(rows), "cpu", lambda: None, horizon=8)
        runtime.seed(list(range(len(rows))), seeds)
        runtime.start_episodes(list(range(len(rows))))
        part = {cam: {k: v[rows] for k, v in images.items()} for cam, images in frames.items()}
        return runtime.camera_frames(part, step[rows], {c: (w[rows], k[rows]) for c, (w, k) in motion.items()})

    batch, one, two = seen([0, 1], [5, 1_000_008]), seen([0], [5]), seen([1], [1_000_008])
    for cam in frames:
        for kind in ("rgb", "depth"):
            assert torch.equal(batch[cam][kind], torch.cat([one[cam][kind], two[cam][kind]])), (cam, kind)
            assert not torch.equal(batch[cam][kind], frames[cam][kind])
    again = seen([0, 1], [5, 1_000_008])  # asked again at the same step: the same frames
    assert all(torch.equal(again[c][k], batch[c][k]) for c in frames for k in ("rgb", "depth"))


# --------------------------------------------------------------------------------------------------------------------
# The env under visual conditions
# --------------------------------------------------------------------------------------------------------------------
def _pick(condition, obs_mode: str = "state_dict", **kwargs):
    env = gym.make("AeroPick-v1", setting="TidyHouse", obs_mode=obs_mode, condition=condition, **kwargs)
    obs, _ = env.reset(seed=3, options={"reconfigure": True, "objects": ["bowl"]})
    return env, obs


def test_scene_conditions_reach_the_lights_and_the_materials_and_keep_the_starts():
    lights = Condition("lights", 1, "", "", lighting=Lighting(0.5, (1.2, 1.0, 0.8), 10.0),
                       surface_colours=SurfaceColours(0.5))
    nominal, _ = _pick(None)
    lit, _ = _pick([lights])
    try:
        a, b = nominal.unwrapped, lit.unwrapped
        assert torch.equal(a.agent.robot.get_qpos(), b.agent.robot.get_qpos())  # the same start
        assert torch.equal(a.target.pose.raw_pose, b.target.pose.raw_pose)
        layout = a.layouts[0]
        system = b.scene.sub_scenes[0].render_system
        assert list(system.ambient_light) == pytest.approx(lights.lighting.light_colour(layout.ambient_light))
        sun, fill = system.lights  # the layout's sun, then the shared fill light
        assert list(sun.color) == pytest.approx(lights.lighting.light_colour(layout.sun_color))
        shines = quat_wxyz_to_matrix(torch.tensor([list(sun.entity.pose.q)]))[0, :, 0]  # a light shines along its x
        assert shines.tolist() == pytest.approx(lights.lighting.sun_direction(layout.sun_direction), abs=1e-5)
        assert list(fill.color) == pytest.approx([0.4 * 0.5 * 1.2, 0.4 * 0.5, 0.4 * 0.5 * 0.8])
        expected = lights.surface_colours.recolour(layout, stream_generator(b._episode_seed[0], SURFACE_STREAM))
        assert b.layouts[0] == expected and expected != layout
        body = b.built.static_actors[0]._objs[0].find_component_by_type(sapien.render.RenderBodyComponent)
        materials = [c for shape in body.render_shapes for c in shape.material.base_color[:3]]
        assert materials == pytest.approx([c for box in expected.boxes for c in box.color], abs=1e-6)
    finally:
        nominal.close()
        lit.close()
    with pytest.raises(ValueError, match="lighting and surface colour conditions"):
        gym.make("AeroFly-v1", condition="lighting_dim")


def test_image_conditions_change_the_frames_by_their_formulas_and_not_the_physics():
    """Nominal and `camera_noise,motion_blur` from the same start, the same actions: the same physics bit for bit,
    and each frame the conditioned env hands out is the nominal frame through the runtime's models."""
    nominal, obs_a = _pick(None, "rgbd", sensor_configs=SMALL_CAMERAS)
    noisy, obs_b = _pick("camera_noise,motion_blur", "rgbd", sensor_configs=SMALL_CAMERAS)
    try:
        a, b = nominal.unwrapped, noisy.unwrapped
        # no condition: the frames are ManiSkill's own, untouched
        plain = BaseEnv._get_obs_sensor_data(a)
        assert all(torch.equal(plain[c][k], obs_a["sensor_data"][c][k]) for c in plain for k in plain[c])
        action = torch.tensor([0.4, -0.2, 0.3, 1.0, 1.0])
        for step in range(4):
            motion = b.camera_motion()
            assert torch.linalg.norm(motion["drone_front"][0]).item() == pytest.approx(
                torch.linalg.norm(b.agent.robot.links_map["airframe"].angular_velocity).item(), rel=1e-5)
            expected = b.condition_runtime.camera_frames(obs_a["sensor_data"], b._elapsed_steps, motion)
            for cam, images in expected.items():
                for kind in ("rgb", "depth"):
                    assert torch.equal(obs_b["sensor_data"][cam][kind], images[kind]), (step, cam, kind)
                    assert not torch.equal(obs_b["sensor_data"][cam][kind], obs_a["sensor_data"][cam][kind])
            obs_a, *_ = nominal.step(action)
            obs_b, *_ = noisy.step(action)
            assert torch.equal(a.agent.robot.get_qpos(), b.agent.robot.get_qpos()), step
            assert torch.equal(a.agent.robot.get_qvel(), b.agent.robot.get_qvel()), step
        assert torch.linalg.norm(b.camera_motion()["drone_front"][0]).item() > 0.1  # it turned: blur in play
    finally:
        nominal.close()
        noisy.close()


@pytest.mark.gpu
def test_frame_conditions_batch_on_gpu():
    """physx_cuda, 2 envs with GPU rendering under every visual condition: each env's noise key is its own episode's
    (a CPU runtime seeded alike draws the same), the frames keep their shapes and dtypes, and each camera's motion is
    per env. Not yet run on a GPU (none on the development machine)."""
    names = ("camera_noise", "motion_blur", "lighting_warm", "surface_colours")
    env = gym.make("AeroPick-v1", setting="TidyHouse", obs_mode="rgbd", sim_backend="physx_cuda", num_envs=2,
                   condition=names, sensor_configs=SMALL_CAMERAS)
    try:
        seeds = [3, 1_000_006]
        obs, _ = env.reset(seed=seeds)
        base = env.unwrapped
        action = torch.zeros(2, base.platform.action_dim, device=base.device)
        action[:, 3] = 1.0  # a yaw: the cameras turn
        for _ in range(3):
            obs, *_ = env.step(action)
        for images in obs["sensor_data"].values():
            assert images["rgb"].shape == (2, 24, 32, 3) and images["rgb"].dtype == torch.uint8
            assert images["depth"].shape == (2, 24, 32, 1) and images["depth"].dtype == torch.int16
        assert all(omega.shape == (2, 3) for omega, _ in base.camera_motion().values())
        alone = ConditionRuntime(resolve_condition(names), base.platform, 2, "cpu", lambda: None)
        alone.seed(range(2), seeds)
        alone.start_episodes(range(2))
        assert torch.equal(base.condition_runtime.camera_keys.cpu(), alone.camera_keys)
    finally:
        env.close()
