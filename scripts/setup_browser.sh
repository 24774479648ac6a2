#!/usr/bin/env bash
# Headless Chromium for the leaderboard HTML test (`make test`); idempotent. Debian's `chromium` package.
set -euo pipefail
if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then exit 0; fi
SUDO=""
if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null 2>&1 || { echo "setup: error: need root (or sudo) to apt-get install chromium" >&2; exit 1; }
    SUDO=sudo
fi
command -v apt-get >/dev/null 2>&1 || { echo "setup: error: no apt-get; install Chromium yourself for the HTML leaderboard test" >&2; exit 1; }
echo "setup: installing headless Chromium (Debian package chromium) for the leaderboard test"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
