"""A run folder moved, deleted or made read-only while its run trains (``docs/guide/training.md``, "The run folder
moved, deleted or read-only"): the run stops at its next write with one line saying what happened and what can be
resumed; it never makes the old path again, and a moved run resumes where it is."""

import errno
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from sb3_saeir.run.lock import RunFolderWatch
from sb3_saeir.train import main as train_main

REPO = Path(__file__).parent.parent
TASK = "cn-sparse-n3"
TIMEOUT = 180
BUDGET = "6000"  # 100 rollouts: seconds, long enough to change the folder after the second checkpoint
SETTINGS = ["--task", TASK, "--n-games", "2", "--num-threads", "1", "-params", "n_steps:10", "--eval-freq", "120",
            "--eval-episodes", "2", "--save-freq", "60"]  # fmt: skip


def command(log_folder, *extra):
    return [sys.executable, "-m", "sb3_saeir.train", "--algo", "mappo", *SETTINGS, "-f", str(log_folder), *extra]


def checkpoints(folder):
    return sorted(folder.glob("rl_model_*_steps.zip")) if folder.is_dir() else []


def run_until_checkpoint_then(tmp_path, change):
    """Start a long run, apply ``change(folder)`` once it has two checkpoints; the exit status and stderr."""
    folder = tmp_path / "mappo" / f"{TASK}_1"
    process = subprocess.Popen(
        command(tmp_path, "-n", BUDGET), env={**os.environ, "OMP_NUM_THREADS": "1"}, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, start_new_session=True,
    )  # fmt: skip
    deadline = time.time() + TIMEOUT
    while len(checkpoints(folder)) < 2:
        assert process.poll() is None and time.time() < deadline, process.communicate()
        time.sleep(0.005)
    os.kill(process.pid, signal.SIGSTOP)  # the change is made whole, not raced by the run's own writes
    try:
        change(folder)
    finally:
        os.kill(process.pid, signal.SIGCONT)
    _, stderr = process.communicate(timeout=TIMEOUT)
    return folder, process.returncode, stderr.decode()


def error_line(stderr):
    assert "Traceback" not in stderr, stderr[-3000:]
    (line,) = [line for line in stderr.splitlines() if line.startswith("sb3_saeir.train: error:")]
    return line


def test_a_moved_run_folder_stops_the_run_and_resumes_where_it_is(tmp_path):
    moved = tmp_path / "elsewhere"
    folder, status, stderr = run_until_checkpoint_then(tmp_path, lambda folder: folder.rename(moved))
    line = error_line(stderr)
    assert status == 1
    assert f"the run folder {folder} was moved to {moved} while the run trained" in line
    assert "the old path is not made again" in line and f"--resume {moved}" in line
    assert not folder.exists()  # the old path was not made again
    resumed = subprocess.run(
        command(tmp_path, "-n", BUDGET, "--resume", str(moved)), env={**os.environ, "OMP_NUM_THREADS": "1"},
        capture_output=True, text=True, timeout=TIMEOUT,
    )  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert (moved / "done.json").is_file() and not folder.exists()


def test_a_deleted_run_folder_stops_the_run_in_one_line(tmp_path):
    folder, status, stderr = run_until_checkpoint_then(tmp_path, lambda folder: shutil.rmtree(folder))
    line = error_line(stderr)
    assert status == 1
    assert f"the run folder {folder} was deleted while the run trained" in line
    assert "nothing is left to resume: start the run again" in line
    assert not folder.exists()


def test_a_run_folder_that_cannot_be_written_stops_the_run_in_one_line(tmp_path, monkeypatch, capsys):
    """A folder made read-only (or on a mount turned read-only): the write's error becomes one line naming the
    checkpoint to resume from once the folder is writable (root writes through permission bits: the error is made)."""
    import sb3_saeir.common.run_state as run_state

    real_save = run_state.save_checkpoint
    saved = []

    def save_then_refuse(model, path, *args, **kwargs):
        if saved:
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        saved.append(path)
        return real_save(model, path, *args, **kwargs)

    monkeypatch.setattr(run_state, "save_checkpoint", save_then_refuse)
    assert train_main(["--algo", "mappo", *SETTINGS, "-f", str(tmp_path), "-n", "600", "--verbose", "0"]) == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    folder = tmp_path / "mappo" / f"{TASK}_1"
    assert line.startswith("sb3_saeir.train: error: Permission denied writing ")
    assert f"the run folder {folder} cannot be written any more" in line
    assert f"chmod -R u+w {folder}" in line and "--resume to continue from rl_model_60_steps.zip" in line


def test_the_watch_tells_moved_deleted_and_in_place_apart(tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    watch = RunFolderWatch(folder)
    assert watch.change() is None
    folder.rename(tmp_path / "moved")
    assert watch.change() == f"moved to {tmp_path / 'moved'}"
    (tmp_path / "moved").rename(folder)
    assert watch.change() is None
    shutil.rmtree(folder)
    folder.mkdir()  # another folder at the path: not the run's
    assert watch.change() == "deleted"
    watch.close()


def test_a_run_folder_emptied_while_it_trains_stops_the_run(tmp_path):
    """``rm -rf`` racing the run's writes deletes its files and leaves the folder: the run went on to the end without
    a word, and the folder then answered --resume with "not a run of this command"."""

    def empty(folder):
        for path in folder.iterdir():
            shutil.rmtree(path) if path.is_dir() else path.unlink()

    folder, status, stderr = run_until_checkpoint_then(tmp_path, empty)
    line = error_line(stderr)
    assert status == 1 and f"the run folder {folder} was emptied (spec.json deleted) while the run trained" in line
    assert "nothing is left to resume" in line
