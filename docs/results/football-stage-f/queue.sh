#!/usr/bin/env bash
# Issue 32 (football stage F): the six runs, one benchmark job at a time, from the worktree at 466a253.
#
#   bash docs/results/football-stage-f/queue.sh                          # every run not yet committed as done
#   bash docs/results/football-stage-f/queue.sh 3v1:mappo:3 counterattack:mappo:1   # only these, in this order
#
# A run is <folder>:<algo>:<seed> (folder: counterattack or 3v1). A run whose done.json is committed beside this script
# (<folder>/runs/<algo>/<task>_s<seed>/done.json) is skipped: it was made on another machine, whose results folder
# this one does not have. Re-running resumes: the benchmark skips finished runs of $OUT and continues started ones
# from their checkpoints (on the machine that holds them).
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
cd "$HOME/saeir-stage-f"
PY=.venv/bin/python
OUT="$HOME/saeir-results/stage-f"
COMMON=(--n-games 8 --eval-episodes 100 -params num_cpus:2 --num-threads 2 --jobs 1 --rliable)
# counterattack easy first (SAEIR_PPO, then MAPPO), then 3 vs 1 seeds 2 and 3, each SAEIR_PPO then MAPPO
ALL_RUNS=(counterattack:saeir_ppo:1 counterattack:mappo:1 3v1:saeir_ppo:2 3v1:mappo:2 3v1:saeir_ppo:3 3v1:mappo:3)
RUNS=("$@")
[ ${#RUNS[@]} -gt 0 ] || RUNS=("${ALL_RUNS[@]}")
echo "$(date -u +%FT%TZ) queue start (commit $(git rev-parse --short HEAD)): ${RUNS[*]}"
for run in "${RUNS[@]}"; do
    IFS=: read -r folder algo seed <<< "$run"
    case "$folder" in
        # 4 agents, 2M env steps = 8M agent-steps, evaluations every 250k env steps = 1M agent-steps
        counterattack) task=grf-counterattack-easy; budget=(-n 8000000 --eval-freq 1000000) ;;
        # 3 agents, 2M env steps = 6M agent-steps, evaluations every 750k agent-steps (seed 1's protocol)
        3v1) task=grf-3v1-keeper; budget=(-n 6000000 --eval-freq 750000) ;;
        *) echo "unknown run '$run': use <counterattack|3v1>:<saeir_ppo|mappo>:<seed>" >&2; exit 2 ;;
    esac
    if [ -f "$HERE/$folder/runs/$algo/${task}_s$seed/done.json" ]; then
        echo "$(date -u +%FT%TZ) $run: committed as done in $HERE/$folder, skipped"
        continue
    fi
    echo "$(date -u +%FT%TZ) $run: start"
    $PY -m sb3_saeir.benchmark --algos "$algo" --tasks "$task" --seeds "$seed" "${budget[@]}" "${COMMON[@]}" \
        --out "$OUT/$folder"
done
echo "$(date -u +%FT%TZ) queue done"
