"""Grouped recurrent buffer: per-scale GAE with the bonus, whole-game minibatches, chunk replay of the GRUs."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer
from sb3_saeir.common.torch_layers import HypergraphScaleCritic


def make_buffer(n_steps=7, n_games=2, n_agents=3, n_scales=2, chunk=3):
    return GroupedRecurrentRolloutBuffer(
        n_steps,
        spaces.Box(-1, 1, (4,)),
        spaces.Discrete(5),
        n_envs=n_games * n_agents,
        n_agents=n_agents,
        n_scales=n_scales,
        actor_hidden_size=2,
        critic_hidden_size=2,
        data_chunk_length=chunk,
        gamma=0.9,
        gae_lambda=0.8,
    )


def fill(buffer, rng, per_scale_rewards=False):
    n_envs, n_scales = buffer.n_envs, buffer.n_scales
    reward_shape = (n_envs, n_scales) if per_scale_rewards else (n_envs,)
    for _ in range(buffer.buffer_size):
        buffer.add(
            rng.normal(size=(n_envs, 4)).astype(np.float32),
            rng.integers(0, 5, size=n_envs),
            rng.normal(size=reward_shape).astype(np.float32),
            (rng.random(n_envs) < 0.2).astype(np.float32),
            th.as_tensor(rng.normal(size=(n_envs, n_scales)), dtype=th.float32),
            th.as_tensor(rng.normal(size=n_envs), dtype=th.float32),
            actor_states=th.as_tensor(rng.normal(size=(n_envs, 2)), dtype=th.float32),
            critic_states=th.as_tensor(rng.normal(size=(n_scales, buffer.n_games, buffer.n_agents, 2)), dtype=th.float32),
        )


def reference_gae(rewards, bonus, values, last_values, episode_starts, last_dones, gamma, lam, denorm):
    """Hand-written scalar loop of docs/method.md "GAE per scale" for one (env, scale) series at a time."""
    n_steps, n_envs, n_scales = values.shape
    advantages = np.zeros_like(values)
    for env in range(n_envs):
        for k in range(n_scales):
            gae = 0.0
            for t in reversed(range(n_steps)):
                if t == n_steps - 1:
                    mask, next_value = 1.0 - last_dones[env], denorm(last_values[env, k], k)
                else:
                    mask, next_value = 1.0 - episode_starts[t + 1, env], denorm(values[t + 1, env, k], k)
                delta = rewards[t, env, k] + bonus[t, env, k] + gamma * next_value * mask - denorm(values[t, env, k], k)
                gae = delta + gamma * lam * mask * gae
                advantages[t, env, k] = gae
    returns = advantages + np.vectorize(denorm)(values, np.arange(n_scales)[None, None, :])
    return advantages, returns


def test_per_scale_gae_with_bonus_matches_hand_loop():
    rng = np.random.default_rng(0)
    buffer = make_buffer()
    fill(buffer, rng, per_scale_rewards=True)  # e.g. a truncation bootstrap that differs per scale
    # a per-scale affine "ValueNorm": denorm_k(v) = v * sigma_k + mu_k
    sigma, mu = np.array([2.0, 0.5]), np.array([1.0, -3.0])
    last_values = rng.normal(size=(buffer.n_envs, 2)).astype(np.float32)
    last_dones = (rng.random(buffer.n_envs) < 0.5).astype(np.float32)
    bonus = rng.random((buffer.buffer_size, buffer.n_envs, 2)).astype(np.float32)
    buffer.add_intrinsic_rewards(bonus)
    buffer.set_last_step(th.as_tensor(last_values), last_dones, denormalize=lambda v: v * sigma + mu)
    buffer.compute_returns_and_advantage()
    advantages, returns = reference_gae(
        buffer.rewards,
        bonus,
        buffer.values,
        last_values,
        buffer.episode_starts,
        last_dones,
        0.9,
        0.8,
        lambda v, k: v * sigma[k] + mu[k],
    )
    np.testing.assert_allclose(buffer.advantages, advantages, atol=1e-5)
    np.testing.assert_allclose(buffer.returns, returns, atol=1e-5)
    # the values in return space are computed once, by set_last_step, and kept for the algorithm's logs
    np.testing.assert_array_equal(buffer.denormalized_values, buffer.values * sigma + mu)
    np.testing.assert_array_equal(buffer.denormalized_last_values, last_values * sigma + mu)
    # a bonus shared by every scale broadcasts
    buffer.add_intrinsic_rewards(np.ones((buffer.buffer_size, buffer.n_envs)))
    np.testing.assert_allclose(buffer.intrinsic_rewards, bonus + 1.0, atol=1e-6)
    with pytest.raises(ValueError, match="shape"):
        buffer.add_intrinsic_rewards(np.ones((3, 3)))


def test_gae_needs_the_bootstrap():
    buffer = make_buffer()
    fill(buffer, np.random.default_rng(3))
    with pytest.raises(RuntimeError, match="set_last_step"):
        buffer.compute_returns_and_advantage()


def test_minibatches_are_whole_games_and_cover_every_step_once():
    rng = np.random.default_rng(1)
    buffer = make_buffer(n_steps=7, n_games=3, chunk=3)  # 7 steps, chunks of 3 -> last chunk padded
    fill(buffer, rng)
    buffer.set_last_step(th.zeros(buffer.n_envs, 2), np.zeros(buffer.n_envs))
    buffer.compute_returns_and_advantage()
    seen = np.zeros((7, 3), dtype=int)
    observations = buffer.observations.reshape(7, 3, 3, 4)  # (T, G, N, d)
    for samples in buffer.get(n_minibatches=4):
        n_steps, n_blocks = samples.mask.shape
        for b in range(n_blocks):
            game = int(samples.game_indices[b])
            for step in range(n_steps):
                if not samples.mask[step, b]:
                    continue
                t = int(samples.time_indices[step, b])
                seen[t, game] += 1
                # every row group is one game's N agents at one step, in agent order
                np.testing.assert_array_equal(samples.observations[step, b].numpy(), observations[t, game])
        # chunk starts carry the stored states of their first step
        starts = samples.time_indices[0].numpy()
        np.testing.assert_array_equal(
            samples.critic_states.numpy(),
            buffer.critic_states[starts, :, samples.game_indices.numpy()].transpose(1, 0, 2, 3),
        )
    assert (seen == 1).all()


def test_standardized_advantages_per_scale():
    rng = np.random.default_rng(2)
    buffer = make_buffer()
    fill(buffer, rng)
    buffer.set_last_step(th.zeros(buffer.n_envs, 2), np.zeros(buffer.n_envs))
    buffer.compute_returns_and_advantage()
    standardized = buffer.standardized_advantages()
    for k in range(2):
        assert abs(standardized[..., k].mean()) < 1e-5
        assert standardized[..., k].std() == pytest.approx(1.0, abs=1e-3)
    # the 1e-5 added to the std (the authors' MAPPO) matters where the spread is tiny: a hand-written example
    buffer.advantages[:] = 0.0
    buffer.advantages[0, 0, 0] = 7e-5  # scale 0: one step 7e-5 above 0; scale 1: all equal
    mean = 7e-5 / buffer.advantages[..., 0].size
    std = np.sqrt(((buffer.advantages[..., 0] - mean) ** 2).mean())
    standardized = buffer.standardized_advantages()
    assert standardized[0, 0, 0] == pytest.approx((7e-5 - mean) / (std + 1e-5), rel=1e-4)
    assert standardized[1, 0, 0] == pytest.approx(-mean / (std + 1e-5), rel=1e-4)
    assert not standardized[..., 1].any()  # no spread: zeros, not NaN


class GroupRecorder:
    """Records the critic inputs of every HypergraphScaleCritic call during training."""

    def __init__(self, monkeypatch):
        self.calls = []
        original = HypergraphScaleCritic.forward

        def forward(critic, obs, hidden, episode_starts, gumbel_noise=True, gumbel_uniform=None):
            if critic.training:
                self.calls.append(obs.detach().numpy().copy())
            return original(critic, obs, hidden, episode_starts, gumbel_noise=gumbel_noise, gumbel_uniform=gumbel_uniform)

        monkeypatch.setattr(HypergraphScaleCritic, "forward", forward)


def test_every_training_hypergraph_is_one_game_at_one_step(monkeypatch):
    """Instrumentation: each (step, block) node set a critic sees in training equals the N agents of one game at one
    step of the rollout (the authors' code mixes unrelated chunks; docs/method.md, "Decisions")."""
    recorder = GroupRecorder(monkeypatch)
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=4, seed=0)
    model = SAEIR_PPO("MSHGPolicy", env, n_steps=20, n_epochs=2, n_minibatches=2, seed=0)
    # keep the buffer of the last rollout: learn one iteration, then re-check it against the recorded inputs
    model.learn(20 * env.num_envs)
    rollout_groups = {
        model.rollout_buffer.observations.reshape(20, 4, 3, -1)[t, g].tobytes() for t in range(20) for g in range(4)
    }
    assert recorder.calls, "the critics were not called in training"
    n_groups = 0
    for obs in recorder.calls:  # (L, B, N, d)
        for step in range(obs.shape[0]):
            for block in range(obs.shape[1]):
                assert obs[step, block].tobytes() in rollout_groups
                n_groups += 1
    assert n_groups == 2 * 3 * 20 * 4  # 2 epochs x 3 scales x (20 steps x 4 games)
    env.close()


def test_chunk_replay_reproduces_rollout_values_and_log_probs():
    """Re-running the GRUs over stored chunks from the stored states gives the rollout's values and log-probs exactly
    (parameters unchanged, Gumbel noise off), also across an episode start inside a chunk (step 25)."""
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=3, seed=1)
    model = SAEIR_PPO(
        "MSHGPolicy", env, n_steps=40, n_epochs=1, seed=1, policy_kwargs=dict(critic_gumbel_noise=False), intrinsic_reward=None
    )
    _, callback = model._setup_learn(40 * env.num_envs, None)
    model.collect_rollouts(model.env, callback, model.rollout_buffer, model.n_steps)
    assert model.rollout_buffer.episode_starts[25].all()
    model.policy.set_training_mode(True)
    n_minibatches = 0
    with th.no_grad():
        for samples in model.rollout_buffer.get(n_minibatches=3):
            n_minibatches += 1
            values, log_prob, _ = model.policy.evaluate_actions(
                samples.observations, samples.actions, samples.actor_states, samples.critic_states, samples.episode_starts
            )
            mask = samples.mask
            np.testing.assert_allclose(values[mask].numpy(), samples.old_values[mask].numpy(), atol=2e-5)
            np.testing.assert_allclose(log_prob[mask].numpy(), samples.old_log_prob[mask].numpy(), atol=2e-5)
    assert n_minibatches == 3
    env.close()


@pytest.mark.parametrize("algo, policy", [(MAPPO, "MAPPOPolicy"), (SAEIR_PPO, "MSHGPolicy")])
def test_a_chunk_longer_than_the_rollout_trains_as_the_rollout_and_warns(algo, policy):
    """``data_chunk_length > n_steps`` pads every game's one chunk to ``data_chunk_length`` steps: the update is the
    one of ``data_chunk_length=n_steps`` (the padding is masked), at more recurrent compute, so it warns. The critics'
    Gumbel noise is off: its draws cover the padded steps too, so with it the updates agree in distribution only."""
    parameters = []
    for chunk in (8, 20):
        env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=3)
        kwargs = dict(n_steps=8, n_epochs=2, n_minibatches=1, data_chunk_length=chunk, seed=3)
        if algo is SAEIR_PPO:
            kwargs["policy_kwargs"] = dict(critic_gumbel_noise=False)
        if chunk > 8:
            with pytest.warns(UserWarning, match=r"data_chunk_length=20 is longer than n_steps=8.*data_chunk_length=8"):
                model = algo(policy, env, **kwargs)
        else:
            model = algo(policy, env, **kwargs)
        model.learn(16 * env.num_envs)
        parameters.append(th.cat([p.detach().flatten() for p in model.policy.parameters()]))
        env.close()
    th.testing.assert_close(parameters[0], parameters[1], atol=1e-5, rtol=0)


def test_a_bonus_on_an_episodes_first_step_moves_only_that_steps_advantage_and_return():
    """The worked example of docs/results/football-ablation.md: one game of one agent, 4 steps, gamma 0.99, lambda
    0.95, every value 0.5, no env reward; an episode ends after step 1 and the next starts at step 2, where a bonus
    b = 0.5 is written. GAE stops at the episode boundary (``m_2 = 0``), so the bonus raises step 2's advantage and
    its return, the value target of the new episode's first state, by exactly b, and nothing else."""

    def advantages_and_returns(bonus_at_first_step):
        buffer = GroupedRecurrentRolloutBuffer(
            4, spaces.Box(-1, 1, (1,)), spaces.Discrete(2), n_envs=1, n_agents=1, n_scales=1,
            actor_hidden_size=0, critic_hidden_size=0, data_chunk_length=4, gamma=0.99, gae_lambda=0.95,
        )  # fmt: skip
        for start in (1.0, 0.0, 1.0, 0.0):  # episode 1: steps 0-1; episode 2 starts at step 2
            buffer.add(
                np.zeros((1, 1), dtype=np.float32), np.zeros(1), np.zeros(1, dtype=np.float32), np.array([start]),
                th.full((1, 1), 0.5), th.zeros(1), actor_states=th.zeros(1, 0), critic_states=th.zeros(1, 1, 1, 0),
            )  # fmt: skip
        bonus = np.zeros((4, 1), dtype=np.float32)  # (T, E)
        bonus[2, 0] = bonus_at_first_step
        buffer.add_intrinsic_rewards(bonus)
        buffer.set_last_step(th.full((1, 1), 0.5), np.zeros(1))
        buffer.compute_returns_and_advantage()
        return buffer.advantages[:, 0, 0], buffer.returns[:, 0, 0]

    gamma, lam, value = 0.99, 0.95, 0.5
    step = gamma * value - value  # a step inside an episode: delta = 0 + gamma * 0.5 - 0.5 = -0.005
    # by hand, backwards: step 3 bootstraps on the last value; step 1 ends its episode (delta = -V)
    expected = np.array([step + gamma * lam * (-value), -value, step + gamma * lam * step, step])
    advantages, returns = advantages_and_returns(0.0)
    np.testing.assert_allclose(advantages, expected, atol=1e-6)  # [-0.47525, -0.5, -0.0097025, -0.005]
    with_bonus, returns_with_bonus = advantages_and_returns(0.5)
    np.testing.assert_allclose(with_bonus - advantages, [0.0, 0.0, 0.5, 0.0], atol=1e-6)
    np.testing.assert_allclose(returns_with_bonus - returns, [0.0, 0.0, 0.5, 0.0], atol=1e-6)
