"""The privileged expert really succeeds: one seeded TidyHouse Pick and one Place episode, scored by the annotation."""

from aerobench.eval.evaluate import EvalConfig, evaluate
from aerobench.rollout.records import read_records


def test_expert_picks_and_places_the_can(tmp_path):
    config = EvalConfig(policy="expert", setting="TidyHouse", skills=("pick", "place"), objects=("master_chef_can",),
                        episodes_per_object=1)
    results = evaluate(config, tmp_path)
    records = {r["skill"]: r for r in read_records(tmp_path / "records.jsonl")}
    assert set(records) == {"pick", "place"}
    pick, place = records["pick"], records["place"]
    assert (pick["outcome"], pick["mode"]) == ("S", "Successful grasp handoff"), pick["cause"]
    assert pick["events"]["t_g"] is not None and pick["events"]["t_l"] is not None and pick["events"]["t_g"] <= pick["events"]["t_l"]
    assert (place["outcome"], place["mode"]) == ("S", "Successful placement"), place["cause"]
    # release only after support contact, and the gripper clears afterwards (the Place table's success row)
    assert place["events"]["t_d"] <= place["events"]["t_r"] <= place["events"]["t_c"]
    assert results["mean_sr"] == 1.0 and all(c["n"] == 1 for c in results["cells"])
