"""Fixtures for the LeRobot policy tests: a tiny camera dataset, and running a CLI offline in a subprocess."""

import os
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from aerobench.export import DatasetSink
from aerobench.rollout.runner import RolloutRunner, RolloutSpec


def _run(cmd: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "MS_SKIP_ASSET_DOWNLOAD_PROMPT": "1", "WANDB_MODE": "disabled"}
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"{' '.join(cmd)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc


@pytest.fixture(scope="session")
def run_offline() -> Callable[[list[str], Path], subprocess.CompletedProcess]:
    """`run(cmd, cwd)`: the command, offline, must exit 0 (the failure shows its output's tail)."""
    return _run


@pytest.fixture(scope="session")
def camera_dataset(tmp_path_factory) -> Path:
    """Two short random-policy Pick episodes with the three RGB-D cameras, exported as a LeRobotDataset."""
    root = tmp_path_factory.mktemp("lerobot") / "ds"
    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=2, objects=("master_chef_can",), policy="random",
                       record_cameras=True, max_steps=12)
    sink = DatasetSink(root, {**spec.as_dict(), "keep": "all"})
    RolloutRunner(spec, sink).run()
    sink.close()
    return root
