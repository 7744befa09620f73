#!/usr/bin/env bash
# Headless Chromium for the report's browser test (tests/report.rs): Debian's `chromium`
# package, installed when missing (root, or through sudo). Prints the variables to export:
#   eval "$(scripts/setup-chromium.sh)"
# MUSCULO_REQUIRE_CHROMIUM=1 makes a missing browser a test failure instead of a skip.
set -euo pipefail

locate() { command -v chromium || command -v chromium-browser || true; }

browser="$(locate)"
if [ -z "$browser" ]; then
    if [ "$(id -u)" = 0 ]; then
        sudo=""
    elif command -v sudo >/dev/null; then
        sudo="sudo"
    else
        echo "setup-chromium: chromium is missing and this user cannot install it (not root, no sudo)" >&2
        exit 1
    fi
    $sudo apt-get update -q >&2
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends chromium >&2
    browser="$(locate)"
fi
[ -n "$browser" ] || { echo "setup-chromium: chromium not found after installing it" >&2; exit 1; }
echo "export MUSCULO_CHROMIUM='$browser' MUSCULO_REQUIRE_CHROMIUM=1"
