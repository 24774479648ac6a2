"""The pick evaluator's control step (`skills.pick.pick_update`): the hold streak, success after PICK_HOLD_STEPS,
the collision and drop flags, the streak kept where the pick is not active, compiled as the eager function."""

from functools import partial

import pytest
import torch

from aerobench.envs.checks import SafetyLimits
from aerobench.envs.skills.pick import PICK_HOLD_STEPS, PICK_LIFT_M, PickUpdate, _flat_pick_update, pick_update
from tests.envs.kernel_checks import assert_compiled_is_eager

pytestmark = [pytest.mark.usefixtures("aot_cache"), pytest.mark.xdist_group("aot_packages")]  # packages built here go to this run's cache

LIMITS = SafetyLimits()


def _inputs():
    """Four envs: grasped and lifted (a streak about to confirm), grasped on the support, dropped, pressed on a
    wall; the first three with the pick active."""
    rest = torch.tensor([0.80, 0.80, 0.80, 0.80])
    bottom = rest + torch.tensor([PICK_LIFT_M + 0.01, 0.0, -LIMITS.drop_margin_m - 0.01, PICK_LIFT_M + 0.05])
    grasped = torch.tensor([True, True, False, True])
    force = torch.tensor([0.0, 0.0, 0.0, LIMITS.collision_force_n + 1.0])
    mine = torch.tensor([True, True, True, False])
    streak = torch.tensor([PICK_HOLD_STEPS - 1, 4, 3, 7])
    return [bottom, rest, grasped, force, mine, streak]


def test_the_pick_update_counts_the_hold_and_flags_failures():
    out = pick_update(*_inputs(), limits=LIMITS)
    assert out.hold_streak.tolist() == [PICK_HOLD_STEPS, 0, 0, 7]  # the last env's pick is not active: kept
    assert out.success.tolist() == [True, False, False, False]
    assert out.lifted.tolist() == [True, False, False, True]
    assert out.fail_drop.tolist() == [False, False, True, False]
    assert out.fail_collision.tolist() == [False, False, False, True]


def test_the_compiled_pick_update_is_the_eager_one(aot_cache):
    assert_compiled_is_eager(partial(_flat_pick_update, limits=LIMITS), "pick_evaluator", LIMITS, _inputs(),
                             PickUpdate._fields, atol=1e-6)
