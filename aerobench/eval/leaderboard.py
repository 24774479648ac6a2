"""Leaderboards rendered from results files, never typed: Markdown and LaTeX per setting, one static HTML page.

Layout follows the spec's PrepareGroceries table: rows policy x skill, columns objects, cells "success % +- SE",
the best policy per skill-object column in bold, and a Mean S.R. column (unweighted mean over the policy's
skill-object pairs). Every row says its input tier (`aerobench.tiers`): rows are ordered by tier, and "best" is
decided among the rows of one tier only (a `vision` row is never ranked against a `privileged` one; random, which
reads nothing, is shown but never best). Every table names the results files and the commands that produced them.
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from pathlib import Path

from .. import tiers
from ..envs.tasks import SKILLS, get_setting
from .pooling import pool_training_runs, training_runs_text
from .results import DEFAULT_TIERS, UNKNOWN_TIER, load_results

OBJECT_LABELS = {
    "master_chef_can": "Master Chef Can", "cracker_box": "Cracker Box", "sugar_box": "Sugar Box",
    "tomato_soup_can": "Tomato Soup Can", "tuna_fish_can": "Tuna Fish Can", "pudding_box": "Pudding Box",
    "gelatin_box": "Gelatin Box", "potted_meat_can": "Potted Meat Can", "bowl": "Bowl", "package": "Package", "": "-",
}


def _pct(x: float) -> str:
    return f"{100 * x:.1f}"


def tier_of_result(result: dict) -> str:
    """A results file's input tier; files written before the field existed: the expert's and random's, else unknown."""
    return result.get("inputs") or DEFAULT_TIERS.get(result["policy"], UNKNOWN_TIER)


class SettingTable:
    """One setting's grid: results (one per policy row block), the object columns and the best cells."""

    def __init__(self, setting: str, results: Sequence[dict]):
        self.setting = setting
        # grouped by input tier (vision, privileged, none), the strongest last within a tier as in the spec
        self.results = sorted(results, key=lambda r: (tiers.tier_rank(tier_of_result(r)), r["mean_sr"]))
        order = {o: i for i, o in enumerate(get_setting(setting).objects)}
        objects = {c["object"] for r in results for c in r["cells"]}
        self.objects = sorted(objects, key=lambda o: (order.get(o, len(order)), o))
        skill_rank = {s: i for i, s in enumerate(SKILLS)}
        self.skills = sorted({c["skill"] for r in results for c in r["cells"]}, key=lambda s: (skill_rank.get(s, 99), s))
        self.best: dict[tuple[str, str, str], float] = {}  # (tier, skill, object) -> the tier's best rate
        for tier in {tier_of_result(r) for r in results} - {tiers.NO_INPUTS}:  # random is never best
            mine = [r for r in results if tier_of_result(r) == tier]
            for skill in self.skills:
                for obj in self.objects:
                    rates = [c["success_rate"] for r in mine if (c := self.cell(r, skill, obj)) is not None]
                    if len(rates) > 1 and max(rates) > 0:
                        self.best[(tier, skill, obj)] = max(rates)

    @staticmethod
    def cell(result: dict, skill: str, obj: str) -> dict | None:
        for c in result["cells"]:
            if c["skill"] == skill and c["object"] == obj and c["n"]:
                return c
        return None

    def skills_of(self, result: dict) -> list[str]:
        present = {c["skill"] for c in result["cells"]}
        return [s for s in self.skills if s in present]

    def is_best(self, result: dict, skill: str, obj: str, cell: dict) -> bool:
        """The cell is the best of its column among the rows of its result's tier."""
        key = (tier_of_result(result), skill, obj)
        return key in self.best and abs(cell["success_rate"] - self.best[key]) < 1e-12

    def is_best_mean(self, result: dict) -> bool:
        tier = tier_of_result(result)
        mine = [r["mean_sr"] for r in self.results if tier_of_result(r) == tier]
        return tier != tiers.NO_INPUTS and len(mine) > 1 and max(mine) > 0 and result["mean_sr"] == max(mine)


def load_all(paths: Sequence[str | Path]) -> dict[str, list[dict]]:
    """Results grouped by setting. Results sharing a label in one setting are training runs of one recipe (different
    checkpoints) and become one pooled row (`pooling`); the same label with the same checkpoint twice is refused."""
    by_label: dict[tuple[str, str], list[dict]] = {}
    for path in paths:
        result = load_results(path)
        result["_source"] = Path(path).name
        result["_path"] = Path(path).resolve()
        by_label.setdefault((result["setting"], result["label"]), []).append(result)
    if not by_label:
        raise ValueError("no results files given")
    by_setting: dict[str, list[dict]] = {}
    for (setting, _), runs in by_label.items():
        by_setting.setdefault(setting, []).append(runs[0] if len(runs) == 1 else pool_training_runs(runs))
    return by_setting


def render_markdown(table: SettingTable) -> str:
    header = ["Policy", "Inputs", "Skill", *(OBJECT_LABELS.get(o, o) for o in table.objects), "Mean S.R."]
    lines = [f"## {table.setting}", "",
             "Success % ± binomial standard error per skill-object pair (n episodes each; see the results files). "
             "Inputs: the policy's input tier (`vision`: cameras, proprioception, instruction; `privileged`: also the "
             "simulator's task state; docs/evaluation.md); rows are ranked within their tier only. Best per column "
             "and tier in bold. Mean S.R.: unweighted mean over the policy's skill-object pairs.", "",
             "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for result in table.results:
        for i, skill in enumerate(table.skills_of(result)):
            cells = []
            for obj in table.objects:
                c = table.cell(result, skill, obj)
                text = "" if c is None else f"{_pct(c['success_rate'])} ± {_pct(c['se'])}"
                cells.append(f"**{text}**" if c is not None and table.is_best(result, skill, obj, c) else text)
            mean = ""
            if i == 0:
                mean = _pct(result["mean_sr"])
                mean = f"**{mean}**" if table.is_best_mean(result) else mean
            first = [result["label"], tier_of_result(result)] if i == 0 else ["", ""]
            lines.append("| " + " | ".join([*first, skill.capitalize(), *cells, mean]) + " |")
    lines += _chain_markdown(table)
    lines += ["", "| Row | n per cell | Starts seen in training | Training runs (Mean S.R. each) | Contact solver | "
              "Results file | Command |", "|---|---|---|---|---|---|---|"]
    for result in table.results:
        ns = sorted({c["n"] for c in result["cells"]})
        command = result["provenance"].get("command") or "-"
        lines.append(f"| {result['label']} | {', '.join(map(str, ns))} | {seen_in_training_text(result)} | "
                     f"{training_runs_text(result)} | {solver_text(result)} | `{result['_source']}` | `{command}` |")
    return "\n".join(lines) + "\n"


def solver_text(result: dict) -> str:
    """The PhysX solver the row was measured with; results from before the key were measured under TGS."""
    return str(result["provenance"].get("physx_solver", "tgs")).upper()


def seen_in_training_text(result: dict) -> str:
    """"none (held out)", "k of n", "not traced" or "-" (no training data: expert, random; or not recorded)."""
    seen = result["provenance"].get("seen_in_training")
    if not seen:
        return "-"
    if seen["untraced"]:
        return "not traced"
    return "none (held out)" if seen["episodes"] == 0 else f"**{seen['episodes']} of {seen['of']}**"


def chain_rows(table: SettingTable) -> list[tuple[str, str, list[str]]]:
    """(policy label, chain, one "skill k/n (p ± se)" text per stage) for every result with chain stages."""
    rows = []
    for result in table.results:
        for name, stages in sorted(result.get("chains", {}).items()):
            texts = [f"{s['skill']} {s['successes']}/{s['reached']} ({_pct(s['conditional_success'])} ± {_pct(s['se'])})"
                     for s in stages]
            rows.append((result["label"], name, texts))
    return rows


def _chain_markdown(table: SettingTable) -> list[str]:
    rows = chain_rows(table)
    if not rows:
        return []
    width = max(len(texts) for _, _, texts in rows)
    lines = ["", "Chained rollouts, per stage: episodes that succeeded / reached the stage (conditional success % ± SE), "
             "so error propagation across skills is visible.", "",
             "| Policy | Chain | " + " | ".join(f"Stage {k + 1}" for k in range(width)) + " |", "|" + "---|" * (width + 2)]
    for label, name, texts in rows:
        lines.append(f"| {label} | {name} | " + " | ".join(texts + [""] * (width - len(texts))) + " |")
    return lines


def render_latex(table: SettingTable) -> str:
    """The spec's table layout (needs booktabs-free `makecell`, `multirow`, `diagbox`, `xcolor`)."""
    n_obj = len(table.objects)
    heads = []
    for o in table.objects:
        words = OBJECT_LABELS.get(o, o).split(" ")
        heads.append(r"\makecell{" + " ".join(words[:-1]) + r"\\" + words[-1] + "}" if len(words) > 1 else words[0])
    lines = [
        r"\begin{table*}[t]", r"\centering", r"\small",
        rf"\caption{{\textbf{{Simulation results on aerobench {table.setting}.}} Success rate (\%) $\pm$ binomial "
        r"standard error per skill--object pair. Mean S.R. is the unweighted average over the skill--object pairs.}",
        r"\resizebox{\textwidth}{!}{%", r"\begin{tabular}{" + "c" * (n_obj + 3) + "}", r"\hline",
        r"\diagbox[width=1.5cm,height=0.95cm]{Alg.}{Obj.} & \emph{Skill} & " + " & ".join(heads)
        + r" & \makecell{Mean S.R.\\(" + " + ".join(s.capitalize() for s in table.skills) + r")} \\", r"\hline",
    ]
    for result in table.results:
        skills = table.skills_of(result)
        for i, skill in enumerate(skills):
            cells = []
            for obj in table.objects:
                c = table.cell(result, skill, obj)
                if c is None:
                    cells.append("--")
                    continue
                text = f"{_pct(c['success_rate'])} \\pm {_pct(c['se'])}"
                cells.append(rf"{{\boldmath${text}$}}" if table.is_best(result, skill, obj, c) else f"${text}$")
            last = i == len(skills) - 1
            label = f"{result['label']} [{tier_of_result(result)}]"
            name = rf"\multirow{{-{len(skills)}}}{{*}}{{{_latex_escape(label)}}}" if last else ""
            mean = ""
            if last:
                value = _pct(result["mean_sr"])
                mean = rf"\multirow{{-{len(skills)}}}{{*}}{{" + (rf"\textbf{{{value}}}" if table.is_best_mean(result) else value) + "}"
            lines.append(f"{name} & {skill.capitalize()} & " + " & ".join(cells) + f" & {mean} \\\\")
        lines.append(r"\hline")
    lines += [r"\end{tabular}%", "}", r"\end{table*}"]
    return "\n".join(lines) + "\n"


def _latex_escape(text: str) -> str:
    for a, b in (("\\", r"\textbackslash{}"), ("_", r"\_"), ("%", r"\%"), ("&", r"\&"), ("#", r"\#")):
        text = text.replace(a, b)
    return text


_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>aerobench leaderboard</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 2em; color: #222; }}
table {{ border-collapse: collapse; margin: 1em 0; font-size: 14px; }}
th, td {{ border: 1px solid #ccc; padding: 4px 8px; text-align: center; }}
th {{ background: #f3f3f3; cursor: pointer; user-select: none; }}
td.best {{ font-weight: bold; }}
.bar {{ display: flex; width: 360px; height: 14px; border: 1px solid #aaa; }}
.bar span {{ display: block; height: 100%; }}
.legend span.swatch {{ display: inline-block; width: 12px; height: 12px; margin: 0 4px 0 12px; vertical-align: middle; }}
@media print {{ .bar span, .legend span.swatch {{ -webkit-print-color-adjust: exact; print-color-adjust: exact; }}
  td[data-n]::after {{ content: " (n=" attr(data-n) ", " attr(data-wilson) ")"; font-size: 9px; }} }}
</style></head><body>
<h1>aerobench leaderboard</h1>
<p>Generated by <code>aerobench leaderboard</code> from results files; success % &plusmn; binomial SE per skill-object pair,
best per column in bold. Click a column header to sort.</p>
{body}
<script>
var tables = document.querySelectorAll("table.sortable");
document.body.setAttribute("data-tables-ready", String(tables.length));
tables.forEach(function (table) {{
  table.querySelectorAll("th").forEach(function (th, col) {{
    th.addEventListener("click", function () {{
      var rows = Array.from(table.tBodies[0].rows);
      var asc = th.dataset.asc !== "1"; th.dataset.asc = asc ? "1" : "0";
      rows.sort(function (a, b) {{
        var x = a.cells[col].dataset.v || a.cells[col].textContent, y = b.cells[col].dataset.v || b.cells[col].textContent;
        var nx = parseFloat(x), ny = parseFloat(y);
        var c = (!isNaN(nx) && !isNaN(ny)) ? nx - ny : x.localeCompare(y);
        return asc ? c : -c;
      }});
      rows.forEach(function (r) {{ table.tBodies[0].appendChild(r); }});
    }});
  }});
}});
document.querySelectorAll("div.compare").forEach(function (view) {{
  var a = view.querySelector("select.cmp-a"), b = view.querySelector("select.cmp-b"), out = view.querySelector(".cmp-out");
  var first = view.querySelector("template");
  a.value = first.dataset.a; b.value = first.dataset.b;
  function show() {{
    out.innerHTML = "";
    var match = Array.from(view.querySelectorAll("template")).find(function (t) {{
      return t.dataset.a === a.value && t.dataset.b === b.value; }});
    if (match) {{ out.appendChild(match.content.cloneNode(true)); }}
    else {{ out.textContent = a.value === b.value ? "Pick two different rows." : "These two rows did not run the same starts."; }}
  }}
  a.addEventListener("change", show); b.addEventListener("change", show); show();
}});
</script></body></html>
"""

# Outcome-mode colours, fixed per mode on every row and setting: one hue per family (success green, each failure
# family its own hue), shades within a family; truncations and incomplete terminal checks are light tints.
# (family, hue, saturation %, (lightest, darkest) lightness %, modes of the spec's mode tables)
MODE_FAMILIES: tuple[tuple[str, int, int, tuple[int, int], tuple[str, ...]], ...] = (
    ("success", 122, 55, (32, 52), ("Successful grasp handoff", "Successful placement", "Successful navigation",
                                    "Successful opening", "Successful closing")),
    ("collision", 2, 75, (38, 58), ("Collision failure", "Collision-budget failure", "Airframe-contact failure",
                                    "Clearance-check failure")),
    ("flight envelope", 285, 55, (38, 55), ("Flight-envelope failure", "Workspace failure")),
    ("object lost", 28, 90, (42, 58), ("Object-drop failure", "Unsupported-release failure", "Handle-slip failure")),
    ("approach, grasp and drive", 215, 70, (38, 58), ("Handle-approach failure", "Handle-pinch failure",
                                                      "Opening-drive failure", "Closing-drive failure")),
    ("other failure", 200, 10, (45, 45), ("Other failure",)),
    ("truncation: no grasp or no progress", 48, 85, (68, 84),
     ("No-progress truncation", "No-alignment truncation", "No-grasp truncation", "Grasp-without-lift truncation",
      "Incomplete-handoff truncation")),
    ("truncation or check unmet at the end", 185, 55, (66, 86),
     ("No-support truncation", "No-release truncation", "Incomplete-completion truncation", "Unsettled truncation",
      "Opening-goal unmet", "Closing-goal unmet", "Handle-release incomplete", "Arm-retraction incomplete",
      "Platform-settling incomplete", "Execution incomplete")),
)
UNKNOWN_MODE_COLOUR = "hsl(0, 0%, 75%)"


def _mode_colours() -> dict[str, str]:
    colours = {}
    for _, hue, sat, (light, dark), modes in MODE_FAMILIES:
        for i, mode in enumerate(modes):
            lightness = dark + (light - dark) * i / max(len(modes) - 1, 1)
            colours[mode] = f"hsl({hue}, {sat}%, {lightness:.0f}%)"
    return colours


MODE_COLOURS = _mode_colours()


def mode_colour(mode: str) -> str:
    return MODE_COLOURS.get(mode, UNKNOWN_MODE_COLOUR)


def _mode_legend() -> str:
    """The page's legend: every family, its modes in their colours."""
    e = html.escape
    rows = []
    for family, _, _, _, modes in MODE_FAMILIES:
        swatches = "".join(f'<span class="swatch" data-mode="{e(m)}" style="background:{mode_colour(m)}"></span>{e(m)}'
                           for m in modes)
        rows.append(f'<p class="legend" data-family="{e(family)}"><b>{e(family)}</b>{swatches}</p>')
    return '<div id="mode-legend"><h3>Outcome-mode colours</h3>' + "".join(rows) + "</div>"


def comparable_pairs(table: SettingTable) -> list[dict]:
    """`compare` of every ordered pair of the table's rows that ran the same starts (same seed and plan)."""
    from .compare import compare, run_from_results

    runs = []
    for result in table.results:
        try:
            runs.append(run_from_results(result["_path"], result))
        except (ValueError, KeyError):  # no per-episode outcomes: the row cannot be paired
            continue
    pairs = []
    for a in runs:
        for b in runs:
            if a is not b:
                try:
                    pairs.append(compare(a, b))
                except ValueError:  # different starts
                    continue
    return pairs


def _comparison_view(table: SettingTable, pairs: list[dict]) -> str:
    """Two selects and one precomputed paired table per ordered pair (the page's script shows the chosen one)."""
    e = html.escape
    labels = sorted({p[side]["label"] for p in pairs for side in ("a", "b")})
    options = "".join(f'<option value="{e(label)}">{e(label)}</option>' for label in labels)
    head = ("<tr><th>skill</th><th>object</th><th>n</th><th>both</th><th>A only</th><th>B only</th><th>neither</th>"
            "<th>A %</th><th>B %</th><th>A-B 95% (pts)</th><th>McNemar p</th><th>verdict</th></tr>")
    templates = []
    for p in pairs:
        rows = []
        for row in [*p["cells"], p["overall"]]:
            lo, hi = row["diff95"]
            rows.append(f"<tr><td>{e(row['skill'])}</td><td>{e(row['object'] or '-')}</td><td>{row['n']}</td>"
                        f"<td>{row['both']}</td><td>{row['only_a']}</td><td>{row['only_b']}</td><td>{row['neither']}</td>"
                        f"<td>{_pct(row['rate_a'])}</td><td>{_pct(row['rate_b'])}</td>"
                        f"<td>{100 * lo:.1f} to {100 * hi:.1f}</td><td>{row['p_value']:.3g}</td>"
                        f'<td class="verdict">{e(row["verdict"])}</td></tr>')
        templates.append(f'<template data-a="{e(p["a"]["label"])}" data-b="{e(p["b"]["label"])}"><table>{head}'
                         + "".join(rows) + "</table></template>")
    return (f'<div class="compare" data-setting="{e(table.setting)}"><h3>Compare two rows (paired, same starts)</h3>'
            f'<p>A <select class="cmp-a">{options}</select> B <select class="cmp-b">{options}</select></p>'
            f'<div class="cmp-out"></div>{"".join(templates)}<p>Exact McNemar test; interval: Newcombe (1998) method '
            f"10; rows without per-episode outcomes or with other starts are not offered.</p></div>")


def _fmt(value: float | None, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _failure_analysis_view(table: SettingTable) -> str:
    """The spec's failure-analysis quantities per policy and object (cells' `failure_analysis`): pick failures by
    mechanism, contact and release speeds, handoff rotation, transport grasp losses by mechanism and rotation."""
    e = html.escape
    rows = []
    for result in table.results:
        for c in result["cells"]:
            fa = c.get("failure_analysis") or {}
            if not fa:
                continue
            pick, place, transport = fa.get("pick", {}), fa.get("place", {}), fa.get("transport", {})
            failures = pick.get("failures")
            mechanisms = "-" if failures is None else (
                f"{failures}: knocked {pick['failures_knocked_object']}, hit scene {pick['failures_hit_scene']}, "
                f"other {failures - pick['failures_knocked_object'] - pick['failures_hit_scene']}")
            losses = ", ".join(f"{k} {v}" for k, v in transport.get("grasp_losses", {}).items()) or (
                "0" if transport else "-")
            by_rotation = ", ".join(f"{k} deg: {lost}/{n}" for k, (lost, n) in
                                    transport.get("losses_by_handoff_rotation_deg", {}).items()) or "-"
            rows.append(f"<tr><td>{e(result['label'])}</td><td>{e(c['skill'])}</td><td>{e(c['object'] or '-')}</td>"
                        f"<td>{c['n']}</td><td>{e(mechanisms)}</td>"
                        f"<td>{_fmt(pick.get('median_speed_at_finger_contact_mps'), 4)}</td>"
                        f"<td>{_fmt(pick.get('median_handoff_rotation_deg'), 1)}</td>"
                        f"<td>{_fmt(place.get('median_speed_at_release_mps'), 4)}</td>"
                        f"<td>{e(losses)}</td><td>{e(by_rotation)}</td></tr>")
    if not rows:
        return ""
    head = ("<tr><th>Policy</th><th>Skill</th><th>Object</th><th>n</th><th>Pick failures by mechanism</th>"
            "<th>Median speed at first finger contact (m/s)</th><th>Median handoff rotation (deg)</th>"
            "<th>Median speed when the jaws open (m/s)</th><th>Transport grasp losses</th>"
            "<th>Losses / transports by handoff rotation</th></tr>")
    return (f'<h3>Failure analysis</h3><table class="failure-analysis">{head}{"".join(rows)}</table>'
            "<p>Per the spec's appendix \"Failure Analysis\": knocked = the object moved more than 3 cm or turned more than "
            "20 deg before it was grasped; hit scene = a collision while the object was undisturbed; a transport grasp "
            "is lost after 4 steps without both fingers above 0.1 N within 6 cm of the grasp point (slip: a finger "
            "lost its force; pinched beyond 6 cm: still pinched, displaced in the jaws). Results written before these "
            "diagnostics existed have none.</p>")


def render_html(tables: Sequence[SettingTable], video_root: Path | None = None) -> str:
    body = []
    for table in tables:
        e = html.escape
        body.append(f"<h2>{e(table.setting)}</h2>")
        head = ["Policy", "Inputs", "Skill", *(OBJECT_LABELS.get(o, o) for o in table.objects), "Mean S.R."]
        body.append(f'<table class="sortable" data-setting="{e(table.setting)}"><thead><tr>'
                    + "".join(f"<th>{e(h)}</th>" for h in head) + "</tr></thead><tbody>")
        for result in table.results:
            for skill in table.skills_of(result):
                row = [f"<td>{e(result['label'])}</td>", f'<td class="inputs">{e(tier_of_result(result))}</td>',
                       f"<td>{e(skill)}</td>"]
                for obj in table.objects:
                    c = table.cell(result, skill, obj)
                    if c is None:
                        row.append('<td data-v="-1"></td>')
                        continue
                    cls = ' class="best"' if table.is_best(result, skill, obj, c) else ""
                    title = f"n={c['n']}, Wilson 95% {_pct(c['wilson95'][0])}-{_pct(c['wilson95'][1])}"
                    row.append(f'<td{cls} data-v="{c["success_rate"]:.6f}" data-n="{c["n"]}" '
                               f'data-wilson="{_pct(c["wilson95"][0])}-{_pct(c["wilson95"][1])}" title="{title}">'
                               f"{_pct(c['success_rate'])} &plusmn; {_pct(c['se'])}</td>")
                row.append(f'<td class="mean" data-v="{result["mean_sr"]:.6f}">{_pct(result["mean_sr"])}</td>')
                body.append("<tr>" + "".join(row) + "</tr>")
        body.append("</tbody></table>")
        chains = chain_rows(table)
        if chains:
            body.append("<h3>Chained rollouts: per-stage conditional success</h3><table><tbody>")
            body += [f"<tr><td>{e(label)}</td><td>{e(name)}</td>" + "".join(f"<td>{e(t)}</td>" for t in texts) + "</tr>"
                     for label, name, texts in chains]
            body.append("</tbody></table>")
        pairs = comparable_pairs(table)
        if pairs:
            body.append(_comparison_view(table, pairs))
        body.append(_failure_analysis_view(table))
        body.append("<h3>Outcome modes</h3>")
        for result in table.results:
            modes: dict[str, int] = {}
            for c in result["cells"]:
                for m, k in c["modes"].items():
                    modes[m] = modes.get(m, 0) + k
            total = sum(modes.values()) or 1
            names = sorted(modes, key=lambda m: (not m.startswith("Successful"), -modes[m]))
            spans = "".join(f'<span data-mode="{e(m)}" style="width:{100 * modes[m] / total:.2f}%;'
                            f'background:{mode_colour(m)}" title="{e(m)}: {modes[m]}"></span>' for m in names)
            legend = "".join(f'<span class="swatch" style="background:{mode_colour(m)}"></span>{e(m)} ({modes[m]})'
                             for m in names)
            videos = "".join(f' <a href="{e(v)}">video {j + 1}</a>' for j, v in enumerate(result.get("_videos", [])))
            runs = f' <span class="runs">{e(training_runs_text(result))}</span>' if result.get("training_runs") else ""
            body.append(f'<p><b>{e(result["label"])}</b>{runs}{videos}</p><div class="bar">{spans}</div>'
                        f'<p class="legend">{legend}</p>')
    return _PAGE.format(body=_mode_legend() + "\n" + "\n".join(body))


GLANCE_SKILLS = ("pick", "place")  # the spec's table: every setting's Pick and Place cells
GLANCE_START, GLANCE_END = "<!-- glance: generated by aerobench leaderboard -->", "<!-- /glance -->"


def _glance_cell(result: dict | None) -> str:
    if result is None:
        return "-"
    from .results import over_all_cells

    pooled = over_all_cells(result)
    lo, hi = pooled["wilson95"]
    return f"{_pct(result['mean_sr'])} ({_pct(lo)}-{_pct(hi)}, n = {pooled['n']})"


def glance_table(by_setting: dict[str, list[dict]], link_prefix: str = "") -> str:
    """Per setting, over its Pick and Place cells: the expert, the best `privileged` and the best `vision` learned
    row and random, as Mean S.R. (pooled Wilson 95%, episodes). A row qualifies if it covers every Pick and Place
    cell of the setting's objects (a row of one skill or a few objects does not). The repository README holds the same
    table with links from the repository root (`link_prefix="leaderboards/"`; tests/eval/test_leaderboard.py)."""
    lines = ["| Setting | Expert | Best privileged | Best vision | Random |", "|---|---|---|---|---|"]
    columns = (("expert", None), (None, "privileged"), (None, "vision"), ("random", None))  # (policy, learned tier)
    for setting in sorted(by_setting):
        objects = set(get_setting(setting).objects)
        full = [r for r in by_setting[setting] if {(c["skill"], c["object"]) for c in r["cells"] if c["n"]}
                == {(k, o) for k in GLANCE_SKILLS for o in objects} and not r["provenance"].get("chain")]
        cells = []
        for policy, tier in columns:
            rows = [r for r in full if r["policy"] == policy] if policy else \
                [r for r in full if r["policy"] not in ("expert", "random") and tier_of_result(r) == tier]
            top = max(rows, key=lambda r: r["mean_sr"]) if rows else None
            cells.append(_glance_cell(top) + (f" {top['policy']}" if top is not None and tier else ""))
        lines.append(f"| [{setting}]({link_prefix}{setting}.md) | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def build_leaderboard(paths: Sequence[str | Path], out: str | Path) -> dict[str, Path]:
    """Write `<setting>.md`, `<setting>.tex`, `index.html` and `README.md` into `out`; returns what was written."""
    out = Path(out)
    by_setting = load_all(paths)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    tables = []
    for setting in sorted(by_setting):
        for result in by_setting[setting]:
            result["_videos"] = [_relative(result["_path"].parent / v, out.resolve()) for v in result.get("videos", [])]
        table = SettingTable(setting, by_setting[setting])
        tables.append(table)
        (out / f"{setting}.md").write_text(render_markdown(table))
        (out / f"{setting}.tex").write_text(render_latex(table))
        written[f"{setting}.md"] = out / f"{setting}.md"
        written[f"{setting}.tex"] = out / f"{setting}.tex"
    (out / "index.html").write_text(render_html(tables))
    written["index.html"] = out / "index.html"
    readme = ["# Leaderboards", "", "Generated by `aerobench leaderboard` from the results files listed in each table; "
              "do not edit by hand.", "", "At a glance, Mean S.R. % over each setting's Pick and Place cells (pooled "
              "Wilson 95% and episodes; the best learned row of each input tier):", "", GLANCE_START,
              glance_table(by_setting), GLANCE_END, ""]
    readme += [f"- [{t.setting}]({t.setting}.md) ({len(t.results)} policies; LaTeX: [{t.setting}.tex]({t.setting}.tex))"
               for t in tables]
    readme += ["", "Open `index.html` in a browser for sortable tables and failure-mode bars.", ""]
    (out / "README.md").write_text("\n".join(readme))
    written["README.md"] = out / "README.md"
    (out / "sources.json").write_text(json.dumps({t.setting: [r["_source"] for r in t.results] for t in tables}, indent=2) + "\n")
    return written


def _relative(target: Path, start: Path) -> str:
    import os

    return os.path.relpath(target, start)
