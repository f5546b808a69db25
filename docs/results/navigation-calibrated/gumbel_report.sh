#!/usr/bin/env bash
# Issue 51 parts 2 and 3 (docs/results/navigation-calibrated.md), run from the repository root of main:
#
#   bash docs/results/navigation-calibrated/gumbel_report.sh copy       # on the machine of the runs: each finished
#       # 3M run's small files (never checkpoints, models or progress.csv) from $HOME/saeir-results/gumbel/<arm>
#       # (gumbel_queue.sh's output) to gumbel/<arm>/runs/mshg_only/cn-sparse-n3_s<seed> here
#   bash docs/results/navigation-calibrated/gumbel_report.sh            # the 15-vs-15 comparison from committed files
#   bash docs/results/navigation-calibrated/gumbel_report.sh diagnose   # part 2's critic readings (needs the models)
#   bash docs/results/navigation-calibrated/gumbel_report.sh rise       # part 3's bonus readings (needs the models)
#
# report: gumbel/runs.csv, seeds 1-5 of each arm as committed by stage 2 (docs/results/stage2-default, method
# mshg_only, with the noise) and stage 2b (docs/results/stage2b-mshg-no-gumbel, without it) and seeds 6-15 from the
# copied runs, the method renamed mshg-gumbel / mshg-no-gumbel; then benchmarks/compare_arms.py (final coverage per
# arm, IQM with its interval, the exact two-sided Mann-Whitney test; gumbel/comparison.md, gumbel/curves.png) and
# benchmarks/learning_speed.py (every seed's curve, gumbel/curves_seeds.png and gumbel/learning_speed.md).
# diagnose: benchmarks/critic_diagnostics.py on the models at 1M (kept by the extension) and 3M agent-steps of seeds
# 6-8 of each arm, 32 Gumbel draws per state, one rollout of the run's 128 games (gumbel/critic_diagnostics.md).
# rise: benchmarks/bonus_rise.py on the final models of the calibrated full-budget runs that exist (nav-calibrated)
# and on the 3M models of seeds 6-8 of each arm (bonus_rise.md).
# runs/ is in .gitignore (for run folders made elsewhere): add the copied run files with git add -f.
set -euo pipefail
RESULTS="${GUMBEL_RESULTS:-$HOME/saeir-results/gumbel}"
NAV_RESULTS="${NAV_RESULTS:-$HOME/saeir-results/nav-calibrated}"
DOCS="${GUMBEL_DOCS:-docs/results/navigation-calibrated}"
PY="${PYTHON:-python}"
ARMS=(mshg-gumbel mshg-no-gumbel)
TASK=cn-sparse-n3

finished_at() {  # $1: a run folder, $2: agent-steps; true when the run finished with that budget
    [ -f "$1/done.json" ] && "$PY" -c 'import json, sys; sys.exit(json.load(open(sys.argv[1]))["n_timesteps"] != int(sys.argv[2]))' "$1/spec.json" "$2"
}

finished_3m() {  # $1: a run folder; true when it finished its 3M agent-steps
    finished_at "$1" 3000000
}

copy_runs() {
    local arm run copied=0
    for arm in "${ARMS[@]}"; do
        for run in "$RESULTS/$arm/runs/mshg_only/${TASK}_s"*; do
            [ -d "$run" ] && [[ "$run" != *.replaced-* ]] && finished_3m "$run" || continue
            "$PY" benchmarks/copy_run_files.py "$run" "$DOCS/gumbel/$arm/runs/mshg_only/$(basename "$run")"
            copied=$((copied + 1))
        done
    done
    echo "$copied finished 3M runs copied from $RESULTS"
}

report() {
    "$PY" - "$DOCS/gumbel" <<'EOF'
import sys
from pathlib import Path

from sb3_saeir.benchmark import read_rows, write_rows

gumbel = Path(sys.argv[1])
earlier = {
    "mshg-gumbel": [row for row in read_rows(Path("docs/results/stage2-default/runs.csv")) if row["algo"] == "mshg_only"],
    "mshg-no-gumbel": read_rows(Path("docs/results/stage2b-mshg-no-gumbel/runs.csv")),
}
rows = []
for arm, committed in earlier.items():
    seeds = {int(row["seed"]) for row in committed}
    rows += [{**row, "algo": arm} for row in committed]
    for path in sorted(gumbel.glob(f"{arm}/runs/mshg_only/*/evaluations.csv")):
        found = read_rows(path)
        seeds |= {int(row["seed"]) for row in found}
        rows += [{**row, "algo": arm} for row in found]
    print(f"{arm}: seeds {sorted(seeds)}")
write_rows(gumbel / "runs.csv", rows)
EOF
    "$PY" benchmarks/compare_arms.py --out "$DOCS/gumbel" \
        "mshg-gumbel=$DOCS/gumbel/runs.csv:mshg-gumbel" "mshg-no-gumbel=$DOCS/gumbel/runs.csv:mshg-no-gumbel"
    "$PY" benchmarks/learning_speed.py --out "$DOCS/gumbel" "$DOCS/gumbel/runs.csv" --at 500000 1000000 \
        --thresholds 10 20
}

models() {  # $1: "1m" or "3m"; the models of seeds 6-8 of each arm that exist (3m: of finished 3M runs)
    local arm seed run
    for arm in "${ARMS[@]}"; do
        for seed in 6 7 8; do
            run="$RESULTS/$arm/runs/mshg_only/${TASK}_s$seed"
            if [ "$1" = 3m ]; then
                if [ -d "$run" ] && finished_3m "$run"; then echo "$run/$TASK.zip"; fi
            elif compgen -G "$run/${TASK}_*_steps.zip" > /dev/null; then
                compgen -G "$run/${TASK}_*_steps.zip"  # kept by the extension to 3M
            elif [ -d "$run" ] && finished_at "$run" 1000000; then
                echo "$run/$TASK.zip"  # finished at 1M, not yet extended
            fi
        done
    done
}

diagnose() {
    mkdir -p "$DOCS/gumbel"
    local early late
    mapfile -t early < <(models 1m)
    mapfile -t late < <(models 3m)
    {
        echo "\`python benchmarks/critic_diagnostics.py --model <seeds 6-8 of each arm, at 1M and 3M agent-steps>\`"
        echo "(32 Gumbel draws per state, one rollout of 128 games per model, rollout seed 20000):"
        echo
        "$PY" benchmarks/critic_diagnostics.py --model "${early[@]}" "${late[@]}"
    } > "$DOCS/gumbel/critic_diagnostics.md"
    cat "$DOCS/gumbel/critic_diagnostics.md"
}

rise() {
    local full=() late
    for run in "$NAV_RESULTS"/*/runs/*/"${TASK}_s1"; do
        if [ -f "$run/$TASK.zip" ]; then full+=("$run/$TASK.zip"); fi
    done
    mapfile -t late < <(models 3m)
    {
        echo "\`python benchmarks/bonus_rise.py --model <the calibrated full-budget models> <seeds 6-8 of each MSHG-only arm at 3M,"
        echo "those finished>\`"
        echo "(one rollout of 128 games per model, rollout seed 20000; steps 2-24 of each 25-step window):"
        echo
        "$PY" benchmarks/bonus_rise.py --model "${full[@]}" "${late[@]}"
    } > "$DOCS/bonus_rise.md"
    cat "$DOCS/bonus_rise.md"
}

case "${1:-report}" in
    copy) copy_runs ;;
    report) report ;;
    diagnose) diagnose ;;
    rise) rise ;;
    *) echo "usage: bash docs/results/navigation-calibrated/gumbel_report.sh [copy|report|diagnose|rise]" >&2; exit 2 ;;
esac
