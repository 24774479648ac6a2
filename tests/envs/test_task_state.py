"""The task state (`observations.TASK_STATE_FIELDS`) against a hand computation for known poses: relative goal
vectors in the world and heading frames, the heading error with the object's symmetry, the flight state."""

import math

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401  (registers the envs)
from aerobench.envs.objects import get_object
from aerobench.envs.observations import field_slices, task_state_fields, wrap_to_period


def _rz(yaw: float, v) -> torch.Tensor:
    c, s = math.cos(yaw), math.sin(yaw)
    x, y, z = (float(t) for t in v)
    return torch.tensor([c * x - s * y, s * x + c * y, z])


def _fields(ts: torch.Tensor, with_arm: bool = False) -> dict[str, torch.Tensor]:
    return {name: ts[sl] for name, sl in field_slices(task_state_fields(with_arm)).items()}


def _move_drone(base, position: torch.Tensor, yaw: float) -> dict[str, torch.Tensor]:
    idx = torch.tensor([0], device=base.device)
    base.set_drone(idx, position[None].to(base.device), torch.tensor([yaw], device=base.device))
    base._signals_step = -1  # the poses changed without a step: recompute the step's signals
    return _fields(base.task_state()[0].cpu())


@pytest.fixture(scope="module")
def pick_env():
    env = gym.make("AeroPick-v1", setting="TidyHouse", obs_mode="state_dict", object="cracker_box")
    yield env
    env.close()


def test_pick_task_state_equals_a_hand_computation(pick_env):
    base = pick_env.unwrapped
    pick_env.reset(seed=5, options={"reconfigure": True})
    platform, spec = base.platform, get_object("cracker_box")
    obj_p, obj_q = base.target.pose.p[0].cpu(), base.target.pose.q[0].cpu()
    obj_yaw = 2 * math.atan2(float(obj_q[3]), float(obj_q[0]))
    start_yaw = float(base.agent.airframe_state().yaw[0])
    # the planned grasp heading: closing axis (body y) along the box's x axis, the one nearer the start heading
    planned = float(base.evaluators[0].heading[0])
    assert abs(float(wrap_to_period(torch.tensor(planned - obj_yaw - math.pi / 2), math.pi))) < 1e-5
    assert abs(float(wrap_to_period(torch.tensor(planned - start_yaw), 2 * math.pi))) <= math.pi / 2 + 1e-5

    position, yaw = obj_p + torch.tensor([0.1, -0.2, 0.5]), planned + 0.3
    f = _move_drone(base, position, yaw)
    tcp = position + _rz(yaw, platform.grasp_point_m)
    grasp = obj_p + _rz(obj_yaw, spec.grasp_point_m)
    assert torch.equal(f["skill"], torch.tensor([1.0, 0, 0, 0, 0]))
    assert torch.allclose(f["goal_pos"], grasp - tcp, atol=1e-4)
    assert torch.allclose(f["goal_pos_body"], _rz(-yaw, grasp - tcp), atol=1e-4)
    assert torch.allclose(f["tcp_to_obj_pos"], obj_p - tcp, atol=1e-4)
    assert f["heading_error"].item() == pytest.approx(-0.3, abs=1e-4)
    assert f["progress"].item() == pytest.approx(0.0, abs=5e-3)  # the box rests where it was put
    assert f["is_grasp_confirmed"].item() == 0.0
    assert torch.allclose(f["linear_velocity"], torch.zeros(3), atol=1e-5)  # set_drone leaves it still and level
    assert torch.allclose(f["gravity_body_xy"], torch.zeros(2), atol=1e-5)
    assert f["altitude"].item() == pytest.approx(float(position[2] - base.workspace_lo[0, 2]), abs=1e-4)
    # the open fingers (11 cm) around the box's 6 cm grasp width: 2.5 cm each side
    assert f["grasp_side_room"].item() == pytest.approx((platform.gripper.max_opening_m - spec.grasp_width_m) / 2)
    assert f["grasp_side_room"].item() == pytest.approx(0.025, abs=1e-6)

    # a box is symmetric under a half turn: 0.3 rad past the other grasp heading reads the same error
    f = _move_drone(base, position, planned + math.pi + 0.3)
    assert f["heading_error"].item() == pytest.approx(-0.3, abs=1e-4)


def test_a_round_objects_heading_error_wraps_at_a_quarter_turn():
    env = gym.make("AeroPick-v1", setting="TidyHouse", obs_mode="state_dict", object="master_chef_can")
    try:
        base = env.unwrapped
        env.reset(seed=2, options={"reconfigure": True})
        planned = float(base.evaluators[0].heading[0])
        assert abs(float(wrap_to_period(torch.tensor(planned), math.pi / 2))) < 1e-5  # a room axis
        f = _move_drone(base, base.target.pose.p[0].cpu() + torch.tensor([0.0, 0.3, 0.5]), planned + 0.9)
        assert f["heading_error"].item() == pytest.approx(math.pi / 2 - 0.9, abs=1e-4)
        assert f["grasp_side_room"].item() == pytest.approx(0.004, abs=1e-6)  # 11 cm around the can's 10.2 cm
    finally:
        env.close()


def test_place_goal_is_measured_from_the_held_object():
    env = gym.make("AeroPlace-v1", setting="TidyHouse", obs_mode="state_dict", object="tomato_soup_can")
    try:
        base = env.unwrapped
        env.reset(seed=1, options={"reconfigure": True})
        f = _fields(base.task_state()[0].cpu())
        goal, obj = base.evaluators[0].goal[0].cpu(), base.target.pose.p[0].cpu()
        tcp = base.agent.tcp_pose.p[0].cpu()
        assert torch.equal(f["skill"], torch.tensor([0.0, 1, 0, 0, 0]))
        assert torch.allclose(f["goal_pos"], goal - obj, atol=1e-5)
        assert torch.allclose(f["tcp_to_obj_pos"], obj - tcp, atol=1e-5)
        assert f["heading_error"].item() == pytest.approx(0.0, abs=1e-5)  # place holds the start heading
        # the episode starts in an eligible held state: the grasp reads confirmed from the start and while the jaws
        # keep pinching; opening them clears it
        assert f["is_grasp_confirmed"].item() == 1.0
        confirmed = []
        for u_g in [-1.0] * 6 + [1.0] * 10:
            env.step(torch.tensor([[0.0, 0.0, 0.0, 0.0, u_g]]))
            confirmed.append(_fields(base.task_state()[0].cpu())["is_grasp_confirmed"].item())
        assert confirmed[:6] == [1.0] * 6 and confirmed[-1] == 0.0
    finally:
        env.close()


def test_a_goal_in_another_room_shows_the_doorway_to_fly_through():
    """PackageDelivery Place: the cabinet is in the lobby. From the street the task state points at the entrance
    doorway (its centre minus the airframe centre); once inside, at nothing."""
    env = gym.make("AeroPlace-v1", setting="PackageDelivery", obs_mode="state_dict", object="package")
    try:
        base = env.unwrapped
        env.reset(seed=3, options={"reconfigure": True})
        layout = base.layouts[0]
        (door,) = layout.doorways
        assert door.rooms == ("street", "lobby")
        f = _fields(base.task_state()[0].cpu())  # the Place start: 0.5-1 m from the cabinet, inside
        assert f["doorway_ahead"].item() == 0.0 and torch.equal(f["doorway_pos"], torch.zeros(3))
        entrance = torch.tensor(layout.nav_points["the building entrance"])  # 1 m outside the doorway
        yaw = float(base.agent.airframe_state().yaw[0])
        f = _move_drone(base, entrance, yaw)
        assert f["doorway_ahead"].item() == 1.0
        assert torch.allclose(f["doorway_pos"], torch.tensor(door.center) - entrance, atol=1e-4)
        assert torch.linalg.norm(f["doorway_pos"][:2]).item() == pytest.approx(1.0 + 0.125, abs=1e-3)
    finally:
        env.close()


@pytest.mark.parametrize("platform", ["gripper", "arm"])
def test_the_proprioceptive_state_is_its_documented_fields(platform):
    """`obs["agent"]["state"]` in the layout of `observations.STATE_FIELDS` (+ the arm's), from the joints as ManiSkill
    reads them: the columns it takes by slice are the named joints'."""
    from aerobench.envs.control.virtual_joints import airframe_state_from_joints
    from aerobench.envs.observations import ARM_STATE_FIELDS, STATE_FIELDS

    env = gym.make("AeroPick-v1", obs_mode="state_dict", platform=platform)
    env.reset(seed=0)
    base = env.unwrapped
    env.step(torch.zeros(1, base.platform.action_dim))
    agent = base.agent
    # every joint moving, each at its own rate (the fingers settle within a control step: set them)
    q = agent.robot.get_qpos().clone()
    q[:, -2:] = torch.tensor([0.011, 0.013])
    agent.robot.set_qpos(q)
    agent.robot.set_qvel(torch.linspace(0.05, 0.3, q.shape[1])[None])
    base._signals_step = -1  # the joints changed without a step: recompute the step's signals
    obs = base.get_obs()
    q, qd = agent.robot.get_qpos(), agent.robot.get_qvel()

    def columns(names):
        return [agent.robot.active_joints_map[n].active_index[0] for n in names]

    v = columns(["root_x", "root_y", "root_z", "root_yaw", "root_pitch", "root_roll"])
    airframe = airframe_state_from_joints(q[:, v], qd[:, v])
    fingers, arm = columns(["finger_left", "finger_right"]), columns(agent.arm_joint_names)
    expected = {
        "position": airframe.position, "orientation_6d": torch.cat([airframe.rotation[:, :, 0], airframe.rotation[:, :, 1]], -1),
        "linear_velocity": airframe.velocity, "angular_velocity_body": airframe.angular_velocity_body,
        "finger_position": q[:, fingers], "finger_velocity": qd[:, fingers],
        "arm_position": q[:, arm], "arm_velocity": qd[:, arm],
    }
    fields = STATE_FIELDS + (ARM_STATE_FIELDS if platform == "arm" else ())
    state = obs["agent"]["state"]
    assert state.shape == (1, sum(n for _, n in fields))
    for name, sl in field_slices(fields).items():
        torch.testing.assert_close(state[:, sl], expected[name], rtol=1e-5, atol=1e-6, msg=name)
    assert float(qd[:, fingers].abs().min()) > 0.1 and float(q[:, fingers].min()) > 0.01
    env.close()


def test_open_confirms_the_handle_pinch_as_a_pick_confirms_its_grasp():
    """Task state version 5: in Open, `is_grasp_confirmed` reads 1 once the fingers have pinched the handle for
    GRASP_CONFIRM_STEPS control steps in a row (it read 0 throughout before: a policy could not tell the drive's first
    frames from the insert's)."""
    import numpy as np

    from aerobench.envs.observations import GRASP_CONFIRM_STEPS
    from aerobench.rollout.episode import EpisodeList
    from aerobench.rollout.runner import RolloutRunner, RolloutSpec

    spec = RolloutSpec(setting="PrepareGroceries", skills=("open",), episodes=1, seed=4200, record_cameras=False,
                       keep_signals=("is_handle_pinched",))
    sink = EpisodeList()
    RolloutRunner(spec, sink).run()
    episode = sink.episodes[0]
    assert episode.record.outcome == "S"
    column = field_slices(task_state_fields(with_arm=True))["is_grasp_confirmed"].start
    confirmed = episode.frames["task_state"][:, column]  # frame t: before step t
    pinched = episode.signals["is_handle_pinched"].astype(bool)  # after step t
    streak = np.array([pinched[max(0, t - GRASP_CONFIRM_STEPS + 1): t + 1].all() and t + 1 >= GRASP_CONFIRM_STEPS
                       for t in range(len(pinched))])
    assert np.array_equal(confirmed[1:], streak[:-1].astype(np.float32)) and confirmed[0] == 0
    assert 0 < confirmed.sum() < len(confirmed)  # confirmed while the expert held the handle, not before or after
