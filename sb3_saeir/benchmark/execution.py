"""Running the benchmark's runs: one run in the folder it takes (a :class:`~sb3_saeir.run.run.Run` in a
:class:`~sb3_saeir.run.folder.RunFolder`), and many runs in local worker processes or on a Ray cluster, with Ctrl-C
stopping them all.
"""

from __future__ import annotations

import os
import signal
import threading
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict
from pathlib import Path
from typing import Any

from sb3_saeir.benchmark.runs import run_folder
from sb3_saeir.run.files import DONE_FILE, EVALUATIONS_FILE
from sb3_saeir.run.folder import RunFolder
from sb3_saeir.run.record import RunSpec, is_finished, read_rows, read_spec_file, write_done_file, write_rows
from sb3_saeir.run.run import Run

# The benchmark checkpoints at every rollout start and keeps the newest two (one to fall back to).
KEEP_CHECKPOINTS = 2
# How the benchmark goes on with a copy of a run folder it cannot write (check_run_folder_writable's fix).
RERUN_COPY = "give the copy's benchmark folder as --out"


def execute_run(spec: RunSpec, folder: str, num_threads: int = 1) -> dict[str, Any]:
    """Train and evaluate one run in ``folder`` (resuming from its newest checkpoint that loads; a finished run is
    skipped unless ``spec`` raises its budget); returns its evaluation rows and, when it finished, its ``done.json``
    record (``"done"``: a driver on another machine writes it).

    Runs in this process or a worker process (local or Ray).

    :param num_threads: torch threads (1, for runs side by side; 2 for one run with its games in 2 env workers, whose
        update then has the cores the workers leave idle). Not one of the run's settings, though a change can move the
        last bits of float sums.

    :raises ValueError: when the folder holds a run made with other settings
    :raises ~sb3_saeir.config.ConfigError: when a run that goes on cannot write its folder
    """
    import torch as th

    from sb3_saeir.experiment import Experiment

    th.set_num_threads(num_threads)
    with RunFolder.take(Path(folder), spec, RERUN_COPY) as taken:
        if taken.finished:
            return {"spec": asdict(spec), "status": "skipped", "rows": read_rows(taken.path / EVALUATIONS_FILE)}
        run = Run(spec, save_freq=0, keep_checkpoints=KEEP_CHECKPOINTS, name=spec.name)
        experiment = Experiment(spec.algo, spec.task, spec.resolved_config(), seed=spec.seed, n_games=spec.n_games)
        run.execute(taken, experiment)
    assert run.evaluator is not None and run.clock is not None
    return {"spec": asdict(spec), "status": "done", "rows": run.evaluator.rows, "wall_s": run.clock.total_s, "done": run.done}


def _safe_execute(spec: RunSpec, folder: str, num_threads: int = 1) -> dict[str, Any]:
    try:
        return execute_run(spec, folder, num_threads)
    except Exception:  # a failing run is reported, the others go on
        return {"spec": asdict(spec), "status": "failed", "rows": [], "error": traceback.format_exc()}


# Seconds between a worker process's checks that its driver is alive.
DRIVER_CHECK_PERIOD_S = 0.5


def _init_worker(driver_pid: int) -> None:
    """A worker process leaves Ctrl-C to the driver, which stops it, and ends when the driver is gone, however the
    driver ended (SIGKILL included): a job never trains on for a driver that cannot take its result, holding its run
    folder's lock. The run resumes from its newest checkpoint (one at every rollout start).

    :param driver_pid: the driver's process id
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for signum in (signal.SIGTERM, signal.SIGHUP):  # the driver's handlers (forked with it) are the driver's own
        signal.signal(signum, signal.SIG_DFL)
    threading.Thread(target=_end_with_driver, args=(driver_pid,), name="end-with-driver", daemon=True).start()


def _end_with_driver(driver_pid: int) -> None:
    """End this process (SIGTERM to itself) once its parent is no longer ``driver_pid``: the driver died and the
    process was handed to another parent."""
    while os.getppid() == driver_pid:
        time.sleep(DRIVER_CHECK_PERIOD_S)
    os.kill(os.getpid(), signal.SIGTERM)


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

    Ctrl-C, SIGTERM or SIGHUP (``KeyboardInterrupt``) stops every job (local worker processes are terminated, Ray
    tasks cancelled; each run resumes from its newest checkpoint, written at every rollout start) and is raised again.
    """
    results: list[dict[str, Any]] = []
    if ray_address is not None:
        results = _run_on_ray(specs, out, ray_address, num_threads)
    elif jobs > 1:
        pool = ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker, initargs=(os.getpid(),))
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
        if is_finished(local, read_spec_file(local), spec.n_timesteps):
            results.append({"spec": asdict(spec), "status": "skipped", "rows": read_rows(local / EVALUATIONS_FILE)})
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
    """Write a run's rows and ``done.json`` (the record the run returned) into its folder on the driver: they may
    come from another machine."""
    spec = RunSpec(**result["spec"])
    folder = run_folder(out, spec)
    if result["rows"]:
        write_rows(folder / EVALUATIONS_FILE, result["rows"])
    if result.get("done") is not None and not (folder / DONE_FILE).is_file():
        write_done_file(folder, result["done"])
    status = result["status"] + (f" in {result['wall_s']:.0f} s" if "wall_s" in result else "")
    print(f"{spec.name}: {status}", flush=True)
    return result
