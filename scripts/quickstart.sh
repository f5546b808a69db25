#!/usr/bin/env bash
# The README's main job: set up .venv (with the plots extra: matplotlib, imageio), train SAEIR_PPO on sparse
# Cooperative Navigation N=3 without the collision penalty (cn-sparse-no-penalty-n3) for about 4 minutes on 2 cores,
# compare it with a random policy on the same evaluation episodes, and write the model, logs, eval.json,
# learning_curve.png and replay.gif into runs/quickstart/.
# Usage: bash scripts/quickstart.sh [arguments for examples/train_cn_sparse.py]   e.g. --timesteps 2000000 --seed 1
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh plots
OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}" .venv/bin/python examples/train_cn_sparse.py "$@"
