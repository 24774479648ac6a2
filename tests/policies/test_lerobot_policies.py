"""ACT and Diffusion Policy end to end on CPU, offline: an exported aerobench dataset -> `lerobot-train` with the repo's
config, unmodified -> a checkpoint -> `aerobench eval --policy P --checkpoint DIR` -> results with its provenance."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from aerobench.export import DatasetSink
from aerobench.rollout.runner import RolloutRunner, RolloutSpec

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def _run(cmd: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "MS_SKIP_ASSET_DOWNLOAD_PROMPT": "1", "WANDB_MODE": "disabled"}
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"{' '.join(cmd)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc


@pytest.fixture(scope="module")
def camera_dataset(tmp_path_factory) -> Path:
    """Two short random-policy Pick episodes with the three RGB-D cameras, exported as a LeRobotDataset."""
    root = tmp_path_factory.mktemp("lerobot") / "ds"
    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=2, objects=("master_chef_can",), policy="random",
                       record_cameras=True, max_steps=12)
    sink = DatasetSink(root, {**spec.as_dict(), "keep": "all"})
    RolloutRunner(spec, sink).run()
    sink.close()
    return root


@pytest.mark.parametrize("policy", ["act", "diffusion"])
def test_policy_trains_with_the_repo_config_and_evaluates(policy, camera_dataset, tmp_path):
    train_dir = tmp_path / "train"
    label = f"{policy} (2 steps, test)"
    _run([str(BIN / "lerobot-train"), "--config_path", str(REPO / "configs" / f"{policy}_tidy_house.json"),
          "--dataset.root", str(camera_dataset), "--steps", "2", "--save_freq", "2", "--batch_size", "2",
          "--num_workers", "0", "--output_dir", str(train_dir)], cwd=tmp_path)
    assert (train_dir / "checkpoints" / "last" / "pretrained_model" / "model.safetensors").is_file()

    out = tmp_path / "eval"
    proc = _run([str(BIN / "aerobench"), "eval", "--policy", policy, "--checkpoint", str(train_dir),
                 "--setting", "TidyHouse", "--skills", "pick", "--objects", "master_chef_can",
                 "--episodes-per-object", "2", "--max-steps", "8", "--label", label, "--out", str(out)],
                cwd=tmp_path)
    assert label in proc.stdout
    results = json.loads((out / "results.json").read_text())
    assert results["policy"] == policy and results["label"] == label
    assert results["provenance"]["checkpoint"] == str(train_dir.resolve())
    assert results["provenance"]["max_steps"] == 8
    (cell,) = results["cells"]
    assert (cell["skill"], cell["object"], cell["n"]) == ("pick", "master_chef_can", 2)
    records = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    assert [r["episode_index"] for r in records] == [0, 1]
    # an untrained policy cannot pick in 8 steps: every episode ends truncated or failed, and is counted
    assert sum(cell["outcomes"].values()) == 2 and cell["successes"] == 0
    assert all(r["steps"] <= 8 for r in records)
