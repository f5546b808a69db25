"""The benchmark's run folders, ``<out>/runs/<algo>/<task>_s<seed>/``: the folder of a planned run, the comparison
of a folder's ``spec.json`` with it, and moving a changed run aside. What a run folder holds and how it is read:
:mod:`sb3_saeir.run_record`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

from sb3_saeir.common.atomic import unused_name
from sb3_saeir.common.run_files import SPEC_FILE
from sb3_saeir.common.utils import MAX_SEED
from sb3_saeir.config import ConfigError
from sb3_saeir.run_record import RunSpec, read_spec_file, spec_differences, write_spec_file


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
    outside = [seed for seed in seeds if not 0 <= seed <= MAX_SEED]
    if outside:
        raise ConfigError(f"--seeds {text!r}: {outside[0]} is not a seed; seeds are 0 .. 2**32 - 1 ({MAX_SEED}).")
    repeated = sorted({seed for seed in seeds if seeds.count(seed) > 1})
    if repeated:
        raise ConfigError(f"--seeds {text!r} gives seed(s) {repeated} more than once: give each seed once.")
    return seeds


def run_folder(out: Path, spec: RunSpec) -> Path:
    """The folder of a run of the benchmark in ``out``: ``<out>/runs/<algo>/<task>_s<seed>/``."""
    return out / "runs" / spec.algo / f"{spec.task}_s{spec.seed}"


def stored_spec_differences(folder: Path, record: dict[str, Any]) -> list[str]:
    """Why the run in ``folder`` cannot be continued or reported with the settings ``record`` (empty: it can, or the
    folder holds nothing yet).

    :param folder: the run's folder
    :param record: :func:`~sb3_saeir.run_record.spec_record` of the planned run
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
    :param record: :func:`~sb3_saeir.run_record.spec_record` of the run
    :raises ValueError: naming what differs
    """
    differences = stored_spec_differences(folder, record)
    if differences:
        raise ValueError(f"{folder} holds a run made with other settings: {'; '.join(differences)}.")
    if not (folder / SPEC_FILE).is_file():
        write_spec_file(folder, record)


def move_aside(folder: Path) -> Path:
    """Rename a run folder to ``<folder>.replaced-<UTC time>`` (nothing is deleted); returns the new path."""
    target = unused_name(folder, "replaced")
    os.rename(folder, target)
    return target
