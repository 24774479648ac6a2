"""Fixtures of the env tests."""

import os

import pytest


@pytest.fixture(scope="module")
def aot_cache(tmp_path_factory):
    """One ahead-of-time package cache for this test run (never the user's), shared by pytest-xdist's workers so a
    package is built once per run."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    base = tmp_path_factory.getbasetemp()
    root = base.parent / f"aerobench_cache_{run}" if run else base / "aerobench_cache"
    root.mkdir(exist_ok=True)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("AEROBENCH_CACHE_DIR", str(root))
        yield root
