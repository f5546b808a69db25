#!/usr/bin/env bash
# Issue 52's report (counterattack easy to 4M env steps), run from the repository root of main:
#
#   bash docs/results/counterattack-4m/report.sh copy   # on the machine of the runs: each run's small files (never
#                                                       # checkpoints, models or progress.csv), finished or not
#   bash docs/results/counterattack-4m/report.sh        # the report, from the committed run files alone
#
# copy: from $HOME/saeir-results/counterattack-4m/runs/<algo>/grf-counterattack-easy_s<seed> (queue.sh's output) to
# runs/<algo>/grf-counterattack-easy_s<seed> here: spec.json, evaluations.csv, segments.json, resume.log, done.json;
# for SAEIR_PPO also bonus_by_250k.md (the bonus's fire rate and mean per scale and the critics' value-softmax
# entropy, per 250k env steps, from the run's progress.csv) and bonus.md/bonus.png (the benchmark's --entropy-plot).
# report: runs.csv here (every run's evaluations; MAPPO seed 1 from stage F's 2M run when it was not continued, as
# the decision rule leaves it), table.md and aggregate.md as the benchmark reports them, evaluations.md (every
# evaluation: success, goal difference, episode length), evaluation_curves.md and
# curves_full.png (success, goal difference and episode length per run; Table 1 dashed), learning_speed.md and
# curves_seeds.png (success at 1M-4M, the first env steps at 5%, 10%, 20% success).
# runs/ is in .gitignore (for run folders made elsewhere): add the copied run files with git add -f.
set -euo pipefail
RESULTS="${COUNTER_RESULTS:-$HOME/saeir-results/counterattack-4m}"
DOCS="${COUNTER_DOCS:-docs/results/counterattack-4m}"
STAGE_F="${STAGE_F_DOCS:-docs/results/football-stage-f}/counterattack/runs.csv"
PY="${PYTHON:-python}"
TASK=grf-counterattack-easy

copy_runs() {
    local run
    for run in "$RESULTS"/runs/*/"${TASK}"_s*; do
        [ -f "$run/spec.json" ] && [[ "$run" != *.replaced-* ]] || continue
        "$PY" benchmarks/copy_run_files.py "$run" "$DOCS/runs/$(basename "$(dirname "$run")")/$(basename "$run")" \
            --bonus-window 250000 --bonus-name bonus_by_250k.md
    done
}

report() {
    "$PY" - "$DOCS" "$STAGE_F" <<'EOF'
import sys
from pathlib import Path

from sb3_saeir.benchmark import pairwise_markdown, read_rows, rliable_markdown, table_markdown, write_rows

docs, stage_f = Path(sys.argv[1]), Path(sys.argv[2])
rows = []
for path in sorted(docs.glob("runs/*/*/evaluations.csv")):
    found = read_rows(path)
    rows += found
    state = "finished" if (path.parent / "done.json").is_file() else "still training"
    print(f"{path.parent.parent.name}/{path.parent.name}: {len(found)} evaluations, {state}")
if not any(row["algo"] == "mappo" and int(row["seed"]) == 1 for row in rows):
    mappo = [row for row in read_rows(stage_f) if row["algo"] == "mappo" and int(row["seed"]) == 1]
    rows += mappo
    print(f"mappo seed 1: stage F's 2M run ({len(mappo)} evaluations, {stage_f})")
write_rows(docs / "runs.csv", rows)
rows = read_rows(docs / "runs.csv")  # what the byte-for-byte test re-reports
(docs / "table.md").write_text(table_markdown(rows))
(docs / "aggregate.md").write_text(rliable_markdown(rows) + "\n" + pairwise_markdown(rows))
lines = [
    "Every evaluation (100 greedy episodes): success %, goal difference and episode length (steps), means per episode.",
    "",
    "| run | env steps | success % | goal difference | episode length |",
    "|---|---|---|---|---|",
]
for row in sorted(rows, key=lambda row: (row["algo"], int(row["seed"]), int(row["env_steps"]))):
    lines.append(
        f"| {row['algo']} s{row['seed']} | {int(row['env_steps']):,} | {100 * float(row['success_mean']):.0f} "
        f"| {float(row['goal_diff_mean']):+.2f} | {float(row['ep_len_mean']):.1f} |"
    )
(docs / "evaluations.md").write_text("\n".join(lines) + "\n")
EOF
    "$PY" benchmarks/evaluation_curves.py --out "$DOCS" "$DOCS/runs.csv" --random-episodes 0 \
        --metrics success goal_diff ep_len --reference-label "paper 25M" \
        --reference "$TASK:saeir_ppo=76.12" "$TASK:mappo=0.73"
    local bonus=()
    for run in "$RESULTS"/runs/saeir_ppo/"${TASK}"_s*; do
        if [ -f "$run/progress.csv" ]; then bonus+=("$run"); fi
    done
    "$PY" benchmarks/learning_speed.py --out "$DOCS" "$DOCS/runs.csv" --at 1000000 2000000 3000000 4000000 \
        --thresholds 5 10 20 --window 250000 ${bonus[@]+--bonus "${bonus[@]}"}
}

case "${1:-report}" in
    copy) copy_runs ;;
    report) report ;;
    *) echo "usage: bash docs/results/counterattack-4m/report.sh [copy|report]" >&2; exit 2 ;;
esac
