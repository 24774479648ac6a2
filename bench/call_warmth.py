"""What a small call costs when it has not run for a while: the machine's share of the step-cost ratios.

`bench/step_cost.py` divides a control step by the bare PhysX step. Between two physics steps the 240 Hz flight
controller is a handful of small Python, torch, numpy and SAPIEN calls, and after the step the evaluation and the
observation are more of them. What such a call costs depends on the machine as well as on the code: on some hosts a
call that has not run for some microseconds pays a fixed extra cost, whatever ran in between. This script measures
that, in one run, one thread:

- a one-element in-place torch add and numpy add, each timed right after a busy wait of `gap` microseconds in pure
  Python (a loop on `time.perf_counter` and nothing else): the median, and the share of calls slower than twice the
  back-to-back median ("cold");
- the 240 Hz hook of `AeroFly-v1` (joint reads, one compiled call, `set_qf`), hovering: called back to back, and
  called between physics steps as it runs in a control step; the PhysX step after the hook, and after only the
  held efforts' write (the bare step of `bench/step_floor.py`).

A cold share that grows with the gap (rather than with the work done in it) says the host, not the code, makes
calls cold. Each number is a median of `--calls` timings.

    python bench/call_warmth.py [--gaps 0,5,10,20,40,100] [--calls 2000] [--no-env]
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import time
from collections.abc import Callable

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import numpy as np  # noqa: E402
import torch  # noqa: E402


def busy_wait(us: float) -> None:
    """Spin for `us` microseconds in the interpreter alone."""
    end = time.perf_counter() + us * 1e-6
    while time.perf_counter() < end:
        pass


def timings(call: Callable[[], object], before: Callable[[], object], n: int) -> list[float]:
    """Microseconds of each of `n` calls of `call`, each right after `before()`."""
    out = []
    for _ in range(n):
        before()
        t0 = time.perf_counter()
        call()
        out.append((time.perf_counter() - t0) * 1e6)
    return out


def gap_rows(gaps: list[float], n: int) -> dict[str, tuple[float, dict[float, tuple[float, float]]]]:
    """For the torch and the numpy add: (back-to-back median us, {gap: (median us, share of calls slower than twice
    the back-to-back median)})."""
    tensor, array = torch.zeros(1), np.zeros(1)
    adds = {"torch add": lambda: tensor.add_(1.0), "numpy add": lambda: np.add(array, 1.0, out=array)}
    rows = {}
    for name, add in adds.items():
        hot = statistics.median(timings(add, lambda: None, n))
        row = {}
        for gap in gaps:
            times = timings(add, (lambda: None) if gap == 0 else (lambda gap=gap: busy_wait(gap)), n)
            row[gap] = (statistics.median(times), sum(t > 2 * hot for t in times) / n)
        rows[name] = (hot, row)
    return rows


def hook_row(n: int) -> dict[str, float]:
    """Median us of the 240 Hz hook back to back and right after a physics step, and of a physics step right after
    the hook and right after the hovering efforts are written again (the bare step)."""
    import gymnasium as gym

    import aerobench.envs  # noqa: F401

    env = gym.make("AeroFly-v1", num_envs=1, obs_mode="state")
    base = env.unwrapped
    env.reset(seed=0, options={"reconfigure": True})
    hover = torch.zeros(1, base.platform.action_dim)
    hover[:, -1] = 1.0
    for _ in range(20):  # lift-off transients out, the compiled package loaded
        env.step(hover)
    controller, px = base.agent.body_controller, base.scene.px
    hook, articulation = controller.before_simulation_step, controller._cpu_articulation
    held = articulation.get_qf().copy()  # the hovering efforts, held as the bare step of step_cost/step_floor does
    state = base.get_state_dict()
    row = {"hook, back to back": statistics.median(timings(hook, lambda: None, n))}
    base.set_state_dict(state)
    row["hook, after a physics step"] = statistics.median(timings(hook, px.step, n))
    base.set_state_dict(state)
    row["physics step, after the hook"] = statistics.median(timings(px.step, hook, n))
    base.set_state_dict(state)
    row["physics step, efforts held"] = statistics.median(timings(px.step, lambda: articulation.set_qf(held), n))
    env.close()
    return row


def main(argv: list[str] | None = None) -> dict[str, dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gaps", default="0,5,10,20,40,100", help="busy waits before each call, microseconds")
    parser.add_argument("--calls", type=int, default=2000, help="timed calls per cell (the median is printed)")
    parser.add_argument("--no-env", action="store_true", help="skip the AeroFly-v1 hook rows")
    args = parser.parse_args(argv)
    try:
        gaps = [float(g) for g in args.gaps.split(",")]
    except ValueError:
        parser.error(f"--gaps takes comma-separated microseconds, e.g. 0,10,40 (got {args.gaps!r})")
    if args.calls < 1 or any(g < 0 for g in gaps):
        parser.error("--calls must be a positive integer and --gaps non-negative")
    torch.set_num_threads(1)
    rows = gap_rows(gaps, args.calls)
    print(f"one thread; median us of {args.calls} calls, each right after a busy wait; "
          "cold = share slower than twice the back-to-back median")
    for name, (hot, row) in rows.items():
        cells = "  ".join(f"{g:g} us: {ms:5.2f} ({ms / hot:4.1f}x, cold {share:4.0%})"
                          for g, (ms, share) in row.items())
        print(f"  {name:<10} back to back {hot:5.2f} | after a wait of {cells}")
    result: dict[str, dict] = {"gaps": rows}
    if not args.no_env:
        hook = hook_row(args.calls)
        print("AeroFly-v1, hovering, the 240 Hz hook; median us")
        for name, us in hook.items():
            print(f"  {name:<28} {us:7.2f}")
        print(f"  {'after a step / back to back':<28} {hook['hook, after a physics step'] / hook['hook, back to back']:6.2f}x")
        result["hook"] = hook
    return result


if __name__ == "__main__":
    main()
