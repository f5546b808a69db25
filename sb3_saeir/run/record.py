"""What a run folder records, and how it is read and written: the settings record (:class:`RunSpec`, ``spec.json``)
and its comparison on resume, ``done.json``, the evaluation rows, the run's log, rl-zoo3's ``<task>/config.yml`` and
``<task>/args.yml``, and the checkpoints a run can resume from. The layout: ``docs/guide/training.md``, "The run
folder"; the file names: :mod:`sb3_saeir.run.files`.
"""

from __future__ import annotations

import csv
import io
import json
import math
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from sb3_saeir.common.atomic import atomic_write_text, keep_damaged, unused_name
from sb3_saeir.common.registry import game_kwargs
from sb3_saeir.common.run_state import checkpoint_problem, load_resume_state, read_zip_data, utc_stamp
from sb3_saeir.common.utils import PACKAGE_VERSION
from sb3_saeir.config import ConfigError, load_hyperparams
from sb3_saeir.run.files import (
    ARGS_FILE,
    CHECKPOINT_NAME,
    CONFIG_FILE,
    DONE_FILE,
    LEGACY_CHECKPOINT,
    RESUME_LOG,
    SPEC_FILE,
    numbered_paths,
)

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
        ``task`` with ``params`` applied, read when the spec is made
    :param options: the command's other settings that a resume must repeat, by their flags (``--save-freq``, ...)
    :param command: the command as ``<task>/args.yml`` records it (rl-zoo3's file; not a setting: ``spec.json`` leaves
        it out); empty: the ``python -m sb3_saeir.train`` arguments that make the same run (:func:`train_command`)
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
    command: dict[str, Any] = field(default_factory=dict, hash=False, compare=False)

    def __post_init__(self) -> None:
        if self.config is None:  # the packaged entry, read once, where the spec is made
            object.__setattr__(self, "config", {**load_hyperparams(self.algo, self.task), **self.params})

    @property
    def name(self) -> str:
        return f"{self.algo}/{self.task}_s{self.seed}"

    def resolved_config(self) -> dict[str, Any]:
        """The config entry the run trains with (a copy)."""
        return dict(self.config or {})


def _jsonable(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples become lists, unknown objects their ``str``)."""
    return json.loads(json.dumps(value, sort_keys=True, default=str))


def spec_record(spec: RunSpec) -> dict[str, Any]:
    """What a run's ``spec.json`` holds: its settings, the config entry it trains with, the keyword arguments its games
    are built with (``game_kwargs``: recorded, not compared on resume, since the task and the config are), the package
    version (``options`` only when the command has any)."""
    from sb3_saeir import __version__

    config = spec.resolved_config()
    games = game_kwargs(spec.task, config.get("env_kwargs"))
    record = {**asdict(spec), "config": config, "game_kwargs": games, "version": __version__}
    del record["command"]
    if not spec.options:
        del record["options"]
    return _jsonable(record)


def train_command(spec: RunSpec) -> dict[str, Any]:
    """A run as ``<task>/args.yml`` records it: the command it was given (:attr:`RunSpec.command`), else the
    ``python -m sb3_saeir.train`` arguments that make the same run (a benchmark run's)."""
    if spec.command:
        return dict(spec.command)
    params = [f"{key}:{value!r}" for key, value in sorted(spec.params.items())]
    return {
        "algo": spec.algo,
        "task": spec.task,
        "seed": spec.seed,
        "n_timesteps": spec.n_timesteps,
        "n_games": spec.n_games,
        "eval_freq": spec.eval_freq,
        "eval_episodes": spec.eval_episodes,
        "params": params or None,
    }


def _show(value: Any) -> str:
    return "(unset)" if value is None else json.dumps(value, sort_keys=True)


def warn_other_version(folder: Path, stored: dict[str, Any]) -> None:
    """Warn in one line that the run in ``folder`` goes on with another sb3-saeir version than the one its record
    ``stored`` names (``segments.json`` records the version of each segment).

    :param folder: the run's folder
    :param stored: its settings record
    """
    other_version = stored.get("version")
    if isinstance(other_version, str) and other_version != PACKAGE_VERSION:
        warnings.warn(
            f"the run in {folder} was recorded by sb3-saeir {other_version} and goes on with {PACKAGE_VERSION}: "
            "segments.json records the version of each segment.",
            UserWarning,
            stacklevel=3,
        )


def spec_differences(stored: dict[str, Any], planned: dict[str, Any], ignored: tuple[str, ...] = ()) -> list[str]:
    """What differs between a run's stored settings record and the planned run, as ``"<setting> <old> -> <new>"``.

    The package version is recorded, not compared; config keys set by ``-params`` are reported once, as ``-params``;
    :data:`UNCOMPARED_CONFIG_KEYS` are not compared; a larger budget than the record's is no difference (the run is
    trained longer: :func:`extended_budget`), a smaller one is.

    :param stored: the run's ``spec.json`` (or :func:`~sb3_saeir.train.legacy_train_record`)
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
        f"{flag} {_show(old)} -> {_show(new)}{_retyped(old, new)}"
        for flag, old, new in (
            (flag, old_options.get(flag), new_options.get(flag))
            for flag in sorted((set(old_options) | set(new_options)) - set(ignored))
        )
        if old != new
    ]
    old_config, new_config = stored.get("config") or {}, planned["config"]
    skipped = set(stored.get("params") or {}) | set(planned["params"]) | set(UNCOMPARED_CONFIG_KEYS)
    differences += [
        f"config {key} {_show(old_config.get(key))} -> {_show(new_config.get(key))}"
        for key in sorted((set(old_config) | set(new_config)) - skipped)
        if old_config.get(key) != new_config.get(key)
    ]
    return differences


def _retyped(old: Any, new: Any) -> str:
    """A note for a recorded value that is the command's written as another type (``"60"`` for ``60``): an edited or
    damaged record, not another setting."""
    if old is not None and new is not None and type(old) is not type(new) and str(old) == str(new):
        return " (the same value as another type: spec.json is damaged; restore it from a copy)"
    return ""


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
    missing = [key for key in ("algo", "task", "n_timesteps") if key not in record]
    if missing:
        raise ConfigError(f"{path} is damaged (no {', '.join(missing)}); restore it from a copy.")
    for key, (valid, what) in SPEC_FIELDS.items():
        if key in record and not valid(record[key]):
            raise ConfigError(
                f"{path} is damaged ({key} is {_show(record[key])}, not {what}); restore it from a copy, or write it "
                "again with the run's own values."
            )
    return record


def _whole(low: int) -> Callable[[Any], bool]:
    """Whether a record's value is a whole number >= ``low`` (not a bool)."""
    return lambda value: isinstance(value, int) and not isinstance(value, bool) and value >= low


# What each field of spec.json must be, where it is present (an older record lacks some): checked when it is read,
# so that a damaged field is named instead of compared, trusted or failing in the code that uses it.
SPEC_FIELDS: dict[str, tuple[Callable[[Any], bool], str]] = {
    "algo": (lambda value: isinstance(value, str), "a method name"),
    "task": (lambda value: isinstance(value, str), "a task id"),
    "n_timesteps": (_whole(1), "a whole number of agent-steps >= 1"),
    "n_games": (lambda value: value is None or _whole(1)(value), "a whole number >= 1 or null"),
    "eval_freq": (_whole(0), "a whole number >= 0"),
    "eval_episodes": (_whole(1), "a whole number >= 1"),
    "params": (lambda value: isinstance(value, dict), "an object"),
    "config": (lambda value: isinstance(value, dict), "an object"),
    "options": (lambda value: isinstance(value, dict), "an object"),
    "game_kwargs": (lambda value: isinstance(value, dict), "an object"),
    "extensions": (lambda value: isinstance(value, list) and all(isinstance(e, dict) for e in value), "a list of objects"),
    "version": (lambda value: isinstance(value, str), "a version string"),
}


def write_spec_file(folder: Path, record: dict[str, Any]) -> None:
    """Write a run folder's ``spec.json`` (atomically): every writer of the file goes through here.

    :param folder: the run's folder (created when missing)
    :param record: the settings record (:func:`spec_record`, or :func:`extension_record` of a run trained longer)
    """
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(folder / SPEC_FILE, json.dumps(record, indent=2, sort_keys=True) + "\n")


# ---------------------------------------------------------------------------------------------------- done.json
def stored_spec_differences(folder: Path, record: dict[str, Any]) -> list[str]:
    """Why the run in ``folder`` cannot be continued or reported with the settings ``record`` (empty: it can, or the
    folder holds nothing yet).

    :param folder: the run's folder
    :param record: :func:`~sb3_saeir.run.record.spec_record` of the planned run
    """
    try:
        stored = read_spec_file(folder)
    except ConfigError as error:  # not JSON, not text, or not an object of settings: what it says, then what follows
        return [f"{str(error).split(';')[0]}: its settings are unknown"]
    if stored is not None:
        return spec_differences(stored, record)
    if folder.is_dir() and any(folder.iterdir()):
        return [f"no {SPEC_FILE} (made by an older version): its settings are unknown"]
    return []


def ensure_spec_file(folder: Path, record: dict[str, Any]) -> None:
    """Write the run's ``spec.json`` unless it is there; refuse a folder made with other settings.

    :param folder: the run's folder
    :param record: :func:`~sb3_saeir.run.record.spec_record` of the run
    :raises ValueError: naming what differs
    """
    differences = stored_spec_differences(folder, record)
    if differences:
        raise ValueError(f"{folder} holds a run made with other settings: {'; '.join(differences)}.")
    if not (folder / SPEC_FILE).is_file():
        write_spec_file(folder, record)


def settle_spec_file(folder: Path, spec: RunSpec) -> tuple[dict[str, Any], bool]:
    """A given run folder's settings record for the run ``spec``: the folder's ``spec.json`` compared with it (a run
    of other settings refused), or, in a folder without one, ``spec``'s record written; and whether the run is
    finished for ``spec``'s budget (:func:`is_finished`).

    :param folder: the run's folder, locked
    :param spec: the run's settings
    :return: the record, and whether the run is finished
    :raises ValueError: naming what differs
    """
    planned = spec_record(spec)
    differences = stored_spec_differences(folder, planned)
    if differences:
        raise ValueError(f"{folder} holds a run made with other settings: {'; '.join(differences)}.")
    stored = read_spec_file(folder)
    finished = is_finished(folder, stored, spec.n_timesteps)
    if stored is None:
        write_spec_file(folder, planned)
    return stored or planned, finished


def is_finished(path: Path, record: dict[str, Any] | None, n_timesteps: int) -> bool:
    """Whether the run in ``path`` is finished for a budget of ``n_timesteps`` agent-steps: it has its ``done.json``
    and the budget does not raise its settings record's (``record``; a larger budget trains it longer).

    :param path: the run's folder
    :param record: its settings record (``None``: none, or unread)
    :param n_timesteps: the command's budget
    """
    return (path / DONE_FILE).is_file() and (record is None or extended_budget(record, n_timesteps) is None)


def done_record(wall_s: float, segments: int, timesteps: int, model_start: int = 0) -> dict[str, Any]:
    """What a finished run's ``done.json`` holds: the total wall time over its segments (rounded to 0.1 s), the
    number of segments (processes that worked on it) and the agent-steps it trained (counted against the budget of
    its ``spec.json``); for a run that continued a loaded model (``-i``), also ``model_start``, the model's agent-step
    count before the run (its final count is the sum).

    :param wall_s: total wall time in seconds
    :param segments: the segments
    :param timesteps: agent-steps trained by the run
    :param model_start: the loaded model's agent-steps before the run (0: a new model)
    """
    record: dict[str, Any] = {"wall_s": round(wall_s, 1), "segments": segments, "timesteps": timesteps}
    if model_start:
        record["model_start"] = model_start
    return record


def read_done_file(folder: Path) -> dict[str, Any] | None:
    """A run folder's ``done.json`` (``None``: the run has not finished).

    :raises ~sb3_saeir.config.ConfigError: when it is damaged (not a JSON object with ``wall_s``, ``segments`` and
        ``timesteps`` numbers)
    """
    path = folder / DONE_FILE
    if not path.is_file():
        return None
    try:
        record = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError):
        record = None
    fields_ok = (
        isinstance(record, dict)
        and isinstance(record.get("wall_s"), (int, float))
        and not isinstance(record.get("wall_s"), bool)
        and math.isfinite(record["wall_s"])
        and record["wall_s"] >= 0
        and _whole(1)(record.get("segments"))
        and _whole(1)(record.get("timesteps"))
    )
    if not fields_ok:
        raise ConfigError(
            f"{path} is damaged (not a JSON object with wall_s >= 0, segments >= 1 and timesteps >= 1); delete it: the "
            "run's final model and checkpoints say where it goes on, and the run writes it again at its budget."
        )
    return record


def write_done_file(folder: Path, record: dict[str, Any]) -> None:
    """Write a finished run's ``done.json`` (atomically): the one writer of the file, on the machine that trained the
    run or, for a run trained elsewhere (Ray), on the driver with the record the run returned.

    :param folder: the run's folder (created when missing)
    :param record: :func:`done_record`
    """
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(folder / DONE_FILE, json.dumps(record))


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
    readable = [
        row for row in old_rows if isinstance(row.get("timesteps"), int) and None not in row and None not in row.values()
    ]
    if len(readable) < len(old_rows):
        copy = keep_damaged(path)
        log(
            f"{len(old_rows) - len(readable)} row(s) of {path.name} cannot be read (cut short or edited): left out, the "
            f"file as it was kept as {copy.name}"
        )
        old_rows = readable
        write_rows(path, old_rows)
    rows = [row for row in old_rows if done_steps is not None and row["timesteps"] <= done_steps]
    lost = {int(row["timesteps"]): row for row in old_rows if done_steps is None or row["timesteps"] > done_steps}
    if lost:
        since = "the start" if done_steps is None else "the checkpoint"
        log(f"evaluations made after {since}, at {sorted(lost)} agent-steps, are re-done")
    if old_rows:
        write_rows(path, rows)
    return rows, lost


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
    data = read_zip_data(path)
    try:
        return int(data["num_timesteps"]) if data is not None else None
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
    next checkpoints do not sit beside them (a folder in a checkpoint's name is renamed aside whole, a link is renamed
    itself: what it points to stays as it is)."""
    for path, _ in skipped:
        if path.is_dir() or path.is_symlink():
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


# ---------------------------------------------------------------------------------------------------- rl-zoo3's files
# What <task>/args.yml and <task>/config.yml hold, for the message on a damaged one.
RUN_FILES = {
    ARGS_FILE: "the command line that started the run, one 'option: value' line per option",
    CONFIG_FILE: "the run's resolved hyperparameters, one 'key: value' line per key",
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
        elif path.name == ARGS_FILE and (isinstance(content.get("seed"), bool) or not isinstance(content.get("seed"), int)):
            problem = f"no integer seed (seed: {content.get('seed')!r})"
    if problem:
        raise ConfigError(
            f"--resume: {path} is damaged ({problem}). It holds {RUN_FILES[path.name]}: restore it from a copy, or "
            f"write it again as another run's {path.name} (the run's own values), then resume; or start a new run "
            "without --resume."
        )
    return content


# How a command makes a settings record of a run of an older version (its <task>/args.yml and <task>/config.yml).
LegacyRecord = Callable[[dict[str, Any], dict[str, Any]], dict[str, Any]]


def stored_record(folder: Path, algo: str, task: str, legacy_record: LegacyRecord | None = None) -> dict[str, Any]:
    """The settings record of the run in ``folder``: its ``spec.json``, or for a run of an older version its
    ``<task>/args.yml`` and ``<task>/config.yml`` made into one by ``legacy_record`` (``None``: such a run is refused).

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
    args_path = folder / task / ARGS_FILE
    if legacy_record is None:
        raise ConfigError(f"--resume: {folder} has no {SPEC_FILE}: it is not a run of this command.")
    if not args_path.is_file():
        raise ConfigError(f"--resume: {folder} has no {SPEC_FILE} nor {task}/{ARGS_FILE}: it is not a run of this command.")
    stored_args = read_run_file(args_path)
    return legacy_record(stored_args, read_run_file(folder / task / CONFIG_FILE))


def save_run_config(params_path: Path, config: dict[str, Any], command: dict[str, Any]) -> None:
    """``<task>/config.yml`` (the resolved hyperparameters) and ``<task>/args.yml`` (the command), as rl-zoo3 writes
    them, each atomically.

    :param params_path: the run's ``<task>/`` folder
    :param config: the resolved hyperparameters
    :param command: the command's options
    """
    atomic_write_text(params_path / CONFIG_FILE, yaml.safe_dump(config_record(config), sort_keys=True))
    atomic_write_text(params_path / ARGS_FILE, yaml.safe_dump(dict(sorted(command.items()))))


def config_record(hyperparams: dict[str, Any]) -> dict[str, Any]:
    """The resolved hyperparameters as ``<task>/config.yml`` holds them (objects as their ``str``)."""
    return {
        key: (str(value) if not isinstance(value, (int, float, str, bool, list, dict, type(None))) else value)
        for key, value in sorted(hyperparams.items())
    }
