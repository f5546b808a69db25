"""Multi-agent random network distillation (RND, Burda et al., ICLR 2019) as an intrinsic-reward callback.

Reference: ``baselines-and-peers.md`` §4 (the official code, openai/random-network-distillation ``ppo_agent.py``,
``policies/cnn_policy_param_matched.py``) and https://arxiv.org/abs/1810.12894.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch as th
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.utils import get_device
from torch import nn

from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer
from sb3_saeir.common.registry import register_intrinsic_reward
from sb3_saeir.common.utils import check_number
from sb3_saeir.intrinsic.base import NextObservationRecorder, true_next_observations

_INPUTS = ("agent", "joint")


def _mlp(input_dim: int, net_arch: Sequence[int], output_dim: int) -> nn.Sequential:
    """ReLU MLP with RND's initialisation: orthogonal weights with gain sqrt(2) on every layer, zero biases."""
    layers: list[nn.Module] = []
    last_dim = input_dim
    for width in net_arch:
        layers += [nn.Linear(last_dim, width), nn.ReLU()]
        last_dim = width
    layers.append(nn.Linear(last_dim, output_dim))
    for layer in layers:
        if isinstance(layer, nn.Linear):
            nn.init.orthogonal_(layer.weight, gain=np.sqrt(2))
            nn.init.zeros_(layer.bias)
    return nn.Sequential(*layers)


@register_intrinsic_reward("rnd")
class RNDCallback(NextObservationRecorder):
    r"""Random network distillation bonus for cooperative multi-agent PPO (Burda et al., 2019,
    https://arxiv.org/abs/1810.12894).

    A fixed, randomly initialised *target* MLP :math:`g` and a trained *predictor* MLP :math:`\hat g` both embed the
    **next** observation :math:`o'_{t+1}` (recorded in :meth:`_on_step`; where a game ended, the real final observation
    from ``infos[i]["terminal_observation"]`` replaces the reset one). The inputs are whitened and clipped with a
    running mean/std of the inputs, as in RND:

    .. math::

        x = \operatorname{clip}\big((o' - \mu) / \sqrt{\sigma^2 + 10^{-8}}, -5, 5\big), \qquad
        b_t = \tfrac{1}{k} \lVert \hat g(x) - g(x) \rVert_2^2 \quad (k = \text{embedding size}),

    and the raw bonus :math:`b_t` is divided by the running std of a discounted, **non-episodic** intrinsic return
    (RND's ``RewardForwardFilter``), without subtracting a mean:

    .. math::

        R_t = \gamma_{int} R_{t-1} + b_t \ (\text{per slot, carried across rollouts and episodes}), \qquad
        r^{int}_t = b_t / \sqrt{\operatorname{Var}[R] + 10^{-8}} .

    **Input** (the SAEIR paper only says "RND extended to MARL", see ``docs/method.md``, "Baselines and ablations"):

    - ``input="agent"`` (default): each agent's own next observation, i.e. individual novelty, one shared
      target/predictor pair for all agents. It matches the parameter sharing of the policy, keeps the input size
      independent of the number of agents N, gives N samples per step to the predictor, and is the per-agent RND of
      MANGER (kkane99/MANGER).
    - ``input="joint"``: the concatenation of the game's N agents' next observations (agent order), i.e. team
      novelty, as JIM's ``"central"`` mode (MToquebiau/Joint-Intrinsic-Motivation); every agent of a game gets the
      same bonus.

    **Schedule** (the official code's order, ``update_ob_stats_every_step=False``): the observation statistics are
    initialised from the first rollout's inputs before its bonus is computed (RND initialises them from random-agent
    steps); each later rollout's bonus uses the statistics of the previous rollouts, and the rollout's inputs are
    then added to the statistics. The predictor is trained after the bonus is computed (:meth:`train_bonus_model`), on
    the rollout's inputs whitened with the updated statistics: Adam, ``n_epochs`` passes, a random
    ``update_proportion`` of the samples in each minibatch (RND's ``proportion_of_exp_used_for_predictor_update``).

    **Deviation forced by the single critic**: RND has two value heads (extrinsic episodic, intrinsic non-episodic)
    and combines ``2 * A_ext + 1 * A_int``. Here the bonus is added to the reward of SAEIR_PPO's critic(s), so it is
    discounted with the PPO ``gamma`` and cut at episode ends; only the normalisation filter is non-episodic.

    Logs ``rollout/rnd_reward_mean`` (normalised bonus, before ``coef``), ``rollout/rnd_raw_reward_mean`` (prediction
    error) and ``train/rnd_loss`` (predictor loss). Returns ``(n_steps, n_envs)``: the same bonus for every critic
    scale.

    :param coef: beta. Default 0.5 = RND's ``int_coeff / ext_coeff`` = 1 / 2: advantages are linear in the rewards
        and PPO standardises them, so adding ``0.5 * r_int`` to the reward of one head keeps RND's 1:2 weighting
    :param input: ``"agent"`` (each agent's own observation, default) or ``"joint"`` (the game's concatenated
        observations)
    :param target_arch: hidden widths of the fixed target MLP (default two 64-unit ReLU layers, the width of the
        MAPPO networks)
    :param predictor_arch: hidden widths of the predictor MLP; default four 64-unit layers = the target's plus two
        more, as RND's predictor adds two 512-unit hidden layers on top of the target's architecture
    :param embedding_dim: output size of both networks (64)
    :param learning_rate: predictor Adam learning rate (1e-4, RND's)
    :param n_epochs: predictor passes over each rollout (4, RND's PPO epochs)
    :param batch_size: predictor minibatch size in samples; ``None`` (default) = a quarter of the rollout, RND's 4
        minibatches per epoch
    :param update_proportion: fraction of each minibatch used for the predictor loss (1.0, the official code's default)
    :param gamma_int: discount of the intrinsic-return filter used for the normalisation (0.99, RND's)
    :param obs_clip: clip of the whitened inputs (5, RND's)
    :param device: torch device of the two networks
    :param verbose: verbosity
    """

    def __init__(
        self,
        coef: float = 0.5,
        input: str = "agent",
        target_arch: Sequence[int] = (64, 64),
        predictor_arch: Sequence[int] = (64, 64, 64, 64),
        embedding_dim: int = 64,
        learning_rate: float = 1e-4,
        n_epochs: int = 4,
        batch_size: int | None = None,
        update_proportion: float = 1.0,
        gamma_int: float = 0.99,
        obs_clip: float = 5.0,
        device: th.device | str = "auto",
        verbose: int = 0,
    ) -> None:
        if input not in _INPUTS:
            raise ValueError(f"Unknown RND input {input!r}; choose one of {_INPUTS}.")
        check_number("RNDCallback", "learning_rate", learning_rate, "> 0", lambda x: x > 0)
        check_number("RNDCallback", "n_epochs", n_epochs, ">= 1", lambda x: x >= 1, integer=True)
        check_number("RNDCallback", "embedding_dim", embedding_dim, ">= 1", lambda x: x >= 1, integer=True)
        check_number("RNDCallback", "gamma_int", gamma_int, "in [0, 1]", lambda x: 0 <= x <= 1)
        check_number("RNDCallback", "obs_clip", obs_clip, "> 0", lambda x: x > 0)
        if not 0.0 < update_proportion <= 1.0:
            raise ValueError(f"update_proportion must be in (0, 1], got {update_proportion}.")
        if batch_size is not None and batch_size < 1:
            raise ValueError(f"batch_size must be positive or None, got {batch_size}.")
        super().__init__(coef=coef, name="rnd", verbose=verbose)
        self.input = input
        self.target_arch = tuple(target_arch)
        self.predictor_arch = tuple(predictor_arch)
        self.embedding_dim = embedding_dim
        self.learning_rate = learning_rate
        self.n_epochs = n_epochs
        self.batch_size = batch_size
        self.update_proportion = update_proportion
        self.gamma_int = gamma_int
        self.obs_clip = obs_clip
        self.device = get_device(device)
        self.target: nn.Module | None = None
        self.predictor: nn.Module | None = None
        self.optimizer: th.optim.Optimizer | None = None
        self.obs_rms: RunningMeanStd | None = None
        self.return_rms = RunningMeanStd(shape=())
        self.intrinsic_returns: np.ndarray | None = None  # RewardForwardFilter state, one per slot
        self._last_inputs: np.ndarray | None = None
        self._last_raw_mean = 0.0
        self._stats_include_last_inputs = False

    # ------------------------------------------------------------------------------------------------ networks
    def setup_networks(self, input_dim: int) -> None:
        """Build the target, predictor, optimiser and observation statistics for inputs of size ``input_dim``
        (done automatically on the first rollout).

        :param input_dim: d for ``input="agent"``, N * d for ``input="joint"``
        """
        self.target = _mlp(input_dim, self.target_arch, self.embedding_dim).to(self.device)
        self.target.requires_grad_(False)
        self.predictor = _mlp(input_dim, self.predictor_arch, self.embedding_dim).to(self.device)
        self.optimizer = th.optim.Adam(self.predictor.parameters(), lr=self.learning_rate)
        self.obs_rms = RunningMeanStd(shape=(input_dim,))

    def update_obs_stats(self, inputs: np.ndarray) -> None:
        """Add inputs ``(..., D)`` to the running mean/std of the whitening (builds the networks if needed)."""
        inputs = np.asarray(inputs, dtype=np.float64)
        if self.obs_rms is None:
            self.setup_networks(inputs.shape[-1])
        assert self.obs_rms is not None
        self.obs_rms.update(inputs.reshape(-1, inputs.shape[-1]))  # (..., D) -> (n, D)

    def normalize_inputs(self, inputs: np.ndarray) -> th.Tensor:
        """Whiten and clip: ``clip((o - mean) / sqrt(var + 1e-8), -obs_clip, obs_clip)``.

        :param inputs: ``(..., D)``
        :return: float32 tensor ``(..., D)`` on the callback's device
        """
        if self.obs_rms is None:
            raise RuntimeError("No observation statistics yet: call update_obs_stats first.")
        whitened = (np.asarray(inputs, dtype=np.float64) - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + 1e-8)
        clipped = np.clip(whitened, -self.obs_clip, self.obs_clip)
        return th.as_tensor(clipped, dtype=th.float32, device=self.device)

    def _prediction_errors(self, x: th.Tensor) -> th.Tensor:
        """Mean squared error over the embedding, ``(..., D) -> (...)``."""
        assert self.target is not None and self.predictor is not None
        return (self.predictor(x) - self.target(x)).pow(2).mean(dim=-1)

    def raw_bonus(self, inputs: np.ndarray) -> np.ndarray:
        """Unnormalised RND bonus: the predictor's mean squared error on the whitened inputs.

        :param inputs: ``(..., D)``
        :return: ``(...)``
        """
        with th.no_grad():
            return self._prediction_errors(self.normalize_inputs(inputs)).cpu().numpy()

    def train_predictor(self, inputs: np.ndarray) -> float:
        """Fit the predictor to the target on inputs ``(n, D)`` (whitened with the current statistics).

        :return: the mean predictor loss over the minibatches
        """
        assert self.optimizer is not None and self.predictor is not None
        x = self.normalize_inputs(inputs).reshape(-1, inputs.shape[-1])  # (..., D) -> (n, D)
        n_samples = x.shape[0]
        batch_size = self.batch_size or max(1, -(-n_samples // 4))
        losses = []
        for _ in range(self.n_epochs):
            for batch in th.randperm(n_samples, device=self.device).split(batch_size):
                errors = self._prediction_errors(x[batch])  # (B,)
                mask = (th.rand_like(errors) < self.update_proportion).float()
                loss = (errors * mask).sum() / mask.sum().clamp(min=1.0)
                self.optimizer.zero_grad()
                loss.backward()
                self.optimizer.step()
                losses.append(loss.item())
        return float(np.mean(losses)) if losses else 0.0

    # ------------------------------------------------------------------------------------------------ normalisation
    def normalize_bonus(self, raw: np.ndarray) -> np.ndarray:
        """RND's reward normalisation: per slot discounted intrinsic return (non-episodic, carried across calls),
        running variance of those returns, ``raw / sqrt(var + 1e-8)``.

        :param raw: raw bonus ``(n_steps, n_envs)``, time first
        :return: the normalised bonus, same shape
        """
        raw = np.asarray(raw, dtype=np.float64)
        if self.intrinsic_returns is None:
            self.intrinsic_returns = np.zeros(raw.shape[1:])
        returns = np.empty_like(raw)
        for step in range(raw.shape[0]):
            self.intrinsic_returns = self.gamma_int * self.intrinsic_returns + raw[step]
            returns[step] = self.intrinsic_returns
        self.return_rms.update(returns.reshape(-1))  # (T, E) -> (T * E,)
        return raw / np.sqrt(self.return_rms.var + 1e-8)

    # ------------------------------------------------------------------------------------------------ callback
    def rollout_inputs(self, next_observations: np.ndarray, n_agents: int) -> np.ndarray:
        """The RND inputs of a rollout.

        :param next_observations: ``(n_steps, n_envs, d)``, slots ordered ``game * n_agents + agent``
        :param n_agents: agents per game N
        :return: ``(n_steps, n_envs, d)`` for ``input="agent"``, ``(n_steps, n_games, N * d)`` for ``"joint"``
        """
        n_steps, n_envs = next_observations.shape[:2]
        flat = next_observations.reshape(n_steps, n_envs, -1)  # (T, E, *obs_shape) -> (T, E, d)
        if self.input == "joint":
            return flat.reshape(n_steps, n_envs // n_agents, -1)  # (T, G * N, d) -> (T, G, N * d)
        return flat

    def bonus_from_next_observations(self, next_observations: np.ndarray, n_agents: int) -> np.ndarray:
        """Normalised bonus of a rollout (updates the normalisation state; the first call also initialises the
        observation statistics).

        :param next_observations: ``(n_steps, n_envs, d)``
        :param n_agents: agents per game N
        :return: ``(n_steps, n_envs)``
        """
        inputs = self.rollout_inputs(next_observations, n_agents)  # (T, U, D)
        if self.obs_rms is None:
            self.update_obs_stats(inputs)
            self._stats_include_last_inputs = True
        raw = self.raw_bonus(inputs)  # (T, U)
        if self.input == "joint":
            raw = np.repeat(raw, n_agents, axis=1)  # (T, G) -> (T, G * N), every agent of a game
        self._last_inputs = inputs
        self._last_raw_mean = float(raw.mean())
        return self.normalize_bonus(raw)

    def compute_bonus(self, buffer: GroupedRecurrentRolloutBuffer) -> np.ndarray:
        next_observations = self.rollout_next_observations(buffer)  # (T, E, *obs_shape)
        return self.bonus_from_next_observations(next_observations, buffer.n_agents)  # (T, E)

    def train_bonus_model(self, buffer: GroupedRecurrentRolloutBuffer) -> None:
        if self._last_inputs is None:
            return
        if not self._stats_include_last_inputs:
            self.update_obs_stats(self._last_inputs)
        self._stats_include_last_inputs = False
        inputs = self._last_inputs.reshape(-1, self._last_inputs.shape[-1])  # (T, U, D) -> (T * U, D)
        self.logger.record("train/rnd_loss", self.train_predictor(inputs))

    def _log_bonus(self, bonus: np.ndarray, buffer: GroupedRecurrentRolloutBuffer) -> None:
        super()._log_bonus(bonus, buffer)
        self.logger.record("rollout/rnd_raw_reward_mean", self._last_raw_mean)


__all__ = ["RNDCallback", "true_next_observations"]
