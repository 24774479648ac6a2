"""Progress bars of the long commands (`aerobench generate`, `aerobench eval`): one process, or every Ray shard."""

from __future__ import annotations

from collections.abc import Callable


def ray_progress_bar(spec) -> tuple[Callable[[int, int, float], None], Callable[[], None]]:
    """One bar over every Ray shard: episodes done, success so far, episodes per minute."""
    from tqdm import tqdm

    state = {}

    def update(done: int, successes: int, seconds: float) -> None:
        if "bar" not in state:
            state["bar"] = tqdm(total=spec.episodes, unit="ep", desc=f"{spec.setting} {','.join(spec.skills)} (ray)",
                                dynamic_ncols=True)
        bar = state["bar"]
        bar.n = done
        rate = successes / done if done else 0.0
        bar.set_postfix_str(f"success {successes}/{done} ({rate:.0%}), {60 * done / max(seconds, 1e-9):.1f} ep/min")
        bar.refresh()

    def close() -> None:
        if "bar" in state:
            state["bar"].close()

    return update, close


# tqdm's own rate and remaining time count from the bar's creation, which is the end of the first episode here (a
# first episode once read "32017.59 ep/s"): the bar shows the runner's own clock instead (`rollout.runner.Progress`).
BAR_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt}{postfix}"  # tqdm puts ", " before the postfix


def _clock(seconds: float) -> str:
    if seconds == float("inf"):
        return "?"
    minutes, secs = divmod(int(seconds), 60)
    return f"{minutes // 60}:{minutes % 60:02d}:{secs:02d}" if minutes >= 60 else f"{minutes:02d}:{secs:02d}"


def progress_bar(spec) -> Callable:
    """`update(progress, final=False)` after every episode of this process; `final=True` closes the bar (its line ends
    before anything is printed after it)."""
    import time

    from tqdm import tqdm

    state = {}

    def update(progress, final: bool = False):
        bar = state.get("bar")
        if bar is None:
            bar = state["bar"] = tqdm(total=progress.total, initial=progress.done - progress.run_done, unit="ep",
                                      desc=f"{spec.setting} {','.join(spec.skills)}", dynamic_ncols=True,
                                      bar_format=BAR_FORMAT)
        if bar.disable:
            return
        bar.n = progress.done
        rate = progress.successes / progress.run_done if progress.run_done else 0.0
        elapsed = time.monotonic() - progress.started
        bar.set_postfix_str(f"{_clock(elapsed)}<{_clock(progress.eta_s)}, success {progress.successes}/"
                            f"{progress.run_done} ({rate:.0%}), {progress.rate_per_min:.1f} ep/min", refresh=False)
        bar.refresh()
        if final:
            bar.close()

    return update
