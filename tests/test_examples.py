"""The examples stay runnable: each one runs as a subprocess at a tiny budget (the football one needs gfootball).

The custom intrinsic reward of ``examples/`` is also checked to reach training.
"""

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sb3_saeir import MAPPO, make_multiagent_vec_env

EXAMPLES = Path(__file__).parent.parent / "examples"


def load_example(name):
    path = EXAMPLES / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run_example(name, *args, timeout=300):
    """Run ``examples/<name>.py`` with ``args``; fail with its output if it fails. Returns its stdout."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / f"{name}.py"), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        cwd=EXAMPLES.parent,
    )
    assert result.returncode == 0, f"{name} failed:\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result.stdout


def test_custom_intrinsic_reward_example():
    example = load_example("custom_intrinsic_reward")
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    bonus = example.PositionCountBonus(coef=0.05)
    model = MAPPO("MAPPOPolicy", env, n_steps=10, n_epochs=1, seed=0).learn(10 * env.num_envs, callback=bonus)
    np.testing.assert_allclose(model.rollout_buffer.intrinsic_rewards[..., 0], 0.05 * bonus.last_bonus, atol=1e-7)
    assert (bonus.last_bonus > 0).all() and (bonus.last_bonus <= 1).all()
    env.close()


@pytest.fixture(scope="module")
def quickstart_run(tmp_path_factory):
    """The quickstart script at a tiny budget (4 games, 3 updates); its run folder."""
    out = tmp_path_factory.mktemp("quickstart")
    stdout = run_example(
        "train_cn_sparse",
        *("--timesteps", 900, "--n-games", 4, "--eval-freq", 300, "--eval-episodes", 4),
        *("--final-episodes", 20, "--gif-episodes", 1, "--no-progress", "--out", out),
    )
    return out, stdout


def test_quickstart_example(quickstart_run):
    out, stdout = quickstart_run
    for name in ("model.zip", "progress.csv", "eval.json", "learning_curve.png", "replay.gif"):
        assert (out / name).is_file(), name
    assert list(out.glob("events.out.tfevents.*")), "no tensorboard events"
    assert stdout.count("agent-steps | eval coverage") == 3  # one compact line per evaluation, no SB3 table
    assert "rollout/" not in stdout
    assert "random policy" in stdout and "coverage rate" in stdout and "success rate" in stdout
    assert "SAEIR bonus fired" in stdout
    report = json.loads((out / "eval.json").read_text())
    assert report["agent_steps"] == 900
    assert report["task"] == "cn-sparse-no-penalty-n3"  # the reading that reaches Table 1 (docs/tasks.md)
    assert report["trained"]["n_episodes"] == report["random"]["n_episodes"] == 20
    assert set(report["intrinsic_fire_rate"]) == {"team", "group", "individual"}
    assert report["verdict"].startswith("After 900 agent-steps")
    assert len(report["evaluations"]["timesteps"]) == 3


def test_evaluate_and_plot_example(quickstart_run, tmp_path):
    out, _ = quickstart_run
    stdout = run_example("evaluate_and_plot", out / "model.zip", "--episodes", 10, "--gif", "--out", tmp_path)
    assert "model " in stdout and "random " in stdout
    for name in ("evaluation.png", "training.png", "replay.gif"):
        assert (tmp_path / name).is_file(), name


def test_custom_env_example():
    stdout = run_example("train_custom_env", "--timesteps", 480, "--n-games", 2, "--eval-episodes", 4)
    assert "2 games x 3 agents = 6 slots" in stdout
    assert "trained  coverage rate" in stdout and "random   coverage rate" in stdout


def test_custom_env_example_game():
    """The example's ParallelEnv passes PettingZoo's parallel API test."""
    from pettingzoo.test import parallel_api_test

    parallel_api_test(load_example("train_custom_env").LineSpread(n_agents=3), num_cycles=30)


def test_custom_intrinsic_reward_script():
    # the script's own budget is 20k agent-steps; it runs as written (about 10 s) and its logs show the bonus
    stdout = run_example("custom_intrinsic_reward")
    bonus_means = [float(line.split("|")[2]) for line in stdout.splitlines() if "count_reward_mean" in line]
    assert bonus_means and all(0 < mean <= 1 for mean in bonus_means)  # 1 / sqrt(visits) of the rollout's cells
    steps = [int(line.split("|")[2]) for line in stdout.splitlines() if "total_timesteps" in line]
    assert steps[-1] >= 20_000


@pytest.mark.football
def test_football_example():
    stdout = run_example(
        "train_football", *("--timesteps", 300, "--n-steps", 50, "--n-epochs", 1, "--n-games", 1, "--eval-episodes", 1)
    )
    assert "trained  success rate" in stdout and "random   success rate" in stdout


def test_football_example_without_gfootball(tmp_path):
    """Without gfootball the example prints how to install it and exits cleanly."""
    (tmp_path / "sitecustomize.py").write_text(
        "import importlib.util\n_find = importlib.util.find_spec\n"
        "importlib.util.find_spec = lambda name, *a: None if name == 'gfootball' else _find(name, *a)\n"
    )
    env = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / "train_football.py")], capture_output=True, text=True, timeout=120, env=env
    )
    assert result.returncode == 0, result.stderr
    assert "bash scripts/install_football.sh" in result.stdout
