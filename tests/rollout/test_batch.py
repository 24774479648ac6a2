"""The runner's per-step batch state: device buffers read to the host once, bookkeeping without host syncs."""

import numpy as np
import pytest
import torch

from aerobench.envs.checks import FailureCause
from aerobench.rollout.batch import BatchStatus, StepBuffer, per_env_signals
from aerobench.rollout.chained import STAGE_MAX_STEPS, ChainMonitor
from tests.envs.host_sync import NoHostSync


def test_the_buffer_stacks_steps_as_time_by_env_and_copies_each_step():
    buffer = StepBuffer(capacity=5)
    reused = torch.zeros(3)  # an env that writes its info tensors in place from step to step
    for t in range(3):
        reused.fill_(t)
        buffer.append({"x": reused, "pose": torch.full((3, 2), float(t))})
    host = buffer.rows_to_host([1, 2])
    assert host["x"].shape == (5, 2) and host["pose"].shape == (5, 2, 2)  # (capacity, rows, ...)
    episode = buffer.episode_steps(host, 0, first=0, steps=3)
    np.testing.assert_array_equal(episode["x"], [0, 1, 2])  # each step as it was, not the last value thrice
    assert episode["pose"].shape == (3, 2) and isinstance(episode["x"], np.ndarray)


def test_the_ring_keeps_the_last_capacity_steps_and_refuses_what_it_overwrote():
    buffer = StepBuffer(capacity=4)
    for t in range(7):  # env 0's episode began at step 5, after steps 0-4 of another
        buffer.append({"x": torch.tensor([float(t), 10.0 + t])})
    host = buffer.rows_to_host([0])
    np.testing.assert_array_equal(buffer.episode_steps(host, 0, first=5, steps=2)["x"], [5, 6])
    np.testing.assert_array_equal(buffer.episode_steps(host, 0, first=3, steps=4)["x"], [3, 4, 5, 6])
    with pytest.raises(ValueError, match="not in the ring"):
        buffer.episode_steps(host, 0, first=2, steps=5)  # step 2 was overwritten by step 6
    with pytest.raises(ValueError, match="not in the ring"):
        buffer.episode_steps(host, 0, first=6, steps=2)  # step 7 was never written
    buffer.append({"x": torch.zeros(2)})
    with pytest.raises(ValueError, match="keys"):
        buffer.append({"x": torch.zeros(2), "y": torch.zeros(2)})


def test_only_per_env_tensors_are_signals():
    info = {"a": torch.zeros(4), "b": torch.zeros(4, 3), "scalar": torch.tensor(1.0), "other": torch.zeros(2), "s": "x"}
    assert sorted(per_env_signals(info, 4)) == ["a", "b"]


def test_status_counts_live_steps_and_ends_terminated_and_truncated_envs():
    status = BatchStatus(torch.tensor([True, True, True, False]))  # the last row pads the batch
    no = torch.zeros(4, dtype=torch.bool)
    status.advance(torch.tensor([True, False, False, False]), no, {})
    status.advance(no, torch.tensor([True, True, False, True]), {})  # row 0 already ended: not counted again
    status.advance(no, no, {})
    assert status.steps.tolist() == [1, 2, 3, 0]
    assert status.active.tolist() == [False, False, True, False]
    assert status.truncated.tolist() == [False, True, False, False]
    status.out_of_time()
    assert status.truncated.tolist() == [False, True, True, False]
    status.restart(torch.tensor([1]), torch.tensor([True]))  # env 1 begins its next episode (a partial reset)
    status.advance(no, no, {})
    assert status.steps.tolist() == [1, 1, 4, 0] and status.active.tolist() == [False, True, True, False]
    assert status.truncated.tolist() == [False, False, True, False]
    status.advance(torch.tensor([False, True, False, False]), no, {})
    assert status.ended.tolist() == [False, True, False, False]  # ended at this step: the runner resets it


def test_status_under_the_chained_protocol_ends_a_stage_over_budget_and_marks_a_lost_grasp():
    monitor = ChainMonitor(["pick", "nav", "place"], num_envs=2)
    status = BatchStatus(torch.ones(2, dtype=torch.bool), monitor)
    no = torch.zeros(2, dtype=torch.bool)

    def step(held):
        return {"subtask_index": torch.tensor([0, 1]), "is_grasp_held": torch.tensor(held),
                "tcp_to_grasp_point": torch.zeros(2), "fail": no.clone(), "fail_cause": torch.zeros(2, dtype=torch.long)}

    signals = step([True, False])
    status.advance(no, no, signals)  # row 1 moved to transport this step: its hold is not checked yet
    while bool(status.active[1]):
        signals = step([True, False])
        status.advance(no, no, signals)
    assert signals["fail"].tolist() == [False, True]
    assert signals["fail_cause"].tolist() == [0, int(FailureCause.OBJECT_DROP)]
    while bool(status.active[0]):
        status.advance(no, no, step([True, True]))
    assert int(status.steps[0]) == STAGE_MAX_STEPS["pick"] and bool(status.truncated[0])


def test_a_step_of_bookkeeping_reads_nothing_to_the_host():
    monitor = ChainMonitor(["pick", "nav", "place"], num_envs=3)
    status = BatchStatus(torch.ones(3, dtype=torch.bool), monitor)
    buffer = StepBuffer(capacity=2)
    info = {"subtask_index": torch.tensor([0, 1, 1]), "is_grasp_held": torch.tensor([True, False, True]),
            "tcp_to_grasp_point": torch.zeros(3), "fail": torch.zeros(3, dtype=torch.bool),
            "fail_cause": torch.zeros(3, dtype=torch.long), "success": torch.zeros(3, dtype=torch.bool)}
    with NoHostSync():
        step = per_env_signals(info, 3)
        status.advance(torch.tensor([False, True, False]), torch.zeros(3, dtype=torch.bool), step)
        buffer.append(step)
        status.out_of_time()
        status.restart(torch.tensor([1]), torch.tensor([True]))  # a partial reset: env 1 runs its next episode
