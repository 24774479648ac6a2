"""The expert's velocity ramp (`SkillExpert.action(max_accel=...)`, used while a transport carries an object): the
command moves toward the wanted velocity by at most max_accel / 20 Hz per control step, and steps without it."""

from types import SimpleNamespace

import torch

from aerobench.envs.control.virtual_joints import AirframeState
from aerobench.envs.platforms import CONTROL_HZ, GRIPPER_PLATFORM, MAX_SPEED_MPS
from aerobench.expert.base import SkillExpert
from aerobench.expert.nav import CARRY_ACCEL_MPS2


def _expert(n: int = 2) -> SkillExpert:
    state = AirframeState(torch.zeros(n, 3), torch.zeros(n, 3), torch.eye(3).expand(n, 3, 3), torch.zeros(n, 3))
    env = SimpleNamespace(num_envs=n, device=torch.device("cpu"), platform=GRIPPER_PLATFORM,
                          current_step_context=lambda: SimpleNamespace(state=state))
    return SkillExpert(env, evaluator=None)


def test_ramp_bounds_the_change_of_the_velocity_command_and_reaches_cruise():
    expert = _expert()
    far = torch.tensor([[10.0, 0.0, 0.0], [0.0, -10.0, 0.0]])
    speed, yaw, grip, here = torch.full((2,), 0.5), torch.zeros(2), -torch.ones(2), torch.zeros(2, 3)
    commands = []
    for _ in range(30):
        action = expert.action(far, speed, yaw, grip, tracked=here, max_accel=CARRY_ACCEL_MPS2)
        commands.append(action[:, :3] * MAX_SPEED_MPS)
    steps = torch.stack(commands)  # (T, N, 3) m/s
    change = torch.linalg.norm(torch.diff(steps, dim=0, prepend=torch.zeros(1, 2, 3)), dim=-1)
    assert float(change.max()) <= CARRY_ACCEL_MPS2 / CONTROL_HZ + 1e-6
    assert torch.allclose(torch.linalg.norm(steps[-1], dim=-1), torch.full((2,), 0.5), atol=1e-5)  # after 1 s
    assert float(torch.linalg.norm(steps[9], dim=-1)[0]) < 0.3  # still ramping halfway


def test_without_a_ramp_the_command_steps():
    expert = _expert(1)
    action = expert.action(torch.tensor([[10.0, 0.0, 0.0]]), torch.full((1,), 0.5), torch.zeros(1), -torch.ones(1),
                           tracked=torch.zeros(1, 3))
    assert abs(float(action[0, 0]) * MAX_SPEED_MPS - 0.5) < 1e-5
