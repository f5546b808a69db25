"""Benchmark fault tests: runs killed with SIGKILL and re-run end with the rows of uninterrupted runs; progress.csv,
wall time and the evaluation grid survive resumes; other settings are refused; Ctrl-C ends with one line."""

import contextlib
import csv
import json
import multiprocessing
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from sb3_saeir import benchmark, make_multiagent_vec_env
from sb3_saeir.benchmark import RunSpec, execute_run, execution, main, run_folder
from sb3_saeir.benchmark.cli import INTERRUPTED
from sb3_saeir.config import ALGOS as ALGO_CLASSES
from sb3_saeir.run.output import RunEvalCallback as BenchmarkEvalCallback

ALGOS = ["mappo", "saeir_ppo", "rnd"]
# 2 games x 3 agents: 6 agent-steps per vec step, 60 per rollout; evaluations at the first step >= k * 250
SETTINGS = ["--tasks", "cn-sparse-n3", "--seeds", "1", "-n", "900", "--n-games", "2", "--eval-freq", "250"]
ARGV = [*SETTINGS, "--eval-episodes", "2", "-params", "n_steps:10", "n_epochs:2"]
GRID = [0, 252, 504, 750, 900]
ROLLOUT_ENDS = list(range(60, 901, 60))
TIMEOUT = 120


def command(out):
    return [sys.executable, "-m", "sb3_saeir.benchmark", "--algos", *ALGOS, *ARGV, "--out", str(out)]


def child_env():
    return {**os.environ, "OMP_NUM_THREADS": "1"}


def read_csv(path):
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def folder_of(out, algo):
    return run_folder(out, RunSpec(algo, "cn-sparse-n3", 1, 900))


def last_evaluation(folder):
    try:
        rows = read_csv(folder / "evaluations.csv")
    except (FileNotFoundError, csv.Error):
        return -1
    return int(rows[-1]["timesteps"]) if rows else -1


def kill_mid_run(out, algo, ready):
    """Start the benchmark, SIGKILL its process group once ``ready(folder)`` holds (after a checkpoint exists)."""
    folder = folder_of(out, algo)
    process = subprocess.Popen(
        command(out), env=child_env(), start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    deadline = time.time() + TIMEOUT
    while not (any(folder.glob("rl_model_*_steps.zip")) and ready(folder)):
        assert process.poll() is None, f"the benchmark ended before {algo} could be killed"
        assert time.time() < deadline
        time.sleep(0.005)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    assert not (folder / "done.json").exists()  # killed mid-way


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """An uninterrupted benchmark (in the background) and the same benchmark killed once in each run, then re-run."""
    root = tmp_path_factory.mktemp("resume")
    reference, resumed = root / "reference", root / "resumed"
    background = subprocess.Popen(
        command(reference), env=child_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    start = time.time()
    kill_mid_run(resumed, "mappo", lambda folder: True)  # right at the first checkpoint
    kill_mid_run(resumed, "saeir_ppo", lambda folder: last_evaluation(folder) > 0)  # often before the next checkpoint
    kill_mid_run(resumed, "rnd", lambda folder: last_evaluation(folder) >= 504)
    final = subprocess.run(command(resumed), env=child_env(), capture_output=True, text=True, timeout=TIMEOUT)
    assert final.returncode == 0, final.stderr
    _, errors = background.communicate(timeout=TIMEOUT)
    assert background.returncode == 0, errors
    print(f"kills and resume {time.time() - start:.0f} s")
    return reference, resumed, final.stdout


def test_killed_runs_end_with_the_rows_of_uninterrupted_runs(runs):
    reference, resumed, stdout = runs
    assert stdout.count("resumed from the checkpoint at") == 1  # the last kill; the first two resumed in later kills
    assert read_csv(resumed / "runs.csv") == read_csv(reference / "runs.csv")
    for algo in ALGOS:
        log = (folder_of(resumed, algo) / "resume.log").read_text()
        assert "resumed from the checkpoint at" in log and "different from" not in log


def test_progress_covers_every_step_once(runs):
    """progress.csv is continued, not overwritten: every rollout and evaluation once, every value as uninterrupted."""
    reference, resumed, _ = runs
    for algo in ALGOS:
        rows = read_csv(folder_of(resumed, algo) / "progress.csv")
        training = [int(row["time/total_timesteps"]) for row in rows if row["time/iterations"]]
        evaluations = [int(row["time/total_timesteps"]) for row in rows if row["eval/mean_reward"]]
        assert training == ROLLOUT_ENDS and evaluations == GRID
        assert [int(row["time/iterations"]) for row in rows if row["time/iterations"]] == list(range(1, 16))
        expected = read_csv(folder_of(reference, algo) / "progress.csv")
        keys = [key for key in expected[0] if not key.startswith("time/") or key == "time/iterations"]
        assert [[row[key] for key in keys] for row in rows] == [[row[key] for key in keys] for row in expected]
    saeir = benchmark.read_rows(folder_of(resumed, "saeir_ppo") / "progress.csv")  # what plot_system_entropy reads
    assert benchmark.numeric_series(saeir, "rollout/intrinsic_reward_mean")[0] == [float(s) for s in ROLLOUT_ENDS]


def test_wall_time_sums_the_segments(runs):
    _, resumed, _ = runs
    for algo in ALGOS:
        folder = folder_of(resumed, algo)
        segments = json.loads((folder / "segments.json").read_text())
        done = json.loads((folder / "done.json").read_text())
        assert len(segments) == done["segments"] >= 2 and done["timesteps"] == 900
        assert done["wall_s"] == pytest.approx(sum(segment["wall_s"] for segment in segments), abs=0.06)
        assert segments[0]["resumed_at"] == 0 and segments[-1]["reached"] == 900
        assert all(segment["wall_s"] > 0 for segment in segments[1:])
        assert not list(folder.glob("rl_model_*_steps.zip"))


def test_final_model_is_saved_and_equals_the_uninterrupted_one(runs):
    """``cn-sparse-n3.zip`` of a finished run loads, has trained the whole budget, and a killed-and-resumed run's equals the
    uninterrupted run's parameter for parameter."""
    reference, resumed, _ = runs
    for algo in ALGOS:
        models = [
            ALGO_CLASSES[algo].load(folder_of(out, algo) / "cn-sparse-n3.zip", device="cpu") for out in (reference, resumed)
        ]
        assert all(model.num_timesteps == 900 for model in models)
        expected, actual = (model.policy.state_dict() for model in models)
        assert expected.keys() == actual.keys()
        for key in expected:
            np.testing.assert_array_equal(actual[key].numpy(), expected[key].numpy(), err_msg=f"{algo}: {key}")


def test_evaluations_stay_on_the_grid(runs):
    for out in runs[:2]:
        for algo in ALGOS:
            assert [int(row["timesteps"]) for row in read_csv(folder_of(out, algo) / "evaluations.csv")] == GRID


def snapshot(folder):
    return {path: path.read_bytes() for path in sorted(folder.rglob("*")) if path.is_file()}


@pytest.mark.parametrize(
    "change, message",
    [
        (["-n", "600"], "-n 900 -> 600 (a run is not trained shorter; a larger -n trains it longer)"),
        (["--eval-episodes", "3"], "--eval-episodes 2 -> 3"),
        (["-params", "n_steps:20", "n_epochs:2"], '-params {"n_epochs": 2, "n_steps": 10} -> {"n_epochs": 2, "n_steps": 20}'),
        (["--n-games", "3"], "--n-games 2 -> 3"),
    ],
)
def test_other_settings_are_refused_before_anything_changes(runs, capsys, change, message):
    reference = runs[0]
    before = snapshot(reference)
    assert main(["--algos", *ALGOS, *ARGV, *change, "--out", str(reference)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines[0].startswith("sb3_saeir.benchmark: error: 3 run(s) in") and "other settings" in lines[0]
    assert lines[1] == f"  mappo/cn-sparse-n3_s1: {message}" and len(lines) == 5
    assert "another --out" in lines[-1] and "--rerun-changed" in lines[-1]
    assert snapshot(reference) == before
    assert main(["--algos", *ALGOS, *ARGV, *change, "--out", str(reference), "--report-only"]) == 2
    assert "fix: give --report-only the settings" in capsys.readouterr().err
    assert snapshot(reference) == before


def test_folder_without_spec_is_refused(tmp_path, capsys):
    folder = folder_of(tmp_path, "mappo")
    folder.mkdir(parents=True)
    (folder / "evaluations.csv").write_text("algo,task,seed,timesteps\nmappo,cn-sparse-n3,1,0\n")
    assert main(["--algos", "mappo", *ARGV, "--out", str(tmp_path)]) == 2
    assert "settings are unknown" in capsys.readouterr().err


def test_rerun_changed_moves_the_old_run_aside(tmp_path, capsys):
    tiny = ["--algos", "mappo", "--seeds", "1", "--n-games", "2", "--eval-freq", "60", "-params", "n_steps:10", "n_epochs:1"]
    assert main([*tiny, "-n", "180", "--out", str(tmp_path)]) == 0
    folder = run_folder(tmp_path, RunSpec("mappo", "cn-sparse-n3", 1, 180))
    old = snapshot(folder)
    assert main([*tiny[:-1], "n_epochs:2", "-n", "180", "--out", str(tmp_path), "--rerun-changed"]) == 0
    assert "made with other settings, moved to" in capsys.readouterr().out
    (moved,) = folder.parent.glob("cn-sparse-n3_s1.replaced-*")
    assert {path.relative_to(moved): data for path, data in snapshot(moved).items()} == {
        path.relative_to(folder): data for path, data in old.items()
    }
    assert json.loads((folder / "spec.json").read_text())["params"] == {"n_epochs": 2, "n_steps": 10}
    assert [int(row["timesteps"]) for row in read_csv(tmp_path / "runs.csv")] == [0, 60, 120, 180]
    assert "(n=1)" in (tmp_path / "table.md").read_text()


def test_lost_evaluation_is_redone_and_said(tmp_path, monkeypatch):
    """An evaluation made after the checkpoint by a segment that dies is re-done, identical, and the log says so."""
    spec = RunSpec("mappo", "cn-sparse-n3", 3, 300, 2, 100, 2, {"n_steps": 10, "n_epochs": 1})
    execute_run(spec, str(tmp_path / "uninterrupted"))
    original = BenchmarkEvalCallback.evaluate

    def die_after_204(self):
        keep_going = original(self)
        if self.num_timesteps == 204:  # written to evaluations.csv; the checkpoint is at 180
            raise RuntimeError("machine went down")
        return keep_going

    folder = tmp_path / "killed"
    monkeypatch.setattr(BenchmarkEvalCallback, "evaluate", die_after_204)
    with pytest.raises(RuntimeError, match="machine went down"):
        execute_run(spec, str(folder))
    assert [int(row["timesteps"]) for row in read_csv(folder / "evaluations.csv")] == [0, 102, 204]
    monkeypatch.setattr(BenchmarkEvalCallback, "evaluate", original)
    execute_run(spec, str(folder))
    log = (folder / "resume.log").read_text()
    assert "resumed from the checkpoint at 180 agent-steps" in log
    assert "after the checkpoint, at [204] agent-steps, are re-done" in log
    assert "evaluation at 204 agent-steps re-done: identical" in log
    assert read_csv(folder / "evaluations.csv") == read_csv(tmp_path / "uninterrupted" / "evaluations.csv")


def test_native_env_resume_state_gives_the_same_streams():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=3, seed=5)
    env.reset()
    rng = np.random.default_rng(0)
    for _ in range(37):  # mid-episode: steps, running returns, generators all advanced
        env.step(rng.integers(0, 5, env.num_envs))
    state = env.get_resume_state()
    other = make_multiagent_vec_env("cn-sparse-n3", n_games=3, seed=99)
    other.reset()
    other.set_resume_state(state)
    for _ in range(30):  # past an episode end (resets draw from the restored generators)
        actions = rng.integers(0, 5, env.num_envs)
        (obs, rewards, dones, infos), (obs2, rewards2, dones2, infos2) = env.step(actions), other.step(actions)
        assert np.array_equal(obs, obs2) and np.array_equal(rewards, rewards2) and np.array_equal(dones, dones2)
        episodes = [{k: v for k, v in info["episode"].items() if k != "t"} for info in infos if "episode" in info]
        assert episodes == [{k: v for k, v in info["episode"].items() if k != "t"} for info in infos2 if "episode" in info]
    with pytest.raises(ValueError, match="cannot be put into"):
        make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0).set_resume_state(state)


def test_ctrl_c_ends_with_one_line(tmp_path, monkeypatch, capsys):
    def interrupted(spec, folder, num_threads=1):
        raise KeyboardInterrupt

    monkeypatch.setattr(execution, "execute_run", interrupted)
    assert main(["--algos", "mappo", *ARGV, "--out", str(tmp_path)]) == 130
    assert capsys.readouterr().err == INTERRUPTED + "\n"


@contextlib.contextmanager
def signal_once_the_jobs_run(tmp_path, monkeypatch, signum):
    """Replace the benchmark's runs by a 60 s sleep and send ``signum`` to this process once two jobs sleep: not
    earlier, since a signal inside the driver's first imports would leave a half-imported module to later tests."""
    started = tmp_path / "started"
    started.mkdir()
    ended = threading.Event()

    def slow(spec, folder, num_threads=1):  # workers are forked: they run this
        (started / str(os.getpid())).touch()
        time.sleep(60)

    def send():
        while len(list(started.iterdir())) < 2:
            if ended.wait(0.05):
                return
        os.kill(os.getpid(), signum)

    monkeypatch.setattr(execution, "execute_run", slow)
    sender = threading.Thread(target=send, daemon=True)
    sender.start()
    try:
        yield
    finally:
        ended.set()
        sender.join()


def test_ctrl_c_stops_the_worker_processes(tmp_path, monkeypatch, capsys):
    # a terminal's Ctrl-C: SIGINT raises KeyboardInterrupt (pytest-xdist workers and background jobs ignore SIGINT)
    previous_handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    start = time.time()
    try:
        with signal_once_the_jobs_run(tmp_path, monkeypatch, signal.SIGINT):
            assert main(["--algos", "mappo", *ARGV, "--seeds", "1-3", "--jobs", "2", "--out", str(tmp_path / "out")]) == 130
    finally:
        signal.signal(signal.SIGINT, previous_handler)
    assert time.time() - start < 30
    assert capsys.readouterr().err == INTERRUPTED + "\n"
    deadline = time.time() + 10  # terminated workers are reaped asynchronously; on a loaded machine it takes a moment
    while multiprocessing.active_children() and time.time() < deadline:
        time.sleep(0.1)
    assert multiprocessing.active_children() == []


@pytest.mark.parametrize(("stop_signal", "status"), [(signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_sigterm_and_sighup_stop_the_driver_and_its_jobs_as_ctrl_c_does(tmp_path, monkeypatch, capsys, stop_signal, status):
    start = time.time()
    with signal_once_the_jobs_run(tmp_path, monkeypatch, stop_signal):
        assert main(["--algos", "mappo", *ARGV, "--seeds", "1-3", "--jobs", "2", "--out", str(tmp_path / "out")]) == status
    assert time.time() - start < 30
    assert capsys.readouterr().err == INTERRUPTED + "\n"
    deadline = time.time() + 10
    while multiprocessing.active_children() and time.time() < deadline:
        time.sleep(0.1)
    assert multiprocessing.active_children() == []
    assert signal.getsignal(stop_signal) == signal.SIG_DFL  # the handler is put back


def ended(pid):
    """Whether process ``pid`` has ended (gone, or a zombie no one has reaped yet)."""
    try:
        with open(f"/proc/{pid}/stat") as file:
            return file.read().rsplit(")", 1)[1].split()[0] == "Z"
    except FileNotFoundError:
        return True


def children(pid):
    """The process ids whose parent is ``pid``."""
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as file:
                    if int(file.read().rsplit(")", 1)[1].split()[1]) == pid:
                        found.append(int(entry))
            except (FileNotFoundError, ProcessLookupError):
                continue
    return found


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads the process table from /proc")
def test_jobs_end_when_their_driver_is_killed(tmp_path):
    """SIGKILL to the driver (nothing can be handled): its --jobs processes end within seconds instead of training
    to the end and waiting forever on the dead driver's pipe with their run folders locked."""
    driver_code = (
        "import time, sys\n"
        "from sb3_saeir.benchmark import execution, main\n"
        "def slow(spec, folder, num_threads=1):\n"
        "    time.sleep(120)\n"
        "execution.execute_run = slow\n"
        f"sys.exit(main({['--algos', 'mappo', *ARGV, '--seeds', '1-2', '--jobs', '2', '--out', str(tmp_path)]!r}))\n"
    )
    driver = subprocess.Popen([sys.executable, "-c", driver_code], env={**os.environ, "OMP_NUM_THREADS": "1"})
    deadline = time.time() + 120
    while len(children(driver.pid)) < 2:
        assert driver.poll() is None and time.time() < deadline
        time.sleep(0.1)
    jobs = children(driver.pid)
    os.kill(driver.pid, signal.SIGKILL)
    driver.wait()
    deadline = time.time() + 15
    while not all(ended(pid) for pid in jobs) and time.time() < deadline:
        time.sleep(0.1)
    assert all(ended(pid) for pid in jobs), [pid for pid in jobs if not ended(pid)]
