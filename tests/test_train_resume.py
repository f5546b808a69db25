"""``python -m sb3_saeir.train --resume``: a run killed with SIGKILL (or stopped with Ctrl-C) and resumed ends as the
same run uninterrupted (parameters, progress.csv, evaluations, monitor rows); changed settings, finished runs and
runs without checkpoints are refused before anything is written."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import torch as th

from sb3_saeir.train import main as train_main
from tests.run_folders import monitor_rows, parameters, read_rows

# 2 games x 3 agents: 60 agent-steps per rollout; checkpoints at the first rollout start >= 120 agent-steps after the
# last one, evaluations every 250
SETTINGS = [
    "--task", "cn-sparse-n3", "--seed", "3", "-n", "900", "--n-games", "2", "--eval-freq", "250", "--eval-episodes", "2",
    "--save-freq", "120", "--num-threads", "1", "-params", "n_steps:10", "n_epochs:2",
]  # fmt: skip
TIMEOUT = 180


def command(algo, log_folder, *extra):
    return [sys.executable, "-m", "sb3_saeir.train", "--algo", algo, *SETTINGS, "-f", str(log_folder), *extra]


def child_env():
    return {**os.environ, "OMP_NUM_THREADS": "1"}


def run_folder(log_folder, algo):
    return log_folder / algo / "cn-sparse-n3_1"


def checkpoints(folder):
    return sorted(folder.glob("rl_model_*_steps.zip"), key=lambda path: int(path.name.split("_")[2]))


def start_and_stop(algo, log_folder, stop_signal, n_checkpoints):
    """Start a training run; send ``stop_signal`` to it once ``n_checkpoints`` checkpoints exist; its stdout."""
    return start_and_signal(algo, log_folder, stop_signal, n_checkpoints)[1]


def start_and_signal(algo, log_folder, stop_signal, n_checkpoints=1):
    """:func:`start_and_stop`, returning the run's exit status, stdout and stderr."""
    folder = run_folder(log_folder, algo)
    process = subprocess.Popen(
        command(algo, log_folder), env=child_env(), start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    deadline = time.time() + TIMEOUT
    while len(checkpoints(folder)) < n_checkpoints:
        assert process.poll() is None, f"the run ended before it could be stopped: {process.communicate()}"
        assert time.time() < deadline
        time.sleep(0.005)
    os.kill(process.pid, stop_signal)
    stdout, stderr = process.communicate(timeout=TIMEOUT)
    return process.returncode, stdout.decode(), stderr.decode()


def resume(algo, log_folder, *extra):
    return subprocess.run(
        command(algo, log_folder, "--resume", *extra), env=child_env(), capture_output=True, text=True, timeout=TIMEOUT
    )


def assert_same_run(folder, reference):
    """Same final parameters, progress.csv rows (but time/ columns), evaluations and monitor rows (but wall time)."""
    final, expected = parameters(folder / "cn-sparse-n3.zip"), parameters(reference / "cn-sparse-n3.zip")
    assert final.keys() == expected.keys()
    for name in expected:
        assert th.equal(final[name], expected[name]), name
    rows, expected_rows = read_rows(folder / "progress.csv"), read_rows(reference / "progress.csv")
    counters = ("time/iterations", "time/total_timesteps")
    keys = [key for key in expected_rows[0] if not key.startswith("time/") or key in counters]
    assert [[row.get(key) for key in keys] for row in rows] == [[row[key] for key in keys] for row in expected_rows]
    evaluations, expected_evaluations = np.load(folder / "evaluations.npz"), np.load(reference / "evaluations.npz")
    assert sorted(evaluations.files) == sorted(expected_evaluations.files)
    for name in expected_evaluations.files:
        np.testing.assert_array_equal(evaluations[name], expected_evaluations[name])
    games, expected_games = monitor_rows(folder), monitor_rows(reference)
    assert games == expected_games and len(games) > 0


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """Each method's uninterrupted run."""
    log_folder = tmp_path_factory.mktemp("uninterrupted")
    for algo in ("mappo", "saeir_ppo"):
        finished = subprocess.run(command(algo, log_folder), env=child_env(), capture_output=True, text=True, timeout=TIMEOUT)
        assert finished.returncode == 0, finished.stderr
    return log_folder


# killed before the first evaluation (at 252 agent-steps) and after it (the eval env's state must come back too)
@pytest.mark.parametrize(("algo", "n_checkpoints"), [("mappo", 2), ("saeir_ppo", 3)])
def test_killed_run_resumes_as_if_uninterrupted(algo, n_checkpoints, reference, tmp_path):
    start_and_stop(algo, tmp_path, signal.SIGKILL, n_checkpoints)
    folder = run_folder(tmp_path, algo)
    assert not (folder / "cn-sparse-n3.zip").exists()  # killed mid-way
    resumed = resume(algo, tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert f"Resuming {folder} from {checkpoints(folder)[n_checkpoints - 1].name}" in resumed.stdout
    assert "approximately" not in resumed.stdout
    assert sorted(path.name for path in (tmp_path / algo).iterdir()) == ["cn-sparse-n3_1"]  # no new run folder
    assert_same_run(folder, run_folder(reference, algo))


def test_ctrl_c_writes_a_checkpoint_and_the_resume_goes_on_from_it(reference, tmp_path):
    stdout = start_and_stop("mappo", tmp_path, signal.SIGINT, n_checkpoints=1)
    folder = run_folder(tmp_path, "mappo")
    assert "Ctrl-C: writing a checkpoint" in stdout and "Stopped at the checkpoint" in stdout
    stopped_at = checkpoints(folder)[-1]
    assert stopped_at.name in stdout.split("Stopped at the checkpoint")[1]
    resumed = resume("mappo", tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert f"from {stopped_at.name}" in resumed.stdout
    assert_same_run(folder, run_folder(reference, "mappo"))


def test_changed_settings_are_refused_and_nothing_is_written(tmp_path, capsys):
    start_and_stop("mappo", tmp_path, signal.SIGKILL, n_checkpoints=1)
    folder = run_folder(tmp_path, "mappo")
    before = {path: path.stat().st_mtime_ns for path in folder.rglob("*")}
    argv = ["--algo", "mappo", *SETTINGS, "-f", str(tmp_path), "--resume"]
    argv[argv.index("--eval-freq") + 1] = "500"
    argv[argv.index("n_epochs:2")] = "n_epochs:3"
    assert train_main(argv) == 2
    error = capsys.readouterr().err
    assert "--eval-freq 250 -> 500" in error and '-params {"n_epochs": 2' in error and '{"n_epochs": 3' in error
    assert "other settings" in error
    assert {path: path.stat().st_mtime_ns for path in folder.rglob("*")} == before


def test_finished_run_is_refused(reference, capsys):
    assert train_main(["--algo", "mappo", *SETTINGS, "-f", str(reference), "--resume"]) == 2
    assert "is finished" in capsys.readouterr().err


def test_nothing_to_resume_is_refused(tmp_path, capsys):
    assert train_main(["--algo", "mappo", *SETTINGS, "-f", str(tmp_path), "--resume"]) == 2
    assert "no run of mappo on cn-sparse-n3" in capsys.readouterr().err
    argv = ["--algo", "mappo", *SETTINGS, "-f", str(tmp_path), "-n", "120"]
    argv[argv.index("--save-freq") + 1] = "-1"
    assert train_main(argv) == 0
    (tmp_path / "mappo" / "cn-sparse-n3_1" / "cn-sparse-n3.zip").unlink()  # no checkpoint, no final model
    argv = ["--algo", "mappo", *SETTINGS, "-f", str(tmp_path), "-n", "300", "--resume", "1"]
    argv[argv.index("--save-freq") + 1] = "-1"
    assert train_main(argv) == 2
    assert "has no checkpoint (rl_model_<steps>_steps.zip) and no final model" in capsys.readouterr().err
    assert train_main([*argv[:-1], "7"]) == 2
    assert "no run 7 of mappo" in capsys.readouterr().err


def test_a_seed_other_than_the_runs_is_refused_and_no_seed_takes_the_runs(finished_tiny_run, tmp_path, capsys):
    from tests.run_folders import argv, snapshot, unfinished_copy

    folder = unfinished_copy(finished_tiny_run, tmp_path / "logs")
    before = snapshot(folder)
    command = argv(tmp_path / "logs", "--resume")  # the run's seed is 3
    index = command.index("--seed")
    command[index + 1] = "5"
    assert train_main(command) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"{folder} was made with --seed 3, not --seed 5" in line and "Give --seed 3 (or no --seed)" in line
    assert snapshot(folder) == before
    command[index + 1] = "-1"  # -1 (draw one) at --resume: the run's
    assert train_main(command) == 0
    assert "agent-steps, seed 3" in capsys.readouterr().out


def test_a_run_stopped_by_ctrl_c_exits_with_130(tmp_path):
    """A script can tell a run stopped early from a finished one: 130, as shells give a command ended by SIGINT."""
    folder = run_folder(tmp_path, "mappo")
    status, stdout, _ = start_and_signal("mappo", tmp_path, signal.SIGINT)
    assert status == 130
    assert "Stopped at the checkpoint" in stdout and not (folder / "done.json").exists()


@pytest.mark.parametrize(("stop_signal", "status"), [(signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_sigterm_and_sighup_stop_at_a_checkpoint_as_ctrl_c_does(reference, tmp_path, stop_signal, status):
    """kill, timeout, container stops and batch schedulers send SIGTERM first, a closed terminal SIGHUP: the run writes
    a checkpoint, says so in one line, exits with 128 + the signal, and --resume ends it as the uninterrupted run."""
    folder = run_folder(tmp_path, "mappo")
    returncode, stdout, stderr = start_and_signal("mappo", tmp_path, stop_signal)
    name = signal.Signals(stop_signal).name
    assert returncode == status, stderr[-2000:]
    assert f"{name}: writing a checkpoint" in stdout and "Stopped at the checkpoint" in stdout
    stopped_at = checkpoints(folder)[-1]
    assert stopped_at.name in stdout.split("Stopped at the checkpoint")[1]
    assert not (folder / "done.json").exists()
    resumed = resume("mappo", tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert f"from {stopped_at.name}" in resumed.stdout
    assert_same_run(folder, run_folder(reference, "mappo"))
