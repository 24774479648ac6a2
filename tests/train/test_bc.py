"""`aerobench train bc` end to end on CPU, offline: an expert-made dataset (all outcomes kept) -> BC on the successful
episodes only -> a checkpoint that `aerobench eval --policy bc` runs; determinism, exact resume, one-line errors;
the image variant on a tiny camera dataset."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from torch.nn import functional as F

from aerobench.envs.observations import TASK_STATE_VERSION
from aerobench.export import DatasetSink, read_jsonl
from aerobench.policies.inputs import InputSpec
from aerobench.policies.learned import CHECKPOINT_FILES, load_weights, resolve_checkpoint
from aerobench.rollout.runner import SEED_STRIDE, RolloutRunner, RolloutSpec
from aerobench.threads import torch_threads
from aerobench.train.bc import (
    BCConfig,
    flight_mse,
    gripper_targets,
    phase_onset_weights,
    select_episodes,
    stage_segments,
    train_bc,
    within_budget,
)
from aerobench.train.common import read_scalars
from tests.cli_here import aerobench_here

BIN = Path(sys.executable).parent


def _run(cmd: list[str], cwd: Path, ok: bool = True) -> subprocess.CompletedProcess:
    # one torch thread: on the shared 2-core machine more threads than free cores slow small torch ops many-fold
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "MS_SKIP_ASSET_DOWNLOAD_PROMPT": "1", "WANDB_MODE": "disabled",
           "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    if ok:
        assert proc.returncode == 0, f"{' '.join(cmd)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc


def _dataset(root: Path, episodes: int, max_steps: int, cameras: bool, seed: int = 0) -> Path:
    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=episodes, objects=("master_chef_can",),
                       policy="expert", record_cameras=cameras, max_steps=max_steps, seed=seed)
    sink = DatasetSink(root, {**spec.as_dict(), "keep": "all"})
    with torch_threads(1):
        RolloutRunner(spec, sink).run()
    sink.close()
    return root


pytestmark = pytest.mark.xdist_group("bc_dataset")  # the module's dataset and BC run are made once, on one worker


@pytest.fixture(scope="module")
def state_dataset(tmp_path_factory) -> Path:
    """Two expert Pick episodes cut at 200 steps, both kept (keep all). With seed 3 the expert needs 195 and 216
    steps: the first succeeds, the second is truncated (the test checks that both kinds are there)."""
    return _dataset(tmp_path_factory.mktemp("bc") / "ds", episodes=2, max_steps=200, cameras=False, seed=3)


@pytest.fixture(scope="module")
def trained(state_dataset, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("bc_run")
    r = aerobench_here("train", "bc", "--dataset", str(state_dataset), "--out", str(out), "--steps", "300",
                       "--batch-size", "64", "--log-every", "25", "--no-progress")
    assert r.returncode == 0, r.stderr[-3000:]
    return out


def _weights(checkpoint: Path) -> dict[str, torch.Tensor]:
    return load_weights(resolve_checkpoint(checkpoint))


def test_bc_trains_on_successful_episodes_only(state_dataset, trained):
    rows = read_jsonl(state_dataset / "meta" / "aerobench_episodes.jsonl")
    successes = [r for r in rows if r["outcome"] == "S"]
    assert successes and len(successes) < len(rows), "the fixture must hold successful and unsuccessful episodes"
    config = json.loads((trained / "checkpoint" / "config.json").read_text())
    assert config["algorithm"] == "bc" and config["platform"] == "gripper"
    assert config["data"]["episodes"] == len(successes)
    assert config["data"]["frames"] == sum(r["steps"] for r in successes) < config["data"]["total_frames"]
    # the default inputs: the whole 31-D task state (today's version) of the last 3 frames, nothing of the proprio state; binary gripper
    assert config["model"]["state_dim"] == 3 * 31 and config["model"]["action_dim"] == 5
    assert config["model"]["inputs"]["history"] == 3
    assert config["model"]["inputs"]["state_fields"] == [] and len(config["model"]["inputs"]["task_fields"]) == 14
    assert config["model"]["inputs"]["task_state_version"] == TASK_STATE_VERSION  # that of the dataset it read
    assert config["model"]["gripper"] == "binary"
    losses = [v for _, v in read_scalars(trained, "losses/bc")]
    assert len(losses) == 300 // 25
    assert losses[-1] < 0.5 * losses[0], f"BC loss did not fall: {losses}"
    assert [s for s, _ in read_scalars(trained, "charts/SPS")] == list(range(25, 301, 25))


def test_bc_checkpoint_evaluates(trained, state_dataset, tmp_path):
    out = tmp_path / "eval"
    proc = _run([str(BIN / "aerobench"), "eval", "--policy", "bc", "--checkpoint", str(trained), "--setting", "TidyHouse",
                 "--skills", "pick", "--objects", "master_chef_can", "--episodes-per-object", "2", "--max-steps", "8",
                 "--label", "bc-test", "--out", str(out)], cwd=tmp_path)
    assert "bc-test" in proc.stdout
    results = json.loads((out / "results.json").read_text())
    assert results["policy"] == "bc" and results["provenance"]["checkpoint"] == str(trained.resolve())
    (cell,) = results["cells"]
    assert (cell["skill"], cell["object"], cell["n"]) == ("pick", "master_chef_can", 2)
    records = read_jsonl(out / "records.jsonl")
    assert [r["episode_index"] for r in records] == [0, 1] and all(r["policy"] == "bc" for r in records)
    # no pick completes in 8 steps (it needs >= 10 held steps): every episode ends truncated or failed
    assert cell["successes"] == 0 and all(r["outcome"] in ("T", "F") and r["steps"] <= 8 for r in records)
    # the policy flew: the drone moved (a constant zero action would hover in place)
    assert max(r["diagnostics"]["max_speed_mps"] for r in records) > 0.01
    # the data was generated with seed 3, this evaluation used seed 0: held out, and traced to the dataset
    assert results["provenance"]["seen_in_training"] == {"episodes": 0, "of": 2, "untraced": [],
                                                          "sources": [str(state_dataset.resolve())]}


def test_an_evaluation_with_the_generation_seed_is_flagged_as_replaying_training_starts(state_dataset, trained,
                                                                                         capsys):
    from aerobench.eval.evaluate import EvalConfig, held_out_check

    def check(seed: int, episodes: int = 2) -> dict:
        config = EvalConfig(policy="bc", setting="TidyHouse", skills=("pick",), objects=("master_chef_can",),
                            episodes_per_object=episodes, checkpoint=str(trained), seed=seed)
        return held_out_check(config.resolve())

    assert check(3)["episodes"] == 2  # the dataset's two episodes are seeds 3 * stride + 0 and + 1
    assert "2 of 2 evaluation episodes start where the policy's training episodes did" in capsys.readouterr().err
    assert check(3, episodes=5) == {"episodes": 2, "of": 5, "sources": [str(state_dataset.resolve())], "untraced": []}
    assert check(4)["episodes"] == 0 and capsys.readouterr().err.count("warning") == 1  # only the seed-3 call above
    # another skill with the same seeds does not start where a Pick demonstration did
    config = EvalConfig(policy="bc", setting="TidyHouse", skills=("place",), objects=("master_chef_can",),
                        episodes_per_object=2, checkpoint=str(trained), seed=3)
    assert held_out_check(config.resolve())["episodes"] == 0


def test_a_checkpoint_copied_without_its_data_still_knows_its_training_starts(state_dataset, trained, tmp_path,
                                                                               monkeypatch):
    """A committed checkpoint (the files needed to act, plus starts.json) is traced without the dataset, and a results
    file made from the repository root names it by its repository path."""
    import shutil

    from aerobench.eval.evaluate import EvalConfig, evaluate
    from aerobench.policies.provenance import STARTS_FILE

    copy = tmp_path / "leaderboards" / "checkpoints" / "TidyHouse" / "bc"
    copy.mkdir(parents=True)
    for name in (*CHECKPOINT_FILES, STARTS_FILE):
        shutil.copy(trained / "checkpoint" / name, copy / name)
    monkeypatch.chdir(tmp_path)
    config = EvalConfig(policy="bc", setting="TidyHouse", skills=("pick",), objects=("master_chef_can",),
                        episodes_per_object=3, checkpoint="leaderboards/checkpoints/TidyHouse/bc", seed=3, max_steps=2)
    with torch_threads(1):
        results = evaluate(config, tmp_path / "eval")
    assert results["provenance"]["checkpoint"] == "leaderboards/checkpoints/TidyHouse/bc"
    seen = results["provenance"]["seen_in_training"]
    assert (seen["episodes"], seen["of"], seen["untraced"]) == (2, 3, [])  # the dataset's two seed-3 episodes


def test_relative_paths_a_training_run_recorded_resolve_from_where_it_ran(tmp_path, monkeypatch):
    from aerobench.policies.provenance import recorded_path as _recorded_path

    (tmp_path / "data" / "ds").mkdir(parents=True)
    run = tmp_path / "runs" / "bc"
    run.mkdir(parents=True)
    monkeypatch.chdir(run)  # evaluated from elsewhere than the training ran
    assert _recorded_path("data/ds", run, "runs/bc") == (tmp_path / "data" / "ds").resolve()
    assert _recorded_path("data/ds", run, "other/bc") is None  # the run was moved: its recorded name does not match
    assert _recorded_path(str(tmp_path / "data" / "ds"), run, None) == tmp_path / "data" / "ds"
    assert _recorded_path("data/gone", run, "runs/bc") is None


def test_bc_is_deterministic_and_resumes_exactly(state_dataset, tmp_path):
    def cfg(out, steps, seed=0):
        return BCConfig(dataset=str(state_dataset), out=str(out), steps=steps, seed=seed, batch_size=32,
                        log_every=5, save_every=10, hidden=(64, 64), progress=False)

    a = train_bc(cfg(tmp_path / "a", 40))
    b = train_bc(cfg(tmp_path / "b", 40))
    c = train_bc(cfg(tmp_path / "c", 40, seed=1))
    wa, wb, wc = _weights(a), _weights(b), _weights(c)
    assert all(torch.equal(wa[k], wb[k]) for k in wa)
    assert read_scalars(tmp_path / "a", "losses/bc") == read_scalars(tmp_path / "b", "losses/bc")
    assert any(not torch.equal(wa[k], wc[k]) for k in wa), "another seed must give other weights"

    train_bc(cfg(tmp_path / "r", 20))
    log = tmp_path / "r" / "scalars.jsonl"
    with open(log, "a") as f:  # an interrupted run logged past its last checkpoint: that part is redone, not kept
        f.write(json.dumps({"step": 25, "tag": "losses/bc", "value": 123.0}) + "\n")
    moved = (tmp_path / "r").rename(tmp_path / "r_moved")  # a run folder resumes wherever it was moved to
    r = train_bc(cfg(moved, 40))
    wr = _weights(r)
    assert all(torch.equal(wa[k], wr[k]) for k in wa), "resuming 20 -> 40 must equal one run of 40 steps"
    assert read_scalars(moved, "losses/bc") == read_scalars(tmp_path / "a", "losses/bc")
    assert torch.load(r / "train_state.pt", weights_only=False)["step"] == 40
    assert train_bc(cfg(moved, 40)) == r  # already finished: nothing to do


def test_a_data_budget_keeps_the_leading_episodes_that_fit():
    frame_episode = torch.tensor([0] * 5 + [1] * 3 + [2] * 4 + [3] * 2)  # episodes of 5, 3, 4, 2 frames
    assert within_budget([0, 1, 2, 3], frame_episode, 8) == [0, 1]  # 5 + 3 fits, 5 + 3 + 4 does not
    assert within_budget([0, 2, 3], frame_episode, 10) == [0, 2]  # in the order given, skipping unselected episodes
    assert within_budget([1, 3], frame_episode, 100) == [1, 3]
    assert within_budget([0, 1], frame_episode, 4) == []  # stops at the first episode over the budget


def test_bc_trains_within_a_data_budget(state_dataset, tmp_path):
    both = ("S", "T")  # the fixture's two episodes: one success, one truncation
    full = train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "all"), steps=1, hidden=(8,), progress=False,
                             outcomes=both))
    full_data = json.loads((full / "config.json").read_text())["data"]
    assert full_data["episodes"] == 2
    first = train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "cap"), steps=1, hidden=(8,), progress=False,
                              outcomes=both, max_transitions=full_data["frames"] - 1))
    data = json.loads((first / "config.json").read_text())["data"]
    assert data["episodes"] == 1 and 0 < data["frames"] < full_data["frames"]
    with pytest.raises(ValueError, match="below the first episode's length"):
        train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "tiny"), steps=1, progress=False, max_transitions=1))
    with pytest.raises(ValueError, match="--max-transitions must be a positive integer"):
        BCConfig(dataset=str(state_dataset), out=str(tmp_path), max_transitions=0)


def test_goal_noise_offsets_goal_pos_body_alike_in_every_history_frame(state_dataset, tmp_path):
    """`--goal-noise-m`: one offset per training frame on goal_pos_body and nothing else, the same in its history (a
    perception's error is a bias); refused without goal_pos_body among the inputs."""
    from aerobench.envs.observations import task_state_fields
    from aerobench.train.bc import goal_noise

    spec = InputSpec(state_fields=("linear_velocity",), ego_fields=("height",), history=3,
                     task_fields=("is_grasp_confirmed", "goal_pos_body", "heading_error"))
    sizes = dict(task_state_fields(with_arm=True))
    frame = 3 + 1 + sizes["is_grasp_confirmed"] + 3 + sizes["heading_error"]
    start = 3 + 1 + sizes["is_grasp_confirmed"]
    torch.manual_seed(0)
    noise = goal_noise(0.02, spec, 3 * frame)(torch.arange(4000))
    blocks = [noise[:, k * frame + start:k * frame + start + 3] for k in range(3)]
    assert torch.equal(blocks[0], blocks[1]) and torch.equal(blocks[0], blocks[2])
    assert torch.allclose(blocks[0].std(0), torch.full((3,), 0.02), rtol=0.1)
    assert (noise != 0).sum() == 3 * 3 * 4000  # nothing else is touched
    run = train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "noisy"), steps=2, hidden=(8,), progress=False,
                            outcomes=("S", "T"), task_fields=("goal_pos_body",), history=2, goal_noise_m=0.02))
    assert json.loads((run / "config.json").read_text())["train"]["goal_noise_m"] == 0.02
    with pytest.raises(ValueError, match="needs goal_pos_body in --task-fields"):
        BCConfig(dataset=str(state_dataset), out=str(tmp_path), task_fields=("progress",), goal_noise_m=0.01)


def test_bc_trains_on_the_chosen_object_classes(state_dataset, tmp_path):
    rows = read_jsonl(state_dataset / "meta" / "aerobench_episodes.jsonl")
    both = ("S", "T")
    assert select_episodes(state_dataset, both, ("master_chef_can",)) == select_episodes(state_dataset, both) == \
        [int(r["dataset_episode_index"]) for r in rows]
    with pytest.raises(ValueError, match="has no episode of bowl; its objects: master_chef_can"):
        select_episodes(state_dataset, both, ("bowl", "master_chef_can"))
    run = train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "can"), steps=1, hidden=(8,), progress=False,
                            outcomes=both, objects=("master_chef_can",)))
    assert json.loads((run / "config.json").read_text())["data"]["objects"] == ["master_chef_can"]
    with pytest.raises(ValueError, match="--objects needs at least one object class"):
        BCConfig(dataset=str(state_dataset), out=str(tmp_path), objects=())


def test_input_history_and_gripper_onsets_never_cross_a_chain_stage():
    # a chained evaluation resets a stage's policy when the stage begins; training must see the same inputs
    episode, stage = torch.tensor([0, 0, 0, 0, 1, 1]), torch.tensor([0, 0, 1, 1, 0, 0])
    segment = stage_segments(episode, stage)
    assert segment.tolist() == [1, 1, 2, 2, 3, 3]
    assert stage_segments(episode, None).tolist() == [1, 1, 1, 1, 2, 2]  # no stage column: whole episodes
    history = InputSpec(state_fields=(), task_fields=("skill",), history=2)
    stacked = history.stack_episodes(torch.arange(6.0)[:, None], segment)
    assert stacked.tolist() == [[0, 0], [1, 0], [2, 2], [3, 2], [4, 4], [5, 4]]  # each stage's first frame repeated
    gripper = torch.tensor([-1.0, 1.0, -1.0, -1.0, 1.0, 1.0])[:, None]  # close in stage 0; open across the boundary
    close, weight = gripper_targets(gripper, segment, onset_weight=10.0)
    assert weight.tolist() == [1, 10, 1, 1, 1, 1]


def test_the_frames_after_an_expert_phase_switch_are_weighted_up():
    phase = torch.tensor([1, 1, 1, 2, 2, 2, 2, 0, 0])  # align -> descend at frame 3; a new segment at frame 7
    segment = torch.tensor([1, 1, 1, 1, 1, 1, 1, 2, 2])
    weight = phase_onset_weights(phase, segment, frames=2, weight=20.0)
    assert weight.tolist() == [1, 1, 1, 20, 20, 1, 1, 1, 1]  # a segment's first frame is no switch
    pred, target = torch.tensor([[1.0, 1.0], [0.0, 0.0]]), torch.zeros(2, 2)
    assert flight_mse(pred, target, None) == F.mse_loss(pred, target)
    assert flight_mse(pred, target, torch.tensor([3.0, 1.0])) == pytest.approx(0.75)  # (3 * 1 + 1 * 0) / 4


def test_bc_trains_on_the_chosen_skill_stages(state_dataset, tmp_path):
    both = ("S", "T")
    every = train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "all"), steps=1, hidden=(8,),
                              progress=False, outcomes=both))
    picks = train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "pick"), steps=1, hidden=(8,),
                              progress=False, outcomes=both, skills=("pick",)))
    every, picks = (json.loads((run / "config.json").read_text())["data"] for run in (every, picks))
    assert picks["skills"] == ["pick"] and picks["frames"] == every["frames"] > 0 and "skills" not in every
    with pytest.raises(ValueError, match="have no frame of place; choose skills the dataset acts"):
        train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "place"), steps=1, progress=False,
                          outcomes=both, skills=("place",)))
    with pytest.raises(ValueError, match="--skills must name skills of pick, place, nav, open, close, got fly"):
        BCConfig(dataset=str(state_dataset), out=str(tmp_path), skills=("fly",))
    weighted = train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "phase"), steps=2, hidden=(8,),
                                 progress=False, outcomes=both, phase_onset_weight=20.0))
    assert json.loads((weighted / "config.json").read_text())["train"]["phase_onset_weight"] == 20.0
    with pytest.raises(ValueError, match="--phase-onset-weight must be at least 1"):
        BCConfig(dataset=str(state_dataset), out=str(tmp_path), phase_onset_weight=0.5)


def test_bc_errors_are_one_line(state_dataset, tmp_path):
    with pytest.raises(ValueError, match="unknown outcomes.*valid: S, F, T, I"):
        BCConfig(dataset=str(state_dataset), out=str(tmp_path), outcomes=("X",))
    with pytest.raises(ValueError, match="must hold config.json, model.safetensors, normalization.json"):
        resolve_checkpoint(tmp_path / "nothing", "bc")
    with pytest.raises(ValueError, match="no LeRobot dataset"):
        train_bc(BCConfig(dataset=str(tmp_path / "missing"), out=str(tmp_path / "o"), steps=1, progress=False))
    with pytest.raises(ValueError, match="no episode with outcome I"):
        train_bc(BCConfig(dataset=str(state_dataset), out=str(tmp_path / "o"), steps=1, outcomes=("I",), progress=False))
    run = tmp_path / "run"
    train_bc(BCConfig(dataset=str(state_dataset), out=str(run), steps=2, hidden=(16,), progress=False))
    with pytest.raises(ValueError, match="different config.*hidden"):
        train_bc(BCConfig(dataset=str(state_dataset), out=str(run), steps=4, hidden=(32,), progress=False))
    proc = aerobench_here("eval", "--policy", "ppo", "--checkpoint", str(run), "--setting", "TidyHouse", "--skills",
                          "pick", "--episodes-per-object", "1", "--out", str(tmp_path / "e"))
    assert proc.returncode == 2 and "holds a bc policy; use --policy bc" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    proc = aerobench_here("train", "bc", "--dataset", str(state_dataset), "--out", str(tmp_path / "x"), "--outcomes", "Q")
    assert proc.returncode == 2 and "unknown outcomes" in proc.stderr
    assert set(CHECKPOINT_FILES) <= {p.name for p in (run / "checkpoint").iterdir()}


def test_bc_image_variant_trains_and_evaluates(tmp_path):
    # 12 steps cannot complete a pick: the episodes are truncations, so this test trains on outcome T (plumbing only)
    data = _dataset(tmp_path / "cams", episodes=2, max_steps=12, cameras=True)
    out = tmp_path / "run"
    ckpt = train_bc(BCConfig(dataset=str(data), out=str(out), steps=4, batch_size=8, images=True, outcomes=("T",),
                             image_size=32, hidden=(64,), log_every=2, progress=False))
    config = json.loads((ckpt / "config.json").read_text())
    assert config["model"]["cameras"] == ["drone_front", "drone_hand", "drone_own"] and config["data"]["frames"] == 24
    assert any(k.startswith("actor.encoder.") for k in _weights(ckpt))
    from aerobench.policies import policy_needs_images

    assert policy_needs_images("bc", str(ckpt)) is True
    from aerobench.eval.evaluate import EvalConfig, evaluate

    with torch_threads(1):
        results = evaluate(EvalConfig(policy="bc", setting="TidyHouse", skills=("pick",), objects=("master_chef_can",),
                                      episodes_per_object=1, checkpoint=str(ckpt), max_steps=4), tmp_path / "eval")
    (cell,) = results["cells"]
    assert cell["n"] == 1 and results["provenance"]["max_steps"] == 4


def test_one_checkpoint_per_skill_and_a_missing_one_is_named(trained, tmp_path):
    """`--checkpoint pick=A,place=B` gives each skill its own policy (PPO trains one per skill)."""
    from aerobench.eval.evaluate import EvalConfig, evaluate

    config = EvalConfig(policy="bc", setting="TidyHouse", skills=("pick", "place"), objects=("master_chef_can",),
                        episodes_per_object=1, checkpoint=f"pick={trained},place={trained}", max_steps=4)
    results = evaluate(config, tmp_path / "eval")
    assert sorted(c["skill"] for c in results["cells"]) == ["pick", "place"]
    assert results["provenance"]["checkpoint"] == f"pick={trained.resolve()},place={trained.resolve()}"
    with pytest.raises(ValueError, match="names no folder for place"):
        EvalConfig(policy="bc", setting="TidyHouse", skills=("pick", "place"), checkpoint=f"pick={trained}").resolve()


def test_a_policy_sees_at_evaluation_exactly_the_inputs_bc_trained_on(state_dataset, monkeypatch, tmp_path):
    """Replaying a demonstration's actions from its seed through the evaluator: the inputs a learned policy reads
    (an `InputSpec` over the proprio state and the task state, with history) equal what BC builds from the exported
    observation.state + observation.environment_state, frame by frame, so nothing differs between what BC trains on
    and what it acts on."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    import aerobench.rollout.runner as runner
    from aerobench.policies.inputs import ALL_STATE_FIELDS, FrameHistory, InputSpec
    from aerobench.rollout.records import RecordSink

    inputs = InputSpec(state_fields=ALL_STATE_FIELDS[:6], task_fields=("goal_pos", "heading_error", "linear_velocity"),
                       history=3)
    table = LeRobotDataset("local/aerobench", root=state_dataset).hf_dataset.with_format("torch")[:]
    first = table["episode_index"] == 0
    frames = inputs.frame(table["observation.state"][first], table["observation.environment_state"][first])
    demo_inputs = inputs.stack_episodes(frames, table["episode_index"][first])
    demo_actions = table["action"][first].float()
    history = FrameHistory(inputs.history)
    seen = []

    class Replay:
        def __init__(self, env):
            self.env = env

        def reset(self, env_idx):
            history.reset(env_idx)

        def act(self, obs):
            seen.append(history.push(inputs.frame(obs["agent"]["state"].cpu(), self.env.task_state().cpu()))[0])
            return demo_actions[min(len(seen), len(demo_actions)) - 1][None].to(self.env.device)

    monkeypatch.setattr(runner, "make_policy", lambda name, env, checkpoint=None: Replay(env))
    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=1, objects=("master_chef_can",),
                       policy="expert", record_cameras=False, max_steps=200, seed=3)  # the fixture's first episode
    with torch_threads(1):
        runner.RolloutRunner(spec, RecordSink(tmp_path, spec.as_dict())).run()
    (record,) = read_jsonl(tmp_path / "records.jsonl")
    assert record["outcome"] == "S" and len(seen) == len(demo_actions) == record["steps"]
    assert torch.equal(torch.stack(seen), demo_inputs.float())


def test_a_camera_dataset_reads_without_torchcodec_traceback_and_in_lerobot_dataset_viz(tmp_path):
    """aerobench names LeRobot's video decoder (pyav) instead of letting it probe torchcodec, whose FFmpeg libraries a
    plain machine lacks: no loading traceback when `dataset info` and `train bc --images` read a camera dataset."""
    data = _dataset(tmp_path / "cams", episodes=1, max_steps=6, cameras=True)
    info = _run([str(BIN / "aerobench"), "dataset", "info", str(data)], cwd=tmp_path)
    train = _run([str(BIN / "aerobench"), "train", "bc", "--dataset", str(data), "--out", str(tmp_path / "run"),
                  "--images", "--steps", "2", "--batch-size", "4", "--image-size", "32", "--outcomes", "T",
                  "--no-progress"], cwd=tmp_path)
    assert "observation.images.drone_front" in info.stdout
    for proc in (info, train):
        text = proc.stdout + proc.stderr
        assert "torchcodec" not in text and "Traceback" not in text and "libavutil" not in text
    # LeRobot's own viewer on the same dataset, headless: a Rerun recording of episode 0
    _run([str(BIN / "lerobot-dataset-viz"), "--repo-id", "local/cams", "--root", str(data), "--episode-index", "0",
          "--save", "1", "--output-dir", str(tmp_path / "viz"), "--num-workers", "0"], cwd=tmp_path)
    (rrd,) = (tmp_path / "viz").glob("*.rrd")
    assert rrd.stat().st_size > 10_000


def _flown_and_recorded(monkeypatch, **spec_kw):
    """One TidyHouse Pick episode (seed 5, 40 steps): the runner's episode and the actions the env executed."""
    from aerobench.rollout.episode import EpisodeList
    from tests.rollout.test_noise import _Executed

    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=1, objects=("master_chef_can",), seed=5,
                       record_cameras=False, max_steps=40, **spec_kw)
    sink = EpisodeList()
    runner = RolloutRunner(spec, sink)
    make_env, wrapped = runner._env, {}

    def env_with_spy(skill):
        if skill not in wrapped:
            wrapped[skill] = _Executed(make_env(skill))
        return wrapped[skill]

    monkeypatch.setattr(runner, "_env", env_with_spy)
    with torch_threads(1):
        runner.run()
    episode = sink.episodes[0]
    return episode, np.concatenate(wrapped["pick"].executed)[: episode.num_frames]


def test_dagger_the_bc_flies_and_the_expert_labels_every_state_it_visits(trained, monkeypatch):
    bc, bc_flown = _flown_and_recorded(monkeypatch, policy="bc", checkpoint=str(trained))
    dagger, dagger_flown = _flown_and_recorded(monkeypatch, policy="bc", checkpoint=str(trained), labeler="expert")
    expert, _ = _flown_and_recorded(monkeypatch, policy="expert")
    # the labels never reach the env: the same flight as the BC's alone, state for state
    assert np.array_equal(dagger_flown, bc_flown) and np.array_equal(dagger.frames["state"], bc.frames["state"])
    assert np.array_equal(bc.frames["action"], bc_flown)  # without a labeler the policy's own action is recorded
    labels = dagger.frames["action"]
    assert np.abs(labels - dagger_flown).max() > 0.05  # recorded: not what flew
    assert np.allclose(labels[0], expert.frames["action"][0])  # the same start: the expert's own first command
    assert (dagger.frames["phase"] >= 0).all() and (bc.frames["phase"] == -1).all()  # the labeler's phases
    assert dagger.record.policy == "bc" and dagger.extra["labeler"] == "expert" and "labeler" not in bc.extra
    spec = dict(setting="TidyHouse", skills=("pick",), episodes=1)
    assert RolloutSpec(**spec, policy="bc", checkpoint="x", labeler="expert").as_dict()["labeler"] == "expert"
    assert "labeler" not in RolloutSpec(**spec).as_dict()  # runs without one keep their spec (and stay resumable)
    with pytest.raises(ValueError, match="labels another policy's flight"):
        RolloutSpec(**spec, labeler="expert")
    with pytest.raises(ValueError, match="--label-with takes expert"):
        RolloutSpec(**spec, policy="bc", checkpoint="x", labeler="random")


def test_dagger_with_a_look_first_labeller(trained, monkeypatch):
    # the labelling expert turns to the object first (`expert.look`); the BC flies exactly as it would alone
    bc, bc_flown = _flown_and_recorded(monkeypatch, policy="bc", checkpoint=str(trained))
    dagger, dagger_flown = _flown_and_recorded(monkeypatch, policy="bc", checkpoint=str(trained), labeler="expert",
                                               look_first=True)
    looking, _ = _flown_and_recorded(monkeypatch, policy="expert", look_first=True)
    plain, _ = _flown_and_recorded(monkeypatch, policy="expert")
    assert np.array_equal(dagger_flown, bc_flown)
    assert np.allclose(dagger.frames["action"][0], looking.frames["action"][0])  # the look-first expert's command
    assert not np.allclose(looking.frames["action"][0], plain.frames["action"][0])  # which is not the plain one's


def test_dagger_from_the_command_line_joined_with_the_demonstrations_and_trained_on(state_dataset, trained, tmp_path,
                                                                                      capsys):
    """The CLI's commands in this process (each subprocess paid 10-15 s of imports): the other CLI tests run them as
    the user does."""
    from aerobench.cli import main

    rounds = tmp_path / "round1"
    assert main(["generate", "--setting", "TidyHouse", "--skills", "pick", "--objects", "master_chef_can", "--episodes",
                 "1", "--seed", "5", "--no-cameras", "--policy", "bc", "--checkpoint", str(trained), "--label-with",
                 "expert", "--keep", "all", "--out", str(rounds)]) == 0
    assert "--label-with expert" in (rounds / "README.md").read_text()  # the card's generate command
    joined = tmp_path / "joined"
    assert main(["dataset", "join", str(state_dataset), str(rounds), "--out", str(joined)]) == 0
    rows = read_jsonl(joined / "meta" / "aerobench_episodes.jsonl")
    assert [(r["policy"], r["dataset_episode_index"]) for r in rows] == [("expert", 0), ("expert", 1), ("bc", 2)]
    out = tmp_path / "bc1"
    assert main(["train", "bc", "--dataset", str(joined), "--out", str(out), "--steps", "2", "--outcomes", "S,F,T",
                 "--no-progress"]) == 0
    starts = json.loads((out / "checkpoint" / "starts.json").read_text())["starts"]
    # the demonstrations' two starts and the DAgger round's one: all seen in training
    assert sorted(s[3] for s in starts) == [3 * SEED_STRIDE, 3 * SEED_STRIDE + 1, 5 * SEED_STRIDE]
    capsys.readouterr()
    assert main(["generate", "--setting", "TidyHouse", "--skills", "pick", "--episodes", "1", "--no-cameras",
                 "--policy", "expert", "--checkpoint", str(trained), "--out", str(tmp_path / "x")]) != 0
    assert "the expert policy takes no --checkpoint" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
