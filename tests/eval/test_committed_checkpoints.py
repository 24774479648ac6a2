"""The committed leaderboard checkpoints re-score: every results file that names a checkpoint under
leaderboards/checkpoints/ points at a folder that exists and loads, and one of them, re-evaluated on a few held-out
Pick starts exactly as `aerobench eval --checkpoint leaderboards/checkpoints/...` would, succeeds at least once."""

import json
from pathlib import Path

from aerobench.eval.evaluate import EvalConfig, evaluate
from aerobench.policies.learned import load_actor
from aerobench.policies.lerobot_policies import load_policy as load_lerobot_policy
from aerobench.policies.perceive_act import CONTROLLER, PERCEPTION, read_perceive_act
from aerobench.policies.registry import policy_training_starts

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "leaderboards" / "results"
PICK = ROOT / "leaderboards" / "checkpoints" / "TidyHouse" / "bc" / "pick"
RESCORE_SEED = 4_290  # not a collection round (1..8), the curves (4000), diversity (4100) or the leaderboards (4200)


def _named_checkpoints() -> list[tuple[str, str, Path]]:
    """(results file, policy, checkpoint folder) for every results file whose checkpoint lies under leaderboards/."""
    found = []
    for path in sorted(RESULTS.glob("*.json")):
        results = json.loads(path.read_text())
        spec = results["provenance"].get("checkpoint") or ""
        for part in spec.split(","):
            folder = part.split("=", 1)[-1]
            if folder.startswith("leaderboards/checkpoints/"):
                found.append((path.name, results["policy"], ROOT / folder))
    return found


def test_learned_rows_name_committed_checkpoints_that_load():
    named = _named_checkpoints()
    assert named, "no results file names a checkpoint under leaderboards/checkpoints/"
    assert {policy for _, policy, _ in named} >= {"bc", "act"}
    for results, policy, folder in named:
        assert folder.is_dir(), f"{results} names {folder}, which is not committed"
        if policy in ("bc", "ppo"):
            config, _, _ = load_actor(folder)  # raises on a missing or mismatched weight file
            assert config["algorithm"] == policy
        elif policy == "perceive_act":  # its two networks load, and the head estimates what the controller reads
            _, composed = read_perceive_act(folder)
            perception = load_actor(folder / PERCEPTION)[0]
            controller = load_actor(folder / CONTROLLER)[0]
            assert perception["model"]["aux_dim"] == len(composed["aux_mean"])
            assert set(controller["model"]["inputs"]["task_fields"]) <= set(composed["fields"])
        else:  # a LeRobot checkpoint: its config, weights and processors load
            load_lerobot_policy(folder, policy)
        starts = policy_training_starts(policy, str(folder))  # carried with the folder, not looked up in outputs/
        assert starts.starts or starts.ranges, f"{folder} does not record its training starts"
        assert not starts.untraced and all(not Path(s).is_absolute() for s in starts.sources), starts.sources


def test_committed_bc_pick_checkpoint_succeeds_held_out(tmp_path):
    config = EvalConfig(policy="bc", setting="TidyHouse", skills=("pick",), objects=("master_chef_can",),
                        episodes_per_object=3, checkpoint=str(PICK), seed=RESCORE_SEED)
    results = evaluate(config, tmp_path / "eval", command="test")
    (cell,) = results["cells"]
    assert cell["n"] == 3
    assert results["provenance"]["seen_in_training"]["episodes"] == 0  # held out
    assert cell["successes"] >= 1, f"committed BC pick checkpoint failed every held-out start: {cell['outcomes']}"
