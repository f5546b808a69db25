"""One training run in its folder: :class:`Run` owns the folder's files, the settings record and its comparison on
resume, the resume point, the checkpoints, the evaluations, the logger, Ctrl-C and the final save.

``python -m sb3_saeir.train`` (rl-zoo's ``<log-folder>/<algo>/<task>_<N>/``) and ``python -m sb3_saeir.benchmark``
(``<out>/runs/<algo>/<task>_s<seed>/``) put their runs in different places and are thin callers of :class:`Run`; the
inside of a run folder is the same for both (``docs/guide/training.md``, "The run folder"):

- ``spec.json``: the settings record (:class:`RunSpec`: method, task, seed, budget, games, evaluation, overrides, the
  config entry it trains with, the command's other settings, the package version), compared on every resume
  (:func:`spec_differences`); ``<task>/config.yml`` and ``<task>/args.yml`` as rl-zoo3 writes them;
- ``rl_model_<steps>_steps.zip``: resumable checkpoints (:mod:`sb3_saeir.common.run_state`);
- ``evaluations.csv`` (one row per evaluation), ``evaluations.npz`` and ``best_model.zip`` (SB3's evaluation files):
  evaluations at the start, at the first agent-step count >= k * ``eval_freq`` (k = 1, 2, ...) and at the end, each
  on the same episodes (the eval env is reseeded before each);
- ``progress.csv`` (SB3's logger, continued over resumes), ``games.monitor.csv`` (one row per finished game),
  ``segments.json`` (wall time of each process that worked on the run), ``resume.log`` (what each resume did);
- ``<task>.zip`` and ``done.json`` when finished (the final model, with the resume state of its last step, from
  which a larger budget continues: "Training a run longer"; total wall time and agent-steps).

Run folders written before this layout resume too: a benchmark run's ``checkpoint.zip`` is read as its newest
checkpoint, and a ``train`` run without ``spec.json`` is compared through its ``args.yml`` and ``config.yml``.
"""

from __future__ import annotations

import csv
import errno
import inspect
import io
import json
import shutil
import signal
import sys
import threading
import time
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import KVWriter
from stable_baselines3.common.utils import configure_logger

from sb3_saeir.common.atomic import atomic_write_text, keep_damaged, unused_name
from sb3_saeir.common.run_state import (
    RunCheckpointCallback,
    SegmentClock,
    capture_resume_state,
    checkpoint_problem,
    describe_resume,
    is_exact,
    load_resume_state,
    progress_logger,
    save_checkpoint,
    utc_stamp,
)
from sb3_saeir.common.vec_env import MultiAgentVecMonitor
from sb3_saeir.config import ConfigError, load_hyperparams
from sb3_saeir.evaluation import MultiAgentEvalCallback
from sb3_saeir.experiment import EVAL_SEED_OFFSET, Experiment, numbered_paths

# Files of a run folder.
SPEC_FILE = "spec.json"
CHECKPOINT_NAME = "rl_model_{steps}_steps.zip"
LEGACY_CHECKPOINT = "checkpoint.zip"  # the benchmark's one checkpoint before this layout: read, never written
EVALUATIONS_FILE = "evaluations.csv"
DONE_FILE = "done.json"
SEGMENTS_FILE = "segments.json"
RESUME_LOG = "resume.log"
MONITOR_PREFIX = "games"  # -> games.monitor.csv
# Settings of a RunSpec compared on resume, by their command-line names.
SPEC_SETTINGS = {
    "n_timesteps": "-n",
    "n_games": "--n-games",
    "eval_freq": "--eval-freq",
    "eval_episodes": "--eval-episodes",
    "params": "-params",
}
# What a smaller budget than a run's record is told (a larger one trains the run longer).
SHORTER = " (a run is not trained shorter; a larger -n trains it longer)"
# Config keys a resume does not compare: mirrored by a setting (n_envs: --n-games, n_timesteps: -n), or a setting of
# the machine, not of what is trained (compile).
UNCOMPARED_CONFIG_KEYS = ("n_envs", "n_timesteps", "compile")
# -params keys that may change at a resume: settings of the machine (docs/guide/training.md).
RESUME_FREE_PARAMS = ("compile",)
# errno values of a write that failed for want of space.
NO_SPACE_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


class RunStoppedError(RuntimeError):
    """Training stopped by the system (a full disk): the message names the run's folder and the checkpoint to resume
    from."""


# ---------------------------------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class RunSpec:
    """One training run's settings: what its ``spec.json`` records and a resume compares.

    :param algo: the method
    :param task: the task id
    :param seed: the seed
    :param n_timesteps: the run's budget in agent-steps
    :param n_games: games (``None``: the config's ``n_envs``)
    :param eval_freq: agent-steps between evaluations (0: none)
    :param eval_episodes: game episodes per evaluation
    :param params: config overrides (``-params``)
    :param config: the config entry it trains with (overrides applied); ``None``: the packaged entry of ``algo`` and
        ``task`` with ``params`` applied, read when needed (:meth:`resolved_config`)
    :param options: the command's other settings that a resume must repeat, by their flags (``--save-freq``, ...)
    """

    algo: str
    task: str
    seed: int
    n_timesteps: int
    n_games: int | None = None
    eval_freq: int = 50_000
    eval_episodes: int = 20
    params: dict[str, Any] = field(default_factory=dict, hash=False, compare=False)
    config: dict[str, Any] | None = field(default=None, hash=False, compare=False)
    options: dict[str, Any] = field(default_factory=dict, hash=False, compare=False)

    @property
    def name(self) -> str:
        return f"{self.algo}/{self.task}_s{self.seed}"

    def resolved_config(self) -> dict[str, Any]:
        """The config entry the run trains with: ``config``, else the packaged entry with ``params`` applied."""
        if self.config is not None:
            return dict(self.config)
        return {**load_hyperparams(self.algo, self.task), **self.params}


def _jsonable(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples become lists, unknown objects their ``str``)."""
    return json.loads(json.dumps(value, sort_keys=True, default=str))


def spec_record(spec: RunSpec) -> dict[str, Any]:
    """What a run's ``spec.json`` holds: its settings, the config entry it trains with, the package version
    (``options`` only when the command has any)."""
    from sb3_saeir import __version__

    record = {**asdict(spec), "config": spec.resolved_config(), "version": __version__}
    if not spec.options:
        del record["options"]
    return _jsonable(record)


def _show(value: Any) -> str:
    return "(unset)" if value is None else json.dumps(value, sort_keys=True)


def spec_differences(stored: dict[str, Any], planned: dict[str, Any], ignored: tuple[str, ...] = ()) -> list[str]:
    """What differs between a run's stored settings record and the planned run, as ``"<setting> <old> -> <new>"``.

    The package version is recorded, not compared; config keys set by ``-params`` are reported once, as ``-params``;
    :data:`UNCOMPARED_CONFIG_KEYS` are not compared; a larger budget than the record's is no difference (the run is
    trained longer: :func:`extended_budget`), a smaller one is.

    :param stored: the run's ``spec.json`` (or :func:`legacy_train_record`)
    :param planned: :func:`spec_record` of the planned run
    :param ignored: flags of ``options`` not compared (``-f`` for a run resumed by its folder's path)
    """
    differences = [
        f"{key} {_show(stored.get(key))} -> {_show(planned[key])}"
        for key in ("algo", "task", "seed")
        if stored.get(key) != planned[key]
    ]
    compared = {**stored, "params": _compared_params(stored.get("params"))}
    planned_compared = {**planned, "params": _compared_params(planned["params"])}
    differences += [
        f"{flag} {_show(compared.get(key))} -> {_show(planned_compared[key])}{_shorter(key, stored)}"
        for key, flag in SPEC_SETTINGS.items()
        if compared.get(key) != planned_compared[key] and not (key == "n_timesteps" and extended_budget(stored, planned[key]))
    ]
    old_options, new_options = stored.get("options") or {}, planned.get("options") or {}
    differences += [
        f"{flag} {_show(old_options.get(flag))} -> {_show(new_options.get(flag))}"
        for flag in sorted((set(old_options) | set(new_options)) - set(ignored))
        if old_options.get(flag) != new_options.get(flag)
    ]
    old_config, new_config = stored.get("config") or {}, planned["config"]
    skipped = set(stored.get("params") or {}) | set(planned["params"]) | set(UNCOMPARED_CONFIG_KEYS)
    differences += [
        f"config {key} {_show(old_config.get(key))} -> {_show(new_config.get(key))}"
        for key in sorted((set(old_config) | set(new_config)) - skipped)
        if old_config.get(key) != new_config.get(key)
    ]
    return differences


def _compared_params(params: Any) -> Any:
    """``-params`` as a resume compares them: without :data:`RESUME_FREE_PARAMS` (``None`` stays ``None``)."""
    if not isinstance(params, dict):
        return params
    return {key: value for key, value in params.items() if key not in RESUME_FREE_PARAMS}


def _shorter(key: str, stored: dict[str, Any]) -> str:
    """:data:`SHORTER` for a budget that differs from a record's budget (it is smaller: a larger one is no difference)."""
    budget = stored.get(key)
    return SHORTER if key == "n_timesteps" and isinstance(budget, (int, float)) and not isinstance(budget, bool) else ""


def extended_budget(stored: dict[str, Any], n_timesteps: int) -> int | None:
    """The budget a run's record holds when ``n_timesteps`` is larger (the run is to be trained longer, an extension),
    ``None`` when it is not larger (or the record holds no budget).

    :param stored: the run's settings record
    :param n_timesteps: the budget of the command
    """
    budget = stored.get("n_timesteps")
    if isinstance(budget, (int, float)) and not isinstance(budget, bool) and n_timesteps > budget:
        return int(budget)
    return None


def extension_record(stored: dict[str, Any], n_timesteps: int, finished: dict[str, Any] | None) -> dict[str, Any]:
    """A run's settings record after an extension to ``n_timesteps``: the new budget, and the extension appended to
    its ``extensions`` (the budget before, the new one, when, and the ``done.json`` of the shorter run if it finished).

    :param stored: the run's settings record before
    :param n_timesteps: the new budget
    :param finished: the shorter run's ``done.json`` (``None``: it had not finished)
    """
    record = json.loads(json.dumps(stored))
    extension = {"from": record["n_timesteps"], "to": n_timesteps, "at": utc_stamp(), "finished": finished}
    record["n_timesteps"] = n_timesteps
    if isinstance(record.get("config"), dict) and "n_timesteps" in record["config"]:
        record["config"]["n_timesteps"] = n_timesteps
    record["extensions"] = [*record.get("extensions", []), extension]
    return record


def read_spec_file(folder: Path) -> dict[str, Any] | None:
    """A run folder's ``spec.json`` (``None`` when there is none).

    :raises ~sb3_saeir.config.ConfigError: when it is not a JSON object
    """
    path = folder / SPEC_FILE
    if not path.is_file():
        return None
    try:
        record = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ConfigError(f"{path} is damaged (not valid JSON: {error}); restore it from a copy.") from None
    if not isinstance(record, dict):
        raise ConfigError(f"{path} is damaged (not a JSON object); restore it from a copy.")
    return record


# ---------------------------------------------------------------------------------------------------- row files
def read_rows(path: Path) -> list[dict[str, Any]]:
    """The rows of a CSV file, numbers as numbers (``[]`` when there is no file)."""
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


def same_row(row: dict[str, Any], other: dict[str, Any]) -> bool:
    """Whether two evaluation rows hold the same values (as written to CSV and read back)."""
    return {key: _number(str(value)) for key, value in row.items()} == {
        key: _number(str(value)) for key, value in other.items()
    }


class RunLog:
    """What a run says about itself (resumes, skipped checkpoints, rows that cannot be restored): printed, with the
    run's name when it has one, and appended to its ``resume.log``.

    :param folder: the run's folder
    :param name: the run's name in printed lines (``""``: lines start with ``Note:``)
    """

    def __init__(self, folder: Path, name: str = "") -> None:
        self.path = folder / RESUME_LOG
        self.name = name

    def __call__(self, message: str) -> None:
        print(f"{self.name}: {message}" if self.name else f"Note: {message}", flush=True)
        with open(self.path, "a") as file:
            file.write(f"{utc_stamp()} {message}\n")


# ---------------------------------------------------------------------------------------------------- evaluation
class RunEvalCallback(MultiAgentEvalCallback):
    """A run's evaluations: at the first agent-step count >= k * ``eval_freq`` (on the grid whether or not the run was
    resumed), each on the same episodes (the eval env is reseeded with ``eval_seed`` first); each becomes a row of
    ``evaluations.csv``, and ``evaluations.npz`` and ``best_model.zip`` are kept as SB3's ``EvalCallback`` keeps them.

    :param eval_env: the evaluation env
    :param spec: the run
    :param folder: the run's folder
    :param rows: evaluation rows already recorded (kept on resume)
    :param n_agents: agents per game (``env_steps = agent-steps / n_agents``)
    :param main_metric: the task's main metric
    :param eval_seed: seed given to the eval env before every evaluation
    :param lost_rows: rows made after the checkpoint by an interrupted segment, by agent-steps: they are re-done
    :param clock: the run's wall-time record
    :param log: the run's log
    :param verbose: print each evaluation's main metric
    """

    def __init__(
        self,
        eval_env: Any,
        spec: RunSpec,
        folder: Path,
        rows: list[dict[str, Any]],
        n_agents: int,
        main_metric: str,
        eval_seed: int,
        lost_rows: dict[int, dict[str, Any]],
        clock: SegmentClock,
        log: Callable[[str], None],
        verbose: int = 0,
    ) -> None:
        super().__init__(
            eval_env,
            spec.eval_episodes,
            spec.eval_freq,
            main_metric=main_metric,
            log_path=str(folder),
            best_model_save_path=str(folder),
            verbose=verbose,
        )
        self.spec = spec
        self.evaluations_path = folder / EVALUATIONS_FILE
        self.rows = rows
        self.n_agents = n_agents
        self.eval_seed = eval_seed
        self.lost_rows = dict(lost_rows)
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
        self.eval_env.seed(self.eval_seed)  # every evaluation plays the same episodes
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
        self.clock.tick(self.num_timesteps)
        return keep_going

    def get_resume_state(self) -> dict[str, Any]:
        return {**super().get_resume_state(), "next_eval": self.next_eval}

    def set_resume_state(self, state: dict[str, Any]) -> None:
        super().set_resume_state(state)
        self.next_eval = int(state.get("next_eval", self.grid_after(self.last_eval_timestep)))


def split_rows(
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
    if old_rows:
        write_rows(path, rows)
    return rows, lost


# ---------------------------------------------------------------------------------------------------- checkpoints
def checkpoint_steps(folder: str | Path) -> dict[int, Path]:
    """The resumable checkpoints of a run folder, by agent-steps: ``rl_model_<steps>_steps.zip``, and a benchmark
    run's ``checkpoint.zip`` of the older layout (its agent-steps read from the zip)."""
    prefix, suffix = CHECKPOINT_NAME.split("{steps}")
    found = numbered_paths(folder, prefix, suffix)
    legacy = Path(folder) / LEGACY_CHECKPOINT
    if legacy.is_file():
        steps = saved_timesteps(legacy)
        found.setdefault(steps if steps is not None else -1, legacy)
    return found


def saved_timesteps(path: Path) -> int | None:
    """The agent-steps a saved model zip records (``num_timesteps`` in its ``data``), without loading it (``None``
    when the zip cannot be read)."""
    try:
        with zipfile.ZipFile(path) as archive:
            return int(json.loads(archive.read("data"))["num_timesteps"])
    except Exception:  # a damaged zip: checkpoint_problem names the damage
        return None


def newest_loading_checkpoint(folder: Path, final_model: Path | None = None) -> tuple[Path | None, list[tuple[Path, str]]]:
    """The newest checkpoint of a run folder that loads (``None``: none does), and the newer ones that do not, with
    why (:func:`~sb3_saeir.common.run_state.checkpoint_problem`).

    :param folder: the run's folder
    :param final_model: the run's final model (``<task>.zip``): a resume point too when it holds a resume state (a
        finished run's, written before its final evaluation) and is newer than the checkpoints
    """
    checkpoints = checkpoint_steps(folder)
    if final_model is not None and final_model.is_file() and not checkpoint_problem(final_model):
        steps = saved_timesteps(final_model)
        if steps is not None and steps not in checkpoints and load_resume_state(final_model) is not None:
            checkpoints[steps] = final_model
    skipped: list[tuple[Path, str]] = []
    for steps in sorted(checkpoints, reverse=True):
        problem = checkpoint_problem(checkpoints[steps])
        if not problem:
            return checkpoints[steps], skipped
        skipped.append((checkpoints[steps], problem))
    return None, skipped


def keep_damaged_checkpoints(skipped: list[tuple[Path, str]]) -> None:
    """Move checkpoints that do not load aside (``<name>.damaged-<UTC time>``; nothing deleted), so that the run's
    next checkpoints do not sit beside them (a folder in a checkpoint's name is renamed aside whole)."""
    for path, _ in skipped:
        if path.is_dir():
            path.rename(unused_name(path, "damaged"))
            continue
        keep_damaged(path)
        path.unlink()


@dataclass(frozen=True)
class ResumePoint:
    """Where a run continues: its last checkpoint that loads and the checkpoint's resume state.

    :param checkpoint: the checkpoint
    :param state: its resume state (``None``: a plain model zip, resumed approximately)
    :param skipped: the newer checkpoints that do not load, with why (the resume falls back past them)
    """

    checkpoint: Path
    state: dict[str, Any] | None
    skipped: tuple[tuple[Path, str], ...] = ()

    @property
    def steps(self) -> int:
        """Agent-steps of the checkpoint."""
        steps = self.state["num_timesteps"] if self.state is not None else saved_timesteps(self.checkpoint)
        return int(steps or 0)

    def total_timesteps(self, n_timesteps: int) -> int:
        """The agent-step count at which the run ends: where its ``learn`` started (0, or a ``-i`` model's count)
        plus its budget ``n_timesteps``."""
        start = self.state["model"].get("_num_timesteps_at_start", 0) if self.state is not None else 0
        return int(start) + n_timesteps


# What <task>/args.yml and <task>/config.yml hold, for the message on a damaged one.
RUN_FILES = {
    "args.yml": "the command line that started the run, one 'option: value' line per option",
    "config.yml": "the run's resolved hyperparameters, one 'key: value' line per key",
}


def read_run_file(path: Path) -> dict[str, Any]:
    """A run's ``<task>/args.yml`` or ``<task>/config.yml``: a YAML mapping (``args.yml`` with an integer ``seed``).

    :param path: the file
    :raises ~sb3_saeir.config.ConfigError: naming the file, what is wrong with it and the fix
    """
    try:
        content = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = f"not valid YAML{where}: {getattr(error, 'problem', None) or error}"
    else:
        problem = ""
        if not isinstance(content, dict) or not content:
            problem = f"not a mapping of {path.stem}, but {type(content).__name__} {str(content)[:40]!r}"
        elif path.name == "args.yml" and (isinstance(content.get("seed"), bool) or not isinstance(content.get("seed"), int)):
            problem = f"no integer seed (seed: {content.get('seed')!r})"
    if problem:
        raise ConfigError(
            f"--resume: {path} is damaged ({problem}). It holds {RUN_FILES[path.name]}: restore it from a copy, or "
            f"write it again as another run's {path.name} (the run's own values), then resume; or start a new run "
            "without --resume."
        )
    return content


def stored_record(
    folder: Path, algo: str, task: str, legacy_record: Callable[[dict[str, Any], dict[str, Any]], dict[str, Any]]
) -> dict[str, Any]:
    """The settings record of the run in ``folder``: its ``spec.json``, or for a run of an older version its
    ``<task>/args.yml`` and ``<task>/config.yml`` made into one by ``legacy_record``.

    :param folder: the run's folder
    :param algo: the method of the command
    :param task: the task of the command (``<task>/`` holds the older files)
    :param legacy_record: the record of an older run from its ``args.yml`` and ``config.yml``
    :raises ~sb3_saeir.config.ConfigError: when the folder holds no run of this command, or its record is damaged
    """
    try:
        record = read_spec_file(folder)
    except ConfigError as error:
        raise ConfigError(f"--resume: {error}") from None
    if record is not None:
        if (record.get("algo"), record.get("task")) != (algo, task):
            raise ConfigError(
                f"--resume: {folder} holds a run of {record.get('algo')} on {record.get('task')}: it is not a run of this "
                "command."
            )
        return record
    args_path = folder / task / "args.yml"
    if not args_path.is_file():
        raise ConfigError(f"--resume: {folder} has no {SPEC_FILE} nor {task}/args.yml: it is not a run of this command.")
    stored_args = read_run_file(args_path)
    return legacy_record(stored_args, read_run_file(folder / task / "config.yml"))


# ---------------------------------------------------------------------------------------------------- the run
@dataclass
class RunOutput:
    """How a run shows itself while it trains.

    :param formats: the logger's writers besides ``progress.csv`` (stdout, tensorboard)
    :param progress_bar: SB3's progress bar
    :param verbose: print each evaluation
    :param stop_on_ctrl_c: the first Ctrl-C writes a checkpoint and stops cleanly (main thread only)
    :param callbacks: more callbacks of the caller (an ETA line, ...)
    """

    formats: list[KVWriter] = field(default_factory=list)
    progress_bar: bool = False
    verbose: int = 0
    stop_on_ctrl_c: bool = False
    callbacks: list[BaseCallback] = field(default_factory=list)


def command_output(model: Any, verbose: int, progress_bar: bool, continued: bool, callbacks: list[BaseCallback]) -> RunOutput:
    """How a run of a command line shows itself: SB3's stdout (``verbose`` >= 1) and tensorboard (the model's
    ``tensorboard_log``) writers, the latter going on in the latest ``<tb_log_name>_<N>`` folder when ``continued``
    (as SB3's ``reset_num_timesteps=False`` does), the progress bar, Ctrl-C's checkpoint and the command's callbacks.

    :param model: the run's model
    :param verbose: the command's verbosity
    :param progress_bar: SB3's progress bar
    :param continued: the run or its model goes on (``--resume``, ``-i``)
    :param callbacks: more callbacks (an ETA line, ...)
    """
    tb_log_name = inspect.signature(type(model).learn).parameters["tb_log_name"].default
    sb3_logger = configure_logger(verbose, model.tensorboard_log, tb_log_name, reset_num_timesteps=not continued)
    formats = [output for output in sb3_logger.output_formats if type(output).__name__ != "CSVOutputFormat"]
    return RunOutput(formats, progress_bar, verbose, True, callbacks)


class Run:
    """One training run in its folder (this module's docstring lists the files).

    Build it with a folder and a :class:`RunSpec`, then :meth:`open` it (checks the settings against the folder's
    record, finds the resume point) and :meth:`start` it on a built experiment; :meth:`train` trains to the budget and
    writes the final model and ``done.json``. ``python -m sb3_saeir.train`` and the benchmark use it the same way.

    :param folder: the run's folder (created by the caller)
    :param spec: the run's settings
    :param save_freq: agent-steps between checkpoints (0: at every rollout start)
    :param keep_checkpoints: checkpoints kept (the newest; ``None``: all, as SB3's ``CheckpointCallback``)
    :param command: the command as ``<task>/args.yml`` records it (rl-zoo3's file)
    :param continue_model: the model was loaded to be trained on (``-i``): its agent-step count goes on
    :param log: where the run says what happens (default: printed and appended to ``resume.log``)
    """

    def __init__(
        self,
        folder: Path,
        spec: RunSpec,
        save_freq: int = 0,
        keep_checkpoints: int | None = None,
        command: dict[str, Any] | None = None,
        continue_model: bool = False,
        log: Callable[[str], None] | None = None,
    ) -> None:
        self.folder = Path(folder)
        self.spec = spec
        self.save_freq = save_freq
        self.keep_checkpoints = keep_checkpoints
        self.command = dict(command or {})
        self.continue_model = continue_model
        self.target_timesteps = spec.n_timesteps
        self.log = log if log is not None else RunLog(self.folder)
        self.resume: ResumePoint | None = None
        self.stored: dict[str, Any] | None = None
        self.extended_from: int | None = None
        self.skipped: list[tuple[Path, str]] = []
        self.experiment: Experiment | None = None
        self.checkpoints: RunCheckpointCallback | None = None
        self.evaluator: RunEvalCallback | None = None
        self.clock: SegmentClock | None = None
        self.callbacks: list[BaseCallback] = []
        self.output = RunOutput()

    # ------------------------------------------------------------------------------------------------ settings
    @property
    def is_done(self) -> bool:
        """Whether the run is finished (``done.json``)."""
        return (self.folder / DONE_FILE).is_file()

    @property
    def final_model(self) -> Path:
        """The run's final model, ``<task>.zip`` (with the resume state of its last step: :meth:`train`)."""
        return self.folder / f"{self.spec.task}.zip"

    def check_budget(self, stored: dict[str, Any]) -> None:
        """Compare the command's budget with the run's record: the same, or larger (the run is trained longer, an
        extension: :attr:`extended_from` is the record's budget, and :meth:`write_spec` records the extension); a
        smaller one is refused.

        :param stored: the run's settings record
        :raises ~sb3_saeir.config.ConfigError: for a smaller budget
        """
        budget = stored.get("n_timesteps")
        if isinstance(budget, (int, float)) and self.spec.n_timesteps < budget:
            raise ConfigError(
                f"--resume: -n {self.spec.n_timesteps:,} is smaller than the budget of the run in {self.folder} "
                f"({int(budget):,} agent-steps): a run is not shortened. Give -n {int(budget)} (or more, to train it "
                "longer)."
            )
        self.stored = stored
        self.extended_from = extended_budget(stored, self.spec.n_timesteps)

    def check_resumable(self, stored: dict[str, Any]) -> None:
        """Find where ``--resume`` continues the run (:meth:`open`: its newest checkpoint that loads, or its final
        model); refuse a smaller budget than the record's (:meth:`check_budget`), a run with nothing to resume from,
        or a finished one whose budget the command does not raise.

        :param stored: the run's settings record (:func:`stored_record`)
        :raises ~sb3_saeir.config.ConfigError: naming the run and the fix
        """
        self.check_budget(stored)
        folder, final = self.folder, self.final_model
        point = self.open()
        if point is None and not self.skipped:
            pattern = CHECKPOINT_NAME.format(steps="<steps>")
            if final.is_file():
                raise ConfigError(
                    f"--resume: {folder} has no checkpoint ({pattern}) and its final model {final.name} holds no resume "
                    f"state (written by an older version): continue that model with -i {final} instead (a fresh state)."
                )
            raise ConfigError(
                f"--resume: {folder} has no checkpoint ({pattern}) and no final model: nothing to resume from (a run "
                "writes checkpoints with --save-freq and on Ctrl-C). Start a new run without --resume."
            )
        if point is None:
            problems = "; ".join(f"{path.name}: {why}" for path, why in self.skipped)
            fix = f"continue its model with -i {final}" if final.is_file() else "start a new run without --resume"
            raise ConfigError(f"--resume: no checkpoint of {folder} loads ({problems}); {fix}.")
        if point.state is None:
            raise ConfigError(
                f"--resume: {point.checkpoint} has no resume state (written by an older version): continue it with -i instead."
            )
        final_steps = saved_timesteps(final) if final.is_file() else None
        target = point.total_timesteps(self.spec.n_timesteps)
        if point.steps >= target or (final_steps is not None and final_steps >= target):
            raise ConfigError(
                f"--resume: {folder} is finished ({final.name} at {final_steps or point.steps:,} agent-steps, its budget "
                f"{self.spec.n_timesteps:,}); give a larger -n to train it longer."
            )

    def check_settings(self, stored: dict[str, Any], by_path: bool) -> None:
        """Refuse to continue the run with other settings than its record's (one line per setting; ``-f`` is not
        compared for a run given by its folder's path; a larger budget is an extension, :meth:`check_budget`).

        :param stored: the run's settings record (:func:`stored_record`)
        :param by_path: the run was given by its folder's path (``--resume FOLDER``)
        :raises ~sb3_saeir.config.ConfigError: naming what differs and the fix
        """
        differences = spec_differences(stored, spec_record(self.spec), ignored=("-f",) if by_path else ())
        if differences:
            moved = any(difference.startswith("-f ") for difference in differences)
            hint = f" If the run folder was moved, give its path instead: --resume {self.folder}." if moved else ""
            raise ConfigError(
                f"--resume: {self.folder} was made with other settings: {'; '.join(differences)}. Fix: resume with the "
                f"command that started it, or start a new run without --resume.{hint}"
            )

    def write_spec(self) -> None:
        """Write ``spec.json`` (unless the folder has one), ``<task>/config.yml`` and ``<task>/args.yml``; for an
        extension (:meth:`check_budget`), record it in ``spec.json`` (:func:`extension_record`) and keep the shorter
        run's final model as ``<task>_<steps>_steps.zip`` (its ``done.json`` goes into the record)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        if self.extended_from is not None and self.stored is not None:
            self._record_extension(self.stored)
        if not (self.folder / SPEC_FILE).is_file():
            atomic_write_text(self.folder / SPEC_FILE, json.dumps(spec_record(self.spec), indent=2, sort_keys=True) + "\n")
        params_path = self.folder / self.spec.task
        if not (params_path / "config.yml").is_file():
            params_path.mkdir(exist_ok=True)
            save_run_config(params_path, self.spec.resolved_config(), self.command)

    def _record_extension(self, stored: dict[str, Any]) -> None:
        done_path, final = self.folder / DONE_FILE, self.final_model
        finished = json.loads(done_path.read_text()) if done_path.is_file() else None
        if finished is not None and final.is_file():
            steps = saved_timesteps(final)
            kept = final.with_name(f"{self.spec.task}_{steps}_steps.zip")
            if not kept.exists():
                shutil.copy2(final, kept)
        record = extension_record(stored, self.spec.n_timesteps, finished)
        done_path.unlink(missing_ok=True)  # first: a run killed before the new record is a run not yet finished
        atomic_write_text(self.folder / SPEC_FILE, json.dumps(record, indent=2, sort_keys=True) + "\n")
        self.log(f"trained longer: budget {self.extended_from:,} -> {self.spec.n_timesteps:,} agent-steps")
        self.stored, self.extended_from = record, None

    # ------------------------------------------------------------------------------------------------ start
    def open(self) -> ResumePoint | None:
        """Find where the run continues: its newest checkpoint that loads, or its final model if that is newer and
        holds a resume state (:attr:`resume`; ``None``: the run starts from the beginning). The newer ones that do not
        load are :attr:`skipped`; :meth:`start` names them in the log and moves them aside. Nothing is written here.

        :return: the resume point
        """
        checkpoint, skipped = newest_loading_checkpoint(self.folder, self.final_model)
        self.skipped = skipped
        self.resume = ResumePoint(checkpoint, load_resume_state(checkpoint), tuple(skipped)) if checkpoint else None
        return self.resume

    def make_env(self, experiment: Experiment) -> MultiAgentVecMonitor:
        """The run's training env: the experiment's, monitored into ``games.monitor.csv`` (continued on resume)."""
        return MultiAgentVecMonitor(
            experiment.make_env(),
            str(self.folder / MONITOR_PREFIX),
            env_id=self.spec.task,
            append=self.resume is not None,
            log=self.log,
        )

    def start(self, experiment: Experiment, output: RunOutput | None = None) -> None:
        """Set the run up on ``experiment``, whose model is built (or loaded) on :meth:`make_env`'s env: load the
        resume point's checkpoint, continue the logger, the wall-time record and the evaluations, make the
        checkpoints.

        :param experiment: the run's experiment, built
        :param output: how the run shows itself (default: quietly)
        """
        assert experiment.model is not None and experiment.env is not None
        self.experiment = experiment
        self.output = output if output is not None else RunOutput()
        resume = self.resume
        if self.skipped:
            self._keep_skipped_aside()
        state = None
        if resume is not None:
            model = experiment.model
            state = experiment.resume(resume.checkpoint, device=str(model.device), tensorboard_log=model.tensorboard_log)
            state = self._for_this_env(state)
            self.log(f"resumed from the checkpoint at {resume.steps} agent-steps ({resume.checkpoint.name})")
            for message in describe_resume(experiment.model, state):
                self.log(message)
        model = experiment.model
        done_steps = resume.steps if resume is not None else None
        if resume is not None:
            self.target_timesteps = resume.total_timesteps(self.spec.n_timesteps)
        else:
            self.target_timesteps = (model.num_timesteps if self.continue_model else 0) + self.spec.n_timesteps
        self.clock = SegmentClock(self.folder / SEGMENTS_FILE, done_steps or 0)
        rollout = int(getattr(model, "n_steps", 1)) * experiment.env.num_envs
        expected_rows = state.get("progress_rows") if state is not None else None
        offset = (done_steps or 0) // rollout
        model.set_logger(progress_logger(self.folder, done_steps, offset, self.output.formats, expected_rows, self.log))
        extras: dict[str, Any] = {}
        self.callbacks = []
        if self.spec.eval_freq > 0:
            self.evaluator = self._evaluator(experiment, done_steps)
            extras["evaluation"] = self.evaluator
            self.callbacks.append(self.evaluator)
        self.checkpoints = RunCheckpointCallback(
            self.folder,
            CHECKPOINT_NAME,
            save_freq=self.save_freq,
            resumed_at=done_steps or 0,
            resume_state=state,
            extras=extras,
            previous_wall_s=self.clock.previous_s,
            on_checkpoint=self._on_checkpoint,
            log=self.log,
        )
        self.callbacks.insert(0, self.checkpoints)
        if resume is not None and not is_exact(model, state):  # approximate: learn() resets the env and the states
            model._last_obs = None  # type: ignore[assignment]

    def _keep_skipped_aside(self) -> None:
        """Name the checkpoints that do not load in the log and move them aside (``<name>.damaged-<UTC time>``)."""
        damaged = "; ".join(f"{path.name} does not load ({why})" for path, why in self.skipped)
        fallback = f"resuming from {self.resume.checkpoint.name}" if self.resume else "the run starts over from the beginning"
        keep_damaged_checkpoints(self.skipped)
        self.log(f"skipped the newest checkpoint(s): {damaged}; kept aside as <name>.damaged-<UTC time>; {fallback}")
        self.skipped = []

    def _for_this_env(self, state: dict[str, Any] | None) -> dict[str, Any] | None:
        """A resume state taken on the bare training env (a benchmark checkpoint of the older layout, with no monitor
        around its env) made fit for the monitored env: the monitor starts with no records."""
        assert self.experiment is not None and self.experiment.env is not None
        env = self.experiment.env
        if state is None or state["env"] is None or not isinstance(env, MultiAgentVecMonitor) or "venv" in state["env"]:
            return state
        self.log(f"the checkpoint has no monitor records: {MONITOR_PREFIX}.monitor.csv starts at the resume")
        monitor_state = {"venv": state["env"], "episodes": [], "n_finished_games": 0, "t_start": time.time()}
        return {**state, "env": monitor_state}

    def _evaluator(self, experiment: Experiment, done_steps: int | None) -> RunEvalCallback:
        assert experiment.env is not None and self.clock is not None
        eval_seed = EVAL_SEED_OFFSET + self.spec.seed
        rows, lost = split_rows(self.folder / EVALUATIONS_FILE, done_steps, self.log)
        return RunEvalCallback(
            experiment.make_eval_env(self.spec.eval_episodes, seed=eval_seed),
            self.spec,
            self.folder,
            rows,
            experiment.env.num_envs // experiment.n_games,
            experiment.main_metric,
            eval_seed,
            lost,
            self.clock,
            self.log,
            verbose=self.output.verbose,
        )

    def _on_checkpoint(self, steps: int) -> None:
        """After a checkpoint: record the wall time, and remove the oldest checkpoints beyond ``keep_checkpoints``."""
        assert self.clock is not None
        self.clock.tick(steps)
        if self.keep_checkpoints is None:
            return
        checkpoints = checkpoint_steps(self.folder)
        for old in sorted(checkpoints)[: -self.keep_checkpoints]:
            checkpoints[old].unlink(missing_ok=True)

    # ------------------------------------------------------------------------------------------------ train
    def train(self) -> Path:
        """Train to the budget (the first Ctrl-C, with ``stop_on_ctrl_c``: a checkpoint and a clean stop), evaluate at
        the end, save ``<task>.zip`` and, when the budget is reached, write ``done.json`` and remove the checkpoints a
        finished run no longer needs (with ``keep_checkpoints``). A full disk stops the run with a
        :class:`RunStoppedError` naming the checkpoint to resume from.

        :return: the final model's path
        """
        experiment, checkpoints = self.experiment, self.checkpoints
        assert experiment is not None and experiment.model is not None and checkpoints is not None
        model = experiment.model
        resume = self.resume
        remaining = self.target_timesteps - model.num_timesteps if resume is not None else self.spec.n_timesteps
        # the state at the last step, before the final evaluation: the final model carries it, so that a larger budget
        # continues the run exactly (as an uninterrupted run with that budget would go on from here)
        end_state = resume.state if resume is not None and remaining <= 0 else None
        try:
            if remaining > 0:
                if resume is None and self.evaluator is not None:
                    self.evaluator.init_callback(model)
                    self.evaluator.evaluate()  # the curve starts at the start
                with self._ctrl_c(checkpoints):
                    experiment.learn(
                        remaining,
                        callbacks=[*self.callbacks, *self.output.callbacks],
                        progress_bar=self.output.progress_bar,
                        reset_num_timesteps=resume is None and not self.continue_model,
                    )
                if checkpoints.stopped_at is None:
                    end_state = capture_resume_state(model, checkpoints.extras)
            if checkpoints.stopped_at is None and self.evaluator is not None:
                rows = self.evaluator.rows
                if not rows or rows[-1]["timesteps"] < model.num_timesteps:
                    self.evaluator.init_callback(model)
                    self.evaluator.evaluate()  # the final evaluation
            return self._finish(end_state)
        except OSError as error:
            if error.errno not in NO_SPACE_ERRNOS:
                raise
            self._close_quietly()
            raise RunStoppedError(self.no_space_message(error)) from None

    @contextmanager
    def _ctrl_c(self, checkpoints: RunCheckpointCallback) -> Iterator[None]:
        """With ``stop_on_ctrl_c``, in the main thread: the first Ctrl-C asks for a checkpoint at the next rollout
        start and a stop there; a second stops at once (``KeyboardInterrupt``)."""
        if not self.output.stop_on_ctrl_c or threading.current_thread() is not threading.main_thread():
            yield
            return

        def handler(signum: int, frame: Any) -> None:
            if checkpoints.stop_requested:
                raise KeyboardInterrupt
            checkpoints.request_stop()
            print("\nCtrl-C: writing a checkpoint after this rollout and update, then stopping (Ctrl-C again: stop now)")

        previous = signal.signal(signal.SIGINT, handler)
        try:
            yield
        finally:
            signal.signal(signal.SIGINT, previous)

    def _finish(self, end_state: dict[str, Any] | None) -> Path:
        """Save ``<task>.zip`` (with ``end_state``, the resume state of its last step, when there is one); when the
        budget is reached, write ``done.json`` and drop the kept checkpoints (the final model is the resume point of a
        larger budget)."""
        assert self.experiment is not None and self.experiment.model is not None and self.clock is not None
        model = self.experiment.model
        if end_state is not None:
            path = self.final_model
            save_checkpoint(model, path, state=end_state)
        else:
            path = self.experiment.save(self.final_model)
        steps = model.num_timesteps
        self.clock.tick(steps)
        if steps >= self.target_timesteps:
            summary = {"wall_s": round(self.clock.total_s, 1), "segments": len(self.clock.segments), "timesteps": steps}
            atomic_write_text(self.folder / DONE_FILE, json.dumps(summary))
            if self.keep_checkpoints is not None:
                for checkpoint in checkpoint_steps(self.folder).values():
                    checkpoint.unlink(missing_ok=True)
        return path

    def no_space_message(self, error: OSError) -> str:
        """One line for a run stopped by a full disk: what failed, the run's folder, the checkpoint to resume from."""
        what = f"{error.strerror or 'no space left on the device'}" + (f" writing {error.filename}" if error.filename else "")
        checkpoint, _ = newest_loading_checkpoint(self.folder)
        if checkpoint is None:
            return (
                f"{what}: the run in {self.folder} stopped and has no checkpoint to resume from. Free some space and "
                "start it again (--save-freq writes resumable checkpoints)."
            )
        return (
            f"{what}: the run in {self.folder} stopped; its last good checkpoint is {checkpoint.name}. Free some space, "
            "then run the same command with --resume to continue from it."
        )

    def _close_quietly(self) -> None:
        """Close the run's open files (logger, monitor CSV) after a failed write: data still buffered for a full disk
        is dropped here rather than reported at exit."""
        experiment = self.experiment
        assert experiment is not None
        monitor = experiment.env
        writers = [experiment.model.logger if experiment.model is not None else None]
        writers.append(monitor.results_writer if isinstance(monitor, MultiAgentVecMonitor) else None)
        for writer in writers:
            if writer is not None:
                with suppress(OSError, ValueError):
                    writer.close()


def save_run_config(params_path: Path, config: dict[str, Any], command: dict[str, Any]) -> None:
    """``<task>/config.yml`` (the resolved hyperparameters) and ``<task>/args.yml`` (the command), as rl-zoo3 writes
    them, each atomically.

    :param params_path: the run's ``<task>/`` folder
    :param config: the resolved hyperparameters
    :param command: the command's options
    """
    atomic_write_text(params_path / "config.yml", yaml.safe_dump(config_record(config), sort_keys=True))
    atomic_write_text(params_path / "args.yml", yaml.safe_dump(dict(sorted(command.items()))))


def config_record(hyperparams: dict[str, Any]) -> dict[str, Any]:
    """The resolved hyperparameters as ``<task>/config.yml`` holds them (objects as their ``str``)."""
    return {
        key: (str(value) if not isinstance(value, (int, float, str, bool, list, dict, type(None))) else value)
        for key, value in sorted(hyperparams.items())
    }
