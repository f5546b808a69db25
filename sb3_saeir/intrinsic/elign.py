"""Elign's team expectation-alignment bonus (``elign_team``, Ma et al., NeurIPS 2022) as an intrinsic-reward callback.

Reference: ``baselines-and-peers.md`` §3 (the official code, StanfordVL/alignment
``map/tianshou/policy/modelfree/sacd_multi_wm.py``, ``map/models/world_model.py``) and
https://arxiv.org/abs/2210.04365.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.utils import get_device
from torch import nn
from torch.nn import functional as F

from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer
from sb3_saeir.common.registry import register_intrinsic_reward
from sb3_saeir.common.utils import check_number
from sb3_saeir.intrinsic.base import NextObservationRecorder

PositionFn = Callable[[th.Tensor], th.Tensor]
VisibilityFn = Callable[[th.Tensor, th.Tensor, float], th.Tensor]
ForwardFn = Callable[[th.Tensor, th.Tensor], th.Tensor]


# ---------------------------------------------------------------------------------------------------- mpe2 layout
def navigation_position(observations: th.Tensor) -> th.Tensor:
    """Absolute position of the observing agent in the mpe2 ``simple_spread`` layout
    ``[self_vel(2), self_pos(2), landmark_rel(2L), other_agents_rel(2(N-1)), comm(2(N-1))]``.

    :param observations: ``(..., d)``
    :return: ``(..., 2)``
    """
    return observations[..., 2:4]


def navigation_visibility(
    observations: th.Tensor, viewer_positions: th.Tensor, radius: float, n_landmarks: int | None = None
) -> th.Tensor:
    """Which entries of an mpe2 ``simple_spread`` observation a viewer at ``viewer_positions`` can see.

    Entities are the observer itself (velocity and position entries), the landmarks and the other agents (relative
    position and the aligned communication entries); an entity's absolute position is ``self_pos + relative``. An
    entity is visible when it is within ``radius`` of the viewer (inclusive, as Elign's ``<= obs_radius``). mpe2
    observations are fully observable, so "visible to both the observer and the viewer" (Elign) reduces to "visible to
    the viewer".

    :param observations: ``(..., d)`` with ``d = 4 + 2L + 4(N - 1)``
    :param viewer_positions: ``(..., 2)``, broadcastable to the observations' leading shape
    :param radius: observation radius of the viewer
    :param n_landmarks: L; ``None`` = as many landmarks as agents (Cooperative Navigation, ``d = 6N``)
    :return: ``(..., d)`` mask of 0.0 / 1.0 in the observations' dtype
    """
    obs_dim = observations.shape[-1]
    if n_landmarks is None:
        if obs_dim % 6:
            raise ValueError(f"Observation size {obs_dim} is not 6N: pass n_landmarks for a layout with L != N.")
        n_landmarks = obs_dim // 6
    n_others, remainder = divmod(obs_dim - 4 - 2 * n_landmarks, 4)
    if remainder or n_others < 0:
        raise ValueError(f"Observation size {obs_dim} does not fit the mpe2 layout with {n_landmarks} landmarks.")
    own_position = observations[..., 2:4]  # (..., 2)
    n_entities = n_landmarks + n_others
    # (..., 2 * n_entities) -> (..., n_entities, 2): landmarks, then the other agents
    relative = observations[..., 4 : 4 + 2 * n_entities].reshape(*observations.shape[:-1], n_entities, 2)
    # (..., 1 + n_entities, 2): the observer itself first
    positions = th.cat([own_position.unsqueeze(-2), own_position.unsqueeze(-2) + relative], dim=-2)
    visible = th.linalg.vector_norm(positions - viewer_positions.unsqueeze(-2), dim=-1) <= radius  # (..., 1 + n_entities)
    mask = th.cat(
        [
            visible[..., :1].expand(*visible.shape[:-1], 4),  # self velocity and position
            visible[..., 1:].repeat_interleave(2, dim=-1),  # landmark and other-agent relative positions
            visible[..., 1 + n_landmarks :].repeat_interleave(2, dim=-1),  # communication of the other agents
        ],
        dim=-1,
    )
    return mask.to(observations.dtype)


# ---------------------------------------------------------------------------------------------------- the bonus
def neighbour_mask(observations: th.Tensor, obs_radius: float | None, position_fn: PositionFn | None) -> th.Tensor:
    """``mask[..., i, j]``: agent j is a neighbour of agent i (j != i, Euclidean distance <= ``obs_radius``).

    :param observations: ``(..., N, d)``, the agents of one game on the second-to-last axis
    :param obs_radius: neighbourhood radius; ``None`` = every teammate is a neighbour
    :param position_fn: ``(..., d) -> (..., 2)``, needed when ``obs_radius`` is set
    :return: boolean ``(..., N, N)``
    """
    n_agents = observations.shape[-2]
    not_self = ~th.eye(n_agents, dtype=th.bool, device=observations.device)
    if obs_radius is None:
        return not_self.expand(*observations.shape[:-2], n_agents, n_agents)
    if position_fn is None:
        raise ValueError("position_fn is needed when obs_radius is set.")
    positions = position_fn(observations)  # (..., N, 2)
    # (..., N, 1, 2) - (..., 1, N, 2) -> (..., N, N)
    distances = th.linalg.vector_norm(positions.unsqueeze(-2) - positions.unsqueeze(-3), dim=-1)
    return (distances <= obs_radius) & not_self


def elign_team_bonus(
    forward_model: ForwardFn,
    observations: th.Tensor,
    actions: th.Tensor,
    next_observations: th.Tensor,
    obs_radius: float | None = 0.5,
    position_fn: PositionFn | None = navigation_position,
    visibility_fn: VisibilityFn | None = navigation_visibility,
) -> th.Tensor:
    r"""Elign's ``elign_team`` bonus of every agent, vectorised over the leading axes.

    For agent i with neighbours :math:`J_i` and each :math:`j \in J_i`, :math:`\hat o_{j \to i}` is i's observation
    with the entries j cannot see zeroed (``visibility_fn`` with j's position as the viewer), and

    .. math::

        e_{ij} = \lVert o'_i - f(\hat o_{j \to i}, a_i) \rVert_2, \qquad
        r_i = -\frac{1}{|J_i|} \sum_{j \in J_i} \frac{e_{ij}}{d}, \qquad r_i = 0 \text{ if } J_i = \emptyset .

    The neighbours are visited by offset (``j = (i + k) mod N`` for ``k = 1..N-1``), all offsets in one batch.

    :param forward_model: ``f(observations (..., d), encoded actions (..., a)) -> predicted next observations
        (..., d)``
    :param observations: :math:`o_t`, ``(..., N, d)``
    :param actions: encoded actions :math:`a_t` (e.g. one-hot), ``(..., N, a)``
    :param next_observations: :math:`o'_{t+1}`, ``(..., N, d)``
    :param obs_radius: neighbourhood and visibility radius; ``None`` = every teammate is a neighbour, no masking
    :param position_fn: ``(..., d) -> (..., 2)`` agent positions (needed when ``obs_radius`` is set)
    :param visibility_fn: ``(observations (..., d), viewer positions (..., 2), radius) -> mask (..., d)``, multiplied
        into the observation; ``None`` = no masking (full observability)
    :return: the unscaled bonus, ``(..., N)``
    """
    n_agents, obs_dim = observations.shape[-2:]
    neighbours = neighbour_mask(observations, obs_radius, position_fn)  # (..., N, N)
    agents = th.arange(n_agents, device=observations.device)
    offsets = th.arange(1, n_agents, device=observations.device)
    partners = (agents.unsqueeze(0) + offsets.unsqueeze(1)) % n_agents  # (N-1, N): partners[k-1, i] = j
    is_neighbour = neighbours[..., agents.unsqueeze(0), partners]  # (..., N-1, N)

    shape = (*observations.shape[:-2], n_agents - 1, n_agents)
    imagined = observations.unsqueeze(-3).expand(*shape, obs_dim)  # (..., N-1, N, d): o_i for every partner j
    if obs_radius is not None and visibility_fn is not None:
        assert position_fn is not None
        viewer_positions = position_fn(observations)[..., partners, :]  # (..., N, 2) -> (..., N-1, N, 2)
        imagined = imagined * visibility_fn(imagined, viewer_positions, obs_radius)
    repeated_actions = actions.unsqueeze(-3).expand(*shape, actions.shape[-1])  # (..., N-1, N, a)
    predictions = forward_model(imagined, repeated_actions)  # (..., N-1, N, d)
    errors = th.linalg.vector_norm(next_observations.unsqueeze(-3) - predictions, dim=-1)  # (..., N-1, N)

    weights = is_neighbour.to(errors.dtype)
    n_neighbours = weights.sum(dim=-2)  # (..., N)
    mean_error = (errors * weights).sum(dim=-2) / n_neighbours.clamp(min=1.0)  # (..., N)
    return th.where(n_neighbours > 0, -mean_error / obs_dim, th.zeros_like(mean_error))


# ---------------------------------------------------------------------------------------------------- the model
def encoded_action_dim(action_space: spaces.Space) -> int:
    """Size of :func:`encode_actions`' output: n for Discrete, sum(nvec) for MultiDiscrete, the flat size otherwise
    (gymnasium's ``flatdim``)."""
    return spaces.flatdim(action_space)


def encode_actions(actions: th.Tensor, action_space: spaces.Space) -> th.Tensor:
    """One-hot encode Discrete / MultiDiscrete actions; Box / MultiBinary actions are used as they are.

    :param actions: actions as stored in the rollout buffer, ``(..., action_dim)``
    :param action_space: one agent's action space
    :return: float ``(..., encoded_action_dim)``
    """
    if isinstance(action_space, spaces.Discrete):
        return F.one_hot(actions[..., 0].long(), int(action_space.n)).float()
    if isinstance(action_space, spaces.MultiDiscrete):
        return th.cat([F.one_hot(actions[..., k].long(), int(n)).float() for k, n in enumerate(action_space.nvec)], dim=-1)
    return actions.float()


class ForwardModel(nn.Module):
    """Forward model ``f(o, a) -> o'``: a ReLU MLP on the concatenated observation and encoded action, as Elign's
    ``WorldModel`` (``Linear -> ReLU`` per hidden layer, a linear output of the observation size).

    :param obs_dim: observation size d
    :param action_dim: encoded action size
    :param net_arch: hidden widths
    """

    def __init__(self, obs_dim: int, action_dim: int, net_arch: Sequence[int] = (128, 128)) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        last_dim = obs_dim + action_dim
        for width in net_arch:
            layers += [nn.Linear(last_dim, width), nn.ReLU()]
            last_dim = width
        layers.append(nn.Linear(last_dim, obs_dim))
        self.net = nn.Sequential(*layers)

    def forward(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        return self.net(th.cat([observations, actions], dim=-1))


# ---------------------------------------------------------------------------------------------------- the callback
@register_intrinsic_reward("elign")
class ElignCallback(NextObservationRecorder):
    r"""Elign's team expectation-alignment bonus (``elign_team``; Ma, Wang, Fei-Fei, Bernstein, Krishna,
    "ELIGN: Expectation Alignment as a Multi-Agent Intrinsic Reward", NeurIPS 2022, https://arxiv.org/abs/2210.04365)
    for parameter-shared on-policy training.

    Agent i is rewarded for behaving as its neighbours expect: a forward model :math:`f(o, a) \to o'` predicts i's next
    observation from i's observation *as each neighbour j would see it* (:math:`\hat o_{j \to i}`, entries j cannot
    see zeroed) and i's action, and the bonus is minus the mean L2 prediction error over the neighbours, divided by the
    observation size (see :func:`elign_team_bonus`). Agents without a neighbour get 0.

    **Adaptation and the choices the paper leaves open**:

    - *One shared model*: Elign gives each agent its own model, trained on its own transitions. Here one model is
      shared by all agents, like the policy; it runs on each agent's own transition, so it is still "agent i's model
      of itself" evaluated per agent. Trained by MSE on every agent's :math:`(o_t, a_t, o'_{t+1})` of the rollout
      (Adam, ``learning_rate`` 1e-3 as Elign's). Actions are one-hot (Elign feeds the raw action index).
      :math:`o'_{t+1}` is recorded in :meth:`_on_step`; where a game ended it is the real final observation.
    - *Model size*: two hidden layers of 128 (Elign's ``WorldModel`` defaults ``layer_num=2``,
      ``hidden_units=128``; the released MPE script passes the action count as ``hidden_units``, a width of 5, which
      looks unintended and is not reproduced).
    - *Schedule*: the bonus of a rollout is computed with the model as it was before the rollout, then the model is
      trained on the rollout (:meth:`train_bonus_model`), as in Elign where each sampled batch gets its bonus from
      the current model before the model's gradient step on it. Elign takes one 1024-sample step per 100 collected
      transitions, about 10 gradient samples per transition; ``n_epochs=10`` with ``batch_size=1024`` keeps that
      reuse. Elign recomputes a replayed transition's bonus with newer models; on-policy data is used once.
    - *Neighbourhood*: teammates within ``obs_radius`` (default 0.5, the README's ``--obs-radius 0.5`` command) of
      agent i, positions from ``position_fn``; ``obs_radius=None`` = every teammate (tasks without positions).
    - *Visibility*: ``visibility_fn`` (default :func:`navigation_visibility` for the mpe2 Cooperative Navigation
      layout) zeroes the entities beyond ``obs_radius`` of j; ``None`` = no masking.
    - *Averaging*: over the neighbours of i, as the paper's :math:`1/|J_i|`. The released code instead adds i's own
      prediction error to the team terms and divides by the team size (``j_list`` includes i, invisible j count as
      0); that is not reproduced.
    - *Coefficient*: 1.0, Elign adds the bonus to the extrinsic reward with weight 1.

    Logs ``rollout/elign_reward_mean`` (bonus before ``coef``), ``rollout/elign_neighbour_fraction`` (share of agent
    steps with at least one neighbour) and ``train/elign_model_loss``. Returns ``(n_steps, n_envs)``: the same bonus
    for every critic scale.

    :param coef: weight of the bonus (1.0, Elign's)
    :param obs_radius: neighbourhood and visibility radius (0.5); ``None`` = all teammates, no masking
    :param position_fn: ``(..., d) -> (..., 2)`` agent position from its observation (default: mpe2 ``obs[..., 2:4]``)
    :param visibility_fn: ``(obs (..., d), viewer positions (..., 2), radius) -> mask (..., d)``; default
        :func:`navigation_visibility`, ``None`` = no masking
    :param net_arch: hidden widths of the forward model ((128, 128))
    :param learning_rate: forward-model Adam learning rate (1e-3)
    :param n_epochs: forward-model passes over each rollout (10)
    :param batch_size: forward-model minibatch size in agent transitions (1024, Elign's batch size)
    :param device: torch device of the forward model
    :param verbose: verbosity
    """

    def __init__(
        self,
        coef: float = 1.0,
        obs_radius: float | None = 0.5,
        position_fn: PositionFn | None = navigation_position,
        visibility_fn: VisibilityFn | None = navigation_visibility,
        net_arch: Sequence[int] = (128, 128),
        learning_rate: float = 1e-3,
        n_epochs: int = 10,
        batch_size: int = 1024,
        device: th.device | str = "auto",
        verbose: int = 0,
    ) -> None:
        if obs_radius is not None and position_fn is None:
            raise ValueError("position_fn is needed when obs_radius is set (or use obs_radius=None).")
        if obs_radius is not None:
            check_number("ElignCallback", "obs_radius", obs_radius, "> 0 (or None: every teammate)", lambda x: x > 0)
        check_number("ElignCallback", "learning_rate", learning_rate, "> 0", lambda x: x > 0)
        check_number("ElignCallback", "n_epochs", n_epochs, ">= 1", lambda x: x >= 1, integer=True)
        if batch_size < 1:
            raise ValueError(f"batch_size must be positive, got {batch_size}.")
        super().__init__(coef=coef, name="elign", verbose=verbose)
        self.obs_radius = obs_radius
        self.position_fn = position_fn
        self.visibility_fn = visibility_fn
        self.net_arch = tuple(net_arch)
        self.learning_rate = learning_rate
        self.n_epochs = n_epochs
        self.batch_size = batch_size
        self.device = get_device(device)
        self.action_space: spaces.Space | None = None
        self.forward_model: ForwardModel | None = None
        self.optimizer: th.optim.Optimizer | None = None
        self._last_transitions: tuple[th.Tensor, th.Tensor, th.Tensor] | None = None
        self.last_neighbour_fraction = 0.0

    def setup_forward_model(self, observation_space: spaces.Space, action_space: spaces.Space) -> None:
        """Build the forward model and its optimiser (done in ``_init_callback`` from the algorithm's spaces).

        :param observation_space: one agent's observation space
        :param action_space: one agent's action space
        """
        self.action_space = action_space
        obs_dim = spaces.flatdim(observation_space)
        self.forward_model = ForwardModel(obs_dim, encoded_action_dim(action_space), self.net_arch).to(self.device)
        self.optimizer = th.optim.Adam(self.forward_model.parameters(), lr=self.learning_rate)

    def _init_callback(self) -> None:
        super()._init_callback()
        if self.forward_model is None:
            self.setup_forward_model(self.model.observation_space, self.model.action_space)

    def _predict(self, observations: th.Tensor, encoded_actions: th.Tensor) -> th.Tensor:
        assert self.forward_model is not None
        return self.forward_model(observations, encoded_actions)

    def _to_tensors(
        self, observations: np.ndarray, actions: np.ndarray, next_observations: np.ndarray
    ) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        """Flat float tensors ``(..., d)``, encoded actions ``(..., a)`` and ``(..., d)`` on the device."""
        assert self.action_space is not None, "call setup_forward_model first"
        lead = np.shape(actions)[:-1]
        # (..., *obs_shape) -> (..., d)
        obs = th.as_tensor(np.asarray(observations), dtype=th.float32, device=self.device).reshape(*lead, -1)
        next_obs = th.as_tensor(np.asarray(next_observations), dtype=th.float32, device=self.device).reshape(*lead, -1)
        encoded = encode_actions(th.as_tensor(np.asarray(actions), device=self.device), self.action_space)
        return obs, encoded, next_obs

    # ------------------------------------------------------------------------------------------------ bonus
    def bonus_from_transitions(
        self, observations: np.ndarray, actions: np.ndarray, next_observations: np.ndarray, n_agents: int
    ) -> np.ndarray:
        """Elign bonus of a rollout with the current forward model (keeps the transitions for the next training).

        :param observations: :math:`o_t`, ``(n_steps, n_envs, d)``, slots ordered ``game * n_agents + agent``
        :param actions: :math:`a_t` as stored in the buffer, ``(n_steps, n_envs, action_dim)``
        :param next_observations: :math:`o'_{t+1}`, ``(n_steps, n_envs, d)``
        :param n_agents: agents per game N
        :return: ``(n_steps, n_envs)``
        """
        obs, encoded, next_obs = self._to_tensors(observations, actions, next_observations)
        n_steps, n_envs = obs.shape[:2]
        n_games = n_envs // n_agents

        def per_game(array: th.Tensor) -> th.Tensor:
            return array.reshape(n_steps * n_games, n_agents, array.shape[-1])  # (T, G * N, x) -> (T * G, N, x)

        with th.no_grad():
            bonus = elign_team_bonus(
                self._predict,
                per_game(obs),
                per_game(encoded),
                per_game(next_obs),
                self.obs_radius,
                self.position_fn,
                self.visibility_fn,
            )  # (T * G, N)
            has_neighbour = neighbour_mask(per_game(obs), self.obs_radius, self.position_fn).any(dim=-1)  # (T * G, N)
        self.last_neighbour_fraction = float(has_neighbour.float().mean()) if has_neighbour.numel() else 0.0
        self._last_transitions = (obs, encoded, next_obs)
        return bonus.reshape(n_steps, n_envs).cpu().numpy()  # (T * G, N) -> (T, E)

    def compute_bonus(self, buffer: GroupedRecurrentRolloutBuffer) -> np.ndarray:
        next_observations = self.rollout_next_observations(buffer)  # (T, E, *obs_shape)
        return self.bonus_from_transitions(buffer.observations, buffer.actions, next_observations, buffer.n_agents)

    # ------------------------------------------------------------------------------------------------ training
    def model_loss(self, observations: np.ndarray, actions: np.ndarray, next_observations: np.ndarray) -> float:
        """Mean squared error of the forward model on transitions ``(..., d)``, ``(..., action_dim)``, ``(..., d)``."""
        obs, encoded, next_obs = self._to_tensors(observations, actions, next_observations)
        with th.no_grad():
            return float(F.mse_loss(self._predict(obs, encoded), next_obs))

    def train_forward_model(self, observations: np.ndarray, actions: np.ndarray, next_observations: np.ndarray) -> float:
        """Fit the forward model by MSE on transitions ``(..., d)``, ``(..., action_dim)`` (buffer format), ``(..., d)``.

        :return: the mean training loss over the minibatches
        """
        return self._train_on_tensors(*self._to_tensors(observations, actions, next_observations))

    def _train_on_tensors(self, obs: th.Tensor, encoded: th.Tensor, next_obs: th.Tensor) -> float:
        assert self.optimizer is not None
        obs = obs.reshape(-1, obs.shape[-1])  # (..., d) -> (n, d)
        encoded = encoded.reshape(-1, encoded.shape[-1])  # (..., a) -> (n, a)
        next_obs = next_obs.reshape(-1, next_obs.shape[-1])  # (..., d) -> (n, d)
        losses = []
        for _ in range(self.n_epochs):
            for batch in th.randperm(obs.shape[0], device=self.device).split(self.batch_size):
                loss = F.mse_loss(self._predict(obs[batch], encoded[batch]), next_obs[batch])
                self.optimizer.zero_grad()
                loss.backward()
                self.optimizer.step()
                losses.append(loss.item())
        return float(np.mean(losses)) if losses else 0.0

    def train_bonus_model(self, buffer: GroupedRecurrentRolloutBuffer) -> None:
        if self._last_transitions is None:
            return
        self.logger.record("train/elign_model_loss", self._train_on_tensors(*self._last_transitions))
        self._last_transitions = None

    def _log_bonus(self, bonus: np.ndarray, buffer: GroupedRecurrentRolloutBuffer) -> None:
        super()._log_bonus(bonus, buffer)
        self.logger.record("rollout/elign_neighbour_fraction", self.last_neighbour_fraction)
