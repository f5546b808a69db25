"""Running the benchmark's runs: one run in its folder (train, evaluate on the grid, checkpoint, resume), and many
runs in local worker processes or on a Ray cluster, with Ctrl-C stopping them all.
"""

from __future__ import annotations

import json
import signal
import sys
import traceback
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict
from pathlib import Path
from typing import Any

from sb3_saeir.benchmark.runs import (
    CHECKPOINT_FILE,
    MODEL_FILE,
    RunLog,
    RunSpec,
    ensure_spec_file,
    read_rows,
    run_folder,
    same_row,
    spec_record,
    write_rows,
)
from sb3_saeir.common.atomic import atomic_write_text, keep_damaged, save_model
from sb3_saeir.common.run_state import (
    RunCheckpointCallback,
    SegmentClock,
    checkpoint_problem,
    describe_resume,
    is_exact,
    progress_logger,
)
from sb3_saeir.evaluation import MultiAgentEvalCallback


class BenchmarkEvalCallback(MultiAgentEvalCallback):
    """The benchmark's evaluations.

    Evaluations happen at the first agent-step count >= k * ``eval_freq`` (on the grid whether or not the run was
    resumed), each on the same episodes (the eval env is reseeded with ``eval_seed`` first), and each becomes a row of
    the run's ``evaluations.csv``. (The run's checkpoints are a
    :class:`~sb3_saeir.common.run_state.RunCheckpointCallback` beside it.)

    :param eval_env: the evaluation env
    :param spec: the run
    :param evaluations_path: the run's ``evaluations.csv``
    :param rows: evaluation rows already recorded (kept on resume)
    :param n_agents: agents per game (``env_steps = agent-steps / n_agents``)
    :param main_metric: the task's main metric
    :param eval_seed: seed given to the eval env before every evaluation (``None``: not reseeded)
    :param lost_rows: rows made after the checkpoint by the interrupted segment, by agent-steps: they are re-done
    :param clock: the run's wall-time record
    :param log: where resume messages go
    """

    def __init__(
        self,
        eval_env: Any,
        spec: RunSpec,
        evaluations_path: Path,
        rows: list[dict[str, Any]],
        n_agents: int,
        main_metric: str,
        eval_seed: int | None = None,
        lost_rows: dict[int, dict[str, Any]] | None = None,
        clock: SegmentClock | None = None,
        log: Callable[[str], None] = print,
    ) -> None:
        super().__init__(eval_env, spec.eval_episodes, spec.eval_freq, main_metric=main_metric, verbose=0)
        self.spec = spec
        self.evaluations_path = evaluations_path
        self.rows = rows
        self.n_agents = n_agents
        self.eval_seed = eval_seed
        self.lost_rows = dict(lost_rows or {})
        self.clock = clock
        self.log = log
        self.last_eval_timestep = int(rows[-1]["timesteps"]) if rows else 0
        self.next_eval = self.grid_after(self.last_eval_timestep) if rows else 0

    def grid_after(self, steps: int) -> int:
        """The first multiple of ``eval_freq`` after ``steps`` agent-steps."""
        return (steps // self.eval_freq + 1) * self.eval_freq if self.eval_freq > 0 else sys.maxsize

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_eval:
            self.last_eval_timestep = self.num_timesteps
            return self.evaluate()
        return True

    def evaluate(self) -> bool:
        self.num_timesteps = self.model.num_timesteps
        if self.eval_seed is not None:  # every evaluation plays the same episodes
            self.eval_env.seed(self.eval_seed)
        keep_going = super().evaluate()
        spec = self.spec
        row: dict[str, Any] = {"algo": spec.algo, "task": spec.task, "seed": spec.seed, "timesteps": self.num_timesteps}
        row["env_steps"] = self.num_timesteps // self.n_agents
        row.update({key: value for key, value in self.last_summary.items() if not key.endswith("_std")})
        row.update({key: value for key, value in self.last_summary.items() if key.endswith("_std")})
        self.next_eval = self.grid_after(self.num_timesteps)
        lost = self.lost_rows.pop(self.num_timesteps, None)
        if lost is not None:
            outcome = "identical to" if same_row(row, lost) else "different from"
            self.log(f"evaluation at {self.num_timesteps} agent-steps re-done: {outcome} the interrupted segment's")
        self.rows.append(row)
        write_rows(self.evaluations_path, self.rows)
        if self.clock is not None:
            self.clock.tick(self.num_timesteps)
        return keep_going


def _open_checkpoint(experiment: Any, checkpoint: Path, log: Callable[[str], None]) -> tuple[Any, dict | None]:
    """Load the model of a checkpoint onto the experiment's env, and its resume state; say in the log when the
    resumption can only be approximate (no resume state, or an env that cannot save its state).

    :param experiment: the run's built :class:`~sb3_saeir.experiment.Experiment`
    :param checkpoint: ``checkpoint.zip``
    :param log: the run's log
    :return: the model and the resume state
    """
    state = experiment.resume(checkpoint)
    model = experiment.model
    log(f"resumed from the checkpoint at {model.num_timesteps} agent-steps")
    for message in describe_resume(model, state):
        log(message)
    return model, state


def _damaged_checkpoint(checkpoint: Path, log: Callable[[str], None]) -> bool:
    """Whether the run's checkpoint does not load (cut short or damaged); if so it is moved aside to
    ``checkpoint.zip.damaged-<UTC time>`` (nothing deleted) and the run starts over, as a run with no checkpoint
    does, saying so in its log.

    :param checkpoint: the run's ``checkpoint.zip``
    :param log: the run's log
    """
    problem = checkpoint_problem(checkpoint)
    if not problem:
        return False
    kept = keep_damaged(checkpoint)
    checkpoint.unlink()
    log(f"{checkpoint.name} does not load ({problem}): kept as {kept.name}; the run starts over from the beginning")
    return True


def execute_run(spec: RunSpec, folder: str, num_threads: int = 1) -> dict[str, Any]:
    """Train and evaluate one run in ``folder`` (resuming from its checkpoint); returns its evaluation rows.

    Runs in this process or a worker process (local or Ray).

    :param num_threads: torch threads (1, for runs side by side; 2 for one run with its games in 2 env workers, whose
        update then has the cores the workers leave idle). Not one of the run's settings, though a change can move the
        last bits of float sums.

    :raises ValueError: when the folder holds a run made with other settings
    """
    import torch as th

    from sb3_saeir.experiment import EVAL_SEED_OFFSET, Experiment

    th.set_num_threads(num_threads)
    path = Path(folder)
    record = spec_record(spec)
    ensure_spec_file(path, record)
    evaluations_path = path / "evaluations.csv"
    if (path / "done.json").is_file():
        return {"spec": asdict(spec), "status": "skipped", "rows": read_rows(evaluations_path)}
    log = RunLog(path, spec.name)
    config = spec.resolved_config()  # as given (spec.json holds its JSON form)
    experiment = Experiment(spec.algo, spec.task, config, seed=spec.seed, n_games=spec.n_games)
    model = experiment.build()
    assert experiment.env is not None
    n_agents = experiment.env.num_envs // experiment.n_games
    checkpoint = path / CHECKPOINT_FILE
    state = None
    resumed = checkpoint.is_file() and not _damaged_checkpoint(checkpoint, log)
    if resumed:  # the model, its optimizer and ValueNorm statistics, its step counter; the rest at the next rollout
        model, state = _open_checkpoint(experiment, checkpoint, log)
    done_steps = model.num_timesteps if resumed else 0
    clock = SegmentClock(path / "segments.json", done_steps)
    rows, lost = _split_rows(evaluations_path, done_steps if resumed else None, log)
    rollout = int(getattr(model, "n_steps", 1)) * experiment.env.num_envs
    expected_rows = state.get("progress_rows") if state is not None else None
    model.set_logger(progress_logger(path, done_steps if resumed else None, done_steps // rollout, None, expected_rows, log))
    checkpoints = RunCheckpointCallback(
        path,
        CHECKPOINT_FILE,
        resumed_at=done_steps,
        resume_state=state,
        previous_wall_s=clock.previous_s,
        on_checkpoint=clock.tick,
        log=log,
    )
    evaluator = BenchmarkEvalCallback(
        experiment.make_eval_env(spec.eval_episodes, seed=EVAL_SEED_OFFSET + spec.seed),
        spec,
        evaluations_path,
        rows,
        n_agents,
        experiment.main_metric,
        eval_seed=EVAL_SEED_OFFSET + spec.seed,
        lost_rows=lost,
        clock=clock,
        log=log,
    )
    if resumed and not is_exact(model, state):  # approximate: learn() resets the env and the recurrent states
        model._last_obs = None  # type: ignore[assignment]
    remaining = spec.n_timesteps - done_steps
    if remaining > 0:
        if not resumed:
            evaluator.init_callback(model)
            evaluator.evaluate()  # the curve starts at 0 steps
        experiment.learn(remaining, callbacks=[checkpoints, evaluator], reset_num_timesteps=not resumed)
    if not rows or rows[-1]["timesteps"] < model.num_timesteps:
        evaluator.init_callback(model)
        evaluator.evaluate()  # final evaluation
    experiment.close()
    _finish(path, clock, model)
    return {"spec": asdict(spec), "status": "done", "rows": rows, "wall_s": clock.total_s}


def _split_rows(
    path: Path, done_steps: int | None, log: Callable[[str], None]
) -> tuple[list[dict[str, Any]], dict[int, dict[str, Any]]]:
    """The evaluation rows a run keeps (made up to its checkpoint) and those it re-does (made after it, by a segment
    that was interrupted), by agent-steps; ``evaluations.csv`` is rewritten with the kept rows.

    :param path: the run's ``evaluations.csv``
    :param done_steps: agent-steps of the checkpoint, ``None`` for a fresh start (every row is re-done)
    :param log: the run's log
    """
    old_rows = read_rows(path)
    rows = [row for row in old_rows if done_steps is not None and row["timesteps"] <= done_steps]
    lost = {int(row["timesteps"]): row for row in old_rows if done_steps is None or row["timesteps"] > done_steps}
    if lost:
        since = "the start" if done_steps is None else "the checkpoint"
        log(f"evaluations made after {since}, at {sorted(lost)} agent-steps, are re-done")
    write_rows(path, rows)
    return rows, lost


def _finish(path: Path, clock: SegmentClock, model: Any) -> None:
    """Save the final model (``model.zip``, atomically), write ``done.json`` (total wall time over the segments) and
    remove the checkpoint."""
    timesteps = model.num_timesteps
    save_model(model, path / MODEL_FILE)
    clock.tick(timesteps)
    summary = {"wall_s": round(clock.total_s, 1), "segments": len(clock.segments), "timesteps": timesteps}
    atomic_write_text(path / "done.json", json.dumps(summary))
    (path / CHECKPOINT_FILE).unlink(missing_ok=True)


def _safe_execute(spec: RunSpec, folder: str, num_threads: int = 1) -> dict[str, Any]:
    try:
        return execute_run(spec, folder, num_threads)
    except Exception:  # a failing run is reported, the others go on
        return {"spec": asdict(spec), "status": "failed", "rows": [], "error": traceback.format_exc()}


def _ignore_sigint() -> None:
    """Worker processes leave Ctrl-C to the driver, which stops them."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel the jobs not started and end the running ones (their checkpoints are whole: they resume)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(timeout=10)


def run_all(
    specs: list[RunSpec], out: Path, jobs: int = 1, ray_address: str | None = None, num_threads: int = 1
) -> list[dict[str, Any]]:
    """Run every spec (local processes or Ray); write each run's rows into its folder; return the results.

    :param num_threads: torch threads of each run (see :func:`execute_run`)

    Ctrl-C (``KeyboardInterrupt``) stops every job (local worker processes are terminated, Ray tasks cancelled) and
    is raised again.
    """
    results: list[dict[str, Any]] = []
    if ray_address is not None:
        results = _run_on_ray(specs, out, ray_address, num_threads)
    elif jobs > 1:
        pool = ProcessPoolExecutor(max_workers=jobs, initializer=_ignore_sigint)
        try:
            futures = [pool.submit(_safe_execute, spec, str(run_folder(out, spec)), num_threads) for spec in specs]
            results = [_store(future.result(), out) for future in as_completed(futures)]
        except BaseException:
            _stop_pool(pool)
            raise
        pool.shutdown()
    else:
        results = [_store(_safe_execute(spec, str(run_folder(out, spec)), num_threads), out) for spec in specs]
    return results


def _run_on_ray(specs: list[RunSpec], out: Path, ray_address: str, num_threads: int = 1) -> list[dict[str, Any]]:
    import ray

    ray.init(address=ray_address, ignore_reinit_error=True, log_to_driver=False)
    remote = ray.remote(num_cpus=num_threads)(_safe_execute)
    results = []
    pending = {}
    for spec in specs:
        local = run_folder(out, spec)
        if (local / "done.json").is_file():
            results.append({"spec": asdict(spec), "status": "skipped", "rows": read_rows(local / "evaluations.csv")})
        else:
            pending[remote.remote(spec, str(local), num_threads)] = spec
    try:
        for ref in pending:
            results.append(_store(ray.get(ref), out))
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref, force=True)
        raise
    return results


def _store(result: dict[str, Any], out: Path) -> dict[str, Any]:
    """Write a run's rows into its folder on the driver (they may come from another machine)."""
    spec = RunSpec(**result["spec"])
    folder = run_folder(out, spec)
    if result["rows"]:
        write_rows(folder / "evaluations.csv", result["rows"])
    if result["status"] == "done" and not (folder / "done.json").is_file():
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write_text(folder / "done.json", json.dumps({"wall_s": round(result.get("wall_s", 0.0), 1)}))
    status = result["status"] + (f" in {result['wall_s']:.0f} s" if "wall_s" in result else "")
    print(f"{spec.name}: {status}", flush=True)
    return result
