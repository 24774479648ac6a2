"""The README and docs/ as a reader meets them: every relative link resolves, the README's results table is the one
the committed results files generate, and the README opens with the two commands a new user runs."""

import re
from pathlib import Path

import pytest

from aerobench.eval.leaderboard import GLANCE_END, GLANCE_START, glance_table, load_all

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
# docs/notebook/ is the dated history, kept as written (its links point at sections of pages that have moved on)
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]

FENCE = re.compile(r"^(```|~~~).*?^\1[^\n]*$", re.MULTILINE | re.DOTALL)
INLINE_CODE = re.compile(r"`[^`\n]*`")
LINK = re.compile(r"\]\(\s*<?([^()\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
EXTERNAL = ("http://", "https://", "mailto:")


def relative_links(text: str) -> list[str]:
    """The targets of the Markdown links `[..](target)` and images `![..](target)` a renderer would make: not in
    fenced code blocks or inline code, not external, not a bare `#anchor`; the `#anchor` part is dropped."""
    prose = INLINE_CODE.sub("", FENCE.sub("", text))
    targets = []
    for target in LINK.findall(prose):
        if target.startswith(EXTERNAL) or target.startswith("#"):
            continue
        targets.append(target.split("#", 1)[0])
    return targets


def test_the_link_finder_sees_links_and_skips_code_and_external_ones():
    text = ("see [a](docs/a.md), [b](b.md#part) and ![img](img/x.png); [web](https://x.org) [mail](mailto:a@b) "
            "[here](#anchor) `[not](code.md)`\n```\n[not](fenced.md)\n```\n[c]( c.md \"title\")\n")
    assert relative_links(text) == ["docs/a.md", "b.md", "img/x.png", "c.md"]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_points_to_a_file_that_exists(page):
    broken = [t for t in relative_links(page.read_text()) if not (page.parent / t).exists()]
    assert not broken, f"{page.relative_to(ROOT)} links to paths that do not exist (relative to its folder): {broken}"


def test_the_pages_have_links_to_check():
    """Guards the link test against a finder that silently matches nothing."""
    assert len(relative_links(README.read_text())) >= 10


def readme_glance() -> str:
    text = README.read_text()
    assert text.count(GLANCE_START) == 1 and text.count(GLANCE_END) == 1, \
        f"README.md must hold the results table once, between {GLANCE_START} and {GLANCE_END}"
    return text.split(GLANCE_START, 1)[1].split(GLANCE_END, 1)[0].strip()


@pytest.fixture(scope="module")
def by_setting():
    """The committed results, loaded as `build_leaderboard` loads them for leaderboards/README.md."""
    return load_all(sorted((ROOT / "leaderboards" / "results").glob("*.json")))


def test_the_readme_results_table_is_the_one_the_results_files_generate(by_setting):
    expected = glance_table(by_setting, link_prefix="leaderboards/").strip()
    assert readme_glance() == expected, (
        "README.md's results table differs from the one leaderboards/results/*.json generate; replace the lines "
        f"between its markers with:\n{expected}")


def test_the_readme_says_no_vision_row_exists_exactly_when_the_vision_column_is_empty():
    """The sentence under the table must not outlive the table it describes."""
    rows = [line for line in readme_glance().splitlines()[2:] if line.startswith("|")]
    assert rows, "the README's results table has no rows"
    header = [c.strip() for c in readme_glance().splitlines()[0].strip("|").split("|")]
    vision = header.index("Best vision")
    vision_empty = all(line.strip().strip("|").split("|")[vision].strip() == "-" for line in rows)
    says_none = "No `vision` row exists yet" in " ".join(README.read_text().split())
    assert says_none == vision_empty, (
        "README.md says no vision row exists, but its table has one" if says_none
        else "README.md's vision column is empty; say so under the table (No `vision` row exists yet)")


def test_the_readme_opens_with_make_demo_and_make_test():
    first_block = re.search(r"^```[^\n]*\n(.*?)^```", README.read_text(), re.MULTILINE | re.DOTALL)
    assert first_block, "README.md has no fenced code block"
    commands = first_block.group(1)
    assert "make demo" in commands and "make test" in commands, \
        f"README.md's first code block should give `make demo` and `make test`, not:\n{commands}"
