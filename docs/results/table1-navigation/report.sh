#!/usr/bin/env bash
# Issue 64 part 4's report (docs/results/table1-navigation.md), run from the repository root:
#
#   bash docs/results/table1-navigation/report.sh           # copy, then the page
#   bash docs/results/table1-navigation/report.sh copy      # on the machine of the runs: the run files only
#   bash docs/results/table1-navigation/report.sh report    # the page, from the committed run files alone
#
# copy: from $HOME/saeir-results/table1-navigation/n<N>/runs/<algo>/<task>_s<seed> (queue.sh's output) to
# runs/<algo>/<task>_s<seed> here, with benchmarks/copy_run_files.py: spec.json, evaluations.csv, segments.json,
# resume.log, done.json (never checkpoints, models or progress.csv). A run still training is copied as far as it got
# (the page shows it as running, never as a final) and nothing is written into its folder; a finished SAEIR_PPO run
# also gets its bonus files (bonus.md, bonus.png and bonus_by_1m.md, the fire rate per scale per 1M env steps from its
# progress.csv; the benchmark's --entropy-plot writes system_entropy.png into the finished run's folder).
# report: benchmarks/table1_navigation.py writes runs.md, finals.md, differences.md, reward.md, fire_rate.md,
# curves.png and fire_rate.png here from the committed run files (N=3 seed 1 of both methods: the runs of
# navigation-calibrated/runs/<algo>-no-penalty/cn-sparse-n3_s1), then benchmarks/results_pages.py copies the tables
# into the page's generated blocks. Runs not started or not finished are shown as such: the report never fails on them.
# runs/ is in .gitignore (for run folders made elsewhere): add the copied run files with git add -f.
set -euo pipefail
RESULTS="${NAV_RESULTS:-$HOME/saeir-results/table1-navigation}"
DOCS="${NAV_DOCS:-docs}"
STUDY="$DOCS/results/table1-navigation"
PY="${PYTHON:-python}"

copy_runs() {
    local run bonus
    for run in "$RESULTS"/n*/runs/*/*_s*; do
        [ -f "$run/spec.json" ] && [[ "$run" != *.replaced-* ]] || continue
        bonus=()
        [ -f "$run/done.json" ] && bonus=(--bonus-window 1000000 --bonus-name bonus_by_1m.md)
        "$PY" benchmarks/copy_run_files.py "$run" "$STUDY/runs/$(basename "$(dirname "$run")")/$(basename "$run")" \
            "${bonus[@]}"
    done
}

report() {
    "$PY" benchmarks/table1_navigation.py --results "$DOCS/results"
    "$PY" benchmarks/results_pages.py --docs "$DOCS" --pages table1-navigation
}

case "${1:-all}" in
    all) copy_runs; report ;;
    copy) copy_runs ;;
    report) report ;;
    *) echo "usage: bash docs/results/table1-navigation/report.sh [all|copy|report]" >&2; exit 2 ;;
esac
