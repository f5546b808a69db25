#!/usr/bin/env bash
# Issue 51 part 2: seeds 6-15 of stage 2b's two MSHG-only arms (with and without the critic's Gumbel noise), stage 2's
# protocol (cn-sparse-n3, 3M agent-steps, 128 games, evaluations every 500k agent-steps on 100 episodes). Each arm runs
# to 1M agent-steps first, then is trained longer to 3M (exactly as a straight 3M run: docs/guide/training.md,
# "Training a run longer"); the extension keeps the final model at 1M (cn-sparse-n3_<steps>_steps.zip) beside the one at
# 3M, which the diagnostics read. From a worktree of a fixed commit; re-running resumes.
#   git worktree add $HOME/saeir-gumbel <commit> && bash docs/results/navigation-calibrated/gumbel_queue.sh
# BUDGETS (default "1000000 3000000") are run in turn. Seeds 6-8 ran with the default (the diagnostics read their 1M
# and 3M models); seeds 9-15 straight to 3M, two seeds of one arm at a time, then the same two of the other arm:
#   for seeds in 9-10 11-12 13-14 15; do SEEDS=$seeds BUDGETS=3000000 bash .../gumbel_queue.sh; done
set -euo pipefail
cd "$HOME/saeir-gumbel"
export PYTHONPATH="$HOME/saeir-gumbel"
PY=/work/main/.venv/bin/python
OUT="$HOME/saeir-results/gumbel"
MSHG="activation_fn=nn.Tanh, hidden_size=64, group_size=2, n_edge_types=3, scales=('team', 'group', 'individual')"
COMMON=(--algos mshg_only --tasks cn-sparse-n3 --seeds "${SEEDS:-6-15}" --n-games 128 --eval-freq 500000 --eval-episodes 100
        --jobs "${JOBS:-2}" --num-threads 1 --rliable)
echo "$(date -u +%FT%TZ) gumbel queue start (commit $(git rev-parse --short HEAD))"
for budget in ${BUDGETS:-1000000 3000000}; do
    $PY -m sb3_saeir.benchmark "${COMMON[@]}" -n "$budget" --out "$OUT/mshg-gumbel"
    $PY -m sb3_saeir.benchmark "${COMMON[@]}" -n "$budget" --out "$OUT/mshg-no-gumbel" \
        -params "policy_kwargs:dict($MSHG, critic_gumbel_noise=False)"
done
echo "$(date -u +%FT%TZ) gumbel queue done"
