"""`bench/grasp_creep.py`: one row per solver setting and object, the PGS row holding and the TGS default creeping."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import grasp_creep  # noqa: E402


def test_prints_a_row_per_setting_and_the_default_holds(capsys):
    grasp_creep.main(["--objects", "potted_meat_can", "--steps", "100"])
    rows = [line for line in capsys.readouterr().out.splitlines()[1:] if "potted_meat_can" in line]
    assert len(rows) == len(grasp_creep.SETTINGS)
    slide = {label: float(row[48:].split()[1]) for (label, _), row in zip(grasp_creep.SETTINGS, rows)}
    assert abs(slide["PGS (aerobench default)"]) < 0.005
    assert slide["TGS, 15 position iterations (ManiSkill default)"] > 0.05
