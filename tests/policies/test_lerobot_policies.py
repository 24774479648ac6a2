"""ACT and Diffusion Policy end to end on CPU, offline: an exported aerobench dataset -> `lerobot-train` with the repo's
config, unmodified -> a checkpoint -> `aerobench eval --policy P --checkpoint DIR` -> results with its provenance."""

import sys
from pathlib import Path

import pytest

from .smoke_eval import eval_two_short_picks

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


@pytest.mark.parametrize("policy", ["diffusion"])  # ACT: the next test, whose training also evaluates in the env
def test_policy_trains_with_the_repo_config_and_evaluates(policy, camera_dataset, run_offline, tmp_path):
    _run = run_offline
    train_dir = tmp_path / "train"
    label = f"{policy} (2 steps, test)"
    _run([str(BIN / "lerobot-train"), "--config_path", str(REPO / "configs" / f"{policy}_tidy_house.json"),
          "--dataset.root", str(camera_dataset), "--steps", "2", "--save_freq", "2", "--batch_size", "2",
          "--num_workers", "0", "--output_dir", str(train_dir)], cwd=tmp_path)
    assert (train_dir / "checkpoints" / "last" / "pretrained_model" / "model.safetensors").is_file()

    eval_two_short_picks(policy, train_dir, label, tmp_path)


def test_lerobot_train_evaluates_in_the_aerobench_env_during_training(camera_dataset, run_offline, tmp_path):
    """`--env.type aerobench` (registered by the lerobot_env_aerobench plugin) runs LeRobot's own rollout
    evaluation inside lerobot-train: metrics in the log and an episode video from the env's render. The ACT
    checkpoint it trains (the repo config) then evaluates with `aerobench eval`."""
    train_dir = tmp_path / "train"
    proc = run_offline([str(BIN / "lerobot-train"), "--config_path", str(REPO / "configs" / "act_tidy_house.json"),
                        "--dataset.root", str(camera_dataset), "--steps", "2", "--save_freq", "2", "--batch_size", "2",
                        "--num_workers", "0", "--output_dir", str(train_dir), "--env_eval_freq", "2",
                        "--env.type", "aerobench", "--env.task", "TidyHouse/pick", "--env.episode_length", "4",
                        "--eval.n_episodes", "1", "--eval.batch_size", "1"], cwd=tmp_path)
    log = proc.stdout + proc.stderr
    assert "Eval policy at step 2" in log
    overall = next(line for line in log.splitlines() if "Suite overall aggregated" in line)
    assert "'n_episodes': 1" in overall and "'pc_success': 0.0" in overall  # 2 steps of training cannot pick
    (video,) = (train_dir / "eval" / "videos_step_000002").rglob("*.mp4")
    assert video.stat().st_size > 0

    eval_two_short_picks("act", train_dir, "act (2 steps, test)", tmp_path)
