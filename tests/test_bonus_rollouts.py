"""A bonus callback of a baseline (RND, Elign) in a SAEIR_PPO run without its own bonus: ``coef`` times the bonus is
written into the rollout's intrinsic rewards, the recorded next observations are the rollout's, and the callback's
``rollout/`` and ``train/`` keys are logged."""

import numpy as np
import pytest
from stable_baselines3.common.logger import configure

from sb3_saeir import SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.intrinsic.elign import ElignCallback
from sb3_saeir.intrinsic.rnd import RNDCallback

BONUSES = {
    # a positive novelty bonus
    "rnd": (
        lambda: RNDCallback(coef=0.3),
        0.3,
        lambda bonus: (bonus > 0).all(),
        ("rollout/rnd_reward_mean", "rollout/rnd_raw_reward_mean", "train/rnd_loss"),
    ),
    # minus the teammates' prediction error: a wide radius so that every agent has neighbours
    "elign": (
        lambda: ElignCallback(coef=0.7, obs_radius=2.0),
        0.7,
        lambda bonus: (bonus < 0).any(),
        ("rollout/elign_reward_mean", "rollout/elign_neighbour_fraction", "train/elign_model_loss"),
    ),
}


@pytest.mark.parametrize("name", sorted(BONUSES))
def test_saeir_ppo_run_adds_coef_times_bonus(tmp_path, name):
    make_callback, coef, sign_holds, keys = BONUSES[name]
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    model = SAEIR_PPO(
        "MSHGPolicy", env, n_steps=10, n_epochs=1, intrinsic_reward=None, policy_kwargs=dict(hidden_size=8), seed=0
    )
    logger = configure(str(tmp_path), ["csv"])
    model.set_logger(logger)
    records = []
    original_dump = logger.dump
    logger.dump = lambda step=0: (records.append(dict(logger.name_to_value)), original_dump(step))
    callback = make_callback()
    model.learn(2 * 10 * 6, callback=callback)
    env.close()

    buffer = model.rollout_buffer
    assert callback.last_bonus is not None and callback.last_bonus.shape == (10, 6)
    assert np.isfinite(callback.last_bonus).all() and sign_holds(callback.last_bonus)
    expected = np.broadcast_to(coef * callback.last_bonus[..., None], buffer.intrinsic_rewards.shape)
    np.testing.assert_allclose(buffer.intrinsic_rewards, expected, rtol=1e-6)
    # no game ended within the 10 steps: the recorded o'_{t+1} is the next stored observation
    np.testing.assert_array_equal(np.stack(callback.next_observations)[:-1], buffer.observations[1:])
    for key in keys:
        assert key in records[-1], key
