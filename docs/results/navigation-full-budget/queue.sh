#!/usr/bin/env bash
# Issue 36 (navigation at the paper's budget): seed 1, packaged configs (128 games), evaluations every 2M env steps
# on 200 episodes, from the worktree at 2ff651c. Two one-thread jobs side by side. Re-running resumes.
# usage: queue.sh mappo-n3 | mappo-n4 | saeir-n3
set -euo pipefail
cd "$HOME/saeir-nav-full"
export PYTHONPATH="$HOME/saeir-nav-full"
PY=/work/main/.venv/bin/python
OUT="$HOME/saeir-results/nav-full"
COMMON=(--seeds 1 --eval-episodes 200 --num-threads "${NAV_THREADS:-1}" --jobs 1 --rliable)
echo "$(date -u +%FT%TZ) $1 start (commit $(git rev-parse --short HEAD))"
case "$1" in
  # N=3: 20M env steps = 60M agent-steps, evaluations every 2M env steps = 6M agent-steps
  mappo-n3) $PY -m sb3_saeir.benchmark --algos mappo --tasks cn-sparse-n3 -n 60000000 --eval-freq 6000000 "${COMMON[@]}" --out "$OUT/cn-sparse-n3" ;;
  saeir-n3) $PY -m sb3_saeir.benchmark --algos saeir_ppo --tasks cn-sparse-n3 -n 60000000 --eval-freq 6000000 "${COMMON[@]}" --out "$OUT/cn-sparse-n3" ;;
  # N=4: 20M env steps = 80M agent-steps, evaluations every 2M env steps = 8M agent-steps
  mappo-n4) $PY -m sb3_saeir.benchmark --algos mappo --tasks cn-sparse-n4 -n 80000000 --eval-freq 8000000 "${COMMON[@]}" --out "$OUT/cn-sparse-n4" ;;
esac
echo "$(date -u +%FT%TZ) $1 done"
