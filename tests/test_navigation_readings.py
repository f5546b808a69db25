"""The named readings of sparse navigation (``docs/tasks.md``): ``cn-sparse-no-penalty-n3`` / ``-n4`` build the game
without the collision penalty, ``cn-sparse-n3`` / ``-n4`` keep the paper's words, and the new ids work everywhere a
task id works (the vec env, the zoo configs, ``train``, ``enjoy``, Optuna, the benchmark, ``zoo train``), with the
reward options in each run's record."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.benchmark import main as benchmark_main
from sb3_saeir.config import ALGOS, load_hyperparams
from sb3_saeir.enjoy import main as enjoy_main
from sb3_saeir.envs import list_tasks, make_task
from sb3_saeir.train import main as train_main

REPO = Path(__file__).parent.parent
NO_PENALTY = {3: "cn-sparse-no-penalty-n3", 4: "cn-sparse-no-penalty-n4"}
WORDED = {3: "cn-sparse-n3", 4: "cn-sparse-n4"}
TINY = ["--n-games", "2", "-params", "n_steps:10", "n_epochs:1", "--verbose", "0"]


@pytest.mark.parametrize("n_agents", [3, 4])
def test_each_reading_has_its_id_and_the_worded_ids_keep_their_meaning(n_agents):
    assert {NO_PENALTY[n_agents], WORDED[n_agents]} <= set(list_tasks())
    no_penalty, worded = make_task(NO_PENALTY[n_agents]), make_task(WORDED[n_agents])
    assert len(no_penalty.possible_agents) == len(worded.possible_agents) == n_agents
    assert no_penalty.collision_penalty == 0.0 and no_penalty.reward == "occupancy"
    assert worded.collision_penalty == 1.0 and worded.reward == "occupancy"


def random_play_rewards(task, n_steps=200, **kwargs):
    """Team rewards and collision flags of ``n_steps`` of seeded random play in 4 games of ``task``."""
    env = make_multiagent_vec_env(task, n_games=4, seed=3, **kwargs)
    actions = np.random.default_rng(0).integers(0, 5, size=(n_steps, env.num_envs))
    env.reset()
    rewards = []
    for step_actions in actions:
        _, reward, _, _ = env.step(step_actions)
        rewards.append(reward)
    env.close()
    return np.array(rewards)  # (n_steps, 4 games x n_agents)


def test_the_no_penalty_id_is_the_worded_task_with_collision_penalty_zero():
    no_penalty = random_play_rewards("cn-sparse-no-penalty-n3")
    assert np.array_equal(no_penalty, random_play_rewards("cn-sparse-n3", collision_penalty=0.0))
    worded = random_play_rewards("cn-sparse-n3")
    # the same episodes: the worded reward is 1 lower exactly on the steps with a collision, never negative without it
    difference = no_penalty - worded
    assert set(np.unique(difference)) == {0.0, 1.0} and (no_penalty >= 0).all() and (worded < 0).any()


@pytest.mark.parametrize("algo", sorted(ALGOS))
@pytest.mark.parametrize("n_agents", [3, 4])
def test_every_method_has_the_paper_settings_for_the_new_ids(algo, n_agents):
    worded = load_hyperparams(algo, WORDED[n_agents])
    no_penalty = load_hyperparams(algo, NO_PENALTY[n_agents])
    assert no_penalty["env_kwargs"] == {"N": n_agents, "collision_penalty": 0.0}
    assert {**no_penalty, "env_kwargs": None} == {**worded, "env_kwargs": None}


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny ``train`` run of MAPPO on ``cn-sparse-no-penalty-n3``."""
    folder = tmp_path_factory.mktemp("logs")
    argv = ["--algo", "mappo", "--task", "cn-sparse-no-penalty-n3", *TINY, "-n", "120", "--eval-freq", "60"]
    assert train_main([*argv, "--eval-episodes", "2", "-f", str(folder)]) == 0
    return folder, folder / "mappo" / "cn-sparse-no-penalty-n3_1"


def test_train_records_the_reward_options(trained):
    _, run = trained
    record = json.loads((run / "spec.json").read_text())
    assert record["task"] == "cn-sparse-no-penalty-n3"
    assert record["config"]["env_kwargs"] == {"N": 3, "collision_penalty": 0.0}
    assert record["game_kwargs"] == {"N": 3, "collision_penalty": 0.0}
    assert (run / "cn-sparse-no-penalty-n3.zip").is_file()


def test_the_record_names_the_reward_options_the_config_leaves_out(tmp_path):
    """``-params env_kwargs:{N: 3}`` drops the option from the config; the game still has no penalty, and the record
    says so in ``game_kwargs``."""
    argv = ["--algo", "mappo", "--task", "cn-sparse-no-penalty-n3", "--n-games", "2", "--verbose", "0", "-n", "60"]
    argv += ["-params", "n_steps:10", "n_epochs:1", "env_kwargs:{'N': 3}", "--eval-freq", "0", "-f", str(tmp_path)]
    assert train_main(argv) == 0
    record = json.loads((tmp_path / "mappo" / "cn-sparse-no-penalty-n3_1" / "spec.json").read_text())
    assert record["config"]["env_kwargs"] == {"N": 3}
    assert record["game_kwargs"] == {"N": 3, "collision_penalty": 0.0}


def test_enjoy_replays_the_new_id(trained, capsys):
    folder, _ = trained
    argv = ["--algo", "mappo", "--task", "cn-sparse-no-penalty-n3", "-f", str(folder), "-n", "2", "--n-games", "2"]
    assert enjoy_main(argv) == 0
    assert "coverage_rate" in capsys.readouterr().out


def test_optuna_on_the_new_id(tmp_path):
    argv = ["--algo", "mappo", "--task", "cn-sparse-no-penalty-n4", "--n-games", "2", "-n", "80", "--eval-episodes", "2"]
    argv += ["--n-evaluations", "1", "-params", "n_steps:10", "--verbose", "0", "--optimize", "--n-trials", "1"]
    assert train_main([*argv, "--sampler", "random", "-f", str(tmp_path)]) == 0
    assert (tmp_path / "mappo" / "mappo_cn-sparse-no-penalty-n4.db").is_file()


def test_benchmark_on_the_new_ids(tmp_path, capsys):
    argv = ["--algos", "mappo", "--tasks", "cn-sparse-no-penalty-n3", "cn-sparse-no-penalty-n4", "--seeds", "1"]
    argv += ["-n", "80", "--n-games", "2", "--eval-freq", "40", "--eval-episodes", "2", "-params", "n_steps:10"]
    assert benchmark_main([*argv, "--out", str(tmp_path)]) == 0
    for n_agents, task in NO_PENALTY.items():
        record = json.loads((tmp_path / "runs" / "mappo" / f"{task}_s1" / "spec.json").read_text())
        assert record["game_kwargs"] == {"N": n_agents, "collision_penalty": 0.0}
    assert "cn-sparse-no-penalty-n4" in (tmp_path / "table.md").read_text()


def test_zoo_train_on_the_new_id(tmp_path):
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    task = "cn-sparse-no-penalty-n3"
    command = [sys.executable, "-m", "sb3_saeir.zoo", "train", "--algo", "mappo", "--env", task, "--conf-file"]
    command += ["zoo_configs/mappo.yml", "-f", str(tmp_path), "--num-threads", "1", "--device", "cpu", "--seed", "0"]
    command += ["-n", "120", "-params", "n_envs:2", "n_steps:10", "--eval-freq", "0"]
    result = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    record = json.loads((tmp_path / "mappo" / f"{task}_1" / "spec.json").read_text())
    assert record["task"] == task and record["game_kwargs"] == {"N": 3, "collision_penalty": 0.0}
