"""Benchmark runner: methods x tasks x seeds -> ``runs.csv``, the paper's Table 1 layout and learning curves.

    python -m sb3_saeir.benchmark --algos saeir_ppo mappo --tasks cn-sparse-n3 --seeds 1-3 \\
        --n-timesteps 1000000 --n-games 16 --eval-freq 50000 --eval-episodes 50 --jobs 2 --out results/cn3

Each run trains with the packaged config of its method (``zoo_configs/<algo>.yml``; ``--n-games`` and ``-params``
override it) and evaluates every ``--eval-freq`` agent-steps on game episodes. Output folder:

- ``runs/<algo>/<task>_s<seed>/``: ``evaluations.csv`` (one row per evaluation), ``progress.csv`` (SB3 logger),
  ``checkpoint.zip`` (latest, for resuming), ``done.json`` (when finished);
- ``runs.csv``: every evaluation row of every run (algo, task, seed, agent-steps, env steps, metrics);
- ``table.md``: mean ± std over seeds at the final evaluation, best method in bold (the paper's Table 1 layout);
- ``curves.png``: one panel per task, mean line and std band per method, x axis in env steps (game steps);
- ``aggregate.md`` with ``--rliable``: IQM and 95% stratified-bootstrap confidence intervals of the final main metric.

Re-running the same command skips finished runs and resumes interrupted ones from their checkpoint; a failing run is
reported in ``failures.txt`` and does not stop the others. ``--ray-address`` runs them on a Ray cluster instead of
local processes (results gathered into the same folder; resuming from checkpoints needs a shared filesystem).
``--entropy-plot RUN_FOLDER`` draws the SAEIR bonus and the value-softmax entropy over training for one run.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sb3_saeir.config import ALGOS, ConfigError, check_hyperparams, load_hyperparams, parse_params
from sb3_saeir.evaluation import MultiAgentEvalCallback

# Columns of the paper's Table 1 per task family: (metric key in runs.csv, header, scale)
TABLE_COLUMNS = {
    "cn": [("coverage_rate_mean", "Coverage %", 100.0), ("ep_rew_mean", "Ep. reward", 1.0)],
    "grf": [("success_mean", "Success %", 100.0), ("ep_rew_mean", "Ep. reward", 1.0)],
}


@dataclass(frozen=True)
class RunSpec:
    """One training run of the benchmark."""

    algo: str
    task: str
    seed: int
    n_timesteps: int
    n_games: int | None = None
    eval_freq: int = 50_000
    eval_episodes: int = 20
    params: dict[str, Any] = field(default_factory=dict, hash=False, compare=False)

    @property
    def name(self) -> str:
        return f"{self.algo}/{self.task}_s{self.seed}"


def parse_seeds(text: str) -> list[int]:
    """``"1-5"`` -> [1, 2, 3, 4, 5]; ``"1,3,7"`` -> [1, 3, 7]."""
    seeds: list[int] = []
    for part in text.split(","):
        if "-" in part.strip()[1:]:
            low, high = part.split("-", 1)
            seeds.extend(range(int(low), int(high) + 1))
        elif part.strip():
            seeds.append(int(part))
    return seeds


def run_folder(out: Path, spec: RunSpec) -> Path:
    return out / "runs" / spec.algo / f"{spec.task}_s{spec.seed}"


def read_rows(path: Path) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    with open(path, newline="") as file:
        return [{key: _number(value) for key, value in row.items()} for row in csv.DictReader(file)]


def _number(value: str) -> Any:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return value
    return int(number) if number.is_integer() and "." not in value and "e" not in value.lower() else number


def write_rows(path: Path, rows: list[dict[str, Any]]) -> None:
    keys = list(dict.fromkeys(key for row in rows for key in row))
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)


class BenchmarkEvalCallback(MultiAgentEvalCallback):
    """The benchmark's evaluation: every evaluation becomes a row of the run's ``evaluations.csv``, and the model is
    checkpointed at the start of every rollout after the first (a consistent point to resume from).

    :param eval_env: the evaluation env
    :param spec: the run
    :param evaluations_path: the run's ``evaluations.csv``
    :param checkpoint_path: the run's ``checkpoint.zip``
    :param rows: evaluation rows already recorded (kept on resume)
    :param n_agents: agents per game (``env_steps = agent-steps / n_agents``)
    :param main_metric: the task's main metric
    """

    def __init__(
        self,
        eval_env: Any,
        spec: RunSpec,
        evaluations_path: Path,
        checkpoint_path: Path,
        rows: list[dict[str, Any]],
        n_agents: int,
        main_metric: str,
    ) -> None:
        super().__init__(eval_env, spec.eval_episodes, spec.eval_freq, main_metric=main_metric, verbose=0)
        self.spec = spec
        self.evaluations_path = evaluations_path
        self.checkpoint_path = checkpoint_path
        self.rows = rows
        self.n_agents = n_agents
        self.resumed_at = 0
        self.last_eval_timestep = int(rows[-1]["timesteps"]) if rows else 0

    def _on_rollout_start(self) -> None:
        if self.model.num_timesteps > self.resumed_at:  # after an update: a consistent point to resume from
            self.model.save(self.checkpoint_path)

    def evaluate(self) -> bool:
        keep_going = super().evaluate()
        spec = self.spec
        row: dict[str, Any] = {"algo": spec.algo, "task": spec.task, "seed": spec.seed, "timesteps": self.num_timesteps}
        row["env_steps"] = self.num_timesteps // self.n_agents
        row.update({key: value for key, value in self.last_summary.items() if not key.endswith("_std")})
        row.update({key: value for key, value in self.last_summary.items() if key.endswith("_std")})
        self.rows.append(row)
        write_rows(self.evaluations_path, self.rows)
        return keep_going


def execute_run(spec: RunSpec, folder: str) -> dict[str, Any]:
    """Train and evaluate one run in ``folder`` (resuming from its checkpoint); returns its evaluation rows.

    Runs in a worker process (local or Ray): torch uses one thread.
    """
    import torch as th
    from stable_baselines3.common.logger import configure

    from sb3_saeir.config import load_hyperparams
    from sb3_saeir.experiment import Experiment

    th.set_num_threads(1)
    path = Path(folder)
    path.mkdir(parents=True, exist_ok=True)
    evaluations_path = path / "evaluations.csv"
    if (path / "done.json").is_file():
        return {"spec": asdict(spec), "status": "skipped", "rows": read_rows(evaluations_path)}
    start = time.time()
    experiment = Experiment(
        spec.algo, spec.task, {**load_hyperparams(spec.algo, spec.task), **spec.params}, seed=spec.seed, n_games=spec.n_games
    )
    model = experiment.build()
    assert experiment.env is not None
    n_agents = experiment.env.num_envs // experiment.n_games
    done_steps = 0
    checkpoint = path / "checkpoint.zip"
    if checkpoint.is_file():  # resume: the model, its optimizer and ValueNorm statistics, and its step counter
        model = experiment.load(checkpoint)
        done_steps = model.num_timesteps
    rows = [row for row in read_rows(evaluations_path) if row["timesteps"] <= done_steps]
    model.set_logger(configure(str(path), ["csv"]))
    evaluator = BenchmarkEvalCallback(
        experiment.make_eval_env(spec.eval_episodes),
        spec,
        evaluations_path,
        checkpoint,
        rows,
        n_agents,
        experiment.main_metric,
    )
    evaluator.resumed_at = done_steps
    remaining = spec.n_timesteps - done_steps
    if remaining > 0:
        if done_steps == 0:
            evaluator.init_callback(model)
            evaluator.evaluate()  # the curve starts at 0 steps
        experiment.learn(remaining, callbacks=[evaluator], reset_num_timesteps=done_steps == 0)
    if not rows or rows[-1]["timesteps"] < model.num_timesteps:
        evaluator.evaluate()  # final evaluation
    experiment.close()
    wall = time.time() - start
    (path / "done.json").write_text(json.dumps({"wall_s": round(wall, 1), "timesteps": model.num_timesteps}))
    if checkpoint.is_file():
        checkpoint.unlink()
    return {"spec": asdict(spec), "status": "done", "rows": rows, "wall_s": wall}


def _safe_execute(spec: RunSpec, folder: str) -> dict[str, Any]:
    try:
        return execute_run(spec, folder)
    except Exception:  # a failing run is reported, the others go on
        return {"spec": asdict(spec), "status": "failed", "rows": [], "error": traceback.format_exc()}


def run_all(specs: list[RunSpec], out: Path, jobs: int = 1, ray_address: str | None = None) -> list[dict[str, Any]]:
    """Run every spec (local processes or Ray); write each run's rows into its folder; return the results."""
    results: list[dict[str, Any]] = []
    if ray_address is not None:
        import ray

        ray.init(address=ray_address, ignore_reinit_error=True, log_to_driver=False)
        remote = ray.remote(num_cpus=1)(_safe_execute)
        pending = {}
        for spec in specs:
            local = run_folder(out, spec)
            if (local / "done.json").is_file():
                results.append({"spec": asdict(spec), "status": "skipped", "rows": read_rows(local / "evaluations.csv")})
            else:
                pending[remote.remote(spec, str(local))] = spec
        for ref in pending:
            results.append(_store(ray.get(ref), out))
    elif jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = [pool.submit(_safe_execute, spec, str(run_folder(out, spec))) for spec in specs]
            results = [_store(future.result(), out) for future in as_completed(futures)]
    else:
        results = [_store(_safe_execute(spec, str(run_folder(out, spec))), out) for spec in specs]
    return results


def _store(result: dict[str, Any], out: Path) -> dict[str, Any]:
    """Write a run's rows into its folder on the driver (they may come from another machine)."""
    spec = RunSpec(**result["spec"])
    folder = run_folder(out, spec)
    if result["rows"]:
        write_rows(folder / "evaluations.csv", result["rows"])
    if result["status"] == "done" and not (folder / "done.json").is_file():
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "done.json").write_text(json.dumps({"wall_s": round(result.get("wall_s", 0.0), 1)}))
    status = result["status"] + (f" in {result['wall_s']:.0f} s" if "wall_s" in result else "")
    print(f"{spec.name}: {status}", flush=True)
    return result


def collect(out: Path) -> list[dict[str, Any]]:
    """Every evaluation row of every run folder, written to ``runs.csv``."""
    rows = [row for path in sorted(out.glob("runs/*/*/evaluations.csv")) for row in read_rows(path)]
    if rows:
        write_rows(out / "runs.csv", rows)
    return rows


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


def table_markdown(rows: list[dict[str, Any]]) -> str:
    """The paper's Table 1 layout: methods as rows, (task, metric) as columns, mean ± std over seeds, best in bold."""
    finals = final_rows(rows)
    algos = sorted({algo for algo, _ in finals}, key=lambda a: (a == "saeir_ppo", a))
    tasks = sorted({task for _, task in finals})
    columns = [(task, *column) for task in tasks for column in TABLE_COLUMNS["grf" if task.startswith("grf") else "cn"]]
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
    """Axis label for a step count: ``0``, ``250k``, ``1.5M``."""
    if abs(value) >= 1e6:
        return f"{value / 1e6:g}M"
    if abs(value) >= 1e3:
        return f"{value / 1e3:g}k"
    return f"{value:g}"


def plot_curves(rows: list[dict[str, Any]], path: Path) -> None:
    """One panel per task: mean of the main metric over seeds per method, with a ±1 std band; x in env steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tasks = sorted({row["task"] for row in rows})
    figure, axes = plt.subplots(1, len(tasks), figsize=(5 * len(tasks), 3.6), squeeze=False)
    for axis, task in zip(axes[0], tasks):
        key, title, scale = TABLE_COLUMNS["grf" if task.startswith("grf") else "cn"][0]
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
        axis.set_title(task)
        axis.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(format_steps))
        axis.set_xlabel("env steps")
        axis.set_ylabel(title)
        axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def rliable_markdown(rows: list[dict[str, Any]], reps: int = 2000) -> str:
    """IQM of the final main metric with 95% stratified-bootstrap confidence intervals (rliable)."""
    from rliable import library as rly
    from rliable import metrics

    finals = final_rows(rows)
    lines = ["| Task | Method | IQM | 95% CI |", "|---|---|---|---|"]
    for task in sorted({task for _, task in finals}):
        key, title, scale = TABLE_COLUMNS["grf" if task.startswith("grf") else "cn"][0]
        scores = {algo: np.array([[scale * row[key]] for row in runs]) for (algo, t), runs in finals.items() if t == task}
        estimates, intervals = rly.get_interval_estimates(scores, lambda x: np.array([metrics.aggregate_iqm(x)]), reps=reps)
        for algo in sorted(scores):
            low, high = intervals[algo][:, 0]
            lines.append(f"| {task} | {algo} | {estimates[algo][0]:.2f} {title} | [{low:.2f}, {high:.2f}] |")
    return "\n".join(lines) + "\n"


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


def plot_system_entropy(run: Path, path: Path) -> None:
    """SAEIR bonus and value-softmax entropy per scale over training, from a run's ``progress.csv``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = read_rows(run / "progress.csv")
    if not rows or "rollout/intrinsic_reward_mean" not in rows[0]:
        raise ValueError(f"{run / 'progress.csv'} has no SAEIR logs (rollout/intrinsic_reward_mean).")
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(6, 5), sharex=True)
    top.plot(*numeric_series(rows, "rollout/intrinsic_reward_mean"), label="all scales")
    for key in sorted(k for k in rows[0] if k.startswith("rollout/intrinsic_reward_mean_")):
        top.plot(*numeric_series(rows, key), label=key.rsplit("_", 1)[1], alpha=0.7)
    top.set_ylabel("SAEIR bonus (unscaled)")
    top.legend(fontsize=8)
    for key in sorted(k for k in rows[0] if k.startswith("rollout/value_entropy_")):
        bottom.plot(*numeric_series(rows, key), label=key.rsplit("_", 1)[1])
    bottom.set_ylabel("value-softmax entropy")
    bottom.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(format_steps))
    bottom.set_xlabel("agent-steps")
    bottom.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def report(out: Path, use_rliable: bool = False) -> list[dict[str, Any]]:
    """Write ``runs.csv``, ``table.md``, ``curves.png`` (and ``aggregate.md``) from the run folders."""
    rows = collect(out)
    if not rows:
        print("no evaluation rows yet")
        return rows
    (out / "table.md").write_text(table_markdown(rows))
    plot_curves(rows, out / "curves.png")
    if use_rliable:
        (out / "aggregate.md").write_text(rliable_markdown(rows))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sb3_saeir.benchmark", description=__doc__.split("\n")[0])
    parser.add_argument("--algos", nargs="+", default=["saeir_ppo", "mappo"], help=f"methods: {', '.join(sorted(ALGOS))}")
    parser.add_argument("--tasks", nargs="+", default=["cn-sparse-n3"])
    parser.add_argument("--seeds", default="1-3", help="e.g. 1-5 or 1,3,7")
    parser.add_argument("-n", "--n-timesteps", type=int, default=1_000_000, help="agent-steps per run")
    parser.add_argument("--n-games", type=int, default=None, help="override the configs' n_envs (games)")
    parser.add_argument("--eval-freq", type=int, default=50_000, help="agent-steps between evaluations")
    parser.add_argument("--eval-episodes", type=int, default=20, help="game episodes per evaluation")
    parser.add_argument("-params", "--hyperparams", dest="params", nargs="+", default=None, help="overrides key:value")
    parser.add_argument("--jobs", type=int, default=1, help="parallel local processes")
    parser.add_argument("--ray-address", default=None, help="run on a Ray cluster (e.g. 'auto' or host:port)")
    parser.add_argument("--out", default="benchmark", help="output folder")
    parser.add_argument("--rliable", action="store_true", help="also write aggregate.md (IQM, bootstrap CIs)")
    parser.add_argument("--report-only", action="store_true", help="rebuild runs.csv/table/curves without training")
    parser.add_argument("--entropy-plot", default=None, help="RUN_FOLDER: plot the SAEIR bonus and value entropy")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if args.entropy_plot:
        plot_system_entropy(Path(args.entropy_plot), Path(args.entropy_plot) / "system_entropy.png")
        print(f"wrote {Path(args.entropy_plot) / 'system_entropy.png'}")
        return 0
    unknown = [algo for algo in args.algos if algo not in ALGOS]
    if unknown:
        print(f"sb3_saeir.benchmark: error: unknown methods {unknown}; valid: {', '.join(sorted(ALGOS))}", file=sys.stderr)
        return 2
    from sb3_saeir.envs import list_tasks

    unknown = [task for task in args.tasks if task not in list_tasks()]
    if unknown:
        print(f"sb3_saeir.benchmark: error: unknown tasks {unknown}; valid: {', '.join(list_tasks())}", file=sys.stderr)
        return 2
    try:
        params = parse_params(args.params)
        for algo in args.algos:
            for task in args.tasks:
                check_hyperparams(algo, load_hyperparams(algo, task), params)
    except (ConfigError, KeyError) as error:
        print(f"sb3_saeir.benchmark: error: {error.args[0] if isinstance(error, KeyError) else error}", file=sys.stderr)
        return 2
    specs = [
        RunSpec(algo, task, seed, args.n_timesteps, args.n_games, args.eval_freq, args.eval_episodes, params)
        for task in args.tasks
        for algo in args.algos
        for seed in parse_seeds(args.seeds)
    ]
    out.mkdir(parents=True, exist_ok=True)
    failures: list[str] = []
    if not args.report_only:
        start = time.time()
        results = run_all(specs, out, args.jobs, args.ray_address)
        failures = [f"{RunSpec(**r['spec']).name}\n{r['error']}" for r in results if r["status"] == "failed"]
        (out / "failures.txt").write_text("\n".join(failures))
        print(f"{len(specs)} runs ({len(failures)} failed) in {time.time() - start:.0f} s")
    report(out, args.rliable)
    print(f"results in {out}: runs.csv, table.md, curves.png" + (", aggregate.md" if args.rliable else ""))
    return 1 if failures else 0


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
