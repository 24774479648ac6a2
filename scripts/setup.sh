#!/usr/bin/env bash
# Idempotent set-up for aerobench, run by `make setup` (and so by `make demo` / `make test`):
#   1. find a Python 3.12 (PATH, then pyenv's versions) and create .venv;
#   2. install the pinned packages (pyproject.toml + requirements/lock.txt), only when they changed;
#   3. where SAPIEN finds no Vulkan device (no GPU), install CPU Vulkan: Mesa lavapipe from bookworm-backports.
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=.venv
STAMP="$VENV/.aerobench-installed"

find_python312() {
    local candidate
    for candidate in python3.12 python3; do
        if command -v "$candidate" >/dev/null 2>&1 && "$candidate" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 12))' 2>/dev/null; then
            command -v "$candidate"; return 0
        fi
    done
    if command -v pyenv >/dev/null 2>&1; then
        for candidate in "$(pyenv root)"/versions/3.12.*/bin/python3.12; do
            if [ -x "$candidate" ]; then echo "$candidate"; return 0; fi
        done
    fi
    return 1
}

if [ ! -x "$VENV/bin/python" ]; then
    PY=$(find_python312) || {
        echo "setup: error: no Python 3.12 found on PATH or in pyenv; install one (e.g. 'pyenv install 3.12') and re-run" >&2
        exit 1
    }
    echo "setup: creating $VENV with $PY"
    "$PY" -m venv "$VENV"
fi

want=$(cat pyproject.toml plugins/lerobot_env_aerobench/pyproject.toml requirements/lock.txt | sha256sum | cut -d' ' -f1)
if [ "$(cat "$STAMP" 2>/dev/null)" != "$want" ]; then
    echo "setup: installing pinned packages into $VENV (a few minutes the first time)"
    log="$VENV/pip-install.log"
    if ! { "$VENV/bin/python" -m pip install --upgrade pip && "$VENV/bin/python" -m pip install -c requirements/lock.txt -e ".[test]" -e plugins/lerobot_env_aerobench; } >"$log" 2>&1; then
        tail -n 30 "$log" >&2
        echo "setup: error: pip install failed (full log: $log)" >&2
        exit 1
    fi
    echo "$want" > "$STAMP"
fi

vulkan_ok() { "$VENV/bin/python" -c 'import sapien; sapien.render.RenderSystem()' >/dev/null 2>&1; }
if ! vulkan_ok; then
    echo "setup: no Vulkan device for SAPIEN; installing CPU Vulkan (Mesa lavapipe) from bookworm-backports"
    SUDO=""
    if [ "$(id -u)" != 0 ]; then
        command -v sudo >/dev/null 2>&1 || { echo "setup: error: need root (or sudo) to apt-get install mesa-vulkan-drivers" >&2; exit 1; }
        SUDO=sudo
    fi
    command -v apt-get >/dev/null 2>&1 || {
        echo "setup: error: no Vulkan device and no apt-get; install a Vulkan driver (Mesa >= 25 lavapipe or a GPU driver)" >&2
        exit 1
    }
    uris=$(awk '/^URIs:/{print $2; exit}' /etc/apt/sources.list.d/*.sources 2>/dev/null || true)
    [ -n "$uris" ] || uris=$(awk '$1=="deb"{print $2; exit}' /etc/apt/sources.list 2>/dev/null || true)
    [ -n "$uris" ] || { echo "setup: error: cannot find the machine's Debian mirror in /etc/apt to add bookworm-backports" >&2; exit 1; }
    printf 'Types: deb\nURIs: %s\nSuites: bookworm-backports\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' "$uris" \
        | $SUDO tee /etc/apt/sources.list.d/aerobench-backports.sources >/dev/null
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq -t bookworm-backports mesa-vulkan-drivers libvulkan1 >/dev/null
    vulkan_ok || { echo "setup: error: SAPIEN still finds no Vulkan device after installing Mesa lavapipe" >&2; exit 1; }
fi
echo "setup: ready ($("$VENV/bin/python" --version), $("$VENV/bin/python" -c 'import torch, mani_skill, lerobot; print(f"torch {torch.__version__}, mani_skill {mani_skill.__version__}, lerobot {lerobot.__version__}")' 2>/dev/null))"
