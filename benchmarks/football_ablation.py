"""Football 3 vs 1, issue 65 (``docs/results/football-ablation.md``): which half of SAEIR leaves the random floor
earlier on ``grf-3v1-keeper``, its critic (``MSHG-only``) or its bonus (``SAE-only``), each against ``MAPPO`` (the
paper's Fig. 5 ablation, on football), then ``SAEIR_PPO`` against ``MAPPO``, over the first 1M env steps, from the
committed run files alone.

    python benchmarks/football_ablation.py                      # docs/results/football-ablation/: tables, figure
    python benchmarks/football_ablation.py --results DIR        # the run files under DIR, the outputs in DIR/football-ablation

The runs are :data:`RUNS`, each a folder of committed run files under ``docs/results/`` (``spec.json``,
``evaluations.csv``, ``done.json``, ...): ``MSHG-only`` and ``SAE-only`` seeds 1-3 and ``MAPPO`` and ``SAEIR_PPO``
seed 4 are this study's runs (1M env steps, ``football-ablation/runs/<algo>/grf-3v1-keeper_s<seed>``, copied by
``report.sh``); ``MAPPO`` and ``SAEIR_PPO`` seeds 1-3 are the 2M env steps runs of the football probe (seed 1,
``football-probe/runs/<algo>``) and of stage F (seeds 2-3, ``football-stage-f/3v1/runs/<algo>/grf-3v1-keeper_s<seed>``),
read up to 1M env steps. Each run's ``spec.json`` is checked against the protocol (:func:`protocol_differences`:
method, seed, task, 8 games, 100 evaluation episodes every 250k env steps).

A run is *finished* when its folder has ``done.json`` or, for a run whose ``done.json`` was never committed (the
probe's ``SAEIR_PPO`` seed 1), when the last segment of its ``segments.json`` reached its budget; it is *final* for
this study when it is finished, follows the protocol and has an evaluation at 1M env steps. Any other run is shown by
its state (``running, at 0.5M env steps``, ``no run files yet``, ...) and enters no mean and no test. Writes into
``DIR/football-ablation/``:

- ``runs.md``: every planned run, where its files are, its protocol and budget from ``spec.json``, the evaluations
  read (those up to 1M env steps), what says it finished, and its state;
- ``success.md``: per method and seed, success % at 0, 250k, 500k, 750k and 1M env steps, then per method the mean
  over its final seeds;
- ``reaches.md``: per method and threshold (10 and 20 % success), each seed's first evaluation at or above it;
- ``rule.md``: the rule below, then its tests and the case found per threshold (pending while a run it needs is not
  final; a pending test names the smallest p-value the runs still to come can give, :func:`smallest_p_still`);
- ``runs.csv`` and ``table.md``: the final runs' evaluations cut at 1M env steps and the benchmark's final table of
  them (``table1_navigation.write_final_runs``: neither file before a run is final), which ``docs/results.md``'s rows
  and its football figure read;
- ``curves.png``: every run's success curve to 1M env steps (thin), each method's mean over its final seeds (thick);
- ``bonus_rise.md``, only where it is missing: a placeholder naming the four kept models, until ``report.sh bonus``
  writes ``benchmarks/bonus_rise.py``'s tables there (an existing ``bonus_rise.md`` is left untouched).

Definitions (the page states them): every curve is cut at 1M env steps (the evaluations with env_steps <= 1,000,000),
so the 2M runs and the 1M runs are compared over the same span, and read on the protocol's grid (every 250k env steps
from 0): the extra evaluation at the end of each of ``SAEIR_PPO`` seed 4's legs is left out (:func:`cut_at_window`).
**Success at S** is the success % of the first evaluation at or after S (100 greedy episodes;
:func:`learning_speed.value_at`). The **first reach** of a threshold is the env steps of a seed's first evaluation at
or above it (:func:`learning_speed.first_reach`); a seed that has not reached it by 1M env steps is censored at 1M and
ranks after every seed that reached it (:func:`learning_speed.reach_ranks`). The **share of seed pairs earlier** is
the share of (arm seed, MAPPO seed) pairs in which the arm's seed reaches first, ties counting half
(:func:`learning_speed.earlier_test`).

The rule, fixed before any result (``rule.md`` and the page repeat it verbatim, :data:`RULE`):

For each threshold separately (10 % and 20 % success), the exact one-sided Mann-Whitney test that an arm's first
reaches are earlier than those of MAPPO's four seeds (learning_speed.earlier_test; ties, censored seeds among them,
count half). The critic takes the credit if MSHG-only is earlier at p <= 0.05 while SAE-only is not; the bonus takes it
if SAE-only is earlier at p <= 0.05 while MSHG-only is not; both, if both are; neither, if neither is. Then SAEIR_PPO
(4 seeds) against MAPPO (4 seeds), the same test, reported as earlier at p <= 0.05 or not. Every curve is cut at 1M
env steps; a seed that has not reached a threshold by 1M is censored at 1M and ranks after every seed that reached it.
The rule is applied only when every run it needs is final; until then it names no case.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from sb3_saeir.envs import get_task_spec

sys.path.insert(0, str(Path(__file__).parent))
from evaluation_curves import metric_curve
from learning_speed import Curve, earlier_test, first_reach, reach_ranks, value_at
from results_pages import DOCS, NAMES, NONE, millions
from table1_navigation import read_run_files, table, write_final_runs, write_markdown

STUDY = "football-ablation"
TASK = "grf-3v1-keeper"
N_AGENTS = int(get_task_spec(TASK).kwargs["N"])
BASELINE = "mappo"
ABLATIONS = ("mshg_only", "sae_only")  # the critic alone, the bonus alone
ARMS = (BASELINE, "saeir_ppo", *ABLATIONS)
SEEDS = {"mappo": (1, 2, 3, 4), "saeir_ppo": (1, 2, 3, 4), "mshg_only": (1, 2, 3), "sae_only": (1, 2, 3)}
# The protocol fixed before the runs (docs/results/football-ablation/queue.sh, stage F's): games, greedy episodes per
# evaluation, env steps between evaluations; the common window every curve is cut at, its checkpoints, the thresholds.
GAMES, EVAL_EPISODES, EVAL_EVERY = 8, 100, 250_000
WINDOW = 1_000_000
CHECKPOINTS = (0.0, 250_000.0, 500_000.0, 750_000.0, 1_000_000.0)
THRESHOLDS = (10.0, 20.0)  # success %
ALPHA = 0.05
CASES = {  # (MSHG-only earlier, SAE-only earlier) -> the case
    (True, False): "the critic takes the credit",
    (False, True): "the bonus takes it",
    (True, True): "both",
    (False, False): "neither",
}
COLORS = {"mappo": "C0", "saeir_ppo": "C3", "mshg_only": "C2", "sae_only": "C1"}
KEPT_STEPS = (250_000, 500_000, 750_000, 1_000_000)  # SAEIR_PPO seed 4's legs: its model kept at the end of each
RULE = (
    "For each threshold separately (10 % and 20 % success), the exact one-sided Mann-Whitney test that an arm's first "
    "reaches are earlier than those of MAPPO's four seeds (learning_speed.earlier_test; ties, censored seeds among "
    "them, count half). The critic takes the credit if MSHG-only is earlier at p <= 0.05 while SAE-only is not; the "
    "bonus takes it if SAE-only is earlier at p <= 0.05 while MSHG-only is not; both, if both are; neither, if neither "
    "is. Then SAEIR_PPO (4 seeds) against MAPPO (4 seeds), the same test, reported as earlier at p <= 0.05 or not. "
    "Every curve is cut at 1M env steps; a seed that has not reached a threshold by 1M is censored at 1M and ranks "
    "after every seed that reached it. The rule is applied only when every run it needs is final; until then it names "
    "no case."
)


class PlannedRun(NamedTuple):
    """A run of the study: its method and seed, and its folder under ``docs/results/``."""

    algo: str
    seed: int
    folder: str


def run_folder(algo: str, seed: int) -> str:
    """The folder of a planned run under ``docs/results/``: the probe's (seed 1) and stage F's (seeds 2-3) runs of
    ``MAPPO`` and ``SAEIR_PPO``, this study's (``report.sh`` copies them there) for the others."""
    if algo in ("mappo", "saeir_ppo") and seed == 1:
        return f"football-probe/runs/{algo}"
    if algo in ("mappo", "saeir_ppo") and seed in (2, 3):
        return f"football-stage-f/3v1/runs/{algo}/{TASK}_s{seed}"
    return f"{STUDY}/runs/{algo}/{TASK}_s{seed}"


RUNS = tuple(PlannedRun(algo, seed, run_folder(algo, seed)) for algo in ARMS for seed in SEEDS[algo])


def cut_at_window(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The evaluations the study reads: those of the protocol's grid (every 250k env steps from 0) in the common window
    (env steps <= 1M). A run trained in legs (``SAEIR_PPO`` seed 4) also evaluates at the end of each leg, one rollout
    past the grid's point (the leg's budget is not a whole number of rollouts: 251,200 env steps after the one at
    250,000), which a run trained in one go does not: those are left out, so that every seed is read on the same
    evaluations."""
    return [row for row in rows if float(row["env_steps"]) <= WINDOW and float(row["env_steps"]) % EVAL_EVERY == 0]


class RunState(NamedTuple):
    """What the committed files of a planned run say.

    :param run: the planned run
    :param rows: all its evaluations, sorted by env steps (empty: none yet)
    :param spec: its ``spec.json`` (``None``: no run files yet)
    :param finished_by: what says it finished (``done.json``, or ``segments.json`` for a run whose ``done.json`` was
        never committed); ``None``: it has not finished
    :param differences: how its ``spec.json`` differs from the protocol (empty: it does not)
    :param curve: its success curve (%) cut at 1M env steps (``None``: no evaluation in the window yet)
    """

    run: PlannedRun
    rows: list[dict[str, Any]]
    spec: dict[str, Any] | None
    finished_by: str | None
    differences: list[str]
    curve: Curve | None

    @property
    def window_rows(self) -> list[dict[str, Any]]:
        """The evaluations the study reads (:func:`cut_at_window`)."""
        return cut_at_window(self.rows)

    @property
    def budget(self) -> float:
        """The run's budget in env steps (its ``spec.json``'s agent-steps over the agents); NaN without files."""
        return math.nan if self.spec is None else float(self.spec["n_timesteps"]) / N_AGENTS

    @property
    def final(self) -> bool:
        """Finished, following the protocol, with an evaluation at 1M env steps."""
        evaluated_to = None if self.curve is None else self.curve[0][-1]
        return self.finished_by is not None and not self.differences and evaluated_to == WINDOW

    def state(self) -> str:
        """``final at 1M env steps``, ``running, at 0.5M env steps``, ``no run files yet``, ..."""
        last = f"{millions(float(self.rows[-1]['env_steps']))} env steps" if self.rows else None
        if self.spec is None:
            return "no run files yet"
        if self.differences:
            return f"differs from the protocol: {'; '.join(self.differences)}"
        if self.final:
            return f"final at {millions(WINDOW)} env steps"
        if self.finished_by is not None and self.budget >= WINDOW:
            return f"stopped before {millions(WINDOW)} env steps, at {last or 'no evaluation'}"
        if self.finished_by is not None:  # a leg of a run trained in legs (SAEIR_PPO seed 4): more legs to come
            return f"running, at {last or 'no evaluation'} (its leg to {millions(self.budget)} env steps finished)"
        return f"running, at {last}" if last else "running, no evaluation yet"


def protocol_differences(spec: dict[str, Any], run: PlannedRun) -> list[str]:
    """How a run's ``spec.json`` differs from the protocol (method, seed, task, games, evaluation episodes and
    spacing); empty when it does not. The budget is not checked: 2M and 1M runs are both read to 1M env steps.

    :param spec: the run's ``spec.json``
    :param run: the planned run it should be
    """
    checks = {
        "method": (spec.get("algo"), run.algo),
        "seed": (spec.get("seed"), run.seed),
        "task": (spec.get("task"), TASK),
        "games": (spec.get("n_games"), GAMES),
        "evaluation episodes": (spec.get("eval_episodes"), EVAL_EPISODES),
        "env steps between evaluations": (float(spec.get("eval_freq", math.nan)) / N_AGENTS, EVAL_EVERY),
    }
    return [f"{name} {found} (expected {wanted})" for name, (found, wanted) in checks.items() if found != wanted]


def finished_record(folder: Path, spec: dict[str, Any]) -> str | None:
    """What says a run finished: ``done.json``, else its ``segments.json`` whose last segment reached the budget of its
    ``spec.json`` (a run whose ``done.json`` was never committed); ``None`` when neither does.

    :param folder: the run's folder of committed files
    :param spec: its ``spec.json``
    """
    if (folder / "done.json").is_file():
        return "done.json"
    segments = json.loads((folder / "segments.json").read_text()) if (folder / "segments.json").is_file() else []
    if segments and float(segments[-1].get("reached", 0)) >= float(spec["n_timesteps"]):
        return "segments.json (no done.json)"
    return None


def read_run(run: PlannedRun, results: Path) -> RunState:
    """The state of a planned run from its committed files under ``results`` (a missing folder: no run files yet)."""
    folder = results / run.folder
    files = read_run_files(folder)
    if files is None:
        return RunState(run, [], None, None, [], None)
    spec, rows = files
    window = cut_at_window(rows)
    curve = metric_curve(window, "success") if window else None
    return RunState(run, rows, spec, finished_record(folder, spec), protocol_differences(spec, run), curve)


def name(s: RunState) -> str:
    """``MAPPO s4``."""
    return f"{NAMES[s.run.algo]} s{s.run.seed}"


def final_curves(states: list[RunState], algo: str) -> dict[int, Curve]:
    """The curves (cut at 1M env steps) of a method's final seeds, by seed."""
    return {s.run.seed: s.curve for s in states if s.run.algo == algo and s.final and s.curve is not None}


def reach_times(curves: dict[int, Curve], threshold: float) -> list[float]:
    """Each seed's first reach of ``threshold`` as a rank key (``inf``: censored at 1M env steps)."""
    return reach_ranks([first_reach(curve, threshold) for curve in curves.values()])


def smallest_p(n_first: int, n_second: int) -> float:
    """The smallest p-value the exact one-sided test can give, ``n_first`` seeds against ``n_second``: one split of
    the pooled seeds in ``comb(n_first + n_second, n_first)`` (1/35 for 3 against 4, 1/70 for 4 against 4)."""
    return 1.0 / math.comb(n_first + n_second, n_first)


def reaches_still_possible(s: RunState, threshold: float) -> list[float]:
    """The first reaches of ``threshold`` (rank keys, ``inf``: censored at 1M env steps) that a run can still end
    with: the one it has, once its evaluations read have reached the threshold; else any grid point after its last
    evaluation read, or censored (a final run, evaluated at 1M: its own, one key). A run without files, or one that
    differs from the protocol (it must be made again), can still end with any of them.

    :param s: the run's state
    :param threshold: success %
    """
    after = -math.inf
    if s.curve is not None and not s.differences:
        steps, reached = first_reach(s.curve, threshold)
        if reached:
            return [steps]
        after = steps  # the last evaluation read, below the threshold
    return [*(c for c in CHECKPOINTS if c > after), math.inf]


def smallest_p_still(states: list[RunState], algo: str, threshold: float) -> float | None:
    """The smallest p-value the rule's test of ``algo`` against ``MAPPO`` can still give, over every first reach that
    the arm's runs not final yet can still end with (:func:`reaches_still_possible`): what the runs still to come can
    change. ``None`` while a ``MAPPO`` seed is not final (the bound is kept to the arm's own runs).

    :param states: every planned run's state
    :param algo: the arm
    :param threshold: success %
    """
    if not all(s.final for s in states if s.run.algo == BASELINE):
        return None
    second = reach_times(final_curves(states, BASELINE), threshold)
    options = [reaches_still_possible(s, threshold) for s in states if s.run.algo == algo]  # one key per final run
    return min(earlier_test(list(first), second)[1] for first in itertools.product(*options))


class ArmTest(NamedTuple):
    """The rule's test of one arm against ``MAPPO`` at one threshold.

    :param algo: the arm
    :param threshold: success %
    :param share: the share of seed pairs where the arm reaches first, ties half (``None``: pending)
    :param p: the exact one-sided p-value (``None``: pending)
    :param missing: the runs it needs that are not final (empty: it is applied)
    :param p_still: while pending, the smallest p-value the runs still to come can give (:func:`smallest_p_still`;
        ``None``: applied, or a ``MAPPO`` seed is not final)
    """

    algo: str
    threshold: float
    share: float | None
    p: float | None
    missing: list[str]
    p_still: float | None = None

    @property
    def earlier(self) -> bool | None:
        """Earlier at p <= 0.05 (``None``: pending)."""
        return None if self.p is None else self.p <= ALPHA + 1e-12


def arm_test(states: list[RunState], algo: str, threshold: float) -> ArmTest:
    """The test that ``algo``'s first reaches of ``threshold`` are earlier than ``MAPPO``'s; pending (no share, no p)
    while any planned run of either method is not final."""
    missing = [name(s) for s in states if s.run.algo in (algo, BASELINE) and not s.final]
    if missing:
        return ArmTest(algo, threshold, None, None, missing, smallest_p_still(states, algo, threshold))
    first = reach_times(final_curves(states, algo), threshold)
    second = reach_times(final_curves(states, BASELINE), threshold)
    share, p = earlier_test(first, second)
    return ArmTest(algo, threshold, share, p, [])


def case(critic: ArmTest, bonus: ArmTest) -> str | None:
    """The rule's case at one threshold from the ``MSHG-only`` and ``SAE-only`` tests (``None``: pending)."""
    if critic.earlier is None or bonus.earlier is None:
        return None
    return CASES[(critic.earlier, bonus.earlier)]


def still_text(test: ArmTest) -> str:
    """``smallest p still possible: 0.086`` (``-`` without a bound) for a pending test."""
    return f"smallest p still possible: {NONE if test.p_still is None else f'{test.p_still:.3f}'}"


def yes_no(value: bool | None) -> str:
    return NONE if value is None else ("yes" if value else "no")


def percent(threshold: float) -> str:
    return f"{threshold:g}%"


def rule_tests(states: list[RunState]) -> dict[tuple[str, float], ArmTest]:
    """The rule's tests: ``MSHG-only``, ``SAE-only`` and ``SAEIR_PPO`` against ``MAPPO`` at each threshold."""
    return {(algo, t): arm_test(states, algo, t) for algo in (*ABLATIONS, "saeir_ppo") for t in THRESHOLDS}


def case_rows(states: list[RunState], tests: dict[tuple[str, float], ArmTest]) -> list[list[str]]:
    """Per threshold: whether ``MSHG-only`` and ``SAE-only`` are earlier, and the case found (or what it waits for)."""
    waits = ", ".join(name(s) for s in states if s.run.algo in (BASELINE, *ABLATIONS) and not s.final)
    rows = []
    for threshold in THRESHOLDS:
        critic, bonus = tests[(ABLATIONS[0], threshold)], tests[(ABLATIONS[1], threshold)]
        found = case(critic, bonus) or f"pending: waits for {waits}"
        rows.append([percent(threshold), yes_no(critic.earlier), yes_no(bonus.earlier), found])
    return rows


def rule_lines(states: list[RunState]) -> list[str]:
    """``rule.md``: the rule, the smallest p-values, the runs not final yet, its tests (one row per arm and
    threshold), then per threshold the case found (or what it waits for)."""
    tests = rule_tests(states)
    missing = [name(s) for s in states if not s.final]
    lines = [
        f"**The rule** (fixed before any result): {RULE}",
        "",
        f"The smallest p-value the test can give: 1/{math.comb(7, 3)} = {smallest_p(3, 4):.3f} for 3 seeds against 4 "
        f"(MSHG-only, SAE-only), 1/{math.comb(8, 4)} = {smallest_p(4, 4):.3f} for 4 against 4 (SAEIR_PPO).",
        "",
        f"Pending: not final yet: {', '.join(missing)}." if missing else "Every run is final: the rule is applied.",
        "",
    ]
    if missing:
        lines += [
            "A pending test names the smallest p-value it can still give: the least over every first reach that the "
            "arm's runs not final yet can still end with (one already reached stays; otherwise any evaluation after "
            "the last one read, or censored at 1M), MAPPO's four seeds as they are (`-` while one of them is not "
            "final). It is a bound, not the test: the rule waits for the runs.",
            "",
        ]
    rows = []
    for (algo, threshold), test in tests.items():
        seeds = f"{len(SEEDS[algo])} vs {len(SEEDS[BASELINE])}"
        if test.p is None or test.share is None:
            cells = [NONE, NONE, f"pending: waits for {', '.join(test.missing)} ({still_text(test)})"]
        else:
            cells = [f"{test.share:.0%}", f"{test.p:.3f}", yes_no(test.earlier)]
        rows.append([NAMES[algo], percent(threshold), seeds, *cells])
    header = ["arm", "threshold", "seeds (arm vs MAPPO)", "share of seed pairs earlier", "p (one-sided)"]
    lines += [*table([*header, f"earlier at p <= {ALPHA:g}"], rows), ""]
    return [*lines, *table(["threshold", "MSHG-only earlier", "SAE-only earlier", "case"], case_rows(states, tests))]


def runs_table(states: list[RunState]) -> list[str]:
    """``runs.md``: every planned run, its files, its protocol and budget from ``spec.json``, the evaluations read,
    what says it finished, and its state."""
    rows = []
    for s in states:
        cells = [NAMES[s.run.algo], str(s.run.seed), f"`{s.run.folder}`"]
        if s.spec is None:
            cells += [NONE] * 4
        else:
            every = float(s.spec["eval_freq"]) / N_AGENTS
            protocol = f"{s.spec['n_games']} games, {s.spec['eval_episodes']} episodes every {millions(every)} env steps"
            read = f"{len(s.window_rows)} of {len(s.rows)}"
            cells += [protocol, millions(s.budget), read, s.finished_by or NONE]
        rows.append([*cells, s.state()])
    header = ["method", "seed", "run files (under docs/results/)", "protocol", "budget (env steps)"]
    grid = f"evaluations read (every {millions(EVAL_EVERY)} to {millions(WINDOW)})"
    return table([*header, grid, "finished (record)", "state"], rows)


def success_table(states: list[RunState]) -> list[str]:
    """``success.md``: per method and seed, success % at each checkpoint (``-``: not evaluated yet), then per method
    the mean over its final seeds."""
    rows = []
    for algo in ARMS:
        chosen = [s for s in states if s.run.algo == algo]
        for s in chosen:
            values = [None if s.curve is None else value_at(s.curve, c) for c in CHECKPOINTS]
            rows.append([NAMES[algo], str(s.run.seed), s.state(), *(NONE if v is None else f"{v:.0f}" for v in values)])
        finals = list(final_curves(states, algo).values())
        means = [f"{np.mean([value_at(c, at) for c in finals]):.1f}" if finals else NONE for at in CHECKPOINTS]
        rows.append([NAMES[algo], f"mean of {len(finals)} final seeds", "", *means])
    return table(["method", "seed", "state", *(millions(c) for c in CHECKPOINTS)], rows)


def reach_cell(s: RunState, threshold: float) -> str:
    """A seed's first reach: ``s1 0.5M``; ``s1 > 1M`` (censored); for a run not final ``s4 0.5M (not final)`` or
    ``s4 - (running, at 0.5M env steps)``."""
    if s.curve is None:
        return f"s{s.run.seed} {NONE} ({s.state()})"
    steps, reached = first_reach(s.curve, threshold)
    if s.final:
        return f"s{s.run.seed} {millions(steps)}" if reached else f"s{s.run.seed} > {millions(WINDOW)}"
    return f"s{s.run.seed} {millions(steps)} (not final)" if reached else f"s{s.run.seed} {NONE} ({s.state()})"


def reaches_table(states: list[RunState]) -> list[str]:
    """``reaches.md``: per method and threshold, each seed's first evaluation at or above it."""
    rows = []
    for algo in ARMS:
        chosen = [s for s in states if s.run.algo == algo]
        n_final = sum(s.final for s in chosen)
        for threshold in THRESHOLDS:
            cells = ", ".join(reach_cell(s, threshold) for s in chosen)
            rows.append([NAMES[algo], percent(threshold), cells, f"{n_final} of {len(chosen)}"])
    return table(["method", "threshold", "first reached at (env steps) per seed", "final seeds"], rows)


def kept_model(steps: int) -> str:
    """SAEIR_PPO seed 4's model kept at ``steps`` env steps (with its ``spec.json``), under
    ``$HOME/saeir-results/football-ablation/`` (queue.sh keeps it there; models are not committed)."""
    return f"kept-models/saeir_ppo_s4_{steps // 1000}k/{TASK}.zip"


def bonus_placeholder() -> list[str]:
    """``bonus_rise.md`` until ``report.sh bonus`` writes it: the kept models, not read yet."""
    rows = [[f"`{kept_model(steps)}`", millions(steps), "not read yet"] for steps in KEPT_STEPS]
    return [
        "Not read yet: `bash docs/results/football-ablation/report.sh bonus` replaces this file with the tables of "
        "`benchmarks/bonus_rise.py` on SAEIR_PPO seed 4's kept models (under `$HOME/saeir-results/football-ablation/`).",
        "",
        *table(["kept model (SAEIR_PPO seed 4)", "env steps", "state"], rows),
    ]


def plot_curves(states: list[RunState], path: Path) -> None:
    """Success % against env steps to 1M: every run's curve thin (a run not final dashed), each method's mean over
    its final seeds thick, one colour per method; the two thresholds dotted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sb3_saeir.benchmark.reports import label_task_panel, save_figure

    figure, axis = plt.subplots(figsize=(7.0, 4.4))
    for s in states:
        if s.curve is None:
            continue
        steps, values = s.curve
        style = "-" if s.final else "--"
        axis.plot(steps, values, color=COLORS[s.run.algo], alpha=0.45, linewidth=1, linestyle=style, marker=".", markersize=3)
        axis.annotate(f"s{s.run.seed}", (steps[-1], values[-1]), fontsize=6, color=COLORS[s.run.algo])
    for algo in ARMS:
        finals = list(final_curves(states, algo).values())
        if not finals:
            continue
        common = min(len(steps) for steps, _ in finals)
        mean = np.mean([values[:common] for _, values in finals], axis=0)  # (common,)
        label = f"{NAMES[algo]} (mean of {len(finals)} final seeds)"
        axis.plot(finals[0][0][:common], mean, color=COLORS[algo], linewidth=2.2, label=label)
    for threshold in THRESHOLDS:
        axis.axhline(threshold, color="0.4", linestyle=":", linewidth=1)
    axis.plot([], [], color="0.4", linestyle=":", linewidth=1, label="thresholds 10% and 20%")
    axis.set_xlim(0, 1.04 * WINDOW)  # room for the seeds' labels at 1M
    label_task_panel(axis, "3 vs 1 (grf-3v1-keeper): success to 1M env steps (dashed: not final)", "Success %")
    save_figure(figure, path)


def build(results: Path) -> list[RunState]:
    """Read every planned run under ``results`` and write the study's tables and figure into
    ``results/football-ablation/``; returns the runs' states."""
    states = [read_run(run, results) for run in RUNS]
    out = results / STUDY
    out.mkdir(parents=True, exist_ok=True)
    write_markdown(out / "runs.md", runs_table(states))
    write_markdown(out / "success.md", success_table(states))
    write_markdown(out / "reaches.md", reaches_table(states))
    write_markdown(out / "rule.md", rule_lines(states))
    write_final_runs(out, [row for s in states if s.final for row in s.window_rows])
    if not (out / "bonus_rise.md").is_file():
        write_markdown(out / "bonus_rise.md", bonus_placeholder())
    plot_curves(states, out / "curves.png")
    return states


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--results", type=Path, default=DOCS / "results", help="docs/results: the run files, the outputs")
    args = parser.parse_args(argv)
    states = build(args.results)
    for s in states:
        print(f"{name(s)} ({s.run.folder}): {s.state()}")
    tests = rule_tests(states)
    for (algo, threshold), test in tests.items():
        found = (
            f"pending ({still_text(test)})"
            if test.p is None
            else f"share {test.share:.0%}, p = {test.p:.3f}, earlier: {yes_no(test.earlier)}"
        )
        print(f"{NAMES[algo]} earlier than MAPPO at {percent(threshold)}: {found}")
    for cells in case_rows(states, tests):
        print(f"case at {cells[0]}: {cells[-1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
