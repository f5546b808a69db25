"""Tiny training runs of ``python -m sb3_saeir.train`` for the tests of damaged, moved and concurrent run folders, and
the tolerance at which the tests compare arrays with those an earlier version saved."""

import csv
import json
import shutil
import zipfile
from pathlib import Path

import torch as th

from sb3_saeir.train import main as train_main

# Arrays saved by an earlier version, on another machine, against today's: bit-identical is expected on one machine;
# 1e-6 (relative 1e-5) leaves room for a reordering of float sums and for another CPU's kernels rounding the last bits
# differently (measured up to 3e-9 on an AVX-512 FP16 machine), while a change of what is computed moves them by far
# more (tests/test_golden.py, tests/test_train_formats.py).
SAVED_ARRAYS_ATOL, SAVED_ARRAYS_RTOL = 1e-6, 1e-5
# 2 games x 3 agents: 60 agent-steps per rollout; checkpoints at 120, 240, ..., 840 agent-steps; evaluations at 250,
# 500, 750 (the settings of tests/test_train_resume.py)
SETTINGS = [
    "--algo", "mappo", "--task", "cn-sparse-n3", "--seed", "3", "-n", "900", "--n-games", "2", "--eval-freq", "250",
    "--eval-episodes", "2", "--save-freq", "120", "--num-threads", "1", "--verbose", "0",
    "-params", "n_steps:10", "n_epochs:2",
]  # fmt: skip
TASK = "cn-sparse-n3"
# A run folder interrupted by commit 2ff651c, before one Run owned a run (its settings in args.yml and config.yml, no
# spec.json), and the rest of the command that made it (tests/data/make_interrupted_train.py)
LEGACY_RUN = Path(__file__).parent / "data" / "interrupted_train" / "logs" / "mappo" / f"{TASK}_1"
LEGACY_SETTINGS = [
    "--task", TASK, "--seed", "1", "-n", "900", "--n-games", "2", "--eval-freq", "250", "--eval-episodes", "2",
    "--save-freq", "240", "--num-threads", "1", "-params", "n_steps:10", "n_epochs:2",
]  # fmt: skip
LAST_CHECKPOINT = 840


def argv(log_folder, *extra):
    """The command line of the tiny run in ``log_folder``."""
    return [*SETTINGS, "-f", str(log_folder), *extra]


def finished_run(log_folder):
    """Train the tiny run to its end in ``log_folder``; returns its folder."""
    assert train_main(argv(log_folder)) == 0
    return Path(log_folder) / "mappo" / f"{TASK}_1"


def unfinished_copy(run, log_folder, moved=False):
    """A copy of a finished run in ``log_folder`` without its final model and ``done.json``: ``--resume`` continues it
    from its last checkpoint (840 agent-steps) and ends as the finished run. Its settings record (``spec.json``) names
    the new log folder, as if it had been started there, unless ``moved``.
    """
    folder = Path(log_folder) / "mappo" / f"{TASK}_1"
    shutil.copytree(run, folder)
    (folder / f"{TASK}.zip").unlink()
    (folder / "done.json").unlink()
    if not moved:
        spec_path = folder / "spec.json"
        spec = json.loads(spec_path.read_text())
        spec["options"]["-f"] = str(log_folder)
        spec_path.write_text(json.dumps(spec))
    return folder


def checkpoint(folder, steps):
    return Path(folder) / f"rl_model_{steps}_steps.zip"


def parameters(path):
    with zipfile.ZipFile(path) as archive, archive.open("policy.pth") as file:
        return th.load(file, map_location="cpu")


def assert_same_parameters(path, reference):
    """The models at ``path`` and ``reference`` have the same parameters, bit for bit."""
    final, expected = parameters(path), parameters(reference)
    assert final.keys() == expected.keys()
    for name in expected:
        assert th.equal(final[name], expected[name]), name


def read_rows(path, skip=0):
    with open(path, newline="") as file:
        for _ in range(skip):
            file.readline()
        return list(csv.DictReader(file))


def monitor_rows(folder):
    """The rows of a run's ``games.monitor.csv`` without their wall time ``t``."""
    return [{key: value for key, value in row.items() if key != "t"} for row in read_rows(folder / "games.monitor.csv", 1)]


def snapshot(folder):
    """Every file under ``folder`` with its content: a refused command must leave it as it was."""
    return {path: path.read_bytes() for path in sorted(Path(folder).rglob("*")) if path.is_file()}
