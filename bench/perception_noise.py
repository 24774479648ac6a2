"""A diagnostic evaluation: how exactly must a camera policy know where the object is? (docs/experiments.md,
"Policies that see").

A `privileged` BC trained on the fields a camera policy is taught to estimate (Pick: `goal_pos_body`,
`heading_error`, `is_grasp_confirmed`, with the `vision` tier's egocentric proprioception and action frame) is
evaluated while what it reads of `goal_pos_body` is off by a per-episode error: a constant horizontal offset drawn
from N(0, sigma^2) per axis at each episode's start (a perception error is mostly a bias that persists while the
view changes slowly, not white noise). The result bounds what perception must deliver before any camera design can
pick: if the policy with perfect perception plus sigma fails, a camera estimate that errs by sigma fails too.

    python bench/perception_noise.py --sigma-m 0.01 --policy bc --checkpoint CKPT --setting PrepareGroceries \
        --skills pick --episodes-per-object 5 --seed 4290 --out OUT         (any `aerobench eval` arguments)

`--sigma-z-m S` adds a vertical per-episode offset of that spread too; `--blank FIELD[,FIELD]` also reads those task-state fields as 0 (e.g. `heading_error`: what a perception that
cannot tell the grasp heading gives).

It wraps what `policies.observer.ActorObserver` reads of the task state, runs `aerobench eval` in this process and
marks the results file (`provenance.diagnostic`), so that it is never read as a row of the protocol.
"""

from __future__ import annotations

import json
import os
import shlex
import sys
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import torch  # noqa: E402

from aerobench.cli import main  # noqa: E402
from aerobench.policies import observer  # noqa: E402
from aerobench.policies.inputs import TASK_SLICES  # noqa: E402

NOISY_FIELD = "goal_pos_body"


class _NoisyTaskState:
    """The env, except that `task_state()` adds each env's current offset to the horizontal part of `goal_pos_body`."""

    def __init__(self, env, offset: torch.Tensor, blank: tuple[str, ...] = ()):
        self._env, self._offset, self._blank = env, offset, blank

    def __getattr__(self, name):
        return getattr(self._env, name)

    def task_state(self) -> torch.Tensor:
        state = self._env.task_state().clone()
        columns = TASK_SLICES[NOISY_FIELD]
        state[:, columns.start:columns.start + 3] += self._offset.to(state.device, state.dtype)
        for field in self._blank:
            state[:, TASK_SLICES[field]] = 0.0
        return state


def install(sigma_m: float, seed: int, blank: tuple[str, ...] = (), sigma_z_m: float = 0.0) -> None:
    """Make every `ActorObserver` read `goal_pos_body` with a per-episode horizontal offset ~ N(0, sigma_m^2), and the
    fields `blank` as 0."""
    generator = torch.Generator().manual_seed(seed)
    plain = observer.ActorObserver.observe
    offsets: dict[int, torch.Tensor] = {}

    def observe(self, env, obs, keep=True):
        n = obs["agent"]["state"].shape[0]
        fresh = torch.ones(n, dtype=torch.bool) if self.fresh is None or len(self.fresh) != n else self.fresh.cpu()
        offset = offsets.setdefault(id(self), torch.zeros(n, 3))
        if keep and fresh.any():
            drawn = torch.randn(int(fresh.sum()), 3, generator=generator)
            offset[fresh] = drawn * torch.tensor([sigma_m, sigma_m, sigma_z_m])
        return plain(self, _NoisyTaskState(env, offset, blank), obs, keep)

    observer.ActorObserver.observe = observe


def run(argv: list[str]) -> int:
    if "--sigma-m" not in argv[:-1]:
        print("perception_noise.py: give --sigma-m METRES (the per-axis standard deviation of the offset)",
              file=sys.stderr)
        return 2
    i = argv.index("--sigma-m")
    sigma = float(argv[i + 1])
    argv = argv[:i] + argv[i + 2:]
    if any(a == "--workers" or a.startswith("--workers=") or a == "--ray" for a in argv):
        print("perception_noise.py: runs in one process; drop --workers / --ray", file=sys.stderr)
        return 2
    sigma_z = 0.0
    if "--sigma-z-m" in argv[:-1]:
        i = argv.index("--sigma-z-m")
        sigma_z = float(argv[i + 1])
        argv = argv[:i] + argv[i + 2:]
    blank: tuple[str, ...] = ()
    if "--blank" in argv[:-1]:
        i = argv.index("--blank")
        blank = tuple(argv[i + 1].split(","))
        argv = argv[:i] + argv[i + 2:]
        unknown = [f for f in blank if f not in TASK_SLICES]
        if unknown:
            print(f"perception_noise.py: unknown task-state fields {unknown}", file=sys.stderr)
            return 2
    plain = observer.ActorObserver.observe
    try:
        install(sigma, seed=int(argv[argv.index("--seed") + 1]) if "--seed" in argv[:-1] else 0, blank=blank,
                sigma_z_m=sigma_z)
        code = main(["eval", *argv])
    finally:  # the process (a test's, say) acts as before afterwards
        observer.ActorObserver.observe = plain
    out = Path(argv[argv.index("--out") + 1]) / "results.json" if "--out" in argv[:-1] else None
    if code == 0 and out is not None and out.is_file():
        results = json.loads(out.read_text())
        blanked = (f", vertical sigma {sigma_z} m" if sigma_z else "") + (f", {','.join(blank)} read as 0" if blank else "")
        results["provenance"]["diagnostic"] = (f"goal_pos_body read with a per-episode horizontal offset, sigma "
                                               f"{sigma} m per axis{blanked} (bench/perception_noise.py): not the "
                                               f"protocol")
        extra = (f"--sigma-z-m {sigma_z} " if sigma_z else "") + (f"--blank {','.join(blank)} " if blank else "")
        results["provenance"]["command"] = f"python bench/perception_noise.py --sigma-m {sigma} {extra}" + shlex.join(argv)
        out.write_text(json.dumps(results, indent=2) + "\n")
    return code


if __name__ == "__main__":
    sys.exit(run(sys.argv[1:]))
