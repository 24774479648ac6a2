"""The leaderboard's robustness view: a perturbed run beside the nominal run of the same checkpoint on the same
starts, with the paired change and its interval; a run without its nominal twin is listed as unpaired."""

import math
from pathlib import Path

import pytest

from aerobench.eval.leaderboard import SettingTable, load_all, render_markdown
from aerobench.eval.results import summarize, write_results
from aerobench.eval.robustness import robustness_rows
from aerobench.eval.row_facts import group_key, perturbation

WIND = [{"name": "wind_gusty_3ms", "version": 1, "parameters": {}, "source": "Dryden"}]


def _results(tmp_path: Path, name: str, outcomes: list[str], checkpoint: str = "ckpt", **provenance) -> Path:
    rows = [{"episode_index": i, "seed": 4200 * 1_000_003 + i, "setting": "TidyHouse", "skill": "pick",
             "object": "sugar_box", "policy": "bc", "outcome": o, "mode": "Successful pick" if o == "S" else "x",
             "cause": ""} for i, o in enumerate(outcomes)]
    base = {"seed": 4200, "checkpoint": checkpoint, "skills": ["pick"], "objects": ["sugar_box"],
            "episodes_per_object": len(outcomes), "max_steps": None}
    return write_results(tmp_path / f"{name}.json", summarize(rows, {**base, **provenance}, label=name,
                                                              inputs="privileged"))


def test_a_perturbed_run_is_paired_with_its_nominal_twin_and_the_change_is_signed(tmp_path):
    nominal = _results(tmp_path, "bc", ["S"] * 18 + ["F"] * 2)
    windy = _results(tmp_path, "bc wind", ["S"] * 8 + ["F"] * 12, conditions=WIND)
    late = _results(tmp_path, "bc late", ["S"] * 20, realtime={"latency_ms": 100.0, "hold": "last", "schedule": "sync"})
    orphan = _results(tmp_path, "other wind", ["F"] * 20, checkpoint="other", conditions=WIND)
    results = load_all([nominal, windy, late, orphan])["TidyHouse"]
    rows = {r["result"]["label"]: r for r in robustness_rows(results)}
    assert set(rows) == {"bc wind", "bc late", "other wind"}
    wind = rows["bc wind"]["comparison"]["overall"]
    assert (wind["n"], wind["rate_a"], wind["rate_b"], wind["only_a"], wind["only_b"]) == (20, 0.9, 0.4, 10, 0)
    assert wind["p_value"] == pytest.approx(2 / 1024)  # all ten discordant pairs one way
    assert rows["other wind"]["comparison"] is None
    assert perturbation(rows["bc late"]["result"]) == "real time (100 ms, hold last, sync)"
    assert group_key(rows["bc wind"]["result"]) != group_key(rows["bc wind"]["nominal"])  # never ranked together
    text = render_markdown(SettingTable("TidyHouse", results))
    assert "### Robustness: conditions and real-time evaluation" in text
    line = next(line for line in text.splitlines() if "| wind_gusty_3ms v1 | 20 |" in line)
    assert "| 90.0 | 40.0 | -50.0 [" in line
    assert "unpaired: no nominal run" in text


def test_a_leaderboard_without_perturbed_runs_has_no_robustness_view(tmp_path):
    results = load_all([_results(tmp_path, "bc", ["S", "F", "S"])])["TidyHouse"]
    assert "Robustness" not in render_markdown(SettingTable("TidyHouse", results))


def test_a_run_pairs_only_with_the_nominal_run_of_its_own_flight_controller(tmp_path):
    aware = _results(tmp_path, "expert", ["S"] * 20)
    nominal_controller = _results(tmp_path, "expert nominal controller", ["S"] * 10 + ["F"] * 10, controller="nominal")
    heavy = _results(tmp_path, "expert nominal controller heavy", ["S"] * 5 + ["F"] * 15, controller="nominal",
                     conditions=[{"name": "payload_heavy", "version": 1, "parameters": {}, "source": "spec"}])
    rows = robustness_rows(load_all([aware, nominal_controller, heavy])["TidyHouse"])
    assert [r["nominal"]["label"] for r in rows] == ["expert nominal controller"]  # not the payload-aware run


def test_an_unknown_flight_controller_is_one_line_before_any_work():
    from aerobench.eval.evaluate import EvalConfig

    with pytest.raises(ValueError, match="unknown controller 'pid'; valid controllers: payload-aware, nominal"):
        EvalConfig(policy="expert", setting="TidyHouse", controller="pid")


def _flown(tmp_path: Path, name: str, outcomes: list[str], diagnostics: list[dict], **provenance) -> Path:
    """An expert Pick run of `outcomes` whose records carry `diagnostics` (one dict per episode), 100 steps each."""
    rows = [{"episode_index": i, "seed": 4200 * 1_000_003 + i, "setting": "TidyHouse", "skill": "pick",
             "object": "sugar_box", "policy": "expert", "outcome": o, "mode": "m", "cause": "", "steps": 100,
             "diagnostics": d} for i, (o, d) in enumerate(zip(outcomes, diagnostics))]
    base = {"seed": 4200, "checkpoint": None, "skills": ["pick"], "objects": ["sugar_box"],
            "episodes_per_object": len(outcomes), "max_steps": None}
    return write_results(tmp_path / f"{name}.json", summarize(rows, {**base, **provenance}, label=name,
                                                              inputs="privileged"))


def _gusty_line(results) -> str:
    return next(line for line in render_markdown(SettingTable("TidyHouse", results)).splitlines()
                if "wind_gusty_3ms v1" in line and "| 3 |" in line)


def test_the_view_shows_how_far_the_airframe_tilted_beside_success(tmp_path):
    def tilts(degrees):
        return [{"max_tilt_rad": math.radians(d)} for d in degrees]

    calm = _flown(tmp_path, "expert", ["S"] * 3, tilts([4.0, 5.0, 6.0]))
    gusty = _flown(tmp_path, "expert gusty", ["S", "F", "F"], tilts([10.0, 30.0, 20.0]), conditions=WIND)
    results = load_all([calm, gusty])["TidyHouse"]
    cell = next(r for r in results if r["label"] == "expert gusty")["cells"][0]
    assert cell["flight"]["median_max_tilt_deg"] == pytest.approx(20.0) and cell["flight"]["max_tilt_deg"] == pytest.approx(30.0)
    assert _gusty_line(results).endswith("| 5.0 -> 20.0 | - -> - |")  # runs that did not record saturation say so


def test_the_view_shows_the_share_of_steps_with_a_clipped_rotor(tmp_path):
    def clipped(steps):
        return [{"max_tilt_rad": math.radians(5.0), "rotor_saturated_steps": k} for k in steps]

    calm = _flown(tmp_path, "expert", ["S"] * 3, clipped([0, 0, 2]))
    gusty = _flown(tmp_path, "expert gusty", ["S", "F", "F"], clipped([10, 40, 25]), conditions=WIND)
    results = load_all([calm, gusty])["TidyHouse"]
    flight = next(r for r in results if r["label"] == "expert gusty")["cells"][0]["flight"]
    assert flight["median_saturated_share"] == pytest.approx(0.25) and flight["saturated_episodes"] == 3
    assert flight["saturated_share_per_episode"] == [0.1, 0.4, 0.25]
    assert _gusty_line(results).endswith("| 5.0 -> 5.0 | 0.0 -> 25.0 |")
