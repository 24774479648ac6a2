"""The payload-aware switches (spec appendix "Payload-Aware Flight Control")."""

import torch

from aerobench.envs.control.flight import FlightMemory, FlightParams
from aerobench.envs.control.payload import ControllerMode, update_payload_estimate
from aerobench.envs.platforms import GRIPPER_PLATFORM

PARAMS = FlightParams.from_platform(GRIPPER_PLATFORM)
MASS = torch.tensor([0.37])
YES, NO = torch.tensor([True]), torch.tensor([False])


def _run(signals, mode=ControllerMode.PAYLOAD_AWARE, memory=None):
    memory = memory or FlightMemory.initial(1, PARAMS)
    history = []
    for grasped, set_down in signals:
        memory = update_payload_estimate(memory, PARAMS, grasped, set_down, MASS, mode)
        history.append(memory)
    return history


def test_mass_and_gains_switch_after_three_grasped_steps():
    h = _run([(YES, NO)] * 4)
    mass = [round(float(m.mass_hat), 5) for m in h]
    assert mass == [2.38, 2.38, 2.75, 2.75]
    assert [(round(float(m.k_R), 5), round(float(m.k_w), 5)) for m in h] == [(2.5, 0.55)] * 2 + [(12.0, 1.2)] * 2


def test_a_broken_grasp_restarts_the_count():
    h = _run([(YES, NO), (YES, NO), (NO, NO), (YES, NO), (YES, NO)])
    assert all(abs(float(m.mass_hat) - 2.38) < 1e-6 for m in h)


def test_set_down_restores_m0_and_resets_vertical_integral_once():
    memory = _run([(YES, NO)] * 3)[-1]
    memory.xi = torch.tensor([[0.4, -0.2, 0.9]])
    after = _run([(YES, YES)], memory=memory)[0]
    assert abs(float(after.mass_hat) - 2.38) < 1e-6
    assert torch.allclose(after.xi, torch.tensor([[0.4, -0.2, 0.0]]))
    after.xi = torch.tensor([[0.0, 0.0, 0.5]])
    still = _run([(YES, YES)], memory=after)[0]  # still supported: no second reset
    assert float(still.xi[0, 2]) == 0.5


def test_release_returns_to_the_unloaded_controller():
    memory = _run([(YES, NO)] * 3)[-1]
    released = _run([(NO, NO)], memory=memory)[0]
    assert abs(float(released.mass_hat) - 2.38) < 1e-6 and float(released.k_R) == 2.5
    assert not bool(released.payload_active)


def test_nominal_controller_never_switches():
    h = _run([(YES, NO)] * 10 + [(YES, YES)], mode=ControllerMode.NOMINAL)
    assert all(abs(float(m.mass_hat) - 2.38) < 1e-6 and float(m.k_R) == 2.5 for m in h)


def test_controller_names():
    assert ControllerMode.parse("nominal") is ControllerMode.NOMINAL
    try:
        ControllerMode.parse("pid")
    except ValueError as e:
        assert str(e) == "unknown controller 'pid'; valid controllers: payload-aware, nominal"
    else:
        raise AssertionError("expected a ValueError")
