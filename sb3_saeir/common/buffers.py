"""Grouped recurrent rollout buffer: per-scale values and GAE, GRU states per step, minibatches of whole games."""

from __future__ import annotations

from collections.abc import Callable, Generator
from typing import NamedTuple

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import RolloutBuffer

from sb3_saeir.common.type_aliases import GroupedRecurrentSamples


def n_blocks(n_steps: int, n_games: int, data_chunk_length: int) -> int:
    """Number of (game, chunk) blocks in a rollout: ``n_games * ceil(n_steps / data_chunk_length)``.

    :param n_steps: steps per game in the rollout
    :param n_games: games
    :param data_chunk_length: steps per chunk (the last chunk of a game may be shorter, and is padded)
    """
    return n_games * -(-n_steps // data_chunk_length)


class ChunkGroup(NamedTuple):
    """The blocks of a minibatch with the same number of valid rows, cut to those rows (:func:`split_by_valid_length`),
    or every valid row of a minibatch as one step (:func:`valid_rows`, for feed-forward networks).

    :param blocks: the blocks' positions in the minibatch, ``(B_g,)`` (for :func:`valid_rows`: the block of each row)
    :param samples: their data, without padded rows: ``observations (length, B_g, N, d)`` and so on
    :param rows: for :func:`valid_rows`, the minibatch's mask ``(L, B)`` that selected the rows; ``None`` otherwise
    """

    blocks: th.Tensor
    samples: GroupedRecurrentSamples
    rows: th.Tensor | None = None

    @property
    def length(self) -> int:
        """Valid rows of each block of the group (its chunk length; 1 for :func:`valid_rows`)."""
        return int(self.samples.mask.shape[0])

    def take(self, per_row: th.Tensor) -> th.Tensor:
        """The group's rows of a per-row tensor of the whole minibatch, in the group's (step, block) order.

        :param per_row: ``(L, B, ...)``, one entry per row of the padded minibatch (e.g. a critic's Gumbel draws)
        :return: ``(length * B_g, ...)``
        """
        if self.rows is not None:
            return per_row[self.rows]  # (L, B, ...) -> (R, ...), rows in (step, block) order
        return per_row[: self.length, self.blocks].flatten(0, 1)  # (length, B_g, ...) -> (length * B_g, ...)


def split_by_valid_length(samples: GroupedRecurrentSamples) -> list[ChunkGroup]:
    """The blocks of a minibatch grouped by their number of valid rows, each group cut to its valid rows.

    When ``n_steps`` is not a multiple of ``data_chunk_length`` every game's last chunk is shorter and padded (with
    ``n_steps=25`` and chunks of 10, a third of the blocks carry 5 padded rows: 17% of the rows); the update runs the
    networks on each group in turn, so that no padded row is computed. A block's valid rows are always its first ones.
    A minibatch without padding is one group: the samples themselves, not a copy.

    :param samples: a minibatch of :meth:`GroupedRecurrentRolloutBuffer.get`
    :return: the groups, longest first
    """
    n_steps, n_blocks = samples.mask.shape
    lengths = samples.mask.sum(dim=0)  # (B,) valid rows per block
    if bool((lengths == n_steps).all()):
        return [ChunkGroup(th.arange(n_blocks, device=lengths.device), samples)]
    groups = []
    for length in sorted({int(value) for value in lengths.tolist()}, reverse=True):
        blocks = (lengths == length).nonzero().squeeze(-1)  # (B_g,)
        part = GroupedRecurrentSamples(  # (L, B, ...) -> (length, B_g, ...) for the per-step fields
            observations=samples.observations[:length, blocks],
            actions=samples.actions[:length, blocks],
            old_log_prob=samples.old_log_prob[:length, blocks],
            old_values=samples.old_values[:length, blocks],
            advantages=samples.advantages[:length, blocks],
            returns=samples.returns[:length, blocks],
            episode_starts=samples.episode_starts[:length, blocks],
            actor_states=samples.actor_states[blocks],  # (B_g, N, H)
            critic_states=samples.critic_states[:, blocks],  # (K, B_g, N, H)
            mask=samples.mask[:length, blocks],
            game_indices=samples.game_indices[blocks],
            time_indices=samples.time_indices[:length, blocks],
        )
        groups.append(ChunkGroup(blocks, part))
    return groups


def valid_rows(samples: GroupedRecurrentSamples) -> ChunkGroup:
    """Every valid row of a minibatch as one step of R blocks, for networks without a GRU (no chunk, no state).

    A feed-forward network gives the same output for a row wherever it sits, so the update runs it once per minibatch
    on the R valid (step, block) rows, instead of once per group of chunk length (:func:`split_by_valid_length`).
    A row keeps its game's N agents together (the critics' hypergraphs are built over them).

    :param samples: a minibatch of :meth:`GroupedRecurrentRolloutBuffer.get`
    :return: one group: ``observations (1, R, N, d)`` and so on, ``blocks (R,)`` the block of each row
    """
    mask = samples.mask  # (L, B)
    n_steps, n_blocks = mask.shape
    row_blocks = th.arange(n_blocks, device=mask.device).expand(n_steps, n_blocks)[mask]  # (R,)

    def rows(per_row: th.Tensor) -> th.Tensor:
        return per_row[mask].unsqueeze(0)  # (L, B, ...) -> (1, R, ...)

    part = GroupedRecurrentSamples(
        observations=rows(samples.observations),
        actions=rows(samples.actions),
        old_log_prob=rows(samples.old_log_prob),
        old_values=rows(samples.old_values),
        advantages=rows(samples.advantages),
        returns=rows(samples.returns),
        episode_starts=rows(samples.episode_starts),
        actor_states=samples.actor_states[row_blocks],  # (B, N, H) -> (R, N, H)
        critic_states=samples.critic_states[:, row_blocks],  # (K, B, N, H) -> (K, R, N, H)
        mask=rows(mask),
        game_indices=samples.game_indices[row_blocks],
        time_indices=rows(samples.time_indices),
    )
    return ChunkGroup(row_blocks, part, rows=mask)


class GroupedRecurrentRolloutBuffer(RolloutBuffer):
    """Rollout buffer that keeps the agents of a game together, for critics over a game's agents.

    Arrays are SB3's ``(n_steps, n_envs, ...)`` with ``n_envs = n_games * n_agents`` in slot order
    ``game * n_agents + agent``, so ``(n_steps, n_games, n_agents, ...)`` is a free reshape. On top of
    :class:`~stable_baselines3.common.buffers.RolloutBuffer` it stores one value per critic scale (normalised space),
    the (already scaled) intrinsic reward of every scale, GRU states per step, and per-scale returns and advantages.

    Per-scale GAE (``docs/method.md``, "GAE per scale"), with :math:`D_K` the scale's ValueNorm denormalisation
    (passed to :meth:`set_last_step`), :math:`r^K_t` the scale's reward (the env reward plus that
    scale's truncation bootstrap, stored by :meth:`add`) and :math:`m_{t+1} = 1 - \\text{episode\\_start}_{t+1}`:

    .. math::

        \\delta^K_t = r^K_t + r^{int,K}_t + \\gamma D_K(v^K_{t+1}) m_{t+1} - D_K(v^K_t), \\quad
        A^K_t = \\delta^K_t + \\gamma \\lambda m_{t+1} A^K_{t+1}, \\quad R^K_t = A^K_t + D_K(v^K_t)

    Minibatches (:meth:`get`) are blocks of (game, chunk of ``data_chunk_length`` steps) carrying all agents, so a
    critic run on a minibatch builds every hypergraph from one game's agents at one step, as during the rollout.
    When ``n_steps`` is not a multiple of the chunk length, each game's last chunk is shorter and padded (masked).

    :param buffer_size: ``n_steps``
    :param observation_space: one agent's observation space
    :param action_space: one agent's action space
    :param device: torch device
    :param gamma: discount
    :param gae_lambda: GAE lambda
    :param n_envs: vec env slots (``n_games * n_agents``)
    :param n_agents: agents per game
    :param n_scales: number of critics K
    :param actor_hidden_size: actor GRU width (0: MLP actor)
    :param critic_hidden_size: critic GRU width (0: feed-forward critics)
    :param data_chunk_length: L, steps per training chunk
    """

    values: np.ndarray
    denormalized_values: np.ndarray
    returns: np.ndarray
    advantages: np.ndarray

    def __init__(
        self,
        buffer_size: int,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        device: th.device | str = "auto",
        gamma: float = 0.99,
        gae_lambda: float = 0.95,
        n_envs: int = 1,
        n_agents: int = 1,
        n_scales: int = 1,
        actor_hidden_size: int = 64,
        critic_hidden_size: int = 64,
        data_chunk_length: int = 10,
    ) -> None:
        if n_envs % n_agents != 0:
            raise ValueError(f"n_envs={n_envs} is not a multiple of n_agents={n_agents}.")
        self.n_agents = n_agents
        self.n_games = n_envs // n_agents
        self.n_scales = n_scales
        self.actor_hidden_size = actor_hidden_size
        self.critic_hidden_size = critic_hidden_size
        self.data_chunk_length = data_chunk_length
        self.last_values: np.ndarray | None = None
        self.denormalized_last_values: np.ndarray | None = None
        self.last_dones: np.ndarray | None = None
        super().__init__(buffer_size, observation_space, action_space, device, gae_lambda, gamma, n_envs)  # type: ignore[arg-type]
        self.gamma, self.gae_lambda = gamma, gae_lambda

    def reset(self) -> None:
        super().reset()
        # observations of any numeric dtype are kept as float32, what the networks take (SB3 casts in the policy)
        self.observations = np.zeros((self.buffer_size, self.n_envs, *self.obs_shape), dtype=np.float32)
        shape_k = (self.buffer_size, self.n_envs, self.n_scales)
        self.rewards = np.zeros(shape_k, dtype=np.float32)
        self.values = np.zeros(shape_k, dtype=np.float32)
        self.denormalized_values = np.zeros(shape_k, dtype=np.float32)  # set by set_last_step
        self.returns = np.zeros(shape_k, dtype=np.float32)
        self.advantages = np.zeros(shape_k, dtype=np.float32)
        self.intrinsic_rewards = np.zeros(shape_k, dtype=np.float32)
        self.actor_states = np.zeros((self.buffer_size, self.n_envs, self.actor_hidden_size), dtype=np.float32)
        self.critic_states = np.zeros(
            (self.buffer_size, self.n_scales, self.n_games, self.n_agents, self.critic_hidden_size), dtype=np.float32
        )
        self.last_values = None
        self.denormalized_last_values = None
        self.last_dones = None

    def add(  # type: ignore[override]
        self,
        obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        episode_start: np.ndarray,
        value: th.Tensor,
        log_prob: th.Tensor,
        *,
        actor_states: th.Tensor,
        critic_states: th.Tensor,
    ) -> None:
        """Store one step.

        :param reward: rewards of every critic scale ``(n_envs, K)`` (the env reward plus the scale's truncation
            bootstrap), or ``(n_envs,)`` for the same reward at every scale
        :param value: normalised values ``(n_envs, K)``
        :param actor_states: actor GRU states that were the *input* of this step ``(n_envs, H)``
        :param critic_states: critic GRU states that were the input of this step ``(K, G, N, H)``
        """
        self.observations[self.pos] = np.asarray(obs).reshape((self.n_envs, *self.obs_shape))
        self.actions[self.pos] = np.asarray(action).reshape((self.n_envs, self.action_dim))
        # (E,) broadcasts to every scale; (E, K) is per scale
        self.rewards[self.pos] = np.asarray(reward, dtype=np.float32).reshape(self.n_envs, -1)
        self.episode_starts[self.pos] = np.asarray(episode_start)
        self.values[self.pos] = value.detach().cpu().numpy().reshape(self.n_envs, self.n_scales)
        self.log_probs[self.pos] = log_prob.detach().cpu().numpy().reshape(self.n_envs)
        if self.actor_hidden_size:
            self.actor_states[self.pos] = actor_states.detach().cpu().numpy()
        if self.critic_hidden_size:
            self.critic_states[self.pos] = critic_states.detach().cpu().numpy()
        self.pos += 1
        if self.pos == self.buffer_size:
            self.full = True

    def add_intrinsic_rewards(self, bonus: np.ndarray) -> None:
        """Add a scaled intrinsic reward before GAE; ``(n_steps, n_envs)`` applies to every scale,
        ``(n_steps, n_envs, K)`` to each scale separately. The algorithm runs GAE once, after every bonus is in."""
        bonus = np.asarray(bonus, dtype=np.float32)
        if bonus.shape == (self.buffer_size, self.n_envs):
            bonus = bonus[..., None]
        if bonus.shape not in ((self.buffer_size, self.n_envs, 1), (self.buffer_size, self.n_envs, self.n_scales)):
            raise ValueError(
                f"intrinsic reward shape {bonus.shape} does not match the buffer: expected "
                f"{(self.buffer_size, self.n_envs)} or {(self.buffer_size, self.n_envs, self.n_scales)}."
            )
        self.intrinsic_rewards += bonus

    def set_last_step(
        self,
        last_values: th.Tensor,
        dones: np.ndarray,
        denormalize: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        """Store the rollout's bootstrap, the values after the last step and whether that step ended an episode, and
        the rollout's values in return space (:attr:`denormalized_values`, :attr:`denormalized_last_values`), once:
        GAE and the algorithm's logs read them.

        Set when the rollout is full, before the intrinsic rewards are computed (SAEIR's ``"paper"`` variant looks one
        step ahead).

        :param last_values: normalised values ``(n_envs, K)`` of the observation after the last step
        :param dones: ``(n_envs,)`` whether the last step ended an episode
        :param denormalize: maps normalised values ``(..., K)`` to return space (the policy's
            ``denormalize_values_numpy``); ``None`` when the values are not normalised
        """
        self.last_values = last_values.detach().cpu().numpy().reshape(self.n_envs, self.n_scales)
        self.last_dones = np.asarray(dones, dtype=np.float32).reshape(self.n_envs)
        self.denormalized_values = self.values if denormalize is None else denormalize(self.values)  # (T, E, K)
        self.denormalized_last_values = self.last_values if denormalize is None else denormalize(self.last_values)  # (E, K)

    def compute_returns_and_advantage(self) -> None:  # type: ignore[override]
        """Per-scale GAE on the values in return space, with the bootstrap of :meth:`set_last_step` and the intrinsic
        rewards stored so far.

        :raises RuntimeError: when :meth:`set_last_step` was not called since the last :meth:`reset`
        """
        if self.last_dones is None or self.denormalized_last_values is None:
            raise RuntimeError("set_last_step(last_values, dones, denormalize) must be called before GAE.")
        values = self.denormalized_values  # (T, E, K)
        rewards = self.rewards + self.intrinsic_rewards  # (T, E, K)
        last_gae_lam = np.zeros((self.n_envs, self.n_scales), dtype=np.float32)
        for step in reversed(range(self.buffer_size)):
            if step == self.buffer_size - 1:
                next_non_terminal = 1.0 - self.last_dones
                next_values = self.denormalized_last_values
            else:
                next_non_terminal = 1.0 - self.episode_starts[step + 1]
                next_values = values[step + 1]
            delta = rewards[step] + self.gamma * next_values * next_non_terminal[:, None] - values[step]
            last_gae_lam = delta + self.gamma * self.gae_lambda * next_non_terminal[:, None] * last_gae_lam
            self.advantages[step] = last_gae_lam
        self.returns = (self.advantages + values).astype(np.float32)

    # ------------------------------------------------------------------------------------------------ sampling
    def n_chunks(self) -> int:
        """Chunks per game: ``ceil(n_steps / data_chunk_length)``."""
        return -(-self.buffer_size // self.data_chunk_length)

    def n_blocks(self) -> int:
        """Blocks (game, chunk) in the buffer (:func:`n_blocks`)."""
        return n_blocks(self.buffer_size, self.n_games, self.data_chunk_length)

    def standardized_advantages(self) -> np.ndarray:
        """Advantages standardised per scale over the whole buffer (``docs/method.md``, "Advantage mixing"), ``(T, E, K)``."""
        mean = self.advantages.mean(axis=(0, 1), keepdims=True)
        std = self.advantages.std(axis=(0, 1), keepdims=True)
        return (self.advantages - mean) / (std + 1e-5)

    def get(  # type: ignore[override]
        self, n_minibatches: int = 1, normalize_advantage: bool = True
    ) -> Generator[GroupedRecurrentSamples, None, None]:
        """Yield ``n_minibatches`` minibatches covering every block once, in random order.

        :param n_minibatches: how many minibatches to split the blocks into (at most ``n_blocks()``)
        :param normalize_advantage: standardise advantages per scale first
        """
        assert self.full, "the rollout buffer is not full"
        n_blocks = self.n_blocks()
        if not 1 <= n_minibatches <= n_blocks:
            raise ValueError(f"n_minibatches must be in [1, {n_blocks}] (blocks in the buffer), got {n_minibatches}.")
        advantages = self.standardized_advantages() if normalize_advantage else self.advantages
        permutation = np.random.permutation(n_blocks)
        for block_ids in np.array_split(permutation, n_minibatches):
            yield self._get_blocks(block_ids, advantages)

    def _get_blocks(self, block_ids: np.ndarray, advantages: np.ndarray) -> GroupedRecurrentSamples:
        length, n_agents, n_games = self.data_chunk_length, self.n_agents, self.n_games
        games = block_ids % n_games  # (B,)
        chunk_starts = (block_ids // n_games) * length  # (B,)
        # (L, 1) + (1, B) -> (L, B) time index of every row; padding beyond the rollout repeats the last step
        raw_time = np.arange(length)[:, None] + chunk_starts[None, :]
        mask = raw_time < self.buffer_size
        time_idx = np.minimum(raw_time, self.buffer_size - 1)

        def per_game(array: np.ndarray) -> np.ndarray:
            # (T, G * N, ...) -> (T, G, N, ...) -> gather -> (L, B, N, ...)
            grouped = array.reshape(self.buffer_size, n_games, n_agents, *array.shape[2:])
            return grouped[time_idx, games[None, :]]

        actor_states = self.actor_states.reshape(self.buffer_size, n_games, n_agents, -1)[chunk_starts, games]  # (B, N, H)
        # (T, K, G, N, H) -> (B, K, N, H) -> (K, B, N, H)
        critic_states = self.critic_states[chunk_starts, :, games].transpose(1, 0, 2, 3)
        data = (
            per_game(self.observations).reshape(length, len(block_ids), n_agents, -1),
            per_game(self.actions),
            per_game(self.log_probs),
            per_game(self.values),
            per_game(advantages),
            per_game(self.returns),
            per_game(self.episode_starts),
            actor_states,
            np.ascontiguousarray(critic_states),
            mask,
            games,
            time_idx,
        )
        return GroupedRecurrentSamples(*(self.to_torch(np.ascontiguousarray(array)) for array in data))

    def to_torch(self, array: np.ndarray, copy: bool = True) -> th.Tensor:
        if array.dtype == bool:
            return th.as_tensor(array, device=self.device)
        if np.issubdtype(array.dtype, np.integer):
            return th.as_tensor(array, device=self.device)
        return super().to_torch(array, copy)
