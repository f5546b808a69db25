"""MultiAgentVecEnv's backends: slot layout, lockstep resets, seeding, episode statistics, SB3 VecEnv API, bad input."""

import numpy as np
import pytest
from gymnasium import spaces
from pettingzoo.utils.conversions import parallel_to_aec
from stable_baselines3.common.monitor import Monitor

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.common.vec_env import AgentDeathError, MultiAgentVecEnv
from sb3_saeir.envs.navigation import SparseCooperativeNavigation
from tests.toy_envs import DyingAgentsEnv, FreshSpacesMeetEnv, MixedSpacesEnv

N_AGENTS = 3


def random_actions(env, rng):
    return rng.integers(0, env.action_space.n, size=env.num_envs)


@pytest.fixture(params=["native", "supersuit"])
def env(request):
    """3 games of ``cn-sparse-n3``, through the native engine and through SuperSuit: both must honour the layout."""
    vec_env = make_multiagent_vec_env("cn-sparse-n3", n_games=3, seed=0, backend=request.param)
    yield vec_env
    vec_env.close()


def test_layout_attributes(env):
    assert isinstance(env, MultiAgentVecEnv)
    assert (env.n_agents, env.n_games, env.num_envs) == (3, 3, 9)
    assert env.possible_agents == ["agent_0", "agent_1", "agent_2"]
    assert env.observation_space.shape == (18,)
    assert isinstance(env.action_space, spaces.Discrete)


def test_slot_layout_by_observation_content(env):
    """slot = game * N + agent: slots of one game see the same landmarks; agent a's view of its teammates matches."""
    obs = env.reset()
    # (G * N, 18) -> (G, N, 18); obs = [vel(2), pos(2), landmark_rel(6), other_rel(4), comm(4)]
    per_game = obs.reshape(3, N_AGENTS, -1)
    positions = per_game[:, :, 2:4]
    landmarks_absolute = per_game[:, :, 4:10].reshape(3, N_AGENTS, 3, 2) + positions[:, :, None, :]
    for game in range(3):
        for agent in range(N_AGENTS):
            np.testing.assert_allclose(landmarks_absolute[game, agent], landmarks_absolute[game, 0], atol=1e-5)
            others = [other for other in range(N_AGENTS) if other != agent]
            other_rel = per_game[game, agent, 10:14].reshape(2, 2)
            np.testing.assert_allclose(other_rel, positions[game, others] - positions[game, agent], atol=1e-5)
    # different games are different episodes
    assert not np.allclose(landmarks_absolute[0, 0], landmarks_absolute[1, 0])


def test_lockstep_resets_and_terminal_observation(env):
    rng = np.random.default_rng(0)
    env.reset()
    for step in range(1, 51):
        _obs, rewards, dones, infos = env.step(random_actions(env, rng))
        assert dones.dtype == bool
        # all slots of a game are done together, and games (fixed 25-step horizon) finish together
        assert dones.all() == (step % 25 == 0)
        assert dones.any() == (step % 25 == 0)
        if step % 25 == 0:
            for slot in range(env.num_envs):
                assert infos[slot]["terminal_observation"].shape == (18,)
                assert "TimeLimit.truncated" not in infos[slot]
        # the team reward is identical for the agents of a game
        per_game = rewards.reshape(3, N_AGENTS)
        assert (per_game == per_game[:, :1]).all()


def test_mark_truncation():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0, mark_truncation=True, max_cycles=3)
    env.reset()
    for _ in range(3):
        _, _, dones, infos = env.step(np.zeros(env.num_envs, dtype=int))
    assert dones.all()
    assert all(info["TimeLimit.truncated"] for info in infos)
    env.close()


def first_observations(seed, n_games=4, num_cpus=0, steps=0):
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=n_games, seed=seed, num_cpus=num_cpus)
    stream = [env.reset()]
    rng = np.random.default_rng(123)
    for _ in range(steps):
        stream.append(env.step(random_actions(env, rng))[0])
    env.close()
    return np.stack(stream)


def test_seeding_reproducible_and_distinct():
    first = first_observations(seed=5)[0]
    np.testing.assert_array_equal(first, first_observations(seed=5)[0])
    assert not np.allclose(first, first_observations(seed=6)[0])
    per_game = first.reshape(4, N_AGENTS, -1)
    for g in range(4):
        for h in range(g + 1, 4):
            assert not np.allclose(per_game[g], per_game[h]), f"games {g} and {h} start identically"


def test_seed_method_and_reset_seed_agree():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2)
    seeds = env.seed(11)
    assert seeds == [11, 11, 11, 12, 12, 12]
    obs_seed_method = env.reset()
    obs_reset_kw = env.reset(seed=11)
    np.testing.assert_array_equal(obs_seed_method, obs_reset_kw)
    env.close()


def test_multiprocess_stream_identical_to_in_process():
    """num_cpus=2 must give the same per-game seeds (SuperSuit's own path gives overlapping ones)."""
    in_process = first_observations(seed=3, n_games=4, num_cpus=0, steps=30)
    subprocesses = first_observations(seed=3, n_games=4, num_cpus=2, steps=30)
    np.testing.assert_array_equal(in_process, subprocesses)
    per_game = subprocesses[0].reshape(4, N_AGENTS, -1)
    assert len({per_game[g, 0, 4:6].tobytes() for g in range(4)}) == 4


def test_reset_infos_flat_with_subprocesses():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=4, seed=0, num_cpus=2)
    env.reset()
    assert len(env.reset_infos) == env.num_envs
    assert all(isinstance(info, dict) for info in env.reset_infos)
    assert env.get_attr("render_mode") == [None] * env.num_envs
    with pytest.raises(RuntimeError, match="num_cpus=0"):
        env.env_method("state")
    env.close()


def test_one_episode_statistic_per_game(env):
    rng = np.random.default_rng(1)
    env.reset()
    episodes, successes = [], []
    for _ in range(50):
        _, _rewards, _dones, infos = env.step(random_actions(env, rng))
        for slot, info in enumerate(infos):
            if "episode" in info:
                assert slot % N_AGENTS == 0  # reported by the game's first agent only
                episodes.append(info["episode"])
            if "is_success" in info:
                successes.append(info["is_success"])
    assert len(episodes) == 2 * 3  # 2 episodes x 3 games, not x 3 agents
    assert len(successes) == 6
    for episode in episodes:
        assert episode["l"] == 25
        assert {"coverage_rate", "coverage_over_steps", "collision_steps", "success"} <= set(episode)
        assert 0.0 <= episode["coverage_rate"] <= 1.0


def test_episode_return_is_team_return():
    """The episode return is the sum over steps of the agents' mean reward: 6 steps of rewards 1, 2, 3 give 12 (the sum
    over agents would give 36, the first agent's rewards 6)."""
    from tests.toy_envs import UnequalRewardsEnv

    env = make_multiagent_vec_env(UnequalRewardsEnv, n_games=2, seed=4)
    env.reset()
    for _ in range(6):
        _, rewards, _, infos = env.step(np.zeros(env.num_envs, dtype=int))
    assert rewards.tolist() == [1.0, 2.0, 3.0] * 2  # the slots keep each agent's own reward
    assert [info["episode"]["r"] for info in infos if "episode" in info] == [12.0, 12.0]
    assert "episode" in infos[0] and "episode" in infos[3]  # one record per game, on its first agent's slot
    env.close()


def test_vec_env_api(env):
    env.reset()
    assert env.get_attr("render_mode") == [None] * 9
    assert env.get_attr("max_cycles", indices=[0, 4]) == [25, 25]
    assert env.env_is_wrapped(Monitor) == [False] * 9
    env.set_attr("max_cycles", 30, indices=[3])  # game 1 only
    assert env.get_attr("max_cycles") == [25] * 3 + [30] * 3 + [25] * 3
    states = env.env_method("state", indices=[0, 3])
    assert len(states) == 2 and states[0].shape == (54,)
    obs = env.reset()
    # global state of a game = concatenation of its agents' observations: (G * N, 18) -> (G, N * 18)
    np.testing.assert_allclose(env.get_state(), obs.reshape(3, -1), atol=1e-6)
    assert env.metadata["name"] == "cn_sparse_v0"


def test_render_game_zero():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0, render_mode="rgb_array")
    env.reset()
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    env.close()


@pytest.mark.parametrize(
    "options, shown",
    [
        (dict(), "NavigationVecEnv(n_games=2, n_agents=3, num_envs=6, world='mpe', reward='occupancy')"),
        (dict(backend="supersuit"), "MultiAgentDummyVecEnv(n_games=2, n_agents=3, num_envs=6, num_cpus=0)"),
        (dict(num_cpus=2), "MultiAgentSubprocVecEnv(n_games=2, n_agents=3, num_envs=6, num_cpus=2)"),
    ],
    ids=["native", "supersuit", "workers"],
)
def test_every_backend_renders_shows_and_closes_alike(options, shown):
    """What the base gives every backend: ``get_images`` (game 0's frame, ``None`` for the other slots), ``render``,
    ``repr`` and ``close`` (after which reset and step are refused)."""
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0, render_mode="rgb_array", **options)
    env.reset()
    images = env.get_images()
    assert len(images) == 6 and images[0].shape == (400, 400, 3) and images[1:] == [None] * 5
    np.testing.assert_array_equal(env.render(), images[0])
    assert repr(env) == shown
    env.close()
    assert env.closed
    with pytest.raises(RuntimeError, match="closed"):
        env.reset()


def test_callable_task():
    env = make_multiagent_vec_env(lambda: SparseCooperativeNavigation(N=2), n_games=2, seed=0)
    assert env.num_envs == 4
    env.close()


# ----------------------------------------------------------------------------------------------- bad input
def test_aec_env_rejected():
    with pytest.raises(TypeError, match="aec_to_parallel"):
        make_multiagent_vec_env(lambda: parallel_to_aec(SparseCooperativeNavigation()), n_games=2)


def test_not_a_pettingzoo_env_rejected():
    import gymnasium as gym

    with pytest.raises(TypeError, match="ParallelEnv"):
        make_multiagent_vec_env(lambda: gym.make("CartPole-v1"), n_games=2)


@pytest.mark.parametrize("which, fix", [("observation", "pad_observations_v0"), ("action", "pad_action_space_v0")])
def test_mixed_spaces_rejected(which, fix):
    with pytest.raises(ValueError, match=fix):
        make_multiagent_vec_env(lambda: MixedSpacesEnv(which), n_games=2)


def test_agent_death_rejected():
    env = make_multiagent_vec_env(DyingAgentsEnv, n_games=2, seed=0)
    env.reset()
    with pytest.raises(AgentDeathError, match=r"sb3_saeir.common.vec_env.black_death\(env\)"):
        for _ in range(5):
            env.step(np.zeros(env.num_envs, dtype=int))
    env.close()


@pytest.mark.parametrize("n_games", [0, -1, 1.5])
def test_bad_n_games(n_games):
    with pytest.raises(ValueError, match="n_games"):
        make_multiagent_vec_env("cn-sparse-n3", n_games=n_games)


def test_unknown_task():
    with pytest.raises(KeyError, match="cn-sparse-n3"):
        make_multiagent_vec_env("cn-dense", n_games=1)


def test_game_checks_ask_each_agents_observation_space_once():
    """The observation checks keep each agent's declared space: an env that builds a new space at every call is not
    asked again at every step (it costs about 15 µs per agent-step with gymnasium's Box)."""
    vec_env = make_multiagent_vec_env(FreshSpacesMeetEnv, n_games=2, seed=0)
    vec_env.reset()
    actions = np.zeros(vec_env.num_envs, dtype=np.int64)
    for _ in range(3):
        vec_env.step(actions)
    calls = FreshSpacesMeetEnv.space_calls
    for _ in range(20):  # past three episode ends (6 steps each)
        vec_env.step(actions)
    assert FreshSpacesMeetEnv.space_calls == calls
    vec_env.close()
