import json
import re
import shutil
from pathlib import Path

import pytest

from aerobench.eval.leaderboard_folder import build_leaderboard
from aerobench.eval.leaderboard_html import MODE_COLOURS, MODE_FAMILIES
from aerobench.eval.results import summarize, write_results

from .spec_table import OBJECTS, SPEC_MEAN_SR, SPEC_TABLE, spec_records


@pytest.fixture
def spec_results(tmp_path):
    paths = []
    for policy in SPEC_TABLE:
        results = summarize(spec_records(policy), {"command": f"aerobench eval --policy {policy.lower()}"}, label=policy)
        paths.append(write_results(tmp_path / "results" / f"{policy}.json", results))
    return paths


def test_cells_match_the_spec(spec_results):
    results = json.loads(spec_results[2].read_text())  # PI0: pick over 30 episodes
    cell = next(c for c in results["cells"] if c["skill"] == "pick" and c["object"] == "master_chef_can")
    assert (cell["successes"], cell["n"]) == (2, 30)
    assert f"{100 * cell['success_rate']:.1f} ± {100 * cell['se']:.1f}" == "6.7 ± 4.6"


def test_markdown_mean_sr_and_bold(spec_results, tmp_path):
    out = tmp_path / "boards"
    build_leaderboard(spec_results, out)
    md = (out / "PrepareGroceries.md").read_text()
    for policy, mean in SPEC_MEAN_SR.items():
        row = next(line for line in md.splitlines() if line.startswith(f"| {policy} |"))
        assert row.rstrip(" |").endswith(f"{mean}") or row.rstrip(" |").endswith(f"**{mean}**"), row
    # pi0.5 has the best mean (bold), ACT's pick bowl 18.0 is the best pick bowl (bold), the spec's order is kept
    assert "**44.6**" in md and "**18.0 ± 5.4**" in md and "**29.5**" not in md
    order = [m.group(1) for m in re.finditer(r"^\| (ACT|DP|PI0|PI05) \|", md.split("| Row |")[0], re.M)]
    assert order == ["ACT", "DP", "PI0", "PI05"]
    header = next(line for line in md.splitlines() if line.startswith("| Policy"))
    assert header.count("|") == len(OBJECTS) + 5  # policy, inputs, skill, the objects, mean


def test_rows_are_ranked_within_their_input_tier_only(spec_results, tmp_path):
    """A vision row is never ranked against a privileged one: each tier has its own best, random none."""
    paths = []
    for policy, tier in (("ACT", "vision"), ("DP", "vision"), ("PI0", "privileged"), ("PI05", "privileged")):
        results = json.loads(next(p for p in spec_results if p.stem == policy).read_text())
        results["inputs"] = tier
        paths.append(write_results(tmp_path / f"{policy}.json", results))
    build_leaderboard(paths, tmp_path / "boards")
    md = (tmp_path / "boards" / "PrepareGroceries.md").read_text().split("| Row |")[0]
    rows = {m.group(1): m.group(0) for m in re.finditer(r"^\| (ACT|DP|PI0|PI05) \| (\w+) \|.*$", md, re.M)}
    assert [m.group(1) for m in re.finditer(r"^\| (ACT|DP|PI0|PI05) \|", md, re.M)] == ["ACT", "DP", "PI0", "PI05"]
    assert rows["DP"].endswith("**33.9** |") and rows["PI05"].endswith("**44.6** |")  # the best of each tier
    assert "| ACT | vision |" in rows["ACT"] and "| PI0 | privileged |" in rows["PI0"]


def _row(tmp_path: Path, name: str, policy: str, label: str, seed: int, successes: int, tier: str) -> Path:
    rows = [{"episode_index": i, "seed": seed * 1_000_003 + i, "setting": "TidyHouse", "policy": policy, "skill": "pick",
             "object": "sugar_box", "outcome": "S" if i < successes else "F", "cause": "", "segments": [],
             "mode": "Successful grasp handoff" if i < successes else "Collision failure", "duration_s": 3.0 + i}
            for i in range(10)]
    results = summarize(rows, {"seed": seed, "physx_solver": "pgs"}, label=label)
    return write_results(tmp_path / "results" / f"TidyHouse_{name}.json", {**results, "inputs": tier})


def test_rows_are_grouped_by_protocol_starts_and_solver(tmp_path):
    """One table per group of comparable rows (same skills, --seed and solver): the expert first, random last, best in
    bold within the group only; a long label gives way to the results file's name, the recipe has its own table."""
    paths = [_row(tmp_path, "random", "random", "random", 7, 0, "none"),
             _row(tmp_path, "bc_long", "bc", "bc (state MLP, 3 frames, 20k steps; a label too long to be a name)", 7, 8,
                  "privileged"),
             _row(tmp_path, "expert", "expert", "expert", 7, 9, "privileged"),
             _row(tmp_path, "ppo", "ppo", "ppo", 8, 10, "privileged")]
    build_leaderboard(paths, tmp_path / "boards")
    md = (tmp_path / "boards" / "TidyHouse.md").read_text()
    groups = md.split("### ")[1:]
    assert groups[0].startswith("Pick; starts of --seed 7; PGS") and groups[1].startswith("Pick; starts of --seed 8; PGS")
    names = [m.group(1) for m in re.finditer(r"^\| (\S+) \| (?:privileged|none) \| Pick \|", groups[0], re.M)]
    assert names == ["expert", "bc_long", "random"]
    assert "| expert | privileged | Pick | **90.0 ± 9.5** | **90.0** |" in groups[0]
    assert "| ppo | privileged | Pick | 100.0 ± 0.0 | 100.0 |" in groups[1]  # alone in its group: never "best"
    facts = next(line for line in md.splitlines() if line.startswith("| bc_long | bc |"))
    assert facts.endswith("| - | - | - | 10 | PGS | pick 6.5 | - | - |")  # no checkpoint named; 3.0 + i s, i < 8
    assert "| bc_long | bc (state MLP, 3 frames, 20k steps; a label too long to be a name) | `TidyHouse_bc_long.json` |" \
        in md


def test_latex_layout(spec_results, tmp_path):
    build_leaderboard(spec_results, tmp_path)
    tex = (tmp_path / "PrepareGroceries.tex").read_text()
    assert r"\multirow{-2}{*}{\textbf{44.6}}" in tex and r"\multirow{-2}{*}{29.5}" in tex
    assert r"{\boldmath$18.0 \pm 5.4$}" in tex and "$2.0 \\pm 2.0$" in tex


def test_refuses_other_versions_and_duplicates(spec_results, tmp_path):
    bad = json.loads(spec_results[0].read_text())
    bad["version"] = 99
    path = tmp_path / "old.json"
    path.write_text(json.dumps(bad))
    with pytest.raises(ValueError, match="results version 99"):
        build_leaderboard([path], tmp_path / "x")
    with pytest.raises(ValueError, match="two results for 'ACT'"):
        build_leaderboard([spec_results[0], spec_results[0]], tmp_path / "y")
    not_results = tmp_path / "other.json"
    not_results.write_text("{}")
    with pytest.raises(ValueError, match="not an aerobench results file"):
        build_leaderboard([not_results], tmp_path / "z")


def _chromium() -> str:
    import shutil

    found = shutil.which("chromium") or shutil.which("chromium-browser")
    assert found, "no chromium on PATH: run `bash scripts/setup_browser.sh` (make test does)"
    return found


def test_training_runs_sharing_a_label_pool_into_one_row(tmp_path):
    """Three training seeds of one recipe (one --label, three checkpoints): one row over all their episodes, with
    each run's Mean S.R., their mean and a bootstrap interval over runs; its recipe read from the checkpoints the
    repository holds (two of three here), the row marked for the one it does not."""
    paths = []
    for seed, successes in ((1, 8), (2, 9), (3, 4)):
        rows = [{"episode_index": i, "seed": 4200 * 1_000_003 + i, "setting": "TidyHouse", "policy": "bc", "skill": "pick",
                 "object": "sugar_box", "outcome": "S" if i < successes else "F", "cause": "", "segments": [],
                 "mode": "Successful grasp handoff" if i < successes else "Collision failure"} for i in range(10)]
        provenance = {"seed": 4200, "checkpoint": f"runs/bc_seed{seed}", "command": f"aerobench eval ... seed{seed}"}
        paths.append(write_results(tmp_path / f"bc_seed{seed}.json", summarize(rows, provenance, label="bc")))
        if seed < 3:  # recorded relative to where the eval ran: found above the results file
            checkpoint = tmp_path / "runs" / f"bc_seed{seed}"
            checkpoint.mkdir(parents=True)
            (checkpoint / "config.json").write_text(json.dumps({"algorithm": "bc", "data": {"episodes": 100, "frames": 12345},
                                                                "train": {"steps": 2000, "seed": seed,
                                                                          "dataset": "outputs/data/pick_dart"}}))
    build_leaderboard(paths, tmp_path / "boards")
    md = (tmp_path / "boards" / "TidyHouse.md").read_text()
    row = next(line for line in md.splitlines() if line.startswith("| bc † | unknown | Pick"))  # no known tier
    assert "70.0 ± 8.4" in row  # 21 of 30 pooled episodes: sqrt(0.7 * 0.3 / 30) = 8.4
    facts = next(line for line in md.splitlines() if line.startswith("| bc † | bc |"))
    assert "| 100 demos, 12.3k transitions (DART) | 2k steps | 3 runs: 1, 2, - | 30 over 3 runs | TGS | - | - |" in facts
    assert "3 runs: 80.0, 90.0, 40.0 (mean 70.0, bootstrap 95% over runs 40.0-90.0)" in facts
    assert "† checkpoint not in the repository" in md and "bc (`runs/bc_seed3`)" in md
    assert "| bc | bc | `bc_seed1.json + bc_seed2.json + bc_seed3.json` |" in md
    from aerobench.eval.pooling import bootstrap_mean_interval

    lo, hi = bootstrap_mean_interval([0.8, 0.9, 0.4])
    assert 0.4 <= lo < 0.7 < hi <= 0.9


def test_html_renders_in_headless_chromium(spec_results, tmp_path):
    import subprocess

    build_leaderboard([*spec_results, *_paired_results(tmp_path)], tmp_path)
    page = (tmp_path / "index.html").resolve()
    r = subprocess.run([_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--dump-dom", page.as_uri()],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    dom = r.stdout
    assert 'data-tables-ready="2"' in dom  # the page's script ran over both settings' tables
    assert dom.count('<td class="mean"') == 11 and "44.6</td>" in dom and '<td class="best"' in dom
    assert dom.count('class="bar"') == 7  # one failure-mode bar per policy
    # the legend lists the modes the bars draw, each once, under the families they belong to, and no other
    legend = dom.split('<div id="mode-legend">')[1].split("</div>")[0]
    listed = re.findall(r'class="swatch" data-mode="([^"]+)"', legend)
    drawn = set(re.findall(r'<span data-mode="([^"]+)" style="width', dom))
    assert sorted(listed) == sorted(drawn) == ["Collision failure", "Object-drop failure", "Successful grasp handoff",
                                              "Successful placement"]
    families = re.findall(r'class="legend" data-family="([^"]+)"', legend)
    assert families == ["success", "collision", "object lost"] and len(MODE_FAMILIES) > len(families)
    # one colour per mode, whatever the row: Collision failure is drawn in the six bars that have one, in its colour
    drawn = re.findall(r'data-mode="Collision failure" style="width:[0-9.]+%;background:([^"]+)"', dom)
    assert len(drawn) == 6 and set(drawn) == {MODE_COLOURS["Collision failure"]}
    assert MODE_COLOURS["Successful placement"].startswith("hsl(122,")
    # the comparison view opens on the best learned row against the expert that ran its starts (not the first pair)
    view = dom.split('<div class="compare" data-setting="TidyHouse"')[1].split('class="cmp-out">')[1]
    view = view.split("<template")[0]
    assert '<p class="cmp-pair">A: stronger; B: expert</p>' in view
    cells = re.findall(r"<tr><td>pick</td><td>(\w+)</td>.*?<td>([0-9.]+)</td><td>([0-9.]+)</td>"
                       r'<td class="verdict">([^<]+)</td></tr>', view)
    # sugar box: 6 of 30 lost to the expert alone, p = 2 / 2^6 = 0.03125 < 0.05 in the cell, but Holm over the two
    # cells doubles it; the bowl cell agrees everywhere and is underpowered at n = 30
    assert cells == [("sugar_box", "0.0312", "0.0625", "B better"), ("bowl", "1", "1", "underpowered")]
    assert '<p class="cmp-holm">Holm over the 2 cells (family-wise alpha 0.05): A better in none, B better in none.</p>' \
        in view
    assert view.count("underpowered") == 1 and view.count("Underpowered") == 1  # the bowl cell; one statement
    assert "Underpowered in 1 of 2 cells at 30 paired episodes: about 77 paired episodes per cell" in view
    # the spec's failure analysis, one row per policy and skill over its object cells (the paired TidyHouse rows)
    assert dom.count('<table class="failure-analysis">') == 1
    fa = dom.split('<table class="failure-analysis">')[1].split("</table>")[0]
    assert fa.count("<tr>") == 4  # a header, weaker, stronger and the expert: pick, over two objects each
    # stronger: failures at 24-29 of sugar box, knocked on even episodes; contact speeds 0.012 and 0.020 per cell
    assert ("<td>stronger</td><td>pick</td><td>2</td><td>60</td><td>6: knocked 3, hit scene 0, other 3</td>"
            "<td>0.0160 (0.0120-0.0200)</td><td>1.5</td>") in fa
    shot = tmp_path / "leaderboard.png"
    r = subprocess.run([_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--window-size=1400,2400",
                        f"--screenshot={shot}", page.as_uri()], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _paired_results(tmp_path: Path) -> list[Path]:
    """Three TidyHouse rows on the same 60 starts (pick, sugar box then bowl): the expert succeeds everywhere;
    "stronger" loses 6 sugar-box episodes; "weaker" loses 13 sugar-box episodes (some by drops) and every bowl one."""
    outcomes = {"weaker": ["S"] * 15 + ["F"] * 10 + ["S"] * 2 + ["F"] * 3 + ["F"] * 30,
                "stronger": ["S"] * 24 + ["F"] * 6 + ["S"] * 30,
                "expert": ["S"] * 60}
    paths = []
    for label, outs in outcomes.items():
        rows = []
        for i, o in enumerate(outs):
            obj = "sugar_box" if i < 30 else "bowl"
            failure = "Object-drop failure" if label == "weaker" and i in (15, 16) else "Collision failure"
            rows.append({"episode_index": i, "seed": 7 * 1_000_003 + i, "setting": "TidyHouse", "policy": label,
                         "skill": "pick", "object": obj, "outcome": o, "cause": "" if o == "S" else "collision",
                         "segments": [], "mode": "Successful grasp handoff" if o == "S" else failure,
                         "diagnostics": {"speed_at_finger_contact_mps": 0.012 if obj == "sugar_box" else 0.02,
                                         "knocked_object": i % 2 == 0, "hit_scene": False,
                                         "handoff_rotation_deg": 1.5}})
        paths.append(write_results(tmp_path / "paired" / f"{label}.json", summarize(rows, {"seed": 7}, label=label)))
    return paths


def test_repository_leaderboards_are_generated_from_their_results(tmp_path):
    """leaderboards/ must be exactly what `aerobench leaderboard leaderboards/results/*.json` renders: never typed."""
    root = Path(__file__).resolve().parents[2] / "leaderboards"
    copy = tmp_path / "leaderboards"  # the same layout, so the page's links to the rows' videos come out the same
    shutil.copytree(root / "results", copy / "results")
    (copy / "checkpoints").symlink_to(root / "checkpoints")  # the rows' recipes are read from their checkpoints
    results = sorted((copy / "results").glob("*.json"))
    settings = {json.loads(p.read_text())["setting"] for p in results}
    assert settings >= {"TidyHouse", "PrepareGroceries", "PackageDelivery", "LongHorizonRearrangement"}
    build_leaderboard(results, copy)
    for rendered in copy.iterdir():
        if rendered.is_file():
            assert rendered.read_text() == (root / rendered.name).read_text(), f"leaderboards/{rendered.name} is stale"
    links = re.findall(r'href="([^"]+\.mp4)"', (root / "index.html").read_text())
    assert links and all((root / link).is_file() for link in links)  # every linked video is committed


def test_repository_results_name_paths_relative_to_the_repository():
    """Committed provenance says outputs/train/..., never where one machine keeps its checkout."""
    def strings(value):
        if isinstance(value, str):
            yield value
        elif isinstance(value, dict | list):
            for v in value.values() if isinstance(value, dict) else value:
                yield from strings(v)

    for path in (Path(__file__).resolve().parents[2] / "leaderboards" / "results").glob("*.json"):
        provenance = json.loads(path.read_text())["provenance"]
        absolute = [s for s in strings(provenance) if s.startswith("/") or "=/" in s]
        assert not absolute, f"{path.name}: {absolute}"


def _chain_row(index: int, stages: list[str]) -> dict:
    """A chain episode record reaching `len(stages)` stages with the given per-stage outcomes."""
    skills = ("pick", "nav", "place")
    segments = [{"stage": k, "skill": skills[k], "outcome": o, "mode": "Successful" if o == "S" else "Collision failure"}
                for k, o in enumerate(stages)]
    return {"episode_index": index, "setting": "TidyHouse", "policy": "ppo", "skill": "pick_nav_place",
            "object": "bowl", "outcome": stages[-1] if len(stages) == 3 or stages[-1] != "S" else "F",
            "mode": segments[-1]["mode"], "cause": None, "segments": segments}


def test_chained_stages_render_with_conditional_success(tmp_path):
    rows = [_chain_row(0, ["S", "S", "S"]), _chain_row(1, ["S", "F"]), _chain_row(2, ["F"]), _chain_row(3, ["S", "S", "F"])]
    write_results(tmp_path / "chain.json", summarize(rows, {"command": "aerobench eval --chain pick,transport,place"},
                                                     label="ppo (chained)"))
    build_leaderboard([tmp_path / "chain.json"], tmp_path / "lb")
    md = (tmp_path / "lb" / "TidyHouse.md").read_text()
    # pick 3 of 4; transport 2 of the 3 that reached it; place 1 of 2
    assert "| ppo (chained) | pick_nav_place | pick 3/4 (75.0 ± 21.7) | nav 2/3 (66.7 ± 27.2) | place 1/2 (50.0 ± 35.4) |" in md
    assert "nav 2/3 (66.7 ± 27.2)" in (tmp_path / "lb" / "index.html").read_text()


def test_the_row_table_says_whether_a_learned_policy_saw_the_evaluation_starts(tmp_path):
    seen = {"ACT": {"episodes": 3, "of": 4, "sources": ["ds"], "untraced": []},
            "DP": {"episodes": 0, "of": 4, "sources": ["ds"], "untraced": []},
            "PI0": {"episodes": 0, "of": 4, "sources": [], "untraced": ["ckpt"]},
            "PI05": None}  # expert / random, or a results file from before the check
    paths = []
    for policy, value in seen.items():
        results = summarize(spec_records(policy), {"command": "c", "seen_in_training": value}, label=policy)
        paths.append(write_results(tmp_path / "results" / f"{policy}.json", results))
    build_leaderboard(paths, tmp_path / "boards")
    rows = (tmp_path / "boards" / "PrepareGroceries.md").read_text().split("| Row |")[1].splitlines()
    assert rows[0].split("|")[8].strip() == "Starts seen in training"
    column = {r.split("|")[1].strip(): r.split("|")[10].strip() for r in rows[2:] if r.startswith("| ")}
    assert column == {"ACT": "**3 of 4**", "DP": "none (held out)", "PI0": "not traced", "PI05": "-"}
    # the contact solver: results without the key were measured under TGS
    assert rows[0].split("|")[6].strip() == "Contact solver"
    assert all(r.split("|")[8].strip() == "TGS" for r in rows[2:] if r.startswith("| "))
