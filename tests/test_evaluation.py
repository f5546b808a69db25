"""The random-policy reference and multi-agent evaluation."""

import numpy as np
import pytest
from gymnasium import spaces

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy


def test_random_policy_discrete_draws_are_uniform_and_seeded():
    policy = RandomMultiAgentPolicy(spaces.Discrete(5, start=2), seed=3)
    actions = np.concatenate([policy.predict(np.zeros((6, 4)))[0] for _ in range(2000)])
    assert actions.shape == (12_000,)
    assert set(np.unique(actions)) == {2, 3, 4, 5, 6}
    assert np.allclose(np.bincount(actions - 2) / len(actions), 0.2, atol=0.02)
    # same seed, same draws; the deterministic flag does not change anything
    first = RandomMultiAgentPolicy(spaces.Discrete(5), seed=3).predict(np.zeros((6, 4)))[0]
    second = RandomMultiAgentPolicy(spaces.Discrete(5), seed=3).predict(np.zeros((6, 4)), deterministic=True)[0]
    np.testing.assert_array_equal(first, second)
    np.testing.assert_array_equal(first, np.random.default_rng(3).integers(0, 5, size=6))


def test_random_policy_box_space_is_copied_and_seeded():
    space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    policy = RandomMultiAgentPolicy(space, seed=1)
    actions, state = policy.predict(np.zeros((3, 4)))
    assert state is None
    assert actions.shape == (3, 2) and np.all(np.abs(actions) <= 1.0)
    assert policy.action_space is not space  # the env's own space is not reseeded
    np.testing.assert_array_equal(actions, RandomMultiAgentPolicy(space, seed=1).predict(np.zeros((3, 4)))[0])


def test_random_policy_on_sparse_navigation():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=4, seed=0)
    metrics, episodes = evaluate_multiagent_policy(RandomMultiAgentPolicy(env.action_space), env, 8, False, True)
    assert metrics["n_episodes"] == 8 and len(episodes) == 8  # two 25-step episodes of each of the 4 games
    assert [episode["l"] for episode in episodes] == [25] * 8
    assert 0.0 <= metrics["coverage_rate_mean"] <= 1.0
    assert 0.0 <= metrics["coverage_over_steps_mean"] <= 1.0
    assert metrics["ep_rew_mean"] == pytest.approx(np.mean([episode["r"] for episode in episodes]))
    assert metrics["coverage_rate_mean"] == pytest.approx(np.mean([episode["coverage_rate"] for episode in episodes]))
