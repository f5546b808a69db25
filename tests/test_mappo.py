"""MAPPO, SN-MAPPO and the ablations in the same machinery as SAEIR_PPO."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3.common.callbacks import BaseCallback

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.policies import MAPPOPolicy, SNMAPPOPolicy
from sb3_saeir.common.policy_arguments import default_optimizer_kwargs
from sb3_saeir.common.torch_layers import RecurrentValueCritic
from sb3_saeir.intrinsic import saeir_bonus
from sb3_saeir.mappo.losses import clipped_value_loss

TINY_KWARGS = dict(n_steps=10, n_epochs=1)


@pytest.mark.parametrize(
    "policy, kwargs, scales, bonus",
    [
        ("MAPPOPolicy", {}, ("critic",), False),  # MAPPO
        ("SNMAPPOPolicy", {}, ("critic",), False),  # SN-MAPPO
        ("MSHGPolicy", {}, ("team", "group", "individual"), False),  # MSHG-only ablation
        ("MAPPOPolicy", dict(intrinsic_reward="saeir"), ("critic",), True),  # SAE-only ablation
    ],
)
def test_methods_train_two_iterations(env, policy, kwargs, scales, bonus):
    model = MAPPO(policy, env, seed=0, **TINY_KWARGS, **kwargs).learn(2 * 10 * env.num_envs)
    assert model.num_timesteps == 2 * 10 * env.num_envs
    assert model.policy.scales == scales
    buffer = model.rollout_buffer
    expected = 0.1 * saeir_bonus(buffer.values) if bonus else np.zeros_like(buffer.values)
    np.testing.assert_allclose(buffer.intrinsic_rewards, expected, atol=1e-6)


def test_gradient_norms_are_clipped_per_network_at_max_grad_norm(env, monkeypatch):
    """Each network (the actor, every critic scale) has its gradient norm clipped to ``max_grad_norm`` separately,
    at every minibatch: the clip is called once per network and step with that network's parameters."""
    model = MAPPO("MSHGPolicy", env, seed=0, n_steps=10, n_epochs=2, n_minibatches=2, max_grad_norm=0.37)
    calls = []
    original = th.nn.utils.clip_grad_norm_

    def recording(parameters, max_norm, *args, **kwargs):
        parameters = list(parameters)
        calls.append((max_norm, {id(p) for p in parameters}))
        norm = original(parameters, max_norm, *args, **kwargs)
        total = th.linalg.vector_norm(th.stack([th.linalg.vector_norm(p.grad) for p in parameters if p.grad is not None]))
        assert total <= max_norm * (1 + 1e-4)  # clipped to the bound given
        return norm

    monkeypatch.setattr(th.nn.utils, "clip_grad_norm_", recording)
    model.learn(10 * env.num_envs)
    networks = [model.policy.actor_parameters()] + [model.policy.critic_parameters(s) for s in model.policy.scales]
    expected = [{id(p) for p in parameters} for parameters in networks]
    assert len(calls) == 2 * 2 * len(expected)  # epochs x minibatches x networks
    assert all(max_norm == 0.37 for max_norm, _ in calls)
    assert [ids for _, ids in calls[: len(expected)]] == expected


def test_mappo_defaults():
    assert MAPPO.policy_aliases["MlpPolicy"] is MAPPOPolicy
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    assert MAPPO("MlpPolicy", env).intrinsic_reward is None
    assert SAEIR_PPO("MAPPOPolicy", env).intrinsic_reward == "saeir"
    env.close()


def reference_adam(param, grads, lr, eps, betas=(0.9, 0.999)):
    """Adam (Kingma & Ba, 2015, Algorithm 1) as a plain loop over steps, float64."""
    p, m, v = param.double().clone(), th.zeros_like(param, dtype=th.float64), th.zeros_like(param, dtype=th.float64)
    for step, grad in enumerate(grads, start=1):
        m = betas[0] * m + (1 - betas[0]) * grad.double()
        v = betas[1] * v + (1 - betas[1]) * grad.double() ** 2
        m_hat, v_hat = m / (1 - betas[0] ** step), v / (1 - betas[1] ** step)
        p = p - lr * m_hat / (v_hat.sqrt() + eps)
    return p


def test_default_optimizer_is_fused_adam_and_steps_as_adam(env):
    model = MAPPO("MlpPolicy", env, seed=0, learning_rate=5e-4)
    optimizer = model.policy.optimizer
    assert type(optimizer) is th.optim.Adam
    assert optimizer.defaults["fused"] is True and optimizer.defaults["eps"] == 1e-5
    params = [p for p in model.policy.parameters() if p.requires_grad]
    before = [p.detach().clone() for p in params]
    generator = th.Generator().manual_seed(0)
    grads = [[th.randn(p.shape, generator=generator) for p in params] for _ in range(3)]
    for step_grads in grads:
        for param, grad in zip(params, step_grads):
            param.grad = grad.clone()
        optimizer.step()
    for index, (param, start) in enumerate(zip(params, before)):
        expected = reference_adam(start, [step_grads[index] for step_grads in grads], lr=5e-4, eps=1e-5)
        np.testing.assert_allclose(param.detach().double().numpy(), expected.numpy(), atol=1e-6, rtol=0)
    # the user's optimizer_kwargs replace the default; another optimizer class gets foreach instead of fused
    custom = MAPPO("MlpPolicy", env, policy_kwargs=dict(optimizer_kwargs={"eps": 1e-8}))
    assert custom.policy.optimizer.defaults["eps"] == 1e-8 and custom.policy.optimizer.defaults["fused"] is None
    rmsprop = MAPPO("MlpPolicy", env, policy_kwargs=dict(optimizer_class=th.optim.RMSprop))
    assert rmsprop.policy.optimizer.defaults["foreach"] is True and rmsprop.policy.optimizer.defaults["eps"] == 1e-5
    # a class without eps (SGD) gets only what its constructor takes: it crashed with SGD's TypeError on eps
    sgd = MAPPO("MlpPolicy", env, learning_rate=0.1, policy_kwargs=dict(optimizer_class=th.optim.SGD))
    assert sgd.policy.optimizer.defaults["foreach"] is True and "eps" not in sgd.policy.optimizer.defaults
    assert default_optimizer_kwargs(th.optim.LBFGS) == {}  # neither keyword


def test_joint_critic_sees_the_concatenation_and_gives_one_value_per_game():
    critic = RecurrentValueCritic(obs_dim=4, n_agents=3, critic_input="joint", hidden_size=8)
    obs = th.randn(5, 2, 3, 4)  # (T, G, N, d)
    values, hidden = critic(obs, th.zeros(2, 3, 8), th.zeros(5, 2, 3))
    assert values.shape == (5, 2, 3) and hidden.shape == (2, 3, 8)
    assert th.allclose(values, values[..., :1].expand_as(values))  # same value for the agents of a game
    # it is a function of the joint observation: the encoder's input LayerNorm has N * d features
    assert critic.mlp[0].normalized_shape == (12,)
    # permuting agents changes the joint input (concatenation order) -> different values
    permuted, _ = critic(obs[:, :, [2, 0, 1]], th.zeros(2, 3, 8), th.zeros(5, 2, 3))
    assert not th.allclose(permuted, values)


def test_own_observation_critic():
    """Each agent's value is a function of its own observation alone: changing one agent's observation changes its
    value and no other agent's, and every agent alone through the network gives its value."""
    th.manual_seed(0)
    critic = RecurrentValueCritic(obs_dim=4, n_agents=3, critic_input="own", hidden_size=8)
    obs = th.randn(1, 2, 3, 4)  # (T, G, N, d)
    values, _ = critic(obs, th.zeros(2, 3, 8), th.zeros(1, 2, 3))
    assert len(th.unique(values)) == 6  # not one value per game, not a constant
    for game in range(2):
        for agent in range(3):
            alone, _ = critic(obs[:, game, agent].expand(1, 1, 3, 4).contiguous(), th.zeros(1, 3, 8), th.zeros(1, 1, 3))
            assert th.allclose(values[0, game, agent], alone[0, 0, 0], atol=1e-6)
    for agent in range(3):
        changed = obs.clone()
        changed[:, :, agent] = th.randn(1, 2, 4)  # a new observation (a shift alone would vanish in the input LayerNorm)
        new_values, _ = critic(changed, th.zeros(2, 3, 8), th.zeros(1, 2, 3))
        moved = ~th.isclose(new_values, values, atol=1e-6)  # (1, G, N)
        assert moved[..., agent].all() and not moved[..., [a for a in range(3) if a != agent]].any()


@pytest.mark.parametrize("layers", [("output",), ("output", "hidden")])
def test_spectral_norm_largest_singular_value_is_one(layers):
    critic = RecurrentValueCritic(obs_dim=6, n_agents=3, hidden_size=16, spectral_norm=layers)
    critic.train()
    with th.no_grad():  # a few power iterations
        for _ in range(30):
            critic(th.randn(2, 4, 3, 6), th.zeros(4, 3, 16), th.zeros(2, 4, 3))
    critic.eval()
    normalized = [critic.value_net] + ([m for m in critic.mlp if isinstance(m, th.nn.Linear)] if "hidden" in layers else [])
    for layer in normalized:
        assert th.linalg.svdvals(layer.weight.detach())[0].item() == pytest.approx(1.0, abs=1e-3)
    if "hidden" not in layers:  # un-normalised encoder layers keep their orthogonal init (singular values = gain)
        linear = next(m for m in critic.mlp if isinstance(m, th.nn.Linear))
        assert th.linalg.svdvals(linear.weight.detach())[0].item() > 1.5


def test_sn_policy_default_and_save_load(env, tmp_path):
    policy = SNMAPPOPolicy(spaces.Box(-1, 1, (18,)), spaces.Discrete(5), lambda _: 1e-3, n_agents=3)
    assert policy.spectral_norm == ("output",)
    model = MAPPO("SNMAPPOPolicy", env, seed=0, **TINY_KWARGS).learn(10 * env.num_envs)
    obs = env.reset()
    model.save(tmp_path / "sn.zip")
    loaded = MAPPO.load(tmp_path / "sn.zip", env=env)
    np.testing.assert_array_equal(loaded.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0])
    assert loaded.policy.spectral_norm == ("output",)


def test_clipped_value_loss_hand_values():
    """MAPPO's value loss on errors either side of the Huber delta (10), without and with value clipping (0.2):
    Huber ``0.5 e^2`` up to delta, ``delta * (|e| - delta / 2)`` beyond; clipped, the larger of the losses of ``v``
    and of ``v_old + clamp(v - v_old, -0.2, 0.2)``."""
    values = th.tensor([3.0, -12.0, 0.9, 14.0])
    old_values = th.tensor([3.0, -12.0, 0.0, 0.0])
    returns = th.tensor([0.0, 0.0, 1.0, 15.0])  # errors -3, 12, 0.1, 1; clipped errors -3, 12, 0.8, 14.8
    np.testing.assert_allclose(clipped_value_loss(values, old_values, returns, None), [4.5, 70.0, 0.005, 0.5], rtol=1e-6)
    np.testing.assert_allclose(clipped_value_loss(values, old_values, returns, 0.2), [4.5, 70.0, 0.32, 98.0], rtol=1e-6)
    # -1 (the model's "value clipping off") is the unclipped loss
    np.testing.assert_allclose(clipped_value_loss(values, old_values, returns, -1.0), [4.5, 70.0, 0.005, 0.5], rtol=1e-6)
    mse = clipped_value_loss(values, old_values, returns, 0.2, loss="mse")
    np.testing.assert_allclose(mse, [4.5, 72.0, 0.32, 109.52], rtol=1e-6)


def test_bad_critic_options():
    with pytest.raises(ValueError, match="critic_input"):
        RecurrentValueCritic(4, 3, critic_input="global")
    with pytest.raises(ValueError, match="spectral_norm"):
        RecurrentValueCritic(4, 3, spectral_norm=("all",))


class RecordEnvRewards(BaseCallback):
    """Keep the env's rewards and truncation flags of every step of the last rollout."""

    def _on_rollout_start(self):
        self.rewards, self.truncated = [], []

    def _on_step(self):
        infos, dones = self.locals["infos"], self.locals["dones"]
        self.rewards.append(np.array(self.locals["rewards"], dtype=np.float32))
        self.truncated.append(np.array([d and i.get("TimeLimit.truncated", False) for d, i in zip(dones, infos)]))
        return True


def test_truncation_bootstrap_is_added_to_the_step_rewards_before_gae():
    """With marked truncation, a truncated step's reward gets gamma * V(final observation) of each scale (here a
    critic made constant, V = 2.5), every other step keeps the env reward."""
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0, mark_truncation=True, max_cycles=4)
    model = MAPPO("MAPPOPolicy", env, n_steps=10, n_epochs=1, normalize_values=False, seed=0)
    value_net = model.policy.critics["critic"].value_net
    with th.no_grad():
        value_net.weight.zero_()
        value_net.bias.fill_(2.5)
    recorder = RecordEnvRewards()
    model.learn(10 * env.num_envs, callback=recorder)
    rewards, truncated = np.stack(recorder.rewards), np.stack(recorder.truncated)  # (T, E)
    assert truncated.any() and not truncated.all()
    expected = rewards + np.where(truncated, model.gamma * 2.5, 0.0)
    np.testing.assert_allclose(model.rollout_buffer.rewards[..., 0], expected, atol=1e-6)
    env.close()
