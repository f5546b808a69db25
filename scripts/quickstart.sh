#!/usr/bin/env bash
# The README's main job: set up .venv and train on sparse Cooperative Navigation N=3 with the default settings,
# then evaluate and print where the model and the metrics are.
# Usage: bash scripts/quickstart.sh [extra arguments for examples/train_cn_sparse.py]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
.venv/bin/python examples/train_cn_sparse.py "$@"
