"""Benchmark runner: methods x tasks x seeds -> ``runs.csv``, the paper's Table 1 layout and learning curves
(``python -m sb3_saeir.benchmark``; the manual: ``docs/guide/benchmark.md``). Each run is a
:class:`~sb3_saeir.run.run.Run` in ``<out>/runs/<algo>/<task>_s<seed>/`` (the files: ``docs/guide/training.md``, "The run
folder").

The modules, one concern each: :mod:`~sb3_saeir.benchmark.runs` (the run folders, the comparison of ``spec.json``
with the command), :mod:`~sb3_saeir.benchmark.execution` (one run; local processes and Ray),
:mod:`~sb3_saeir.benchmark.reports` (the tables and figures), :mod:`~sb3_saeir.benchmark.statistics` (final scores,
IQM, Mann-Whitney) and :mod:`~sb3_saeir.benchmark.cli` (the command line). This package names what a user reaches
for: the command, a run's settings and folder, the rows, the tables, statistics and figures.
"""

from sb3_saeir.benchmark.cli import main
from sb3_saeir.benchmark.execution import execute_run
from sb3_saeir.benchmark.reports import (
    format_steps,
    numeric_series,
    plot_curves,
    plot_system_entropy,
    report,
    system_entropy_summary,
    table_markdown,
)
from sb3_saeir.benchmark.runs import parse_seeds, run_folder
from sb3_saeir.benchmark.statistics import (
    final_scores,
    main_metric,
    mann_whitney,
    pairwise_markdown,
    rliable_markdown,
    table_columns,
)
from sb3_saeir.run.record import RunSpec, read_rows, write_rows

__all__ = [
    "RunSpec",
    "execute_run",
    "final_scores",
    "format_steps",
    "main",
    "main_metric",
    "mann_whitney",
    "numeric_series",
    "pairwise_markdown",
    "parse_seeds",
    "plot_curves",
    "plot_system_entropy",
    "read_rows",
    "report",
    "rliable_markdown",
    "run_folder",
    "system_entropy_summary",
    "table_columns",
    "table_markdown",
    "write_rows",
]
