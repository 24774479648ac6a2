"""The place expert opens the gripper on what the task state shows (the set-down time in Place's `progress` and the
airframe speed), so a policy reading the same inputs can learn when to release (docs/experiments.md)."""

import gymnasium as gym
import torch

import aerobench.envs  # noqa: F401
from aerobench.envs.observations import TASK_STATE_FIELDS, field_slices
from aerobench.envs.platforms import CONTROL_HZ
from aerobench.expert import ExpertController
from aerobench.expert.place import SET_DOWN_STEPS, STOPPED_MPS, STOPPED_STEPS

FIELDS = field_slices(TASK_STATE_FIELDS)


def test_the_release_is_the_first_frame_whose_task_state_allows_it():
    env = gym.make("AeroPlace-v1", obs_mode="state_dict", setting="PrepareGroceries", object="sugar_box")
    env.reset(seed=4250)
    base = env.unwrapped
    controller = ExpertController(base)
    frames = []
    for _ in range(400):
        state = base.task_state()[0]
        action = controller.act()
        frames.append((float(state[FIELDS["progress"]]), float(torch.linalg.norm(state[FIELDS["linear_velocity"]])),
                       float(action[0, -1])))
        _, _, terminated, truncated, info = env.step(action)
        if bool(terminated[0] | truncated[0]):
            break
    assert bool(info["success"][0])
    opened = [k for k, (_, _, grip) in enumerate(frames) if grip > 0]
    assert opened, "the expert never released"
    release = opened[0]
    allowed = [progress >= (SET_DOWN_STEPS + STOPPED_STEPS - 1e-6) / CONTROL_HZ and speed < STOPPED_MPS
               for progress, speed, _ in frames]
    assert allowed[release]
    assert not any(allowed[:release])  # no closed frame before it looked like the release frame
    env.close()
