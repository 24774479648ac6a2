"""`--ray`: generation and evaluation shards as Ray tasks on a local runtime of 2 workers write what one process
writes; a worker killed mid-run is retried by Ray with every planned episode exactly once; a bad address is one line."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.cli_here import aerobench_here

ray = pytest.importorskip("ray")  # a pinned dependency: set-up installs it, so this only guards a broken venv
# One local Ray runtime at a time on the 2-core machine: the Ray tests (here and in tests/train/test_ppo.py) share a
# worker. Two runtimes side by side, each with its workers, once left a GPU-shard run waiting 300 s without a result.
pytestmark = pytest.mark.xdist_group("ray")

CLI = [sys.executable, "-m", "aerobench.cli"]
ENV = dict(os.environ, HF_HUB_OFFLINE="1", MS_SKIP_ASSET_DOWNLOAD_PROMPT="1", PYTHONUNBUFFERED="1")
NAV = ["generate", "--setting", "TidyHouse", "--skills", "nav", "--part-size", "1", "--keep", "all", "--no-cameras"]


def _records(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / ".aerobench" / "records.jsonl").read_text().splitlines()]


def _without_location(rows: list[dict]) -> list[dict]:
    """A record names the shard that ran it and the part it is stored in; everything else must match a one-process
    run."""
    return sorted(({k: v for k, v in r.items() if k not in ("shard", "part")} for r in rows),
                  key=lambda r: r["episode_index"])


def _episode_lengths(root: Path) -> list[int]:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset("local/test", root=root)
    return [int(n) for n in ds.meta.episodes["length"]]


def test_generate_on_ray_with_a_killed_worker_writes_the_episodes_of_one_process(tmp_path):
    """Two Ray shards of four episodes each; one worker is killed once a part is committed (with three episodes of its
    shard still to run, so that it is still running on a fast machine). Ray retries its shard, which resumes from the
    committed parts: every planned episode once, and the same records and frames as one process."""
    serial, on_ray = tmp_path / "serial", tmp_path / "ray"
    r = aerobench_here(*NAV, "--episodes", "8", "--out", str(serial))  # one process: this one
    assert r.returncode == 0, r.stderr[-2000:]
    proc = subprocess.Popen(CLI + NAV + ["--episodes", "8", "--out", str(on_ray), "--ray"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV)
    parts = on_ray / ".aerobench" / "parts"
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and not (parts.is_dir() and any(p.name.startswith("part-") for p in parts.iterdir())):
        time.sleep(0.05)
    workers = subprocess.run(["pgrep", "-f", "ray::_generate_shard"], capture_output=True, text=True).stdout.split()
    assert workers, "no Ray worker was running a generation shard"
    os.kill(int(workers[0]), signal.SIGKILL)  # mid-run: each shard has four episodes, one part is committed
    stdout, stderr = proc.communicate(timeout=900)
    assert proc.returncode == 0, stderr[-2000:]
    assert "8 episodes in" in stdout and "merged" in stdout
    got, want = _records(on_ray), _records(serial)
    assert sorted(x["episode_index"] for x in got) == list(range(8))  # every planned episode exactly once
    assert sorted(x["shard"] for x in got) == [0] * 4 + [1] * 4  # two Ray shards ran them
    assert _without_location(got) == _without_location(want)  # ids, seeds, outcomes, modes, event times, diagnostics
    lengths = _episode_lengths(on_ray)
    assert lengths == _episode_lengths(serial)  # same episodes and frames, in plan order
    assert len(lengths) == 8 and len(set(lengths)) > 1  # (distinct lengths: the order is really checked)


def test_eval_on_ray_gives_the_cells_of_one_process(tmp_path):
    from aerobench.eval.evaluate import EvalConfig, evaluate

    tiny = dict(policy="random", setting="TidyHouse", skills=("pick",), objects=("sugar_box", "bowl"),
                episodes_per_object=2)
    serial = evaluate(EvalConfig(**tiny), tmp_path / "serial", command="test")
    try:
        on_ray = evaluate(EvalConfig(**tiny, ray="local", workers=2), tmp_path / "ray", command="test",
                          on_progress=lambda done, successes, seconds: None)
    finally:
        ray.shutdown()
    assert on_ray["provenance"]["records"] == "shards/0-of-2/records.jsonl,shards/1-of-2/records.jsonl"
    assert on_ray["cells"] == serial["cells"]
    assert on_ray["episodes"] == serial["episodes"] == 4


def test_ray_address_without_a_cluster_is_one_line(tmp_path):
    r = aerobench_here(*NAV, "--episodes", "1", "--out", str(tmp_path / "x"), "--ray", "127.0.0.1:1")
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        "aerobench generate: error: no Ray cluster at 127.0.0.1:1: start one there with `ray start --head --port 1`, "
        "or pass --ray without an address for a local runtime"]
    assert not (tmp_path / "x").exists()


GPU_SHARDS = """
import json, os
import ray
from aerobench.rollout.ray_shards import default_shards, run_shards, shard_gpus

def task(index, progress):
    return index, os.environ.get("CUDA_VISIBLE_DEVICES"), [str(g) for g in ray.get_gpu_ids()]

ray.init(num_cpus=2, num_gpus=2, include_dashboard=False, log_to_driver=False)
try:
    shards = default_shards("physx_cuda")
    print(json.dumps({"shards": shards, "cpu_shards": default_shards("physx_cpu"),
                      "results": run_shards(task, [(i,) for i in range(shards)], num_gpus=shard_gpus("physx_cuda"))}))
finally:
    ray.shutdown()
"""


def test_physx_cuda_shards_get_one_gpu_each():
    """Ray scheduling of physx_cuda shards on a local runtime that declares 2 GPUs (Ray schedules by the declared
    resource and sets CUDA_VISIBLE_DEVICES; no GPU is touched, so this runs on a CPU machine)."""
    r = subprocess.run([sys.executable, "-c", GPU_SHARDS], capture_output=True, text=True, timeout=300, env=ENV)
    assert r.returncode == 0, r.stderr[-2000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["shards"] == 2 and out["cpu_shards"] == 2  # one shard per GPU; per CPU on physx_cpu
    devices = sorted(visible for _, visible, _ in out["results"])
    assert devices == ["0", "1"], out  # each shard sees only its own GPU
    assert all(ids == [visible] for _, visible, ids in out["results"])


def test_physx_cuda_shards_on_a_runtime_without_gpus_are_one_line(monkeypatch):
    """What the runtime offers is Ray's answer (`ray.cluster_resources`); the shards are refused before any task."""
    from aerobench.rollout.ray_shards import run_shards, shard_gpus

    monkeypatch.setattr(ray, "cluster_resources", lambda: {"CPU": 2.0})
    with pytest.raises(ValueError) as e:
        run_shards(lambda index, progress: index, [(0,), (1,)], num_gpus=shard_gpus("physx_cuda"))
    assert str(e.value) == ("--sim-backend physx_cuda shards need a GPU each and this Ray runtime offers none: run on a "
                            "GPU node (`ray start --head --num-gpus N` there, then --ray HOST:PORT), or use physx_cpu")
    assert not ray.is_initialized()
