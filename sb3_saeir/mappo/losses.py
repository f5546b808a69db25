"""The losses of MAPPO's update (``docs/method.md``, "The update") as pure functions: the critic scales' advantage
weights, MAPPO's clipped value loss, and the actor's and each critic's loss on a minibatch."""

from __future__ import annotations

import torch as th
from torch.nn import functional as F

from sb3_saeir.common.buffers import ChunkGroup
from sb3_saeir.common.policies import MultiAgentActorCriticPolicy
from sb3_saeir.common.type_aliases import GroupedRecurrentSamples


def scale_advantage_weights(advantages: th.Tensor) -> th.Tensor:
    """Weights W_K of the critic scales for one minibatch (``docs/method.md``, "Advantage mixing"):

    .. math:: W_K = \\frac{\\sum_j \\exp(\\hat A^K_j)}{\\sum_{K'} \\sum_j \\exp(\\hat A^{K'}_j)}

    computed as a softmax over K of per-scale log-sum-exps (no overflow). No gradient flows through them; with one
    critic the weight is 1.

    :param advantages: standardised advantages of the minibatch's valid samples, ``(n_samples, K)``
    :return: ``(K,)`` weights summing to 1
    """
    return th.softmax(th.logsumexp(advantages.detach(), dim=0), dim=0)


def clipped_value_loss(
    values: th.Tensor,
    old_values: th.Tensor,
    returns: th.Tensor,
    clip_range_vf: float | None,
    loss: str = "huber",
    huber_delta: float = 10.0,
) -> th.Tensor:
    """MAPPO's clipped value loss per sample: ``max(l(R - v), l(R - v_clipped))``, with
    ``v_clipped = v_old + clamp(v - v_old, -clip, clip)`` and ``l`` the Huber loss (``delta``) or half the squared
    error. Without clipping (``clip_range_vf`` ``None`` or <= 0): ``l(R - v)``.

    :param values: predicted (normalised) values, any shape
    :param old_values: values stored in the rollout, same shape
    :param returns: (normalised) returns, same shape
    :param clip_range_vf: value clip range in normalised space
    :param loss: ``"huber"`` or ``"mse"``
    :param huber_delta: Huber delta
    :return: per-sample losses, same shape
    """

    def point_loss(error: th.Tensor) -> th.Tensor:
        if loss == "huber":
            return F.huber_loss(error, th.zeros_like(error), reduction="none", delta=huber_delta)
        return 0.5 * error**2

    losses = point_loss(returns - values)
    if clip_range_vf is not None and clip_range_vf > 0:
        values_clipped = old_values + th.clamp(values - old_values, -clip_range_vf, clip_range_vf)
        losses = th.max(losses, point_loss(returns - values_clipped))
    return losses


def actor_losses(
    policy: MultiAgentActorCriticPolicy, groups: list[ChunkGroup], weights: th.Tensor, n_valid: th.Tensor, clip_range: float
) -> tuple[th.Tensor, th.Tensor, float, float]:
    """The clipped surrogate loss and the entropy loss of a minibatch (means over its valid rows), the share of
    clipped ratios and the approximate KL (Schulman's estimator), the actor run on each group of blocks.

    :param policy: the policy, whose actor runs
    :param groups: the minibatch's blocks by valid length (:func:`~sb3_saeir.common.buffers.split_by_valid_length`)
    :param weights: the scales' advantage weights ``(K,)``
    :param n_valid: valid rows of the minibatch (steps x blocks x agents)
    :param clip_range: the ratio's clip range
    :return: policy loss, entropy loss (tensors with their graphs), clip fraction, approximate KL
    """
    policy_sums, entropy_sums = [], []
    clipped, kl_sum = 0.0, 0.0
    for group in groups:
        part = group.samples
        log_prob, entropy = policy.evaluate_actor(
            part.observations, part.actions, part.actor_states, part.episode_starts
        )  # (length, B_g, N) each
        mixed_advantages = (part.advantages * weights).sum(dim=-1)  # (length, B_g, N, K) -> (length, B_g, N)
        ratio = th.exp(log_prob - part.old_log_prob)
        policy_loss_1 = mixed_advantages * ratio
        policy_loss_2 = mixed_advantages * th.clamp(ratio, 1 - clip_range, 1 + clip_range)
        policy_sums.append(th.min(policy_loss_1, policy_loss_2).sum())
        entropy_sums.append(entropy.sum())
        with th.no_grad():
            clipped += (th.abs(ratio - 1) > clip_range).float().sum().item()
            log_ratio = log_prob - part.old_log_prob
            kl_sum += ((th.exp(log_ratio) - 1) - log_ratio).sum().item()
    policy_loss = -th.stack(policy_sums).sum() / n_valid
    entropy_loss = -th.stack(entropy_sums).sum() / n_valid
    valid = float(n_valid)
    return policy_loss, entropy_loss, clipped / valid, kl_sum / valid


def critic_loss(
    policy: MultiAgentActorCriticPolicy,
    k: int,
    samples: GroupedRecurrentSamples,
    groups: list[ChunkGroup],
    n_valid: th.Tensor,
    clip_range_vf: float | None,
    normalize_values: bool = True,
    value_loss: str = "huber",
    huber_delta: float = 10.0,
) -> th.Tensor:
    """Critic scale ``k``'s clipped value loss on a minibatch (mean over its valid rows), on returns normalised by
    the scale's ValueNorm (updated here with the minibatch's valid returns), the critic run on each group of blocks
    with its rows of the Gumbel draws of the whole minibatch (the noise is that of the padded minibatch).

    :param policy: the policy, whose critic ``k`` runs
    :param k: the scale's index
    :param samples: the minibatch (padded)
    :param groups: its blocks by valid length
    :param n_valid: valid rows of the minibatch (steps x blocks x agents)
    :param clip_range_vf: the value clip range (``None``: no clipping)
    :param normalize_values: the returns are normalised by the scale's ValueNorm (the algorithm's ``normalize_values``)
    :param value_loss: ``"huber"`` or ``"mse"``
    :param huber_delta: Huber delta
    :return: the loss, with its graph
    """
    n_steps, n_blocks = samples.mask.shape
    uniform = policy.draw_gumbel_uniform(k, n_steps, n_blocks)  # (L, B, E, T_K) or None
    if normalize_values:
        value_norm = policy.value_norm(policy.scales[k])
        value_norm.update(samples.returns[..., k][samples.mask])
    loss_sums = []
    for group in groups:
        part = group.samples
        # the group's rows of the draws: (L, B, E, T_K) -> (length * B_g, E, T_K), rows (step, block)
        part_uniform = None if uniform is None else group.take(uniform)
        values = policy.evaluate_critic(
            k, part.observations, part.critic_states[k], part.episode_starts, part_uniform
        )  # (length, B_g, N)
        returns = part.returns[..., k]
        if normalize_values:
            returns = value_norm.normalize(returns)
        per_sample = clipped_value_loss(values, part.old_values[..., k], returns, clip_range_vf, value_loss, huber_delta)
        loss_sums.append(per_sample.sum())
    return th.stack(loss_sums).sum() / n_valid
