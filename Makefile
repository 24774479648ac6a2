# aerobench: `make demo` and `make test` set everything up first (idempotent), then run.
VENV := .venv
PY := $(VENV)/bin/python
CACHE := $(CURDIR)/.cache

# Offline by default; caches stay inside the project.
export HF_HUB_OFFLINE := 1
export MS_SKIP_ASSET_DOWNLOAD_PROMPT := 1
export XDG_CACHE_HOME := $(CACHE)
export HF_HOME := $(CACHE)/huggingface
export MPLCONFIGDIR := $(CACHE)/matplotlib
export MS_ASSET_DIR := $(CACHE)/maniskill

.PHONY: setup demo test bench lint clean

setup:
	@bash scripts/setup.sh

demo: setup
	$(VENV)/bin/aerobench demo --out outputs/demo

test: setup
	@bash scripts/setup_browser.sh
	$(PY) -m pytest -n 2 --dist loadgroup -q --durations=25 tests

bench: setup
	@for f in bench/*.py; do echo "== $$f"; $(PY) $$f || exit 1; done

lint: setup
	$(VENV)/bin/ruff check aerobench tests bench

clean:
	rm -rf outputs .pytest_cache
