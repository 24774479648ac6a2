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
# The eager physics step (same numbers) in every test process and the subprocesses it starts: loading the compiled
# step costs each new process seconds; tests/envs/control/test_fused.py checks the compiled step against it.
os.environ.setdefault("AEROBENCH_COMPILE", "0")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import pytest  # noqa: E402
import torch  # noqa: E402


def pytest_collection_modifyitems(config, items):
    if torch.cuda.is_available():
        return
    skip = pytest.mark.skip(reason="needs a CUDA GPU for physx_cuda; none on this machine (CI is CPU-only)")
    for item in items:
        if "gpu" in item.keywords:
            item.add_marker(skip)
