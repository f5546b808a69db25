#!/usr/bin/env bash
# Issue 51 part 1 (navigation, calibrated task readings at the paper's budget): seed 1, packaged configs (128 games),
# 20M env steps = 60M agent-steps, evaluations every 1M env steps (3M agent-steps) on 200 greedy episodes, from the
# worktree at 6cb8124. One-thread jobs. Re-running resumes from the newest checkpoint. SAEIR_PPO runs with the compiled
# networks (compile:True, measured 1.26x faster update on this task, same maths within 1e-4; no setting changes).
# usage: queue.sh mappo-no-penalty | mappo-reach | saeir-no-penalty | saeir-reach
set -euo pipefail
cd "$HOME/saeir-nav-cal"
export PYTHONPATH="$HOME/saeir-nav-cal"
PY=/work/main/.venv/bin/python
OUT="$HOME/saeir-results/nav-calibrated"
COMMON=(--tasks cn-sparse-n3 --seeds 1 -n 60000000 --eval-freq 3000000 --eval-episodes 200 --num-threads 1 --jobs 1 --rliable)
NO_PENALTY="env_kwargs:{N: 3, collision_penalty: 0.0}"
REACH="env_kwargs:{N: 3, reward: reach}"
echo "$(date -u +%FT%TZ) $1 start (commit $(git rev-parse --short HEAD))"
case "$1" in
  mappo-no-penalty) $PY -m sb3_saeir.benchmark --algos mappo "${COMMON[@]}" -params "$NO_PENALTY" --out "$OUT/no-penalty" ;;
  saeir-no-penalty) $PY -m sb3_saeir.benchmark --algos saeir_ppo "${COMMON[@]}" -params "$NO_PENALTY" compile:True --out "$OUT/no-penalty" ;;
  mappo-reach) $PY -m sb3_saeir.benchmark --algos mappo "${COMMON[@]}" -params "$REACH" --out "$OUT/reach" ;;
  saeir-reach) $PY -m sb3_saeir.benchmark --algos saeir_ppo "${COMMON[@]}" -params "$REACH" compile:True --out "$OUT/reach" ;;
  *) echo "unknown job $1"; exit 2 ;;
esac
echo "$(date -u +%FT%TZ) $1 done"
