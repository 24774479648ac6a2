"""The shared signals of a control step (`signals.shared_signals`): compiled as the eager function, for any scene's
box count, with no host synchronization, and the same as the agent's and ManiSkill's own queries."""

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401
from aerobench.accel.kernels import Kernel
from aerobench.envs.geometry import body_points_to_world, min_distance_to_boxes
from aerobench.envs.observations import GRASP_CONFIRM_STEPS
from aerobench.envs.signals import BOXES_INPUT, FlightSignals, SharedSignals, signals_kernel
from aerobench.policies import make_policy
from tests.envs.host_sync import NoHostSync

pytestmark = [pytest.mark.usefixtures("aot_cache"), pytest.mark.xdist_group("aot_packages")]  # packages built here go to this run's cache


def _held_step(env_id: str = "AeroPick-v1", **kwargs):
    """An env a few steps after the expert confirmed its grasp (contacts on both fingers, the object off its support)."""
    env = gym.make(env_id, num_envs=1, **kwargs)
    obs, _ = env.reset(seed=0)
    policy = make_policy("expert", env.unwrapped)
    policy.reset(torch.arange(1))
    for _ in range(300):
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        if bool(info["is_grasped"].all()) and float(info["lift_height"][0]) > 0.02:
            return env
        assert not bool(terminated.any() | truncated.any()), "the expert did not grasp"
    raise AssertionError("the expert did not grasp in 300 steps")


def test_compiled_signals_are_the_eager_ones_for_any_box_count(aot_cache):
    env = _held_step()
    base = env.unwrapped
    tensors, _ = base.signal_inputs()
    eager = base._signals_kernel.fn
    kernel = Kernel(eager, "shared_signals", "test", [], "cpu", compile=True, dynamic={BOXES_INPUT: 1})
    fewer = list(tensors)
    fewer[BOXES_INPUT] = tensors[BOXES_INPUT][:, : tensors[BOXES_INPUT].shape[1] // 2]
    strided = list(tensors)
    strided[0] = torch.stack([tensors[0], tensors[0]], -1)[..., 0]  # the same joints, read through a strided view
    assert not strided[0].is_contiguous()
    # one package serves all: the box count is a free dimension (each size twice in a row: the call that finds the
    # package, then the one with the very sizes of the last); a strided input is read as its contiguous copy
    for inputs in (tensors, tensors, fewer, fewer, tensors, strided):
        compiled, reference = SharedSignals.from_flat(kernel(*inputs)), SharedSignals.from_flat(eager(*inputs))
        assert kernel.backend == "compiled ahead of time", kernel.backend
        for name, a, b in zip(SharedSignals._fields, compiled, reference):
            # 1e-4: acos near 1 (a tilt of a few mrad) turns a float's last bit in R_zz into 2e-5 rad
            torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-4, msg=name)
    assert len(list((aot_cache / "shared_signals").glob("*.pt2"))) == 1 and len(kernel._aot) == 1  # built, loaded once
    assert bool(SharedSignals.from_flat(eager(*tensors)).is_grasped.all())  # a step with the object in the jaws
    env.close()


@pytest.mark.parametrize("env_id", ["AeroPick-v1", "AeroNav-v1"])
def test_the_shared_signals_make_no_host_sync(env_id):
    env = gym.make(env_id, num_envs=1)
    env.reset(seed=1)
    base = env.unwrapped
    tensors, _ = base.signal_inputs()
    with NoHostSync():
        out = SharedSignals.from_flat(signals_kernel(base._signals_kernel.fn.keywords["const"], "cpu", compile=False)(*tensors))
    assert (out.object_rotation is None) == (base.target is None)
    env.close()


def test_the_step_context_is_the_agents_and_maniskills_own_queries():
    env = _held_step()
    base, agent = env.unwrapped, env.unwrapped.agent
    base._signals_step = -1  # recompute this step's signals
    info, ctx = base.evaluate(), base._ctx
    state = agent.airframe_state()
    torch.testing.assert_close(ctx.tcp_pose.raw_pose, agent.tcp_pose.raw_pose, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(ctx.state.rotation, state.rotation, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(ctx.state.position, state.position)
    torch.testing.assert_close(ctx.gripper_opening, agent.finger_opening())
    assert torch.equal(ctx.is_grasped, agent.is_grasping(base.target)) and bool(ctx.is_grasped.all())
    torch.testing.assert_close(ctx.object_pose.raw_pose, base.target.pose.raw_pose)
    assert torch.equal(ctx.object_velocity, base.target.linear_velocity)
    assert float(torch.linalg.norm(ctx.object_velocity)) > 0.0  # held in flight: a velocity to compare
    points = body_points_to_world(base.proxy_points, state.position, state.rotation)
    clearance = min_distance_to_boxes(points, base.obstacle_boxes()) - base.proxy_radius
    torch.testing.assert_close(info["min_obstacle_clearance"], clearance, rtol=1e-5, atol=1e-6)
    assert float(info["object_displacement"][0]) > 0.02  # lifted off its support
    # the observation's proprioceptive state is the agent's own, computed with the shared signals
    torch.testing.assert_close(base._get_obs_agent()["state"], agent.get_proprioception()["state"])
    env.close()


@pytest.mark.parametrize("platform", ["gripper", "arm"])
def test_the_proprioceptive_state_is_the_agents_on_either_platform(platform):
    """The shared signals' proprioceptive state (the observation's `agent/state`) is `get_proprioception`'s, the arm's
    joints included, while the joints move."""
    env = gym.make("AeroPick-v1", num_envs=1, obs_mode="state_dict", platform=platform)
    base = env.unwrapped
    obs, _ = env.reset(seed=2)
    action = torch.zeros(1, base.platform.action_dim)
    action[:, 0], action[:, 2], action[:, -1] = 0.3, 0.2, -1.0  # fly and open the fingers
    if platform == "arm":
        action[:, 4:7] = 0.5  # move the arm
    for _ in range(8):
        obs, *_ = env.step(action)
        expected = base.agent.get_proprioception()["state"]
        assert expected.shape[-1] == (25 if platform == "arm" else 19)
        torch.testing.assert_close(obs["agent"]["state"], expected)
    assert float(expected[0, 9:12].abs().max()) > 0.0  # ... a state that moves (its velocity)
    env.close()


def test_the_grasp_streak_counts_grasped_steps_and_confirms_a_held_start():
    """The streak grows by one per grasped step and restarts at a step without the grasp; an episode that starts
    with the object in the jaws has it confirmed (GRASP_CONFIRM_STEPS) over its first steps."""
    env = _held_step()
    base = env.unwrapped
    tensors, _ = base.signal_inputs()
    fn = base._signals_kernel.fn
    streak_at, held_at, step_at = len(tensors) - 3, len(tensors) - 2, len(tensors) - 1

    def streak(value: int, held: bool, step: int, grasped: bool = True) -> int:
        inputs = list(tensors)
        inputs[streak_at] = torch.tensor([value])
        inputs[held_at] = torch.tensor([held])
        inputs[step_at] = torch.tensor([step])
        if not grasped:
            inputs[5] = torch.zeros_like(inputs[5])  # no force from the object on the fingers
        return int(SharedSignals.from_flat(fn(*inputs)).grasp_streak[0])

    assert streak(3, held=False, step=40) == 4
    assert streak(3, held=False, step=40, grasped=False) == 0
    assert streak(0, held=True, step=0) == GRASP_CONFIRM_STEPS  # a held start: confirmed at once
    assert streak(0, held=True, step=GRASP_CONFIRM_STEPS) == 1  # ... only over its first steps
    assert streak(0, held=True, step=0, grasped=False) == GRASP_CONFIRM_STEPS
    assert int(base._grasp_streak[0]) >= 1  # the env keeps the signal: the expert holds the object here
    env.close()


@pytest.mark.parametrize("platform", ["gripper", "arm"])
def test_the_flight_test_envs_signals_are_the_agents_own_queries(platform):
    """`AeroFly-v1` reports and observes `signals.flight_signals` (one compiled call outside the tests): the same
    numbers as the agent's airframe state, proprioception and TCP pose while the airframe climbs, turns and tilts; no
    host sync; compiled, the eager numbers."""
    env = gym.make("AeroFly-v1", num_envs=1, obs_mode="state", platform=platform)
    base, agent = env.unwrapped, env.unwrapped.agent
    env.reset(seed=0)
    action = torch.zeros(1, base.platform.action_dim)
    action[:, :4] = torch.tensor([0.6, -0.3, 0.4, 0.5])
    for step in range(30):
        obs, _, _, _, info = env.step(action)
        if step % 10:
            continue
        state = agent.airframe_state()
        torch.testing.assert_close(info["altitude"], state.position[:, 2])
        torch.testing.assert_close(info["speed"], torch.linalg.norm(state.velocity, dim=-1))
        torch.testing.assert_close(info["tilt"], torch.acos(state.rotation[:, 2, 2].clamp(-1, 1)), rtol=1e-5, atol=1e-4)
        raw = base.get_obs(unflattened=True)
        torch.testing.assert_close(raw["agent"]["state"], agent.get_proprioception(state)["state"], rtol=1e-5,
                                   atol=1e-5)
        torch.testing.assert_close(raw["extra"]["tcp_pose"], agent.tcp_pose.raw_pose, rtol=1e-5, atol=1e-6)
        torch.testing.assert_close(raw["extra"]["airframe_velocity"], state.velocity)
    assert float(info["speed"][0]) > 0.2 and float(info["tilt"][0]) > 0.003  # it flew: a real comparison
    reads = []
    base.flight_signals = lambda: reads.append(1) or type(base).flight_signals(base)
    obs, *_ = env.step(action)  # one read a step: the observation takes the signals of the step's info
    assert len(reads) == 1 and torch.equal(obs, base._flatten_raw_obs(base.get_obs(unflattened=True)))
    del base.flight_signals
    q = agent.robot.get_qpos().clone()
    q[:, 2] += 0.5
    agent.robot.set_qpos(q)  # moved without an evaluation: an observation without info reads the joints again
    torch.testing.assert_close(base.get_obs(unflattened=True)["agent"]["state"], agent.get_proprioception()["state"])
    inputs = (*agent.joint_state(), agent.tcp_pose.raw_pose)
    eager = base._flight_kernel.fn
    with NoHostSync():
        reference = eager(*inputs)
    if platform == "gripper":  # compiled ahead of time, as by default outside the tests: the eager numbers
        compiled = Kernel(eager, "flight_signals", "test", [], "cpu", compile=True)(*inputs)
        for name, a, b in zip(FlightSignals._fields, compiled, reference):
            torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-4, msg=name)
    env.close()
