"""The first GPU hour, prepared: checks and measures aerobench on a CUDA GPU in at most 10 minutes and writes its
tables into docs/gpu.md (between its `gpu_check` markers).

    python bench/gpu_check.py [--budget-s 570] [--only tests,starts,state,expert,runner,cameras] [--eager]
                              [--doc docs/gpu.md] [--json FILE] [--no-write]

Jobs, in this order, each in its own process (a crash or a hang costs that job only; every job keeps its cap, the
run has a deadline, and what does not fit is reported as not run):
  tests    `pytest -m gpu tests`: batched hover, skill envs, fixtures, PPO and batched starts on physx_cuda
  starts   batched physx_cuda resets draw the starts of one-env physx_cuda resets with the same seeds (docs/gpu.md,
           "Seeds and starts"); the one-env GPU starts are also compared with the committed CPU starts
           (tests/envs/episode_starts.json): the draws are the same, the float math after them may differ slightly
  state    AeroFly-v1 and AeroPick-v1 control steps per second at N = 1, 16, 256, 1024, state only, hovering, and the
           GPU memory in use; a row predicted not to fit in the time left is skipped and says so
  expert   the privileged expert on AeroPick-v1 (TidyHouse), 64 batched envs, under PGS and under TGS
           (AEROBENCH_PHYSX_SOLVER, docs/physics.md): successes and which starts only one solver solves
  runner   the rollout runner (what `aerobench eval` and `generate` run) with the expert on AeroPick-v1, 32 envs,
           64 episodes: every episode its own scene (two reconfigured batches) against two episodes per scene (one
           batch, each env reset alone between its episodes: `--episodes-per-scene 2`); episodes per minute
  cameras  as `state` with the three 128x128 RGB-D cameras (obs_mode="rgbd"), N = 1, 16, 64
`starts` and `expert` run eager (`AEROBENCH_COMPILE=0`: the same numbers, no compile time); `state` and `cameras`
run the compiled kernels users run unless `--eager`. On a machine without CUDA it prints one line and exits 0.
"""

from __future__ import annotations

import argparse
import datetime
import gc
import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # a machine where aerobench is not installed runs it from the checkout
    sys.path.insert(0, str(ROOT))

NEEDS_GPU = "bench/gpu_check.py needs a CUDA GPU (physx_cuda); torch sees none on this machine, so nothing was checked"
ROW = "GPU_CHECK_ROW "  # a worker's result lines on stdout start with this
JOBS = ("tests", "starts", "state", "expert", "runner", "cameras")
CAP_S = {"tests": 140, "starts": 65, "state": 140, "expert": 95, "runner": 60, "cameras": 70}  # each job keeps this
MIN_JOB_S = 20
STATE_SIZES = (1, 16, 256, 1024)
CAMERA_SIZES = (1, 16, 64)
THROUGHPUT_ENVS = (("AeroFly-v1", {}), ("AeroPick-v1", {"setting": "TidyHouse"}))
WARMUP_STEPS = 5
EXPERT_ENVS = 64
EXPERT_SEED = 31  # episode seeds EXPERT_SEED * SEED_STRIDE + i, objects in turn
RUNNER_ENVS = 32
RUNNER_SEED = 32
GPU_TOLERANCE = 1e-4  # m, rad: GPU poses come back through the sub-scene offsets in float32
FIXTURE = ROOT / "tests" / "envs" / "episode_starts.json"


def start_cases(seed_stride: int) -> list[tuple[str, dict, list[tuple[int, str | None]]]]:
    """(env id, kwargs, [(episode seed, object)]) per batch: the committed CPU starts' seeds first, then others;
    a pick, the fridge chain (enclosed pick, door cone, nav, place goal) and the close skill (fixture and opening)."""
    from aerobench.envs.tasks import get_setting

    nine = get_setting("TidyHouse").objects
    return [
        ("AeroPick-v1", {"setting": "TidyHouse"},
         [(20 * seed_stride + 3, "bowl"), (7, "bowl"), *[(20 * seed_stride + 200 + i, nine[i % 9]) for i in range(6)]]),
        ("AeroSequential-v1", {"setting": "LongHorizonRearrangement", "chain": "open_pick_nav_place"},
         [(22 * seed_stride + 10, "cracker_box"), (22 * seed_stride + 14, nine[14 % 9]),
          (22 * seed_stride + 43, nine[43 % 9]), (5, "bowl")]),
        ("AeroClose-v1", {"setting": "PrepareGroceries"}, [(9, None), (1, None), (2, None), (3, None)]),
    ]


# ----------------------------------------------------------------------------------------------------------------------
# Workers: each yields rows (dicts); run with --worker they print them as they come
# ----------------------------------------------------------------------------------------------------------------------
def _sync() -> None:
    import torch

    if torch.cuda.is_available():
        torch.cuda.synchronize()


def device_memory_gib() -> float:
    """GPU memory in use on the device (PhysX, the renderer and torch together), GiB; nan without CUDA."""
    import torch

    if not torch.cuda.is_available():
        return float("nan")
    free, total = torch.cuda.mem_get_info()
    return (total - free) / 2**30


def _error(exc: Exception) -> str:
    """An exception as one table-safe line."""
    return " ".join(f"{type(exc).__name__}: {exc}".split()).replace("|", "/")[:300]


def _reset_options(obj: str | list[str] | None) -> dict:
    options: dict = {"reconfigure": True}
    if obj is not None:
        options["objects"] = obj if isinstance(obj, list) else [obj]
    return options


def starts_rows(backend: str, cases=None, tolerance: float = GPU_TOLERANCE) -> Iterator[dict]:
    """Per case: a batch reset with all its seeds, then one env reset with each seed; how many rows agree, and how many
    one-env starts agree with the committed CPU starts."""
    import gymnasium as gym

    import aerobench.envs  # noqa: F401
    from aerobench.envs.checker import start_differences, start_key, start_record
    from aerobench.rollout.runner import SEED_STRIDE

    fixture = json.loads(FIXTURE.read_text()) if FIXTURE.exists() else {}
    for env_id, kwargs, draws in cases or start_cases(SEED_STRIDE):
        seeds, objects = [s for s, _ in draws], [o for _, o in draws]
        n = len(draws)
        row = {"env": " ".join([env_id, *(f"{k}={v}" for k, v in sorted(kwargs.items()))]), "n": n}
        t0 = time.monotonic()
        try:
            env = gym.make(env_id, obs_mode="state_dict", num_envs=n, sim_backend=backend, **kwargs)
            try:
                env.reset(seed=seeds if n > 1 else seeds[0],
                          options=_reset_options(objects if objects[0] is not None else None))
                batched = [start_record(env, i) for i in range(n)]
            finally:
                env.close()
            env = gym.make(env_id, obs_mode="state_dict", num_envs=1, sim_backend=backend, **kwargs)
            equal, worst, cpu_equal, cpu_of, cpu_worst = 0, "", 0, 0, ""
            try:
                for i, (seed, obj) in enumerate(draws):
                    env.reset(seed=seed, options=_reset_options(obj))
                    one = start_record(env)
                    problems = start_differences(batched[i], one, tolerance)
                    equal += not problems
                    worst = worst or (f"seed {seed}: {problems[0]}" if problems else "")
                    recorded = fixture.get(start_key(env_id, kwargs, obj, seed))
                    if recorded is not None:
                        problems = start_differences(recorded, one, tolerance)
                        cpu_of += 1
                        cpu_equal += not problems
                        cpu_worst = cpu_worst or (f"seed {seed}: {problems[0]}" if problems else "")
            finally:
                env.close()
            row.update(equal=equal, worst=worst[:300], cpu_equal=cpu_equal, cpu_of=cpu_of, cpu_worst=cpu_worst[:300])
        except Exception as exc:  # noqa: BLE001 - a broken case is a result; the other cases still run
            row["error"] = _error(exc)
        row["seconds"] = round(time.monotonic() - t0, 1)
        yield row


def _predicted_s(done: list[tuple[int, float]], n: int) -> float:
    """A row's time at `n` envs from the rows before it: a fixed part and a part per env (one row: all fixed)."""
    if not done:
        return 0.0
    if len(done) == 1:
        return done[0][1]
    (n0, t0), (n1, t1) = done[-2], done[-1]
    per_env = max(t1 - t0, 0.0) / max(n1 - n0, 1)
    return t1 + per_env * (n - n1)


def throughput_rows(backend: str, obs_mode: str, sizes, steps: int, deadline: float,
                    envs=THROUGHPUT_ENVS) -> Iterator[dict]:
    """Per env id and N: make + reset + warm-up seconds (compilation included), ms per control step hovering, env
    steps per second and the device memory in use after the row, above what the worker held before its first env."""
    import gymnasium as gym
    import torch

    import aerobench.envs  # noqa: F401

    baseline = device_memory_gib()
    for env_id, kwargs in envs:
        done: list[tuple[int, float]] = []
        for n in sizes:
            row = {"env": env_id, "obs": obs_mode, "n": n}
            left, predicted = deadline - time.time(), _predicted_s(done, n)
            if predicted > left:
                row["skipped"] = f"predicted {predicted:.0f} s, {max(left, 0):.0f} s left"
                yield row
                continue
            t0 = time.monotonic()
            env = None
            try:
                env = gym.make(env_id, obs_mode=obs_mode, num_envs=n, sim_backend=backend, **kwargs)
                base = env.unwrapped
                env.reset(seed=list(range(n)) if n > 1 else 0)
                action = torch.zeros(n, base.platform.action_dim, device=base.device)
                for _ in range(WARMUP_STEPS):
                    env.step(action)
                _sync()
                row["setup_s"] = round(time.monotonic() - t0, 1)
                t1 = time.perf_counter()
                for _ in range(steps):
                    env.step(action)
                _sync()
                seconds = time.perf_counter() - t1
                row.update(ms_per_step=round(seconds / steps * 1e3, 2), env_steps_per_s=round(n * steps / seconds),
                           memory_gib=round(device_memory_gib() - baseline, 2))
            except Exception as exc:  # noqa: BLE001 - out of memory at a large N is a result
                row["error"] = _error(exc)
            finally:
                if env is not None:
                    env.close()
                del env
                gc.collect()
                if torch.cuda.is_available():
                    torch.cuda.empty_cache()
            done.append((n, time.monotonic() - t0))
            yield row


def expert_row(backend: str, num_envs: int, deadline: float, max_steps: int | None = None) -> dict:
    """The expert on AeroPick-v1 (TidyHouse), `num_envs` batched starts, run until every feasible episode ended:
    successes (and which rows), the solver it ran under, control steps and env steps per second."""
    import gymnasium as gym
    import torch

    import aerobench.envs  # noqa: F401
    from aerobench.envs.base_env import default_physx_solver
    from aerobench.envs.tasks import get_setting
    from aerobench.policies import make_policy
    from aerobench.rollout.runner import SEED_STRIDE, episode_limit

    objects = get_setting("TidyHouse").objects
    seeds = [EXPERT_SEED * SEED_STRIDE + i for i in range(num_envs)]
    row: dict = {"solver": default_physx_solver(), "envs": num_envs, "seeds": f"{seeds[0]}..{seeds[-1]}"}
    t0 = time.monotonic()
    env = gym.make("AeroPick-v1", obs_mode="state_dict", num_envs=num_envs, sim_backend=backend, setting="TidyHouse")
    try:
        base = env.unwrapped
        obs, info = env.reset(seed=seeds if num_envs > 1 else seeds[0],
                              options=_reset_options([objects[i % len(objects)] for i in range(num_envs)]))
        policy = make_policy("expert", base)
        policy.reset(torch.arange(num_envs, device=base.device))
        infeasible = info["init_failed"].cpu().clone()
        if hasattr(policy, "infeasible"):
            infeasible |= policy.infeasible().cpu()
        active, success = ~infeasible, torch.zeros(num_envs, dtype=torch.bool)
        limit = min(episode_limit(env), max_steps or episode_limit(env))
        row["setup_s"] = round(time.monotonic() - t0, 1)
        t1, steps = time.perf_counter(), 0
        while bool(active.any()) and steps < limit and time.time() < deadline:
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            ended = (terminated | truncated).cpu() & active
            success |= ended & info["success"].cpu()
            active &= ~ended
            steps += 1
        seconds = time.perf_counter() - t1
    finally:
        env.close()
    row.update(feasible=int((~infeasible).sum()), successes=int(success.sum()), unfinished=int(active.sum()),
               steps=steps, run_s=round(seconds, 1), env_steps_per_s=round(num_envs * steps / max(seconds, 1e-9)),
               success_rows=[bool(v) for v in success], feasible_rows=[bool(not v) for v in infeasible])
    return row


class _Stop(Exception):
    pass


def runner_rows(backend: str, num_envs: int, deadline: float, per_scene: tuple[int, ...] = (1, 2),
                max_steps: int | None = None) -> Iterator[dict]:
    """The rollout runner with the expert on AeroPick-v1 (TidyHouse, state only), `2 * num_envs` episodes, once per
    `per_scene` value: episodes, successes, seconds, episodes per minute (env build included: each run builds its
    own)."""
    from aerobench.rollout.episode import EpisodeList
    from aerobench.rollout.runner import RolloutRunner, RolloutSpec

    for g in per_scene:
        row: dict = {"envs": num_envs, "episodes_per_scene": g, "episodes": 0, "successes": 0}
        spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=2 * num_envs, num_envs=num_envs,
                           seed=RUNNER_SEED, sim_backend=backend, record_cameras=False, episodes_per_scene=g,
                           max_steps=max_steps)

        def count(episode, progress, row=row):
            row["episodes"], row["successes"] = progress.done, progress.successes
            if time.time() > deadline:
                raise _Stop

        t0 = time.monotonic()
        try:
            RolloutRunner(spec, EpisodeList(), on_episode=count).run()
        except _Stop:
            row["stopped"] = True
        except Exception as exc:  # noqa: BLE001 - the row says what failed, the other rows still run
            row["error"] = _error(exc)
        seconds = time.monotonic() - t0
        row.update(seconds=round(seconds, 1), episodes_per_min=round(60 * row["episodes"] / max(seconds, 1e-9), 1))
        yield row
        if time.time() > deadline:
            return


def run_worker(args) -> int:
    if args.worker == "starts":
        rows = starts_rows(args.backend)
    elif args.worker == "throughput":
        sizes = [int(v) for v in args.sizes.split(",") if v]
        rows = throughput_rows(args.backend, args.obs, sizes, args.steps, args.deadline)
    elif args.worker == "runner":
        rows = runner_rows(args.backend, args.envs, args.deadline)
    else:
        rows = iter([expert_row(args.backend, args.envs, args.deadline)])
    for row in rows:
        print(ROW + json.dumps(row), flush=True)
    return 0


# ----------------------------------------------------------------------------------------------------------------------
# The driver: jobs in subprocesses, their rows rendered as markdown into docs/gpu.md
# ----------------------------------------------------------------------------------------------------------------------
def run_job(cmd: list[str], timeout: float, env: dict) -> dict:
    """Run `cmd` in its own process group; kill the group at `timeout`. Returns rc (None: killed), output, rows."""
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        out, err = proc.communicate(timeout=max(timeout, 1))
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # the worker and anything it started (compile workers)
        except ProcessLookupError:
            pass
        out, err = proc.communicate()
        rc = None
    rows = [json.loads(line[len(ROW):]) for line in out.splitlines() if line.startswith(ROW)]
    return {"rc": rc, "stdout": out, "stderr": err, "rows": rows, "seconds": round(time.monotonic() - t0, 1)}


def job_env(compile_on: bool, **extra: str) -> dict:
    env = dict(os.environ, PYTHONUNBUFFERED="1", MS_SKIP_ASSET_DOWNLOAD_PROMPT="1", HF_HUB_OFFLINE="1", **extra)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    if not compile_on:
        env["AEROBENCH_COMPILE"] = "0"
    return env


def _tail(text: str, lines: int = 6) -> str:
    return "\n".join(text.strip().splitlines()[-lines:])


def summarize_pytest(result: dict) -> dict:
    """pytest's final counts and the ids of what failed, errored at collection or errored in a test."""
    out = result["stdout"]
    counts = re.findall(r"(\d+) (passed|failed|skipped|deselected|errors?|xfailed|xpassed)", _tail(out, 1))
    failed = re.findall(r"^FAILED (\S+)", out, re.M)
    errors = re.findall(r"^ERROR (\S+)", out, re.M)
    return {"counts": ", ".join(f"{n} {what}" for n, what in counts) or "no summary line", "failed": failed,
            "errors": errors}


def _stamp(context: dict, seconds: float) -> str:
    return f"_{context['date']}, {context['device']}, {context['commit']}; {seconds:.0f} s._"


def render_tests(result: dict, context: dict) -> str:
    s = summarize_pytest(result)
    lines = [_stamp(context, result["seconds"]), "", f"`pytest -m gpu tests`: {s['counts']}"
             + (" (stopped at its time cap)" if result["rc"] is None else "")]
    for label, ids in (("failed", s["failed"]), ("errors (a module that could not be imported is one)", s["errors"])):
        if ids:
            lines += ["", f"{label}:", *[f"- `{i}`" for i in ids[:12]]]
    return "\n".join(lines)


def render_starts(result: dict, context: dict) -> str:
    lines = [_stamp(context, result["seconds"]), "",
             "| env | N | batch row = one env (same seed) | one env on GPU = committed CPU start | first difference |",
             "| --- | ---: | ---: | ---: | --- |"]
    for r in result["rows"]:
        if "error" in r:
            lines.append(f"| {r['env']} | {r['n']} | error | | {r['error']} |")
            continue
        first = r["worst"] or r["cpu_worst"]
        lines.append(f"| {r['env']} | {r['n']} | {r['equal']}/{r['n']} | {r['cpu_equal']}/{r['cpu_of']} | "
                     f"{first.replace('|', '/') or 'none'} |")
    return "\n".join(lines)


def render_throughput(result: dict, context: dict) -> str:
    lines = [_stamp(context, result["seconds"]), "",
             "| env | obs | N | set-up s | ms / control step | env steps / s | GPU memory GiB |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
    for r in result["rows"]:
        head = f"| {r['env']} | {r['obs']} | {r['n']} |"
        if "skipped" in r or "error" in r:
            lines.append(f"{head} {'skipped: ' + r['skipped'] if 'skipped' in r else 'error: ' + r['error']} | | | |")
        else:
            lines.append(f"{head} {r['setup_s']} | {r['ms_per_step']} | {r['env_steps_per_s']} | {r['memory_gib']} |")
    lines += ["", "Set-up: make, reset and 5 warm-up steps (compilation included). Memory: the device's memory in use "
              "after the row, above the worker's own before its first env (PhysX, renderer and torch together)."]
    return "\n".join(lines)


def render_expert(results: list[dict], context: dict) -> str:
    seconds = sum(r["seconds"] for r in results)
    lines = [_stamp(context, seconds), "",
             "| solver | envs | feasible | successes | unfinished | control steps | run s | env steps / s |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    rows = [r for result in results for r in result["rows"]]
    for r in rows:
        lines.append(f"| {r['solver'].upper()} | {r['envs']} | {r['feasible']} | {r['successes']} | {r['unfinished']} "
                     f"| {r['steps']} | {r['run_s']} | {r['env_steps_per_s']} |")
    by_solver = {r["solver"]: r for r in rows}
    if {"pgs", "tgs"} <= by_solver.keys():
        pgs, tgs = by_solver["pgs"]["success_rows"], by_solver["tgs"]["success_rows"]
        only_pgs = sum(a and not b for a, b in zip(pgs, tgs))
        only_tgs = sum(b and not a for a, b in zip(pgs, tgs))
        lines += ["", f"Same {len(pgs)} starts (seeds {rows[0]['seeds']}): {only_pgs} solved only under PGS, "
                  f"{only_tgs} only under TGS."]
    for result in results:
        if not result["rows"]:
            how = "stopped at its time limit" if result["rc"] is None else f"failed (exit {result['rc']})"
            lines += ["", f"The {result.get('solver', '').upper()} run {how}:", "```", _tail(result["stderr"]), "```"]
    return "\n".join(lines)


def render_runner(result: dict, context: dict) -> str:
    lines = [_stamp(context, result["seconds"]), "",
             "| envs | episodes per scene | episodes | successes | seconds | episodes / min | note |",
             "| ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in result["rows"]:
        note = r.get("error") or ("stopped at the job's deadline" if r.get("stopped") else "")
        lines.append(f"| {r['envs']} | {r['episodes_per_scene']} | {r['episodes']} | {r['successes']} | {r['seconds']} "
                     f"| {r['episodes_per_min']} | {note} |")
    return "\n".join(lines)


def marker(job: str, end: bool = False) -> str:
    return f"<!-- {'/' if end else ''}gpu_check:{job} -->"


def write_blocks(text: str, blocks: dict[str, str]) -> str:
    """`text` with each job's block replaced between its markers; a job without markers is appended at the end."""
    for job, body in blocks.items():
        begin, end = marker(job), marker(job, end=True)
        block = f"{begin}\n{body.strip()}\n{end}"
        if begin in text and end in text and text.index(begin) < text.index(end):
            text = text[: text.index(begin)] + block + text[text.index(end) + len(end):]
        else:
            text = text.rstrip("\n") + f"\n\n{block}\n"
    return text


def _context() -> dict:
    import torch

    def git(*cmd: str) -> str:
        try:
            return subprocess.run(["git", *cmd], cwd=ROOT, capture_output=True, text=True, timeout=10).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    commit = git("rev-parse", "--short", "HEAD") or "unknown commit"
    if git("status", "--porcelain", "--untracked-files=no"):
        commit += " with uncommitted changes"
    props = torch.cuda.get_device_properties(0)
    return {"date": datetime.date.today().isoformat(), "commit": commit,
            "device": f"{props.name} ({props.total_memory / 2**30:.0f} GiB), torch {torch.__version__}"}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget-s", type=float, default=570.0, help="the whole run's deadline (default 570)")
    parser.add_argument("--only", default=",".join(JOBS), help=f"jobs to run, comma-separated ({', '.join(JOBS)})")
    parser.add_argument("--eager", action="store_true", help="AEROBENCH_COMPILE=0 for the throughput jobs too")
    parser.add_argument("--doc", type=Path, default=ROOT / "docs" / "gpu.md", help="the markdown file to write into")
    parser.add_argument("--json", type=Path, help="also write every job's rows and output tails to this file")
    parser.add_argument("--no-write", action="store_true", help="print the tables only")
    parser.add_argument("--steps", type=int, default=50, help="timed control steps per state row (cameras: a fifth)")
    parser.add_argument("--state-sizes", default=",".join(map(str, STATE_SIZES)))
    parser.add_argument("--camera-sizes", default=",".join(map(str, CAMERA_SIZES)))
    # a job's own process (the driver starts these)
    parser.add_argument("--worker", choices=("starts", "throughput", "expert", "runner"), help=argparse.SUPPRESS)
    parser.add_argument("--backend", default="physx_cuda", help=argparse.SUPPRESS)
    parser.add_argument("--obs", default="state", help=argparse.SUPPRESS)
    parser.add_argument("--sizes", default="", help=argparse.SUPPRESS)
    parser.add_argument("--envs", type=int, default=EXPERT_ENVS, help=argparse.SUPPRESS)
    parser.add_argument("--deadline", type=float, default=float("inf"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        return run_worker(args)

    import torch

    if not torch.cuda.is_available():
        print(NEEDS_GPU)
        return 0
    jobs = [j.strip() for j in args.only.split(",") if j.strip()]
    unknown = sorted(set(jobs) - set(JOBS))
    if unknown:
        parser.error(f"unknown job(s) {', '.join(unknown)}; jobs: {', '.join(JOBS)}")
    jobs = [j for j in JOBS if j in jobs]
    context = _context()
    print(f"gpu_check on {context['device']}, {context['commit']}, budget {args.budget_s:.0f} s", flush=True)
    start = time.monotonic()
    me = [sys.executable, str(Path(__file__).resolve()), "--backend", args.backend]
    blocks: dict[str, str] = {}
    raw: dict[str, object] = {"context": context}
    for k, job in enumerate(jobs):
        reserved = sum(CAP_S[j] for j in jobs[k + 1:])  # every later job keeps its cap
        timeout = args.budget_s - (time.monotonic() - start) - reserved
        if timeout < MIN_JOB_S:
            blocks[job] = f"{_stamp(context, 0)}\n\nNot run: {max(timeout, 0):.0f} s were left for it."
            print(f"\n## {job}\n{blocks[job]}", flush=True)
            continue
        deadline = time.time() + timeout - 10  # a worker stops starting rows 10 s before its job is killed
        if job == "tests":
            result = run_job([sys.executable, "-m", "pytest", "-q", "-m", "gpu", "-p", "no:cacheprovider",
                              "--continue-on-collection-errors", "tests"], timeout, job_env(compile_on=False))
            blocks[job], results = render_tests(result, context), [result]
        elif job == "starts":
            result = run_job([*me, "--worker", "starts"], timeout, job_env(compile_on=False))
            blocks[job], results = render_starts(result, context), [result]
        elif job == "runner":
            result = run_job([*me, "--worker", "runner", "--envs", str(RUNNER_ENVS), "--deadline", str(deadline)],
                             timeout, job_env(compile_on=False))
            blocks[job], results = render_runner(result, context), [result]
        elif job in ("state", "cameras"):
            obs, sizes = ("state", args.state_sizes) if job == "state" else ("rgbd", args.camera_sizes)
            steps = args.steps if job == "state" else max(args.steps // 5, 5)
            result = run_job([*me, "--worker", "throughput", "--obs", obs, "--sizes", sizes, "--steps", str(steps),
                              "--deadline", str(deadline)], timeout, job_env(compile_on=not args.eager))
            blocks[job], results = render_throughput(result, context), [result]
        else:  # expert: PGS, then TGS with what is left
            results = []
            for solver in ("pgs", "tgs"):
                left = timeout - sum(r["seconds"] for r in results)
                if left < MIN_JOB_S:
                    break
                result = run_job([*me, "--worker", "expert", "--deadline", str(time.time() + left - 10)], left,
                                 job_env(compile_on=False, AEROBENCH_PHYSX_SOLVER=solver))
                results.append({**result, "solver": solver})
            blocks[job] = render_expert(results, context)
        for result in results if job != "expert" else []:  # the expert's table says which of its runs failed
            if result["rc"] is None:
                blocks[job] += f"\n\nStopped at its {timeout:.0f} s limit."
            elif result["rc"] != 0 and not result["rows"] and job != "tests":
                blocks[job] += f"\n\nExit {result['rc']}:\n```\n{_tail(result['stderr'])}\n```"
        raw[job] = [{key: value for key, value in r.items() if key not in ("stdout", "stderr")}
                    | {"stderr_tail": _tail(r["stderr"], 20)} for r in results]
        print(f"\n## {job}\n{blocks[job]}", flush=True)
    print(f"\ngpu_check took {time.monotonic() - start:.0f} s", flush=True)
    if args.json:
        args.json.write_text(json.dumps(raw, indent=1) + "\n")
    if not args.no_write:
        source = args.doc if args.doc.exists() else ROOT / "docs" / "gpu.md"  # e.g. --doc into an output folder
        args.doc.write_text(write_blocks(source.read_text(), blocks))
        print(f"wrote {len(blocks)} table(s) into {args.doc}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
