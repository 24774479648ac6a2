"""What the benches that chain the CLI's commands share (bench/dagger.py, bench/vision_policies.py): each named step
runs once, as a user would type it, and leaves a marker, so a rerun of the bench continues where it stopped."""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
from pathlib import Path


def aerobench(*args: object) -> list[str]:
    """An `aerobench` command line, without the program name."""
    return [str(a) for a in args]


class Steps:
    """Runs each named step once: a marker under out/done says it finished; its output is in out/<name>.log. A step
    of one command runs in this process (the CLI's imports are paid once); shards run as processes at once."""

    def __init__(self, out: Path, tag: str):
        self.out, self.tag = out, tag
        (out / "done").mkdir(parents=True, exist_ok=True)

    def done(self, name: str) -> bool:
        return (self.out / "done" / name).exists()

    def run(self, name: str, *commands: list[str]) -> None:
        marker = self.out / "done" / name
        if marker.exists():
            return
        print(f"[{self.tag}] {name}", flush=True)
        logs = [self.out / f"{name}{'' if len(commands) == 1 else f'.{i}'}.log" for i in range(len(commands))]
        for log, cmd in zip(logs, commands):
            with open(log, "a") as f:
                f.write("$ aerobench " + " ".join(cmd) + "\n")
        codes = [self._in_process(commands[0], logs[0])] if len(commands) == 1 else self._processes(commands, logs)
        failed = [str(log) for log, code in zip(logs, codes) if code != 0]
        if failed:
            raise SystemExit(f"[{self.tag}] step {name} failed; see {', '.join(failed)} (rerun the command to continue)")
        marker.write_text(json.dumps(["aerobench " + " ".join(c) for c in commands]) + "\n")

    @staticmethod
    def _in_process(cmd: list[str], log: Path) -> int:
        from aerobench.cli import main as cli

        with open(log, "a") as f, contextlib.redirect_stdout(f), contextlib.redirect_stderr(f):
            try:
                return cli(cmd)
            except SystemExit as e:  # argparse's exit on a bad flag
                return e.code if isinstance(e.code, int) else 1

    @staticmethod
    def _processes(commands: list[list[str]], logs: list[Path]) -> list[int]:
        program = str(Path(sys.executable).with_name("aerobench"))
        procs = []
        for cmd, log in zip(commands, logs):
            with open(log, "a") as f:
                procs.append(subprocess.Popen([program, *cmd], stdout=f, stderr=subprocess.STDOUT))
        return [p.wait() for p in procs]
