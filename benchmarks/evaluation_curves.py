"""Long single runs of the benchmark by more than their main metric: every run's curve of each chosen metric over
env steps, against the random policy's floor and published values, and per run its final and best values, its speed
and its wall time.

    python benchmarks/evaluation_curves.py --out docs/results/navigation-full-budget \\
        $HOME/saeir-results/nav-full/cn-sparse-n3/runs.csv $HOME/saeir-results/nav-full/cn-sparse-n4/runs.csv \\
        --metrics coverage_rate success_mean --random-episodes 1000 \\
        --reference cn-sparse-n3:mappo=64.43 cn-sparse-n3:saeir_ppo=65.48 cn-sparse-n4:mappo=64.26

Each argument is a benchmark's ``runs.csv`` (``python -m sb3_saeir.benchmark``); rows of the same (method, task,
seed) given in two files are refused. ``--metrics`` names evaluation metrics (``coverage_rate`` or
``coverage_rate_mean``; default: each task's main metric and ``success``); rates (coverage, success) are shown in
percent, other metrics as their means. Writes ``OUT/curves_full.png`` (one row of panels per task, one column per
metric: every (method, seed) curve, the random policy's value dotted, each ``--reference TASK:ALGO=VALUE`` dashed in
the method's colour on the main metric's panel) and ``OUT/evaluation_curves.md``, which it also prints: per task and
run, each metric's value at the last evaluation and its best value with the env steps of the first evaluation that
reached it, the last evaluation's env steps, and from the run folder's ``segments.json`` (``runs/<algo>/<task>_s<seed>``
beside the ``runs.csv``) the agent-steps per second and the wall time over all segments (agent-steps trained by the
segments, a resume's repeated steps included, over their summed wall time, which includes the evaluations); then the
random policy (``--random-episodes`` episodes of uniform random actions on ``--random-games`` games with the task's
defaults, as ``benchmarks/random_baseline.py``; 0 skips it) and the references. With ``--plateau TOL`` each run's
row also says where its main metric plateaus: the env steps of the first evaluation from which every later one lies
within ``TOL`` (display units: percentage points for rates) of the run's level, the mean of its last
3 evaluations.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, NamedTuple, TypeGuard

import numpy as np

from sb3_saeir.benchmark import read_rows
from sb3_saeir.benchmark.reports import format_steps
from sb3_saeir.command_line import OneLineParser
from sb3_saeir.envs import get_task_spec
from sb3_saeir.run.files import SEGMENTS_FILE

sys.path.insert(0, str(Path(__file__).parent))
from random_baseline import random_scores

PROG = "evaluation_curves"
# Metrics that are rates (a fraction of episodes, of landmarks or of steps): shown x100, in percent.
RATES = {"coverage_rate": "Coverage %", "coverage_over_steps": "Coverage over steps %", "success": "Success %"}
REQUIRED = ("algo", "task", "seed", "env_steps")

RunKey = tuple[str, str, int]  # (algo, task, seed)
Curve = tuple[np.ndarray, np.ndarray]  # (env steps, values in the metric's display unit), sorted by env steps


class ReportError(ValueError):
    """A problem with the command's inputs, reported as one line ``evaluation_curves: error: ...`` (exit status 2)."""


class Reference(NamedTuple):
    """A published value of a method's main metric on a task, in the metric's display unit (percent for rates)."""

    task: str
    algo: str
    value: float


def metric_name(name: str) -> str:
    """A metric's name without the ``_mean`` suffix of its ``runs.csv`` column (``success_mean`` -> ``success``)."""
    return name[: -len("_mean")] if name.endswith("_mean") else name


def metric_display(metric: str) -> tuple[str, float]:
    """``(title, scale)`` of a metric: rates in percent (x100), any other metric as its mean (x1).

    :param metric: the metric's name, without ``_mean``
    """
    if metric in RATES:
        return RATES[metric], 100.0
    return metric, 1.0


def parse_reference(text: str) -> Reference:
    """argparse type of ``--reference``: ``TASK:ALGO=VALUE``, the value in percent for rates."""
    head, equals, value = text.rpartition("=")
    task, colon, algo = head.partition(":")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not (equals and colon and task and algo) or not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"{text!r} is not TASK:ALGO=VALUE (e.g. cn-sparse-n3:mappo=64.43)")
    return Reference(task, algo, number)


def gather(paths: list[Path]) -> tuple[dict[RunKey, list[dict[str, Any]]], dict[RunKey, Path]]:
    """The evaluation rows of every ``runs.csv`` per run, sorted by env steps, and each run's folder.

    :param paths: benchmark ``runs.csv`` files
    :return: ``({(algo, task, seed): rows}, {(algo, task, seed): run folder})``, the folder being
        ``runs/<algo>/<task>_s<seed>`` beside the ``runs.csv`` (it may not exist)
    :raises ReportError: a missing file, a file without evaluation rows, or a run found in two files
    """
    runs: dict[RunKey, list[dict[str, Any]]] = {}
    folders: dict[RunKey, Path] = {}
    owner: dict[RunKey, Path] = {}
    for path in paths:
        if not path.is_file():
            raise ReportError(f"{path} does not exist.")
        found = read_rows(path)
        if not found or any(column not in found[0] for column in REQUIRED):
            raise ReportError(f"{path} has no evaluation rows (columns {', '.join(REQUIRED)}, ...).")
        keys = {(str(row["algo"]), str(row["task"]), int(row["seed"])) for row in found}
        for key in sorted(keys):
            if key in owner:
                raise ReportError(f"{key} is in both {owner[key]} and {path}; give each run once.")
            owner[key] = path
            folders[key] = path.parent / "runs" / key[0] / f"{key[1]}_s{key[2]}"
        for row in found:
            runs.setdefault((str(row["algo"]), str(row["task"]), int(row["seed"])), []).append(row)
    return {key: sorted(rows, key=lambda row: float(row["env_steps"])) for key, rows in sorted(runs.items())}, folders


def available_metrics(rows: list[dict[str, Any]]) -> list[str]:
    """The metrics with a number in at least one of ``rows`` (columns ``<metric>_mean``), sorted."""
    return sorted(
        {metric_name(key) for row in rows for key, value in row.items() if key.endswith("_mean") and _is_number(value)}
    )


def main_metric(task: str) -> str:
    """A task's main metric (``TaskSpec.main_metric``) by its ``runs.csv`` name (the return ``r``: ``ep_rew``).

    :param task: a task id
    :raises ReportError: a task that is not registered
    """
    try:
        metric = get_task_spec(task).main_metric
    except KeyError as error:
        raise ReportError(str(error.args[0])) from None
    return "ep_rew" if metric == "r" else metric


def task_metrics(task: str, rows: list[dict[str, Any]], requested: list[str] | None) -> list[str]:
    """The metrics shown for a task: ``requested`` (names with or without ``_mean``), else its main metric and
    ``success`` (when the rows have it).

    :param task: a registered task id
    :param rows: the task's evaluation rows
    :param requested: ``--metrics``, or ``None`` for the default
    :raises ReportError: a metric that none of the task's rows holds (the message lists those they hold)
    """
    main = main_metric(task)
    available = available_metrics(rows)
    if requested is None:
        requested = [main, *(["success"] if "success" in available else [])]
    metrics = list(dict.fromkeys(metric_name(name) for name in requested))
    for metric in metrics:
        if metric not in available:
            raise ReportError(f"no metric {metric!r} in the rows of {task}; they have: {', '.join(available)}.")
    return metrics


def metric_curve(rows: list[dict[str, Any]], metric: str) -> Curve:
    """One run's curve of a metric: env steps and values in its display unit, over the rows that hold a number for it.

    :param rows: the run's evaluation rows, sorted by env steps
    :param metric: the metric's name, without ``_mean``
    """
    _, scale = metric_display(metric)
    points = [
        (float(row["env_steps"]), scale * float(row[f"{metric}_mean"]))
        for row in rows
        if _is_number(row.get(f"{metric}_mean"))
    ]
    steps = np.array([step for step, _ in points])  # (n_evaluations,)
    return steps, np.array([value for _, value in points])


def final_and_best(curve: Curve) -> tuple[float, float, float]:
    """``(value at the last evaluation, highest value, env steps of the first evaluation that reached it)``."""
    steps, values = curve
    best = int(np.argmax(values))  # the first index of the maximum
    return float(values[-1]), float(values[best]), float(steps[best])


def plateau_start(curve: Curve, tolerance: float, tail: int = 3) -> tuple[float, float]:
    """Where a curve plateaus: ``(env steps of the first evaluation from which every later value lies within
    ``tolerance`` of the level, the level)``, the level being the mean of the last ``tail`` values (all of them when
    there are fewer). The last evaluation always qualifies when it is within ``tolerance`` of the level.

    :param curve: env steps and values of one run, sorted by env steps
    :param tolerance: the largest distance from the level, in the values' unit
    :param tail: evaluations averaged for the level
    """
    steps, values = curve
    level = float(np.mean(values[-tail:]))
    inside = np.abs(values - level) <= tolerance  # (n_evaluations,)
    start = len(values)
    while start > 0 and inside[start - 1]:
        start -= 1
    return (float(steps[start]) if start < len(values) else math.nan), level


def wall_time(folder: Path) -> tuple[float, float] | None:
    """``(agent-steps, wall seconds)`` summed over a run's ``segments.json`` segments (``None``: no such file).

    Each segment trained from its ``resumed_at`` to its ``reached`` agent-steps in ``wall_s`` seconds (evaluations and
    checkpoints included); steps a resume trains again count again.

    :param folder: the run's folder
    :raises ReportError: a ``segments.json`` that is not a list of segments
    """
    path = folder / SEGMENTS_FILE
    if not path.is_file():
        return None
    try:
        segments = json.loads(path.read_text())
        steps = sum(float(segment["reached"]) - float(segment["resumed_at"]) for segment in segments)
        seconds = sum(float(segment["wall_s"]) for segment in segments)
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, ValueError) as error:
        raise ReportError(f"{path} is not a list of segments ({error!r}).") from None
    return steps, seconds


def random_floors(tasks: list[str], episodes: int, games: int, seed: int) -> dict[str, dict[str, Any]]:
    """The random policy's evaluation summary per task (:func:`random_baseline.random_scores`, the task's defaults).

    :param tasks: registered task ids
    :param episodes: game episodes per task (0: none, an empty result)
    :param games: games played side by side
    :param seed: seed of the games and of the random actions
    :return: ``{task: {"<metric>_mean": ..., "n_episodes": ..., ...}}``
    """
    if episodes < 1:
        return {}
    return {task: random_scores(task, episodes, games, seed, {}) for task in tasks}


def task_table(
    task: str,
    metrics: list[str],
    runs: dict[RunKey, list[dict[str, Any]]],
    folders: dict[RunKey, Path],
    floor: dict[str, Any] | None,
    references: list[Reference],
    reference_label: str,
    plateau: float | None = None,
) -> list[str]:
    """The Markdown of one task: one row per (method, seed), the random policy's row and the references' rows.

    :param task: the task
    :param metrics: the metrics shown (names without ``_mean``)
    :param runs: the task's runs' evaluation rows
    :param folders: each run's folder
    :param floor: the random policy's summary on the task (``None``: not played)
    :param references: published values of the task's main metric
    :param reference_label: what the references are, after the method's name (``paper 20M``)
    :param plateau: the tolerance of :func:`plateau_start` on the main metric (``None``: no plateau column)
    """
    titles = [metric_display(metric)[0] for metric in metrics]
    main = main_metric(task)
    header = [f"{title} {part}" for title in titles for part in ("final", "best (first at)")]
    if plateau is not None:
        header.append(f"{metric_display(main)[0]} plateau from (level, within {plateau:g})")
    header += ["last evaluation", "agent-steps/s", "wall (h)"]
    lines = [f"## {task}", "", f"| run | {' | '.join(header)} |", "|---" * (len(header) + 1) + "|"]
    evaluations, episodes = {}, set()
    for (algo, _, seed), rows in runs.items():
        cells = []
        for metric in metrics:
            curve = metric_curve(rows, metric)
            if not len(curve[0]):  # the run has no value of this metric
                cells += ["-", "-"]
                continue
            final, best, best_at = final_and_best(curve)
            cells += [f"{final:.2f}", f"{best:.2f} ({format_steps(best_at)})"]
        if plateau is not None:
            main_curve = metric_curve(rows, main)
            start, level = plateau_start(main_curve, plateau) if len(main_curve[0]) else (math.nan, math.nan)
            cells.append("-" if math.isnan(start) else f"{format_steps(start)} ({level:.2f})")
        timing = wall_time(folders[(algo, task, seed)])
        speed, hours = ("n/a", "n/a") if timing is None else (_rate(*timing), f"{timing[1] / 3600:.1f}")
        cells += [format_steps(float(rows[-1]["env_steps"])), speed, hours]
        lines.append(f"| {algo} s{seed} | {' | '.join(cells)} |")
        evaluations[f"{algo} s{seed}"] = len(rows)
        episodes |= {int(row["n_episodes"]) for row in rows if _is_number(row.get("n_episodes"))}
    if floor is not None:
        values = [_scaled(floor, metric) for metric in metrics]
        cells = [cell for value in values for cell in (value, "-")] + ["-"] * (3 + (plateau is not None))
        lines.append(f"| random policy ({floor['n_episodes']:.0f} episodes) | {' | '.join(cells)} |")
    for reference in references:
        cells = [cell for metric in metrics for cell in (f"{reference.value:.2f}" if metric == main else "-", "-")]
        cells += ["-"] * (3 + (plateau is not None))
        lines.append(f"| {reference.algo}, {reference_label} | {' | '.join(cells)} |")
    return [*lines, "", evaluation_note(evaluations, episodes), ""]


def evaluation_note(evaluations: dict[str, int], episodes: set[int]) -> str:
    """The line under a task's table: evaluations per run and game episodes per evaluation (``n_episodes``)."""
    counts = set(evaluations.values())
    if len(counts) == 1:
        per_run = f"Each run has {counts.pop()} evaluations"
    else:
        per_run = "Evaluations per run: " + ", ".join(f"{run} {count}" for run, count in evaluations.items())
    if not episodes:
        return f"{per_run}; the episodes per evaluation are not recorded (no n_episodes column)."
    return f"{per_run}, of {' or '.join(str(n) for n in sorted(episodes))} game episodes each (n_episodes)."


def plot_curves(
    curves: dict[str, dict[str, dict[tuple[str, int], Curve]]],
    floors: dict[str, dict[str, Any]],
    references: list[Reference],
    reference_label: str,
    path: Path,
) -> None:
    """One row of panels per task, one column per metric: every (method, seed) curve over env steps, one colour per
    method (one marker per seed); the random policy's value dotted, references dashed on the main metric's panel.

    :param curves: ``{task: {metric: {(algo, seed): curve}}}``
    :param floors: the random policy's summary per task (a task without one: no line)
    :param references: published main-metric values
    :param reference_label: what the references are, after the method's name
    :param path: the figure's file
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sb3_saeir.benchmark.reports import label_task_panel, save_figure

    algos = sorted({algo for by_metric in curves.values() for runs in by_metric.values() for algo, _ in runs})
    algos += sorted({reference.algo for reference in references} - set(algos))
    colors = {algo: f"C{index}" for index, algo in enumerate(algos)}
    n_columns = max(len(by_metric) for by_metric in curves.values())
    figure, axes = plt.subplots(len(curves), n_columns, figsize=(5.5 * n_columns, 3.8 * len(curves)), squeeze=False)
    for row, (task, by_metric) in enumerate(curves.items()):
        main = main_metric(task)
        for column, (metric, runs) in enumerate(by_metric.items()):
            axis = axes[row, column]
            title, scale = metric_display(metric)
            seeds = sorted({seed for _, seed in runs})
            for (algo, seed), (steps, values) in runs.items():
                marker = ".ox^sv"[seeds.index(seed) % 6]
                axis.plot(
                    steps, values, color=colors[algo], marker=marker, markersize=4, linewidth=1.2, label=f"{algo} s{seed}"
                )
            if task in floors and _is_number(floors[task].get(f"{metric}_mean")):
                axis.axhline(scale * floors[task][f"{metric}_mean"], color="0.35", linestyle=":", label="random")
            for reference in references if metric == main else []:
                if reference.task == task:
                    label = f"{reference.algo}, {reference_label}"
                    axis.axhline(reference.value, color=colors[reference.algo], linestyle="--", linewidth=1, label=label)
            label_task_panel(axis, task, title)
        for column in range(len(by_metric), n_columns):
            axes[row, column].set_visible(False)
    save_figure(figure, path)


def check_references(references: list[Reference], metrics: dict[str, list[str]]) -> None:
    """Refuse a reference to a task without runs, or to one whose main metric is not shown.

    :param references: ``--reference`` values
    :param metrics: the metrics shown per task
    """
    for reference in references:
        name = f"--reference {reference.task}:{reference.algo}={reference.value:g}"
        if reference.task not in metrics:
            raise ReportError(f"{name}: no runs of {reference.task} in the files given (tasks: {', '.join(metrics)}).")
        main = main_metric(reference.task)
        if main not in metrics[reference.task]:
            raise ReportError(f"{name}: it is a value of the main metric {main}, which --metrics leaves out.")


def shown_path(path: Path) -> str:
    """``path`` as the report shows it: under the home folder as ``$HOME/...`` (a report names no user's home)."""
    home = Path.home()
    resolved = Path(path).expanduser().absolute()
    return f"$HOME/{resolved.relative_to(home)}" if resolved.is_relative_to(home) else str(path)


def report(args: argparse.Namespace) -> str:
    """Read the runs, play the random policy, write the figure and the Markdown; the Markdown's text."""
    runs, folders = gather(args.runs)
    by_task: dict[str, dict[RunKey, list[dict[str, Any]]]] = {}
    for key, rows in runs.items():
        by_task.setdefault(key[1], {})[key] = rows
    metrics = {
        task: task_metrics(task, [row for rows in task_runs.values() for row in rows], args.metrics)
        for task, task_runs in sorted(by_task.items())
    }
    check_references(args.reference, metrics)
    floors = random_floors(list(metrics), args.random_episodes, args.random_games, args.random_seed)
    lines = [f"Runs: {', '.join(f'`{shown_path(p)}`' for p in args.runs)}", ""]
    if floors:
        lines += [
            f"Random policy: {args.random_episodes} episodes of uniform random actions on {args.random_games} games per "
            f"task (the task's defaults, seed {args.random_seed}).",
            "",
        ]
    curves: dict[str, dict[str, dict[tuple[str, int], Curve]]] = {}
    for task, shown in metrics.items():
        task_references = [reference for reference in args.reference if reference.task == task]
        table = task_table(
            task, shown, by_task[task], folders, floors.get(task), task_references, args.reference_label, args.plateau
        )
        lines += table
        curves[task] = {
            metric: {(algo, seed): metric_curve(rows, metric) for (algo, _, seed), rows in by_task[task].items()}
            for metric in shown
        }
    args.out.mkdir(parents=True, exist_ok=True)
    plot_curves(curves, floors, args.reference, args.reference_label, args.out / "curves_full.png")
    text = "\n".join(lines)
    (args.out / "evaluation_curves.md").write_text(text)
    return text


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog=PROG, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", type=Path, help="benchmark runs.csv files")
    parser.add_argument("--out", type=Path, required=True, help="folder for evaluation_curves.md and curves_full.png")
    parser.add_argument("--metrics", nargs="+", default=None, help="default: each task's main metric and success")
    parser.add_argument("--random-episodes", type=int, default=1000, help="random-policy episodes per task (0: none)")
    parser.add_argument("--random-games", type=int, default=10, help="games the random policy plays side by side")
    parser.add_argument("--random-seed", type=int, default=0, help="seed of the random policy's games and actions")
    parser.add_argument(
        "--reference", nargs="+", type=parse_reference, default=[], help="TASK:ALGO=VALUE, main metric (%% for rates)"
    )
    parser.add_argument("--reference-label", default="paper 20M", help="what the references are (legend and table)")
    parser.add_argument(
        "--plateau", type=float, default=None, help="also where the main metric plateaus, within this tolerance"
    )
    args = parser.parse_args(argv)
    if args.random_episodes < 0 or args.random_games < 1:
        parser.error(
            f"--random-episodes must be >= 0 and --random-games >= 1, got {args.random_episodes} and {args.random_games}"
        )
    if args.plateau is not None and not (math.isfinite(args.plateau) and args.plateau > 0):
        parser.error(f"--plateau must be a positive number, got {args.plateau}")
    try:
        text = report(args)
    except ReportError as error:
        print(f"{PROG}: error: {error}", file=sys.stderr)
        return 2
    print(text)
    return 0


def _is_number(value: Any) -> TypeGuard[float]:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _rate(steps: float, seconds: float) -> str:
    """Agent-steps per second, with thousands separators (``n/a`` without any wall time)."""
    return f"{steps / seconds:,.0f}" if seconds > 0 else "n/a"


def _scaled(summary: dict[str, Any], metric: str) -> str:
    """A metric's mean in an evaluation summary, in its display unit (``-`` when absent)."""
    value = summary.get(f"{metric}_mean")
    return f"{metric_display(metric)[1] * value:.2f}" if _is_number(value) else "-"


if __name__ == "__main__":
    sys.exit(main())
