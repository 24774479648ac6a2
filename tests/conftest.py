"""Shared test set-up: offline, quiet, caches in a temp dir; GPU tests skip with a reason where there is no GPU."""

import atexit
import logging
import os
import shutil
import tempfile

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
_cache = tempfile.mkdtemp(prefix="aerobench-test-cache-")
atexit.register(shutil.rmtree, _cache, ignore_errors=True)
os.environ.setdefault("XDG_CACHE_HOME", _cache)
os.environ.setdefault("MPLCONFIGDIR", os.path.join(_cache, "matplotlib"))
os.environ.setdefault("HF_HOME", os.path.join(_cache, "huggingface"))
# The eager kernels (physics step, shared signals, the place evaluator's and the pick and place experts' steps: the
# same numbers) in every test process and the subprocesses it starts: loading a compiled one costs each new process
# seconds. The compiled ones are checked against them by tests/envs/control/test_fused.py, tests/envs/test_signals.py,
# tests/envs/test_place_update.py and tests/expert/test_expert_steps.py.
os.environ.setdefault("AEROBENCH_COMPILE", "0")
# The two xdist workers share the 2 cores: one intra-op thread per test process and per subprocess it starts, so
# the workers never run more compute threads than there are cores. With torch's default of two OpenMP threads each,
# a fresh-clone `make test` spent 43 min of CPU in 23.7 min of pytest (ACT's and pi0.5's lerobot-train side by side:
# 721 s and 705 s); with one, 18 min of CPU in 10.7 min (the same two tests: 28 s and 34 s).
os.environ.setdefault("OMP_NUM_THREADS", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import pytest  # noqa: E402
import torch  # noqa: E402

torch.set_num_threads(int(os.environ["OMP_NUM_THREADS"]))  # in case a plugin imported torch before this file


def pytest_collection_modifyitems(config, items):
    if torch.cuda.is_available():
        return
    skip = pytest.mark.skip(reason="needs a CUDA GPU for physx_cuda; none on this machine (CI is CPU-only)")
    for item in items:
        if "gpu" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="module")
def aot_cache(tmp_path_factory):
    """One ahead-of-time package cache for this test run (never the user's), shared by pytest-xdist's workers. The
    modules whose kernels are the env's own (the flight step, signals, evaluators, expert steps) are marked
    `xdist_group("aot_packages")`: `make test` runs with `--dist loadgroup`, so one worker builds each such package
    once and the later tests load it (two workers built the same packages side by side: 15-30 s each)."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    base = tmp_path_factory.getbasetemp()
    root = base.parent / f"aerobench_cache_{run}" if run else base / "aerobench_cache"
    root.mkdir(exist_ok=True)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("AEROBENCH_CACHE_DIR", str(root))
        yield root
