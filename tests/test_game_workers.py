"""The game worker pool (``num_cpus >= 2``): the same streams as the in-process path, groups stepping on their own,
errors and deaths of workers, closing and Ctrl-C."""

import numpy as np
import pytest

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.common.vec_env.workers import GameWorkerError, split_games
from tests.toy_envs import DyingMeetEnv, FailingMeetEnv, JitteryMeetEnv, SlowMeetEnv, ToyMeetEnv


def comparable(info):
    """An info dict with arrays as lists and the episode's wall time dropped."""
    out = {}
    for key, value in info.items():
        if key == "episode":
            value = {k: v for k, v in value.items() if k != "t"}
        out[key] = value.tolist() if isinstance(value, np.ndarray) else value
    return out


def lockstep_rollout(task, n_games, num_cpus, steps=20, seed=5, **kwargs):
    """Reset, then ``steps`` steps of seeded random actions: every returned array and info."""
    env = make_multiagent_vec_env(task, n_games=n_games, seed=seed, num_cpus=num_cpus, **kwargs)
    rng = np.random.default_rng(0)
    record = [env.reset()]
    infos = [[comparable(info) for info in env.reset_infos]]
    for _ in range(steps):
        obs, rewards, dones, step_infos = env.step(rng.integers(0, env.action_space.n, size=env.num_envs))
        record += [obs, rewards, dones]
        infos.append([comparable(info) for info in step_infos])
    env.close()
    return record, infos


def test_split_games_contiguous_and_balanced():
    assert split_games(5, 3) == [range(0, 2), range(2, 4), range(4, 5)]
    assert split_games(4, 4) == [range(i, i + 1) for i in range(4)]
    blocks = split_games(17, 4)
    assert [len(b) for b in blocks] == [5, 4, 4, 4] and blocks[-1].stop == 17


@pytest.mark.parametrize("num_cpus", [2, 3])
def test_pool_streams_equal_in_process(num_cpus):
    """Observations, rewards, dones and infos (terminal observations, episode records) of 5 toy games through 20 steps,
    with three auto-resets per game: the workers give what the in-process path gives, for uneven blocks too."""
    reference, reference_infos = lockstep_rollout(ToyMeetEnv, 5, 0)
    record, infos = lockstep_rollout(ToyMeetEnv, 5, num_cpus)
    assert len(record) == len(reference)
    for got, expected in zip(record, reference):
        np.testing.assert_array_equal(got, expected)
    assert infos == reference_infos
    assert any("terminal_observation" in info for step in infos for info in step)


def test_pool_streams_equal_in_process_navigation():
    reference, reference_infos = lockstep_rollout("cn-sparse-n3", 4, 0, steps=30, backend="supersuit")
    record, infos = lockstep_rollout("cn-sparse-n3", 4, 2, steps=30, backend="supersuit")
    for got, expected in zip(record, reference):
        np.testing.assert_array_equal(got, expected)
    assert infos == reference_infos


def test_groups_stepping_on_their_own_give_the_lockstep_steps():
    """Each worker's games stepped on their own, new actions sent to whichever group answers first (jittery games, so
    the order changes), return through step_wait the steps that lockstep stepping returns."""
    n_steps, n_games = 15, 4
    actions = np.random.default_rng(1).integers(0, 3, size=(n_steps, n_games * 3))
    lockstep = make_multiagent_vec_env(JitteryMeetEnv, n_games=n_games, seed=2, num_cpus=2)
    lockstep.reset()
    expected = [lockstep.step(actions[t]) for t in range(n_steps)]
    lockstep.close()

    env = make_multiagent_vec_env(JitteryMeetEnv, n_games=n_games, seed=2, num_cpus=2)
    env.reset()
    groups = env.sampling_groups
    assert groups == [range(0, 6), range(6, 12)]
    sent = [0, 0]
    for group, slots in enumerate(groups):
        env.step_group_async(group, actions[0, slots.start : slots.stop])
        sent[group] = 1
    got = []
    while len(got) < n_steps:
        group, group_obs, group_dones = env.step_any_group_wait()
        assert group_obs.shape == (6, 2) and group_dones.shape == (6,)
        if sent[group] < n_steps:
            slots = groups[group]
            env.step_group_async(group, actions[sent[group], slots.start : slots.stop])
            sent[group] += 1
        while env.n_staged_steps:
            got.append(env.step_wait())
    env.close()
    for (obs, rewards, dones, infos), (obs_ref, rewards_ref, dones_ref, infos_ref) in zip(got, expected):
        np.testing.assert_array_equal(obs, obs_ref)
        np.testing.assert_array_equal(rewards, rewards_ref)
        np.testing.assert_array_equal(dones, dones_ref)
        assert [comparable(i) for i in infos] == [comparable(i) for i in infos_ref]


def test_in_process_env_is_one_group(toy_env):
    assert toy_env.sampling_groups == [range(toy_env.num_envs)]


def test_lockstep_step_refused_while_groups_step():
    env = make_multiagent_vec_env(ToyMeetEnv, n_games=2, seed=0, num_cpus=2)
    env.reset()
    env.step_group_async(0, np.zeros(3, dtype=np.int64))
    with pytest.raises(RuntimeError, match="double-buffered"):
        env.step_async(np.zeros(6, dtype=np.int64))
    with pytest.raises(RuntimeError, match="before every group"):
        env.step_any_group_wait()
        env.step_wait()
    env.reset()  # drains and starts over
    env.step(np.zeros(6, dtype=np.int64))
    env.close()


@pytest.mark.parametrize(
    "game, n_games, good_steps, message",
    [
        (FailingMeetEnv, 4, 2, r"Game worker 0 \(games 0-1\) failed: ValueError: the toy game broke"),
        (DyingMeetEnv, 2, 1, r"Game worker 0 \(games 0-0\) failed: the worker process ended without answering"),
    ],
    ids=["error", "death"],
)
def test_worker_error_or_death_names_the_worker_and_closes_the_pool(game, n_games, good_steps, message):
    env = make_multiagent_vec_env(game, n_games=n_games, seed=0, num_cpus=2)
    env.reset()
    processes = list(env.pool.processes)
    actions = np.zeros(env.num_envs, dtype=np.int64)
    for _ in range(good_steps):
        env.step(actions)
    with pytest.raises(GameWorkerError, match=message):
        env.step(actions)
    assert not any(process.is_alive() for process in processes)  # the pool closed itself
    with pytest.raises(GameWorkerError, match="closed"):
        env.step(actions)
    env.close()


def test_close_ends_workers_also_with_a_step_in_flight():
    env = make_multiagent_vec_env(JitteryMeetEnv, n_games=4, seed=0, num_cpus=2)
    env.reset()
    processes = list(env.pool.processes)
    env.step_group_async(1, np.zeros(6, dtype=np.int64))
    env.close()
    assert [process.exitcode for process in processes] == [0, 0]
    env.close()  # twice is fine


def test_ctrl_c_interrupts_the_parent_and_leaves_workers_to_close(ctrl_c):
    """SIGINT (what Ctrl-C sends to the whole process group) while waiting for a step: the parent gets
    KeyboardInterrupt, the workers ignore it and end cleanly when the env is closed."""
    env = make_multiagent_vec_env(SlowMeetEnv, n_games=2, seed=0, num_cpus=2)
    env.reset()
    processes = list(env.pool.processes)
    ctrl_c(processes, 0.1)
    with pytest.raises(KeyboardInterrupt):
        for _ in range(100):  # 5 s of steps; interrupted after 0.1 s
            env.step(np.zeros(6, dtype=np.int64))
    assert all(process.is_alive() for process in processes)
    env.close()
    assert [process.exitcode for process in processes] == [0, 0]
