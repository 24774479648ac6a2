"""The check every LeRobot-policy test ends with: `aerobench eval` on a freshly trained checkpoint, for two short
Pick episodes, writes results and records that count every episode with the checkpoint's provenance. The command
runs in the test's process (tests/cli_here.py), in `cwd`."""

import contextlib
import json
from pathlib import Path

from tests.cli_here import aerobench_here


def eval_two_short_picks(policy: str, train_dir: Path, label: str, cwd: Path) -> dict:
    """Scores `train_dir` with `aerobench eval --policy <policy>`, asserts on what it wrote, returns results.json."""
    out = cwd / "eval"
    with contextlib.chdir(cwd):
        proc = aerobench_here("eval", "--policy", policy, "--checkpoint", str(train_dir), "--setting", "TidyHouse",
                              "--skills", "pick", "--objects", "master_chef_can", "--episodes-per-object", "2",
                              "--max-steps", "8", "--label", label, "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert label in proc.stdout
    results = json.loads((out / "results.json").read_text())
    assert results["policy"] == policy and results["label"] == label
    # named relative to the directory the evaluation ran in when the checkpoint lies inside it (portable results)
    assert (cwd / results["provenance"]["checkpoint"]).resolve() == train_dir.resolve()
    assert results["provenance"]["max_steps"] == 8
    (cell,) = results["cells"]
    assert (cell["skill"], cell["object"], cell["n"]) == ("pick", "master_chef_can", 2)
    records = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    assert [r["episode_index"] for r in records] == [0, 1]
    # an untrained policy cannot pick in 8 steps: every episode ends truncated or failed, and is counted
    assert sum(cell["outcomes"].values()) == 2 and cell["successes"] == 0
    assert all(r["steps"] <= 8 for r in records)
    # the camera dataset is two seed-0 Pick episodes of this object, and so are these: traced through lerobot-train's
    # train_config.json to the dataset, both are starts the policy trained on
    seen = results["provenance"]["seen_in_training"]
    assert (seen["episodes"], seen["of"], seen["untraced"]) == (2, 2, []) and len(seen["sources"]) == 1
    return results
