"""What the state policies read (`policies.inputs`) and how their gripper head acts (`policies.learned`)."""

import pytest
import torch

from aerobench.envs.observations import (
    STATE_DIM,
    TASK_STATE_DIM,
    TASK_STATE_FIELDS,
    TASK_STATE_VERSION,
    field_slices,
    task_state_fields,
    task_state_in_layout,
)
from aerobench.envs.tasks import SKILLS
from aerobench.policies.inputs import FINGER_FIELDS, FrameHistory, InputSpec
from aerobench.policies.learned import Normalizer, env_action, identity_stats, normalization_stats
from aerobench.train.bc import gripper_targets


def test_the_default_inputs_are_the_task_state_without_any_finger_value():
    state = torch.arange(STATE_DIM, dtype=torch.float32)[None].repeat(2, 1)
    task = 100 + torch.arange(TASK_STATE_DIM, dtype=torch.float32)[None].repeat(2, 1)
    spec = InputSpec(task_fields=tuple(n for n in InputSpec().task_fields if n != "arm_position"))
    assert torch.equal(spec.frame(state, task), task)
    fingers = InputSpec(state_fields=FINGER_FIELDS, task_fields=("heading_error", "altitude"))
    # proprio 15-18 (finger positions and velocities), then task state 14 and 25
    assert fingers.frame(state, task)[0].tolist() == [15, 16, 17, 18, 114, 125]


def test_bad_field_names_and_platform_mismatches_are_one_line_errors():
    with pytest.raises(ValueError, match="unknown task state fields \\['tcp_position'\\]"):
        InputSpec(task_fields=("tcp_position",))
    with pytest.raises(ValueError, match="unknown proprio state fields"):
        InputSpec(state_fields=("fingers",))
    with pytest.raises(ValueError, match="at least one"):
        InputSpec(task_fields=())
    with pytest.raises(ValueError, match="gripper platform's observations have no \\['arm_position'\\]"):
        InputSpec(task_fields=("arm_position",)).frame(torch.zeros(1, STATE_DIM), torch.zeros(1, TASK_STATE_DIM))


def test_a_policy_reads_the_task_state_in_the_version_it_was_trained_on():
    """Version 1 (before Place's progress became the set-down time) read Place progress as 0; Pick's is unchanged."""
    fields = field_slices(TASK_STATE_FIELDS)
    task = torch.zeros(2, TASK_STATE_DIM)
    task[0, fields["skill"].start + SKILLS.index("place")] = 1.0
    task[1, fields["skill"].start + SKILLS.index("pick")] = 1.0
    task[:, fields["progress"]] = 0.45
    state = torch.zeros(2, STATE_DIM)
    current = InputSpec(task_fields=("progress",))
    assert current.task_state_version == TASK_STATE_VERSION and current.frame(state, task)[:, 0].tolist() == pytest.approx([0.45, 0.45])
    legacy = InputSpec.from_dict({"state_fields": [], "task_fields": ["progress"], "history": 1})  # no version saved
    assert legacy.task_state_version == 1 and legacy.frame(state, task)[:, 0].tolist() == pytest.approx([0.0, 0.45])
    assert InputSpec.from_dict(current.as_dict()) == current
    with pytest.raises(ValueError, match="upgrade aerobench"):
        InputSpec(task_state_version=TASK_STATE_VERSION + 1)


def test_before_version_5_a_policy_reads_open_and_close_grasp_confirmation_as_0():
    """Version 5 made `is_grasp_confirmed` report the handle's pinch in Open / Close (always 0 there before): an
    older policy keeps reading 0 there, and a Pick's confirmation as it was."""
    fields = field_slices(TASK_STATE_FIELDS)
    task = torch.zeros(3, TASK_STATE_DIM)
    for row, skill in enumerate(("open", "close", "pick")):
        task[row, fields["skill"].start + SKILLS.index(skill)] = 1.0
    task[:, fields["is_grasp_confirmed"]] = 1.0
    state = torch.zeros(3, STATE_DIM)
    read = lambda version: InputSpec(task_fields=("is_grasp_confirmed",), task_state_version=version).frame(state, task)  # noqa: E731
    assert read(5)[:, 0].tolist() == [1.0, 1.0, 1.0]
    assert read(4)[:, 0].tolist() == read(2)[:, 0].tolist() == [0.0, 0.0, 1.0]
    assert task[:, fields["is_grasp_confirmed"]].tolist() == [[1.0]] * 3  # the caller's tensor is untouched


def test_a_policy_of_an_older_layout_reads_its_fields_by_name_from_todays_task_state():
    """Version 3 added `grasp_side_room`, version 4 the doorway, each before the arm's fields: a version-2 or -3 policy
    gets the same inputs from a vector of its version (its dataset) and from today's (the env it acts in)."""
    added = {2: ("grasp_side_room", "doorway_ahead", "doorway_pos"), 3: ("doorway_ahead", "doorway_pos")}
    widths = {(False, 2): 26, (True, 2): 29, (False, 3): 27, (True, 3): 30}
    for with_arm in (False, True):
        today = task_state_fields(with_arm)
        width = sum(n for _, n in today)
        assert width == (34 if with_arm else 31)
        for version, missing in added.items():
            old = task_state_fields(with_arm, version=version)
            assert [n for n, _ in old] == [n for n, _ in today if n not in missing]
            old_width = sum(n for _, n in old)
            assert old_width == widths[(with_arm, version)]
            now = torch.randn(3, width)
            slices = field_slices(today)
            now[:, slices["skill"]] = torch.nn.functional.one_hot(torch.tensor(SKILLS.index("pick")), len(SKILLS)).float()
            keep = [i for name, _ in old for i in range(slices[name].start, slices[name].stop)]
            recorded = now[:, keep]  # the same state, recorded in the older version
            assert torch.equal(task_state_in_layout(now, with_arm, old_width), recorded)  # what an older ACT is fed
            state = torch.zeros(3, STATE_DIM + (6 if with_arm else 0))
            spec = InputSpec(task_fields=tuple(n for n, _ in old), task_state_version=version)
            assert torch.equal(spec.frame(state, now), spec.frame(state, recorded))
            assert torch.equal(spec.frame(state, recorded), recorded)
    with pytest.raises(ValueError, match="no \\['grasp_side_room'\\] in this older task state layout"):
        InputSpec(task_fields=("grasp_side_room",)).frame(torch.zeros(1, STATE_DIM), torch.zeros(1, 26))
    with pytest.raises(ValueError, match="no \\['doorway_pos'\\] in this older task state layout"):
        InputSpec(task_fields=("doorway_pos",)).frame(torch.zeros(1, STATE_DIM), torch.zeros(1, 27))
    with pytest.raises(ValueError, match="a task state of 13 values is no layout"):
        InputSpec().frame(torch.zeros(1, STATE_DIM), torch.zeros(1, 13))


def test_history_repeats_an_episodes_first_frame_and_never_crosses_episodes():
    spec = InputSpec(task_fields=("altitude",), history=3)
    frames = torch.tensor([[1.0], [2.0], [3.0], [10.0], [11.0]])
    episodes = torch.tensor([0, 0, 0, 1, 1])
    stacked = spec.stack_episodes(frames, episodes)
    assert stacked.tolist() == [[1, 1, 1], [2, 1, 1], [3, 2, 1], [10, 10, 10], [11, 10, 10]]
    # acting: the same stacking, frame by frame, and a reset env starts over
    history = FrameHistory(3)
    got = [history.push(frames[i : i + 1])[0].tolist() for i in range(3)]
    assert got == stacked[:3].tolist()
    assert history.peek(torch.tensor([[9.0]]))[0].tolist() == [9, 3, 2]  # a peek does not enter the history
    history.reset(torch.tensor([0]))
    assert history.push(frames[3:4])[0].tolist() == [10, 10, 10]
    assert history.push(frames[4:5])[0].tolist() == [11, 10, 10]


def test_the_binary_gripper_sends_minus_one_or_plus_one_and_the_flight_dims_are_unnormalized():
    stats = identity_stats(3, 5)
    stats["action_mean"], stats["action_std"] = [0.1, 0.0, 0.0, 0.0, 0.0], [2.0, 1.0, 1.0, 1.0, 1.0]
    norm = Normalizer(stats)
    out = torch.tensor([[0.2, 5.0, -0.3, 0.0, 3.0], [0.2, 0.0, 0.0, 0.0, -0.5]])
    action = env_action(out, norm, "binary")
    assert action[:, -1].tolist() == [-1.0, 1.0]  # logit > 0: close (u_g = -1)
    assert action[0, :4].tolist() == pytest.approx([0.5, 1.0, -0.3, 0.0])  # 0.2 * 2 + 0.1; 5.0 clamped to 1
    assert env_action(out, norm, "binary", close=torch.tensor([0.0, 1.0]))[:, -1].tolist() == [1.0, -1.0]
    assert env_action(out, norm, "continuous")[:, -1].tolist() == [1.0, -0.5]


def test_close_onsets_are_weighted_and_the_gripper_is_not_normalized():
    u_g = torch.tensor([1.0, 1.0, -1.0, -1.0, 1.0, -1.0, -1.0])
    episodes = torch.tensor([0, 0, 0, 0, 0, 1, 1])  # episode 1 starts closed (a place start): not a switch
    actions = torch.cat([torch.randn(7, 4), u_g[:, None]], -1)
    close, weight = gripper_targets(actions, episodes, onset_weight=10.0)
    assert close.tolist() == [0, 0, 1, 1, 0, 1, 1]
    assert weight.tolist() == [1, 1, 10, 1, 10, 1, 1]
    stats = normalization_stats(torch.randn(7, 3), actions, "binary")
    assert (stats["action_mean"][-1], stats["action_std"][-1]) == (0.0, 1.0)
