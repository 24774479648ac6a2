"""`aerobench ARGS` run in the test's own process, answered as `subprocess.run` answers.

A subprocess pays 7-15 s of imports (torch, ManiSkill, LeRobot) on the 2-core machine before it reads its first
argument; the test process has them loaded. The same `main` parses and runs, and its one-line errors and exit status
are the ones the shell sees. Tests that need the installed entry point itself, a process to kill, or a fresh process
(a decoder probe, worker start-up) still start one.
"""

from __future__ import annotations

import io
import subprocess
from contextlib import redirect_stderr, redirect_stdout


def aerobench_here(*args: str) -> subprocess.CompletedProcess:
    from aerobench.cli import main

    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as stop:  # argparse's own errors and --help
            code = stop.code if isinstance(stop.code, int) else 1
    return subprocess.CompletedProcess(["aerobench", *args], code, out.getvalue(), err.getvalue())
