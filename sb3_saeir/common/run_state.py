"""Run state: what a training run needs to continue bit for bit after it stopped (``docs/guide/training.md``,
"Stopping and resuming a run"), for envs that can save their state (``get_resume_state``).

:func:`save_checkpoint` / :func:`load_resume_state`: the SB3 model zip with one more entry, ``resume_state.pkl``
(:func:`capture_resume_state`: generators, the model's last observations and GRU states, episode buffers, the training
env, intrinsic-reward callbacks, unwritten logger values, ``extras`` such as an evaluation callback), written
atomically. :class:`RunCheckpointCallback` writes them at rollout starts, restores one after resuming and turns a stop
request (Ctrl-C) into a checkpoint and a clean stop; :func:`progress_logger` continues a run's ``progress.csv``;
:class:`SegmentClock` keeps the run's wall time over the processes that worked on it.
"""

from __future__ import annotations

import base64
import csv
import json
import math
import os
import random
import signal
import time
import zipfile
from collections.abc import Callable
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Protocol

import cloudpickle
import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import CSVOutputFormat, KVWriter, Logger, filter_excluded_keys

from sb3_saeir.common.atomic import atomic_file, atomic_write_text, keep_damaged
from sb3_saeir.common.utils import PACKAGE_VERSION

# The entry of a checkpoint zip that holds the resume state (SB3's load ignores it).
RESUME_ENTRY = "resume_state.pkl"
RESUME_FORMAT = 1
# Entries of every SB3 model zip; SB3's save_to_zip_file writes the version last (its presence: the save finished).
COMPLETE_ZIP_ENTRIES = ("data", "policy.pth", "_stable_baselines3_version")
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
# The model attributes that hold the env's side of the rollout: kept only when the env state is restored too.
ENV_SIDE_ATTRIBUTES = ("_last_obs", "_last_episode_starts", "_last_original_obs", "_last_states")
# Callback attributes that are links to the model or per-call data, not state of the callback.
CALLBACK_LINKS = ("model", "parent", "locals", "globals", "training_env")
# Per-rollout data that a callback clears at every rollout start.
CALLBACK_TRANSIENT = ("next_observations",)


class Resumable(Protocol):
    """An object whose state a checkpoint carries (an evaluation callback, an env wrapper)."""

    def get_resume_state(self) -> Any: ...

    def set_resume_state(self, state: Any) -> None: ...


# ---------------------------------------------------------------------------------------------------- files
def utc_stamp() -> str:
    """The current UTC time, ``20250131T235959Z``."""
    return datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")


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

    SB3 ``VecEnvWrapper`` objects forward attribute look-ups to the env they wrap but keep state of their own, so a
    wrapper counts as resumable only when its own class saves its state (as
    :class:`~sb3_saeir.common.vec_env.MultiAgentVecMonitor` does) and the env it wraps is resumable.
    """
    from stable_baselines3.common.vec_env import VecEnvWrapper

    if env is None or not callable(getattr(type(env), "get_resume_state", None)):
        return None
    if isinstance(env, VecEnvWrapper) and resumable_env(env.venv) is None:
        return None
    return env


def unresumable_part(env: Any) -> str:
    """The class name of what keeps ``env`` from saving its state: the first env, going inwards through wrappers that
    save their own state, without ``get_resume_state`` (``env``'s own class name when it can save its state)."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    part = env
    while isinstance(part, VecEnvWrapper) and callable(getattr(type(part), "get_resume_state", None)):
        part = part.venv
    return type(part if resumable_env(env) is None else env).__name__


def callback_state(callback: Any) -> dict[str, Any]:
    """The state of a callback: its attributes but the links to the model and per-rollout data."""
    skipped = (*CALLBACK_LINKS, *CALLBACK_TRANSIENT)
    return {
        "class": type(callback).__qualname__,
        "attributes": {key: value for key, value in vars(callback).items() if key not in skipped},
    }


def capture_resume_state(model: Any, extras: dict[str, Resumable] | None = None) -> dict[str, Any]:
    """Everything besides the model zip that determines the rest of a run, at the start of a rollout.

    :param model: a MAPPO / SAEIR_PPO model in ``learn``
    :param extras: other objects whose state the run needs, by name (e.g. an evaluation callback)
    :return: the resume state (pickled with cloudpickle into the checkpoint zip)
    """
    env = resumable_env(model.get_env())
    logger = model.logger
    return {
        "format": RESUME_FORMAT,
        "num_timesteps": model.num_timesteps,
        "rng": rng_states(),
        "model": {name: getattr(model, name) for name in MODEL_RESUME_ATTRIBUTES if hasattr(model, name)},
        "env": env.get_resume_state() if env is not None else None,
        "env_type": unresumable_part(model.get_env()),
        "callbacks": [callback_state(callback) for callback in getattr(model, "_intrinsic_rewards", [])],
        "logger": {
            "name_to_value": dict(logger.name_to_value),
            "name_to_count": dict(logger.name_to_count),
            "name_to_excluded": dict(logger.name_to_excluded),
        },
        "extras": {name: extra.get_resume_state() for name, extra in (extras or {}).items()},
        "progress_rows": progress_rows(logger),
    }


def is_exact(model: Any, state: dict[str, Any] | None) -> bool:
    """Whether resuming ``model`` from ``state`` is exact: the checkpoint holds the env's state and the model's env
    can take it back."""
    return state is not None and state["env"] is not None and resumable_env(model.get_env()) is not None


def restore_resume_state(
    model: Any, state: dict[str, Any], log: Callable[[str], None], extras: dict[str, Resumable] | None = None
) -> None:
    """Put a resumed model, its env, its intrinsic-reward callbacks, its logger and the ``extras`` back in the state of
    the moment the checkpoint was taken (call it at the same point: the start of the first rollout after resuming).

    Without an env state (the env has no ``get_resume_state``), the env and the recurrent states keep the fresh start
    that ``learn`` gave them: an approximate resume.

    :param model: the model loaded from the checkpoint, in ``learn``
    :param state: the resume state of the checkpoint
    :param log: where to say what could not be restored
    :param extras: the objects given to :func:`capture_resume_state`, by the same names
    """
    exact = is_exact(model, state)
    if exact:
        model.get_env().set_resume_state(state["env"])
    for name, value in state["model"].items():
        if exact or name not in ENV_SIDE_ATTRIBUTES:
            setattr(model, name, value)
    callbacks = list(getattr(model, "_intrinsic_rewards", []))
    saved = state["callbacks"]
    if [type(c).__qualname__ for c in callbacks] != [s["class"] for s in saved]:
        log(f"intrinsic rewards {[s['class'] for s in saved]} in the checkpoint, {callbacks} now: not restored")
    else:
        for callback, callback_saved in zip(callbacks, saved):
            callback.__dict__.update(callback_saved["attributes"])
    saved_extras = state.get("extras", {})
    for name, extra in (extras or {}).items():
        if name in saved_extras:
            extra.set_resume_state(saved_extras[name])
        else:
            log(f"the checkpoint holds no state of {name}: it starts afresh")
    logger = model.logger
    logger.name_to_value.update(state["logger"]["name_to_value"])
    logger.name_to_count.update(state["logger"]["name_to_count"])
    logger.name_to_excluded.update(state["logger"]["name_to_excluded"])
    set_rng_states(state["rng"])


def save_checkpoint(
    model: Any, path: Path, extras: dict[str, Resumable] | None = None, state: dict[str, Any] | None = None
) -> None:
    """Save the model zip with the resume state inside (entry ``resume_state.pkl``), atomically.

    :param model: the model, at the start of a rollout (or at the end of ``learn``: the same point)
    :param path: the checkpoint's zip
    :param extras: other objects whose state the checkpoint carries (:func:`capture_resume_state`)
    :param state: the resume state, captured earlier at such a point (``None``: captured now)
    """
    if state is None:
        state = capture_resume_state(model, extras)
    with atomic_file(path, "w+b") as file:
        model.save(file)
        with zipfile.ZipFile(file, "a") as archive:
            archive.writestr(RESUME_ENTRY, cloudpickle.dumps(state))


def load_resume_state(path: Path) -> dict[str, Any] | None:
    """The resume state inside a checkpoint zip (``None`` for a zip without one: a plain model, or an older version)."""
    with zipfile.ZipFile(path) as archive:
        if RESUME_ENTRY not in archive.namelist():
            return None
        state: dict[str, Any] = cloudpickle.loads(archive.read(RESUME_ENTRY))
    return state if state.get("format") == RESUME_FORMAT else None


def read_zip_data(source: Any) -> dict[str, Any] | None:
    """The ``data`` entry of an SB3 model zip as JSON, without loading the model; ``None`` when it cannot be read (not a
    zip, no ``data``, not a JSON object: SB3's ``load`` or :func:`checkpoint_problem` names the damage).

    :param source: the zip: a path (read as given) or a binary file object (read from where it stands)
    """
    try:
        with zipfile.ZipFile(source) as archive:
            data = json.loads(archive.read("data"))
    except Exception:  # a damaged or foreign file
        return None
    return data if isinstance(data, dict) else None


def saved_policy_class(data: dict[str, Any]) -> Any:
    """The policy class a zip's ``data`` holds (``policy_class``, as SB3 serialises a class), ``None`` when it cannot be
    rebuilt here (its module is not installed, or the entry is damaged).

    :param data: the zip's ``data`` (:func:`read_zip_data`)
    """
    try:
        return cloudpickle.loads(base64.b64decode(data["policy_class"][":serialized:"].encode()))
    except Exception:
        return None


def checkpoint_problem(path: Path) -> str:
    """Why a checkpoint (or any model zip) cannot be loaded, in a few words (``""`` when it can): a link to nothing, a
    folder, not a whole zip
    (cut short by a kill or a full disk), an entry that fails its CRC check (bit rot), an entry of a finished save
    missing (SB3 writes ``_stable_baselines3_version`` last: a save stopped by Ctrl-C closes the zip without it), a
    ``data`` or resume state that does not read back.

    :param path: the zip
    """
    if path.is_symlink() and not path.exists():
        return f"it is a link to {os.readlink(path)}, which does not exist"
    if path.is_dir():
        return "it is a folder, not a zip file"
    try:
        with zipfile.ZipFile(path) as archive:
            damaged = archive.testzip()
            if damaged is not None:
                return f"its entry {damaged} fails the CRC check"
            names = archive.namelist()
            missing = [entry for entry in COMPLETE_ZIP_ENTRIES if entry not in names]
            if missing:
                return f"it has no {', '.join(missing)} entry (a save that did not finish)"
            json.loads(archive.read("data"))
            if RESUME_ENTRY in names:
                cloudpickle.loads(archive.read(RESUME_ENTRY))
    except Exception as error:  # anything that keeps it from loading: the zip is damaged
        detail = str(error).splitlines()[0] if str(error) else "no detail"
        return f"{type(error).__name__}: {detail}"
    return ""


def describe_resume(model: Any, state: dict[str, Any] | None) -> list[str]:
    """What a resume from ``state`` cannot restore, as sentences for the run's log (empty: exact)."""
    if state is None:
        return ["the checkpoint has no resume state (a plain model or an older version): resuming approximately"]
    if not is_exact(model, state):
        return [
            f"the training env ({state['env_type']}) cannot save its state (no get_resume_state: games stepped "
            "through MultiAgentDummyVecEnv or MultiAgentSubprocVecEnv): resuming approximately, the training env "
            "restarts from a reset"
        ]
    return []


class RunCheckpointCallback(BaseCallback):
    """Resumable checkpoints at rollout starts, the restore of a resumed run, and stopping on request.

    At the start of a rollout (after the first, or after the one resumed from), when ``save_freq`` agent-steps have
    passed since the last checkpoint (``save_freq=0``: at every rollout), the model and its resume state
    (:func:`save_checkpoint`) are written to ``folder / name.format(steps=<agent-steps>)``. On the first rollout after
    resuming from a checkpoint, its resume state is restored instead, at the very point it was taken.
    :meth:`request_stop` (e.g. from a Ctrl-C handler) makes the next rollout start write a checkpoint whatever the
    frequency, and training stop there.

    :param folder: where checkpoints go
    :param name: file name of a checkpoint, ``{steps}`` replaced by its agent-steps (e.g. ``"rl_model_{steps}_steps.zip"``)
    :param save_freq: agent-steps between checkpoints (0: every rollout)
    :param resumed_at: agent-steps of the checkpoint resumed from (0 for a fresh start)
    :param resume_state: the checkpoint's resume state, restored at the first rollout start (``None``: nothing to restore)
    :param extras: other objects whose state checkpoints carry, by name (an evaluation callback, ...)
    :param previous_wall_s: wall time of the run before this process (``time/time_elapsed`` and ``time/fps`` go on
        from it after a restore)
    :param on_checkpoint: called with the agent-steps after each checkpoint (e.g. a clock's tick)
    :param log: where resume messages go
    """

    def __init__(
        self,
        folder: str | Path,
        name: str,
        save_freq: int = 0,
        resumed_at: int = 0,
        resume_state: dict[str, Any] | None = None,
        extras: dict[str, Resumable] | None = None,
        previous_wall_s: float | None = None,
        on_checkpoint: Callable[[int], None] | None = None,
        log: Callable[[str], None] = print,
    ) -> None:
        super().__init__()
        if isinstance(save_freq, bool) or not isinstance(save_freq, int) or save_freq < 0:
            raise ValueError(f"save_freq must be an integer >= 0 agent-steps (0: every rollout), got {save_freq!r}.")
        self.folder = Path(folder)
        self.name = name
        self.save_freq = save_freq
        self.resumed_at = resumed_at
        self.resume_state = resume_state
        self.extras = dict(extras or {})
        self.previous_wall_s = previous_wall_s
        self.on_checkpoint = on_checkpoint
        self.log = log
        self.last_saved = resumed_at
        self.stop_requested = False
        self.stop_signal: int | None = None  # the signal that asked for the stop (SIGINT, SIGTERM, SIGHUP)
        self.stopped_at: Path | None = None

    def path(self, steps: int) -> Path:
        """The checkpoint file for ``steps`` agent-steps."""
        return self.folder / self.name.format(steps=steps)

    def request_stop(self, signum: int = signal.SIGINT) -> None:
        """Write a checkpoint at the next rollout start and stop training there.

        :param signum: the signal that asked for it (the command's exit status is 128 + it)
        """
        self.stop_requested = True
        self.stop_signal = int(signum)

    def _on_rollout_start(self) -> None:
        steps = self.model.num_timesteps
        if self.resume_state is not None:  # the first rollout after resuming: the moment the checkpoint was taken
            restore_resume_state(self.model, self.resume_state, self.log, self.extras)
            self.resume_state = None
            if self.previous_wall_s is not None:  # time/time_elapsed and time/fps over all segments
                self.model.start_time = time.time_ns() - int(self.previous_wall_s * 1e9)
            if not self.stop_requested:
                return
        due = steps > self.resumed_at and steps - self.last_saved >= self.save_freq
        if due or self.stop_requested:
            self.save(steps)
            if self.stop_requested:
                self.stopped_at = self.path(steps)

    def save(self, steps: int) -> Path:
        """Write the checkpoint of the current state (call it at a rollout start)."""
        path = self.path(steps)
        self.folder.mkdir(parents=True, exist_ok=True)
        save_checkpoint(self.model, path, self.extras)
        self.last_saved = steps
        if self.on_checkpoint is not None:
            self.on_checkpoint(steps)
        return path

    def _on_step(self) -> bool:
        return self.stopped_at is None


# ---------------------------------------------------------------------------------------------------- progress.csv
class ContinuedCSVOutputFormat(CSVOutputFormat):
    """SB3's CSV writer going on with an existing file (header ``keys`` and its ``rows`` kept) instead of starting a
    new one (SB3 opens with ``"w+"``). When new keys arrive, the file is rewritten with the wider header as SB3 does,
    but atomically (:func:`~sb3_saeir.common.atomic.atomic_write_text`: an interrupt leaves the old rows whole).
    :attr:`rows` counts the rows in the file (a checkpoint records it, see :func:`progress_rows`).

    :param filename: the CSV file
    :param keys: its header (empty: start a new file)
    :param rows: the rows already in it
    """

    def __init__(self, filename: str, keys: list[str], rows: int = 0) -> None:
        # not super().__init__, which opens with "w+" (truncates); the logger closes the file
        self.path = filename
        self.file = open(filename, "r+" if keys else "w+")
        self.file.seek(0, os.SEEK_END)
        self.keys = list(keys)
        self.rows = rows if keys else 0
        self.separator = ","
        self.quotechar = '"'

    def write(self, key_values: dict[str, Any], key_excluded: dict[str, tuple[str, ...]], step: int = 0) -> None:
        new_keys = [key for key in filter_excluded_keys(key_values, key_excluded, "csv") if key not in self.keys]
        try:
            if new_keys:
                self._widen(new_keys)
            super().write(key_values, key_excluded, step)
        except OSError as error:  # a full disk: named by the file
            error.filename = error.filename or self.path
            raise
        self.rows += 1

    def _widen(self, new_keys: list[str]) -> None:
        """Rewrite the file with ``new_keys`` added to the header (and empty cells to every row), atomically."""
        self.file.seek(0)
        lines = self.file.readlines()
        keys = [*self.keys, *new_keys]
        padding = self.separator * len(new_keys)
        text = self.separator.join(keys) + "\n" + "".join(line[:-1] + padding + "\n" for line in lines[1:])
        self.file.close()
        try:
            atomic_write_text(Path(self.path), text)
            self.keys = keys
        finally:  # the old file when the rewrite failed
            self.file = open(self.path, "r+")
            self.file.seek(0, os.SEEK_END)


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


def progress_rows(logger: Logger) -> int | None:
    """The rows in the logger's ``progress.csv`` (``None`` without a :class:`ContinuedCSVOutputFormat`)."""
    return next((output.rows for output in logger.output_formats if isinstance(output, ContinuedCSVOutputFormat)), None)


def _is_row(line: str, keys: list[str], column: int) -> bool:
    """Whether a line of ``progress.csv`` is a whole row: one cell per key and a number (or nothing) as its
    ``time/total_timesteps``."""
    values = next(csv.reader([line]), [])
    if len(values) != len(keys):
        return False
    try:
        float(values[column] or 0)
    except ValueError:
        return False
    return True


def truncate_progress(
    path: Path, done_steps: int, expected_rows: int | None = None, log: Callable[[str], None] = print
) -> tuple[list[str], int]:
    """Keep the rows of a ``progress.csv`` dumped up to the checkpoint and drop later ones (and a last line cut by a
    kill: they are made again). Rows of the checkpoint's that are missing or damaged (the file deleted, cut short or
    edited) cannot be restored: ``log`` says how many, and the damaged file is kept beside it
    (:func:`keep_damaged`) before it is rewritten without them.

    :param path: the run's ``progress.csv``
    :param done_steps: agent-steps of the checkpoint
    :param expected_rows: rows the file held at the checkpoint (``None``, a checkpoint of an older version: the rows up
        to ``done_steps`` agent-steps are kept)
    :param log: where to say what cannot be restored
    :return: the header (empty when there is nothing to keep) and the number of rows kept
    """
    lost = f"the {expected_rows} rows" if expected_rows is not None else "the rows"
    fix = "the run goes on from the checkpoint and writes the rows after it"
    if not path.is_file():
        if expected_rows != 0 and done_steps > 0:
            log(f"{path} is missing: {lost} written up to the checkpoint cannot be restored; {fix}.")
        return [], 0
    lines = path.read_text(errors="replace").split("\n")[:-1]  # after the last newline: a row cut by a kill
    keys = next(csv.reader(lines[:1]), [])
    if "time/total_timesteps" not in keys:  # empty, or the header damaged: no row can be read
        if expected_rows != 0 and done_steps > 0:
            copy = keep_damaged(path)
            log(
                f"{path} has no readable header: {lost} written up to the checkpoint cannot be restored (the file is "
                f"kept as {copy.name}); {fix}."
            )
        return [], 0
    column = keys.index("time/total_timesteps")
    rows = lines[1:] if expected_rows is None else lines[1 : 1 + expected_rows]
    damaged = [number for number, line in enumerate(rows, start=2) if not _is_row(line, keys, column)]
    kept = [line for line in rows if _is_row(line, keys, column)]
    if expected_rows is None:
        kept = [line for line in kept if float(next(csv.reader([line]))[column] or 0) <= done_steps]
    cut_short = 0 if expected_rows is None else expected_rows - len(rows)
    if damaged or cut_short:
        copy = keep_damaged(path)
        reasons = [f"{len(damaged)} damaged (lines {', '.join(map(str, damaged))})"] if damaged else []
        reasons += [f"{cut_short} missing at its end (the file was cut short)"] if cut_short else []
        log(
            f"{path}: {len(damaged) + cut_short} rows written up to the checkpoint cannot be restored "
            f"({'; '.join(reasons)}) and are left out (the damaged file is kept as {copy.name}); {fix}."
        )
    atomic_write_text(path, "".join(line + "\n" for line in [lines[0], *kept]))
    return keys, len(kept)


def progress_logger(
    path: Path,
    done_steps: int | None,
    iteration_offset: int,
    output_formats: list[KVWriter] | None = None,
    expected_rows: int | None = None,
    log: Callable[[str], None] = print,
) -> Logger:
    """The run's logger: its ``progress.csv`` started anew (``done_steps`` ``None``) or continued after its rows up to
    the checkpoint (:func:`truncate_progress`), plus ``output_formats`` (stdout, tensorboard, ...).

    :param path: the run's ``progress.csv``
    :param done_steps: agent-steps of the checkpoint resumed from, ``None`` for a fresh start
    :param iteration_offset: rollouts done before the checkpoint
    :param output_formats: the logger's other writers
    :param expected_rows: rows ``progress.csv`` held at the checkpoint (its resume state's ``progress_rows``)
    :param log: where to say which rows cannot be restored
    """
    keys, rows = truncate_progress(path, done_steps, expected_rows, log) if done_steps is not None else ([], 0)
    formats: list[KVWriter] = [*(output_formats or []), ContinuedCSVOutputFormat(str(path), keys, rows)]
    return ContinuedLogger(str(path.parent), formats, iteration_offset)


# ---------------------------------------------------------------------------------------------------- wall time
def _seconds(value: Any) -> bool:
    """Whether a record's value is a wall time: a finite number of seconds >= 0 (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value >= 0


class SegmentClock:
    """Wall time of a run over its segments (one per process that worked on it), kept in ``segments.json``.

    A segment's time is recorded at each checkpoint, evaluation and at the end; a killed segment counts up to its
    last record.

    :param path: the run's ``segments.json``
    :param resumed_at: agent-steps this segment starts from
    :param log: where a damaged ``segments.json`` is told (it is kept aside and the record starts again)
    """

    def __init__(self, path: Path, resumed_at: int, log: Callable[[str], None] | None = None) -> None:
        self.path = path
        self.segments: list[dict[str, Any]] = self._read(log)
        self.previous_s = float(sum(segment["wall_s"] for segment in self.segments))
        self.start = time.time()
        segment = {"started": utc_stamp(), "resumed_at": resumed_at, "reached": resumed_at, "wall_s": 0.0}
        self.segments.append({**segment, "version": PACKAGE_VERSION})  # which version trained each segment
        self.tick(resumed_at)

    def _read(self, log: Callable[[str], None] | None) -> list[dict[str, Any]]:
        """The recorded segments; a damaged file (not a JSON list of segments with their ``wall_s``) is kept aside as
        ``segments.json.damaged-<UTC time>`` and the record starts again with this segment."""
        if not self.path.is_file():
            return []
        try:
            segments = json.loads(self.path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError):
            segments = None
        if isinstance(segments, list) and all(isinstance(item, dict) and _seconds(item.get("wall_s")) for item in segments):
            return segments
        copy = keep_damaged(self.path)
        if log is not None:
            log(f"{self.path.name} is damaged: kept as {copy.name}; the wall-time record starts again at this segment")
        return []

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
