"""Common types: the minibatch of the grouped buffer and the recurrent states of a multi-agent policy.

Both are also importable from their historical modules (``sb3_saeir.common.buffers``, ``sb3_saeir.common.policies``).
"""

from __future__ import annotations

from typing import NamedTuple

import torch as th


class GroupedRecurrentSamples(NamedTuple):
    """A minibatch of B blocks; a block = one game, one chunk of L consecutive steps, all N agents.

    Shapes: ``observations (L, B, N, d)``, ``actions (L, B, N, action_dim)``, ``old_log_prob (L, B, N)``,
    ``old_values (L, B, N, K)`` (normalised), ``advantages (L, B, N, K)`` (standardised per scale),
    ``returns (L, B, N, K)``, ``episode_starts (L, B, N)``, ``actor_states (B, N, H)``, ``critic_states (K, B, N, H)``
    (stored states at each chunk's first step), ``mask (L, B)`` (False on padding after the rollout's end),
    ``game_indices (B,)`` and ``time_indices (L, B)`` (where each block's data came from in the buffer).
    """

    observations: th.Tensor
    actions: th.Tensor
    old_log_prob: th.Tensor
    old_values: th.Tensor
    advantages: th.Tensor
    returns: th.Tensor
    episode_starts: th.Tensor
    actor_states: th.Tensor
    critic_states: th.Tensor
    mask: th.Tensor
    game_indices: th.Tensor
    time_indices: th.Tensor


class MultiAgentStates(NamedTuple):
    """Recurrent states of a multi-agent policy.

    :param actor: actor GRU states, ``(n_slots, H)`` with ``n_slots = G * N`` (zeros-size if the actor is an MLP)
    :param critic: critic GRU states, ``(K, G, N, H)`` for the K critic scales
    """

    actor: th.Tensor
    critic: th.Tensor
