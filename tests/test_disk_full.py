"""A full disk during ``python -m sb3_saeir.train`` (an ``OSError(ENOSPC)`` from a write: a checkpoint, the final or
best model (first written by the evaluation at the start), ``evaluations.npz``, a row of ``progress.csv`` or of
``games.monitor.csv``) ends the command in one line naming what failed, the run's folder and its last good checkpoint,
which ``--resume`` then continues; the files written before are whole and no temporary file is left."""

import errno
import re
import zipfile

import pytest
from stable_baselines3.common.logger import CSVOutputFormat
from stable_baselines3.common.monitor import ResultsWriter

from sb3_saeir import MAPPO
from sb3_saeir.train import main as train_main
from tests.run_folders import TASK, argv, assert_same_parameters, finished_run, monitor_rows

NO_SPACE = "No space left on device"


def no_space():
    return OSError(errno.ENOSPC, NO_SPACE)


def full_disk_on_zip(monkeypatch, name_part, after=0):
    """Writes into a zip whose file name holds ``name_part`` fail, but into the first ``after`` such zips (SB3's model
    zips and np.savez write through zipfile's entry writer)."""
    write = zipfile._ZipWriteFile.write
    spared: list[int] = []

    def failing_write(self, data):
        if name_part in str(getattr(self._zipfile, "filename", "")):
            if id(self._zipfile) in spared or len(spared) < after:
                if id(self._zipfile) not in spared:
                    spared.append(id(self._zipfile))
                return write(self, data)
            raise no_space()
        return write(self, data)

    monkeypatch.setattr(zipfile._ZipWriteFile, "write", failing_write)


def full_disk_on_progress_row(monkeypatch, steps):
    """The row of ``progress.csv`` dumped at ``steps`` agent-steps or later fails."""
    write = CSVOutputFormat.write

    def failing_write(self, key_values, key_excluded, step=0):
        if key_values.get("time/total_timesteps", 0) >= steps:
            raise no_space()
        return write(self, key_values, key_excluded, step)

    monkeypatch.setattr(CSVOutputFormat, "write", failing_write)


def full_disk_on_monitor_row(monkeypatch, rows):
    """Rows of ``games.monitor.csv`` after the first ``rows`` fail."""
    write_row = ResultsWriter.write_row
    written = []

    def failing_write_row(self, row):
        if len(written) >= rows:
            raise no_space()
        written.append(row)
        return write_row(self, row)

    monkeypatch.setattr(ResultsWriter, "write_row", failing_write_row)


FULL_DISKS = {
    "a checkpoint": (lambda monkeypatch: full_disk_on_zip(monkeypatch, "rl_model_360_steps"), 240),
    "the final model": (lambda monkeypatch: full_disk_on_zip(monkeypatch, f"{TASK}.zip"), 840),
    # the first evaluation, at 0 agent-steps, writes it before any checkpoint: the second one (at 252) fails
    "evaluations.npz": (lambda monkeypatch: full_disk_on_zip(monkeypatch, "evaluations", after=1), 240),
    "a progress.csv row": (lambda monkeypatch: full_disk_on_progress_row(monkeypatch, 500), 480),
    "a monitor row": (lambda monkeypatch: full_disk_on_monitor_row(monkeypatch, 6), 480),
}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The tiny run, uninterrupted."""
    return finished_run(tmp_path_factory.mktemp("uninterrupted"))


@pytest.mark.parametrize("where", list(FULL_DISKS))
def test_a_full_disk_ends_in_one_line_naming_the_checkpoint_to_resume_from(reference, tmp_path, monkeypatch, capsys, where):
    fill_disk, last_good = FULL_DISKS[where]
    folder = tmp_path / "logs" / "mappo" / f"{TASK}_1"
    with monkeypatch.context() as patch:
        fill_disk(patch)
        status = train_main(argv(tmp_path / "logs"))
    captured = capsys.readouterr()
    assert status == 1, captured.err
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.out + captured.err, captured.err
    assert lines[0].startswith(f"sb3_saeir.train: error: {NO_SPACE} writing "), lines[0]
    checkpoint = folder / f"rl_model_{last_good}_steps.zip"
    assert f"the run in {folder} stopped; its last good checkpoint is {checkpoint.name}" in lines[0]
    assert "run the same command with --resume" in lines[0]
    steps = sorted(int(re.findall(r"\d+", path.name)[0]) for path in folder.glob("rl_model_*_steps.zip"))
    assert steps[-1] == last_good  # nothing newer, and every checkpoint whole
    for step in steps:
        MAPPO.load(folder / f"rl_model_{step}_steps.zip")
    assert [path.name for path in folder.rglob(".*")] == []  # no temporary file left
    resumed = train_main(argv(tmp_path / "logs", "--resume"))  # space freed
    assert resumed == 0, capsys.readouterr().err
    assert f"from {checkpoint.name}" in capsys.readouterr().out
    assert_same_parameters(folder / f"{TASK}.zip", reference / f"{TASK}.zip")
    assert monitor_rows(folder) == monitor_rows(reference)


@pytest.mark.parametrize("name_part", ["rl_model_120_steps", "best_model"])  # best_model: the evaluation at 0
def test_a_full_disk_before_any_checkpoint_says_so(tmp_path, monkeypatch, capsys, name_part):
    full_disk_on_zip(monkeypatch, name_part)
    assert train_main(argv(tmp_path / "logs")) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "has no checkpoint to resume from" in err, err
