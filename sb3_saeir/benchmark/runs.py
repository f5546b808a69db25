"""The benchmark's runs and their folders: run specs, ``spec.json`` and the comparison of settings, the CSV row files,
and what a run says about its resumes (``resume.log``).

A run's folder is ``<out>/runs/<algo>/<task>_s<seed>/`` (see :mod:`sb3_saeir.benchmark` for the files in it).
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from sb3_saeir.common.atomic import atomic_write_text, unused_name
from sb3_saeir.common.run_state import utc_stamp
from sb3_saeir.config import ConfigError, load_hyperparams

# Files of a run folder.
SPEC_FILE = "spec.json"
CHECKPOINT_FILE = "checkpoint.zip"
MODEL_FILE = "model.zip"
# Settings compared with a run's spec.json, by their command-line names.
SPEC_SETTINGS = {
    "n_timesteps": "-n",
    "n_games": "--n-games",
    "eval_freq": "--eval-freq",
    "eval_episodes": "--eval-episodes",
    "params": "-params",
}


@dataclass(frozen=True)
class RunSpec:
    """One training run of the benchmark.

    :param config: the config entry it trains with (the packaged entry with ``params`` applied); ``None``: read it
        when needed (:meth:`resolved_config`)
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

    @property
    def name(self) -> str:
        return f"{self.algo}/{self.task}_s{self.seed}"

    def resolved_config(self) -> dict[str, Any]:
        """The config entry the run trains with: ``config``, read once when the run was planned
        (:func:`~sb3_saeir.benchmark.cli.plan_runs`), else the packaged entry of its method and task with ``params``
        applied."""
        if self.config is not None:
            return dict(self.config)
        return {**load_hyperparams(self.algo, self.task), **self.params}


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


def _jsonable(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples become lists, unknown objects their ``str``)."""
    return json.loads(json.dumps(value, sort_keys=True, default=str))


def spec_record(spec: RunSpec) -> dict[str, Any]:
    """What a run's ``spec.json`` holds: its settings, the config entry it trains with, the package version."""
    from sb3_saeir import __version__

    return _jsonable({**asdict(spec), "config": spec.resolved_config(), "version": __version__})


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
    target = unused_name(folder, "replaced")
    os.rename(folder, target)
    return target


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


def same_row(row: dict[str, Any], other: dict[str, Any]) -> bool:
    """Whether two evaluation rows hold the same values (as written to CSV and read back)."""
    return {key: _number(str(value)) for key, value in row.items()} == {
        key: _number(str(value)) for key, value in other.items()
    }
