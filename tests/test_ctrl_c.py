"""Ctrl-C at any moment of ``train`` and ``zoo train`` (``docs/guide/training.md``, "Signals"): while the package is
imported, while the run is set up, during the first evaluation, twice in a row, during the final evaluation. Each
prints one line, no traceback; each stop exits 130 and leaves a folder whose ``--resume`` answer is true."""

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).parent.parent
TASK = "cn-sparse-n3"
TIMEOUT = 180
SETTINGS = ["--task", TASK, "--n-games", "2", "--num-threads", "1", "-params", "n_steps:10"]  # 60 agent-steps a rollout


def train_command(log_folder, *extra):
    return [sys.executable, "-m", "sb3_saeir.train", "--algo", "mappo", *SETTINGS, "-f", str(log_folder), *extra]


def zoo_command(log_folder, *extra):
    return [
        sys.executable, "-m", "sb3_saeir.zoo", "train", "--algo", "mappo", "--env", TASK, "--num-threads", "1",
        "--device", "cpu", "--seed", "0", "-f", str(log_folder), "-params", "n_envs:2", "n_steps:10", *extra,
    ]  # fmt: skip


def child_env():
    return {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}


def start(command):
    return subprocess.Popen(
        command, cwd=REPO, env=child_env(), start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )


def wait_for(process, ready):
    deadline = time.time() + TIMEOUT
    while not ready():
        assert process.poll() is None, f"the run ended before it could be stopped: {process.communicate()}"
        assert time.time() < deadline
        time.sleep(0.005)


def finish(process):
    stdout, stderr = process.communicate(timeout=TIMEOUT)
    assert "Traceback" not in stderr.decode(), stderr.decode()[-3000:]
    return process.returncode, stdout.decode(), stderr.decode()


def trained_rows(folder):
    """progress.csv's rows of the rollouts (SB3 writes one after each rollout, before its update; an evaluation
    writes rows of its own)."""
    path = folder / "progress.csv"
    if not path.is_file():
        return 0
    with path.open() as file:
        return sum(1 for row in csv.DictReader(file) if row.get("time/iterations"))


def ctrl_c_twice(process, gap_s=0.03):
    os.kill(process.pid, signal.SIGINT)
    time.sleep(gap_s)
    os.kill(process.pid, signal.SIGINT)


def stop_twice_after_two_rollouts(command, folder):
    """Start ``command``, Ctrl-C it twice 30 ms apart after two rollouts: it exits 130 with its model saved and one
    ``Stopped at once`` line, returned."""
    process = start(command)
    wait_for(process, lambda: trained_rows(folder) >= 2)
    ctrl_c_twice(process)
    status, stdout, _ = finish(process)
    assert status == 130
    (line,) = [line for line in stdout.splitlines() if line.startswith("Stopped")]
    assert line.startswith("Stopped at once (Ctrl-C twice): saved") and (folder / f"{TASK}.zip").is_file()
    return line


def test_ctrl_c_while_importing_exits_130_in_one_line(tmp_path):
    process = start(train_command(tmp_path, "-n", "600"))
    time.sleep(0.3)  # the package's import takes seconds
    os.kill(process.pid, signal.SIGINT)
    status, _, stderr = finish(process)
    assert status == 130
    (line,) = [line for line in stderr.splitlines() if line.startswith("sb3_saeir.train")]
    assert "Ctrl-C" in line and "nothing was written" in line
    assert not (tmp_path / "mappo").exists()


@pytest.mark.parametrize("save_freq", [None, "60"])
def test_ctrl_c_twice_saves_the_model_and_names_what_continues_it(tmp_path, save_freq):
    """The second Ctrl-C 30 ms after the first: the model is saved where it is, one line names the checkpoint that
    ``--resume`` continues from (or, with none yet, the ``-i`` that continues the model), exit 130."""
    extra = ["-n", "30000", "--eval-freq", "0"] + (["--save-freq", save_freq] if save_freq else [])
    folder = tmp_path / "mappo" / f"{TASK}_1"
    line = stop_twice_after_two_rollouts(train_command(tmp_path, *extra), folder)
    if save_freq is None:  # no checkpoint yet: -i continues the model, and --resume says so
        assert f"continue that model with -i {folder / (TASK + '.zip')}" in line
        resumed = subprocess.run(
            train_command(tmp_path, *extra, "--resume"), cwd=REPO, env=child_env(), capture_output=True, text=True,
            timeout=TIMEOUT,
        )  # fmt: skip
        assert resumed.returncode == 2
        assert "a run stopped at once by a second Ctrl-C or stop signal" in resumed.stderr
        assert f"-i {folder / (TASK + '.zip')}" in resumed.stderr
    else:
        assert "the same command with --resume continues from the checkpoint" in line
        assert Path(line.rsplit(" ", 1)[1].rstrip(".")).is_file()


def test_ctrl_c_during_the_first_evaluation_stops_at_the_first_checkpoint(tmp_path):
    """Before the first rollout (the evaluation at 0 agent-steps): the stop comes at the first rollout start, whose
    checkpoint ``--resume`` continues from."""
    extra = ["-n", "120", "--eval-freq", "60", "--eval-episodes", "1000"]
    process = start(train_command(tmp_path, *extra))
    folder = tmp_path / "mappo" / f"{TASK}_1"
    wait_for(process, lambda: (folder / "spec.json").is_file())
    os.kill(process.pid, signal.SIGINT)
    status, stdout, _ = finish(process)
    assert status == 130
    assert "Stopped at the checkpoint" in stdout and (folder / "rl_model_0_steps.zip").is_file()
    resumed = subprocess.run(
        train_command(tmp_path, *extra, "--resume"), cwd=REPO, env=child_env(), capture_output=True, text=True,
        timeout=TIMEOUT,
    )  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert (folder / "done.json").is_file()


def test_ctrl_c_during_the_final_evaluation_finishes_the_run(tmp_path):
    """After the last rollout (during its update or the final evaluation): the run finishes (final evaluation, model,
    ``done.json``) and exits 0."""
    process = start(train_command(tmp_path, "-n", "60", "--eval-freq", "100000", "--eval-episodes", "2000"))
    folder = tmp_path / "mappo" / f"{TASK}_1"
    wait_for(process, lambda: trained_rows(folder) >= 1)  # the one rollout is done (its update follows)
    time.sleep(0.3)  # the update takes milliseconds, the final evaluation of 2000 game episodes seconds
    os.kill(process.pid, signal.SIGINT)
    status, _, _ = finish(process)
    assert status == 0 and (folder / "done.json").is_file()


def test_zoo_ctrl_c_twice_exits_130_with_one_line(tmp_path):
    """``zoo train`` exited 0, with no line, on the second Ctrl-C."""
    stop_twice_after_two_rollouts(zoo_command(tmp_path, "-n", "30000", "--eval-freq", "0"), tmp_path / "mappo" / f"{TASK}_1")


def test_zoo_ctrl_c_while_starting_leaves_nothing(tmp_path):
    process = start(zoo_command(tmp_path, "-n", "600"))
    time.sleep(0.3)
    os.kill(process.pid, signal.SIGINT)
    status, _, stderr = finish(process)
    assert status == 130 and "nothing was written" in stderr
    assert not (tmp_path / "mappo").exists()


def test_ctrl_c_twice_during_the_final_evaluation_finishes_the_run_without_it(tmp_path):
    """The run is trained to its budget: it is saved with its resume state and done.json (it was saved without them,
    and neither --resume nor a larger -n could continue it), and the line says the final evaluation was left out."""
    process = start(train_command(tmp_path, "-n", "60", "--eval-freq", "100000", "--eval-episodes", "2000"))
    folder = tmp_path / "mappo" / f"{TASK}_1"
    wait_for(process, lambda: trained_rows(folder) >= 1)
    time.sleep(0.3)
    ctrl_c_twice(process)
    status, stdout, _ = finish(process)
    assert status == 130 and (folder / "done.json").is_file()
    (line,) = [line for line in stdout.splitlines() if line.startswith("Stopped")]
    assert line.startswith("Stopped at once (Ctrl-C twice) during the final evaluation: the run is trained to its")
    longer = subprocess.run(
        train_command(tmp_path, "-n", "120", "--eval-freq", "100000", "--eval-episodes", "2000", "--resume"), cwd=REPO,
        env=child_env(), capture_output=True, text=True, timeout=TIMEOUT,
    )  # fmt: skip
    assert longer.returncode == 0, longer.stderr[-2000:]


@pytest.mark.parametrize(("stop_signal", "status", "name"), [(signal.SIGTERM, 143, "SIGTERM"), (signal.SIGHUP, 129, "SIGHUP")])
def test_sigterm_and_sighup_while_importing_exit_in_one_line(tmp_path, stop_signal, status, name):
    """They killed the process without a word (Ctrl-C had its line)."""
    process = start(train_command(tmp_path, "-n", "600"))
    time.sleep(0.3)
    os.kill(process.pid, stop_signal)
    exit_status, _, stderr = finish(process)
    assert exit_status == status
    assert f"sb3_saeir.train: {name} while starting: stopped, nothing was written" in stderr or (
        f"sb3_saeir.train: {name}: stopped before the run started: nothing was written" in stderr  # imported already
    )


def test_a_stop_signal_after_the_command_ended_is_ignored(monkeypatch):
    """The interpreter's shutdown takes a second after the command's last line: a signal then killed the finished
    command with another exit status."""
    from sb3_saeir.common.stop_signals import STOP_SIGNALS, exit_after_the_command

    previous = {signum: signal.getsignal(signum) for signum in STOP_SIGNALS}
    try:
        with pytest.raises(SystemExit) as ended:
            exit_after_the_command(0)
        assert ended.value.code == 0
        assert all(signal.getsignal(signum) is signal.SIG_IGN for signum in STOP_SIGNALS)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
