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


def progress_bar(spec) -> Callable:
    from tqdm import tqdm

    state = {}

    def update(progress, final: bool = False):
        bar = state.get("bar")
        if bar is None:
            bar = state["bar"] = tqdm(total=progress.total, initial=progress.done - progress.run_done, unit="ep",
                                      desc=f"{spec.setting} {','.join(spec.skills)}", dynamic_ncols=True)
        bar.n = progress.done
        rate = progress.successes / progress.run_done if progress.run_done else 0.0
        bar.set_postfix_str(f"success {progress.successes}/{progress.run_done} ({rate:.0%}), {progress.rate_per_min:.1f} ep/min")
        bar.refresh()
        if final:
            bar.close()

    return update
