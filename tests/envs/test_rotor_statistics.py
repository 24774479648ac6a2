"""Rotor saturation statistics (`rotor_statistics=True`, as `aerobench eval` runs): a per-step signal of whether the
controller's rotor thrusts are clipped, sampled on the side; it changes nothing the simulation does."""

import gymnasium as gym
import torch

import aerobench.envs  # noqa: F401

SEED = 4210 * 1_000_003


def _fly(env, actions):
    env.reset(seed=SEED, options={"reconfigure": True})
    infos = []
    for action in actions:
        infos.append(env.step(action)[-1])
    return infos


def test_the_signal_is_recorded_only_where_asked_and_changes_nothing():
    hover = [torch.zeros(1, 5)] * 30
    plain = gym.make("AeroPick-v1", obs_mode="state_dict", setting="TidyHouse")
    counted = gym.make("AeroPick-v1", obs_mode="state_dict", setting="TidyHouse", rotor_statistics=True)
    assert "rotor_saturated" not in _fly(plain, hover[:1])[-1]
    _fly(plain, hover)
    infos = _fly(counted, hover)
    a, b = plain.unwrapped.agent.airframe_state(), counted.unwrapped.agent.airframe_state()
    assert torch.equal(a.position, b.position) and torch.equal(a.velocity, b.velocity)  # bit for bit
    assert not any(bool(i["rotor_saturated"][0]) for i in infos[5:])  # a hover needs no rotor at a limit


def test_a_full_climb_with_a_full_turn_clips_rotors():
    env = gym.make("AeroPick-v1", obs_mode="state_dict", setting="TidyHouse", rotor_statistics=True)
    # climb and turn at the limits of the command: the allocation asks for more than some rotor has (or less than 0)
    infos = _fly(env, [torch.tensor([[0.0, 0.0, 1.0, 1.0, 1.0]])] * 3 + [torch.tensor([[0.0, 0.0, -1.0, -1.0, 1.0]])] * 3)
    assert any(bool(i["rotor_saturated"][0]) for i in infos)
