#!/usr/bin/env bash
# Issue 64 part 3 (Table 1, navigation, on the reading without the collision penalty): the paper's budget, 20M env
# steps, issue 51's protocol (the packaged configs: 128 games; evaluations every 1M env steps and at 0 on 200 greedy
# episodes; one torch thread per job; SAEIR_PPO with the compiled networks, compile:True, as in issue 51). Fixed before
# any result: all six runs go to 20M env steps, whatever the curves do. Two lanes side by side, each a queue of runs:
#   lane 1: MAPPO N=4 s1, MAPPO N=3 s2, MAPPO N=3 s3, SAEIR_PPO N=3 s3
#   lane 2: SAEIR_PPO N=4 s1, SAEIR_PPO N=3 s2
# (the N=4 pair first, then N=3 seeds 2 and 3; the lanes are balanced on the measured walls of issue 51.)
# Runs from the worktree at $WORKTREE (a fixed commit). Re-running a lane resumes it: finished runs are skipped, an
# unfinished one continues from its newest checkpoint (the benchmark's own resume).
# usage: queue.sh lane1 | lane2 | JOB      (JOB: mappo-n4-s1 saeir-n4-s1 mappo-n3-s2 saeir-n3-s2 mappo-n3-s3 saeir-n3-s3)
set -euo pipefail
WORKTREE="${WORKTREE:-$HOME/saeir-table1}"
cd "$WORKTREE"
export PYTHONPATH="$WORKTREE"
PY="${PY:-/work/main/.venv/bin/python}"
OUT="$HOME/saeir-results/table1-navigation"
PROTOCOL=(--eval-episodes 200 --num-threads 1 --jobs 1 --rliable)

job() {  # job ALGO N SEED
    local algo=$1 n=$2 seed=$3 extra=()
    local agent_steps=$((20000000 * n)) eval_freq=$((1000000 * n))
    [ "$algo" = saeir_ppo ] && extra=(-params compile:True)
    echo "$(date -u +%FT%TZ) $algo n$n s$seed start (commit $(git rev-parse --short HEAD))"
    "$PY" -m sb3_saeir.benchmark --algos "$algo" --tasks "cn-sparse-no-penalty-n$n" --seeds "$seed" -n "$agent_steps" \
        --eval-freq "$eval_freq" "${PROTOCOL[@]}" "${extra[@]}" --out "$OUT/n$n"
    echo "$(date -u +%FT%TZ) $algo n$n s$seed done"
}

case "$1" in
  lane1) job mappo 4 1; job mappo 3 2; job mappo 3 3; job saeir_ppo 3 3 ;;
  lane2) job saeir_ppo 4 1; job saeir_ppo 3 2 ;;
  mappo-n4-s1) job mappo 4 1 ;;
  saeir-n4-s1) job saeir_ppo 4 1 ;;
  mappo-n3-s2) job mappo 3 2 ;;
  saeir-n3-s2) job saeir_ppo 3 2 ;;
  mappo-n3-s3) job mappo 3 3 ;;
  saeir-n3-s3) job saeir_ppo 3 3 ;;
  *) echo "unknown job $1 (lane1, lane2, or one run: mappo-n4-s1 saeir-n4-s1 ...)"; exit 2 ;;
esac
