"""The random-policy reference and multi-agent evaluation."""

import numpy as np
import pytest
from gymnasium import spaces

from sb3_saeir import MAPPO, make_multiagent_vec_env
from sb3_saeir.evaluation import MultiAgentEvalCallback, RandomMultiAgentPolicy, evaluate_multiagent_policy


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


@pytest.mark.parametrize("n_episodes", [2.5, "3", True, 0])
def test_evaluation_refuses_an_episode_count_that_is_not_a_whole_number(env, n_episodes):
    """2.5 evaluated 2 episodes without a word, True evaluated one, "3" ended in a TypeError naming no argument."""
    policy = RandomMultiAgentPolicy(env.action_space, seed=0)
    with pytest.raises(ValueError, match=r"^evaluate_multiagent_policy: n_episodes \(game episodes\) must be an integer"):
        evaluate_multiagent_policy(policy, env, n_episodes)
    assert evaluate_multiagent_policy(policy, env, np.int64(2))["n_episodes"] == 2  # NumPy integers pass


def test_a_main_metric_the_episodes_do_not_record_is_named_at_the_first_evaluation(env, tiny_kwargs, tmp_path):
    """A misspelt ``main_metric`` scored every evaluation -inf, so no best model was ever kept, without a word."""
    model = MAPPO("MAPPOPolicy", env, **tiny_kwargs)
    best = tmp_path / "best"
    callback = MultiAgentEvalCallback(env, n_eval_episodes=2, eval_freq=60, main_metric="coverage", verbose=0)
    with pytest.raises(ValueError) as error:
        model.learn(120, callback=callback)
    message = str(error.value)
    assert message.startswith("main_metric='coverage' is not recorded by the evaluated episodes") and "\n" not in message
    assert "coverage_rate" in message and "'r' for the team return" in message
    # the task's own metric keeps a best model
    callback = MultiAgentEvalCallback(
        env, n_eval_episodes=2, eval_freq=60, main_metric="coverage_rate", best_model_save_path=str(best), verbose=0
    )
    model.learn(120, callback=callback)
    assert (best / "best_model.zip").is_file() and np.isfinite(callback.best_score)


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"log_path": 3}, "log_path=3 is not a folder path"),
        ({"best_model_save_path": 3}, "best_model_save_path=3 is not a folder path"),
        ({"log_path": "/proc/evaluations"}, "log_path='/proc/evaluations': no file can be created in /proc"),
    ],
)
def test_eval_callback_folders_are_checked_when_it_is_built(env, kwargs, words):
    """A path that is not a path ended in os.makedirs' TypeError at learn; one that cannot be written, at the
    first evaluation's save."""
    with pytest.raises(ValueError) as error:
        MultiAgentEvalCallback(env, **kwargs)
    assert str(error.value).startswith(f"MultiAgentEvalCallback: {words}") and "\n" not in str(error.value)


def test_an_evaluation_on_games_that_do_not_end_warns(monkeypatch):
    """A game without a time limit kept evaluate_multiagent_policy waiting for ever, without a word."""
    from functools import partial

    import sb3_saeir.evaluation as evaluation
    from sb3_saeir import make_multiagent_vec_env
    from tests.toy_envs import ToyMeetEnv

    class Still:
        def predict(self, observations, state=None, episode_start=None, deterministic=False):
            return np.zeros(len(observations), dtype=np.int64), state

    monkeypatch.setattr(evaluation, "STEPS_WITHOUT_AN_END", 20)
    env = make_multiagent_vec_env(partial(ToyMeetEnv, max_cycles=30), n_games=1, seed=0)
    with pytest.warns(UserWarning, match="no game episode has ended in 20 steps; the evaluation waits for 1 to end"):
        summary = evaluation.evaluate_multiagent_policy(Still(), env, n_episodes=1)
    assert summary["ep_len_mean"] == 30
    env.close()
