#!/usr/bin/env bash
# Issue 52: counterattack easy at the paper's number of updates, the stage F protocol (8 games on 2 env workers,
# double-buffered, packaged configs, evaluations every 250k env steps on 100 greedy episodes), 4M env steps = 16M
# agent-steps (4 agents). One football job at a time (it uses both cores). The networks compiled (compile:True, a
# setting of the machine, not of the run): measured on this machine class, SAEIR_PPO's update on counterattack easy
# with 8 games and 2 threads takes 3.04 s compiled against 4.12 s eager (medians of 5, 1.35x; 115 s to compile once;
# benchmarks/compiled_update.py --algo saeir_ppo --task grf-counterattack-easy --n-games 8 --threads 2 --rounds 5).
# From a worktree of a fixed commit; re-running resumes (football resumes approximately: its games restart from a
# reset).
# THREADS (default 2) is the learner's torch thread count: 1 while another job holds a core (two threads on one free
# core stall each other; measured here beside a one-thread navigation job: 13 env steps/s with 2, see resume.log).
#   git worktree add $HOME/saeir-football <commit> && bash docs/results/counterattack-4m/queue.sh saeir_ppo:1
#   (decision rule, issue 52: if SAEIR_PPO reaches >= 5% success at an evaluation after 2M env steps, then
#    queue.sh mappo:1 saeir_ppo:2)
set -euo pipefail
cd "$HOME/saeir-football"
PY=/work/main/.venv/bin/python
export PYTHONPATH="$HOME/saeir-football"
OUT="$HOME/saeir-results/counterattack-4m"
COMMON=(--tasks grf-counterattack-easy -n 16000000 --eval-freq 1000000 --n-games 8 --eval-episodes 100
        -params num_cpus:2 "compile:${COMPILE:-True}" --num-threads "${THREADS:-2}" --jobs 1 --rliable)
echo "$(date -u +%FT%TZ) queue start (commit $(git rev-parse --short HEAD)): $*"
for run in "$@"; do
    IFS=: read -r algo seed <<< "$run"
    echo "$(date -u +%FT%TZ) $run: start"
    $PY -m sb3_saeir.benchmark --algos "$algo" --seeds "$seed" "${COMMON[@]}" --out "$OUT"
done
echo "$(date -u +%FT%TZ) queue done"
