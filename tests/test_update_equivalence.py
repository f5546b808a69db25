"""The PPO update as computed (network by network, padded rows skipped, the Gumbel draws handed to each group of
blocks) against a hand-written reference: the whole padded minibatch through ``evaluate_actions``, masked means, one
backward of the summed loss. Values, log-probs, losses and every gradient agree within 1e-5 (the sums run in
another order), on the golden tests' setup (25-step rollouts, chunks of 10: a padded last chunk of 5 steps). The
feed-forward networks (``recurrent=False``) run on every valid row at once (``valid_rows``) and agree the same way."""

import numpy as np
import pytest
import torch as th

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.buffers import split_by_valid_length, valid_rows
from sb3_saeir.mappo.losses import actor_losses, clipped_value_loss, critic_loss, scale_advantage_weights

TOLERANCE = 1e-5  # measured: at most 5e-7 (values, log-probs, losses, gradients)
METHODS = {
    "saeir_ppo": (SAEIR_PPO, "MSHGPolicy", {}),
    "mappo": (MAPPO, "MAPPOPolicy", {}),
    "saeir_ppo_feed_forward": (SAEIR_PPO, "MSHGPolicy", {"recurrent": False}),
    "mappo_feed_forward": (MAPPO, "MAPPOPolicy", {"recurrent": False}),
}


@pytest.fixture(scope="module", params=sorted(METHODS))
def model_and_samples(request):
    algo, policy, policy_kwargs = METHODS[request.param]
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=3)
    model = algo(policy, env, n_steps=25, seed=3, n_epochs=1, policy_kwargs={"hidden_size": 16, **policy_kwargs})
    model.learn(25 * env.num_envs)  # one rollout and update: trained parameters, a full buffer
    samples = next(model.rollout_buffer.get(1, model.normalize_advantage))
    assert not bool(samples.mask.all())  # the setup has padded rows
    return model, samples


def reference_losses(model, samples, clip_range, clip_range_vf):
    """The padded minibatch through evaluate_actions, means over the valid rows (the update before 0.2.0a0's)."""
    policy = model.policy
    values, log_prob, entropy = policy.evaluate_actions(
        samples.observations, samples.actions, samples.actor_states, samples.critic_states, samples.episode_starts
    )
    mask = samples.mask[:, :, None].expand_as(samples.old_log_prob).float()  # (L, B, N)

    def masked_mean(x):
        return (x * mask).sum() / mask.sum()

    weights = scale_advantage_weights(samples.advantages[samples.mask].reshape(-1, policy.n_scales))
    mixed = (samples.advantages * weights).sum(dim=-1)
    ratio = th.exp(log_prob - samples.old_log_prob)
    policy_loss = -masked_mean(th.min(mixed * ratio, mixed * th.clamp(ratio, 1 - clip_range, 1 + clip_range)))
    entropy_loss = -masked_mean(entropy)
    value_losses = []
    for k, scale in enumerate(policy.scales):
        value_norm = policy.value_norm(scale)
        returns = value_norm.normalize(samples.returns[..., k])
        per_sample = clipped_value_loss(
            values[..., k], samples.old_values[..., k], returns, clip_range_vf, model.value_loss, model.huber_delta
        )
        value_losses.append(masked_mean(per_sample))
    return policy_loss, entropy_loss, value_losses


def gradients(model):
    return {name: param.grad.clone() for name, param in model.policy.named_parameters() if param.grad is not None}


def test_the_update_matches_the_padded_reference(model_and_samples):
    model, samples = model_and_samples
    # the stored log-probs moved by up to 0.5 either way (ratios from 0.6 to 1.65): the clipped surrogate clips rows
    # on both sides, so the comparison covers the clip range too
    shift = th.rand(samples.old_log_prob.shape, generator=th.Generator().manual_seed(0)) - 0.5
    samples = samples._replace(old_log_prob=samples.old_log_prob + shift)
    policy = model.policy
    assert model.normalize_values
    clip_range, clip_range_vf = 0.2, None
    before = {name: value.clone() for name, value in policy.state_dict().items()}  # ValueNorm statistics included

    for k, scale in enumerate(policy.scales):  # the update normalises with the statistics it has just updated
        policy.value_norm(scale).update(samples.returns[..., k][samples.mask])
    th.manual_seed(11)
    policy_loss, entropy_loss, value_losses = reference_losses(model, samples, clip_range, clip_range_vf)
    policy.zero_grad()
    (policy_loss + model.ent_coef * entropy_loss + model.vf_coef * th.stack(value_losses).sum()).backward()
    expected = gradients(model)

    policy.load_state_dict(before)
    th.manual_seed(11)  # the same Gumbel draws: the actor draws none, each critic its own in scale order
    groups = [valid_rows(samples)] if policy.feed_forward else split_by_valid_length(samples)
    assert [group.length for group in groups] == ([1] if policy.feed_forward else [10, 5])
    n_valid = samples.mask.sum() * policy.n_agents
    weights = scale_advantage_weights(samples.advantages[samples.mask].reshape(-1, policy.n_scales))
    computed_policy_loss, computed_entropy_loss, clip_fraction, _ = actor_losses(
        model.policy, groups, weights, n_valid, clip_range
    )
    assert 0.2 < clip_fraction < 0.8
    policy.zero_grad()
    (computed_policy_loss + model.ent_coef * computed_entropy_loss).backward()
    for k in range(policy.n_scales):
        scale_loss = critic_loss(
            model.policy,
            k,
            samples,
            groups,
            n_valid,
            clip_range_vf,
            model.normalize_values,
            model.value_loss,
            model.huber_delta,
        )
        np.testing.assert_allclose(scale_loss.item(), value_losses[k].item(), rtol=TOLERANCE, atol=TOLERANCE)
        (model.vf_coef * scale_loss).backward()
    np.testing.assert_allclose(computed_policy_loss.item(), policy_loss.item(), rtol=TOLERANCE, atol=TOLERANCE)
    np.testing.assert_allclose(computed_entropy_loss.item(), entropy_loss.item(), rtol=TOLERANCE, atol=TOLERANCE)
    computed = gradients(model)
    assert computed.keys() == expected.keys() and len(expected) > 10
    for name in expected:
        np.testing.assert_allclose(
            computed[name].numpy(), expected[name].numpy(), rtol=TOLERANCE, atol=TOLERANCE, err_msg=name
        )


def test_groups_cover_the_valid_rows_once(model_and_samples):
    _, samples = model_and_samples
    groups = split_by_valid_length(samples)
    blocks = th.cat([group.blocks for group in groups])
    assert sorted(blocks.tolist()) == list(range(samples.mask.shape[1]))
    for group in groups:
        assert bool(group.samples.mask.all())  # no padded row left
        np.testing.assert_array_equal(group.samples.observations, samples.observations[: group.length, group.blocks])
        np.testing.assert_array_equal(group.samples.critic_states, samples.critic_states[:, group.blocks])
    assert sum(group.length * len(group.blocks) for group in groups) == int(samples.mask.sum())


def test_values_and_log_probs_of_the_groups_match_the_padded_pass(model_and_samples):
    model, samples = model_and_samples
    policy = model.policy
    th.manual_seed(5)
    values, log_prob, _ = policy.evaluate_actions(
        samples.observations, samples.actions, samples.actor_states, samples.critic_states, samples.episode_starts
    )
    th.manual_seed(5)
    groups = split_by_valid_length(samples)
    for group in groups:
        part = group.samples
        part_log_prob, _ = policy.evaluate_actor(part.observations, part.actions, part.actor_states, part.episode_starts)
        np.testing.assert_allclose(
            part_log_prob.detach().numpy(),
            log_prob[: group.length, group.blocks].detach().numpy(),
            rtol=TOLERANCE,
            atol=TOLERANCE,
        )
    for k in range(policy.n_scales):
        uniform = policy.draw_gumbel_uniform(k, *samples.mask.shape)
        for group in groups:
            part = group.samples
            part_uniform = None if uniform is None else uniform[: group.length, group.blocks].flatten(0, 1)
            part_values = policy.evaluate_critic(
                k, part.observations, part.critic_states[k], part.episode_starts, part_uniform
            )
            np.testing.assert_allclose(
                part_values.detach().numpy(),
                values[: group.length, group.blocks, :, k].detach().numpy(),
                rtol=TOLERANCE,
                atol=TOLERANCE,
            )


@pytest.mark.parametrize("method", sorted(METHODS))
def test_one_update_steps_along_the_hand_written_loss(method):
    """``train()`` as a whole: with plain SGD and no gradient clipping, one update moves every parameter by the
    learning rate times minus the gradient of the hand-written loss, policy + ent_coef * entropy + vf_coef * the sum
    of the scales' value losses. The coefficients are set far from their defaults and from each other (``ent_coef``
    2.3 makes the entropy a large part of the actor's gradient: 1% more of it fails), so a coefficient changed, dropped
    or swapped in ``train()`` shows; the test above checks the loss terms, not how ``train()`` weighs them. The
    hypergraph critics draw no Gumbel noise here (``critic_gumbel_noise=False``): ``train()`` and the reference visit
    the rows in different orders."""
    algo, policy, policy_kwargs = METHODS[method]
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=3)
    learning_rate, ent_coef, vf_coef = 0.05, 2.3, 0.61
    policy_kwargs = {"hidden_size": 16, "optimizer_class": th.optim.SGD, "critic_gumbel_noise": False, **policy_kwargs}
    model = algo(
        policy, env, n_steps=25, seed=3, n_epochs=1, learning_rate=learning_rate, ent_coef=ent_coef, vf_coef=vf_coef,
        max_grad_norm=1e9, policy_kwargs=policy_kwargs,
    )  # fmt: skip
    model.learn(25 * env.num_envs)  # one rollout and update: a full buffer whose log-probs are one update old
    policy = model.policy
    before = {name: value.clone() for name, value in policy.state_dict().items()}  # ValueNorm statistics included
    model.train()
    moved = {name: param.detach() - before[name] for name, param in policy.named_parameters()}

    policy.load_state_dict(before)
    samples = next(model.rollout_buffer.get(1, model.normalize_advantage))
    for k, scale in enumerate(policy.scales):  # the update normalises with the statistics it has just updated
        policy.value_norm(scale).update(samples.returns[..., k][samples.mask])
    # clip_range_vf unset: train() clips the value loss at clip_range (0.2), as MAPPO's clipped value loss does
    policy_loss, entropy_loss, value_losses = reference_losses(model, samples, 0.2, 0.2)
    policy.zero_grad()
    (policy_loss + ent_coef * entropy_loss + vf_coef * th.stack(value_losses).sum()).backward()
    expected = {name: -learning_rate * grad for name, grad in gradients(model).items()}
    assert expected.keys() <= moved.keys() and len(expected) > 10
    for name in moved.keys() - expected.keys():  # no loss reaches them (the constant heads' weights): left as they are
        assert not moved[name].any(), name
    assert max(float(step.abs().max()) for step in moved.values()) > 1e-3  # the update moved the parameters
    for name in expected:
        np.testing.assert_allclose(moved[name].numpy(), expected[name].numpy(), rtol=1e-4, atol=1e-6, err_msg=name)
