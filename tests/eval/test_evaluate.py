"""`aerobench eval`: records + results on a tiny grid, resume without loss or duplication, bad input, summarize."""

import concurrent.futures
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from aerobench.eval.evaluate import EvalConfig, evaluate
from aerobench.eval.results import RESULTS_VERSION, failure_modes, load_results, over_all_cells
from aerobench.rollout.records import RecordSink, read_records
from tests.cli_here import aerobench_here

TINY = dict(policy="random", setting="TidyHouse", skills=("pick", "place"), objects=("sugar_box", "bowl"), episodes_per_object=2)


def _cli(*args: str) -> subprocess.CompletedProcess:
    return aerobench_here(*args)  # in this process: the imports are loaded (tests/cli_here.py)


pytestmark = pytest.mark.xdist_group("tiny_eval")  # the module's tiny evaluation runs once, on one worker


@pytest.fixture(scope="module")
def tiny_eval(tmp_path_factory):
    out = tmp_path_factory.mktemp("eval")
    return out, evaluate(EvalConfig(**TINY), out, command="test")


def test_results_cover_the_grid(tiny_eval):
    out, results = tiny_eval
    assert results["version"] == RESULTS_VERSION and results["policy"] == "random"
    cells = {(c["skill"], c["object"]): c for c in results["cells"]}
    assert set(cells) == {(s, o) for s in ("pick", "place") for o in ("sugar_box", "bowl")}
    assert all(c["n"] + c["init_failures"] == 2 for c in cells.values())
    assert sum(sum(c["modes"].values()) for c in cells.values()) == sum(c["n"] for c in cells.values())
    # a random policy does not pick or place: every executed episode ends in a named failure mode
    assert results["mean_sr"] == 0.0 and all(not m.startswith("Successful") for c in cells.values() for m in c["modes"])
    assert load_results(out / "results.json")["cells"] == results["cells"]
    assert results["provenance"]["command"] == "test" and results["provenance"]["episodes_per_object"] == 2
    rows = read_records(out / "records.jsonl")
    assert sorted(r["episode_index"] for r in rows) == list(range(8))


def test_one_number_over_all_cells_sums_their_counts_and_modes(tiny_eval):
    _, results = tiny_eval
    pooled = over_all_cells(results)
    assert pooled["n"] == sum(c["n"] for c in results["cells"]) and pooled["successes"] == 0
    assert sum(pooled["modes"].values()) == pooled["n"] and pooled["wilson95"][0] == 0.0 < pooled["wilson95"][1]
    modes = {"Successful opening": 4, "Handle-slip failure": 20, "Handle-pinch failure": 23}
    assert list(failure_modes(modes).items()) == [("Handle-pinch failure", 23), ("Handle-slip failure", 20)]


def _no_worker_processes(*args, **kwargs):
    raise AssertionError("a worker process was started for shards with nothing left to run")


def test_worker_processes_record_the_same_episodes_as_one_process(tiny_eval, tmp_path, monkeypatch):
    """`workers=2` runs the plan's two shards in two processes, each into its own record file; the results are
    those of the serial run, episode for episode (a random policy is seeded per episode)."""
    out, serial = tiny_eval
    results = evaluate(EvalConfig(**TINY, workers=2), tmp_path / "eval", command="test")
    files = results["provenance"]["records"].split(",")
    assert files == ["shards/0-of-2/records.jsonl", "shards/1-of-2/records.jsonl"]
    shards = [read_records(tmp_path / "eval" / f) for f in files]
    assert [r["episode_index"] for r in shards[0]] == [0, 1, 2, 3]  # contiguous blocks of the plan
    assert [r["episode_index"] for r in shards[1]] == [4, 5, 6, 7]

    def outcome(r):
        return r["episode_index"], r["seed"], r["object"], r["skill"], r["outcome"], r["mode"], r["steps"]

    parallel = sorted(outcome(r) for rows in shards for r in rows)
    assert parallel == sorted(outcome(r) for r in read_records(out / "records.jsonl"))
    assert results["cells"] == serial["cells"]
    # rerunning the command finds every shard complete and runs nothing: not even a worker process starts
    before = [(tmp_path / "eval" / f).read_text() for f in files]
    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", _no_worker_processes)
    evaluate(EvalConfig(**TINY, workers=2), tmp_path / "eval", command="test")
    assert [(tmp_path / "eval" / f).read_text() for f in files] == before
    with pytest.raises(ValueError, match="--workers must be a positive integer"):
        EvalConfig(**TINY, workers=0)


def test_resume_after_a_torn_write_loses_and_duplicates_nothing(tiny_eval, tmp_path):
    out, results = tiny_eval
    rows = (out / "records.jsonl").read_text().splitlines()
    resumed = tmp_path / "resumed"
    resumed.mkdir()
    (resumed / "run.json").write_text((out / "run.json").read_text())
    # the process died after five episodes, in the middle of writing the sixth
    (resumed / "records.jsonl").write_text("\n".join(rows[:5]) + "\n" + rows[5][: len(rows[5]) // 2])
    again = evaluate(EvalConfig(**TINY), resumed, command="test")
    new_rows = read_records(resumed / "records.jsonl")
    assert [r["episode_index"] for r in new_rows] == list(range(8))
    assert [r["mode"] for r in new_rows] == [json.loads(r)["mode"] for r in rows]  # deterministic: same episodes
    assert again["cells"] == results["cells"]


def test_resume_under_another_shard_layout_runs_and_counts_each_episode_once(tiny_eval, tmp_path, monkeypatch):
    """A run begun with interleaved shards (even / odd indices; an older layout) and resumed with contiguous blocks,
    then with four workers: no episode runs twice and the results count each once."""
    out, serial = tiny_eval
    rows = {json.loads(r)["episode_index"]: r for r in (out / "records.jsonl").read_text().splitlines()}
    run = json.loads((out / "run.json").read_text())
    resumed = tmp_path / "resumed"
    for i, done in ((0, (0, 2, 4, 6)), (1, (1, 3))):  # the process of shard 1 died after two episodes
        folder = resumed / "shards" / f"{i}-of-2"
        folder.mkdir(parents=True)
        (folder / "run.json").write_text(json.dumps({**run, "shard": [i, 2]}))
        (folder / "records.jsonl").write_text("".join(rows[k] + "\n" for k in done))
    again = evaluate(EvalConfig(**TINY, workers=2), resumed, command="test")
    recorded = [r["episode_index"] for f in sorted(resumed.glob("shards/*/records.jsonl")) for r in read_records(f)]
    assert sorted(recorded) == list(range(8))  # only 5 and 7 ran
    assert again["cells"] == serial["cells"]
    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", _no_worker_processes)
    evaluate(EvalConfig(**TINY, workers=4), resumed, command="test")  # another worker count: nothing to run
    assert sorted(r["episode_index"] for f in resumed.glob("shards/*/records.jsonl") for r in read_records(f)) == list(range(8))
    other = resumed / "shards" / "9-of-9"
    other.mkdir()
    (other / "run.json").write_text(json.dumps({**run, "seed": 7, "shard": [8, 9]}))
    with pytest.raises(ValueError, match="holds a different run"):
        evaluate(EvalConfig(**TINY, workers=2), resumed, command="test")


def test_a_folder_holding_another_run_is_refused(tiny_eval):
    out, _ = tiny_eval
    with pytest.raises(ValueError, match="holds a different run"):
        RecordSink(out, {"policy": "expert"})


def test_cli_errors_are_one_line(tmp_path):
    r = _cli("eval", "--policy", "nope", "--setting", "TidyHouse", "--out", str(tmp_path / "x"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "unknown policy 'nope'; valid policies:" in r.stderr and "expert" in r.stderr and "random" in r.stderr
    assert not (tmp_path / "x").exists()
    r = _cli("eval", "--policy", "random", "--setting", "Garage", "--out", str(tmp_path / "y"))
    assert r.returncode == 2 and "unknown setting 'Garage'" in r.stderr and not (tmp_path / "y").exists()
    r = _cli("eval", "--policy", "random", "--setting", "TidyHouse", "--chain", "place,pick", "--out", str(tmp_path / "z"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and not (tmp_path / "z").exists()
    assert "TidyHouse has no chain place,pick; valid --chain values: pick,transport,place" in r.stderr
    bad = tmp_path / "old.json"
    bad.write_text(json.dumps({"format": "aerobench-results", "version": 0}))
    r = _cli("leaderboard", str(bad), "--out", str(tmp_path / "boards"))
    assert r.returncode == 2 and "results version 0" in r.stderr and not (tmp_path / "boards").exists()


def test_summarize_and_leaderboard_cli(tiny_eval, tmp_path):
    out, results = tiny_eval
    r = _cli("summarize", str(out), "--label", "random (tiny)", "--out", str(tmp_path / "r.json"))
    assert r.returncode == 0, r.stderr
    summary = load_results(tmp_path / "r.json")
    assert summary["label"] == "random (tiny)" and summary["cells"] == results["cells"]
    r = _cli("leaderboard", str(tmp_path / "r.json"), str(out / "results.json"), "--out", str(tmp_path / "boards"))
    assert r.returncode == 0, r.stderr
    md = (tmp_path / "boards" / "TidyHouse.md").read_text()
    assert "| random (tiny) | none | Pick | 0.0 ± 0.0 | 0.0 ± 0.0 | 0.0 |" in md and "| random | none | Pick |" in md
    page = Path(tmp_path / "boards" / "index.html").read_text()
    grid = page.split('<table class="sortable"')[1].split("</table>")[0]
    assert grid.count("<tr>") == 1 + 4  # one setting: a header row and 2 policies x 2 skills
    assert '<div class="compare" data-setting="TidyHouse"' in page  # both ran the same starts: comparable


def test_video_shows_the_third_person_view_above_the_onboard_cameras(tmp_path, monkeypatch):
    """`--video 1`: episode 0 gets an mp4 with the third-person view (384x384) above the three onboard cameras;
    episode 1 records no third-person frames and gets no video. A state-only policy's run stays state-only: the
    onboard views are rendered for the video's episode alone (once per recorded frame), not for every episode."""
    import imageio.v3 as iio
    from mani_skill.envs.sapien_env import BaseEnv

    rendered = []
    original = BaseEnv.get_sensor_images
    monkeypatch.setattr(BaseEnv, "get_sensor_images", lambda env: rendered.append(env.obs_mode) or original(env))
    config = EvalConfig(policy="random", setting="TidyHouse", skills=("pick",), objects=("sugar_box",),
                        episodes_per_object=2, video=1, max_steps=6)
    results = evaluate(config, tmp_path / "eval", command="test")
    assert results["videos"] == ["videos/episode_000000.mp4"]
    assert 1 <= len(rendered) <= 6 and set(rendered) == {"state_dict"}  # episode 0's frames only, at most 6 steps
    frames = iio.imread(tmp_path / "eval" / "videos" / "episode_000000.mp4")
    assert frames.shape[1:] == (384 + 128, 384, 3) and frames.shape[0] >= 1


_ORPHAN_SCRIPT = """
import multiprocessing, os, signal, time
from concurrent.futures import ProcessPoolExecutor
from aerobench.eval.evaluate import exit_with_parent

if __name__ == "__main__":
    pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), initializer=exit_with_parent,
                               initargs=(os.getpid(), 0.1))
    worker = pool.submit(os.getpid).result()
    pool.submit(time.sleep, 120)  # a shard still running
    print(worker, flush=True)
    os.kill(os.getpid(), signal.SIGKILL)  # the driver killed mid-run
"""


def _running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "\nState:\tZ" not in state  # a zombie has exited (nobody reaped it yet)


def test_eval_workers_exit_when_the_driver_is_killed(tmp_path):
    # an orphaned worker went on appending episodes to the shard files a re-run of the same command was resuming
    script = tmp_path / "driver.py"
    script.write_text(_ORPHAN_SCRIPT)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    worker = int(done.stdout.split()[0])
    deadline = time.monotonic() + 20
    while _running(worker) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _running(worker), f"worker {worker} outlived its killed driver"
