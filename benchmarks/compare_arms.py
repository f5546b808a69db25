"""Several benchmark folders side by side: one table, one IQM table, every pairwise test, one figure.

    python benchmarks/compare_arms.py --out docs/results/stage2b-comparison \\
        "mappo=docs/results/stage2-default/runs.csv:mappo" \\
        "saeir (code)=docs/results/stage2-default/runs.csv:saeir_ppo" \\
        "saeir (supplement)=docs/results/stage2b-saeir-supplement/runs.csv"

Each argument is ``ARM=RUNS_CSV[:ALGO]``: the rows of ``RUNS_CSV`` (a benchmark's ``runs.csv``; with ``:ALGO``, only
that method's rows) renamed to ``ARM``. Arms run with different ``-params`` live in different benchmark folders, so
the benchmark's own report cannot put them in one table; this script does, with the benchmark's report functions
(``table_markdown``, ``rliable_markdown``, ``pairwise_markdown``, ``plot_curves``), so the figures are computed as the
benchmark computes them. Writes ``OUT/comparison.md`` and ``OUT/curves.png`` and prints the Markdown. Only the runs in
the files are used: finish (or report) the benchmark folders first.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from sb3_saeir.benchmark import pairwise_markdown, plot_curves, read_rows, rliable_markdown, table_markdown


def arm_rows(argument: str) -> list[dict[str, Any]]:
    """The rows of one ``ARM=RUNS_CSV[:ALGO]`` argument, their ``algo`` renamed to ``ARM``."""
    if "=" not in argument:
        raise SystemExit(f"compare_arms: {argument!r} is not ARM=RUNS_CSV[:ALGO].")
    arm, source = argument.split("=", 1)
    path, _, algo = source.partition(":")
    rows = read_rows(Path(path))
    if not rows:
        raise SystemExit(f"compare_arms: no rows in {path} (missing or empty).")
    chosen = [row for row in rows if not algo or row["algo"] == algo]
    if not chosen:
        raise SystemExit(f"compare_arms: no rows of {algo!r} in {path}; methods there: {sorted({r['algo'] for r in rows})}.")
    return [{**row, "algo": arm} for row in chosen]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("arms", nargs="+", help="ARM=RUNS_CSV[:ALGO]")
    parser.add_argument("--out", type=Path, required=True, help="folder for comparison.md and curves.png")
    args = parser.parse_args(argv)
    rows: list[dict[str, Any]] = []
    for argument in args.arms:
        rows += arm_rows(argument)
    arms = list(dict.fromkeys(row["algo"] for row in rows))
    if len(arms) != len(args.arms):
        parser.error("two arguments give the same ARM name")
    args.out.mkdir(parents=True, exist_ok=True)
    sources = "\n".join(f"- `{argument}`" for argument in args.arms)
    text = (
        f"Arms:\n\n{sources}\n\n"
        f"Final evaluation, mean ± std over seeds:\n\n{table_markdown(rows)}\n"
        f"IQM and pairwise tests:\n\n{rliable_markdown(rows)}\n{pairwise_markdown(rows)}"
    )
    (args.out / "comparison.md").write_text(text)
    plot_curves(rows, args.out / "curves.png")
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
