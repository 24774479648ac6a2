"""Shards of a rollout plan as Ray tasks: `aerobench generate --ray` and `aerobench eval --ray`.

Ray is the engine (scheduling, worker processes, retries, the object store); aerobench adds only what is its own:
which shards exist and where each writes. Every shard is one Ray task (one CPU) that runs the ordinary one-process
code path for its `--shard i/k` into a crash-safe sink in a folder all workers share; a task whose worker dies
(`kill -9`, a lost node) is retried by Ray (`max_retries`) and the retry skips what its sink already committed, so
no finished episode is lost or written twice. The driver shows one progress bar fed by a small actor the tasks
report to, then merges the shards.

`connect(None)` starts a local Ray runtime with the machine's cores; `connect("HOST:PORT")` (or "auto") joins a
cluster started with `ray start --head`. A physx_cuda shard is one env batch on one GPU: its task asks Ray for that GPU
(Ray sets the worker's CUDA_VISIBLE_DEVICES), and a run has one shard per GPU the cluster offers.
"""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Callable, Sequence
from typing import Any

LOCAL = "local"  # `--ray` with no address
TASK_RETRIES = 3  # Ray resubmits a shard whose worker died this often
FORWARDED_ENV_PREFIXES = ("AEROBENCH_", "HF_", "MS_", "XDG_CACHE_HOME")  # the caller's settings reach every worker


def _check_reachable(address: str) -> None:
    host, _, port = address.rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"--ray {address}: give HOST:PORT of a Ray head (e.g. 127.0.0.1:6379), 'auto', or no address "
                         f"for a local runtime")
    try:
        socket.create_connection((host, int(port)), timeout=3).close()
    except OSError:
        raise ValueError(f"no Ray cluster at {address}: start one there with `ray start --head --port {port}`, or pass "
                         f"--ray without an address for a local runtime") from None


def connect(address: str | None = None, num_cpus: int | None = None) -> None:
    """Start (address None / "local") or join a Ray runtime (`default_shards` says how many shards it holds). A
    one-line ValueError when there is no cluster at `address`."""
    import ray

    env_vars = {k: v for k, v in os.environ.items() if k.startswith(FORWARDED_ENV_PREFIXES)}
    kwargs: dict[str, Any] = dict(runtime_env={"env_vars": env_vars}, log_to_driver=False, ignore_reinit_error=True,
                                  configure_logging=False)
    if ray.is_initialized():
        return
    if address in (None, LOCAL):
        ray.init(num_cpus=num_cpus or os.cpu_count(), include_dashboard=False, **kwargs)
    else:
        if address != "auto":
            _check_reachable(address)
        try:
            ray.init(address=address, **kwargs)
        except (ConnectionError, RuntimeError) as e:
            raise ValueError(f"no Ray cluster at {address} ({str(e).splitlines()[0]}): start one with "
                             f"`ray start --head`, or pass --ray without an address for a local runtime") from None


def shard_gpus(sim_backend: str) -> int:
    """GPUs one shard's task asks Ray for: a physx_cuda shard holds its whole env batch on one GPU."""
    return 1 if sim_backend == "physx_cuda" else 0


def default_shards(sim_backend: str) -> int:
    """One shard per CPU the Ray runtime offers (physx_cpu: one env per process), or per GPU (physx_cuda)."""
    import ray

    resources = ray.cluster_resources()
    return max(1, int(resources.get("GPU" if shard_gpus(sim_backend) else "CPU", 1)))


def _check_gpus(num_gpus: int) -> None:
    import ray

    if num_gpus and ray.cluster_resources().get("GPU", 0) < num_gpus:
        raise ValueError("--sim-backend physx_cuda shards need a GPU each and this Ray runtime offers none: run on a GPU "
                         "node (`ray start --head --num-gpus N` there, then --ray HOST:PORT), or use physx_cpu")


def _progress_actor():
    import ray

    @ray.remote(num_cpus=0)
    class ShardProgress:
        """Episodes finished by any shard, by plan index (a retried shard's repeats count once)."""

        def __init__(self):
            self.outcomes: dict[int, bool] = {}

        def report(self, index: int, success: bool) -> None:
            self.outcomes[index] = success

        def counts(self) -> tuple[int, int]:
            return len(self.outcomes), sum(self.outcomes.values())

    return ShardProgress.remote()


def episode_reporter(progress) -> Callable[[Any, Any], None]:
    """An `on_episode` callback for a shard's runner that tells the driver's progress actor (fire and forget)."""

    def report(episode, _progress) -> None:
        if progress is not None:
            progress.report.remote(int(episode.record.episode_index), episode.record.outcome == "S")

    return report


def run_shards(
    task: Callable[..., Any],
    shard_args: Sequence[tuple],
    on_progress: Callable[[int, int, float], None] | None = None,
    poll_s: float = 1.0,
    num_gpus: int = 0,
) -> list[Any]:
    """Run `task(*args, progress)` for each args tuple as a Ray task (one CPU and `num_gpus` GPUs, retried when its
    worker dies) and return their results in order. `on_progress(episodes_done, successes, seconds)` is called while
    they run. A task's own exception (bad input, a broken checkpoint) is not retried: it is raised here; GPU tasks on
    a runtime without GPUs are refused up front (Ray would wait for one forever)."""
    import ray

    _check_gpus(num_gpus)
    progress = _progress_actor()
    # max_calls=1: a shard's worker exits when it is done, releasing its env (and every run starts from the same state)
    remote = ray.remote(num_cpus=1, num_gpus=num_gpus, max_retries=TASK_RETRIES, retry_exceptions=False,
                        max_calls=1)(task)
    refs = [remote.remote(*args, progress) for args in shard_args]
    pending, start = list(refs), time.monotonic()
    try:
        while pending:
            _, pending = ray.wait(pending, num_returns=len(pending), timeout=poll_s)
            if on_progress:
                done, successes = ray.get(progress.counts.remote())
                on_progress(done, successes, time.monotonic() - start)
        return ray.get(refs)
    except ray.exceptions.RayTaskError as e:
        cause = getattr(e, "cause", None)
        raise (cause if isinstance(cause, Exception) else e) from None
    finally:
        ray.kill(progress)
