#!/usr/bin/env bash
# Issue 36's report, rebuilt from the run folders under $HOME/saeir-results/nav-full (queue.sh), run from the
# repository root of main: copies each run's small files (never checkpoints or progress.csv), writes runs.csv,
# table.md and aggregate.md of the finished runs, evaluation_curves.md and curves_full.png, and learning_speed.md
# with the SAEIR bonus per 2M env steps. The rows come from each run's own evaluations.csv: a benchmark folder's
# runs.csv holds only the runs of the command that last wrote it (SAEIR_PPO's command replaced MAPPO's N=3 rows).
# usage: bash docs/results/navigation-full-budget/report.sh
set -euo pipefail
RESULTS="${NAV_RESULTS:-$HOME/saeir-results/nav-full}"
DOCS="${NAV_DOCS:-docs/results/navigation-full-budget}"
PY="${PYTHON:-python}"

for run in "$RESULTS"/cn-sparse-n*/runs/*/*_s*; do
    [ -f "$run/spec.json" ] || continue
    "$PY" benchmarks/copy_run_files.py "$run" "$DOCS/runs/$(basename "$(dirname "$run")")/$(basename "$run")"
done

# runs.csv, table.md, aggregate.md: the finished runs (a done.json in their folder), as the benchmark reports them
"$PY" - "$DOCS" "$DOCS"/runs/*/*/evaluations.csv <<'EOF'
import sys
from pathlib import Path

from sb3_saeir.benchmark import pairwise_markdown, read_rows, rliable_markdown, table_markdown, write_rows

docs = Path(sys.argv[1])
rows = [row for path in sys.argv[2:] for row in read_rows(Path(path))]
finished = [
    row for path in sorted(sys.argv[2:]) if (Path(path).parent / "done.json").is_file() for row in read_rows(Path(path))
]
write_rows(docs / "runs.csv", finished)
finished = read_rows(docs / "runs.csv")  # what the byte-for-byte test re-reports
(docs / "table.md").write_text(table_markdown(finished))
(docs / "aggregate.md").write_text(rliable_markdown(finished) + "\n" + pairwise_markdown(finished))
print(f"{len(finished)} rows of finished runs ({len(rows)} in all)")
EOF

"$PY" benchmarks/evaluation_curves.py --out "$DOCS" \
    "$DOCS"/runs.csv --random-episodes 1000 \
    --reference cn-sparse-n3:mappo=64.43 cn-sparse-n3:saeir_ppo=65.48 cn-sparse-n4:mappo=64.26

"$PY" benchmarks/learning_speed.py --out "$DOCS" "$DOCS"/runs.csv \
    --at 2000000 10000000 20000000 --thresholds 10 20 30 --window 2000000 \
    --bonus "$RESULTS"/cn-sparse-n3/runs/saeir_ppo/cn-sparse-n3_s1
