"""Leaderboards rendered from results files, never typed: Markdown and LaTeX per setting, one static HTML page.

Layout follows the spec's PrepareGroceries table: rows policy x skill, columns objects, cells "success % +- SE",
the best policy per skill-object column in bold, and a Mean S.R. column (unweighted mean over the policy's
skill-object pairs). Rows are grouped by what makes them comparable (`row_facts.GroupKey`: protocol, starts,
contact solver): in a group the expert comes first and random last, and "best" is decided within the group and
within one input tier (`aerobench.tiers`: a `vision` row is never ranked against a `privileged` one; random, which
reads nothing, is shown but never best). A row is named short; its recipe (training data, budget, seeds) is a table
of its own, read from its checkpoints, and every table names the results files and the commands that produced them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from .. import tiers
from ..envs.tasks import SKILLS, get_setting
from .pooling import pool_training_runs, training_runs_text
from .results import load_results
from .robustness import robustness_markdown
from .row_facts import GroupKey, group_key, row_facts, short_labels, solver_text, tier_of_result, time_to_success_text

__all__ = ["SettingTable", "glance_table", "render_latex", "render_markdown", "solver_text",
           "tier_of_result"]

OBJECT_LABELS = {
    "master_chef_can": "Master Chef Can", "cracker_box": "Cracker Box", "sugar_box": "Sugar Box",
    "tomato_soup_can": "Tomato Soup Can", "tuna_fish_can": "Tuna Fish Can", "pudding_box": "Pudding Box",
    "gelatin_box": "Gelatin Box", "potted_meat_can": "Potted Meat Can", "bowl": "Bowl", "package": "Package", "": "-",
}
NOT_COMMITTED = "†"  # marks a row whose checkpoint the repository does not hold


def _pct(x: float) -> str:
    return f"{100 * x:.1f}"


def _row_order(result: dict) -> tuple:
    """In a group: the expert first, random last; between them by input tier, the strongest last as in the spec."""
    place = 0 if result["policy"] == "expert" else (2 if result["policy"] == "random" else 1)
    return place, tiers.tier_rank(tier_of_result(result)), result["mean_sr"]


class Group:
    """Rows that ran the same protocol on the same starts under the same solver: their objects, skills and best cells."""

    def __init__(self, key: GroupKey, results: Sequence[dict], object_order: dict[str, int]):
        self.key = key
        self.title = key.title()
        self.results = sorted(results, key=_row_order)
        objects = {c["object"] for r in results for c in r["cells"] if c["n"]}
        self.objects = sorted(objects, key=lambda o: (object_order.get(o, len(object_order)), o))
        rank = {s: i for i, s in enumerate(SKILLS)}
        self.skills = sorted({c["skill"] for r in results for c in r["cells"]}, key=lambda s: (rank.get(s, 99), s))
        self.best: dict[tuple[str, str, str], float] = {}  # (tier, skill, object) -> the tier's best rate
        for tier in {tier_of_result(r) for r in results} - {tiers.NO_INPUTS}:  # random is never best
            mine = [r for r in results if tier_of_result(r) == tier]
            for skill in self.skills:
                for obj in self.objects:
                    rates = [c["success_rate"] for r in mine if (c := SettingTable.cell(r, skill, obj)) is not None]
                    if len(rates) > 1 and max(rates) > 0:
                        self.best[(tier, skill, obj)] = max(rates)

    def is_best_mean(self, result: dict) -> bool:
        tier = tier_of_result(result)
        mine = [r["mean_sr"] for r in self.results if tier_of_result(r) == tier]
        return tier != tiers.NO_INPUTS and len(mine) > 1 and max(mine) > 0 and result["mean_sr"] == max(mine)


def _group_order(group: Group) -> tuple:
    """The groups with an expert first (the reference rows), the ones of random alone and smoke runs last."""
    policies = {r["policy"] for r in group.results}
    return group.key.smoke, policies == {"random"}, "expert" not in policies, bool(group.key.chain), -len(group.results)


class SettingTable:
    """One setting: its comparison groups (in order), every row (group by group), the object columns and row names."""

    def __init__(self, setting: str, results: Sequence[dict]):
        self.setting = setting
        order = {o: i for i, o in enumerate(get_setting(setting).objects)}
        by_key: dict[GroupKey, list[dict]] = {}
        for result in results:
            by_key.setdefault(group_key(result), []).append(result)
        self.groups = sorted((Group(k, rs, order) for k, rs in by_key.items()), key=lambda g: (_group_order(g), g.key.order()))
        self._group_of = {id(r): g for g in self.groups for r in g.results}
        self.results = [r for g in self.groups for r in g.results]
        objects = {c["object"] for r in results for c in r["cells"]}
        self.objects = sorted(objects, key=lambda o: (order.get(o, len(order)), o))
        rank = {s: i for i, s in enumerate(SKILLS)}
        self.skills = sorted({c["skill"] for r in results for c in r["cells"]}, key=lambda s: (rank.get(s, 99), s))
        self._names = short_labels(self.results)
        self.facts = {id(r): row_facts(r) for r in self.results}

    @staticmethod
    def cell(result: dict, skill: str, obj: str) -> dict | None:
        for c in result["cells"]:
            if c["skill"] == skill and c["object"] == obj and c["n"]:
                return c
        return None

    def skills_of(self, result: dict) -> list[str]:
        present = {c["skill"] for c in result["cells"]}
        return [s for s in self.skills if s in present]

    def name(self, result: dict, mark: bool = True) -> str:
        """The row's short name, marked where its checkpoint is not in the repository."""
        missing = mark and self.facts[id(result)].missing
        return self._names[id(result)] + (f" {NOT_COMMITTED}" if missing else "")

    def is_best(self, result: dict, skill: str, obj: str, cell: dict) -> bool:
        """The cell is the best of its column among the rows of its group and of its result's tier."""
        best = self._group_of[id(result)].best
        key = (tier_of_result(result), skill, obj)
        return key in best and abs(cell["success_rate"] - best[key]) < 1e-12

    def is_best_mean(self, result: dict) -> bool:
        return self._group_of[id(result)].is_best_mean(result)


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


def _group_markdown(table: SettingTable, group: Group) -> list[str]:
    header = ["Policy", "Inputs", "Skill", *(OBJECT_LABELS.get(o, o) for o in group.objects), "Mean S.R."]
    lines = ["", f"### {group.title}", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for result in group.results:
        for i, skill in enumerate(table.skills_of(result)):
            cells = []
            for obj in group.objects:
                c = table.cell(result, skill, obj)
                text = "" if c is None else f"{_pct(c['success_rate'])} ± {_pct(c['se'])}"
                cells.append(f"**{text}**" if c is not None and table.is_best(result, skill, obj, c) else text)
            mean = ""
            if i == 0:
                mean = _pct(result["mean_sr"])
                mean = f"**{mean}**" if table.is_best_mean(result) else mean
            first = [table.name(result), tier_of_result(result)] if i == 0 else ["", ""]
            lines.append("| " + " | ".join([*first, skill.capitalize(), *cells, mean]) + " |")
    return lines


def render_markdown(table: SettingTable) -> str:
    lines = [f"## {table.setting}", "",
             "Success % ± binomial standard error per skill-object pair. Rows are grouped by what makes them "
             "comparable: the same protocol, the same starts (`--seed`) and the same contact solver; best per column, "
             "within a group and an input tier, in bold (Inputs: `vision` = cameras, proprioception, instruction; "
             "`privileged` = also the simulator's task state; docs/evaluation.md). Mean S.R.: unweighted mean over "
             "the row's skill-object pairs. The tables below say how each row was trained and produced."]
    for group in table.groups:
        lines += _group_markdown(table, group)
    lines += _chain_markdown(table)
    lines += robustness_markdown(table.results, table.name)
    lines += ["", "### Rows", "", "| Row | Policy | Inputs | Training data | Budget | Training seeds | n per cell | "
              "Contact solver | Time to success (s) | Starts seen in training | Training runs (Mean S.R. each) |",
              "|" + "---|" * 11]
    for result in table.results:
        facts = table.facts[id(result)]
        ns = ", ".join(map(str, sorted({c["n"] for c in result["cells"]})))
        if result.get("training_runs"):
            ns += f" over {len(result['training_runs']['mean_sr'])} runs"
        lines.append(f"| {table.name(result)} | {result['policy']} | {tier_of_result(result)} | {facts.data} | "
                     f"{facts.budget} | {facts.seeds} | {ns} | {solver_text(result)} | {time_to_success_text(result)} | "
                     f"{seen_in_training_text(result)} | {training_runs_text(result)} |")
    missing = [r for r in table.results if table.facts[id(r)].missing]
    lines += ["", "Training data: demonstrations (episodes) and transitions (frames) as the checkpoint records them "
              "(DART / DAgger as its training data is named); budget: gradient steps (BC, LeRobot) or environment "
              "steps (PPO); time to success: median seconds of the successful episodes, per skill (results files "
              "written before the field have none). \"-\": not recorded."]
    if missing:
        lines[-1] += (f" {NOT_COMMITTED} checkpoint not in the repository, so the row cannot be re-scored from a clone: "
                      + "; ".join(f"{table.name(r, mark=False)} (`{', '.join(table.facts[id(r)].missing)}`)"
                                  for r in missing) + ".")
    lines += ["", "### Provenance", "", "| Row | Label | Results file | Command |", "|---|---|---|---|"]
    for result in table.results:
        command = result["provenance"].get("command") or "-"
        lines.append(f"| {table.name(result, mark=False)} | {result['label']} | `{result['_source']}` | `{command}` |")
    return "\n".join(lines) + "\n"


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
            rows.append((table.name(result), name, texts))
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
        + r" & \makecell{Mean S.R.\\(" + " + ".join(_latex_escape(s.capitalize()) for s in table.skills) + r")} \\", r"\hline",
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
            label = f"{table.name(result)} [{tier_of_result(result)}]"
            name = rf"\multirow{{-{len(skills)}}}{{*}}{{{_latex_escape(label)}}}" if last else ""
            mean = ""
            if last:
                value = _pct(result["mean_sr"])
                mean = rf"\multirow{{-{len(skills)}}}{{*}}{{" + (rf"\textbf{{{value}}}" if table.is_best_mean(result) else value) + "}"
            lines.append(f"{name} & {_latex_escape(skill.capitalize())} & " + " & ".join(cells) + f" & {mean} \\\\")
        lines.append(r"\hline")
    lines += [r"\end{tabular}%", "}", r"\end{table*}"]
    return "\n".join(lines) + "\n"


def _latex_escape(text: str) -> str:
    for a, b in (("\\", r"\textbackslash{}"), ("_", r"\_"), ("%", r"\%"), ("&", r"\&"), ("#", r"\#")):
        text = text.replace(a, b)
    return text


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
    table with links from the repository root (`link_prefix="leaderboards/"`; tests/test_docs.py)."""
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
