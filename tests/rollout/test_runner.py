"""The rollout runner and `aerobench generate`: plans, determinism, crash-safe resume, shards, bad input."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from aerobench.cli import main
from aerobench.rollout.runner import RolloutSpec, plan_episodes, shard_plans

CLI = [sys.executable, "-m", "aerobench.cli"]
ENV = dict(os.environ, HF_HUB_OFFLINE="1", MS_SKIP_ASSET_DOWNLOAD_PROMPT="1", PYTHONUNBUFFERED="1")


def _nav(out: Path, *extra: str, episodes: int = 3) -> list[str]:
    return ["generate", "--setting", "TidyHouse", "--skills", "nav", "--episodes", str(episodes), "--part-size", "1",
            "--keep", "all", "--out", str(out), *extra]


def _generate(out: Path, *extra: str, episodes: int = 3) -> int:
    """`aerobench generate` in this process (a subprocess pays 10-15 s of imports); the kill below needs its own."""
    return main(_nav(out, *extra, episodes=episodes))


def _records(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / ".aerobench" / "records.jsonl").read_text().splitlines()]


def test_plans_are_deterministic_balanced_and_sharded():
    spec = RolloutSpec(setting="PrepareGroceries", skills=("pick", "place"), episodes=32, seed=7)
    plans = plan_episodes(spec)
    assert plans == plan_episodes(spec)
    assert [p.skill for p in plans[:4]] == ["pick", "place", "pick", "place"]
    picks = [p.object for p in plans if p.skill == "pick"]
    assert len(set(picks)) == 8  # all eight PrepareGroceries classes, in turn
    assert len({p.seed for p in plans}) == 32
    shards = [shard_plans(RolloutSpec(setting="PrepareGroceries", skills=("pick",), episodes=10, shard=(i, 3))) for i in range(3)]
    assert [p.index for s in shards for p in s] == list(range(10))  # contiguous blocks, in plan order
    assert [len(s) for s in shards] == [3, 3, 4]


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(skills=("fly",)), "unknown skill 'fly'; valid for TidyHouse: pick, place, nav, pick_nav_place"),
        (dict(skills=("open",)), "TidyHouse has no open skill"),
        (dict(skills=("pick",), shard=(3, 2)), "--shard must be i/k with 0 <= i < k, got 3/2"),
        (dict(skills=("pick",), num_envs=4), "physx_cpu runs one env per process"),
        (dict(skills=("pick",), objects=("package",)), "object 'package' is not part of TidyHouse"),
        (dict(skills=("pick",), episodes=0), "--episodes must be a positive integer"),
        (dict(skills=("pick",), seed=5000), "--seed must be between 0 and 4294 (episode i runs with seed"),
        (dict(skills=("pick",), seed=-1), "--seed must be between 0 and 4294"),
    ],
)
def test_spec_errors(kwargs, message):
    base = dict(setting="TidyHouse", episodes=4)
    base.update(kwargs)
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        RolloutSpec(**base)


def test_generate_is_deterministic_and_resumes_after_a_kill(tmp_path):
    """With the three cameras: the kill can leave a part's videos half-written. Two episodes, one part each: the kill
    lands in the second, after the first is committed."""
    reference = tmp_path / "reference"
    assert _generate(reference, episodes=2) == 0
    killed = tmp_path / "killed"
    proc = subprocess.Popen(CLI + _nav(killed, episodes=2), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=ENV)
    parts = killed / ".aerobench" / "parts"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and not (parts.is_dir() and any(p.name.startswith("part-") for p in parts.iterdir())):
        time.sleep(0.2)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert len([p for p in parts.iterdir() if p.name.startswith("part-")]) == 1  # killed in the second episode
    assert _generate(killed, episodes=2) == 0  # the same command continues
    got, want = _records(killed), _records(reference)
    assert sorted(x["episode_index"] for x in got) == [0, 1]  # each episode exactly once
    strip = lambda rows: sorted((x["episode_index"], x["seed"], x["outcome"], x["steps"], x["mode"]) for x in rows)  # noqa: E731
    assert strip(got) == strip(want)  # the same episodes as an uninterrupted run
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset("local/killed", root=killed)
    assert ds.num_episodes == 2 and len(ds.meta.video_keys) == 3


def test_shards_then_merge(tmp_path, capsys):
    out = tmp_path / "sharded"
    for i in range(2):
        assert _generate(out, "--shard", f"{i}/2", "--no-cameras", episodes=4) == 0
    assert main(["dataset", "merge", str(out)]) == 0
    capsys.readouterr()
    assert main(["dataset", "info", str(out)]) == 0
    info = capsys.readouterr().out
    assert "episodes  4" in info and "nav 4" in info
    card = (out / "README.md").read_text()  # the dataset card, as LeRobot's hub datasets have
    assert "aerobench generate --setting TidyHouse --skills nav --episodes 4 --seed 0 --keep all" in card
    assert "| nav | 4 |" in card and "| `observation.state` | float32 | 19 |" in card and "state only" in card
    snippet = card.split("```python\n")[1].split("```")[0]
    scope: dict = {}
    exec(snippet, scope)  # the card's loading code works as written
    assert scope["ds"].num_episodes == 4
    # the merged folder holds this dataset: another plan (a different seed) is refused and nothing in it is touched
    before = sorted((str(p.relative_to(out)), p.stat().st_mtime_ns) for p in out.rglob("*"))
    assert _generate(out, "--no-cameras", "--seed", "5", episodes=4) == 2
    err = capsys.readouterr().err
    assert "holds a different dataset" in err and len(err.strip().splitlines()) == 1
    assert sorted((str(p.relative_to(out)), p.stat().st_mtime_ns) for p in out.rglob("*")) == before


def test_a_bad_shard_is_one_line_and_creates_nothing(tmp_path, capsys):
    assert main(["generate", "--setting", "TidyHouse", "--skills", "nav", "--episodes", "1", "--shard", "3/2", "--out",
                 str(tmp_path / "x")]) == 2
    assert capsys.readouterr().err.strip() == "aerobench generate: error: --shard must be i/k with 0 <= i < k, got 3/2"
    assert not (tmp_path / "x").exists()


def test_a_chain_dataset_labels_each_frame_with_its_stages_skill(tmp_path):
    """`annotation.skill` holds the global skill index (meta/aerobench.json's list) of the stage acting on each frame:
    checked against the task state's skill one-hot, which the env computes on its own. (Chains once exported the
    global index mapped a second time: their nav frames read "place" and their place frames "nav".)"""
    import pandas as pd

    from aerobench.envs.tasks import SKILLS
    from aerobench.export import DatasetSink
    from aerobench.rollout.runner import RolloutRunner
    from aerobench.threads import torch_threads

    out = tmp_path / "chain"
    spec = RolloutSpec(setting="PackageDelivery", skills=("deliver",), episodes=1, policy="expert",
                       record_cameras=False, max_steps=260, seed=9)
    sink = DatasetSink(out, {**spec.as_dict(), "keep": "all"})
    with torch_threads(1):
        RolloutRunner(spec, sink).run()
    sink.close()
    frames = pd.concat(pd.read_parquet(f) for f in sorted((out / "data").rglob("*.parquet")))
    skill = frames["annotation.skill"].map(lambda v: int(v[0]) if hasattr(v, "__len__") else int(v))
    stage = frames["annotation.stage"].map(lambda v: int(v[0]) if hasattr(v, "__len__") else int(v))
    one_hot = frames["observation.environment_state"].map(lambda v: int(v[: len(SKILLS)].argmax()))
    assert set(stage) == {0, 1}, "the expert must reach the transport within the step cap for this test to bite"
    assert (skill == one_hot).all()
    assert skill[stage == 0].eq(SKILLS.index("pick")).all() and skill[stage == 1].eq(SKILLS.index("nav")).all()
