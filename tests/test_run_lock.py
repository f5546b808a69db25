"""One process per run folder: a second ``train``, ``zoo train`` or benchmark process that would write into a run
folder in use is refused in one line naming the folder and the process holding it, before it writes anything; a
SIGKILLed holder leaves the folder resumable (an OS lock, released with the process)."""

import os
import signal
import subprocess
import sys
import time

import pytest

from sb3_saeir.benchmark import RunSpec, run_folder
from sb3_saeir.benchmark import main as benchmark_main
from sb3_saeir.run.lock import RunFolderInUseError, RunFolderLock
from sb3_saeir.train import main as train_main
from tests.run_folders import TASK, argv, snapshot, unfinished_copy

TIMEOUT = 180


def train_process(*arguments):
    return subprocess.Popen(
        [sys.executable, "-m", "sb3_saeir.train", *arguments],
        env={**os.environ, "OMP_NUM_THREADS": "1"},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def wait_until_locked(folder, process):
    """Wait until ``process`` holds the lock of ``folder`` (another lock on it is refused)."""
    deadline = time.time() + TIMEOUT
    while True:
        assert process.poll() is None, f"the run ended before it held its folder: {process.communicate()}"
        assert time.time() < deadline
        try:
            RunFolderLock(folder).acquire().release()
        except RunFolderInUseError:
            return
        time.sleep(0.01)


def with_budget(command, n_timesteps):
    command = list(command)
    command[command.index("-n") + 1] = str(n_timesteps)
    return command


def test_two_resumes_of_one_folder_one_trains_the_other_is_refused(finished_tiny_run, tmp_path):
    folder = unfinished_copy(finished_tiny_run, tmp_path / "logs")
    command = with_budget(argv(tmp_path / "logs", "--resume", str(folder)), 3000)
    first = train_process(*command)
    wait_until_locked(folder, first)
    before = snapshot(folder)
    second = train_process(*command)
    _, second_err = second.communicate(timeout=TIMEOUT)
    _, first_err = first.communicate(timeout=TIMEOUT)
    assert first.returncode == 0, first_err
    assert second.returncode == 2
    (line,) = [line for line in second_err.splitlines() if "error:" in line]  # (gym, if installed, prints a notice)
    assert f"{folder} is in use by process {first.pid} (" in line and "sb3_saeir.train" in line
    # nothing of the refused process in the folder: one resume, segments of the two processes that trained
    assert set(before) <= set(snapshot(folder))
    assert (folder / "resume.log").read_text().count("resumed from the checkpoint at 840") == 1
    assert (folder / "done.json").is_file()


def test_a_sigkilled_holder_leaves_the_folder_resumable(finished_tiny_run, tmp_path):
    folder = unfinished_copy(finished_tiny_run, tmp_path / "logs")
    command = with_budget(argv(tmp_path / "logs", "--resume", str(folder)), 3000)
    holder = train_process(*command)
    wait_until_locked(folder, holder)
    deadline = time.time() + TIMEOUT
    while not any(int(path.name.split("_")[2]) > 900 for path in folder.glob("rl_model_*_steps.zip")):
        assert holder.poll() is None and time.time() < deadline
        time.sleep(0.01)
    os.killpg(holder.pid, signal.SIGKILL)
    holder.wait()
    assert not (folder / "done.json").exists()
    resumed = subprocess.run(
        [sys.executable, "-m", "sb3_saeir.train", *command], capture_output=True, text=True, timeout=TIMEOUT
    )
    assert resumed.returncode == 0, resumed.stderr
    assert (folder / "done.json").is_file()


def test_a_folder_in_use_refuses_train_benchmark_and_zoo_and_nothing_is_written(finished_tiny_run, tmp_path, capsys):
    folder = unfinished_copy(finished_tiny_run, tmp_path / "logs")
    before = snapshot(folder)
    with RunFolderLock(folder):  # another holder (flock: a second open of the folder conflicts, also in one process)
        assert train_main(argv(tmp_path / "logs", "--resume")) == 2
        assert f"{folder} is in use by process {os.getpid()}" in capsys.readouterr().err
        assert snapshot(folder) == before
    assert train_main(argv(tmp_path / "logs", "--resume")) == 0  # released: it goes on

    out = tmp_path / "benchmark"
    run = run_folder(out, RunSpec("mappo", TASK, 1, 120))
    run.mkdir(parents=True)
    with RunFolderLock(run):
        benchmark = ["--algos", "mappo", "--seeds", "1", "-n", "120", "--n-games", "2", "--eval-freq", "60",
                     "-params", "n_steps:10", "n_epochs:1", "--out", str(out)]  # fmt: skip
        assert benchmark_main(benchmark) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert f"{run} is in use by process {os.getpid()}" in line
        assert list(run.iterdir()) == [] and sorted(path.name for path in out.iterdir()) == ["runs"]


def test_zoo_resume_of_a_folder_in_use_is_refused(tmp_path, capsys, monkeypatch):
    """Refused by the launcher (``claim_run_folder``), before rl-zoo3 sets anything up: the manager's setup must not
    be reached."""
    pytest.importorskip("rl_zoo3")
    from sb3_saeir.zoo.launcher import main as zoo_main
    from sb3_saeir.zoo.manager import RunExperimentManager

    def not_reached(self):
        raise AssertionError("rl-zoo3's setup ran: the launcher did not refuse the folder in use")

    monkeypatch.setattr(RunExperimentManager, "setup_experiment", not_reached)
    folder = tmp_path / "mappo" / f"{TASK}_1"
    folder.mkdir(parents=True)
    (folder / "spec.json").write_text('{"algo": "mappo", "task": "cn-sparse-n3", "seed": 0}')
    before = snapshot(folder)
    with RunFolderLock(folder):
        assert zoo_main(["train", "--algo", "mappo", "--env", TASK, "-f", str(tmp_path), "--resume"]) == 2
    err = capsys.readouterr().err
    assert f"{folder} is in use by process {os.getpid()}" in err and len(err.strip().splitlines()) == 1
    assert snapshot(folder) == before


def test_the_lock_is_released_and_taken_again():
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        lock = RunFolderLock(folder).acquire()
        with pytest.raises(RunFolderInUseError, match=f"in use by process {os.getpid()}"):
            RunFolderLock(folder).acquire()
        lock.release()
        again = RunFolderLock(folder).acquire()
        assert again.held
        again.release()


@pytest.mark.skipif(not os.path.isfile("/proc/locks"), reason="the holder is read from the kernel's lock table")
def test_a_stopped_holder_is_said_to_be_stopped(tmp_path):
    """A SIGSTOPped holder was named by pid only: "wait for it to end" would wait forever."""
    code = (
        "import time; from sb3_saeir.run.lock import RunFolderLock; "
        f"RunFolderLock({str(tmp_path)!r}).acquire(); print('locked', flush=True); time.sleep(120)"
    )
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(RunFolderInUseError) as running:
            RunFolderLock(tmp_path).acquire()
        assert f"process {holder.pid}" in str(running.value) and "which is stopped" not in str(running.value)
        os.kill(holder.pid, signal.SIGSTOP)
        deadline = time.time() + 10
        while time.time() < deadline:
            with open(f"/proc/{holder.pid}/stat") as file:
                if file.read().rsplit(")", 1)[1].split()[0] in ("T", "t"):
                    break
            time.sleep(0.05)
        with pytest.raises(RunFolderInUseError) as stopped:
            RunFolderLock(tmp_path).acquire()
        message = str(stopped.value)
        assert f"process {holder.pid}" in message and "which is stopped (SIGSTOP or Ctrl-Z)" in message
        assert f"kill -CONT {holder.pid}" in message and "\n" not in message
    finally:
        os.kill(holder.pid, signal.SIGKILL)
        holder.wait()
