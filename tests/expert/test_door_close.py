"""Closing the fridge door through its pinched handle is pushing a stick: the door's reaction at the tool centre
point turned the drone away from the door's normal (under PGS the heading lagged the door by 0.44 rad) until a rotor
disk came within 2 cm of the door. The drive centres the airframe on the handle's normal line and sweeps it round with
the door, and the unwind keeps damping the sweep (docs/expert.md, "The single-skill close")."""

import math

import gymnasium as gym
import torch

import aerobench.envs  # noqa: F401
from aerobench.envs.skills.articulation import CLEARANCE_M
from aerobench.expert import ExpertController
from aerobench.expert.articulation import ArticulationPhase
from aerobench.rollout.runner import SEED_STRIDE

# PrepareGroceries close, eval seed 1, episode 3: the fridge door from 0.99 open; failed the clearance check before
SEED = 1 * SEED_STRIDE + 3


def test_pushing_the_fridge_door_shut_keeps_the_heading_on_the_door_and_the_rotors_clear():
    env = gym.make("AeroClose-v1", obs_mode="state_dict", setting="PrepareGroceries")
    try:
        env.reset(seed=SEED, options={"reconfigure": True})
        base = env.unwrapped
        controller = ExpertController(base)
        controller.reset(torch.arange(1))
        closer = controller.experts[0]
        assert not bool(closer.is_drawer[0])  # the fridge door
        worst_heading_error, drive_steps, info = 0.0, 0, None
        for _ in range(600):
            _, _, terminated, truncated, info = env.step(controller.act())
            if int(closer.phase[0]) == ArticulationPhase.DRIVE:
                _, normal = closer.handle()
                facing = float(torch.atan2(-normal[0, 1], -normal[0, 0]))
                worst_heading_error = max(worst_heading_error, abs(math.remainder(facing - float(closer.state().yaw[0]), 2 * math.pi)))
                drive_steps += 1
            if bool(terminated[0]) or bool(truncated[0]):
                break
        assert drive_steps > 60  # the door was driven shut, not skipped
        assert worst_heading_error < 0.15, worst_heading_error
        assert float(info["min_clearance"][0]) >= CLEARANCE_M
        assert bool(info["success"][0])
    finally:
        env.close()
