"""The benchmark's run folders, ``<out>/runs/<algo>/<task>_s<seed>/``: the folder of a planned run and moving a
changed run aside. A run folder's record compared with a planned run: :mod:`sb3_saeir.run.folder`; what a run folder
holds and how it is read: :mod:`sb3_saeir.run.record`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from sb3_saeir.common.atomic import unused_name
from sb3_saeir.common.utils import MAX_SEED
from sb3_saeir.config import ConfigError
from sb3_saeir.run.record import RunSpec


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


def move_aside(folder: Path) -> Path:
    """Rename a run folder to ``<folder>.replaced-<UTC time>`` (nothing is deleted); returns the new path."""
    target = unused_name(folder, "replaced")
    os.rename(folder, target)
    return target
