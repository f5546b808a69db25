#!/usr/bin/env bash
# Issue 51 part 1's report (docs/results/navigation-calibrated.md), run from the repository root of main:
#
#   bash docs/results/navigation-calibrated/report.sh copy   # on the machine that makes the runs: copy each run's
#                                                            # small files here (never checkpoints, models or progress.csv)
#   bash docs/results/navigation-calibrated/report.sh        # the report, from the committed run files alone
#
# copy: from $HOME/saeir-results/nav-calibrated/<reading>/runs/<algo>/cn-sparse-n3_s1 (queue.sh's output; readings
# no-penalty and reach) to runs/<algo>-<reading>/cn-sparse-n3_s1 here: spec.json, evaluations.csv, segments.json,
# resume.log, done.json (a run still training is copied as far as it got); for SAEIR_PPO also the bonus, which needs
# the run's progress.csv: bonus_by_2m.md (fire rate and mean bonus per scale per 2M env steps) and bonus.md/bonus.png
# (the benchmark's --entropy-plot).
# report: runs.csv here (every run's evaluations, the method renamed <algo>-<reading>, since both readings hold a
# mappo seed 1), its table.md (the benchmark's table) and evaluations.md (coverage, success and collision steps at every evaluation), then
# evaluation_curves.md and curves_full.png of the finished runs (finished.csv: final, best and plateau within 2 points
# of coverage, success, per run; the random floor; Table 1's values).
# runs/ is in .gitignore (for run folders made elsewhere): add the copied run files with git add -f.
set -euo pipefail
RESULTS="${NAV_RESULTS:-$HOME/saeir-results/nav-calibrated}"
DOCS="${NAV_DOCS:-docs/results/navigation-calibrated}"
PY="${PYTHON:-python}"

copy_runs() {
    local run reading
    for run in "$RESULTS"/*/runs/*/*_s*; do
        [ -f "$run/spec.json" ] && [[ "$run" != *.replaced-* ]] || continue
        reading="$(basename "$(dirname "$(dirname "$(dirname "$run")")")")"
        "$PY" benchmarks/copy_run_files.py "$run" "$DOCS/runs/$(basename "$(dirname "$run")")-$reading/$(basename "$run")" \
            --bonus-window 2000000 --bonus-name bonus_by_2m.md
    done
}

report() {
    "$PY" - "$DOCS" <<'EOF'
import sys
from pathlib import Path

from sb3_saeir.benchmark import read_rows, table_markdown, write_rows

docs = Path(sys.argv[1])
rows = []
for path in sorted(docs.glob("runs/*/*/evaluations.csv")):
    arm = path.parent.parent.name
    rows += [{**row, "algo": arm} for row in read_rows(path)]
    state = "finished" if (path.parent / "done.json").is_file() else "still training"
    print(f"{arm}/{path.parent.name}: {len(read_rows(path))} evaluations, {state}")
write_rows(docs / "runs.csv", rows)
finished = {path.parent.parent.name for path in docs.glob("runs/*/*/done.json")}
write_rows(docs / "finished.csv", [row for row in rows if row["algo"] in finished])  # evaluation_curves' input
(docs / "table.md").write_text(table_markdown(read_rows(docs / "runs.csv")))  # as the benchmark reports it
lines = [
    "Every evaluation (200 greedy episodes): final-step coverage and success in %, collision steps per 25-step episode.",
    "",
    "| run | env steps | coverage % | success % | collision steps per episode |",
    "|---|---|---|---|---|",
]
for row in rows:
    lines.append(
        f"| {row['algo']} s{row['seed']} | {float(row['env_steps']) / 1e6:.0f}M | {100 * float(row['coverage_rate_mean']):.1f} "
        f"| {100 * float(row['success_mean']):.1f} | {float(row['collision_steps_mean']):.2f} |"
    )
(docs / "evaluations.md").write_text("\n".join(lines) + "\n")
EOF
    local references=(cn-sparse-n3:mappo-no-penalty=64.43)
    if [ -f "$DOCS/runs/saeir_ppo-no-penalty/cn-sparse-n3_s1/done.json" ]; then
        references+=(cn-sparse-n3:saeir_ppo-no-penalty=65.48)
    fi
    "$PY" benchmarks/evaluation_curves.py --out "$DOCS" "$DOCS/finished.csv" --random-episodes 1000 \
        --metrics coverage_rate success --plateau 2 --reference "${references[@]}"
}

case "${1:-report}" in
    copy) copy_runs ;;
    report) report ;;
    *) echo "usage: bash docs/results/navigation-calibrated/report.sh [copy|report]" >&2; exit 2 ;;
esac
