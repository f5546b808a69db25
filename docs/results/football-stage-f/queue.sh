#!/usr/bin/env bash
# Issue 32 (football stage F): the six runs, one benchmark job at a time, from the worktree at 466a253.
# Re-running this script resumes: the benchmark skips finished runs and continues started ones from their checkpoints.
set -euo pipefail
cd "$HOME/saeir-stage-f"
PY=.venv/bin/python
OUT="$HOME/saeir-results/stage-f"
COMMON=(--n-games 8 --eval-episodes 100 -params num_cpus:2 --num-threads 2 --jobs 1 --rliable)
echo "$(date -u +%FT%TZ) queue start (commit $(git rev-parse --short HEAD))"
# counterattack easy: 4 agents, 2M env steps = 8M agent-steps, evaluations every 250k env steps = 1M agent-steps
$PY -m sb3_saeir.benchmark --algos saeir_ppo --tasks grf-counterattack-easy --seeds 1 -n 8000000 --eval-freq 1000000 \
    "${COMMON[@]}" --out "$OUT/counterattack"
$PY -m sb3_saeir.benchmark --algos mappo --tasks grf-counterattack-easy --seeds 1 -n 8000000 --eval-freq 1000000 \
    "${COMMON[@]}" --out "$OUT/counterattack"
# 3 vs 1 with keeper: 3 agents, 2M env steps = 6M agent-steps, evaluations every 750k agent-steps (seed 1's protocol)
for seed in 2 3; do
    for algo in saeir_ppo mappo; do
        $PY -m sb3_saeir.benchmark --algos $algo --tasks grf-3v1-keeper --seeds $seed -n 6000000 --eval-freq 750000 \
            "${COMMON[@]}" --out "$OUT/3v1"
    done
done
echo "$(date -u +%FT%TZ) queue done"
