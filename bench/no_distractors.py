"""A diagnostic evaluation: `aerobench eval` with the skill envs built without distractors (docs/experiments.md,
"Policies that see"). Not a benchmark row: the distractors are part of every setting's protocol, and without them the
starts differ too (the drone's start is drawn after the distractors are placed, from the same per-env stream). It
answers one question about a failing camera policy: does it fail because it cannot tell the named object from the
others beside it, or because it cannot fly to any object precisely?

    python bench/no_distractors.py --policy bc --checkpoint CKPT --setting PrepareGroceries --skills pick \
        --episodes-per-object 2 --seed 4290 --inputs vision --out OUT        (any `aerobench eval` arguments)

It sets `num_distractors=0` in the registered specs of the skill envs (gymnasium's `EnvSpec.kwargs`, the defaults
`gym.make` merges), runs `aerobench eval` with the arguments given, and marks the results file
(`provenance.diagnostic`), so that it is never read as a row of the protocol.
"""

from __future__ import annotations

import json
import os
import shlex
import sys
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import gymnasium as gym  # noqa: E402

from aerobench.cli import main  # noqa: E402
from aerobench.envs.checker import SKILL_ENV_IDS  # noqa: E402

DIAGNOSTIC = "num_distractors=0 (bench/no_distractors.py): not the setting's protocol"


def run(argv: list[str]) -> int:
    workers = argv[argv.index("--workers") + 1] if "--workers" in argv[:-1] else "1"
    workers = next((a.split("=", 1)[1] for a in argv if a.startswith("--workers=")), workers)
    if workers != "1" or "--ray" in argv:  # worker processes import the specs afresh: they would keep the distractors
        print("no_distractors.py: runs in one process; drop --workers / --ray", file=sys.stderr)
        return 2
    for env_id in SKILL_ENV_IDS.values():
        gym.spec(env_id).kwargs["num_distractors"] = 0
    code = main(["eval", *argv])
    out = Path(argv[argv.index("--out") + 1]) / "results.json" if "--out" in argv else None
    if code == 0 and out is not None and out.is_file():
        results = json.loads(out.read_text())
        results["provenance"]["diagnostic"] = DIAGNOSTIC
        results["provenance"]["command"] = "python bench/no_distractors.py " + shlex.join(argv)
        out.write_text(json.dumps(results, indent=2) + "\n")
    return code


if __name__ == "__main__":
    sys.exit(run(sys.argv[1:]))
