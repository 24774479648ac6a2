"""The data-generation benches (`bench/learning_curves.py`, `bench/diversity.py`, `bench/bc_inputs.py`) end to end
with tiny budgets: real expert rollouts, real BC and PPO training, held-out evaluation, JSON and PNG; plus their pure
helpers."""

import json
import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from aerobench.envs.rendering import ray_tracing_device

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

import bc_inputs  # noqa: E402
import call_warmth  # noqa: E402
import descent_onset  # noqa: E402
import diversity  # noqa: E402
import label_predictability  # noqa: E402
import learning_curves  # noqa: E402
import ppo_progress  # noqa: E402
import release_aliasing  # noqa: E402
import step_cost  # noqa: E402
import step_floor  # noqa: E402

from aerobench.rollout.episode import EVENT_FLAGS  # noqa: E402

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _is_png(path: Path) -> bool:
    return path.is_file() and path.read_bytes()[:8] == PNG_MAGIC


def _finite_estimate(est) -> bool:
    return est is not None and all(math.isfinite(v) for v in [est["mean"], *est["ci95"]]) and \
        est["ci95"][0] - 1e-9 <= est["mean"] <= est["ci95"][1] + 1e-9


def test_moving_average_is_a_trailing_window():
    ma = learning_curves.moving_average(np.array([1, 0, 0, 1, 1, 1]), window=2)
    assert ma == pytest.approx([1, 0.5, 0, 0.5, 1, 1])


def test_ppo_recipe_anneals_the_cpu_recipe_from_its_start_to_the_budgets_end():
    assert learning_curves.ppo_recipe("spec", 5_000_000) == {}
    cpu = learning_curves.ppo_recipe("cpu", 4_000_000)
    assert (cpu["lr_decay_start"], cpu["lr_decay_steps"], cpu["reward"]) == (1_500_000, 4_000_000, "dense")
    short = learning_curves.ppo_recipe("cpu", 1_500_000)  # ends where the decay would start: a constant rate
    assert "lr_decay_start" not in short and "lr_decay_steps" not in short and short["num_steps"] == 1024
    assert "lr_decay_start" in learning_curves.PPO_RECIPES["cpu"]  # the table itself is not changed by a call


def test_ppo_progress_bins_a_run_by_interactions_and_reads_the_pick_potential(tmp_path, capsys):
    assert ppo_progress.default_bins(120_000) == [0, 50_000, 100_000, 150_000]
    assert ppo_progress.default_bins(1_200_000)[-3:] == [900_000, 1_000_000, 1_500_000]
    run = tmp_path / "run"
    (run / "checkpoint").mkdir(parents=True)
    (run / "checkpoint" / "config.json").write_text(json.dumps({"train": {"skill": "pick"}}))
    rows = [  # (global step, outcome, length, peak potential)
        (10, "collision", 30, -0.6), (20, "collision", 40, -0.4), (30, "truncated", 400, -0.2),
        (60, "truncated", 400, -0.04), (70, "success", 150, 2.9), (80, "collision", 90, 0.8)]
    with open(run / "train_episodes.jsonl", "w") as f:
        for i, (step, outcome, length, peak) in enumerate(rows):
            f.write(json.dumps({"global_step": step, "episode": i + 1, "success": outcome == "success", "return": 0.0,
                                "length": length, "outcome": outcome, "peak_potential": peak}) + "\n")
    first, second = ppo_progress.progress_rows(ppo_progress.ppo_training_episodes(run), [0, 50, 100], "pick")
    assert (first["episodes"], first["successes"], first["median_length"]) == (3, 0, 40)
    assert first["collision"] == pytest.approx(2 / 3) and first["truncated"] == pytest.approx(1 / 3)
    assert first["median_closest_m"] == pytest.approx(0.4) and first["within_5cm"] == 0 and first["grasped"] == 0
    assert (second["episodes"], second["successes"], second["grasped"]) == (3, 1, 2)
    assert second["median_closest_m"] == 0.0 and second["within_5cm"] == 1.0
    assert ppo_progress.update_rows(run, [0, 50, 100]) == []  # no scalars logged yet
    with open(run / "scalars.jsonl", "w") as f:  # three updates: two in the first bin, one in the second
        for step, kl, clip, std, lr in ((20, 0.01, 0.1, 0.6, 3e-4), (40, 0.03, 0.3, 0.5, 2e-4), (80, 0.2, 0.6, 0.2, 0.0)):
            for tag, value in (("losses/approx_kl", kl), ("losses/clipfrac", clip), ("charts/action_std", std),
                               ("charts/learning_rate", lr), ("charts/SPS", 900.0)):
                f.write(json.dumps({"step": step, "tag": tag, "value": value}) + "\n")
        f.write('{"step": 90, "tag": "losses/appr')  # a torn last line
    early, late = ppo_progress.update_rows(run, [0, 50, 100])
    assert early == {"from": 0, "to": 50, "updates": 2, "approx_kl": pytest.approx(0.02), "clipfrac": pytest.approx(0.2),
                     "action_std": pytest.approx(0.55), "learning_rate": pytest.approx(2.5e-4)}
    assert (late["updates"], late["approx_kl"], late["action_std"], late["learning_rate"]) == (1, 0.2, 0.2, 0.0)
    ppo_progress.main([str(run), "--bins", "0,50,100", "--png", str(tmp_path / "p.png")])
    out = capsys.readouterr().out
    assert "6 episodes to step 80, skill pick" in out and "median closest  40.0 cm" in out and _is_png(tmp_path / "p.png")
    assert "2 updates, approx KL 0.020, clipped 20.0%, action std 0.550, learning rate 2.50e-04" in out
    with pytest.raises(SystemExit):
        ppo_progress.main([str(tmp_path / "missing")])


def test_ppo_progress_gripper_probe_acts_with_a_real_checkpoint(tmp_path):
    from aerobench.train.ppo import PPOConfig, train_ppo

    run = tmp_path / "ppo"
    train_ppo(PPOConfig(setting="TidyHouse", skill="pick", objects=("master_chef_can",), out=str(run), total_steps=64,
                        max_episode_steps=24, update_epochs=1, hidden=(16, 16), progress=False))
    steps = ppo_progress.gripper_probe(run, episodes=2)
    assert 2 <= len(steps) <= 48  # two episodes of at most the run's 24 steps (a failure ends one sooner)
    assert all(0.0 < s["p_close"] < 1.0 and -1.0 <= s["vz"] <= 1.0 and s["distance"] >= 0.0 for s in steps)
    rows = ppo_progress.probe_rows(steps)
    assert sum(r["steps"] for r in rows) == len(steps) and rows[0]["group"].startswith("farther than 10 cm")
    grasped = ppo_progress.probe_rows([{**steps[0], "grasped": True, "lift": 0.02}])
    assert [(r["group"], r["steps"], r["max_lift_m"]) for r in grasped] == [("grasped", 1, 0.02)]


def test_phase_boundaries_from_events_and_gripper_command():
    t = 12
    events = np.zeros((t, len(EVENT_FLAGS)), np.float32)
    events[7:, EVENT_FLAGS.index("is_grasped")] = 1  # grasped after step 7 -> 8 steps elapsed
    events[9:, EVENT_FLAGS.index("is_lifted")] = 1
    action = np.zeros((t, 5), np.float32)
    action[:, -1] = 1.0
    action[5:, -1] = -1.0  # the closing command starts at step 5
    frames = {"events": events, "action": action}
    assert diversity.phase_boundaries(frames, steps=12, success=True, approach_end=4) == [4, 5, 8, 10, 12]
    assert diversity.phase_boundaries(frames, steps=12, success=False, approach_end=None)[-1] is None
    events[:, EVENT_FLAGS.index("is_grasped")] = 0
    assert diversity.phase_boundaries({"events": events, "action": action}, 12, False, 4) == [4, None, None, None, None]


@pytest.mark.parametrize("parse, argv, message", [
    (learning_curves.parse_budget, ["--rounds", "2,1"], "increasing positive integers"),
    (diversity.parse_config, ["--policies", "expert,dagger"], "expert, bc, ppo"),
    (learning_curves.parse_budget, ["--objects", "anvil"], "valid objects"),
    (learning_curves.parse_budget, ["--ppo-recipe", "gpu"], "invalid choice: 'gpu'"),
    (learning_curves.parse_budget, ["--ppo-run", "runs/ppo"], "--bc-summary and --ppo-run go together"),
    (call_warmth.main, ["--gaps", "0,ten", "--no-env"], "comma-separated microseconds"),
])
def test_bad_flags_are_one_line_errors(parse, argv, message, capsys):
    with pytest.raises(SystemExit):
        parse(argv)
    assert message in capsys.readouterr().err


@pytest.fixture(scope="module")
def learning_curves_run(tmp_path_factory):
    """One tiny learning-curves run; its BC and PPO checkpoints also feed the diversity test."""
    out = tmp_path_factory.mktemp("learning_curves")
    args = ["--rounds", "1,2", "--rollouts-per-round", "1", "--bc-steps", "20", "--ppo-steps", "100",
            "--eval-per-object", "1", "--max-steps", "30", "--out", str(out)]
    return out, args, learning_curves.main(args)


@pytest.mark.xdist_group("learning_curves_run")  # its module fixture runs once, on one worker
def test_learning_curves_end_to_end_and_resume(learning_curves_run):
    tmp_path, args, summary = learning_curves_run
    saved = json.loads((tmp_path / "learning_curves.json").read_text())
    assert saved["budget"]["rounds"] == [1, 2] and _is_png(tmp_path / "learning_curves.png")
    assert {"expert", "rounds", "bc", "ppo", "spec", "held_out_seed"} <= set(saved)
    assert [r["rounds"] for r in saved["bc"]] == [1, 2]
    # the expert picks the can in full-length collection episodes; round 2 adds its transitions to round 1's
    assert saved["rounds"][0]["successes"] >= 1
    assert saved["bc"][1]["transitions"] == sum(r["transitions"] for r in saved["rounds"]) > saved["bc"][0]["transitions"] > 0
    for row in saved["bc"]:
        h = row["held_out"]
        assert h["n"] == 1 and 0.0 <= h["success"] <= 1.0 and Path(row["checkpoint"]).is_dir()
    ppo = saved["ppo"]
    assert ppo["interactions"] >= 100 and ppo["episodes"] >= 1  # 30-step training episodes finish
    curve = ppo["curve"]
    assert len(curve["global_step"]) == len(curve["success_moving_average"]) >= 1
    assert all(0.0 <= v <= 1.0 for v in curve["success_moving_average"]) and curve["global_step"] == sorted(curve["global_step"])
    assert saved["expert"]["n"] == 1 and ppo["held_out"]["n"] == 1

    # the same command again reuses every dataset, checkpoint and evaluation: nothing new is run
    records = sorted(tmp_path.glob("eval/*/records.jsonl"))
    before = {p: p.read_text() for p in records}
    again = learning_curves.main(args)
    assert {p: p.read_text() for p in records} == before
    def outcome(row):  # what a rerun must reproduce (timings differ)
        return row["transitions"], row["checkpoint"], row["held_out"]["successes"], row["held_out"]["n"]

    assert [outcome(r) for r in again["bc"]] == [outcome(r) for r in summary["bc"]]
    assert again["ppo"]["curve"] == summary["ppo"]["curve"] and again["ppo"]["train_s"] == summary["ppo"]["train_s"]

    # a data budget adds one BC point on the leading demos (collection order) and reuses everything else
    cap = saved["bc"][1]["transitions"] - 1  # admits round 1's demo, not round 2's
    capped = learning_curves.main(args + ["--transition-budget", str(cap)])
    assert {p: p.read_text() for p in records} == before
    assert [outcome(r) for r in capped["bc"][:2]] == [outcome(r) for r in summary["bc"]]
    row = capped["bc"][2]
    assert row["transition_budget"] == cap and row["transitions"] == saved["bc"][0]["transitions"] and row["demos"] == 1
    assert row["held_out"]["n"] == 1 and Path(row["checkpoint"]).is_dir() and row["checkpoint"] != saved["bc"][1]["checkpoint"]

    # the CPU recipe trains its own PPO run beside the spec's (BC rows and datasets reused)
    cpu = learning_curves.main(args + ["--ppo-recipe", "cpu"])
    assert [outcome(r) for r in cpu["bc"]] == [outcome(r) for r in summary["bc"]]
    assert Path(cpu["ppo"]["checkpoint"]).parent.name.endswith("_cpu") and cpu["ppo"]["held_out"]["n"] == 1
    train = json.loads((Path(cpu["ppo"]["checkpoint"]) / "config.json").read_text())["train"]
    assert (train["reward"], train["num_steps"], train["state_fields"]) == ("dense", 1024, ["finger_position", "finger_velocity"])
    assert (train["lr_decay_start"], train["lr_decay_steps"]) == (0, 0)  # the budget ends before the decay would start
    assert cpu["ppo"]["interactions"] > 100 and cpu["ppo"]["episodes"] >= 1 and cpu["budget"]["ppo_recipe"] == "cpu"


@pytest.mark.xdist_group("learning_curves_run")  # its module fixture runs once, on one worker
def test_learning_curves_figure_from_a_summary_and_a_ppo_run_trained_apart(learning_curves_run, tmp_path, capsys):
    src, _, summary = learning_curves_run
    ppo_run = Path(summary["ppo"]["checkpoint"]).parent
    args = ["--bc-summary", str(src / "learning_curves.json"), "--ppo-run", str(ppo_run), "--out", str(tmp_path)]
    combined = learning_curves.main(args)
    assert _is_png(tmp_path / "learning_curves.png") and (tmp_path / "learning_curves.json").is_file()
    # the expert and BC rows are the summary's; PPO's curve is the run's, evaluated here on the summary's starts
    assert combined["bc"] == json.loads((src / "learning_curves.json").read_text())["bc"]
    assert combined["ppo"]["curve"] == summary["ppo"]["curve"]
    assert combined["ppo"]["held_out"]["n"] == summary["ppo"]["held_out"]["n"] == 1
    assert (tmp_path / "eval" / f"ppo_{ppo_run.name}_e1" / "records.jsonl").is_file()
    assert combined["budget"]["ppo_steps"] == combined["ppo"]["interactions"] == summary["ppo"]["interactions"]
    assert combined["ppo"]["train_config"]["reward"] == "potential" and combined["sources"]["ppo_run"] == str(ppo_run)
    assert combined["ppo"]["train_config"]["lr_decay_steps"] == 0  # the spec recipe: a constant learning rate
    # the training time comes from the run's logged throughput (no bench_done.json for a run trained apart)
    assert 0 < combined["ppo"]["train_s"] < 10 * summary["ppo"]["train_s"] + 60

    other = json.loads((src / "learning_curves.json").read_text())
    other["skill"] = other["budget"]["skill"] = "place"
    (tmp_path / "place.json").write_text(json.dumps(other))
    with pytest.raises(SystemExit, match="pass a PPO run of the same setting, skill and objects"):
        learning_curves.main(["--bc-summary", str(tmp_path / "place.json"), "--ppo-run", str(ppo_run),
                              "--out", str(tmp_path / "x")])
    with pytest.raises(SystemExit, match="holds no checkpoint/config.json"):
        learning_curves.main(["--bc-summary", str(src / "learning_curves.json"), "--ppo-run", str(tmp_path),
                              "--out", str(tmp_path / "x")])


@pytest.mark.xdist_group("learning_curves_run")  # its module fixture runs once, on one worker
def test_diversity_end_to_end(learning_curves_run, tmp_path):
    # training a BC and a PPO checkpoint is the learning-curves bench's shared helpers, tested above; reuse its runs
    trained = learning_curves_run[2]
    summary = diversity.main(["--episodes", "2", "--objects", "master_chef_can", "--max-steps", "300", "--subsets", "20",
                              "--bc-checkpoint", trained["bc"][-1]["checkpoint"],
                              "--ppo-checkpoint", trained["ppo"]["checkpoint"], "--out", str(tmp_path)])
    saved = json.loads((tmp_path / "diversity.json").read_text())
    assert _is_png(tmp_path / "diversity.png") and _is_png(tmp_path / "diversity_efficiency.png")
    assert set(saved["policies"]) == {"expert", "bc", "ppo"}
    assert saved["checkpoints"] == {"expert": None, "bc": trained["bc"][-1]["checkpoint"], "ppo": trained["ppo"]["checkpoint"]}
    for name, m in saved["policies"].items():
        assert {"episodes", "successes", "approach_paths", "coverage_cells", "direction_entropy_bits",
                "mean_path_deviation", "time_to_success_s", "success_lengths_s"} <= set(m), name
        assert m["episodes"] + m["init_failures"] == 2
        for key in diversity.METRICS:  # measured where a policy reached the grasp point twice, else stated absent
            assert _finite_estimate(m[key]) if m["approach_paths"] >= 2 else m[key] is None
    expert = saved["policies"]["expert"]
    # the expert reaches the grasp point of the can on every start: two paths, measured
    assert expert["approach_paths"] == 2 and saved["subset_size"] == 2
    assert expert["coverage_cells"]["mean"] >= 20  # a path from (1, 1) to (0, 0) crosses at least 20 cells
    if expert["successes"]:
        t = expert["time_to_success_s"]
        assert all(math.isfinite(t[p]) and t[p] >= 0 for p in diversity.PHASES)
        assert t["total"] == pytest.approx(np.mean(expert["success_lengths_s"]))
    assert summary["policies"] == saved["policies"]


def test_bc_inputs_bench_trains_and_scores_each_variant_once(tmp_path):
    """One generated demonstration, two variants x one seed, one held-out episode each; a rerun runs nothing new."""
    args = ["--demos", "1", "--steps", "20", "--episodes", "1", "--seeds", "0", "--workers", "1",
            "--variants", "default,no_heading_error", "--out", str(tmp_path)]
    summary = bc_inputs.main(args)
    saved = json.loads((tmp_path / "bc_inputs.json").read_text())
    assert list(saved["variants"]) == ["default", "no_heading_error"] and saved["skill"] == "pick"
    for name, variant in saved["variants"].items():
        (run,) = variant["runs"]
        assert run["held_out"]["n"] == 1 and 0 <= run["held_out"]["successes"] <= 1
        assert run["held_out"]["seen_in_training"]["episodes"] == 0  # data seed 0, evaluation seed 1
        config = json.loads((Path(run["checkpoint"]) / "config.json").read_text())
        assert ("heading_error" in config["model"]["inputs"]["task_fields"]) == (name == "default")
    records = sorted(tmp_path.glob("eval/*/records.jsonl"))
    before = {p: p.read_text() for p in records}
    assert bc_inputs.main(args)["variants"].keys() == summary["variants"].keys()
    assert {p: p.read_text() for p in records} == before
    with pytest.raises(SystemExit):
        bc_inputs.main(["--variants", "telepathy", "--out", str(tmp_path / "x")])


def test_step_cost_prints_every_row_with_a_ratio_to_the_bare_scene(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["step_cost.py", "--steps", "3", "--episodes", "1", "--no-cameras",
                                      "--ppo-windows", "2", "--repeats", "2"])
    # the PPO rows' training is a stand-in here (tests/train/test_ppo.py runs the real one): what is checked is that
    # they take the best of three rounds in turn by default, whatever `--repeats` the rows above use
    ppo_calls, ppo_rates = [], iter([100.0, 90.0, 120.0, 230.0, 110.0, 200.0])
    monkeypatch.setattr(step_cost, "ppo_steps_per_second",
                        lambda k, windows: ppo_calls.append((k, windows)) or next(ppo_rates))
    step_cost.main()
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("(")]
    assert [r.split()[0] for r in rows] == ["(b)", "(c)", "(d)", "(d)", "(d)", "(d)", "(a)"]
    ours, bare, ratio = (float(v.rstrip("x")) for v in rows[0].split()[-3:])  # ManiSkill's own step and physics
    assert ours > bare > 0 and ratio == pytest.approx(ours / bare, rel=0.05)
    for row in rows[1:-1]:  # ms/step, the bare steps and their ratios: measured, positive, consistent
        ours, rest, rest_ratio, replay, replay_ratio, deviation = (float(v.rstrip("x")) for v in row.split()[-6:])
        assert ours > 0 and rest > 0 and rest_ratio == pytest.approx(ours / rest, rel=0.05)
        assert replay > 0 and replay_ratio == pytest.approx(ours / replay, rel=0.05)
        assert deviation <= 1e-5  # the replay followed the row's episode: the same states stepped bare
    assert "expert Pick episodes per minute on one core" in out and "(1/1 successful" in out
    host = out.split("host: a torch add right after a 40 us pause costs ")[1]
    assert float(host.split("x its back-to-back price")[0]) > 0 and "% of calls cold" in host
    assert float(out.split("AeroPick-v1 reset with a new layout: ")[1].split(" ms")[0]) > 0
    assert ppo_calls == [(1, 2), (2, 2)] * 3
    assert "the best of 3 runs in turn: K=1 120.0" in out
    assert "the best of 3 runs in turn: K=2 worker processes 230.0 (1.92x of K=1" in out


def test_step_cost_host_line_reads_the_torch_add_after_the_pause(monkeypatch):
    """The host line is call_warmth's torch add after a 40 us pause, against its back-to-back price."""
    asked = []

    def rows(gaps, n):
        asked.append((gaps, n))
        return {"torch add": (2.0, {40.0: (9.0, 0.875)}), "numpy add": (0.8, {40.0: (0.9, 0.0)})}

    monkeypatch.setattr(step_cost, "gap_rows", rows)
    line = step_cost.host_line(calls=50)
    assert asked == [([40.0], 50)]
    assert "costs 4.5x its back-to-back price, 88% of calls cold" in line


def test_step_cost_ppo_rate_is_the_timed_windows_steps_over_their_time(monkeypatch):
    """Each window logs its own rate over the same steps: the run's rate leaves out the first window (process
    start-up) and is the harmonic mean of the others, steps over time, not the mean of the rates (which would count
    a fast window for more than its time)."""
    import aerobench.train.common as common
    import aerobench.train.ppo as ppo

    configs = []
    monkeypatch.setattr(ppo, "train_ppo", configs.append)
    monkeypatch.setattr(common, "read_scalars", lambda out, tag: [(64, 50.0), (128, 100.0), (192, 300.0)])
    assert step_cost.ppo_steps_per_second(2, 3) == pytest.approx(150.0)
    assert configs[0].num_envs == 2 and configs[0].total_steps == 64 * 2 * 3


def test_step_cost_times_the_ppo_env_counts_in_turn_and_keeps_the_best_of_each(monkeypatch):
    """A load change between two K's runs must reach every K alike: rounds of K = 1, 2, 4 in turn, the best kept."""
    calls, rates = [], iter([100.0, 150.0, 160.0, 80.0, 190.0, 150.0, 90.0, 170.0, 155.0])
    monkeypatch.setattr(step_cost, "ppo_steps_per_second", lambda k, windows: calls.append((k, windows)) or next(rates))
    assert step_cost.ppo_rates([1, 2, 4], windows=3, repeats=3) == {1: 100.0, 2: 190.0, 4: 160.0}
    assert calls == [(1, 3), (2, 3), (4, 3)] * 3


def test_scale_prints_the_rate_of_one_and_two_ray_workers(monkeypatch, capsys):
    """`bench/scale.py`'s rates, table and ratio, on a generation that reports progress on a fake clock: 5 s to start,
    then 10 s per episode and shard. (`generate_on_ray` itself, on a real local Ray runtime, is checked by
    tests/rollout/test_ray.py; running it here twice more cost this test 139 s of a `make test`.)"""
    import scale

    clock = {"t": 0.0}
    calls = []

    def generate(spec, out, keep, shards, on_progress):
        calls.append((spec.episodes, keep, shards, spec.record_cameras))
        began = clock["t"]
        clock["t"] += 5.0  # the workers' start-up
        done = 0
        while done < spec.episodes:
            clock["t"] += 10.0  # each shard finishes one episode
            for _ in range(min(shards, spec.episodes - done)):
                done += 1
                on_progress(done, done, clock["t"] - began)

    monkeypatch.setattr(scale, "generate_on_ray", generate)
    monkeypatch.setattr(scale, "connect", lambda address, num_cpus: calls.append(("connect", address, num_cpus)))
    monkeypatch.setattr(scale, "time", SimpleNamespace(monotonic=lambda: clock["t"]))
    monkeypatch.setattr(sys, "argv", ["scale.py", "--episodes", "4", "--workers", "2"])
    scale.main()
    out = capsys.readouterr().out
    assert calls == [("connect", None, 2), (4, "all", 1, False), (4, "all", 2, False)]
    rows = {int(line.split()[0]): [float(v) for v in line.split()[1:]] for line in out.splitlines()
            if line.strip()[:1].isdigit()}
    # one shard: 4 episodes in 45 s end to end (5.3/min); 3 more after the first at 15 s, in 30 s (6/min)
    # two shards: 4 in 25 s (9.6/min); 3 more after the first at 15 s, the last at 25 s (18/min)
    assert rows == {1: [5.3, 6.0], 2: [9.6, 18.0]}
    assert "ratio 2 / 1 workers: end-to-end 1.80x, steady 3.00x" in out


@pytest.mark.skipif(ray_tracing_device() is not None, reason="this machine has a ray-tracing GPU (the row is measured)")
def test_ray_tracing_bench_measures_rasterized_and_says_why_not_ray_traced(tmp_path):
    r = subprocess.run([sys.executable, str(BENCH / "ray_tracing.py"), "--steps", "1"], capture_output=True, text=True,
                       timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    rows = dict(line.split(None, 1) for line in r.stdout.splitlines() if line.strip())
    assert float(rows["rasterized"].split()[0]) > 0
    assert rows["ray-traced"].startswith("not measured: ray-traced rendering needs a GPU with Vulkan ray tracing")


def test_release_aliasing_counts_the_still_closed_frames_before_a_release(tmp_path):
    import pandas as pd

    from aerobench.envs.observations import TASK_STATE_FIELDS, field_slices

    width = sum(n for _, n in TASK_STATE_FIELDS)
    still = np.zeros(width)
    moving = [still + 0.01 * (i + 1) for i in range(3)]
    # episode 0: three moving closed frames, then four still closed frames, then the release (still): 4 aliased
    # episode 1: the state moves up to the release: 0 aliased; episode 2: never releases: not counted
    episodes = {0: (moving + [still] * 5, [-1] * 7 + [1]), 1: (moving + [still + 0.5], [-1, -1, -1, 1]),
                2: (moving, [-1, -1, -1])}
    rows = [{"episode_index": e, "observation.environment_state": s.astype(np.float32), "action": np.array([0, 0, 0, 0, g], np.float32)}
            for e, (states, grips) in episodes.items() for s, g in zip(states, grips)]
    (tmp_path / "data" / "chunk-000").mkdir(parents=True)
    pd.DataFrame(rows).to_parquet(tmp_path / "data" / "chunk-000" / "file-000.parquet")
    (tmp_path / "meta").mkdir()
    (tmp_path / "meta" / "aerobench_episodes.jsonl").write_text(
        "".join(json.dumps({"dataset_episode_index": e, "object": o}) + "\n" for e, o in ((0, "can"), (1, "box"), (2, "can"))))
    table = release_aliasing.main([str(tmp_path), "--json", str(tmp_path / "out.json")])
    assert table == {"box": {"episodes": 1, "median": 0.0, "mean": 0.0, "max": 0},
                     "can": {"episodes": 1, "median": 4.0, "mean": 4.0, "max": 4}}
    assert json.loads((tmp_path / "out.json").read_text())["objects"] == table
    assert field_slices(TASK_STATE_FIELDS)["skill"].stop == release_aliasing.AFTER_SKILL
    with pytest.raises(SystemExit):
        release_aliasing.main([str(tmp_path / "missing")])


def test_label_predictability_finds_the_reading_a_label_depends_on():
    """Synthetic frames: the flight command is a function of xi only, the gripper of the finger positions only; the
    input sets with that reading explain it, the BC's task-state fields alone do not."""
    rng = np.random.default_rng(0)
    t = 1200
    width = {k: max(s.stop for s in layout.values()) for k, layout in label_predictability.LAYOUT.items()}
    frames = {"task": rng.normal(size=(t, width["task"])).astype(np.float32),
              "proprio": rng.normal(size=(t, width["proprio"])).astype(np.float32),
              "xi": rng.normal(size=(t, 3)).astype(np.float32), "phase": np.where(np.arange(t) % 2 == 0, 3, 2),
              "episode": np.arange(t) // 200, "action": np.zeros((t, 8), np.float32)}
    frames["action"][:, :3] = np.tanh(frames["xi"])
    left_finger = label_predictability.LAYOUT["proprio"]["finger_position"].start
    frames["action"][:, -1] = np.sign(frames["proprio"][:, left_finger])
    results = label_predictability.measure(frames, held_out=2, steps=600, phase_names={2: "pinch", 3: "drive"})
    assert set(results) == set(label_predictability.INPUT_SETS)
    assert results["bc+velocity_integral"]["drive"]["flight_r2"] > 0.8
    assert results["bc"]["drive"]["flight_r2"] < 0.3
    assert results["bc+finger_position"]["pinch"]["gripper_wrong"] < 0.3
    assert results["bc"]["pinch"]["gripper_wrong"] > 0.4  # a coin flip: the BC's fields say nothing of the fingers
    assert results["bc+all"]["drive"]["frames"] == 200  # two held-out episodes of 200 frames, half of them drive
    with pytest.raises(ValueError, match="--held-out"):
        label_predictability.measure(frames, held_out=6, steps=1, phase_names={2: "pinch"})


def _pick_frame(height: float, xy: float, speed: float, vz: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    from aerobench.envs.observations import TASK_STATE_FIELDS, field_slices

    sl = field_slices(TASK_STATE_FIELDS)
    state = np.zeros(sum(n for _, n in TASK_STATE_FIELDS), np.float32)
    state[sl["goal_pos"]] = [xy, 0.0, -height]
    state[sl["linear_velocity"]] = [0.0, 0.0, -speed]
    return state, np.array([0, 0, vz, 0, 1], np.float32)


def test_descent_onset_finds_the_switch_the_still_frames_and_a_parked_episode(tmp_path):
    import pandas as pd

    from aerobench.expert.pick import PickPhase as P

    # episode 0 (box): approach, two still frames above it, the switch at 0.20 m / 0.03 m/s / 4 mm, a descent
    # episode 1 (can): waits still at 0.18 m (three frames, vz 0), then switches while still
    episodes = {0: [(0.5, 0.3, 0.4, P.APPROACH), (0.21, 0.004, 0.005, P.ALIGN), (0.21, 0.004, 0.002, P.ALIGN),
                    (0.20, 0.004, 0.03, P.DESCEND), (0.10, 0.002, 0.15, P.DESCEND)],
                1: [(0.18, 0.003, 0.001, P.ALIGN)] * 3 + [(0.18, 0.001, 0.001, P.DESCEND)]}
    rows = []
    for e, frames in episodes.items():
        for height, xy, speed, phase in frames:
            state, action = _pick_frame(height, xy, speed)
            rows.append({"episode_index": e, "observation.environment_state": state, "action": action,
                         "annotation.phase": int(phase)})
    (tmp_path / "data" / "chunk-000").mkdir(parents=True)
    pd.DataFrame(rows).to_parquet(tmp_path / "data" / "chunk-000" / "file-000.parquet")
    (tmp_path / "meta").mkdir()
    (tmp_path / "meta" / "aerobench_episodes.jsonl").write_text(
        "".join(json.dumps({"dataset_episode_index": e, "object": o}) + "\n" for e, o in ((0, "box"), (1, "can"))))
    frames, objects = descent_onset.read_frames(tmp_path)
    table = descent_onset.expert_switches(frames, objects, still=0.01)
    assert table["box"] == {"switches": 1, "height_m": 0.2, "speed_mps": 0.03, "xy_m": 0.004, "frames_above": 2,
                            "still_frames_above": 2}
    assert table["can"]["switches"] == 1 and table["can"]["still_frames_above"] == 3
    # a policy episode that ends still 0.18 m above the grasp point is parked; the can's waiting frames lie near it
    still_end = np.stack([_pick_frame(0.18, 0.001, 0.0)[0]] * 10)
    stop = descent_onset.parked(still_end, window=5, still=0.01)
    assert stop == {"height_m": 0.18, "xy_m": 0.001}
    near = descent_onset.expert_labels_near(descent_onset.labelled_frames(frames, objects), stop, "box", still=0.01)
    assert near["same_class"] == {"frames": 0, "mean_vz_command": None}
    assert near["other_classes"]["frames"] == 4
    # moving at the end, or down at the grasp point: not parked
    assert descent_onset.parked(np.stack([_pick_frame(0.18, 0.001, 0.05)[0]] * 10), window=5, still=0.01) is None
    assert descent_onset.parked(np.stack([_pick_frame(0.01, 0.001, 0.0)[0]] * 10), window=5, still=0.01) is None
    with pytest.raises(SystemExit):
        descent_onset.main([str(tmp_path / "missing")])


def test_step_floor_prints_each_variant_and_the_floor_against_the_bare_step(capsys):
    rows = step_floor.main(["--envs", "AeroFly-v1", "--windows", "2", "--steps", "2"])
    row = rows["AeroFly-v1"]
    assert list(row) == [step_floor.BARE, step_floor.READS, step_floor.MANISKILL, step_floor.CONTROLLER,
                         step_floor.WHOLE]
    assert all(ms > 0 for ms in row.values())
    assert row[step_floor.WHOLE] > row[step_floor.BARE]  # observation, evaluation, controller: several times bare
    out = capsys.readouterr().out
    floor_line = next(line for line in out.splitlines() if line.strip().startswith(step_floor.FLOOR))
    ms, ratio = float(floor_line.split()[-3]), float(floor_line.split()[-1].rstrip("x"))
    floor = step_floor.floor_ms(row)
    assert ms == pytest.approx(floor, abs=1e-3) and ratio == pytest.approx(floor / row[step_floor.BARE], abs=0.01)


def test_call_warmth_times_each_call_after_each_gap_and_the_hook_both_ways(capsys):
    result = call_warmth.main(["--gaps", "0,30", "--calls", "40"])
    assert list(result["gaps"]) == ["torch add", "numpy add"]
    for hot, row in result["gaps"].values():
        assert hot > 0 and list(row) == [0.0, 30.0]
        assert all(us > 0 and 0.0 <= cold <= 1.0 for us, cold in row.values())
    hook = result["hook"]
    assert list(hook) == ["hook, back to back", "hook, after a physics step", "physics step, after the hook",
                          "physics step, efforts held"]
    assert all(us > 0 for us in hook.values())
    out = capsys.readouterr().out
    assert out.count(" us: ") == 4  # one cell per gap in each add's row
    ratio = float(out.strip().splitlines()[-1].split()[-1].rstrip("x"))
    assert ratio == pytest.approx(hook["hook, after a physics step"] / hook["hook, back to back"], abs=0.01)


def test_busy_wait_waits_at_least_the_gap():
    import time
    t0 = time.perf_counter()
    call_warmth.busy_wait(2000)
    assert time.perf_counter() - t0 >= 2e-3
