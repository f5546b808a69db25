"""How fast each method leaves the floor, over seeds: success at fixed env-step counts, the env steps at which each
seed first reaches a success threshold (and a one-sided test of whether one method gets there earlier), the area
under the success curve, the pairwise table and every seed's curve.

    python benchmarks/learning_speed.py --out docs/results/football-stage-f \\
        docs/results/football-probe/runs.csv docs/results/football-stage-f/3v1/runs.csv \\
        docs/results/football-stage-f/counterattack/runs.csv \\
        --bonus $HOME/saeir-results/stage-f/3v1/runs/saeir_ppo/grf-3v1-keeper_s2

Each argument is a benchmark's ``runs.csv`` (``python -m sb3_saeir.benchmark``); rows of the same (method, task,
seed) given twice are refused. The figures are computed from the evaluation rows only, with the benchmark's own
statistics (:func:`sb3_saeir.benchmark.mann_whitney`, the IQM with rliable's stratified bootstrap): see
``docs/results.md``. Writes ``OUT/learning_speed.md`` and ``OUT/curves_seeds.png`` and prints the Markdown. With
``--bonus RUN_FOLDER ...`` it adds, per SAEIR run, the bonus's fire rate and mean size per scale averaged over each
``--window`` env steps, the critics' value-softmax entropy and the episode starts per env step (from the run's
``progress.csv``).

Definitions (env steps are game steps, the x axis of the benchmark's curves):

- **success at S**: the main metric of the evaluation taken at S env steps (the first evaluation at or after S);
- **first reach of a threshold**: the env steps of the first evaluation whose main metric is at or above it; a seed
  that never reaches it within its run is censored at its last evaluation and ranks after every seed that did;
- **area under the curve**: the trapezoid area under the main metric over env steps, divided by the span of env
  steps (the curve's mean height over training, in the metric's unit), up to the shortest run's last evaluation so
  that every seed covers the same span;
- **earlier test**: the exact one-sided Mann-Whitney test of "method A reaches the threshold earlier than B" over
  seeds (ties, censored seeds included, count half); with 3 seeds each its smallest possible p-value is 1/20 = 0.05.
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from sb3_saeir.benchmark import read_rows
from sb3_saeir.benchmark.statistics import iqm_interval_estimates, iqm_trims_none, main_metric, seeded_global_numpy

sys.path.insert(0, str(Path(__file__).parent))
from evaluation_curves import shown_path

Curve = tuple[np.ndarray, np.ndarray]  # (env steps, main metric in its unit), sorted by env steps


def seed_curves(rows: list[dict[str, Any]]) -> dict[tuple[str, str], dict[int, Curve]]:
    """Every seed's curve of the main metric, grouped by (task, method).

    :param rows: evaluation rows of one or more ``runs.csv``
    :return: ``{(task, algo): {seed: (env_steps, values)}}``, values scaled to the metric's unit (percent)
    """
    points: dict[tuple[str, str, int], dict[int, float]] = {}
    for row in rows:
        key, _, scale = main_metric(row["task"])
        points.setdefault((row["task"], row["algo"], int(row["seed"])), {})[int(row["env_steps"])] = scale * float(row[key])
    curves: dict[tuple[str, str], dict[int, Curve]] = {}
    for (task, algo, seed), by_step in sorted(points.items()):
        steps = np.array(sorted(by_step), dtype=float)  # (n_evaluations,)
        curves.setdefault((task, algo), {})[seed] = (steps, np.array([by_step[int(s)] for s in steps]))
    return curves


def value_at(curve: Curve, env_steps: float) -> float | None:
    """The value of the first evaluation at or after ``env_steps`` (``None``: the run ends before)."""
    steps, values = curve
    later = np.nonzero(steps >= env_steps)[0]
    return float(values[later[0]]) if len(later) else None


def first_reach(curve: Curve, threshold: float) -> tuple[float, bool]:
    """``(env steps, reached)``: the first evaluation at or above ``threshold``, else the last one, censored."""
    steps, values = curve
    above = np.nonzero(values >= threshold)[0]
    if len(above):
        return float(steps[above[0]]), True
    return float(steps[-1]), False


def area_under_curve(curve: Curve, end: float) -> float:
    """The curve's mean height between its first evaluation and ``end`` (trapezoids; ``end`` is one of its steps)."""
    steps, values = curve
    inside = steps <= end
    steps, values = steps[inside], values[inside]
    if len(steps) < 2:
        raise ValueError(f"an area needs two evaluations up to {end:.0f} env steps, got {len(steps)}")
    area = float(np.sum((steps[1:] - steps[:-1]) * (values[1:] + values[:-1]) / 2.0))
    return area / float(steps[-1] - steps[0])


def reach_ranks(reaches: list[tuple[float, bool]]) -> list[float]:
    """Sort keys of first reaches: reached seeds by their env steps, censored ones after all of them (all tied)."""
    return [steps if reached else math.inf for steps, reached in reaches]


def earlier_test(first: list[float], second: list[float]) -> tuple[float, float]:
    """Exact one-sided Mann-Whitney test that ``first`` (times to a threshold) is smaller than ``second``.

    :param first: one time per seed of method A (``inf``: never reached)
    :param second: one time per seed of method B
    :return: ``(share of (A, B) seed pairs where A is earlier, ties counting half; p-value)``: the p-value is the
        share of the splits of the pooled times into groups of these sizes whose share is at least the observed one
        (counted, not listed: :func:`sb3_saeir.benchmark.statistics.mann_whitney_splits`)
    """
    from sb3_saeir.benchmark.statistics import mann_whitney_splits

    pairs = len(first) * len(second)
    later, split_later, counts = mann_whitney_splits(first, second)  # U: pairs where A is later, ties half
    # a split's earlier share is 1 - U / pairs: at least the observed share where its U is at most the observed U
    extreme = split_later <= later + 1e-9
    return 1.0 - later / pairs, float(counts[extreme].sum() / counts.sum())


def iqm_interval(values: list[float], reps: int = 2000, bootstrap_seed: int = 0) -> tuple[float, float, float]:
    """IQM of one method's values over seeds and its 95% bootstrap interval (rliable, as ``aggregate.md``)."""
    scores = {"m": np.array(values, dtype=float)[:, None]}  # (n_seeds, 1 task)
    with seeded_global_numpy(bootstrap_seed):
        estimates, intervals = iqm_interval_estimates(scores, reps)
    return float(estimates["m"][0]), float(intervals["m"][0, 0]), float(intervals["m"][1, 0])


def _format(value: float | None, digits: int = 0) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _millions(steps: float) -> str:
    """``steps`` in millions to four significant digits: ``0.5M``, ``1.002M`` for 1,001,600."""
    return f"{steps / 1e6:.4g}M"


def success_table(curves: dict[int, Curve], checkpoints: list[float], title: str) -> list[str]:
    """Per checkpoint: every seed's value, the mean and (with 3 or more seeds) the IQM and its bootstrap interval.

    The IQM trims a quarter of the seeds from each end, rounded down, so with 3 seeds it trims none and equals the mean;
    the table then says so under it.
    """
    lines = [f"| env steps | per seed ({title}) | mean | IQM [95% CI] |", "|---|---|---|---|"]
    iqm_untrimmed = False
    for checkpoint in checkpoints:
        values = {seed: value_at(curve, checkpoint) for seed, curve in curves.items()}
        known = [v for v in values.values() if v is not None]
        per_seed = ", ".join(f"s{seed} {_format(v)}" for seed, v in values.items())
        mean = _format(float(np.mean(known)), 1) if known else "-"
        iqm = "-"
        if len(known) >= 3 and len(known) == len(values):
            estimate, low, high = iqm_interval(known)
            iqm = f"{estimate:.1f} [{low:.1f}, {high:.1f}]"
            iqm_untrimmed = iqm_untrimmed or iqm_trims_none(len(known))
        lines.append(f"| {_millions(checkpoint)} | {per_seed} | {mean} | {iqm} |")
    if iqm_untrimmed:
        lines += [
            "",
            "With 3 seeds the IQM trims none of them (a quarter of 3 rounds down to 0), so it equals the mean; its "
            "interval is the bootstrap's over the seeds.",
        ]
    return lines


def reach_table(curves: dict[int, Curve], thresholds: list[float]) -> list[str]:
    """Per threshold: the env steps at which each seed first reaches it (``>`` last evaluation: never)."""
    lines = ["| threshold | first reached at (env steps) per seed |", "|---|---|"]
    for threshold in thresholds:
        cells = []
        for seed, curve in curves.items():
            steps, reached = first_reach(curve, threshold)
            cells.append(f"s{seed} {_millions(steps)}" if reached else f"s{seed} > {_millions(steps)}")
        lines.append(f"| {threshold:g} | {', '.join(cells)} |")
    return lines


def task_section(
    task: str, by_algo: dict[str, dict[int, Curve]], checkpoints: list[float], thresholds: list[float]
) -> list[str]:
    """The Markdown of one task: success table, first reaches and AUC per method, then the pairwise comparisons."""
    from sb3_saeir.benchmark import mann_whitney

    _, title, _ = main_metric(task)
    end = min(curve[0][-1] for curves in by_algo.values() for curve in curves.values())
    # the areas run to the shortest run's last evaluation: none while a run has only its evaluation at 0
    with_areas = all(np.sum(curve[0] <= end) >= 2 for curves in by_algo.values() for curve in curves.values())
    lines = [f"## {task}", ""]
    for algo, curves in by_algo.items():
        lines += [f"### {algo} (seeds {', '.join(str(s) for s in curves)})", ""]
        lines += [*success_table(curves, checkpoints, title), ""]
        lines += [*reach_table(curves, thresholds), ""]
        if not with_areas:
            lines += ["Area under the curve: none yet (a run has one evaluation so far).", ""]
            continue
        areas = [area_under_curve(curve, end) for curve in curves.values()]
        per_seed = ", ".join(f"s{seed} {area:.1f}" for seed, area in zip(curves, areas))
        lines += [
            f"Area under the curve up to {_millions(end)} env steps (mean {title}): {per_seed}; mean {np.mean(areas):.1f}.",
            "",
        ]
    lines += [
        "Pairwise (A against B): difference of the means, the share of seed pairs where A is above (ties half) and "
        "the two-sided Mann-Whitney p; for first reaches, the share of seed pairs where A is earlier and the exact "
        "one-sided p that A is earlier.",
        "",
        "| A | B | quantity | mean A - mean B | A above / earlier (seed pairs) | p |",
        "|---|---|---|---|---|---|",
    ]
    for first, second in itertools.permutations(by_algo, 2):
        a_curves, b_curves = by_algo[first], by_algo[second]
        label = f"| {first} (n={len(a_curves)}) | {second} (n={len(b_curves)}) "
        for checkpoint in checkpoints:
            a = [value_at(c, checkpoint) for c in a_curves.values()]
            b = [value_at(c, checkpoint) for c in b_curves.values()]
            if None in a or None in b or first > second:  # each two-sided comparison once
                continue
            statistic, p_value = mann_whitney(a, b)  # type: ignore[arg-type]
            lines.append(
                f"{label}| {title} at {_millions(checkpoint)} | {np.mean(a) - np.mean(b):+.1f} "  # type: ignore[arg-type]
                f"| {statistic / (len(a) * len(b)):.0%} | {p_value:.3f} (two-sided) |"
            )
        if first < second and with_areas:
            a_area = [area_under_curve(c, end) for c in a_curves.values()]
            b_area = [area_under_curve(c, end) for c in b_curves.values()]
            statistic, p_value = mann_whitney(a_area, b_area)
            lines.append(
                f"{label}| area to {_millions(end)} | {np.mean(a_area) - np.mean(b_area):+.1f} "
                f"| {statistic / (len(a_area) * len(b_area)):.0%} | {p_value:.3f} (two-sided) |"
            )
        for threshold in thresholds:
            a_times = reach_ranks([first_reach(c, threshold) for c in a_curves.values()])
            b_times = reach_ranks([first_reach(c, threshold) for c in b_curves.values()])
            share, p_value = earlier_test(a_times, b_times)
            lines.append(f"{label}| first reach of {threshold:g} | | {share:.0%} | {p_value:.3f} (one-sided) |")
    return [*lines, ""]


def plot_seed_curves(curves: dict[tuple[str, str], dict[int, Curve]], path: Path) -> None:
    """One panel per task: every seed's curve (thin) and the mean over seeds (thick), one colour per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sb3_saeir.benchmark.reports import label_task_panel, save_figure

    tasks = sorted({task for task, _ in curves})
    figure, axes = plt.subplots(1, len(tasks), figsize=(5.5 * len(tasks), 3.8), squeeze=False)
    for axis, task in zip(axes[0], tasks):
        _, title, _ = main_metric(task)
        algos = sorted(algo for t, algo in curves if t == task)
        for index, algo in enumerate(algos):
            color = f"C{index}"
            seeds = curves[(task, algo)]
            for seed, (steps, values) in seeds.items():
                axis.plot(steps, values, color=color, alpha=0.45, linewidth=1, marker=".", markersize=3)
                axis.annotate(f"s{seed}", (steps[-1], values[-1]), fontsize=6, color=color)
            common = min(len(steps) for steps, _ in seeds.values())
            steps = next(iter(seeds.values()))[0][:common]
            mean = np.mean([values[:common] for _, values in seeds.values()], axis=0)  # (common,)
            axis.plot(steps, mean, color=color, linewidth=2.2, label=f"{algo} (mean of {len(seeds)})")
        label_task_panel(axis, task, title)
    save_figure(figure, path)


def bonus_windows(run: Path, window: float) -> list[str]:
    """The SAEIR bonus's fire rate and mean size per scale, averaged over the rollouts of each ``window`` env steps,
    the entropy of each critic's value-softmax over the rollout window (``rollout/value_entropy_<scale>``) where the
    run logged it, and the episode starts per env step, ``1 / rollout/ep_len_mean``, where it logged episode lengths.

    A bonus that fires only when a new episode starts inside the bonus window fires on at most that share of steps
    (every agent of a game starts its episode together), so the last column bounds that kind of firing.

    :param run: a SAEIR run's folder (``progress.csv`` with ``rollout/intrinsic_fire_rate_<scale>``; ``spec.json``
        for the number of agents, since ``progress.csv`` counts agent-steps)
    :param window: env steps per row
    :return: the Markdown table's lines
    """
    import json

    from sb3_saeir.benchmark.reports import _scales, numeric_series

    rows = read_rows(run / "progress.csv")
    scales = _scales(rows, "rollout/intrinsic_fire_rate_") if rows else []
    if not scales:
        raise SystemExit(f"learning_speed: {run / 'progress.csv'} has no SAEIR bonus logs (rollout/intrinsic_fire_rate_*).")
    n_agents = int(json.loads((run / "spec.json").read_text())["config"]["env_kwargs"]["N"])
    entropy_scales = [s for s in scales if f"rollout/value_entropy_{s}" in rows[0]]
    header = [f"fire rate {s}" for s in scales] + [f"bonus mean {s}" for s in scales]
    header += [f"value entropy {s}" for s in entropy_scales]
    series = [numeric_series(rows, f"rollout/intrinsic_fire_rate_{s}") for s in scales]
    series += [numeric_series(rows, f"rollout/intrinsic_reward_mean_{s}") for s in scales]
    series += [numeric_series(rows, f"rollout/value_entropy_{s}") for s in entropy_scales]
    if "rollout/ep_len_mean" in rows[0]:
        header.append("episode starts per step")
        steps, lengths = numeric_series(rows, "rollout/ep_len_mean")
        series.append((steps, [1.0 / length for length in lengths]))
    # each series keeps only the rows that logged it (an episode length appears once an episode has ended), so each is
    # windowed by its own env steps
    env_steps = [np.array(steps) / n_agents for steps, _ in series]  # per series (n_logged,): agent-steps -> env steps
    lines = [f"| env steps | {' | '.join(header)} |", "|---" * (len(header) + 1) + "|"]
    for start in np.arange(0.0, env_steps[0].max(), window):
        if not ((env_steps[0] > start) & (env_steps[0] <= start + window)).any():
            continue
        cells = []
        for at, (_, values) in zip(env_steps, series):
            inside = (at > start) & (at <= start + window)
            cells.append(f"{np.mean(np.array(values)[inside]):.2e}" if inside.any() else "-")
        lines.append(f"| {_millions(start)}-{_millions(start + window)} | {' | '.join(cells)} |")
    return lines


def gather(paths: list[Path]) -> list[dict[str, Any]]:
    """The evaluation rows of every ``runs.csv``; a (method, task, seed) found in two files is refused."""
    rows: list[dict[str, Any]] = []
    owner: dict[tuple[str, str, int], Path] = {}
    for path in paths:
        found = read_rows(path)
        if not found:
            raise SystemExit(f"learning_speed: no rows in {path} (missing or empty).")
        for key in sorted({(r["algo"], r["task"], int(r["seed"])) for r in found}):
            if key in owner:
                raise SystemExit(f"learning_speed: {key} is in both {owner[key]} and {path}; give each run once.")
            owner[key] = path
        rows += found
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", type=Path, help="benchmark runs.csv files")
    parser.add_argument("--out", type=Path, required=True, help="folder for learning_speed.md and curves_seeds.png")
    parser.add_argument("--at", nargs="+", type=float, default=[500_000, 1_000_000, 2_000_000], help="env steps")
    parser.add_argument("--thresholds", nargs="+", type=float, default=[10.0, 20.0], help="in the metric's unit (%%)")
    parser.add_argument("--bonus", nargs="*", type=Path, default=[], help="SAEIR run folders: bonus per window")
    parser.add_argument("--window", type=float, default=250_000, help="env steps per row of the bonus tables")
    args = parser.parse_args(argv)
    curves = seed_curves(gather(args.runs))
    lines = [f"Runs: {', '.join(f'`{shown_path(p)}`' for p in args.runs)}", ""]
    for task in sorted({task for task, _ in curves}):
        by_algo = {algo: seeds for (t, algo), seeds in curves.items() if t == task}
        lines += task_section(task, by_algo, args.at, args.thresholds)
    for run in args.bonus:
        lines += [f"## SAEIR bonus over training: `{run.name}` ({run.parent.name})", ""]
        lines += [*bonus_windows(run, args.window), ""]
    text = "\n".join(lines)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "learning_speed.md").write_text(text)
    plot_seed_curves(curves, args.out / "curves_seeds.png")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
