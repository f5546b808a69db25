"""The names of a run folder's files, one constant each: what each holds is ``docs/guide/training.md``, "The run
folder" (the one description of the layout)."""

from __future__ import annotations

from pathlib import Path

SPEC_FILE = "spec.json"
CONFIG_FILE = "config.yml"  # in <task>/, as rl-zoo3 writes it
ARGS_FILE = "args.yml"  # in <task>/, as rl-zoo3 writes it
CHECKPOINT_NAME = "rl_model_{steps}_steps.zip"
LEGACY_CHECKPOINT = "checkpoint.zip"  # the benchmark's one checkpoint before this layout: read, never written
EVALUATIONS_FILE = "evaluations.csv"
BEST_MODEL_FILE = "best_model.zip"
PROGRESS_FILE = "progress.csv"
MONITOR_PREFIX = "games"  # -> games.monitor.csv
SEGMENTS_FILE = "segments.json"
RESUME_LOG = "resume.log"
FINAL_MODEL = "{task}.zip"
SHORTER_RUN_MODEL = "{task}_{steps}_steps.zip"  # the final model of a run later trained longer
DONE_FILE = "done.json"


def numbered_paths(folder: str | Path, prefix: str, suffix: str = "") -> dict[int, Path]:
    """The paths ``<folder>/<prefix><number><suffix>`` by their number (other names are left out): run folders
    ``<task>_<run>``, checkpoints ``rl_model_<steps>_steps.zip``.

    :param folder: the folder to list
    :param prefix: the names' start
    :param suffix: the names' end
    """
    found = {}
    for path in Path(folder).glob(f"{prefix}*{suffix}"):
        number = path.name[len(prefix) : len(path.name) - len(suffix)]
        if number.isascii() and number.isdigit():  # "²" is a digit to str.isdigit, not to int()
            found[int(number)] = path
    return found
