"""SAEIR_PPO as a drop-in for SB3's PPO: defaults on every task, API, callbacks, save/load, seeding, bad input."""

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, EvalCallback
from stable_baselines3.common.env_util import make_vec_env

from sb3_saeir import SAEIR_PPO, MSHGPolicy, make_multiagent_vec_env
from sb3_saeir.envs.navigation import SparseCooperativeNavigation
from sb3_saeir.intrinsic import SAEIRCallback, saeir_bonus
from sb3_saeir.mappo.losses import scale_advantage_weights

TINY_KWARGS = dict(n_steps=10, n_epochs=1, policy_kwargs=dict(hidden_size=8))


@pytest.mark.parametrize("task", ["cn-sparse-n3", "cn-sparse-n4", SparseCooperativeNavigation])
def test_defaults_work_on_every_task(task):
    """Default arguments (n_steps=25, chunk 10 -> a padded last chunk) never fail."""
    env = make_multiagent_vec_env(task, n_games=2, seed=0)
    model = SAEIR_PPO("MSHGPolicy", env, policy_kwargs=dict(hidden_size=8)).learn(2 * 25 * env.num_envs)
    assert model.num_timesteps == 2 * 25 * env.num_envs
    assert model.policy.scales == ("team", "group", "individual")
    env.close()


def test_policy_aliases():
    assert SAEIR_PPO.policy_aliases["MSHGPolicy"] is MSHGPolicy


def test_logs_task_metrics_intrinsic_reward_and_per_scale_losses(env, tmp_path):
    from stable_baselines3.common.logger import configure

    model = SAEIR_PPO("MSHGPolicy", env, seed=0, **TINY_KWARGS)
    logger = configure(str(tmp_path), ["csv"])
    model.set_logger(logger)
    records = []
    original_dump = logger.dump
    logger.dump = lambda step=0: (records.append(dict(logger.name_to_value)), original_dump(step))
    model.learn(3 * 10 * env.num_envs)
    last = records[-1]
    for key in (
        "rollout/ep_rew_mean",
        "rollout/coverage_rate",
        "rollout/success_rate",
        "rollout/intrinsic_reward_mean",
        "rollout/intrinsic_fire_rate_group",
        "train/value_loss_team",
        "train/value_loss_individual",
        "train/advantage_weight_group",
        "time/fps",
    ):
        assert key in last, key
    weights = [last[f"train/advantage_weight_{s}"] for s in ("team", "group", "individual")]
    assert sum(weights) == pytest.approx(1.0, abs=1e-5)


def test_scale_advantage_weights_hand_example():
    # team: e^0 + e^1, group: e^1 + e^1, individual: e^ln2 + e^0 = 3
    advantages = th.tensor([[0.0, 1.0, np.log(2.0)], [1.0, 1.0, 0.0]])
    sums = np.array([1 + np.e, 2 * np.e, 3.0])
    weights = scale_advantage_weights(advantages)
    np.testing.assert_allclose(weights.numpy(), sums / sums.sum(), rtol=1e-6)
    assert weights.sum().item() == pytest.approx(1.0)
    big = scale_advantage_weights(th.tensor([[500.0, 0.0], [0.0, 0.0]]))  # no overflow
    assert th.isfinite(big).all() and big[0] > 0.99


class CheckBonusInAdvantages(BaseCallback):
    """CheckGAE-style (SB3 tests/test_gae.py): at on_rollout_end the buffer's advantages include beta * SAEIR."""

    def __init__(self, beta, variant="code"):
        super().__init__()
        self.beta = beta
        self.variant = variant
        self.checked = 0

    def _on_step(self):
        return True

    def _on_rollout_end(self):
        buffer = self.model.rollout_buffer
        expected_bonus = self.beta * saeir_bonus(  # (T, E, K), from the stored values and the bootstrap only
            buffer.values, variant=self.variant, last_values=buffer.last_values, last_dones=buffer.last_dones
        )
        np.testing.assert_allclose(buffer.intrinsic_rewards, expected_bonus, atol=1e-6)
        # GAE without the bonus must differ by exactly the bonus' discounted sums: recompute both by hand
        values = self.model.policy.denormalize_values_numpy(buffer.values)
        last = self.model.policy.denormalize_values_numpy(buffer.last_values)
        gamma, lam = self.model.gamma, self.model.gae_lambda
        gae = np.zeros_like(last)
        for t in reversed(range(buffer.buffer_size)):
            mask = 1.0 - (buffer.last_dones if t == buffer.buffer_size - 1 else buffer.episode_starts[t + 1])
            next_values = last if t == buffer.buffer_size - 1 else values[t + 1]
            delta = buffer.rewards[t] + expected_bonus[t] + gamma * next_values * mask[:, None] - values[t]
            gae = delta + gamma * lam * mask[:, None] * gae
            np.testing.assert_allclose(buffer.advantages[t], gae, atol=1e-4)
        self.checked += 1


def test_saeir_bonus_reaches_the_advantages(env):
    checker = CheckBonusInAdvantages(beta=0.5)
    model = SAEIR_PPO("MSHGPolicy", env, intrinsic_coef=0.5, seed=0, **TINY_KWARGS)
    model.learn(2 * 10 * env.num_envs, callback=checker)  # auto SAEIRCallback runs before the checker
    assert checker.checked == 2


@pytest.mark.parametrize("variant", ["paper", "supplement"])
def test_bonus_variants_reach_the_advantages(env, variant):
    checker = CheckBonusInAdvantages(beta=0.5, variant=variant)
    model = SAEIR_PPO("MSHGPolicy", env, intrinsic_coef=0.5, intrinsic_kwargs={"variant": variant}, seed=0, **TINY_KWARGS)
    model.learn(2 * 10 * env.num_envs, callback=checker)
    assert checker.checked == 2
    assert np.count_nonzero(model.rollout_buffer.intrinsic_rewards) > 0


def test_explicit_saeir_callback_with_intrinsic_off(env):
    checker = CheckBonusInAdvantages(beta=0.2)
    model = SAEIR_PPO("MSHGPolicy", env, intrinsic_reward=None, seed=0, **TINY_KWARGS)
    # the checker comes first: every bonus is in the advantages before any callback's on_rollout_end, whatever the order
    model.learn(10 * env.num_envs, callback=[checker, SAEIRCallback(coef=0.2)])
    assert checker.checked == 1


def test_no_bonus_when_off(env):
    model = SAEIR_PPO("MSHGPolicy", env, intrinsic_reward=None, seed=0, **TINY_KWARGS).learn(10 * env.num_envs)
    assert not model.rollout_buffer.intrinsic_rewards.any()


def test_predict_any_number_of_agents_with_state(env):
    model = SAEIR_PPO("MSHGPolicy", env, seed=0, **TINY_KWARGS)
    obs = env.reset()
    actions, state = model.predict(obs, deterministic=True)
    assert actions.shape == (6,) and state.shape == (6, 8)
    _, state2 = model.predict(obs, state=state, episode_start=np.zeros(6), deterministic=True)
    assert not np.allclose(state, state2)  # the GRU state moved on
    # episode_start resets the state: same as a fresh call
    _, state_reset = model.predict(obs, state=state2, episode_start=np.ones(6), deterministic=True)
    np.testing.assert_allclose(state_reset, state, atol=1e-6)
    single_action, single_state = model.predict(obs[0], deterministic=True)
    assert np.ndim(single_action) == 0 and single_state.shape == (8,)
    assert single_action == actions[0]
    mlp_actor = SAEIR_PPO("MSHGPolicy", env, policy_kwargs=dict(hidden_size=8, recurrent_actor=False), n_steps=10)
    actions, state = mlp_actor.predict(obs[:4])
    assert actions.shape == (4,) and state is None


def test_save_load_identical_actions(env, tmp_path):
    model = SAEIR_PPO("MSHGPolicy", env, seed=0, **TINY_KWARGS).learn(2 * 10 * env.num_envs)
    obs = env.reset()
    actions, _ = model.predict(obs, deterministic=True)
    model.save(tmp_path / "model.zip")
    loaded = SAEIR_PPO.load(tmp_path / "model.zip", env=env)
    np.testing.assert_array_equal(loaded.predict(obs, deterministic=True)[0], actions)
    for scale in model.policy.scales:  # ValueNorm statistics are saved with the policy
        for name, buffer in model.policy.value_norms[scale].named_buffers():
            assert th.equal(buffer, dict(loaded.policy.value_norms[scale].named_buffers())[name])
    assert loaded.n_agents == 3 and loaded.n_minibatches == model.n_minibatches
    loaded.learn(10 * env.num_envs)  # continues training
    without_env = SAEIR_PPO.load(tmp_path / "model.zip")
    np.testing.assert_array_equal(without_env.predict(obs, deterministic=True)[0], actions)


def parameters_after_two_iterations(seed):
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2)
    model = SAEIR_PPO("MSHGPolicy", env, seed=seed, **TINY_KWARGS).learn(2 * 10 * env.num_envs)
    env.close()
    return th.cat([p.detach().flatten() for p in model.policy.parameters()])


def test_same_seed_same_parameters():
    first = parameters_after_two_iterations(3)
    assert th.equal(first, parameters_after_two_iterations(3))
    assert not th.equal(first, parameters_after_two_iterations(4))


def test_callbacks_progress_bar_tensorboard(env, tmp_path):
    eval_env = make_multiagent_vec_env("cn-sparse-n3", n_games=1, seed=5)
    callbacks = [
        CheckpointCallback(save_freq=10, save_path=str(tmp_path / "ckpt"), name_prefix="saeir"),
        EvalCallback(eval_env, n_eval_episodes=3, eval_freq=10, best_model_save_path=str(tmp_path / "best")),
    ]
    model = SAEIR_PPO("MSHGPolicy", env, tensorboard_log=str(tmp_path / "tb"), **TINY_KWARGS)
    model.learn(2 * 10 * env.num_envs, callback=callbacks, progress_bar=True)
    assert list((tmp_path / "ckpt").glob("saeir_*_steps.zip"))
    assert (tmp_path / "best" / "best_model.zip").exists()
    assert list((tmp_path / "tb").glob("SAEIR_PPO_1/events.out.tfevents.*"))
    eval_env.close()


def test_subset_of_scales_and_options(env):
    model = SAEIR_PPO(
        "MSHGPolicy",
        env,
        value_loss="mse",
        normalize_values=False,
        policy_kwargs=dict(hidden_size=8, scales=("team", "individual"), group_size=3, n_edge_types=2),
        **{k: v for k, v in TINY_KWARGS.items() if k != "policy_kwargs"},
    ).learn(10 * env.num_envs)
    assert model.policy.scales == ("team", "individual")
    assert model.rollout_buffer.values.shape[-1] == 2


# ----------------------------------------------------------------------------------------------- bad input
def test_env_without_n_agents_rejected():
    env = make_vec_env("CartPole-v1", n_envs=2)
    with pytest.raises(ValueError, match="make_multiagent_vec_env"):
        SAEIR_PPO("MSHGPolicy", env)


def test_batch_size_that_breaks_whole_games(env):
    with pytest.raises(ValueError, match=r"valid batch sizes: \[30, 60, 120\]"):
        SAEIR_PPO("MSHGPolicy", env, n_steps=20, batch_size=50)
    with pytest.raises(ValueError, match=r"valid batch sizes: \[150\].*not a multiple of data_chunk_length"):
        SAEIR_PPO("MSHGPolicy", env, n_steps=25, batch_size=30)
    assert SAEIR_PPO("MSHGPolicy", env, n_steps=25, batch_size=150).n_minibatches == 1
    model = SAEIR_PPO("MSHGPolicy", env, n_steps=20, batch_size=60)
    assert model.n_minibatches == 2
    with pytest.raises(ValueError, match="n_minibatches"):
        SAEIR_PPO("MSHGPolicy", env, n_steps=20, n_minibatches=5)


def test_unknown_options_rejected(env):
    with pytest.raises(ValueError, match="saeir"):
        SAEIR_PPO("MSHGPolicy", env, intrinsic_reward="curiosity")
    with pytest.raises(ValueError, match="scales"):
        SAEIR_PPO("MSHGPolicy", env, policy_kwargs=dict(scales=("team", "global")))


@pytest.mark.parametrize("n_agents, individual", [(3, 67_446), (4, 71_801)])
def test_policy_parameter_counts_football_shapes(n_agents, individual):
    """Spec §1.12 (authors' counts minus their unused 4,288-parameter block), GRF shapes: obs 115, 19 actions."""
    from gymnasium import spaces
    from torch import nn

    policy = MSHGPolicy(
        spaces.Box(-1, 1, (115,)), spaces.Discrete(19), lambda _: 5e-4, n_agents=n_agents, activation_fn=nn.ReLU
    )

    def count(params):
        return sum(p.numel() for p in params)

    assert count(policy.actor_parameters()) == 38_393
    assert count(policy.critic_parameters("team")) == 58_736
    assert count(policy.critic_parameters("group")) == 67_446
    assert count(policy.critic_parameters("individual")) == individual
    assert count(policy.parameters()) == 38_393 + 58_736 + 67_446 + individual
