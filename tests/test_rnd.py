"""Multi-agent RND: predictor learning, input whitening, reward normalisation, joint input, SAEIR_PPO integration."""

import numpy as np
import pytest
import torch as th

from sb3_saeir.intrinsic.base import true_next_observations
from sb3_saeir.intrinsic.rnd import RNDCallback


def test_bonus_shrinks_on_trained_states_and_stays_high_on_unseen_ones():
    th.manual_seed(0)
    rng = np.random.default_rng(0)
    states = rng.normal(size=(32, 6))
    unseen = rng.normal(size=(32, 6)) + 3.0  # another region of the input space (whitened ~ +3 per entry)
    callback = RNDCallback(learning_rate=1e-3, n_epochs=100, batch_size=32, device="cpu")
    callback.update_obs_stats(states)
    before = callback.raw_bonus(states).mean()
    callback.train_predictor(states)
    after = callback.raw_bonus(states).mean()
    assert after < 0.25 * before  # ~0.08 with these seeds
    assert callback.raw_bonus(unseen).mean() > 5 * after


def test_update_proportion_zero_is_rejected_and_partial_proportion_still_trains():
    with pytest.raises(ValueError, match=r"update_proportion must be in \(0, 1\], got 0.0"):
        RNDCallback(update_proportion=0.0)
    th.manual_seed(0)
    states = np.random.default_rng(1).normal(size=(32, 4))
    callback = RNDCallback(learning_rate=1e-3, n_epochs=50, batch_size=32, update_proportion=0.25, device="cpu")
    callback.update_obs_stats(states)
    before = callback.raw_bonus(states).mean()
    callback.train_predictor(states)
    assert callback.raw_bonus(states).mean() < 0.5 * before


def test_whitening_and_clipping_match_hand_computation():
    callback = RNDCallback(device="cpu")
    batch = np.array([[0.0, 1.0], [2.0, 1.5], [4.0, 2.0]])
    callback.update_obs_stats(batch)
    # batch mean (2, 1.5) and variance (8/3, 1/6), merged with RunningMeanStd's prior (mean 0, var 1, count 1e-4)
    prior, n_samples = 1e-4, 3
    batch_mean, batch_var = np.array([2.0, 1.5]), np.array([8 / 3, 1 / 6])
    mean = n_samples * batch_mean / (n_samples + prior)
    var = (prior + n_samples * batch_var + batch_mean**2 * prior * n_samples / (n_samples + prior)) / (n_samples + prior)
    std = np.sqrt(var + 1e-8)
    queries = np.array(
        [
            mean + np.array([1.0, 0.0]) * std,
            mean + np.array([0.0, -0.5]) * std,
            mean + np.array([4.5, -4.5]) * std,  # inside the clip
            [100.0, -100.0],  # clipped to +-5
        ]
    )
    expected = np.array([[1.0, 0.0], [0.0, -0.5], [4.5, -4.5], [5.0, -5.0]])
    np.testing.assert_allclose(callback.normalize_inputs(queries).numpy(), expected, atol=1e-5)
    # the prior is negligible: the statistics are the batch's
    np.testing.assert_allclose(callback.obs_rms.mean, batch_mean, rtol=1e-4)
    np.testing.assert_allclose(callback.obs_rms.var, batch_var, rtol=1e-3)


def test_reward_normalisation_matches_hand_loop():
    callback = RNDCallback(gamma_int=0.9, device="cpu")
    rollouts = [
        np.array([[1.0, 0.0], [2.0, 0.5], [0.0, 3.0]]),  # (T=3, 2 slots)
        np.array([[1.0, 1.0], [0.5, 2.0]]),  # the filter carries on from the previous rollout (non-episodic)
    ]
    discounted = np.zeros(2)
    all_returns = []
    for raw in rollouts:
        for step in range(len(raw)):
            discounted = 0.9 * discounted + raw[step]
            all_returns.append(discounted.copy())
        variance = np.var(np.concatenate(all_returns))  # every return seen so far, all slots pooled
        expected = raw / np.sqrt(variance + 1e-8)  # no mean subtraction
        np.testing.assert_allclose(callback.normalize_bonus(raw), expected, rtol=1e-3)


def test_joint_input_concatenates_a_games_agents_and_shares_the_bonus():
    th.manual_seed(0)
    next_obs = np.random.default_rng(0).normal(size=(4, 6, 5))  # T=4, 2 games x 3 agents, d=5
    joint = RNDCallback(input="joint", device="cpu")
    inputs = joint.rollout_inputs(next_obs, n_agents=3)
    assert inputs.shape == (4, 2, 15)
    np.testing.assert_array_equal(inputs[2, 1], np.concatenate([next_obs[2, 3], next_obs[2, 4], next_obs[2, 5]]))

    bonus = joint.bonus_from_next_observations(next_obs, n_agents=3)
    assert bonus.shape == (4, 6)
    per_game = bonus.reshape(4, 2, 3)
    np.testing.assert_array_equal(per_game, np.repeat(per_game[..., :1], 3, axis=-1))
    assert not np.allclose(per_game[:, 0, 0], per_game[:, 1, 0])

    individual = RNDCallback(input="agent", device="cpu").bonus_from_next_observations(next_obs, n_agents=3)
    assert individual.shape == (4, 6)
    assert not np.allclose(individual[:, 0], individual[:, 1])
    with pytest.raises(ValueError, match="Unknown RND input 'global'"):
        RNDCallback(input="global")


def test_true_next_observations_use_the_terminal_observation():
    new_obs = np.array([[1.0, 1.0], [2.0, 2.0]])  # slot 1's game ended: new_obs[1] is already the reset obs
    infos = [{}, {"terminal_observation": np.array([9.0, 8.0])}]
    result = true_next_observations(new_obs, np.array([False, True]), infos)
    np.testing.assert_array_equal(result, [[1.0, 1.0], [9.0, 8.0]])
    assert new_obs[1, 0] == 2.0  # a copy
