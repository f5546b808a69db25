#!/usr/bin/env bash
# Create .venv (if missing) and install sb3-saeir with the given extras, torch==2.13.0 first.
# Usage: bash scripts/install.sh [extras]     e.g. bash scripts/install.sh tests,zoo,plots
set -euo pipefail
cd "$(dirname "$0")/.."
EXTRAS="${1:-}"
PYTHON="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
    "$PYTHON" -m venv .venv
fi
# torch first: the pinned CPU build; any other torch request may pull a multi-GB CUDA build.
.venv/bin/python -m pip install --quiet --disable-pip-version-check "torch==2.13.0"
if [ -n "$EXTRAS" ]; then
    .venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".[$EXTRAS]" "torch==2.13.0"
else
    .venv/bin/python -m pip install --quiet --disable-pip-version-check -e . "torch==2.13.0"
fi
