"""Shared fixtures: the tiny navigation env most tests train on, tiny algorithm budgets, a toy cooperative game."""

import os
import signal
import sys
import threading
import time

import pytest
import torch

from sb3_saeir import make_multiagent_vec_env

torch.set_num_threads(1)
os.environ.setdefault("OMP_NUM_THREADS", "1")  # the CLIs' default thread count follows it: tests run side by side


@pytest.fixture
def env():
    """``cn-sparse-n3`` with 2 games (6 agent slots), seeded."""
    vec_env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    yield vec_env
    vec_env.close()


@pytest.fixture
def tiny_kwargs():
    """Algorithm arguments for a fast MAPPO / SAEIR_PPO: 10-step rollouts, one epoch, 8-wide networks."""
    return dict(n_steps=10, n_epochs=1, policy_kwargs=dict(hidden_size=8))


@pytest.fixture
def toy_env():
    """:class:`toy_envs.ToyMeetEnv` (3 agents, 6 steps) with 3 games through SuperSuit, seeded."""
    from tests.toy_envs import ToyMeetEnv

    vec_env = make_multiagent_vec_env(ToyMeetEnv, n_games=3, seed=0)
    yield vec_env
    vec_env.close()


@pytest.fixture(scope="session")
def load_benchmark_script():
    """A loader of ``benchmarks/<name>.py`` as a module (the scripts are not a package)."""
    import importlib.util
    from pathlib import Path

    benchmarks = Path(__file__).parent.parent / "benchmarks"
    if str(benchmarks) not in sys.path:  # the scripts import each other, as they do when run from the command line
        sys.path.append(str(benchmarks))

    def load(name):
        spec = importlib.util.spec_from_file_location(name, benchmarks / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    return load


@pytest.fixture
def ctrl_c():
    """``ctrl_c(processes, delay)``: after ``delay`` seconds, send SIGINT to ``processes`` and to this process, as a
    terminal's Ctrl-C does to its process group. Python's SIGINT handler is restored for the test (pytest-xdist workers
    ignore SIGINT) and put back afterwards."""
    previous_handler = signal.signal(signal.SIGINT, signal.default_int_handler)

    def send(processes, delay):
        def interrupt():
            time.sleep(delay)
            for process in processes:
                os.kill(process.pid, signal.SIGINT)
            os.kill(os.getpid(), signal.SIGINT)

        threading.Thread(target=interrupt).start()

    yield send
    signal.signal(signal.SIGINT, previous_handler)


@pytest.fixture(scope="session")
def finished_tiny_run(tmp_path_factory):
    """The tiny ``train`` run of :mod:`tests.run_folders`, trained to its end once per test process. Read-only: the
    tests of damaged and moved run folders resume copies of it (:func:`tests.run_folders.unfinished_copy`)."""
    from tests.run_folders import finished_run

    return finished_run(tmp_path_factory.mktemp("uninterrupted"))


@pytest.fixture(scope="session")
def tiny_saeir_benchmark_run(tmp_path_factory):
    """A finished ``SAEIR_PPO`` benchmark run of 450 agent-steps (2 games, rollouts of 25 steps) with its
    ``progress.csv``, made once per test process, for the scripts that read a run folder's bonus logs. Read it only
    (``--entropy-plot`` writes its figure beside the logs, the same each time)."""
    from sb3_saeir.benchmark import main as benchmark_main

    out = tmp_path_factory.mktemp("saeir_benchmark")
    argv = ["--algos", "saeir_ppo", "--tasks", "cn-sparse-n3", "--seeds", "1", "-n", "450", "--n-games", "2"]
    argv += ["--eval-freq", "450", "--eval-episodes", "1", "-params", "n_steps:25", "n_epochs:1", "--out", str(out)]
    assert benchmark_main(argv) == 0
    return out / "runs" / "saeir_ppo" / "cn-sparse-n3_s1"


@pytest.fixture
def model(env, tiny_kwargs):
    """A tiny ``SAEIR_PPO`` on :func:`env` (the bad-input tests' model)."""
    from sb3_saeir import SAEIR_PPO

    return SAEIR_PPO("MSHGPolicy", env, **tiny_kwargs)
