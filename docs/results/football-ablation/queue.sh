#!/usr/bin/env bash
# Issue 65 (football 3 vs 1: which half of SAEIR leaves the floor earlier): eight runs, one benchmark job at a time,
# stage F's protocol (the packaged configs, 8 games on 2 env workers, two torch threads, evaluations every 250k env
# steps and at 0 on 100 greedy episodes), to 1M env steps = 3M agent-steps, from the worktree at $WORKTREE (a fixed
# commit). Order: MSHG-only and SAE-only seeds 1 and MSHG-only seed 2, then SAEIR_PPO and MAPPO seed 4 (SAEIR_PPO
# seed 4's kept models are what part 3 reads), then SAE-only seed 2 and both ablations' seed 3. The order changes no
# setting of a run; the rule is read only when every run it needs is final.
#
#   bash docs/results/football-ablation/queue.sh                        # every run not yet committed as done
#   bash docs/results/football-ablation/queue.sh sae_only:2 mappo:4     # only these, in this order
#
# SAEIR_PPO seed 4 is trained in four legs (-n 750k, 1.5M, 2.25M, 3M agent-steps; a finished run trained longer goes
# on from its last step, the football games from a reset as on any resume), and each leg's final model is kept with
# its spec.json in $KEEP/saeir_ppo_s4_<thousands of env steps>k/ for benchmarks/bonus_rise.py (outside the
# repository); a resumed queue starts at the first leg not kept.
# A run whose done.json is committed beside this script at the full budget (3M agent-steps; SAEIR_PPO seed 4 writes
# one after each leg) is skipped; re-running resumes the others from their checkpoints (the benchmark's own resume).
# When a navigation pair shares the machine, pause it while this queue runs, or run it in its own session at
# autogroup nice 19 (echo 19 > /proc/<pid>/autogroup; plain nice does not hold across sessions), and note it in
# $OUT/scheduling.log.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
WORKTREE="${WORKTREE:-$HOME/saeir-football-ablation}"
cd "$WORKTREE"
export PYTHONPATH="$WORKTREE"
PY="${PY:-/work/main/.venv/bin/python}"
OUT="$HOME/saeir-results/football-ablation"
KEEP="$OUT/kept-models"
TASK=grf-3v1-keeper
COMMON=(--tasks "$TASK" --n-games 8 --eval-freq 750000 --eval-episodes 100 -params num_cpus:2 --num-threads 2 --jobs 1)
ALL_RUNS=(mshg_only:1 sae_only:1 mshg_only:2 saeir_ppo:4 mappo:4 sae_only:2 mshg_only:3 sae_only:3)
RUNS=("$@")
[ ${#RUNS[@]} -gt 0 ] || RUNS=("${ALL_RUNS[@]}")
mkdir -p "$OUT" "$KEEP"
echo "$(date -u +%FT%TZ) queue start (commit $(git rev-parse --short HEAD)): ${RUNS[*]}"
for run in "${RUNS[@]}"; do
    IFS=: read -r algo seed <<< "$run"
    done_file="$HERE/runs/$algo/${TASK}_s$seed/done.json"
    # skipped only when the committed done.json is at the full budget: SAEIR_PPO seed 4 writes one after each leg
    if [ -f "$done_file" ] && [ "$(sed -n 's/.*"timesteps": *\([0-9]*\).*/\1/p' "$done_file")" -ge 3000000 ]; then
        echo "$(date -u +%FT%TZ) $run: committed as done, skipped"
        continue
    fi
    echo "$(date -u +%FT%TZ) $run: start"
    if [ "$run" = saeir_ppo:4 ]; then
        for leg in 750000 1500000 2250000 3000000; do
            kept="$KEEP/saeir_ppo_s4_$((leg / 3000))k"  # the model and its spec.json, as bonus_rise.py reads them
            # a kept leg is done: resuming starts at the first leg not kept (a smaller budget than the run's spec
            # would not resume it, and would overwrite an earlier leg's kept model with a later one)
            if [ -f "$kept/$TASK.zip" ]; then
                echo "$(date -u +%FT%TZ) $run: leg to $leg agent-steps kept in $kept, skipped"
                continue
            fi
            "$PY" -m sb3_saeir.benchmark --algos "$algo" --seeds "$seed" -n "$leg" "${COMMON[@]}" --rliable --out "$OUT"
            rm -rf "$kept.partial" && mkdir -p "$kept.partial"
            cp "$OUT/runs/$algo/${TASK}_s$seed/$TASK.zip" "$OUT/runs/$algo/${TASK}_s$seed/spec.json" "$kept.partial/"
            rm -rf "$kept"  # (only an interrupted earlier copy can have left it, without the model)
            mv "$kept.partial" "$kept"  # whole or not at all: a kill during the copy leaves no kept leg
        done
    else
        "$PY" -m sb3_saeir.benchmark --algos "$algo" --seeds "$seed" -n 3000000 "${COMMON[@]}" --rliable --out "$OUT"
    fi
    echo "$(date -u +%FT%TZ) $run: done"
done
echo "$(date -u +%FT%TZ) queue done"
