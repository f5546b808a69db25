"""sb3_saeir.common.run_state and the objects whose state a checkpoint carries: which envs resume exactly, what a
monitor's CSV keeps after a restore, the checkpoint callback's bad input."""

import csv

import numpy as np
import pytest

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.common.run_state import RunCheckpointCallback, atomic_write_text, resumable_env, unresumable_part
from sb3_saeir.common.vec_env import MultiAgentVecMonitor


@pytest.fixture
def supersuit():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0, backend="supersuit")
    yield env
    env.close()


def test_which_envs_resume_exactly(env, supersuit):
    assert resumable_env(env) is env and unresumable_part(env) == "NavigationVecEnv"
    monitor = MultiAgentVecMonitor(env)
    assert resumable_env(monitor) is monitor and unresumable_part(monitor) == "MultiAgentVecMonitor"
    assert resumable_env(supersuit) is None and unresumable_part(supersuit) == "MultiAgentDummyVecEnv"
    assert resumable_env(MultiAgentVecMonitor(supersuit)) is None
    assert unresumable_part(MultiAgentVecMonitor(supersuit)) == "MultiAgentDummyVecEnv"  # the part that cannot, named


def play(env, steps, rng):
    for _ in range(steps):
        env.step(rng.integers(0, 5, size=env.num_envs))


def rows(path):
    with open(path) as file:
        file.readline()  # the JSON header line
        return list(csv.DictReader(file))


def test_monitor_restore_cuts_its_csv_back_and_goes_on_as_before(env, tmp_path):
    rng = np.random.default_rng(0)
    monitor = MultiAgentVecMonitor(env, str(tmp_path / "games"))
    monitor.reset()
    play(monitor, 30, rng)  # 25-step episodes: 2 rows
    state, rng_state = monitor.get_resume_state(), rng.bit_generator.state
    play(monitor, 50, rng)  # 4 more rows
    uninterrupted = rows(tmp_path / "games.monitor.csv")
    assert len(uninterrupted) == 6
    monitor.set_resume_state(state)  # as a resumed process would, after rows written past the checkpoint
    assert len(rows(tmp_path / "games.monitor.csv")) == 2 and monitor.n_finished_games == 2
    rng.bit_generator.state = rng_state
    play(monitor, 50, rng)
    monitor.close()
    without_time = [{key: value for key, value in row.items() if key != "t"} for row in rows(tmp_path / "games.monitor.csv")]
    assert without_time == [{key: value for key, value in row.items() if key != "t"} for row in uninterrupted]


def test_monitor_append_keeps_an_existing_csv(env, tmp_path):
    rng = np.random.default_rng(0)
    first = MultiAgentVecMonitor(env, str(tmp_path / "games"))
    first.reset()
    play(first, 25, rng)
    first.close()
    second_env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=1)
    second = MultiAgentVecMonitor(second_env, str(tmp_path / "games"), append=True)
    second.reset()
    play(second, 25, rng)
    second.close()
    assert len(rows(tmp_path / "games.monitor.csv")) == 4
    with pytest.raises(TypeError, match="append must be True or False"):
        MultiAgentVecMonitor(second_env, append="yes")


@pytest.mark.parametrize("save_freq", [-1, 1.5, True])
def test_checkpoint_callback_refuses_a_bad_frequency(tmp_path, save_freq):
    with pytest.raises(ValueError, match="save_freq must be an integer >= 0"):
        RunCheckpointCallback(tmp_path, "rl_model_{steps}_steps.zip", save_freq=save_freq)


def test_checkpoint_names_carry_the_steps(tmp_path):
    callback = RunCheckpointCallback(tmp_path, "rl_model_{steps}_steps.zip", save_freq=100)
    assert callback.path(1200) == tmp_path / "rl_model_1200_steps.zip"


def test_atomic_write_leaves_no_temporary_file(tmp_path):
    atomic_write_text(tmp_path / "a.txt", "one")
    atomic_write_text(tmp_path / "a.txt", "two")
    assert (tmp_path / "a.txt").read_text() == "two" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
