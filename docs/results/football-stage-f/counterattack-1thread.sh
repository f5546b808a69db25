#!/usr/bin/env bash
# Stage F's first run with one torch thread (for sharing the machine with a one-thread navigation job); else queue.sh.
set -euo pipefail
cd "$HOME/saeir-stage-f"
echo "$(date -u +%FT%TZ) counterattack saeir_ppo, --num-threads 1 (commit $(git rev-parse --short HEAD))"
.venv/bin/python -m sb3_saeir.benchmark --algos saeir_ppo --tasks grf-counterattack-easy --seeds 1 -n 8000000 \
    --eval-freq 1000000 --n-games 8 --eval-episodes 100 -params num_cpus:2 --num-threads 1 --jobs 1 --rliable \
    --out "$HOME/saeir-results/stage-f/counterattack"
