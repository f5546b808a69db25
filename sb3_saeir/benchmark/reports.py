"""The benchmark's reports: ``runs.csv`` gathered from the run folders, ``table.md`` (the paper's Table 1 layout),
``curves.png``, ``aggregate.md`` (with :mod:`sb3_saeir.benchmark.statistics`) and the SAEIR bonus/entropy plot of
one run.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from sb3_saeir.benchmark.runs import run_folder
from sb3_saeir.benchmark.statistics import final_rows, main_metric, pairwise_markdown, rliable_markdown, table_columns
from sb3_saeir.common.atomic import atomic_write_text
from sb3_saeir.run.files import DONE_FILE, EVALUATIONS_FILE, PROGRESS_FILE, SPEC_FILE
from sb3_saeir.run.record import RunSpec, read_rows, spec_record, stored_spec_differences, write_rows


def collect(out: Path, specs: list[RunSpec]) -> list[dict[str, Any]]:
    """Every evaluation row of the runs of ``specs`` whose ``spec.json`` matches, written to ``runs.csv`` (removed
    when there is none, so that it never shows runs of other settings).

    :param out: the benchmark folder
    :param specs: the command's runs
    """
    rows = []
    for spec in specs:
        folder = run_folder(out, spec)
        if (folder / SPEC_FILE).is_file() and not stored_spec_differences(folder, spec_record(spec)):
            rows.extend(read_rows(folder / EVALUATIONS_FILE))
    if rows:
        write_rows(out / "runs.csv", rows)
    else:
        (out / "runs.csv").unlink(missing_ok=True)
    return rows


def table_markdown(rows: list[dict[str, Any]]) -> str:
    """The paper's Table 1 layout: methods as rows, (task, metric) as columns, mean ± std over seeds, best in bold."""
    finals = final_rows(rows)
    algos = sorted({algo for algo, _ in finals}, key=lambda a: (a == "saeir_ppo", a))
    tasks = sorted({task for _, task in finals})
    columns = [(task, *column) for task in tasks for column in table_columns(task)]
    stats: dict[tuple[str, int], tuple[float, float, int]] = {}
    for algo in algos:
        for c, (task, key, _, scale) in enumerate(columns):
            values = [scale * row[key] for row in finals.get((algo, task), []) if key in row]
            if values:
                stats[(algo, c)] = (float(np.mean(values)), float(np.std(values)), len(values))
    header = "| Method | " + " | ".join(f"{task} {title}" for task, _, title, _ in columns) + " |"
    lines = [header, "|---" * (len(columns) + 1) + "|"]
    for algo in algos:
        cells = []
        for c in range(len(columns)):
            if (algo, c) not in stats:
                cells.append("-")
                continue
            mean, std, n = stats[(algo, c)]
            best = max(stats[(other, c)][0] for other in algos if (other, c) in stats)
            cell = f"{mean:.2f} ± {std:.2f} (n={n})"
            cells.append(f"**{cell}**" if mean == best and len(algos) > 1 else cell)
        lines.append(f"| {algo} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def format_steps(value: float, _position: Any = None) -> str:
    """Label for a step count, to four significant digits: ``0``, ``250k``, ``1.5M``, ``7M`` for 7,000,064."""
    if abs(value) >= 1e6:
        return f"{value / 1e6:.4g}M"
    if abs(value) >= 1e3:
        return f"{value / 1e3:.4g}k"
    return f"{value:.4g}"


def label_task_panel(axis: Any, task: str, title: str) -> None:
    """Title, env-step x axis, the metric's y label and the legend of one task's panel of learning curves."""
    import matplotlib

    axis.set_title(task)
    axis.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(format_steps))
    axis.set_xlabel("env steps")
    axis.set_ylabel(title)
    axis.legend(fontsize=8)


def save_figure(figure: Any, path: Path) -> None:
    """Lay out, write (120 dpi) and close a figure."""
    import matplotlib.pyplot as plt

    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def plot_curves(rows: list[dict[str, Any]], path: Path) -> None:
    """One panel per task: mean of the main metric over seeds per method, with a ±1 std band; x in env steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tasks = sorted({row["task"] for row in rows})
    figure, axes = plt.subplots(1, len(tasks), figsize=(5 * len(tasks), 3.6), squeeze=False)
    for axis, task in zip(axes[0], tasks):
        key, title, scale = main_metric(task)
        for algo in sorted({row["algo"] for row in rows if row["task"] == task}):
            by_step: dict[int, list[float]] = {}
            for row in rows:
                if row["task"] == task and row["algo"] == algo and key in row:
                    by_step.setdefault(int(row["env_steps"]), []).append(scale * float(row[key]))
            steps = np.array(sorted(by_step))
            mean = np.array([np.mean(by_step[s]) for s in steps])
            std = np.array([np.std(by_step[s]) for s in steps])
            axis.plot(steps, mean, label=algo)
            # rates cannot be negative: the band stops at 0
            axis.fill_between(steps, np.clip(mean - std, 0.0, None), mean + std, alpha=0.2)
        label_task_panel(axis, task, title)
    save_figure(figure, path)


def numeric_series(rows: list[dict[str, Any]], key: str) -> tuple[list[float], list[float]]:
    """(agent-steps, values) of ``key`` over the rows of a ``progress.csv`` that hold a number for it.

    SB3's CSV logger leaves a key empty in rows dumped without it (for example the evaluation rows), so each series
    keeps only its own rows.
    """
    steps, values = [], []
    for row in rows:
        value, step = row.get(key), row.get("time/total_timesteps")
        if isinstance(value, (int, float)) and isinstance(step, (int, float)):
            steps.append(float(step))
            values.append(float(value))
    return steps, values


def _scales(rows: list[dict[str, Any]], prefix: str) -> list[str]:
    """The scale names ``<scale>`` of the per-scale keys ``<prefix><scale>`` of a run's ``progress.csv``, sorted."""
    return sorted(key[len(prefix) :] for key in rows[0] if key.startswith(prefix))


def system_entropy_summary(rows: list[dict[str, Any]], last_fraction: float = 0.1) -> dict[str, dict[str, float]]:
    """Per scale: the SAEIR bonus fire rate (fraction of steps where the bonus fired) averaged over all rollouts and over
    the last ``last_fraction`` of them, and the value-softmax entropy of the first and the last rollout.

    :param rows: a SAEIR run's ``progress.csv`` rows (:func:`read_rows`)
    :param last_fraction: share of the rollouts, at the end of training, of the late fire rate
    :return: ``{scale: {"fire_rate": ..., "fire_rate_late": ..., "entropy_first": ..., "entropy_last": ...}}``
    """
    if not rows or "rollout/intrinsic_reward_mean" not in rows[0]:
        raise ValueError("the run's progress.csv has no SAEIR logs (rollout/intrinsic_reward_mean).")
    summary: dict[str, dict[str, float]] = {}
    for scale in _scales(rows, "rollout/intrinsic_fire_rate_"):
        _, fire = numeric_series(rows, f"rollout/intrinsic_fire_rate_{scale}")
        _, entropy = numeric_series(rows, f"rollout/value_entropy_{scale}")
        if not fire or not entropy:
            continue
        late = fire[-max(1, round(len(fire) * last_fraction)) :]
        summary[scale] = {
            "fire_rate": float(np.mean(fire)),
            "fire_rate_late": float(np.mean(late)),
            "entropy_first": entropy[0],
            "entropy_last": entropy[-1],
        }
    return summary


def plot_system_entropy(run: Path, path: Path) -> dict[str, dict[str, float]]:
    """SAEIR bonus, its fire rate and the value-softmax entropy per scale over training, from a run's ``progress.csv``.

    :param run: the run's folder
    :param path: the figure's file
    :return: :func:`system_entropy_summary` of the run
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = read_rows(run / PROGRESS_FILE)
    try:
        summary = system_entropy_summary(rows)
    except ValueError as error:
        raise ValueError(f"{run / 'progress.csv'}: {error}") from error
    figure, (top, middle, bottom) = plt.subplots(3, 1, figsize=(6, 7), sharex=True)
    scales = _scales(rows, "rollout/value_entropy_")
    colors = {scale: f"C{i}" for i, scale in enumerate(scales)}  # one colour per scale in every panel
    top.plot(*numeric_series(rows, "rollout/intrinsic_reward_mean"), label="all scales", color="black", alpha=0.6)
    for scale in scales:
        top.plot(*numeric_series(rows, f"rollout/intrinsic_reward_mean_{scale}"), label=scale, color=colors[scale])
    top.set_ylabel("SAEIR bonus (unscaled)")
    top.legend(fontsize=8)
    for scale in scales:
        middle.plot(*numeric_series(rows, f"rollout/intrinsic_fire_rate_{scale}"), label=scale, color=colors[scale])
    middle.set_ylabel("bonus fire rate")
    middle.legend(fontsize=8)
    for scale in scales:
        bottom.plot(*numeric_series(rows, f"rollout/value_entropy_{scale}"), label=scale, color=colors[scale])
    bottom.set_ylabel("value-softmax entropy")
    bottom.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(format_steps))
    bottom.set_xlabel("agent-steps")
    bottom.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return summary


def report(out: Path, specs: list[RunSpec], use_rliable: bool = False) -> list[dict[str, Any]]:
    """Write ``runs.csv``, ``table.md``, ``curves.png`` (and ``aggregate.md``) from the folders of the command's runs
    whose ``spec.json`` matches (a table or figure of other runs is removed, never left next to this ``runs.csv``).

    :param out: the benchmark folder
    :param specs: the command's runs
    :param use_rliable: also write ``aggregate.md``
    """
    rows = collect(out, specs)
    if not rows:
        for name in ("table.md", "curves.png"):
            (out / name).unlink(missing_ok=True)
        print("no evaluation rows yet")
        return rows
    unfinished = unfinished_runs(out, specs, rows)
    final = [row for row in rows if (row["algo"], row["task"], int(row["seed"])) not in unfinished]
    note = ""
    if unfinished:  # their last evaluation is not at the budget: curves only, never a final value
        listed = ", ".join(f"{algo}/{task}_s{seed} at {steps:,}" for (algo, task, seed), steps in unfinished.items())
        note = f"\nNot finished, left out of this table (curves only): {listed} agent-steps.\n"
        print(f"table.md and aggregate.md count finished runs only; not finished: {listed} agent-steps")
    if final:
        atomic_write_text(out / "table.md", table_markdown(final) + note)
        if use_rliable:
            atomic_write_text(out / "aggregate.md", rliable_markdown(final) + "\n" + pairwise_markdown(final) + note)
    else:
        for name in ("table.md", "aggregate.md"):
            (out / name).unlink(missing_ok=True)
    plot_curves(rows, out / "curves.png")
    others = other_run_folders(out, specs)
    if others:  # a later command with other methods or seeds must not read as a report of the whole folder
        print(
            f"runs.csv, table.md and curves.png hold only this command's runs ({len(specs)}); also in {out / 'runs'}: "
            f"{', '.join(others)} (to report them together, give --report-only all their methods, tasks and seeds)"
        )
    return rows


def other_run_folders(out: Path, specs: list[RunSpec]) -> list[str]:
    """The run folders under ``out/runs`` that are not runs of ``specs`` (``algo/task_sSEED``, sorted); folders moved
    aside by ``--rerun-changed`` (``<task>_s<seed>.replaced-<UTC time>``) are not runs any command reports.

    :param out: the benchmark folder
    :param specs: the command's runs
    """
    own = {run_folder(out, spec) for spec in specs}
    # a run folder is runs/<algo>/<task>_s<seed>, with its spec.json
    folders = sorted(spec_file.parent for spec_file in (out / "runs").glob(f"*/*/{SPEC_FILE}"))
    return [
        f"{folder.parent.name}/{folder.name}"
        for folder in folders
        if folder not in own and re.fullmatch(r".+_s-?\d+", folder.name)
    ]


def unfinished_runs(out: Path, specs: list[RunSpec], rows: list[dict[str, Any]]) -> dict[tuple[str, str, int], int]:
    """The runs of ``specs`` with evaluation rows that have not finished the command's budget (running, stopped or
    failed: no ``done.json``; or finished at a smaller budget, their last evaluation before ``-n``), with the
    agent-steps of their last evaluation.

    :param out: the benchmark folder
    :param specs: the command's runs
    :param rows: their evaluation rows (:func:`collect`)
    """
    reached: dict[tuple[str, str, int], int] = {}
    for row in rows:
        key = (row["algo"], row["task"], int(row["seed"]))
        reached[key] = max(reached.get(key, 0), int(row["timesteps"]))
    unfinished = {}
    for spec in specs:
        key = (spec.algo, spec.task, spec.seed)
        if key in reached and (not (run_folder(out, spec) / DONE_FILE).is_file() or reached[key] < spec.n_timesteps):
            unfinished[key] = reached[key]
    return unfinished
