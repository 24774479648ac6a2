"""bench/gpu_check.py: one line and exit 0 without CUDA; its workers run (on physx_cpu, one env) and its tables land
between their markers. The GPU run itself is for a machine with CUDA (docs/gpu.md)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

import gpu_check  # noqa: E402

CONTEXT = {"date": "2026-12-05", "device": "test device", "commit": "abc1234"}


def test_without_cuda_it_prints_one_line_and_exits_0():
    env = dict(os.environ, CUDA_VISIBLE_DEVICES="")  # hides a GPU where the tests run on one
    result = subprocess.run([sys.executable, str(BENCH / "gpu_check.py")], capture_output=True, text=True, env=env,
                            timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.splitlines() == [gpu_check.NEEDS_GPU]


def test_the_tables_replace_what_is_between_their_markers_and_nothing_else():
    doc = "# GPU\n\nbefore\n<!-- gpu_check:starts -->\nold table\n<!-- /gpu_check:starts -->\nafter\n"
    written = gpu_check.write_blocks(doc, {"starts": "new table", "state": "state table"})
    assert "old table" not in written and "new table" in written
    assert written.startswith("# GPU\n\nbefore\n<!-- gpu_check:starts -->\nnew table\n<!-- /gpu_check:starts -->\nafter")
    assert written.rstrip().endswith("<!-- gpu_check:state -->\nstate table\n<!-- /gpu_check:state -->")
    assert gpu_check.write_blocks(written, {"starts": "new table", "state": "state table"}) == written


def test_the_committed_doc_has_a_marked_block_for_every_job():
    text = (BENCH.parent / "docs" / "gpu.md").read_text()
    for job in gpu_check.JOBS:
        assert gpu_check.marker(job) in text and gpu_check.marker(job, end=True) in text, job


def test_pytests_summary_names_failures_and_collection_errors():
    out = ("..F\nFAILED tests/envs/test_gpu.py::test_batched_gpu_hover[arm] - assert 0.02 < 0.01\n"
           "ERROR tests/policies/test_pi_policies.py\n1 failed, 2 passed, 700 deselected, 1 error in 40.2s\n")
    s = gpu_check.summarize_pytest({"stdout": out})
    assert s["counts"] == "1 failed, 2 passed, 700 deselected, 1 error"
    assert s["failed"] == ["tests/envs/test_gpu.py::test_batched_gpu_hover[arm]"]
    assert s["errors"] == ["tests/policies/test_pi_policies.py"]


def test_the_workers_run_on_physx_cpu_and_their_rows_render():
    """One env each: the batched-vs-one-env comparison (here a batch of one) finds the committed CPU start of
    AeroNav-v1 seed 4; a hovering AeroFly-v1 row; three expert steps."""
    (starts,) = gpu_check.starts_rows("physx_cpu", cases=[("AeroNav-v1", {"setting": "PackageDelivery"}, [(4, None)])],
                                      tolerance=1e-5)
    assert "error" not in starts, starts
    assert (starts["equal"], starts["cpu_equal"], starts["cpu_of"]) == (1, 1, 1)
    (fly,) = gpu_check.throughput_rows("physx_cpu", "state", [1], steps=2, deadline=float("inf"),
                                       envs=(("AeroFly-v1", {}),))
    assert "error" not in fly and fly["ms_per_step"] > 0 and fly["env_steps_per_s"] > 0, fly
    expert = gpu_check.expert_row("physx_cpu", 1, deadline=float("inf"), max_steps=3)
    assert expert["solver"] == "pgs" and expert["steps"] <= 3 and len(expert["success_rows"]) == 1
    job = {"rc": 0, "seconds": 1.0, "stderr": ""}
    assert "| AeroNav-v1 setting=PackageDelivery | 1 | 1/1 | 1/1 | none |" in gpu_check.render_starts(
        {**job, "rows": [starts]}, CONTEXT)
    assert f"| AeroFly-v1 | state | 1 | {fly['setup_s']} |" in gpu_check.render_throughput({**job, "rows": [fly]}, CONTEXT)
    assert "| PGS | 1 |" in gpu_check.render_expert([{**job, "rows": [expert]}], CONTEXT)
    runs = list(gpu_check.runner_rows("physx_cpu", 1, deadline=float("inf"), max_steps=3))
    assert [(r["episodes_per_scene"], r["episodes"]) for r in runs] == [(1, 2), (2, 2)], runs
    assert all("error" not in r and r["episodes_per_min"] > 0 for r in runs)
    assert "| 1 | 2 | 2 | 0 |" in gpu_check.render_runner({**job, "rows": runs}, CONTEXT)
