#!/usr/bin/env bash
# Issue 32's report, run from the repository root of main. The runs are made on different machines, whose results
# folders do not outlive their session, so the report reads only what is committed here:
#
#   bash docs/results/football-stage-f/report.sh copy   # on the machine that made runs: copy each finished run's
#                                                       # small files here (never checkpoints, models or progress.csv)
#   bash docs/results/football-stage-f/report.sh        # the report, from the committed run files alone
#
# copy: from $HOME/saeir-results/stage-f/<counterattack|3v1>/runs/<algo>/<task>_s<seed> (queue.sh's output) to
# <counterattack|3v1>/runs/<algo>/<task>_s<seed> here: spec.json, evaluations.csv, segments.json, resume.log,
# done.json; for SAEIR_PPO also the bonus, which needs the run's progress.csv: bonus.md and bonus.png (the
# benchmark's --entropy-plot) and bonus_by_250k.md (the fire rate and mean bonus per scale per 250k env steps).
# report: each folder's runs.csv, table.md, aggregate.md and curves.png (the benchmark with --report-only), then
# learning_speed.md and curves_seeds.png here, with seed 1 of 3 vs 1 from the football probe.
set -euo pipefail
RESULTS="${STAGE_F_RESULTS:-$HOME/saeir-results/stage-f}"
DOCS="${STAGE_F_DOCS:-docs/results/football-stage-f}"
PY="${PYTHON:-python}"
COMMON=(--n-games 8 --eval-episodes 100 -params num_cpus:2 --num-threads 2 --jobs 1 --rliable --report-only)

copy_runs() {
    local run folder copied=0
    for run in "$RESULTS"/counterattack/runs/*/*_s* "$RESULTS"/3v1/runs/*/*_s*; do
        # finished runs only (a run that has not finished is lost with its machine); not the folders that the
        # benchmark's --rerun-changed moved aside
        [ -f "$run/done.json" ] && [[ "$run" != *.replaced-* ]] || continue
        folder="$(basename "$(dirname "$(dirname "$(dirname "$run")")")")"
        "$PY" benchmarks/copy_run_files.py "$run" "$DOCS/$folder/runs/$(basename "$(dirname "$run")")/$(basename "$run")" \
            --bonus-window 250000 --bonus-name bonus_by_250k.md
        copied=$((copied + 1))
    done
    echo "$copied finished runs copied from $RESULTS"
}

report() {
    "$PY" -m sb3_saeir.benchmark --algos saeir_ppo mappo --tasks grf-counterattack-easy --seeds 1 -n 8000000 \
        --eval-freq 1000000 "${COMMON[@]}" --out "$DOCS/counterattack"
    "$PY" -m sb3_saeir.benchmark --algos saeir_ppo mappo --tasks grf-3v1-keeper --seeds 2-3 -n 6000000 \
        --eval-freq 750000 "${COMMON[@]}" --out "$DOCS/3v1"
    "$PY" benchmarks/learning_speed.py --out "$DOCS" docs/results/football-probe/runs.csv "$DOCS/3v1/runs.csv" \
        "$DOCS/counterattack/runs.csv"
}

case "${1:-report}" in
    copy) copy_runs ;;
    report) report ;;
    *) echo "usage: bash docs/results/football-stage-f/report.sh [copy|report]" >&2; exit 2 ;;
esac
