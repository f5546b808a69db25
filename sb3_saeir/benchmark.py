"""Benchmark runner: methods x tasks x seeds -> ``runs.csv``, the paper's Table 1 layout and learning curves.

    python -m sb3_saeir.benchmark --algos saeir_ppo mappo --tasks cn-sparse-n3 --seeds 1-3 \\
        --n-timesteps 1000000 --n-games 16 --eval-freq 50000 --eval-episodes 50 --jobs 2 --out results/cn3

Each run trains with the packaged config of its method (``zoo_configs/<algo>.yml``; ``--n-games`` and ``-params``
override it) and evaluates at 0 agent-steps, at the first agent-step count >= k * ``--eval-freq`` (k = 1, 2, ...)
and at the end, on game episodes. Every evaluation reseeds the evaluation env with the same seed (``10_000 + seed``)
before it starts, so every evaluation of a run plays the same ``--eval-episodes`` episodes. Output folder:

- ``runs/<algo>/<task>_s<seed>/``: ``spec.json`` (the run's settings: algo, task, seed, n_timesteps, n_games,
  eval_freq, eval_episodes, params, the config entry it trains with, the package version), ``evaluations.csv`` (one
  row per evaluation), ``progress.csv`` (SB3 logger, continued over resumes), ``checkpoint.zip`` (latest, for
  resuming), ``segments.json`` (wall time of each process that worked on the run), ``resume.log`` (what each resume
  did), ``done.json`` and ``model.zip`` (when finished: total wall time over the segments, agent-steps; the final
  model, for ``enjoy`` or ``benchmarks/bonus_readings.py``);
- ``runs.csv``: every evaluation row of the command's runs (algo, task, seed, agent-steps, env steps, metrics);
- ``table.md``: mean ± std over seeds at the final evaluation, best method in bold (the paper's Table 1 layout);
- ``curves.png``: one panel per task, mean line and std band per method, x axis in env steps (game steps);
- ``aggregate.md`` with ``--rliable``: IQM and 95% stratified-bootstrap confidence intervals of the final main metric
  (the bootstrap is seeded: reporting the same runs again writes the same intervals), then every pair of methods: the
  difference of the means, how often one ends above the other over the pairs of seeds, and the two-sided Mann-Whitney
  U test's p-value, to tell which differences are larger than the seed spread.

**Settings are never mixed.** Before any training the command compares every planned run with the ``spec.json`` of
its folder; when one differs (another ``-n``, ``-params``, ``--n-games``, ``--eval-freq``, ``--eval-episodes``, or
an edited config), it refuses with one line per run naming what differs, and exit status 2: use another ``--out``,
or ``--rerun-changed`` to move those folders aside (``<folder>.replaced-<UTC time>``, nothing is deleted) and train
them again. A larger ``-n`` is a different run too, not an extension: learning-rate and clip schedules depend on the
total budget, the shorter run's final (off-grid) evaluation would sit in the curve, and a finished run keeps no
checkpoint. ``runs.csv``, ``table.md`` and ``curves.png`` hold only runs whose spec matches the command.

**Resuming loses nothing.** Re-running the same command skips finished runs and resumes interrupted ones from their
checkpoint, taken at the start of every rollout after the first. ``checkpoint.zip`` is the SB3 model zip with one
more entry, ``resume_state.pkl``: the torch, NumPy and ``random`` generator states, the model's last observations,
episode starts and GRU states, its episode-info buffers, the training env's state (the native navigation env's
``get_resume_state``: arrays and per-game generators), the intrinsic-reward callbacks (RND, Elign: networks,
optimisers, running statistics) and the logger's values not yet written. It is written to a temporary file and moved
into place with ``os.replace``, so a kill during a save leaves the previous checkpoint whole. A run killed at any
moment (even SIGKILL) and re-run ends with the same ``runs.csv`` rows as an uninterrupted run of the same seed.
Envs without ``get_resume_state`` (SuperSuit-backed tasks) resume approximately: the training env restarts from a
reset, and ``resume.log`` says so. On resume ``progress.csv`` keeps its rows up to the checkpoint and goes on;
evaluations made after the checkpoint are re-done (``resume.log`` says whether each came out identical); ``wall_s``
in ``done.json`` sums the segments (each counted up to its last checkpoint or evaluation). Ctrl-C stops every job
and prints "interrupted: re-run the same command to resume" (exit status 130).

A failing run is reported in ``failures.txt`` and does not stop the others. ``--ray-address`` runs them on a Ray
cluster instead of local processes (results gathered into the same folder; resuming from checkpoints needs a shared
filesystem). ``--entropy-plot RUN_FOLDER`` draws the SAEIR bonus, its fire rate and the value-softmax entropy over training for
one run (``system_entropy.png`` in the run's folder) and prints the fire rate and entropy per scale.
"""

from __future__ import annotations

import argparse
import csv
import io
import itertools
import json
import math
import os
import random
import re
import signal
import sys
import time
import traceback
import zipfile
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import cloudpickle
import numpy as np
from stable_baselines3.common.logger import CSVOutputFormat, KVWriter, Logger

from sb3_saeir.common.extras import MissingExtraError, require_extra
from sb3_saeir.config import (
    ALGOS,
    ConfigError,
    OneLineParser,
    check_folder,
    check_hyperparams,
    count,
    load_hyperparams,
    parse_params,
)
from sb3_saeir.evaluation import MultiAgentEvalCallback

# Columns of the paper's Table 1 per task family: (metric key in runs.csv, header, scale)
TABLE_COLUMNS = {
    "cn": [("coverage_rate_mean", "Coverage %", 100.0), ("ep_rew_mean", "Ep. reward", 1.0)],
    "grf": [("success_mean", "Success %", 100.0), ("ep_rew_mean", "Ep. reward", 1.0)],
}
# The line Ctrl-C ends with (exit status 130).
INTERRUPTED = "interrupted: re-run the same command to resume"
# Files of a run folder.
SPEC_FILE = "spec.json"
CHECKPOINT_FILE = "checkpoint.zip"
MODEL_FILE = "model.zip"
# The entry of checkpoint.zip that holds the resume state (SB3's load ignores it).
RESUME_ENTRY = "resume_state.pkl"
RESUME_FORMAT = 1
# Settings compared with a run's spec.json, by their command-line names.
SPEC_SETTINGS = {
    "n_timesteps": "-n",
    "n_games": "--n-games",
    "eval_freq": "--eval-freq",
    "eval_episodes": "--eval-episodes",
    "params": "-params",
}
# Model attributes that determine the next rollout and are not (or not reliably) in SB3's zip.
MODEL_RESUME_ATTRIBUTES = (
    "_last_obs",
    "_last_episode_starts",
    "_last_original_obs",
    "_last_states",
    "ep_info_buffer",
    "ep_success_buffer",
    "_episode_num",
    "_num_timesteps_at_start",
)
# Callback attributes that are links to the model or per-call data, not state of the callback.
CALLBACK_LINKS = ("model", "parent", "locals", "globals", "training_env")
# Per-rollout data that a callback clears at every rollout start.
CALLBACK_TRANSIENT = ("next_observations",)


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
    """``"1-5"`` -> [1, 2, 3, 4, 5]; ``"1,3,7"`` -> [1, 3, 7].

    :raises ~sb3_saeir.config.ConfigError: on a part that is not a seed or an increasing range, a repeated seed, or no seed
    """
    seeds: list[int] = []
    for part in text.split(","):
        if not part.strip():
            continue
        match = re.fullmatch(r"\s*(-?\d+)\s*(?:-\s*(-?\d+)\s*)?", part)
        if match is None:
            raise ConfigError(f"--seeds {text!r}: {part.strip()!r} is not a seed or a range like 1-5.")
        low, high = int(match[1]), int(match[2]) if match[2] is not None else int(match[1])
        if high < low:
            raise ConfigError(f"--seeds {text!r}: the range {part.strip()} is empty (write it low-high, e.g. {high}-{low}).")
        seeds.extend(range(low, high + 1))
    if not seeds:
        raise ConfigError(f"--seeds {text!r} gives no seed; e.g. --seeds 1-3 or --seeds 1,3,7.")
    repeated = sorted({seed for seed in seeds if seeds.count(seed) > 1})
    if repeated:
        raise ConfigError(f"--seeds {text!r} gives seed(s) {repeated} more than once: give each seed once.")
    return seeds


def run_folder(out: Path, spec: RunSpec) -> Path:
    return out / "runs" / spec.algo / f"{spec.task}_s{spec.seed}"


# ---------------------------------------------------------------------------------------------------- files
def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``path`` through a temporary file moved into place: a kill leaves the old file or the new one.

    :param path: the file
    :param data: its new content
    """
    temp = path.with_name(f".{path.name}.tmp")
    temp.write_bytes(data)
    os.replace(temp, path)


def atomic_write_text(path: Path, text: str) -> None:
    """:func:`atomic_write_bytes` for text (UTF-8)."""
    atomic_write_bytes(path, text.encode())


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
    """Write rows as CSV (atomically: a kill during the write leaves the previous file)."""
    keys = list(dict.fromkeys(key for row in rows for key in row))
    path.parent.mkdir(parents=True, exist_ok=True)
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=keys)
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_text(path, text.getvalue())


def utc_stamp() -> str:
    """The current UTC time, ``20250131T235959Z``."""
    return datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")


# ---------------------------------------------------------------------------------------------------- run specs
def _jsonable(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples become lists, unknown objects their ``str``)."""
    return json.loads(json.dumps(value, sort_keys=True, default=str))


def spec_record(spec: RunSpec) -> dict[str, Any]:
    """What a run's ``spec.json`` holds: its settings, the config entry it trains with, the package version."""
    from sb3_saeir import __version__

    config = {**load_hyperparams(spec.algo, spec.task), **spec.params}
    return _jsonable({**asdict(spec), "config": config, "version": __version__})


def _show(value: Any) -> str:
    return "(unset)" if value is None else json.dumps(value, sort_keys=True)


def spec_differences(stored: dict[str, Any], planned: dict[str, Any]) -> list[str]:
    """What differs between a run's stored ``spec.json`` and the planned run, as ``"<setting> <old> -> <new>"``.

    The package version is recorded, not compared. Config keys set by ``-params`` are reported once, as ``-params``.

    :param stored: the content of ``spec.json``
    :param planned: :func:`spec_record` of the planned run
    """
    differences = [
        f"{key} {_show(stored.get(key))} -> {_show(planned[key])}"
        for key in ("algo", "task", "seed")
        if stored.get(key) != planned[key]
    ]
    differences += [
        f"{flag} {_show(stored.get(key))} -> {_show(planned[key])}"
        for key, flag in SPEC_SETTINGS.items()
        if stored.get(key) != planned[key]
    ]
    old_config, new_config = stored.get("config") or {}, planned["config"]
    overridden = set(stored.get("params") or {}) | set(planned["params"])
    differences += [
        f"config {key} {_show(old_config.get(key))} -> {_show(new_config.get(key))}"
        for key in sorted((set(old_config) | set(new_config)) - overridden)
        if old_config.get(key) != new_config.get(key)
    ]
    return differences


def stored_spec_differences(folder: Path, record: dict[str, Any]) -> list[str]:
    """Why the run in ``folder`` cannot be continued or reported with the settings ``record`` (empty: it can, or the
    folder holds nothing yet).

    :param folder: the run's folder
    :param record: :func:`spec_record` of the planned run
    """
    spec_path = folder / SPEC_FILE
    if spec_path.is_file():
        try:
            stored = json.loads(spec_path.read_text())
        except json.JSONDecodeError:
            return [f"{SPEC_FILE} is unreadable"]
        return spec_differences(stored, record)
    if folder.is_dir() and any(folder.iterdir()):
        return [f"no {SPEC_FILE} (made by an older version): its settings are unknown"]
    return []


def ensure_spec_file(folder: Path, record: dict[str, Any]) -> None:
    """Write the run's ``spec.json`` unless it is there; refuse a folder made with other settings.

    :param folder: the run's folder
    :param record: :func:`spec_record` of the run
    :raises ValueError: naming what differs
    """
    differences = stored_spec_differences(folder, record)
    if differences:
        raise ValueError(f"{folder} holds a run made with other settings: {'; '.join(differences)}.")
    if not (folder / SPEC_FILE).is_file():
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write_text(folder / SPEC_FILE, json.dumps(record, indent=2, sort_keys=True) + "\n")


def move_aside(folder: Path) -> Path:
    """Rename a run folder to ``<folder>.replaced-<UTC time>`` (nothing is deleted); returns the new path."""
    target = folder.with_name(f"{folder.name}.replaced-{utc_stamp()}")
    number = 1
    while target.exists():
        number += 1
        target = folder.with_name(f"{folder.name}.replaced-{utc_stamp()}-{number}")
    os.rename(folder, target)
    return target


# ---------------------------------------------------------------------------------------------------- resume state
def rng_states() -> dict[str, Any]:
    """The torch, NumPy-global and Python ``random`` generator states (and CUDA's when available)."""
    import torch as th

    states: dict[str, Any] = {"torch": th.get_rng_state(), "numpy": np.random.get_state(), "random": random.getstate()}
    if th.cuda.is_available():
        states["cuda"] = th.cuda.get_rng_state_all()
    return states


def set_rng_states(states: dict[str, Any]) -> None:
    """Restore generator states from :func:`rng_states`."""
    import torch as th

    th.set_rng_state(states["torch"])
    np.random.set_state(states["numpy"])
    random.setstate(states["random"])
    if "cuda" in states and th.cuda.is_available():
        th.cuda.set_rng_state_all(states["cuda"])


def resumable_env(env: Any) -> Any | None:
    """The training env if it can save and restore its exact state (``get_resume_state``), else ``None``.

    SB3 ``VecEnvWrapper`` objects forward attribute look-ups to the env they wrap but keep state of their own, so a wrapped
    env counts as not resumable.
    """
    from stable_baselines3.common.vec_env import VecEnvWrapper

    if env is None or isinstance(env, VecEnvWrapper) or not callable(getattr(env, "get_resume_state", None)):
        return None
    return env


def callback_state(callback: Any) -> dict[str, Any]:
    """The state of a callback: its attributes but the links to the model and per-rollout data."""
    skipped = (*CALLBACK_LINKS, *CALLBACK_TRANSIENT)
    return {
        "class": type(callback).__qualname__,
        "attributes": {key: value for key, value in vars(callback).items() if key not in skipped},
    }


def capture_resume_state(model: Any) -> dict[str, Any]:
    """Everything besides the model zip that determines the rest of a run, at the start of a rollout.

    :param model: a MAPPO / SAEIR_PPO model in ``learn``
    :return: the resume state (pickled with cloudpickle into ``checkpoint.zip``)
    """
    env = resumable_env(model.get_env())
    logger = model.logger
    return {
        "format": RESUME_FORMAT,
        "num_timesteps": model.num_timesteps,
        "rng": rng_states(),
        "model": {name: getattr(model, name) for name in MODEL_RESUME_ATTRIBUTES if hasattr(model, name)},
        "env": env.get_resume_state() if env is not None else None,
        "env_type": type(model.get_env()).__name__,
        "callbacks": [callback_state(callback) for callback in getattr(model, "_intrinsic_rewards", [])],
        "logger": {
            "name_to_value": dict(logger.name_to_value),
            "name_to_count": dict(logger.name_to_count),
            "name_to_excluded": dict(logger.name_to_excluded),
        },
    }


def restore_resume_state(model: Any, state: dict[str, Any], log: Callable[[str], None]) -> None:
    """Put a resumed model, its env, its intrinsic-reward callbacks and its logger back in the state of the moment
    the checkpoint was taken (call it at the same point: the start of the first rollout after resuming).

    Without an env state (the env has no ``get_resume_state``), the env and the recurrent states keep the fresh start
    that ``learn`` gave them: an approximate resume.

    :param model: the model loaded from the checkpoint, in ``learn``
    :param state: the resume state of the checkpoint
    :param log: where to say what could not be restored
    """
    env = resumable_env(model.get_env())
    exact = state["env"] is not None and env is not None
    if env is not None and exact:
        env.set_resume_state(state["env"])
    for name, value in state["model"].items():
        if exact or name not in ("_last_obs", "_last_episode_starts", "_last_original_obs", "_last_states"):
            setattr(model, name, value)
    callbacks = list(getattr(model, "_intrinsic_rewards", []))
    saved = state["callbacks"]
    if [type(c).__qualname__ for c in callbacks] != [s["class"] for s in saved]:
        log(f"intrinsic rewards {[s['class'] for s in saved]} in the checkpoint, {callbacks} now: not restored")
    else:
        for callback, callback_saved in zip(callbacks, saved):
            callback.__dict__.update(callback_saved["attributes"])
    logger = model.logger
    logger.name_to_value.update(state["logger"]["name_to_value"])
    logger.name_to_count.update(state["logger"]["name_to_count"])
    logger.name_to_excluded.update(state["logger"]["name_to_excluded"])
    set_rng_states(state["rng"])


def save_checkpoint(model: Any, path: Path) -> None:
    """Save the model zip with the resume state inside (entry ``resume_state.pkl``), atomically.

    :param model: the model, at the start of a rollout
    :param path: ``checkpoint.zip``
    """
    temp = path.with_name(f".{path.stem}.tmp.zip")
    model.save(temp)
    with zipfile.ZipFile(temp, "a") as archive:
        archive.writestr(RESUME_ENTRY, cloudpickle.dumps(capture_resume_state(model)))
    os.replace(temp, path)


def load_resume_state(path: Path) -> dict[str, Any] | None:
    """The resume state inside a checkpoint zip (``None`` for a zip without one, from an older version)."""
    with zipfile.ZipFile(path) as archive:
        if RESUME_ENTRY not in archive.namelist():
            return None
        state: dict[str, Any] = cloudpickle.loads(archive.read(RESUME_ENTRY))
    return state if state.get("format") == RESUME_FORMAT else None


# ---------------------------------------------------------------------------------------------------- progress.csv
class ContinuedCSVOutputFormat(CSVOutputFormat):
    """SB3's CSV writer going on with an existing file (header ``keys`` and its rows kept) instead of starting a new
    one (SB3 opens with ``"w+"``). New keys are added as SB3 adds them (the file is rewritten with a wider header).

    :param filename: the CSV file
    :param keys: its header (empty: start a new file)
    """

    def __init__(self, filename: str, keys: list[str]) -> None:
        # not super().__init__, which opens with "w+" (truncates); the logger closes the file
        self.file = open(filename, "r+" if keys else "w+")
        self.file.seek(0, os.SEEK_END)
        self.keys = list(keys)
        self.separator = ","
        self.quotechar = '"'


class ContinuedLogger(Logger):
    """SB3's logger whose ``time/iterations`` counts on from the earlier segments of a resumed run.

    :param folder: the logging folder
    :param output_formats: the writers
    :param iteration_offset: rollouts done before this segment
    """

    def __init__(self, folder: str | None, output_formats: list[KVWriter], iteration_offset: int = 0) -> None:
        super().__init__(folder, output_formats)
        self.iteration_offset = iteration_offset

    def record(self, key: str, value: Any, exclude: str | tuple[str, ...] | None = None) -> None:
        if key == "time/iterations":
            value = value + self.iteration_offset
        super().record(key, value, exclude)


def truncate_progress(path: Path, done_steps: int) -> list[str]:
    """Keep the rows of a ``progress.csv`` dumped up to ``done_steps`` agent-steps (the checkpoint); drop later ones
    and a last line cut by a kill. Returns the header (empty when there is nothing to keep).

    :param path: the run's ``progress.csv``
    :param done_steps: agent-steps of the checkpoint
    """
    if not path.is_file():
        return []
    lines = path.read_text().split("\n")[:-1]  # the text after the last newline is a row cut by a kill
    if not lines:
        return []
    keys = next(csv.reader([lines[0]]))
    column = keys.index("time/total_timesteps") if "time/total_timesteps" in keys else None
    kept = [lines[0]]
    for line in lines[1:]:
        values = next(csv.reader([line]), [])
        if len(values) != len(keys):
            continue
        if column is not None and values[column] != "" and float(values[column]) > done_steps:
            continue
        kept.append(line)
    atomic_write_text(path, "".join(line + "\n" for line in kept))
    return keys


def progress_logger(folder: Path, done_steps: int | None, iteration_offset: int) -> Logger:
    """The run's logger: ``progress.csv`` started anew (``done_steps`` ``None``) or continued after its rows up to the
    checkpoint.

    :param folder: the run's folder
    :param done_steps: agent-steps of the checkpoint resumed from, ``None`` for a fresh start
    :param iteration_offset: rollouts done before the checkpoint
    """
    path = folder / "progress.csv"
    keys = truncate_progress(path, done_steps) if done_steps is not None else []
    return ContinuedLogger(str(folder), [ContinuedCSVOutputFormat(str(path), keys)], iteration_offset)


# ---------------------------------------------------------------------------------------------------- run bookkeeping
class SegmentClock:
    """Wall time of a run over its segments (one per process that worked on it), kept in ``segments.json``.

    A segment's time is recorded at each checkpoint, evaluation and at the end; a killed segment counts up to its
    last record.

    :param path: the run's ``segments.json``
    :param resumed_at: agent-steps this segment starts from
    """

    def __init__(self, path: Path, resumed_at: int) -> None:
        self.path = path
        self.segments: list[dict[str, Any]] = json.loads(path.read_text()) if path.is_file() else []
        self.previous_s = float(sum(segment["wall_s"] for segment in self.segments))
        self.start = time.time()
        self.segments.append({"started": utc_stamp(), "resumed_at": resumed_at, "reached": resumed_at, "wall_s": 0.0})
        self.tick(resumed_at)

    def tick(self, steps: int) -> None:
        """Record this segment's wall time so far and the agent-steps it reached.

        :param steps: agent-steps reached
        """
        self.segments[-1].update(reached=int(steps), wall_s=round(time.time() - self.start, 3))
        atomic_write_text(self.path, json.dumps(self.segments, indent=1) + "\n")

    @property
    def total_s(self) -> float:
        """Wall time over every segment, this one up to its last record."""
        return self.previous_s + float(self.segments[-1]["wall_s"])


class RunLog:
    """What a run says about its resumes: printed with the run's name and appended to its ``resume.log``.

    :param folder: the run's folder
    :param name: the run's name
    """

    def __init__(self, folder: Path, name: str) -> None:
        self.path = folder / "resume.log"
        self.name = name

    def __call__(self, message: str) -> None:
        print(f"{self.name}: {message}", flush=True)
        with open(self.path, "a") as file:
            file.write(f"{utc_stamp()} {message}\n")


def _same_row(row: dict[str, Any], other: dict[str, Any]) -> bool:
    """Whether two evaluation rows hold the same values (as written to CSV and read back)."""
    return {key: _number(str(value)) for key, value in row.items()} == {
        key: _number(str(value)) for key, value in other.items()
    }


class BenchmarkEvalCallback(MultiAgentEvalCallback):
    """The benchmark's evaluation and checkpoints.

    Evaluations happen at the first agent-step count >= k * ``eval_freq`` (on the grid whether or not the run was
    resumed), each on the same episodes (the eval env is reseeded with ``eval_seed`` first), and each becomes a row of
    the run's ``evaluations.csv``. At the start of every rollout after the first, the model and its resume state are
    saved to ``checkpoint.zip`` (a consistent point to resume from); on the first rollout after resuming, the resume
    state is restored instead, at the very point it was taken.

    :param eval_env: the evaluation env
    :param spec: the run
    :param evaluations_path: the run's ``evaluations.csv``
    :param checkpoint_path: the run's ``checkpoint.zip``
    :param rows: evaluation rows already recorded (kept on resume)
    :param n_agents: agents per game (``env_steps = agent-steps / n_agents``)
    :param main_metric: the task's main metric
    :param eval_seed: seed given to the eval env before every evaluation (``None``: not reseeded)
    :param resumed_at: agent-steps of the checkpoint resumed from (0 for a fresh start)
    :param resume_state: the checkpoint's resume state, restored at the first rollout start
    :param lost_rows: rows made after the checkpoint by the interrupted segment, by agent-steps: they are re-done
    :param clock: the run's wall-time record
    :param log: where resume messages go
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
        eval_seed: int | None = None,
        resumed_at: int = 0,
        resume_state: dict[str, Any] | None = None,
        lost_rows: dict[int, dict[str, Any]] | None = None,
        clock: SegmentClock | None = None,
        log: Callable[[str], None] = print,
    ) -> None:
        super().__init__(eval_env, spec.eval_episodes, spec.eval_freq, main_metric=main_metric, verbose=0)
        self.spec = spec
        self.evaluations_path = evaluations_path
        self.checkpoint_path = checkpoint_path
        self.rows = rows
        self.n_agents = n_agents
        self.eval_seed = eval_seed
        self.resumed_at = resumed_at
        self.resume_state = resume_state
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

    def _on_rollout_start(self) -> None:
        if self.resume_state is not None:  # the first rollout after resuming: the moment the checkpoint was taken
            restore_resume_state(self.model, self.resume_state, self.log)
            self.resume_state = None
            if self.clock is not None:  # time/time_elapsed and time/fps over all segments
                self.model.start_time = time.time_ns() - int(self.clock.previous_s * 1e9)
        elif self.model.num_timesteps > self.resumed_at:  # after an update: a consistent point to resume from
            save_checkpoint(self.model, self.checkpoint_path)
            if self.clock is not None:
                self.clock.tick(self.model.num_timesteps)

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
            outcome = "identical to" if _same_row(row, lost) else "different from"
            self.log(f"evaluation at {self.num_timesteps} agent-steps re-done: {outcome} the interrupted segment's")
        self.rows.append(row)
        write_rows(self.evaluations_path, self.rows)
        if self.clock is not None:
            self.clock.tick(self.num_timesteps)
        return keep_going


# ---------------------------------------------------------------------------------------------------- one run
def _open_checkpoint(experiment: Any, checkpoint: Path, log: Callable[[str], None]) -> tuple[Any, dict | None]:
    """Load the model of a checkpoint onto the experiment's env, and its resume state; say in the log when the
    resumption can only be approximate (no resume state, or an env that cannot save its state).

    :param experiment: the run's built :class:`~sb3_saeir.experiment.Experiment`
    :param checkpoint: ``checkpoint.zip``
    :param log: the run's log
    :return: the model and the resume state
    """
    model = experiment.load(checkpoint)
    state = load_resume_state(checkpoint)
    log(f"resumed from the checkpoint at {model.num_timesteps} agent-steps")
    if state is None:
        log("the checkpoint has no resume state (older version): resuming approximately")
    elif state["env"] is None or resumable_env(model.get_env()) is None:
        log(
            f"the training env ({state['env_type']}) cannot save its state (no get_resume_state; SuperSuit-backed "
            "envs): resuming approximately, the training env restarts from a reset"
        )
    return model, state


def execute_run(spec: RunSpec, folder: str) -> dict[str, Any]:
    """Train and evaluate one run in ``folder`` (resuming from its checkpoint); returns its evaluation rows.

    Runs in a worker process (local or Ray): torch uses one thread.

    :raises ValueError: when the folder holds a run made with other settings
    """
    import torch as th

    from sb3_saeir.experiment import EVAL_SEED_OFFSET, Experiment

    th.set_num_threads(1)
    path = Path(folder)
    record = spec_record(spec)
    ensure_spec_file(path, record)
    evaluations_path = path / "evaluations.csv"
    if (path / "done.json").is_file():
        return {"spec": asdict(spec), "status": "skipped", "rows": read_rows(evaluations_path)}
    log = RunLog(path, spec.name)
    config = {**load_hyperparams(spec.algo, spec.task), **spec.params}  # as given (spec.json holds its JSON form)
    experiment = Experiment(spec.algo, spec.task, config, seed=spec.seed, n_games=spec.n_games)
    model = experiment.build()
    assert experiment.env is not None
    n_agents = experiment.env.num_envs // experiment.n_games
    checkpoint = path / CHECKPOINT_FILE
    state = None
    resumed = checkpoint.is_file()
    if resumed:  # the model, its optimizer and ValueNorm statistics, its step counter; the rest at the next rollout
        model, state = _open_checkpoint(experiment, checkpoint, log)
    done_steps = model.num_timesteps if resumed else 0
    clock = SegmentClock(path / "segments.json", done_steps)
    rows, lost = _split_rows(evaluations_path, done_steps if resumed else None, log)
    rollout = int(getattr(model, "n_steps", 1)) * experiment.env.num_envs
    model.set_logger(progress_logger(path, done_steps if resumed else None, done_steps // rollout))
    evaluator = BenchmarkEvalCallback(
        experiment.make_eval_env(spec.eval_episodes, seed=EVAL_SEED_OFFSET + spec.seed),
        spec,
        evaluations_path,
        checkpoint,
        rows,
        n_agents,
        experiment.main_metric,
        eval_seed=EVAL_SEED_OFFSET + spec.seed,
        resumed_at=done_steps,
        resume_state=state,
        lost_rows=lost,
        clock=clock,
        log=log,
    )
    exact = state is not None and state["env"] is not None and resumable_env(model.get_env()) is not None
    if resumed and not exact:  # approximate: learn() resets the env and the recurrent states
        model._last_obs = None  # type: ignore[assignment]
    remaining = spec.n_timesteps - done_steps
    if remaining > 0:
        if not resumed:
            evaluator.init_callback(model)
            evaluator.evaluate()  # the curve starts at 0 steps
        experiment.learn(remaining, callbacks=[evaluator], reset_num_timesteps=not resumed)
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
    temp = path / f".{Path(MODEL_FILE).stem}.tmp.zip"
    model.save(temp)
    os.replace(temp, path / MODEL_FILE)
    clock.tick(timesteps)
    summary = {"wall_s": round(clock.total_s, 1), "segments": len(clock.segments), "timesteps": timesteps}
    atomic_write_text(path / "done.json", json.dumps(summary))
    (path / CHECKPOINT_FILE).unlink(missing_ok=True)


def _safe_execute(spec: RunSpec, folder: str) -> dict[str, Any]:
    try:
        return execute_run(spec, folder)
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


def run_all(specs: list[RunSpec], out: Path, jobs: int = 1, ray_address: str | None = None) -> list[dict[str, Any]]:
    """Run every spec (local processes or Ray); write each run's rows into its folder; return the results.

    Ctrl-C (``KeyboardInterrupt``) stops every job (local worker processes are terminated, Ray tasks cancelled) and
    is raised again.
    """
    results: list[dict[str, Any]] = []
    if ray_address is not None:
        results = _run_on_ray(specs, out, ray_address)
    elif jobs > 1:
        pool = ProcessPoolExecutor(max_workers=jobs, initializer=_ignore_sigint)
        try:
            futures = [pool.submit(_safe_execute, spec, str(run_folder(out, spec))) for spec in specs]
            results = [_store(future.result(), out) for future in as_completed(futures)]
        except BaseException:
            _stop_pool(pool)
            raise
        pool.shutdown()
    else:
        results = [_store(_safe_execute(spec, str(run_folder(out, spec))), out) for spec in specs]
    return results


def _run_on_ray(specs: list[RunSpec], out: Path, ray_address: str) -> list[dict[str, Any]]:
    import ray

    ray.init(address=ray_address, ignore_reinit_error=True, log_to_driver=False)
    remote = ray.remote(num_cpus=1)(_safe_execute)
    results = []
    pending = {}
    for spec in specs:
        local = run_folder(out, spec)
        if (local / "done.json").is_file():
            results.append({"spec": asdict(spec), "status": "skipped", "rows": read_rows(local / "evaluations.csv")})
        else:
            pending[remote.remote(spec, str(local))] = spec
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
            rows.extend(read_rows(folder / "evaluations.csv"))
    if rows:
        write_rows(out / "runs.csv", rows)
    else:
        (out / "runs.csv").unlink(missing_ok=True)
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


def main_metric(task: str) -> tuple[str, str, float]:
    """``(key, title, scale)`` of the task's main metric: the first column of :data:`TABLE_COLUMNS` for its family."""
    return TABLE_COLUMNS["grf" if task.startswith("grf") else "cn"][0]


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
        axis.set_title(task)
        axis.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(format_steps))
        axis.set_xlabel("env steps")
        axis.set_ylabel(title)
        axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def rliable_markdown(rows: list[dict[str, Any]], reps: int = 2000, bootstrap_seed: int = 0) -> str:
    """IQM of the final main metric with 95% stratified-bootstrap confidence intervals (rliable).

    :param rows: the evaluation rows of ``runs.csv`` (:func:`collect`), finished runs only
    :param reps: bootstrap resamples per interval
    :param bootstrap_seed: seed of the resampling, so that reporting the same runs twice writes the same intervals
    :return: the Markdown table of ``aggregate.md``
    """
    from rliable import library as rly
    from rliable import metrics

    lines = ["| Task | Method | IQM | 95% CI |", "|---|---|---|---|"]
    # rliable's StratifiedBootstrap draws its resamples from NumPy's global generator (it ignores random_state): seed
    # that one for the call and give the caller's state back afterwards.
    global_state = np.random.get_state()
    np.random.seed(bootstrap_seed)
    try:
        for task, (title, values) in final_scores(final_rows(rows)).items():
            scores = {algo: np.array(seeds)[:, None] for algo, seeds in values.items()}  # (n_seeds, 1 task) per method
            estimates, intervals = rly.get_interval_estimates(
                scores, lambda x: np.array([metrics.aggregate_iqm(x)]), reps=reps
            )
            lines += _aggregate_lines(task, title, scores, estimates, intervals)
    finally:
        np.random.set_state(global_state)
    return "\n".join(lines) + "\n"


def mann_whitney(first: list[float], second: list[float], max_splits: int = 200_000) -> tuple[float, float]:
    """The Mann-Whitney U statistic of ``first`` against ``second`` (pairs where ``first`` is above, ties counting half)
    and its two-sided p-value: exact, from every split of the pooled values into two groups of these sizes (mid-ranks,
    so ties are handled; the share of splits whose U is at least as far from its mean as the observed one), or SciPy's
    normal approximation when there are more than ``max_splits`` splits.

    :param first: final values of the first method, one per seed
    :param second: final values of the second method, one per seed
    :param max_splits: largest number of splits enumerated for the exact p-value
    :return: ``(U, p)``
    """
    from scipy.stats import mannwhitneyu, rankdata

    n_first, n_second = len(first), len(second)
    ranks = rankdata(np.concatenate([first, second]))  # (n_first + n_second,) mid-ranks of the pooled values
    offset = n_first * (n_first + 1) / 2
    statistic = float(ranks[:n_first].sum() - offset)
    if math.comb(n_first + n_second, n_first) > max_splits:
        return statistic, float(mannwhitneyu(first, second, alternative="two-sided", method="asymptotic").pvalue)
    mean = n_first * n_second / 2
    split_statistics = np.array(
        [ranks[list(split)].sum() - offset for split in itertools.combinations(range(n_first + n_second), n_first)]
    )
    extreme = np.abs(split_statistics - mean) >= abs(statistic - mean) - 1e-9
    return statistic, float(extreme.mean())


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

    rows = read_rows(run / "progress.csv")
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
    return rows


def unfinished_runs(out: Path, specs: list[RunSpec], rows: list[dict[str, Any]]) -> dict[tuple[str, str, int], int]:
    """The runs of ``specs`` with evaluation rows but no ``done.json`` (running, stopped or failed), with the
    agent-steps of their last evaluation.

    :param out: the benchmark folder
    :param specs: the command's runs
    :param rows: their evaluation rows (:func:`collect`)
    """
    reached: dict[tuple[str, str, int], int] = {}
    for row in rows:
        key = (row["algo"], row["task"], int(row["seed"]))
        reached[key] = max(reached.get(key, 0), int(row["timesteps"]))
    return {
        (spec.algo, spec.task, spec.seed): reached[(spec.algo, spec.task, spec.seed)]
        for spec in specs
        if (spec.algo, spec.task, spec.seed) in reached and not (run_folder(out, spec) / "done.json").is_file()
    }


def refusal(out: Path, mismatches: list[tuple[RunSpec, list[str]]], report_only: bool = False) -> str:
    """The message of a command whose runs differ from those already in ``out``: one line per run, then the fix.

    :param out: the benchmark folder
    :param mismatches: each mismatching run with its differences (:func:`spec_differences`)
    :param report_only: the command only reports (``--rerun-changed`` does not apply)
    """
    lines = [f"sb3_saeir.benchmark: error: {len(mismatches)} run(s) in {out} were made with other settings:"]
    lines += [f"  {spec.name}: {'; '.join(differences)}" for spec, differences in mismatches]
    if report_only:
        lines.append("fix: give --report-only the settings these runs were made with (the old values above)")
    else:
        lines.append(
            "fix: use another --out for these settings, or add --rerun-changed to move these runs aside "
            "(to <folder>.replaced-<UTC time>, nothing deleted) and train them again"
        )
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="python -m sb3_saeir.benchmark", description=__doc__.split("\n")[0])
    parser.add_argument("--algos", nargs="+", default=["saeir_ppo", "mappo"], help=f"methods: {', '.join(sorted(ALGOS))}")
    parser.add_argument("--tasks", nargs="+", default=["cn-sparse-n3"])
    parser.add_argument("--seeds", default="1-3", help="e.g. 1-5 or 1,3,7")
    parser.add_argument("-n", "--n-timesteps", type=count, default=1_000_000, help="agent-steps per run")
    parser.add_argument("--n-games", type=count, default=None, help="override the configs' n_envs (games)")
    parser.add_argument("--eval-freq", type=count, default=50_000, help="agent-steps between evaluations")
    parser.add_argument("--eval-episodes", type=count, default=20, help="game episodes per evaluation")
    parser.add_argument("-params", "--hyperparams", dest="params", nargs="+", default=None, help="overrides key:value")
    parser.add_argument("--jobs", type=count, default=1, help="parallel local processes")
    parser.add_argument("--ray-address", default=None, help="run on a Ray cluster (e.g. 'auto' or host:port)")
    parser.add_argument("--out", default="benchmark", help="output folder")
    parser.add_argument(
        "--rerun-changed",
        action="store_true",
        help="move runs made with other settings aside (<folder>.replaced-<UTC time>) and train them again",
    )
    parser.add_argument(
        "--rliable", action="store_true", help="also write aggregate.md (IQM, bootstrap CIs, pairwise Mann-Whitney tests)"
    )
    parser.add_argument("--report-only", action="store_true", help="rebuild runs.csv/table/curves without training")
    parser.add_argument("--entropy-plot", default=None, help="RUN_FOLDER: plot the SAEIR bonus, fire rate and value entropy")
    return parser


def _error(message: str) -> int:
    print(f"sb3_saeir.benchmark: error: {message}", file=sys.stderr)
    return 2


def _check_arguments(args: argparse.Namespace) -> str | None:
    """The first bad argument, as a message (``None``: all good)."""
    from sb3_saeir.envs import list_tasks

    unknown = [algo for algo in args.algos if algo not in ALGOS]
    if unknown:
        return f"unknown methods {unknown}; valid: {', '.join(sorted(ALGOS))}"
    unknown = [task for task in args.tasks if task not in list_tasks()]
    if unknown:
        return f"unknown tasks {unknown}; valid: {', '.join(list_tasks())}"
    for flag, value in (("-n", args.n_timesteps), ("--eval-freq", args.eval_freq), ("--eval-episodes", args.eval_episodes)):
        if value < 1:
            return f"{flag} must be >= 1, got {value}"
    for flag, value in (("--n-games", args.n_games), ("--jobs", args.jobs)):
        if value is not None and value < 1:
            return f"{flag} must be >= 1, got {value}"
    try:
        parse_seeds(args.seeds)
        if not args.report_only:
            check_folder("--out", args.out)
    except ConfigError as error:
        return str(error)
    return None


def check_runs_build(specs: list[RunSpec], out: Path) -> None:
    """Build (and close) the model of every run still to train, once per method, task and number of games, so that a
    setting only the algorithm, the env or a config callback refuses stops the command before any run folder is made.

    :raises ~sb3_saeir.config.ConfigError: naming the run and the problem
    """
    from sb3_saeir.experiment import Experiment

    checked: set[tuple[str, str, int | None]] = set()
    for spec in specs:
        key = (spec.algo, spec.task, spec.n_games)
        if key in checked or (run_folder(out, spec) / "done.json").is_file():
            continue
        checked.add(key)
        experiment = Experiment(
            spec.algo,
            spec.task,
            {**load_hyperparams(spec.algo, spec.task), **spec.params},
            seed=spec.seed,
            n_games=spec.n_games,
        )
        try:
            experiment.build(verbose=0)
            experiment.make_eval_env(spec.eval_episodes)
        except (ValueError, TypeError, KeyError) as error:
            message = error.args[0] if isinstance(error, KeyError) and error.args else error
            raise ConfigError(f"cannot build {spec.algo} on {spec.task} with these settings: {message}") from error
        finally:
            experiment.close()


def plan_runs(args: argparse.Namespace, params: dict[str, Any]) -> list[RunSpec]:
    """The command's runs, with the number of games resolved (``--n-games`` or the config's ``n_envs``)."""
    specs = []
    for task in args.tasks:
        for algo in args.algos:
            config = {**load_hyperparams(algo, task), **params}
            n_games = args.n_games if args.n_games is not None else int(config.get("n_envs", 8))
            for seed in parse_seeds(args.seeds):
                specs.append(RunSpec(algo, task, seed, args.n_timesteps, n_games, args.eval_freq, args.eval_episodes, params))
    return specs


def prepare_folders(out: Path, specs: list[RunSpec], mismatches: list[tuple[RunSpec, list[str]]]) -> None:
    """Move the mismatching runs aside and write every planned run's ``spec.json`` (before any training)."""
    for spec, _ in mismatches:
        folder = run_folder(out, spec)
        print(f"{spec.name}: made with other settings, moved to {move_aside(folder)}", flush=True)
    for spec in specs:
        ensure_spec_file(run_folder(out, spec), spec_record(spec))


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit status (0 done, 1 some run failed, 2 bad arguments or settings that differ
    from the runs in ``--out``, 130 interrupted)."""
    args = _parser().parse_args(argv)
    try:
        return _main(args)
    except KeyboardInterrupt:
        print(INTERRUPTED, file=sys.stderr, flush=True)
        return 130


def _missing_extra(args: argparse.Namespace) -> str | None:
    """Check, before any training, that the optional packages this command needs are installed."""
    needed = [("matplotlib", "plots", "the benchmark's curves.png")]
    if args.rliable:
        needed += [("rliable", "plots", "--rliable"), ("scipy", "plots", "--rliable")]
    if args.ray_address is not None:
        needed.append(("ray", "ray", "--ray-address"))
    for module, extra, purpose in needed:
        try:
            require_extra(module, extra, purpose)
        except MissingExtraError as error:
            return str(error)
    return None


def _main(args: argparse.Namespace) -> int:
    out = Path(args.out)
    missing = _missing_extra(args)
    if missing is not None:
        print(f"sb3_saeir.benchmark: error: {missing}", file=sys.stderr)
        return 2
    if args.entropy_plot:
        summary = plot_system_entropy(Path(args.entropy_plot), Path(args.entropy_plot) / "system_entropy.png")
        print(f"wrote {Path(args.entropy_plot) / 'system_entropy.png'}")
        print("| scale | fire rate (all rollouts) | fire rate (last 10%) | value entropy (first -> last rollout) |")
        print("|---|---|---|---|")
        for scale, figures in summary.items():
            print(
                f"| {scale} | {figures['fire_rate']:.2e} | {figures['fire_rate_late']:.2e} "
                f"| {figures['entropy_first']:.3f} -> {figures['entropy_last']:.3f} |"
            )
        return 0
    problem = _check_arguments(args)
    if problem is not None:
        return _error(problem)
    try:
        params = parse_params(args.params)
        for algo in args.algos:
            for task in args.tasks:
                check_hyperparams(algo, load_hyperparams(algo, task), params)
    except (ConfigError, KeyError) as error:
        return _error(str(error.args[0] if isinstance(error, KeyError) else error))
    specs = plan_runs(args, params)
    if not args.report_only:
        try:
            check_runs_build(specs, out)
        except ConfigError as error:
            return _error(str(error))
    mismatches = [(spec, stored_spec_differences(run_folder(out, spec), spec_record(spec))) for spec in specs]
    mismatches = [(spec, differences) for spec, differences in mismatches if differences]
    if mismatches and (args.report_only or not args.rerun_changed):
        print(refusal(out, mismatches, args.report_only), file=sys.stderr)
        return 2
    failures: list[str] = []
    if not args.report_only:
        out.mkdir(parents=True, exist_ok=True)
        prepare_folders(out, specs, mismatches)
        start = time.time()
        results = run_all(specs, out, args.jobs, args.ray_address)
        failures = [f"{RunSpec(**r['spec']).name}\n{r['error']}" for r in results if r["status"] == "failed"]
        atomic_write_text(out / "failures.txt", "\n".join(failures))
        print(f"{len(specs)} runs ({len(failures)} failed) in {time.time() - start:.0f} s")
    elif not out.is_dir():
        return _error(f"{out} does not exist: nothing to report")
    report(out, specs, args.rliable)
    print(f"results in {out}: runs.csv, table.md, curves.png" + (", aggregate.md" if args.rliable else ""))
    return 1 if failures else 0


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
