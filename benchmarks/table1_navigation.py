"""Table 1 on navigation (``docs/results/table1-navigation.md``): ``MAPPO`` and ``SAEIR_PPO`` at the paper's budget on
the navigation reading without the collision penalty, N=3 (seeds 1-3) and N=4 (seed 1), beside the paper's Table 1,
from the committed run files alone.

    python benchmarks/table1_navigation.py                      # docs/results/table1-navigation/: tables, figures
    python benchmarks/table1_navigation.py --results DIR        # the run files under DIR, the outputs in DIR/table1-navigation

The runs are :data:`RUNS`, each a folder of committed run files under ``docs/results/`` (``spec.json``,
``evaluations.csv``, ``done.json``; for a finished ``SAEIR_PPO`` run also the windowed bonus table ``bonus_by_*.md`` of
``benchmarks/copy_run_files.py --bonus-window``). N=3 seed 1 of both methods are the runs of
``docs/results/navigation-calibrated.md``, which ran as task ``cn-sparse-n3`` with ``env_kwargs: {collision_penalty:
0.0}``; each run's ``spec.json`` is checked against the reading and the protocol (:func:`protocol_differences`).

A run is *final* when its folder has ``done.json``, its ``spec.json`` matches the protocol and its last evaluation is at
the budget (the paper's 20M env steps, :data:`results_pages.PAPER_ENV_STEPS`); any other run is shown by its state
(``running, at 7M env steps``, ``no run files yet``, ...), never as a final. Writes into ``DIR/table1-navigation/``:

- ``runs.md``: every planned run, the task id it ran under, its game keywords and protocol, and its state;
- ``finals.md``: per task and method, Table 1 and ours (mean ± std over the final seeds, each seed's final, the IQM);
- ``differences.md``: per task and seed, ``SAEIR_PPO`` minus ``MAPPO`` with its 95% interval and the verdict, then the
  verdicts counted per task;
- ``reward.md``: Table 1's episode reward beside ours in the authors' unit, with the ratio of ``docs/tasks.md``;
- ``fire_rate.md``: per ``SAEIR_PPO`` run and scale, the bonus's fire rate over training (its bonus table);
- ``runs.csv`` and ``table.md``: the final runs' evaluations under their reading's task id and the benchmark's final
  table of them (:func:`write_final_runs`; neither file before a run is final), which ``docs/results.md``'s rows read;
- ``curves.png`` (every run's coverage curve, Table 1 dashed with its std shaded) and ``fire_rate.png``.

Definitions (the page states them): a run's final is its coverage % at the evaluation at the budget (200 greedy
episodes); mean ± std is over the final seeds with NumPy's (population) std; the IQM and its 95% interval are
rliable's stratified bootstrap over the final seeds (2,000 resamples, seed 0), from 3 seeds on, as ``docs/results.md``.
The difference of a seed is ``SAEIR_PPO``'s final minus ``MAPPO``'s, its 95% interval the normal one from the two
evaluations' episodes (:func:`difference`), and its verdict :func:`verdict`: ahead when the interval lies above 0,
behind when below, level when it holds 0. The episode reward is ``ep_rew_mean``: every agent gets the team's reward, so
it is one agent's reward summed over the episode, the authors' unit; the ratio is reward / (N x coverage).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path
from statistics import NormalDist
from typing import Any, NamedTuple

import numpy as np

from sb3_saeir.benchmark import read_rows, table_markdown, write_rows
from sb3_saeir.common.atomic import atomic_write_text
from sb3_saeir.envs import get_task_spec

sys.path.insert(0, str(Path(__file__).parent))
from evaluation_curves import metric_curve
from learning_speed import iqm_interval
from results_pages import (
    DOCS,
    NAMES,
    NBSP,
    NONE,
    PAPER,
    PAPER_ENV_STEPS,
    PAPER_REWARD,
    Figures,
    millions,
    number_cells,
    tables_of,
)

STUDY = "table1-navigation"
ALGOS = ("mappo", "saeir_ppo")
TASKS = {3: "cn-sparse-no-penalty-n3", 4: "cn-sparse-no-penalty-n4"}
# The protocol fixed before the runs (docs/results/table1-navigation/queue.sh): games, greedy episodes per evaluation
# and env steps between evaluations; the budget is the paper's (PAPER_ENV_STEPS).
GAMES, EVAL_EPISODES, EVAL_EVERY = 128, 200, 1_000_000
Z95 = NormalDist().inv_cdf(0.975)  # the normal 97.5% quantile: a two-sided 95% interval
COLORS = {"mappo": "C0", "saeir_ppo": "C3"}
SCALE_COLORS = {"team": "C0", "group": "C1", "individual": "C2"}
SEED_STYLES = ("-", ":", "-.", (0, (1, 3)))  # per seed; Table 1 is dashed


class PlannedRun(NamedTuple):
    """A run of the study: the task it is read as, its method and seed, and its folder under ``docs/results/``."""

    task: str
    algo: str
    seed: int
    folder: str


def study_folder(task: str, algo: str, seed: int) -> str:
    """The folder of a run this study made (``report.sh`` copies it there), under ``docs/results/``."""
    return f"{STUDY}/runs/{algo}/{task}_s{seed}"


RUNS = (
    PlannedRun(TASKS[3], "mappo", 1, "navigation-calibrated/runs/mappo-no-penalty/cn-sparse-n3_s1"),
    PlannedRun(TASKS[3], "saeir_ppo", 1, "navigation-calibrated/runs/saeir_ppo-no-penalty/cn-sparse-n3_s1"),
    *(PlannedRun(TASKS[3], algo, seed, study_folder(TASKS[3], algo, seed)) for seed in (2, 3) for algo in ALGOS),
    *(PlannedRun(TASKS[4], algo, 1, study_folder(TASKS[4], algo, 1)) for algo in ALGOS),
)


class RunState(NamedTuple):
    """What the committed files of a planned run say.

    :param run: the planned run
    :param rows: its evaluations, sorted by env steps (empty: none yet)
    :param spec: its ``spec.json`` (``None``: no run files yet)
    :param done: whether its folder has ``done.json``
    :param differences: how its ``spec.json`` differs from the reading and the protocol (empty: it does not)
    """

    run: PlannedRun
    rows: list[dict[str, Any]]
    spec: dict[str, Any] | None
    done: bool
    differences: list[str]

    @property
    def budget(self) -> float:
        return PAPER_ENV_STEPS[self.run.task]

    @property
    def final(self) -> dict[str, Any] | None:
        """The evaluation at the budget of a finished run that follows the protocol (``None`` for any other run)."""
        if not self.done or self.differences or not self.rows or float(self.rows[-1]["env_steps"]) < self.budget:
            return None
        return self.rows[-1]

    def state(self) -> str:
        """``final at 20M env steps``, ``running, at 7M env steps``, ``no run files yet``, ..."""
        last = f"{millions(float(self.rows[-1]['env_steps']))} env steps" if self.rows else None
        if self.spec is None:
            return "no run files yet"
        if self.differences:
            return f"differs from the protocol: {'; '.join(self.differences)}"
        if self.final is not None:
            return f"final at {millions(self.budget)} env steps"
        if self.done:
            return f"stopped before the budget, at {last or 'no evaluation'}"
        return f"running, at {last}" if last else "running, no evaluation yet"


def game_keywords(spec: dict[str, Any]) -> dict[str, Any]:
    """The keywords a run's games were built with: ``game_kwargs`` where the spec records it, else the task's registered
    keywords updated by the config's ``env_kwargs`` (runs made before ``game_kwargs`` was recorded)."""
    if "game_kwargs" in spec:
        return dict(spec["game_kwargs"])
    return {**get_task_spec(spec["task"]).kwargs, **spec.get("config", {}).get("env_kwargs", {})}


def protocol_differences(spec: dict[str, Any], run: PlannedRun) -> list[str]:
    """How a run's ``spec.json`` differs from the reading (the task's game keywords) and the protocol (method, seed,
    games, evaluation episodes and spacing, budget); empty when it does not.

    :param spec: the run's ``spec.json``
    :param run: the planned run it should be
    """
    expected_games = get_task_spec(run.task).kwargs
    n_agents = int(expected_games["N"])
    checks = {
        "method": (spec.get("algo"), run.algo),
        "seed": (spec.get("seed"), run.seed),
        "game keywords": (game_keywords(spec), expected_games),
        "games": (spec.get("n_games"), GAMES),
        "evaluation episodes": (spec.get("eval_episodes"), EVAL_EPISODES),
        "env steps between evaluations": (float(spec.get("eval_freq", math.nan)) / n_agents, EVAL_EVERY),
        "budget in env steps": (float(spec.get("n_timesteps", math.nan)) / n_agents, PAPER_ENV_STEPS[run.task]),
    }
    return [f"{name} {found} (expected {wanted})" for name, (found, wanted) in checks.items() if found != wanted]


def read_run_files(folder: Path) -> tuple[dict[str, Any], list[dict[str, Any]]] | None:
    """A run folder's committed ``spec.json`` and its evaluations sorted by env steps (none yet: ``[]``); ``None``
    when the folder has no ``spec.json`` (no run files yet)."""
    if not (folder / "spec.json").is_file():
        return None
    spec = json.loads((folder / "spec.json").read_text())
    return spec, sorted(read_rows(folder / "evaluations.csv"), key=lambda row: float(row["env_steps"]))


def read_run(run: PlannedRun, results: Path) -> RunState:
    """The state of a planned run from its committed files under ``results`` (a missing folder: no run files yet)."""
    folder = results / run.folder
    files = read_run_files(folder)
    if files is None:
        return RunState(run, [], None, False, [])
    spec, rows = files
    return RunState(run, rows, spec, (folder / "done.json").is_file(), protocol_differences(spec, run))


def coverage(row: dict[str, Any]) -> float:
    """An evaluation's final-step coverage, in percent."""
    return 100.0 * float(row["coverage_rate_mean"])


def standard_error(row: dict[str, Any]) -> float:
    """The standard error of an evaluation's coverage %, from its episodes: ``evaluations.csv`` records NumPy's
    (population) std over ``n_episodes``, so the unbiased one is ``std / sqrt(n - 1)``."""
    return 100.0 * float(row["coverage_rate_std"]) / math.sqrt(float(row["n_episodes"]) - 1.0)


def difference(mappo: dict[str, Any], saeir: dict[str, Any]) -> tuple[float, float, float]:
    """``SAEIR_PPO``'s final coverage % minus ``MAPPO``'s for one seed and its 95% interval: the two evaluations are
    independent sets of episodes, so the difference's standard error is the root of the sum of their squares.

    :param mappo: ``MAPPO``'s evaluation at the budget
    :param saeir: ``SAEIR_PPO``'s evaluation at the budget
    :return: ``(difference, low, high)`` in percentage points
    """
    value = coverage(saeir) - coverage(mappo)
    half = Z95 * math.hypot(standard_error(saeir), standard_error(mappo))
    return value, value - half, value + half


def verdict(low: float, high: float) -> str:
    """``ahead`` when the interval of ``SAEIR_PPO`` minus ``MAPPO`` lies above 0, ``behind`` when below, else ``level``."""
    if low > 0:
        return "ahead"
    if high < 0:
        return "behind"
    return "level"


def paper_numbers(text: str) -> tuple[float, float]:
    """``(mean, std)`` of a Table 1 cell ``"64.43 ± 1.56"``."""
    mean, std = text.split(" ± ")
    return float(mean), float(std)


def paper_cell(column: dict[tuple[str, str], str], task: str, algo: str) -> str:
    """A Table 1 cell (``"64.43 ± 1.56"``) as the tables show it, its ``±`` kept with the numbers."""
    return column[(task, algo)].replace(" ± ", f"{NBSP}±{NBSP}")


def reward_ratio(reward: float, coverage_percent: float, n_agents: int) -> float:
    """The ratio of ``docs/tasks.md``: episode reward (one agent's, summed over the episode) / (N x coverage)."""
    return reward / (n_agents * coverage_percent / 100.0)


def n_agents(task: str) -> int:
    return int(get_task_spec(task).kwargs["N"])


def label(task: str) -> str:
    """``N=3`` for the N=3 task."""
    return f"N={n_agents(task)}"


def seeds_of(task: str) -> list[int]:
    return sorted({run.seed for run in RUNS if run.task == task})


def by_key(states: list[RunState]) -> dict[tuple[str, str, int], RunState]:
    return {(s.run.task, s.run.algo, s.run.seed): s for s in states}


def table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table's lines."""
    return ["| " + " | ".join(header) + " |", "|---" * len(header) + "|", *("| " + " | ".join(r) + " |" for r in rows)]


def runs_table(states: list[RunState]) -> list[str]:
    """``runs.md``: every planned run, the task id it ran under, its games and protocol from ``spec.json``, its state."""
    rows = []
    for s in states:
        cells = [label(s.run.task), NAMES[s.run.algo], str(s.run.seed), f"`{s.run.folder}`"]
        if s.spec is None:
            cells += [NONE] * 4
        else:
            games = ", ".join(f"{key}={value}" for key, value in sorted(game_keywords(s.spec).items()))
            every = float(s.spec["eval_freq"]) / n_agents(s.run.task)
            protocol = f"{s.spec['n_games']} games, {s.spec['eval_episodes']} episodes every {millions(every)} env steps"
            budget = millions(float(s.spec["n_timesteps"]) / n_agents(s.run.task))
            cells += [f"`{s.spec['task']}`", games, protocol, budget]
        rows.append([*cells, s.state()])
    header = ["task", "method", "seed", "run files (under docs/results/)", "ran as", "game keywords", "protocol"]
    return table([*header, "budget (env steps)", "state"], rows)


def finals_table(states: list[RunState]) -> list[str]:
    """``finals.md``: per task and method, Table 1 and ours over the final seeds; the other seeds by their state."""
    rows = []
    for task in TASKS.values():
        for algo in ALGOS:
            chosen = [s for s in states if s.run.task == task and s.run.algo == algo]
            finals = [(s.run.seed, coverage(s.final)) for s in chosen if s.final is not None]
            values = [value for _, value in finals]
            pending = "; ".join(f"s{s.run.seed} {s.state()}" for s in chosen if s.final is None) or NONE
            mean_std, iqm = NONE, NONE
            if values:
                interval = iqm_interval(values) if len(values) >= 3 else None
                figures = Figures(task, algo, PAPER_ENV_STEPS[task], values, interval, "", PAPER[(task, algo)])
                mean_std, iqm = number_cells(figures, 2)
            per_seed = ", ".join(f"s{seed} {value:.2f}" for seed, value in finals) or NONE
            paper = paper_cell(PAPER, task, algo)
            rows.append([label(task), NAMES[algo], paper, str(len(values)), per_seed, mean_std, iqm, pending])
    header = ["task", "method", "Table 1 (5 seeds)", "final seeds", "final % per seed", "final %, mean ± std"]
    return table([*header, "IQM [95% CI]", "not final yet"], rows)


def differences_tables(states: list[RunState]) -> list[str]:
    """``differences.md``: per task and seed ``SAEIR_PPO`` minus ``MAPPO`` with its interval and verdict (a seed with a
    run not final: its state, no verdict), then per task the verdicts counted and the mean difference."""
    found = by_key(states)
    rows, counts = [], []
    for task in TASKS.values():
        verdicts: list[str] = []
        values: list[float] = []
        for seed in seeds_of(task):
            pair = [found[(task, algo, seed)] for algo in ALGOS]
            cells = [f"{coverage(s.final):.2f}" if s.final is not None else s.state() for s in pair]
            if pair[0].final is None or pair[1].final is None:
                rows.append([label(task), str(seed), *cells, NONE, NONE, "waits for both finals"])
                continue
            value, low, high = difference(pair[0].final, pair[1].final)
            verdicts.append(verdict(low, high))
            values.append(value)
            rows.append([label(task), str(seed), *cells, f"{value:+.2f}", f"[{low:+.2f},{NBSP}{high:+.2f}]", verdicts[-1]])
        tally = [str(verdicts.count(word)) for word in ("ahead", "level", "behind")]
        mean = f"{np.mean(values):+.2f}" if values else NONE
        counts.append([label(task), f"{len(values)} of {len(seeds_of(task))}", *tally, mean])
    header = ["task", "seed", "MAPPO final %", "SAEIR_PPO final %", "SAEIR_PPO - MAPPO", "95% interval", "verdict"]
    summary = ["task", "seeds compared", "ahead", "level", "behind", "mean difference"]
    return [*table(header, rows), "", *table(summary, counts)]


def our_reward_cells(finals: list[dict[str, Any]], paper_reward: float, n: int) -> list[str]:
    """Ours for :func:`reward_table`: final seeds, mean coverage %, episode reward (mean ± std over the seeds), the
    ratio of the means, and our reward over Table 1's (``-`` without a final seed)."""
    if not finals:
        return ["0", *[NONE] * 4]
    covered = float(np.mean([coverage(row) for row in finals]))
    rewards = [float(row["ep_rew_mean"]) for row in finals]
    reward = float(np.mean(rewards))
    spread = f"{NBSP}±{NBSP}{np.std(rewards):.2f}" if len(rewards) > 1 else ""
    ratio = reward_ratio(reward, covered, n)
    return [str(len(finals)), f"{covered:.2f}", f"{reward:.2f}{spread}", f"{ratio:.2f}", f"{reward / paper_reward:.1f}"]


def reward_table(states: list[RunState]) -> list[str]:
    """``reward.md``: per task and method, Table 1's coverage and episode reward and their ratio, beside ours (mean over
    the final seeds; the reward in the authors' unit, ``ep_rew_mean``) and ours over Table 1's reward."""
    rows = []
    for task in TASKS.values():
        n = n_agents(task)
        for algo in ALGOS:
            finals = [s.final for s in states if s.run.task == task and s.run.algo == algo and s.final is not None]
            paper_coverage, _ = paper_numbers(PAPER[(task, algo)])
            paper_reward, _ = paper_numbers(PAPER_REWARD[(task, algo)])
            paper = [f"{paper_coverage:.2f}", paper_cell(PAPER_REWARD, task, algo)]
            paper.append(f"{reward_ratio(paper_reward, paper_coverage, n):.2f}")
            rows.append([label(task), NAMES[algo], *paper, *our_reward_cells(finals, paper_reward, n)])
    header = ["task", "method", "Table 1 coverage %", "Table 1 episode reward", "Table 1 reward / (N x coverage)"]
    ours = ["final seeds", "ours: coverage %", "ours: episode reward", "ours: reward / (N x coverage)"]
    return table([*header, *ours, "ours / Table 1 (episode reward)"], rows)


class BonusTable(NamedTuple):
    """A run's windowed bonus table: each window's first and last env steps and, per scale, its fire rate."""

    name: str
    starts: np.ndarray
    ends: np.ndarray
    fire_rates: dict[str, np.ndarray]


WINDOW = re.compile(r"^(?P<start>[\d.]+)M-(?P<end>[\d.]+)M$")


def read_bonus_table(path: Path) -> BonusTable:
    """Parse a ``bonus_by_*.md`` (``benchmarks/bonus_files.py``): its ``env steps`` column (``0M-1M``) and its
    ``fire rate <scale>`` columns (``-``: a window without that scale's logs, read as NaN)."""
    lines = next((t for t in tables_of(path.read_text()) if "env steps" in t[0]), None)
    if lines is None:
        raise SystemExit(f"table1_navigation: {path} has no table with an 'env steps' column.")
    cells = [[cell.strip() for cell in line.strip().strip("|").split("|")] for line in lines]
    header, body = cells[0], cells[2:]
    windows = [WINDOW.match(row[header.index("env steps")]) for row in body]
    if any(window is None for window in windows):
        raise SystemExit(f"table1_navigation: {path} has an env steps cell that is not '<start>M-<end>M'.")
    starts = np.array([1e6 * float(w["start"]) for w in windows if w])  # (n_windows,)
    ends = np.array([1e6 * float(w["end"]) for w in windows if w])  # (n_windows,)
    rates = {
        name.removeprefix("fire rate "): np.array([math.nan if row[i] == NONE else float(row[i]) for row in body])
        for i, name in enumerate(header)
        if name.startswith("fire rate ")
    }
    return BonusTable(path.name, starts, ends, rates)


def bonus_tables(states: list[RunState], results: Path) -> dict[tuple[str, int], BonusTable]:
    """The bonus table of every ``SAEIR_PPO`` run whose folder has one (``bonus_by_*.md``), by (task, seed)."""
    found = {}
    for s in states:
        paths = sorted((results / s.run.folder).glob("bonus_by_*.md")) if s.run.algo == "saeir_ppo" else []
        if paths:
            found[(s.run.task, s.run.seed)] = read_bonus_table(paths[0])
    return found


def fire_rate_cells(found: BonusTable, rates: np.ndarray) -> list[str]:
    """One scale's cells of :func:`fire_rate_table`: the first window's rate, the highest later one and its window
    (``0 (none fired)`` when no later window fired), the mean over the windows, the windows that fired.

    :param found: the run's bonus table
    :param rates: the scale's fire rate per window, shape ``(n_windows,)``
    """
    later = rates[1:]
    highest = NONE
    if len(later) and np.nanmax(later, initial=0.0) > 0:
        peak = int(np.nanargmax(later)) + 1
        highest = f"{rates[peak]:.2e} ({millions(found.starts[peak])}-{millions(found.ends[peak])})"
    elif len(later):
        highest = "0 (none fired)"
    return [f"{rates[0]:.2e}", highest, f"{np.nanmean(rates):.2e}", f"{int(np.sum(rates > 0))} of {len(rates)}"]


def fire_rate_table(states: list[RunState], bonus: dict[tuple[str, int], BonusTable]) -> list[str]:
    """``fire_rate.md``: per ``SAEIR_PPO`` run and scale, the fire rate in the first window, the highest over the later
    windows (with where), the mean over all windows and the windows with any firing; a run without a table: its state."""
    rows = []
    for s in states:
        if s.run.algo != "saeir_ppo":
            continue
        head = [label(s.run.task), str(s.run.seed), s.state()]
        found = bonus.get((s.run.task, s.run.seed))
        if found is None:
            rows.append([*head, "no bonus table yet (report.sh copies it when the run is finished)", *[NONE] * 5])
            continue
        width = millions(float(found.ends[0] - found.starts[0]))
        for scale, rates in sorted(found.fire_rates.items(), key=lambda item: scale_order(item[0])):
            rows.append([*head, f"`{found.name}` ({width} windows)", scale, *fire_rate_cells(found, rates)])
    header = ["task", "seed", "state", "bonus table", "scale", "first window", "highest later window", "mean"]
    return table([*header, "windows fired"], rows)


def curve_label(s: RunState) -> str:
    """``MAPPO s1``, ``SAEIR_PPO s1 (running)``, or ``(not final)`` for a finished run that is not a final."""
    if s.final is not None:
        return f"{NAMES[s.run.algo]} s{s.run.seed}"
    return f"{NAMES[s.run.algo]} s{s.run.seed} ({'not final' if s.done else 'running'})"


def plot_curves(states: list[RunState], path: Path) -> None:
    """One panel per task: every run's coverage curve (a run not final marked ``running``), Table 1's value per method
    dashed with its std shaded, up to the budget."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sb3_saeir.benchmark.reports import format_steps, save_figure

    figure, axes = plt.subplots(1, len(TASKS), figsize=(6.5 * len(TASKS), 4.4), squeeze=False)
    for axis, task in zip(axes[0], TASKS.values()):
        for s in (s for s in states if s.run.task == task and s.rows):
            steps, values = metric_curve(s.rows, "coverage_rate")
            style = SEED_STYLES[(s.run.seed - 1) % len(SEED_STYLES)]
            axis.plot(
                steps, values, color=COLORS[s.run.algo], linestyle=style, marker=".", linewidth=1.2, label=curve_label(s)
            )
        for algo in ALGOS:
            mean, std = paper_numbers(PAPER[(task, algo)])
            axis.axhline(mean, color=COLORS[algo], linestyle="--", linewidth=1.6, alpha=0.7, label=f"{NAMES[algo]}, Table 1")
            axis.axhspan(mean - std, mean + std, color=COLORS[algo], alpha=0.1)
        axis.set_xlim(0, PAPER_ENV_STEPS[task])
        axis.set_title(f"{label(task)}, no collision penalty: coverage at each evaluation")
        axis.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(format_steps))
        axis.set_xlabel("env steps")
        axis.set_ylabel("Coverage %")
        axis.legend(fontsize=7, loc="lower right")
    save_figure(figure, path)


def scale_order(scale: str) -> int:
    """The place of a scale in the tables and legends: team, group, individual, then any other."""
    order = list(SCALE_COLORS)
    return order.index(scale) if scale in order else len(order)


def plot_fire_rates(bonus: dict[tuple[str, int], BonusTable], path: Path) -> None:
    """One panel per task: each ``SAEIR_PPO`` run's fire rate per scale over training (a point per window, at its
    middle), on a scale linear below the smallest rate that fired (so that windows without firing show at 0)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sb3_saeir.benchmark.reports import format_steps, save_figure

    positive = [float(np.nanmin(r[r > 0])) for b in bonus.values() for r in b.fire_rates.values() if (r > 0).any()]
    figure, axes = plt.subplots(1, len(TASKS), figsize=(6.5 * len(TASKS), 4.4), squeeze=False)
    for axis, task in zip(axes[0], TASKS.values()):
        for (found_task, seed), found in sorted(bonus.items()):
            if found_task != task:
                continue
            middles = (found.starts + found.ends) / 2  # (n_windows,)
            for scale, rates in sorted(found.fire_rates.items(), key=lambda item: scale_order(item[0])):
                style = SEED_STYLES[(seed - 1) % len(SEED_STYLES)]
                color = SCALE_COLORS.get(scale, "0.4")
                axis.plot(middles, rates, color=color, linestyle=style, marker=".", linewidth=1.1, label=f"s{seed} {scale}")
        if axis.lines:
            axis.set_yscale("symlog", linthresh=min(positive) if positive else 1.0)
        axis.set_xlim(0, PAPER_ENV_STEPS[task])
        axis.set_title(f"{label(task)}: SAEIR_PPO's bonus fire rate per scale")
        axis.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(format_steps))
        axis.set_xlabel("env steps")
        axis.set_ylabel("fire rate (share of agent-steps)")
        if axis.get_legend_handles_labels()[0]:
            axis.legend(fontsize=7)
        else:
            axis.text(0.5, 0.5, "no bonus table yet", ha="center", va="center", transform=axis.transAxes)
    save_figure(figure, path)


def write_markdown(path: Path, lines: list[str]) -> None:
    path.write_text("\n".join(lines) + "\n")


def write_final_runs(out: Path, rows: list[dict[str, Any]]) -> None:
    """A study's final runs as the benchmark writes a results folder: ``out/runs.csv`` (their evaluations, read by
    ``benchmarks/results_pages.py`` for the study's rows in ``docs/results.md``) and ``out/table.md`` (the final table
    of ``python -m sb3_saeir.benchmark``). With no final run yet neither file exists (a stale pair is removed), so that
    no summary row can show a run before it is final.

    :param out: the study's folder
    :param rows: the evaluations of its final runs
    """
    if not rows:
        (out / "runs.csv").unlink(missing_ok=True)
        (out / "table.md").unlink(missing_ok=True)
        return
    write_rows(out / "runs.csv", rows)
    atomic_write_text(out / "table.md", table_markdown(rows))


def final_runs_rows(states: list[RunState]) -> list[dict[str, Any]]:
    """The evaluations of the final runs, each under the task id of the reading it was read as (N=3 seed 1 ran as
    ``cn-sparse-n3`` with ``env_kwargs: {collision_penalty: 0.0}``: the same game keywords, checked against the id's by
    :func:`protocol_differences`)."""
    return [{**row, "task": s.run.task} for s in states if s.final is not None for row in s.rows]


def build(results: Path) -> list[RunState]:
    """Read every planned run under ``results`` and write the study's tables and figures into
    ``results/table1-navigation/``; returns the runs' states."""
    states = [read_run(run, results) for run in RUNS]
    out = results / STUDY
    out.mkdir(parents=True, exist_ok=True)
    bonus = bonus_tables(states, results)
    write_markdown(out / "runs.md", runs_table(states))
    write_markdown(out / "finals.md", finals_table(states))
    write_markdown(out / "differences.md", differences_tables(states))
    write_markdown(out / "reward.md", reward_table(states))
    write_markdown(out / "fire_rate.md", fire_rate_table(states, bonus))
    write_final_runs(out, final_runs_rows(states))
    plot_curves(states, out / "curves.png")
    plot_fire_rates(bonus, out / "fire_rate.png")
    return states


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--results", type=Path, default=DOCS / "results", help="docs/results: the run files, the outputs")
    args = parser.parse_args(argv)
    for s in build(args.results):
        print(f"{label(s.run.task)} {s.run.algo} s{s.run.seed} ({s.run.folder}): {s.state()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
