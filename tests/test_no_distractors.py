"""`bench/no_distractors.py`: `aerobench eval` with the skill envs built without distractors, marked as a diagnostic."""

import importlib.util
import json
from pathlib import Path

import gymnasium as gym

from aerobench.envs.checker import SKILL_ENV_IDS

SCRIPT = Path(__file__).resolve().parents[1] / "bench" / "no_distractors.py"


def test_a_diagnostic_run_has_no_distractors_and_says_so(tmp_path, monkeypatch):
    spec = importlib.util.spec_from_file_location("no_distractors", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for env_id in SKILL_ENV_IDS.values():  # the script edits the registered specs: restored after the test
        monkeypatch.setitem(gym.spec(env_id).kwargs, "num_distractors", 2)
    built = []
    make = gym.make
    monkeypatch.setattr(gym, "make", lambda *a, **kw: built.append(make(*a, **kw)) or built[-1])
    out = tmp_path / "eval"
    code = module.run(["--policy", "expert", "--setting", "PrepareGroceries", "--skills", "pick", "--objects",
                       "sugar_box", "--episodes-per-object", "1", "--max-steps", "3", "--seed", "5", "--out", str(out)])
    assert code == 0
    assert built and all(env.unwrapped.num_distractors == 0 and not env.unwrapped.distractors for env in built)
    provenance = json.loads((out / "results.json").read_text())["provenance"]
    assert provenance["diagnostic"].startswith("num_distractors=0")
    assert provenance["command"].startswith("python bench/no_distractors.py --policy expert")
    assert module.run(["--policy", "expert", "--workers", "2", "--out", str(tmp_path / "w")]) == 2  # would not hold
