#!/usr/bin/env bash
# Issue 51 part 1 (running): copy each run's small files from $HOME/saeir-results/nav-calibrated (never checkpoints or
# progress.csv) and print the table of evaluations on the study page (docs/results/navigation-calibrated.md).
# usage, from main's root: bash docs/results/navigation-calibrated/report.sh
set -euo pipefail
RESULTS="${NAV_RESULTS:-$HOME/saeir-results/nav-calibrated}"
DOCS="docs/results/navigation-calibrated"
PY="${PYTHON:-python}"
for run in "$RESULTS"/*/runs/*/*_s*; do
    [ -f "$run/spec.json" ] || continue
    reading="$(basename "$(dirname "$(dirname "$(dirname "$run")")")")"
    target="$DOCS/$reading/runs/$(basename "$(dirname "$run")")/$(basename "$run")"
    mkdir -p "$target"
    for name in spec.json evaluations.csv segments.json resume.log done.json; do
        if [ -f "$run/$name" ]; then cp "$run/$name" "$target/"; fi
    done
done
"$PY" - "$DOCS" <<'PYTHON'
import csv
import sys
from pathlib import Path

docs = Path(sys.argv[1])
runs = sorted(docs.glob("*/runs/*/*/evaluations.csv"))
print("| reading | method | env steps | coverage % | success % | collision steps per episode |")
print("|---|---|---|---|---|---|")
for path in runs:
    reading, algo = path.parts[-5], path.parts[-3]
    for row in csv.DictReader(open(path)):
        steps = int(row["env_steps"])
        print(f"| {reading} | {algo} | {steps / 1e6:.0f}M | {100 * float(row['coverage_rate_mean']):.1f} | "
              f"{100 * float(row['success_mean']):.1f} | {float(row['collision_steps_mean']):.2f} |")
PYTHON
