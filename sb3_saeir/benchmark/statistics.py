"""Final scores and their statistics: the last evaluation of every run, the main metric per task, IQM with
stratified-bootstrap confidence intervals (rliable) and the exact two-sided Mann-Whitney U test between methods.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from sb3_saeir.envs import get_task_spec

# The table's column of each main metric (a task's ``TaskSpec.main_metric``): (key in runs.csv, header, scale).
METRIC_COLUMNS = {
    "coverage_rate": ("coverage_rate_mean", "Coverage %", 100.0),
    "success": ("success_mean", "Success %", 100.0),
    "r": ("ep_rew_mean", "Ep. reward", 1.0),
}
# The column every task's table has after its main metric: the episode return.
RETURN_COLUMN = METRIC_COLUMNS["r"]


def final_rows(rows: list[dict[str, Any]]) -> dict[tuple[str, str], list[dict[str, Any]]]:
    """The last evaluation of every (algo, task, seed), grouped by (algo, task)."""
    last: dict[tuple[str, str, int], dict[str, Any]] = {}
    for row in rows:
        key = (row["algo"], row["task"], row["seed"])
        if key not in last or row["timesteps"] >= last[key]["timesteps"]:
            last[key] = row
    grouped: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for (algo, task, _), row in sorted(last.items()):
        grouped.setdefault((algo, task), []).append(row)
    return grouped


def main_metric(task: str) -> tuple[str, str, float]:
    """``(key, title, scale)`` of the task's main metric, read from its registration (``TaskSpec.main_metric``,
    ``docs/guide/custom_env.md``); a metric without an entry in :data:`METRIC_COLUMNS` is shown as its mean, unscaled.

    :param task: a registered task id
    """
    metric = get_task_spec(task).main_metric
    return METRIC_COLUMNS.get(metric, (f"{metric}_mean", metric, 1.0))


def table_columns(task: str) -> list[tuple[str, str, float]]:
    """The task's columns of the paper's Table 1 layout: its main metric, then the episode return (once, when the
    main metric is the return).

    :param task: a registered task id
    """
    main = main_metric(task)
    return [main] if main == RETURN_COLUMN else [main, RETURN_COLUMN]


def final_scores(finals: dict[tuple[str, str], list[dict[str, Any]]]) -> dict[str, tuple[str, dict[str, list[float]]]]:
    """Per task: the main metric's title and, per method, its scaled final values, one per seed.

    :param finals: :func:`final_rows`
    :return: ``{task: (title, {algo: values})}``
    """
    scores: dict[str, tuple[str, dict[str, list[float]]]] = {}
    for task in sorted({task for _, task in finals}):
        key, title, scale = main_metric(task)
        scores[task] = (title, {algo: [scale * row[key] for row in runs] for (algo, t), runs in finals.items() if t == task})
    return scores


def rliable_markdown(rows: list[dict[str, Any]], reps: int = 2000, bootstrap_seed: int = 0) -> str:
    """IQM of the final main metric with 95% stratified-bootstrap confidence intervals (rliable).

    :param rows: the evaluation rows of ``runs.csv`` (:func:`collect`), finished runs only
    :param reps: bootstrap resamples per interval
    :param bootstrap_seed: seed of the resampling, so that reporting the same runs twice writes the same intervals
    :return: the Markdown table of ``aggregate.md``
    """
    lines = ["| Task | Method | IQM | 95% CI |", "|---|---|---|---|"]
    untrimmed: list[str] = []  # "<task> <algo> (n=<seeds>)" of the methods with fewer than 4 seeds
    with seeded_global_numpy(bootstrap_seed):  # one stream for all tasks, in the order of final_scores
        for task, (title, values) in final_scores(final_rows(rows)).items():
            scores = {algo: np.array(seeds)[:, None] for algo, seeds in values.items()}  # (n_seeds, 1 task) per method
            estimates, intervals = iqm_interval_estimates(scores, reps)
            lines += _aggregate_lines(task, title, scores, estimates, intervals)
            untrimmed += [
                f"{task} {algo} (n={len(seeds)})" for algo, seeds in sorted(values.items()) if iqm_trims_none(len(seeds))
            ]
    if untrimmed:
        lines += ["", _untrimmed_iqm_note(untrimmed)]
    return "\n".join(lines) + "\n"


@contextmanager
def seeded_global_numpy(seed: int) -> Iterator[None]:
    """Seed NumPy's global generator for the block and give the caller's state back afterwards.

    rliable's ``StratifiedBootstrap`` draws its resamples from that generator (it ignores ``random_state``), so this
    is what makes the intervals repeat: the same runs reported twice give the same intervals.

    :param seed: the seed of the block's draws
    """
    global_state = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(global_state)


def iqm_interval_estimates(scores: dict[str, np.ndarray], reps: int) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """IQM of each method's scores and its 95% stratified-bootstrap interval (rliable), drawn from NumPy's global
    generator: call it inside :func:`seeded_global_numpy`.

    :param scores: per method, its scores of shape ``(n_seeds, n_tasks)``
    :param reps: bootstrap resamples per interval
    :return: per method, the IQM (shape ``(1,)``), and per method the interval's ends (shape ``(2, 1)``: low, high)
    """
    from rliable import library as rly
    from rliable import metrics

    return rly.get_interval_estimates(scores, lambda x: np.array([metrics.aggregate_iqm(x)]), reps=reps)


def iqm_trims_none(n_seeds: int) -> bool:
    """Whether the IQM of ``n_seeds`` values trims none of them: it cuts a quarter of the values from each end, rounded
    down (rliable's ``aggregate_iqm``, SciPy's ``trim_mean`` at 0.25), so below 4 seeds it is the plain mean.

    :param n_seeds: how many values the IQM is taken over
    :return: ``True`` when nothing is trimmed
    """
    return int(0.25 * n_seeds) == 0


def _untrimmed_iqm_note(untrimmed: list[str]) -> str:
    """The line under the IQM table when some method has fewer than 4 seeds: the IQM trims a quarter of the seeds from
    each end, rounded down, so below 4 seeds it trims none and equals the mean.

    :param untrimmed: ``"<task> <algo> (n=<seeds>)"`` for each such method
    :return: the line, naming those methods
    """
    return (
        "With fewer than 4 seeds the IQM trims none of them (a quarter of the seeds, rounded down, from each end), so it "
        "equals the mean, and its interval is the bootstrap's over the seeds (one seed: its own value): "
        + ", ".join(untrimmed)
        + "."
    )


def mann_whitney_splits(first: list[float], second: list[float]) -> tuple[float, np.ndarray, np.ndarray]:
    """The Mann-Whitney U statistic of ``first`` against ``second`` (pairs where ``first`` is above, ties counting half)
    and its exact distribution over every split of the pooled values into two groups of these sizes, on mid-ranks (so
    ties, ``inf`` included, are handled).

    The splits are counted, not listed: the number of ways to pick ``len(first)`` of the pooled mid-ranks with each
    rank sum is built one value at a time (the doubled mid-ranks are integers), so 15 seeds against 15 (1.6e8 splits)
    cost a few thousand additions.

    :param first: one value per seed of the first method
    :param second: one value per seed of the second method
    :return: ``(U, statistics, counts)``: the observed U, and for each possible U of a split (``statistics``) the
        number of splits that give it (``counts``, summing to ``comb(n_first + n_second, n_first)``)
    """
    from scipy.stats import rankdata

    n_first = len(first)
    ranks = rankdata(np.concatenate([first, second]))  # (n_first + n_second,) mid-ranks of the pooled values
    offset = n_first * (n_first + 1) / 2
    statistic = float(ranks[:n_first].sum() - offset)
    doubled = np.rint(2 * ranks).astype(np.int64)  # mid-ranks are multiples of 1/2
    # counts[k, s]: subsets of k of the values seen so far whose doubled rank sum is s (float64: exact below 2**53)
    counts = np.zeros((n_first + 1, int(doubled.sum()) + 1))
    counts[0, 0] = 1.0
    for seen, rank in enumerate(doubled, start=1):
        for k in range(min(seen, n_first), 0, -1):  # descending: each value enters a subset at most once
            counts[k, rank:] += counts[k - 1, : counts.shape[1] - rank]
    split_statistics = np.arange(counts.shape[1]) / 2 - offset  # U of a split with doubled rank sum s
    return statistic, split_statistics, counts[n_first]


def mann_whitney(first: list[float], second: list[float]) -> tuple[float, float]:
    """The Mann-Whitney U statistic of ``first`` against ``second`` and its exact two-sided p-value: the share of all
    splits of the pooled values into two groups of these sizes whose U is at least as far from its mean as the
    observed one (:func:`mann_whitney_splits`).

    :param first: final values of the first method, one per seed
    :param second: final values of the second method, one per seed
    :return: ``(U, p)``
    """
    statistic, split_statistics, counts = mann_whitney_splits(first, second)
    mean = len(first) * len(second) / 2
    extreme = np.abs(split_statistics - mean) >= abs(statistic - mean) - 1e-9
    return statistic, float(counts[extreme].sum() / counts.sum())


def pairwise_markdown(rows: list[dict[str, Any]]) -> str:
    """Which differences between methods are larger than the seed spread: for every pair of methods on a task, the
    difference of the mean final main metric, the share of (seed, seed) pairs where the first method ends above the
    second (ties count half) and the two-sided Mann-Whitney U test's p-value (:func:`mann_whitney`).

    :param rows: the evaluation rows of ``runs.csv`` (:func:`collect`), finished runs only
    :return: the Markdown table appended to ``aggregate.md``
    """
    lines = [
        "| Task | Method A | Method B | mean A - mean B | A above B (seed pairs) | Mann-Whitney p (two-sided) |",
        "|---|---|---|---|---|---|",
    ]
    for task, (title, scores) in final_scores(final_rows(rows)).items():
        for first, second in itertools.combinations(sorted(scores), 2):
            a, b = scores[first], scores[second]
            statistic, p_value = mann_whitney(a, b)
            lines.append(
                f"| {task} | {first} (n={len(a)}) | {second} (n={len(b)}) | {np.mean(a) - np.mean(b):+.2f} {title} "
                f"| {statistic / (len(a) * len(b)):.0%} | {p_value:.3f} |"
            )
    return "\n".join(lines) + "\n"


def _aggregate_lines(
    task: str, title: str, scores: dict[str, np.ndarray], estimates: dict[str, np.ndarray], intervals: dict[str, np.ndarray]
) -> list[str]:
    """The rows of ``aggregate.md`` for one task: IQM and its interval per method."""
    lines = []
    for algo in sorted(scores):
        low, high = intervals[algo][:, 0]  # intervals[algo]: (2 bounds, 1 metric)
        lines.append(f"| {task} | {algo} | {estimates[algo][0]:.2f} {title} | [{low:.2f}, {high:.2f}] |")
    return lines
