"""physx_cuda: many airframes hover together (skipped with a reason on CPU-only machines)."""

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401


@pytest.mark.gpu
@pytest.mark.parametrize("platform", ["gripper", "arm"])
def test_batched_gpu_hover(platform):
    env = gym.make("AeroFly-v1", obs_mode="state", scene="empty", platform=platform, sim_backend="physx_cuda", num_envs=64)
    env.reset(seed=0)
    base = env.unwrapped
    action = torch.zeros(64, base.platform.action_dim, device=base.device)
    if base.platform.arm is not None:
        action[:, 4:7] = base.agent.body_controller.arm_action(torch.tensor(base.platform.arm.working_pose_rad, device=base.device))
    start = base.agent.airframe_state().position.clone()
    for _ in range(100):
        env.step(action)
    drift = (base.agent.airframe_state().position - start).norm(dim=-1)
    assert drift.max() < 0.01
    env.close()


@pytest.mark.gpu
@pytest.mark.parametrize("env_id, kwargs", [("AeroPick-v1", {"setting": "TidyHouse"}), ("AeroOpen-v1", {"setting": "PrepareGroceries"})])
def test_skill_envs_batch_on_gpu(env_id, kwargs):
    env = gym.make(env_id, obs_mode="state_dict", sim_backend="physx_cuda", num_envs=16, **kwargs)
    obs, info = env.reset(seed=0)
    assert obs["agent"]["state"].shape[0] == 16 and info["success"].shape == (16,)
    base = env.unwrapped
    action = torch.zeros(16, base.platform.action_dim, device=base.device)
    for _ in range(5):
        obs, _, _, _, info = env.step(action)
    assert torch.isfinite(obs["agent"]["state"]).all()
    env.close()


@pytest.mark.gpu
def test_batched_starts_are_the_starts_of_single_envs_with_the_same_seeds():
    """Each env's start is drawn from its own episode seed (envs/episode_rng.py): row i of a batch reset with seeds
    [s1..sN] is what one env reset with s_i draws (poses through the sub-scenes' offsets: 1e-4)."""
    from aerobench.envs.checker import start_differences, start_record

    seeds, objects = [20000063, 7, 11, 20000071], ["bowl", "bowl", "sugar_box", "tuna_fish_can"]
    env = gym.make("AeroPick-v1", obs_mode="state_dict", sim_backend="physx_cuda", num_envs=4, setting="TidyHouse")
    env.reset(seed=seeds, options={"reconfigure": True, "objects": objects})
    batched = [start_record(env, i) for i in range(4)]
    env.close()
    one = gym.make("AeroPick-v1", obs_mode="state_dict", sim_backend="physx_cuda", num_envs=1, setting="TidyHouse")
    try:
        for i, (seed, obj) in enumerate(zip(seeds, objects)):
            one.reset(seed=seed, options={"reconfigure": True, "objects": [obj]})
            problems = start_differences(batched[i], start_record(one), 1e-4)
            assert not problems, f"row {i} (seed {seed}): " + "; ".join(problems)
    finally:
        one.close()
