"""The tables of the results pages (``docs/results.md`` and ``docs/results/*.md``) and the summary's navigation figure,
rebuilt from the committed run files, so that the pages cannot drift from the data.

    python benchmarks/results_pages.py              # rewrite the generated blocks of every results page
    python benchmarks/results_pages.py --check      # exit 1, naming each block that differs from the run files
    python benchmarks/results_pages.py --out DIR    # write the rebuilt pages into DIR (the pages stay as they are)
    python benchmarks/results_pages.py --figures    # also redraw the summary's figures (docs/results/summary/*.png)
    python benchmarks/results_pages.py --curves docs/results/stage2-default   # redraw a folder's curves.png

A generated block of a page sits between ``<!-- results_pages: KIND ARGUMENTS -->`` and ``<!-- /results_pages -->``
(HTML comments: neither GitHub nor Sphinx shows them); everything outside the blocks is written by hand. Kinds:

- ``summary``: the summary table, one row per (task, method) of every study (:data:`STUDIES`, ``summary=True``);
- ``rows STUDY``: the study's rows, each seed's final value added;
- ``checkpoints STUDY [METRIC]``: per (task, method), each seed's value of METRIC (default: the main metric) at the
  study's checkpoints (the first evaluation at or after each) and at its last evaluation, with their mean;
- ``copy FILE [TABLE ...]``: tables of a committed report file under ``docs/results/`` (``aggregate.md``,
  ``learning_speed.md``, ...), verbatim: the TABLE-th (1-based) tables of the file, all of them by default;
- ``bonus-readings FILE ...``: the pooled rows (scale ``all``) of ``benchmarks/bonus_readings.py`` tables, one block
  per file, and the supplement's Fig. 3 row.

Definitions (``docs/results.md`` states them): the final value of a run is its last evaluation's main metric
(:func:`sb3_saeir.benchmark.statistics.final_rows`), in percent; mean ± std is over seeds with NumPy's (population)
std, as ``table.md``; the IQM and its 95% interval (rliable's stratified bootstrap, 2,000 resamples, seed 0) are given
from 3 seeds on, bootstrapped together with the methods of the committed report the study cites (``aggregate.md``,
``comparison.md``; a study without one: each method alone, as ``learning_speed.md``), so that they are the same
numbers; a run leaves the random floor at its first evaluation at or above :data:`FLOOR_EXIT` percent.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from sb3_saeir.benchmark import read_rows
from sb3_saeir.benchmark.statistics import final_rows, final_scores, iqm_interval_estimates, main_metric, seeded_global_numpy

sys.path.insert(0, str(Path(__file__).parent))
from learning_speed import first_reach, seed_curves, value_at

DOCS = Path(__file__).parent.parent / "docs"
FLOOR_EXIT = 10.0  # percent: a run has left the random floor (1-2% on these tasks) at its first evaluation at or above it
PAPER_ENV_STEPS = {"cn-sparse-n3": 20e6, "cn-sparse-n4": 20e6, "grf-3v1-keeper": 25e6, "grf-counterattack-easy": 25e6}
OPEN = re.compile(r"^<!-- results_pages: (?P<command>.+?) -->$")
CLOSE = "<!-- /results_pages -->"
NONE = "-"
NBSP = "\u00a0"  # inside a number's cell, so that a narrow column does not break "14.7 ± 7.7" over lines

# The paper's Table 1 (5 seeds, 20M env steps on navigation, 25M on football), final coverage or success %.
PAPER = {
    ("cn-sparse-n3", "mappo"): "64.43 ± 1.56",
    ("cn-sparse-n3", "saeir_ppo"): "65.48 ± 1.59",
    ("cn-sparse-n4", "mappo"): "64.26 ± 3.14",
    ("cn-sparse-n4", "saeir_ppo"): "66.80 ± 1.54",
    ("grf-3v1-keeper", "mappo"): "53.77 ± 8.53",
    ("grf-3v1-keeper", "saeir_ppo"): "84.95 ± 4.10",
    ("grf-counterattack-easy", "mappo"): "0.73 ± 0.17",
    ("grf-counterattack-easy", "saeir_ppo"): "76.12 ± 4.48",
}
# Its navigation episode rewards: one agent's reward summed over the 25-step episode (docs/tasks.md, "the authors' unit").
PAPER_REWARD = {
    ("cn-sparse-n3", "mappo"): "3.38 ± 0.06",
    ("cn-sparse-n3", "saeir_ppo"): "3.46 ± 0.07",
    ("cn-sparse-n4", "mappo"): "4.59 ± 0.21",
    ("cn-sparse-n4", "saeir_ppo"): "4.79 ± 0.02",
}
# Task ids read against another task's rows of Table 1: the navigation reading without the collision penalty is the
# paper's task on the reading that reaches its coverage (docs/tasks.md, "Which task id reproduces Table 1").
PAPER_TASK = {"cn-sparse-no-penalty-n3": "cn-sparse-n3", "cn-sparse-no-penalty-n4": "cn-sparse-n4"}


def paper_rows(table: dict[tuple[str, str], str]) -> dict[tuple[str, str], str]:
    """The rows of :data:`PAPER_TASK`'s ids in a table of Table 1 keyed by (task, method): their paper task's rows."""
    return {(task, algo): value for task, paper in PAPER_TASK.items() for (row, algo), value in table.items() if row == paper}


PAPER_ENV_STEPS |= {task: PAPER_ENV_STEPS[paper] for task, paper in PAPER_TASK.items()}
PAPER |= paper_rows(PAPER)
PAPER_REWARD |= paper_rows(PAPER_REWARD)
# The random policy's final coverage or success %: uniform random actions, 1,000 navigation episodes
# (benchmarks/scripted_navigation.py, docs/tasks.md) and 500 football episodes (football-probe/random_baseline.md).
RANDOM = {"mpe N=3": "1.5", "mpe N=4": "2.1", "mpe2 N=3": "1.3", "mpe2 N=4": "1.5", "3v1": "1.0", "counterattack": "0.0"}


class Row(NamedTuple):
    """One (task, method) of a study: its runs and what it is compared with.

    :param task: the task as the tables show it
    :param method: the method as the tables show it
    :param runs: ``CSV[:ALGO]`` sources under ``docs/results/`` whose rows are this method's runs (one seed each)
    :param random: the random policy's value (:data:`RANDOM`)
    :param paper: the paper's Table 1 value (:data:`PAPER`; ``None``: looked up by the runs' task and method)
    :param iqm_group: the ``NAME=CSV[:ALGO]`` (or ``CSV``: every method under its own name) sources of the report
        whose IQM intervals this row repeats, bootstrapped together in that order; empty: this row's runs alone
    :param iqm_name: this row's name in ``iqm_group`` (default: its method's ``algo``)
    :param summary: whether the summary table shows the row
    :param task_id: the runs' task id, where ``runs`` hold more than one task (``None``: they hold one)
    """

    task: str
    method: str
    runs: tuple[str, ...]
    random: str
    paper: str | None = None
    iqm_group: tuple[str, ...] = ()
    iqm_name: str | None = None
    summary: bool = True
    task_id: str | None = None


class Study(NamedTuple):
    """A study page ``docs/results/<name>.md``: its rows and the checkpoints (env steps) of its ``checkpoints`` tables."""

    rows: tuple[Row, ...]
    checkpoints: tuple[float, ...] = ()


NAMES = {
    "mappo": "MAPPO", "saeir_ppo": "SAEIR_PPO", "mshg_only": "MSHG-only", "sae_only": "SAE-only", "ippo": "IPPO",
    "sn_mappo": "SN-MAPPO", "rnd": "RND", "elign": "Elign",
}  # fmt: skip
# the tasks as the tables name them (docs/results.md says what they are)
NAV3, NAV3_FREE, NAV3_REACH, NAV4 = "N=3", "N=3, no penalty", "N=3, reach", "N=4"
THREE, COUNTER = "3 vs 1", "counterattack"


def methods(
    task: str,
    sources: tuple[str, ...],
    algos: str,
    random: str,
    paper: str | None = None,
    iqm_group: tuple[str, ...] = (),
    summary: bool = True,
    task_id: str | None = None,
) -> tuple[Row, ...]:
    """One :class:`Row` per method of ``algos`` (space-separated), its runs ``sources`` with ``{algo}`` filled in; the
    other parameters are :class:`Row`'s, the same for every method."""
    return tuple(
        Row(
            task,
            NAMES[algo],
            tuple(s.format(algo=algo) for s in sources),
            random,
            paper,
            iqm_group,
            summary=summary,
            task_id=task_id,
        )
        for algo in algos.split()
    )


# stage 2b's eight arms, as docs/results/stage2b-comparison/comparison.md names and orders them
ARMS_2B = (
    "MAPPO=stage2-default/runs.csv:mappo",
    "SAE-only (code)=stage2-default/runs.csv:sae_only",
    "MSHG-only=stage2-default/runs.csv:mshg_only",
    "SAEIR_PPO (code)=stage2-default/runs.csv:saeir_ppo",
    "SAE-only (supplement)=stage2b-sae-supplement/runs.csv",
    "SAEIR_PPO (supplement)=stage2b-saeir-supplement/runs.csv",
    "MSHG-only (team scale)=stage2b-mshg-team/runs.csv",
    "MSHG-only (no Gumbel)=stage2b-mshg-no-gumbel/runs.csv",
)


def arm_2b(label: str, name: str, summary: bool) -> Row:
    """A stage 2b arm: its runs and IQM as ``comparison.md``'s; Table 1 only beside stage 2's MAPPO and SAEIR_PPO."""
    source = dict(arm.split("=", 1) for arm in ARMS_2B)[name]
    paper = None if name in ("MAPPO", "SAEIR_PPO (code)") else NONE
    return Row(NAV3, label, (source,), RANDOM["mpe N=3"], paper, ARMS_2B, name, summary)


# issue 51 part 2: the two MSHG-only arms over 15 seeds, as gumbel/comparison.md names and orders them
GUMBEL = "navigation-calibrated/gumbel/runs.csv"
GUMBEL_ARMS = (f"mshg-gumbel={GUMBEL}:mshg-gumbel", f"mshg-no-gumbel={GUMBEL}:mshg-no-gumbel")
# Football 3 vs 1 over the first 1M env steps, the four arms of issue 65 (docs/results/football-ablation.md): the final
# runs cut at 1M that benchmarks/football_ablation.py writes into football-ablation/runs.csv.
ABLATION_3V1 = methods(THREE, ("football-ablation/runs.csv:{algo}",), "mappo saeir_ppo mshg_only sae_only", RANDOM["3v1"])
STAGE2 = "mappo sae_only mshg_only saeir_ppo"
STUDIES: dict[str, Study] = {
    "navigation-5pct": Study(
        (
            *methods(
                NAV3, ("stage2-default/runs.csv:{algo}",), STAGE2, RANDOM["mpe N=3"], iqm_group=("stage2-default/runs.csv",)
            ),
            *methods(
                NAV3_FREE,
                ("stage2-no-penalty/runs.csv:{algo}",),
                STAGE2,
                RANDOM["mpe N=3"],
                NONE,
                iqm_group=("stage2-no-penalty/runs.csv",),
            ),
        ),
        checkpoints=(166_784, 500_000),
    ),
    "navigation-bonus-critic": Study(
        (
            arm_2b("MAPPO", "MAPPO", False),
            arm_2b("SAE-only", "SAE-only (code)", False),
            arm_2b("MSHG-only", "MSHG-only", False),
            arm_2b("SAEIR_PPO", "SAEIR_PPO (code)", False),
            arm_2b("SAE-only, supplement bonus", "SAE-only (supplement)", True),
            arm_2b("SAEIR_PPO, supplement bonus", "SAEIR_PPO (supplement)", True),
            arm_2b("MSHG-only, team scale only", "MSHG-only (team scale)", True),
            arm_2b("MSHG-only, no Gumbel noise", "MSHG-only (no Gumbel)", False),  # in the 15 seeds of the next study
        ),
        checkpoints=(166_784, 500_000),
    ),
    "navigation-variants": Study(
        (
            *methods(NAV3, ("stage1-default/runs.csv:{algo}",), "mappo ippo", RANDOM["mpe N=3"]),
            *methods(
                "N=3, `reach` reward",
                ("stage1-reach/runs.csv:{algo}",),
                "mappo ippo",
                RANDOM["mpe N=3"],
                NONE,
                summary=False,
            ),
            *methods(NAV3_FREE, ("stage1-no-penalty/runs.csv:{algo}",), "mappo ippo", RANDOM["mpe N=3"], NONE, summary=False),
            *methods(
                "N=3, mpe2 world",
                ("stage1-mpe2/runs.csv:{algo}",),
                "mappo ippo",
                RANDOM["mpe2 N=3"],
                NONE,
                summary=False,
            ),
        ),
        checkpoints=(0.5e6, 1e6),
    ),
    "navigation-full-budget": Study(
        (
            *methods(
                NAV3,
                ("navigation-full-budget/runs.csv:{algo}",),
                "mappo saeir_ppo",
                RANDOM["mpe N=3"],
                task_id="cn-sparse-n3",
            ),
            *methods(NAV4, ("navigation-full-budget/runs.csv:{algo}",), "mappo", RANDOM["mpe N=4"], task_id="cn-sparse-n4"),
        ),
        checkpoints=tuple(2e6 * k for k in range(10)),
    ),
    "navigation-calibrated": Study(
        (
            Row(NAV3_FREE, "MAPPO", ("navigation-calibrated/runs.csv:mappo-no-penalty",), RANDOM["mpe N=3"], NONE),
            Row(NAV3_REACH, "MAPPO", ("navigation-calibrated/runs.csv:mappo-reach",), RANDOM["mpe N=3"], NONE),
            Row(NAV3_FREE, "SAEIR_PPO", ("navigation-calibrated/runs.csv:saeir_ppo-no-penalty",), RANDOM["mpe N=3"], NONE),
            *(
                Row(NAV3, label, (f"{GUMBEL}:{arm}",), RANDOM["mpe N=3"], NONE, GUMBEL_ARMS, arm)
                for label, arm in (("MSHG-only", "mshg-gumbel"), ("MSHG-only, no Gumbel noise", "mshg-no-gumbel"))
            ),
        ),
        checkpoints=tuple(2e6 * k for k in range(10)),
    ),
    "football-3v1": Study(
        methods(
            THREE, ("football-probe/runs.csv:{algo}", "football-stage-f/3v1/runs.csv:{algo}"), "mappo saeir_ppo", RANDOM["3v1"]
        ),
        checkpoints=(250_000, 500_000, 750_000, 1e6, 1.5e6),
    ),
    "football-ablation": Study(ABLATION_3V1, checkpoints=(250_000, 500_000, 750_000, 1e6)),
    "counterattack-easy": Study(
        methods(COUNTER, ("football-stage-f/counterattack/runs.csv:{algo}",), "mappo saeir_ppo", RANDOM["counterattack"]),
        checkpoints=(250_000, 500_000, 1e6, 1.5e6),
    ),
    "counterattack-4m": Study(
        (
            *methods(COUNTER, ("counterattack-4m/runs.csv:{algo}",), "mappo", RANDOM["counterattack"], summary=False),
            *methods(COUNTER, ("counterattack-4m/runs.csv:{algo}",), "saeir_ppo", RANDOM["counterattack"]),
        ),
        checkpoints=(1e6, 2e6, 3e6, 4e6),
    ),
    "mpe2-history": Study(
        (
            *methods(
                "N=3, mpe2 world, 16 games",
                ("cn-sparse-n3/runs.csv:{algo}",),
                "mappo sn_mappo rnd elign mshg_only sae_only saeir_ppo",
                RANDOM["mpe2 N=3"],
                NONE,
                summary=False,
            ),
            *methods(
                "N=4, mpe2 world, 16 games",
                ("cn-sparse-n4/runs.csv:{algo}",),
                "mappo sn_mappo rnd elign saeir_ppo",
                RANDOM["mpe2 N=4"],
                NONE,
                summary=False,
            ),
            *methods(
                "N=3, mpe2 world, no penalty, 16 games",
                ("cn-sparse-n3-no-collision-penalty/runs.csv:{algo}",),
                "mappo ippo saeir_ppo",
                RANDOM["mpe2 N=3"],
                NONE,
                summary=False,
            ),
            *methods(
                "N=3, mpe2 world, no penalty, 128 games",
                ("cn-sparse-n3-no-collision-penalty-g128/runs.csv:{algo}",),
                "mappo ippo saeir_ppo",
                RANDOM["mpe2 N=3"],
                NONE,
                summary=False,
            ),
            *methods(
                "N=3, mpe2 world, no penalty, 128 games, seeds 2-3",
                ("cn-sparse-n3-no-collision-penalty-g128-1m/runs.csv:{algo}",),
                "mappo saeir_ppo",
                RANDOM["mpe2 N=3"],
                NONE,
                summary=False,
            ),
            *methods(
                "3 vs 1, 2 games",
                ("grf-3v1-keeper/runs.csv:{algo}",),
                "mappo saeir_ppo",
                RANDOM["3v1"],
                NONE,
                summary=False,
            ),
        ),
    ),
}


def source_rows(source: str, results: Path) -> list[dict[str, Any]]:
    """The evaluation rows of ``CSV[:ALGO]`` (a path under ``results``), only ``ALGO``'s where given."""
    path, _, algo = source.partition(":")
    rows = read_rows(results / path)
    if not rows:
        raise SystemExit(f"results_pages: no rows in {results / path} (missing or empty).")
    chosen = [row for row in rows if not algo or row["algo"] == algo]
    if not chosen:
        raise SystemExit(f"results_pages: no rows of {algo!r} in {results / path}.")
    return chosen


def row_runs(row: Row, results: Path) -> list[dict[str, Any]]:
    """The evaluation rows of a study row's runs, of its one task (``row.task_id`` where its sources hold several)."""
    rows = [r for source in row.runs for r in source_rows(source, results)]
    if row.task_id is not None:
        rows = [r for r in rows if r["task"] == row.task_id]
        if not rows:
            raise SystemExit(f"results_pages: no rows of task {row.task_id!r} in {', '.join(row.runs)}.")
    tasks = sorted({r["task"] for r in rows})
    if len(tasks) > 1:
        raise SystemExit(f"results_pages: {', '.join(row.runs)} hold tasks {', '.join(tasks)}: name the row's task_id.")
    return rows


def group_intervals(sources: tuple[str, ...], results: Path) -> dict[str, tuple[float, float, float]]:
    """IQM and 95% interval per method of a report's runs, bootstrapped as ``rliable_markdown`` does (one seeded
    stream, the methods in the order of :func:`final_scores`), so that they repeat the committed report's."""
    rows: list[dict[str, Any]] = []
    for source in sources:
        name, _, spec = source.rpartition("=")
        rows += [{**r, "algo": name} if name else r for r in source_rows(spec, results)]
    intervals = {}
    with seeded_global_numpy(0):
        for _, (_, values) in final_scores(final_rows(rows)).items():
            scores = {algo: np.array(seeds)[:, None] for algo, seeds in values.items()}  # (n_seeds, 1 task)
            estimates, bounds = iqm_interval_estimates(scores, 2000)
            for algo in scores:
                intervals[algo] = (float(estimates[algo][0]), float(bounds[algo][0, 0]), float(bounds[algo][1, 0]))
    return intervals


def millions(steps: float) -> str:
    """``0``, ``0.17M``, ``0.5M``, ``1.67M``, ``20M``: env steps in millions, two decimals at most."""
    return f"{round(steps / 1e6, 2):g}M" if steps else "0"


def share(steps: float, task: str) -> str:
    percent = f"{100.0 * steps / PAPER_ENV_STEPS[task]:.1f}".rstrip("0").rstrip(".")
    return f"{percent}%"


def floor_exit(curves: list[tuple[np.ndarray, np.ndarray]]) -> str:
    """When the seeds first reach :data:`FLOOR_EXIT`: ``0.5M``, ``0.5-0.75M``, ``0.33M (2 of 5)`` (2 of 5 seeds reached
    it), ``not by 2M``."""
    reaches = [first_reach(curve, FLOOR_EXIT) for curve in curves]
    reached = sorted(steps for steps, hit in reaches if hit)
    last = max(steps for steps, _ in reaches)
    if not reached:
        return f"not by {millions(last)}"
    low, high = millions(reached[0]), millions(reached[-1])
    span = low if low == high else f"{low[:-1]}-{high}"
    return span if len(reached) == len(reaches) else f"{span} ({len(reached)}{NBSP}of{NBSP}{len(reaches)})"


class Figures(NamedTuple):
    """A row's numbers: its runs' task and method, budget (env steps), final values per seed (percent), IQM with its
    interval (``None`` below 3 seeds), when the seeds left the floor and the paper's value."""

    task_id: str
    algo: str
    budget: float
    values: list[float]
    iqm: tuple[float, float, float] | None
    exit: str
    paper: str


def row_figures(row: Row, results: Path, intervals: dict[tuple[str, ...], dict[str, tuple[float, float, float]]]) -> Figures:
    rows = row_runs(row, results)
    task = rows[0]["task"]
    key, _, scale = main_metric(task)
    finals = [r for runs in final_rows(rows).values() for r in runs]
    values = [scale * float(r[key]) for r in finals]
    algo = rows[0]["algo"]
    iqm = None
    if len(values) >= 3:
        group = row.iqm_group or tuple(row.runs)
        if group not in intervals:
            intervals[group] = group_intervals(group if row.iqm_group else tuple(f"{algo}={s}" for s in row.runs), results)
        iqm = intervals[group][row.iqm_name or algo]
    curves = list(next(iter(seed_curves(rows).values())).values())
    return Figures(
        task_id=task,
        algo=algo,
        budget=max(float(r["env_steps"]) for r in finals),
        values=values,
        iqm=iqm,
        exit=floor_exit(curves),
        paper=row.paper if row.paper is not None else PAPER.get((task, algo), NONE),
    )


def number_cells(figures: Figures, digits: int) -> tuple[str, str]:
    """``mean ± std`` (one seed: its value) and ``IQM [low, high]`` (``-`` below 3 seeds), ``digits`` decimals."""
    values = figures.values
    mean_std = (
        f"{np.mean(values):.{digits}f}{NBSP}±{NBSP}{np.std(values):.{digits}f}"
        if len(values) > 1
        else f"{values[0]:.{digits}f}"
    )
    if figures.iqm is None:
        return mean_std, NONE
    estimate, low, high = figures.iqm
    return mean_std, f"{estimate:.{digits}f} [{low:.{digits}f},{NBSP}{high:.{digits}f}]"


def rows_table(study_rows: list[tuple[str, Row]], results: Path, summary: bool) -> list[str]:
    """The Markdown table of some studies' rows: the summary's (one decimal; each budget links to its study page) or a
    study page's (two decimals, as ``table.md``; each seed's final value added; the budget only where it differs
    between rows, the page's protocol gives it otherwise; Table 1 only where the paper has a value)."""
    intervals: dict[tuple[str, ...], dict[str, tuple[float, float, float]]] = {}
    columns: dict[str, list[str]] = {}  # header -> one cell per row
    for name, row in study_rows:
        f = row_figures(row, results, intervals)
        budget = millions(f.budget)
        if f.task_id in PAPER_ENV_STEPS:
            budget += f" ({share(f.budget, f.task_id)})"
        mean_std, iqm = number_cells(f, 1 if summary else 2)
        cells = {
            "task (random %)": f"{row.task} ({row.random})",  # the random policy's floor is the task's
            "method": row.method,
            "budget (paper's share)": f"[{budget}](results/{name}.md)" if summary else budget,
            "seeds": str(len(f.values)),
            "final % per seed": ", ".join(f"{v:.1f}" for v in f.values),
            "final %, mean ± std": mean_std,
            "IQM [95% CI]": iqm,
            f"leaves the floor (≥ {FLOOR_EXIT:g}%)": f.exit,
            "Table 1": f.paper.replace(" ± ", f"{NBSP}±{NBSP}"),
        }
        for header, cell in cells.items():
            columns.setdefault(header, []).append(cell)
    if summary:
        del columns["final % per seed"]
    else:
        if len(set(columns["budget (paper's share)"])) == 1:
            del columns["budget (paper's share)"]
        if set(columns["Table 1"]) == {NONE}:
            del columns["Table 1"]
    lines = ["| " + " | ".join(columns) + " |", "|---" * len(columns) + "|"]
    lines += ["| " + " | ".join(cells) + " |" for cells in zip(*columns.values())]
    return lines


def checkpoints_table(name: str, results: Path, metric: str | None = None) -> list[str]:
    """Per row of the study: each seed's value at each checkpoint and at its last evaluation, with their mean (``-``:
    a run ended before the checkpoint). A row whose runs all end before the second checkpoint is left out: the table
    follows the study's longer runs (``navigation-calibrated``: 20M env steps beside the 1M of its 15-seed arms)."""
    study = STUDIES[name]
    lines = ["| task | method | " + " | ".join(millions(c) for c in study.checkpoints) + " | final |"]
    lines.append("|---" * (len(study.checkpoints) + 3) + "|")
    for row in study.rows:
        rows = row_runs(row, results)
        key, _, scale = main_metric(rows[0]["task"])
        digits = 1
        if metric is not None:
            key, scale, digits = metric, 1.0, 2
        for r in rows:  # the curves of ``metric`` instead of the main metric: same shape, same seeds
            r["_value"] = scale * float(r[key])
        by_seed: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for r in sorted(rows, key=lambda r: (int(r["seed"]), int(r["env_steps"]))):
            steps, values = by_seed.get(int(r["seed"]), (np.array([]), np.array([])))
            by_seed[int(r["seed"])] = (np.append(steps, float(r["env_steps"])), np.append(values, r["_value"]))
        cells = []
        for checkpoint in (*study.checkpoints, None):
            read = [curve[1][-1] if checkpoint is None else value_at(curve, checkpoint) for curve in by_seed.values()]
            found = [float(v) for v in read if v is not None]
            if len(found) < len(read):
                cells.append("-")
                continue
            text = ", ".join(f"{v:.{digits}f}" for v in found)
            cells.append(text if len(found) == 1 else f"{text} (mean {np.mean(found):.{digits}f})")
        if len(study.checkpoints) > 1 and all(cell == "-" for cell in cells[1 : len(study.checkpoints)]):
            continue
        lines.append(f"| {row.task} | {row.method} | " + " | ".join(cells) + " |")
    return lines


def tables_of(text: str) -> list[list[str]]:
    """The Markdown tables of a file, each as its lines."""
    tables: list[list[str]] = []
    current: list[str] = []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            current.append(line)
        elif current:
            tables.append(current)
            current = []
    return tables


def copy_tables(path: Path, numbers: list[int]) -> list[str]:
    tables = tables_of(path.read_text())
    chosen = numbers or list(range(1, len(tables) + 1))
    if not tables or max(chosen) > len(tables):
        raise SystemExit(f"results_pages: {path} has {len(tables)} tables, not {max(chosen, default=1)}.")
    lines: list[str] = []
    for number in chosen:
        lines += ["", *tables[number - 1]] if lines else tables[number - 1]
    return lines


def bonus_readings_table(paths: list[Path]) -> list[str]:
    """The pooled rows (scale ``all``) of ``bonus_readings.md`` files side by side, then the Fig. 3 row."""
    lines = ["| models | reading | fire rate | mean bonus when fired | fire rate at step 0 |", "|---|---|---|---|---|"]
    figure = ""
    for path in paths:
        text = path.read_text()
        models = text.splitlines()[0].removeprefix("### ").split(", stage")[0]
        for table in tables_of(text):
            for line in table[2:]:
                cells = [cell.strip() for cell in line.strip("|").split("|")]
                if cells[1] == "all":
                    lines.append(f"| {models} | {cells[0]} | {' | '.join(cells[2:])} |")
                    models = ""
                elif cells[0].startswith("Fig. 3"):
                    figure = f"| {cells[0]} | | {' | '.join(cells[2:])} |"
    return [*lines, figure] if figure else lines


def block_lines(command: str, results: Path) -> list[str]:
    """The generated lines of one block (``KIND ARGUMENTS``)."""
    kind, *arguments = command.split()
    if kind == "summary":
        chosen = [(name, row) for name, study in STUDIES.items() for row in study.rows if row.summary]
        order = [NAV3, NAV3_FREE, NAV3_REACH, NAV4, THREE, COUNTER]  # by task family, each study's rows in its order
        chosen.sort(key=lambda item: order.index(item[1].task))
        return rows_table(chosen, results, summary=True)
    if kind == "rows":
        return rows_table([(arguments[0], row) for row in STUDIES[arguments[0]].rows], results, summary=False)
    if kind == "checkpoints":
        return checkpoints_table(arguments[0], results, *arguments[1:])
    if kind == "copy":
        return copy_tables(results / arguments[0], [int(n) for n in arguments[1:]])
    if kind == "bonus-readings":
        return bonus_readings_table([results / a for a in arguments])
    raise SystemExit(f"results_pages: unknown block kind {kind!r} ({command!r}).")


def rebuild(text: str, results: Path) -> tuple[str, list[str]]:
    """The page with every block regenerated, and the commands of the blocks that changed."""
    out: list[str] = []
    changed: list[str] = []
    lines = text.splitlines()
    index = 0
    while index < len(lines):
        line = lines[index]
        out.append(line)
        index += 1
        match = OPEN.match(line)
        if not match:
            continue
        end = index
        while end < len(lines) and lines[end] != CLOSE:
            end += 1
        if end == len(lines):
            raise SystemExit(f"results_pages: {line} has no {CLOSE}.")
        fresh = block_lines(match["command"], results)
        if lines[index:end] != fresh:
            changed.append(match["command"])
        out += [*fresh, CLOSE]
        index = end + 1
    return "\n".join(out) + "\n", changed


def pages(docs: Path) -> list[Path]:
    """The results pages: the summary, one page per study, and any other page under ``results/`` with a generated
    block (a study still running copies its report's tables before it has rows)."""
    studies = [docs / "results" / f"{name}.md" for name in STUDIES]
    others = [page for page in sorted((docs / "results").glob("*.md")) if page not in studies and CLOSE in page.read_text()]
    return [docs / "results.md", *studies, *others]


COLORS = {"MAPPO": "C0", "SAEIR_PPO": "C3", "MSHG-only": "C2", "SAE-only": "C1"}  # the summary figures' methods


def draw_panel(axis: Any, title: str, rows: list[Row], results: Path, ylabel: str, paper: bool) -> None:
    """One panel of a summary figure: every seed's curve of each row (thin) and the row's mean over its seeds (thick),
    one colour per method; the random policy dotted and, where ``paper``, Table 1 dashed in the method's colour.

    :param axis: the matplotlib axes
    :param title: the panel's title
    :param rows: the study rows drawn (one method each)
    :param results: ``docs/results``
    :param ylabel: the main metric's label
    :param paper: whether to draw Table 1's values
    """
    import matplotlib

    from sb3_saeir.benchmark.reports import format_steps

    algos = {name: algo for algo, name in NAMES.items()}
    for row in rows:
        runs = row_runs(row, results)
        curves = list(next(iter(seed_curves(runs).values())).values())
        for steps, values in curves:
            axis.plot(steps, values, color=COLORS[row.method], alpha=0.35, linewidth=0.9)
        common = min(len(steps) for steps, _ in curves)
        mean = np.mean([values[:common] for _, values in curves], axis=0)  # (common,)
        label = row.method if len(curves) == 1 else f"{row.method} ({len(curves)} seeds)"
        axis.plot(curves[0][0][:common], mean, color=COLORS[row.method], linewidth=2.2, label=label)
        value = PAPER.get((runs[0]["task"], algos[row.method]))
        if value is not None and paper:
            axis.axhline(float(value.split(" ± ")[0]), color=COLORS[row.method], linestyle="--", linewidth=1,
                         label=f"{row.method}, Table 1")  # fmt: skip
    axis.axhline(float(rows[0].random), color="0.35", linestyle=":", linewidth=1, label="random")
    axis.set_title(title, fontsize=10)
    axis.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(format_steps))
    axis.set_xlabel("env steps")
    axis.set_ylabel(ylabel)
    axis.legend(fontsize=8)


def plot_navigation(results: Path, path: Path) -> None:
    """The summary's navigation figure, six panels: every seed's coverage curve (thin) and each method's mean (thick)
    at 5% of the paper's budget with and without the collision penalty, N=3 and N=4 at its full budget, then N=3 at the
    full budget without the collision penalty and with the ``reach`` reward; the random policy dotted, Table 1 dashed
    in the method's colour on the full-budget panels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sb3_saeir.benchmark.reports import save_figure

    five, full = STUDIES["navigation-5pct"].rows, STUDIES["navigation-full-budget"].rows
    calibrated = STUDIES["navigation-calibrated"].rows
    panels = [
        ("N=3 at 5% of the budget (5 seeds)", [r for r in five if r.task == NAV3]),
        ("N=3 without collision penalty, 5% (5 seeds)", [r for r in five if r.task == NAV3_FREE]),
        ("N=3 at the full budget (1 seed)", [r for r in full if r.task == NAV3]),
        ("N=4 at the full budget (1 seed)", [r for r in full if r.task == NAV4]),
        ("N=3 without collision penalty, full budget (1 seed)", [r for r in calibrated if r.task == NAV3_FREE]),
        ("N=3, reach reward, full budget (1 seed)", [r for r in calibrated if r.task == NAV3_REACH]),
    ]
    figure, axes = plt.subplots(2, 3, figsize=(15.0, 7.6))
    for axis, (title, rows) in zip(axes.flat, panels):
        draw_panel(axis, title, rows, results, "Coverage %", paper="full" in title)
    save_figure(figure, path)


def plot_football(results: Path, path: Path) -> None:
    """The summary's football figure, three panels: every seed's success curve (thin) and each method's mean (thick)
    on 3 vs 1 to 2M env steps (``MAPPO`` and ``SAEIR_PPO``), on 3 vs 1 over the first 1M env steps with the two
    ablations (:data:`ABLATION_3V1`, the final runs only) and on counterattack easy to 4M env steps; the random policy
    dotted. Table 1 is left out: its values are at 25M env steps, far beyond these axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sb3_saeir.benchmark.reports import save_figure

    panels = [
        ("3 vs 1 to 2M env steps", list(STUDIES["football-3v1"].rows)),
        ("3 vs 1, the first 1M: SAEIR's halves alone", list(ABLATION_3V1)),
        ("counterattack easy to 4M env steps", list(STUDIES["counterattack-4m"].rows)),
    ]
    figure, axes = plt.subplots(1, 3, figsize=(15.0, 4.2), sharey=True)  # one success scale: 1% looks like 1%
    for axis, (title, rows) in zip(axes.flat, panels):
        draw_panel(axis, title, rows, results, "Success %", paper=False)
    save_figure(figure, path)


def redraw_curves(folder: Path) -> None:
    """``folder/curves.png`` from ``folder/runs.csv`` with the benchmark's own figure (for folders without run folders)."""
    from sb3_saeir.benchmark import plot_curves

    rows = read_rows(folder / "runs.csv")
    if not rows:
        raise SystemExit(f"results_pages: no rows in {folder / 'runs.csv'}.")
    plot_curves(rows, folder / "curves.png")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--docs", type=Path, default=DOCS, help="the documentation folder (results.md and results/)")
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 where a page differs")
    parser.add_argument("--out", type=Path, help="write the rebuilt pages here (results.md, results/<study>.md)")
    parser.add_argument("--pages", nargs="+", metavar="STUDY", help="only these study pages (default: every page)")
    parser.add_argument("--figures", action="store_true", help="also redraw the summary's figures in results/summary/")
    parser.add_argument("--curves", nargs="+", type=Path, default=[], metavar="FOLDER", help="redraw FOLDER/curves.png")
    args = parser.parse_args(argv)
    results = args.docs / "results"
    chosen = pages(args.docs)
    if args.pages:
        known = {page.stem for page in chosen[1:]}
        unknown = sorted(set(args.pages) - known)
        if unknown:
            parser.error(f"no study page {', '.join(unknown)}; pages: {', '.join(sorted(known))}")
        chosen = [args.docs / "results" / f"{name}.md" for name in args.pages]
    differing = []
    for page in chosen:
        text, changed = rebuild(page.read_text(), results)
        differing += [f"{page}: {command}" for command in changed]
        if args.out is not None:
            target = args.out / page.relative_to(args.docs)
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(text)
        elif not args.check and changed:
            page.write_text(text)
    if args.figures:
        (results / "summary").mkdir(exist_ok=True)
        plot_navigation(results, results / "summary" / "navigation_seeds.png")
        plot_football(results, results / "summary" / "football_seeds.png")
    for folder in args.curves:
        redraw_curves(folder)
    for line in differing:
        print(f"{'differs' if args.check else 'rebuilt'}: {line}")
    return 1 if args.check and differing else 0


if __name__ == "__main__":
    sys.exit(main())
