"""Multi-agent recurrent actor-critic policies: a parameter-shared actor per agent, critics over each game's agents.

The actor sees one agent's observation (decentralised execution, so ``predict`` works on any number of agents'
observations). Every critic scale sees the N agents of a game together: its inputs are shaped ``(T, G, N, obs_dim)``
(time, games, agents), which is why ``SAEIR_PPO`` keeps games whole in its buffer and minibatches.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.distributions import (
    BernoulliDistribution,
    CategoricalDistribution,
    DiagGaussianDistribution,
    Distribution,
    MultiCategoricalDistribution,
)
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.type_aliases import PyTorchObs, Schedule
from torch import nn

from sb3_saeir.common.compilation import compile_network, mark_dynamic
from sb3_saeir.common.hypergraph import SCALES
from sb3_saeir.common.policy_arguments import (
    DEFAULT_GROUP_SIZE,
    check_optimizer_arguments,
    check_predict_array,
    check_predict_observation,
    check_sb3_policy_kwargs,
    default_scales,
    warn_degenerate_group_scale,
)
from sb3_saeir.common.torch_layers import (
    ActorNetwork,
    HypergraphScaleCritic,
    RecurrentValueCritic,
    ValueNorm,
    check_hidden_size,
)
from sb3_saeir.common.type_aliases import MultiAgentStates
from sb3_saeir.common.utils import check_bool


class MultiAgentActorCriticPolicy(ActorCriticPolicy):
    """Base class: recurrent parameter-shared actor, one or more critics over a game's agents, ValueNorm per critic.

    Subclasses implement :meth:`_build_critics`. The actor follows the authors' rMAPPO actor (spec §3): LayerNorm on
    the input, two ``Linear -> activation -> LayerNorm`` layers, a GRU with LayerNorm output, then SB3's action head
    (orthogonal init, gain 0.01). All networks are trained by one Adam optimizer; since they share no parameters this
    equals one Adam per network, and gradients are clipped per network by the algorithm.

    ``recurrent=False`` builds every network without its GRU (the feed-forward variant, as the MAPPO authors'
    ``use_recurrent_policy=False`` and BenchMARL's default MAPPO; not the paper's setting): the policy keeps no state
    (its states have width 0) and the update runs each network once per minibatch on its valid rows, without chunks
    (``docs/guide/algorithms.md``, "Feed-forward networks"). With ``recurrent_actor=True`` the actor keeps its GRU
    (feed-forward critics; the update runs on chunks).

    :param observation_space: one agent's observation space
    :param action_space: one agent's action space
    :param lr_schedule: learning rate schedule
    :param n_agents: agents per game (N); set by the algorithm from the vec env
    :param hidden_size: width of every hidden layer and GRU (64 in the paper's code)
    :param activation_fn: activation of the MLP layers (Tanh for navigation, ReLU for football in the paper)
    :param recurrent: GRUs in the actor and every critic (the paper's and the authors' setting, default); ``False``:
        feed-forward critics, and a feed-forward actor unless ``recurrent_actor=True`` keeps the actor's GRU
    :param recurrent_actor: GRU in the actor; ``None`` (default): as ``recurrent``. ``False`` with recurrent critics
        gives the paper's plain MLP actor; ``True`` with ``recurrent=False`` a GRU actor with feed-forward critics
        (``docs/guide/algorithms.md``, "Feed-forward networks")
    :param normalize_values: one ValueNorm per critic (spec §1.9); values are predicted in normalised space
    :param value_norm_beta: ValueNorm's EMA coefficient
    :param critic_gumbel_noise: draw Gumbel noise in the hypergraph critics at every forward pass (authors' code);
        ``False`` uses the plain softmax (deterministic critics)
    :param log_std_init: initial log standard deviation of the Gaussian action head (continuous actions)
    :param ortho_init: orthogonal initialisation; only ``True`` (the paper's) is supported, ``False`` raises
    :param optimizer_class: optimizer class, a subclass of ``torch.optim.Optimizer``
    :param optimizer_kwargs: optimizer kwargs, the class's own keywords except ``lr`` (the model's ``learning_rate``)
        and ``params``, checked before the networks are built
        (:func:`~sb3_saeir.common.policy_arguments.check_optimizer_arguments`); default:
        :func:`~sb3_saeir.common.policy_arguments.default_optimizer_kwargs`, ``eps=1e-5`` as MAPPO with ``fused=True``
        for Adam and AdamW
    :param sb3_kwargs: SB3 ``ActorCriticPolicy`` arguments, accepted only with their default value (SB3 passes them
        when it rebuilds a saved policy); ``net_arch``, ``features_extractor_class``, ``use_sde`` or
        ``share_features_extractor=False`` raise a ``ValueError`` naming what to use instead, as does any unknown key
    """

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        lr_schedule: Schedule,
        n_agents: int = 1,
        hidden_size: int = 64,
        activation_fn: type[nn.Module] = nn.Tanh,
        recurrent: bool = True,
        recurrent_actor: bool | None = None,
        normalize_values: bool = True,
        value_norm_beta: float = 0.99999,
        critic_gumbel_noise: bool = True,
        log_std_init: float = 0.0,
        ortho_init: bool = True,
        optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
        optimizer_kwargs: dict[str, Any] | None = None,
        **sb3_kwargs: Any,
    ) -> None:
        hidden_size = check_hidden_size(type(self).__name__, hidden_size)
        if recurrent_actor is None:
            recurrent_actor = recurrent
        check_bool(
            type(self).__name__,
            recurrent=recurrent,
            recurrent_actor=recurrent_actor,
            normalize_values=normalize_values,
            critic_gumbel_noise=critic_gumbel_noise,
            ortho_init=ortho_init,
        )
        check_sb3_policy_kwargs(type(self).__name__, sb3_kwargs, ortho_init)
        if not isinstance(observation_space, spaces.Box) or len(observation_space.shape) != 1:
            raise ValueError(
                f"{type(self).__name__} needs flat Box observations per agent, got {observation_space}. "
                "Flatten them with supersuit.flatten_v0 (or a gymnasium FlattenObservation-style wrapper)."
            )
        if n_agents < 1:
            raise ValueError(f"n_agents must be >= 1, got {n_agents}.")
        self.n_agents = n_agents
        self.hidden_size = hidden_size
        self.recurrent = recurrent
        self.recurrent_actor = recurrent_actor
        self.normalize_values = normalize_values
        self.value_norm_beta = value_norm_beta
        self.critic_gumbel_noise = critic_gumbel_noise
        self.compile_backend: str | None = None
        self._compiled_actor: Callable[..., Any] | None = None
        self._compiled_critics: dict[str, Callable[..., Any]] = {}
        optimizer_kwargs = check_optimizer_arguments(type(self).__name__, optimizer_class, optimizer_kwargs)
        super().__init__(
            observation_space,
            action_space,
            lr_schedule,
            activation_fn=activation_fn,
            log_std_init=log_std_init,
            ortho_init=ortho_init,
            optimizer_class=optimizer_class,
            optimizer_kwargs=optimizer_kwargs,
            share_features_extractor=True,
        )

    # ------------------------------------------------------------------------------------------------ construction
    @property
    def obs_dim(self) -> int:
        return int(np.prod(self.observation_space.shape))  # type: ignore[arg-type]

    @property
    def scales(self) -> tuple[str, ...]:
        """Names of the critics, in the order of the last axis of every value array."""
        return tuple(self.critics.keys())

    @property
    def n_scales(self) -> int:
        return len(self.critics)

    @property
    def critic_state_size(self) -> int:
        """Width of each critic's state: ``hidden_size`` with GRUs, 0 for feed-forward critics."""
        return self.hidden_size if self.recurrent else 0

    @property
    def actor_state_size(self) -> int:
        """Width of the actor's state: ``hidden_size`` with its GRU, 0 for an MLP actor."""
        return self.hidden_size if self.recurrent_actor else 0

    @property
    def feed_forward(self) -> bool:
        """True when no network has a GRU: the update may run on the valid rows without chunks."""
        return not (self.recurrent or self.recurrent_actor)

    def _build_critics(self) -> nn.ModuleDict:
        """Critic modules by scale name; each maps ``(T, G, N, d), (G, N, H), (T, G, N)`` to values ``(T, G, N)``."""
        raise NotImplementedError

    def _build(self, lr_schedule: Schedule) -> None:
        self.actor = ActorNetwork(self.obs_dim, self.hidden_size, self.activation_fn, recurrent=self.recurrent_actor)
        self.action_net, self.log_std = self._build_action_net(self.hidden_size)  # type: ignore[assignment]
        self.critics = self._build_critics()
        self.value_norms = nn.ModuleDict({name: ValueNorm(beta=self.value_norm_beta) for name in self.critics})
        self.optimizer = self.optimizer_class(self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs)  # type: ignore[call-arg]

    def _build_action_net(self, latent_dim: int) -> tuple[nn.Linear, nn.Parameter | None]:
        log_std = None
        if isinstance(self.action_dist, DiagGaussianDistribution):
            action_net, log_std = self.action_dist.proba_distribution_net(latent_dim, log_std_init=self.log_std_init)
        elif isinstance(self.action_dist, (CategoricalDistribution, MultiCategoricalDistribution, BernoulliDistribution)):
            action_net = self.action_dist.proba_distribution_net(latent_dim)
        else:
            raise NotImplementedError(f"Unsupported action distribution {type(self.action_dist).__name__}.")
        assert isinstance(action_net, nn.Linear)
        nn.init.orthogonal_(action_net.weight, gain=0.01)
        nn.init.zeros_(action_net.bias)
        return action_net, log_std

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(
            n_agents=self.n_agents,
            hidden_size=self.hidden_size,
            recurrent=self.recurrent,
            recurrent_actor=self.recurrent_actor,
            normalize_values=self.normalize_values,
            value_norm_beta=self.value_norm_beta,
            critic_gumbel_noise=self.critic_gumbel_noise,
        )
        data.pop("net_arch", None)
        return data

    def set_compile(self, backend: str | None) -> None:
        """Run the forward of the actor's trunk and of every critic through ``torch.compile`` (in the rollout, in
        ``predict`` and in the update), or eagerly again (``None``). The modules are not wrapped: the state-dict keys
        do not change (``sb3_saeir.common.compilation``; the algorithms' ``compile`` switch calls this).

        :param backend: a ``torch.compile`` backend (``"inductor"``), or ``None`` for eager
        """
        self.compile_backend = backend
        if backend is None:
            self._compiled_actor, self._compiled_critics = None, {}
            return
        self._compiled_actor = compile_network(self.actor.forward, backend)
        self._compiled_critics = {name: compile_network(critic.forward, backend) for name, critic in self.critics.items()}

    # ------------------------------------------------------------------------------------------------ parameters
    def actor_parameters(self) -> list[nn.Parameter]:
        """Parameters of the actor (trunk, action head, log std)."""
        params = [*self.actor.parameters(), *self.action_net.parameters()]
        if self.log_std is not None:
            params.append(self.log_std)
        return params

    def critic_parameters(self, scale: str) -> list[nn.Parameter]:
        """Parameters of one critic."""
        return list(self.critics[scale].parameters())

    def initial_states(self, n_games: int) -> MultiAgentStates:
        """Zero recurrent states for ``n_games`` games (of width 0 for the networks without a GRU)."""
        n_slots = n_games * self.n_agents
        return MultiAgentStates(
            actor=th.zeros(n_slots, self.actor_state_size, device=self.device),
            critic=th.zeros(self.n_scales, n_games, self.n_agents, self.critic_state_size, device=self.device),
        )

    # ------------------------------------------------------------------------------------------------ value space
    def denormalize_values(self, values: th.Tensor) -> th.Tensor:
        """Map normalised values ``(..., K)`` to return space with each scale's ValueNorm."""
        if not self.normalize_values:
            return values
        return th.stack([self.value_norm(name).denormalize(values[..., k]) for k, name in enumerate(self.scales)], dim=-1)

    def value_norm(self, scale: str) -> ValueNorm:
        """The ValueNorm of one critic scale (the algorithm updates it with each minibatch's returns)."""
        value_norm = self.value_norms[scale]
        assert isinstance(value_norm, ValueNorm)
        return value_norm

    def denormalize_values_numpy(self, values: np.ndarray) -> np.ndarray:
        """NumPy version of :meth:`denormalize_values` (used by the rollout buffer's GAE)."""
        with th.no_grad():
            return self.denormalize_values(th.as_tensor(values, dtype=th.float32, device=self.device)).cpu().numpy()

    # ------------------------------------------------------------------------------------------------ networks
    def _actor_latent(
        self, obs: th.Tensor, states: th.Tensor | None, episode_starts: th.Tensor
    ) -> tuple[th.Tensor, th.Tensor | None]:
        """obs ``(T, B, d)``, states ``(B, H)``, episode_starts ``(T, B)`` -> latent ``(T, B, H)``, new states."""
        hidden = states if self.recurrent_actor else None
        if self._compiled_actor is None:
            return self.actor(obs, hidden, episode_starts)
        mark_dynamic(obs, 1)
        mark_dynamic(hidden, 0)
        mark_dynamic(episode_starts, 1)
        return self._compiled_actor(obs, hidden, episode_starts)

    def _run_critic(
        self,
        k: int,
        obs: th.Tensor,
        states: th.Tensor,
        episode_starts: th.Tensor,
        gumbel_noise: bool,
        gumbel_uniform: th.Tensor | None,
    ) -> tuple[th.Tensor, th.Tensor]:
        """Critic scale ``k`` on obs ``(T, G, N, d)``, states ``(G, N, H)``, episode_starts ``(T, G, N)`` and its Gumbel
        draws ``(T * G, E, T_K)`` (compiled when :meth:`set_compile` asked for it) -> values ``(T, G, N)``, new states."""
        name = self.scales[k]
        compiled = self._compiled_critics.get(name)
        if compiled is None:
            return self.critics[name](obs, states, episode_starts, gumbel_noise=gumbel_noise, gumbel_uniform=gumbel_uniform)
        mark_dynamic(obs, 1)
        mark_dynamic(states, 0)
        mark_dynamic(episode_starts, 1)
        mark_dynamic(gumbel_uniform, 0)
        return compiled(obs, states, episode_starts, gumbel_noise=gumbel_noise, gumbel_uniform=gumbel_uniform)

    def _critic_values(
        self, obs: th.Tensor, states: th.Tensor, episode_starts: th.Tensor, gumbel_noise: bool | None = None
    ) -> tuple[th.Tensor, th.Tensor]:
        """obs ``(T, G, N, d)``, states ``(K, G, N, H)``, episode_starts ``(T, G, N)`` -> values ``(T, G, N, K)``,
        new states ``(K, G, N, H)``.

        Each critic's Gumbel draws are made here, before it runs, from the global generator as the critic would draw
        them itself (the same numbers; outside compiled code)."""
        noise = self.critic_gumbel_noise if gumbel_noise is None else gumbel_noise
        n_steps, n_games = obs.shape[:2]
        values, new_states = [], []
        for k in range(self.n_scales):
            uniform = self.draw_gumbel_uniform(k, n_steps, n_games) if noise else None  # (T, G, E, T_K)
            flat_uniform = None if uniform is None else uniform.flatten(0, 1)  # (T * G, E, T_K), rows (step, game)
            value, state = self._run_critic(k, obs, states[k], episode_starts, noise, flat_uniform)
            values.append(value)
            new_states.append(state)
        return th.stack(values, dim=-1), th.stack(new_states)

    def _distribution(self, latent_pi: th.Tensor) -> Distribution:
        mean_actions = self.action_net(latent_pi)
        if self.log_std is not None:
            return self.action_dist.proba_distribution(mean_actions, self.log_std)  # type: ignore[call-arg]
        return self.action_dist.proba_distribution(action_logits=mean_actions)  # type: ignore[call-arg]

    def _to_games(self, flat: th.Tensor) -> th.Tensor:
        """``(n_slots, ...)`` -> ``(1, G, N, ...)`` (one time step)."""
        return flat.reshape(1, -1, self.n_agents, *flat.shape[1:])

    def forward(  # type: ignore[override]
        self, obs: th.Tensor, states: MultiAgentStates, episode_starts: th.Tensor, deterministic: bool = False
    ) -> tuple[th.Tensor, th.Tensor, th.Tensor, MultiAgentStates]:
        """One rollout step for all slots of the vec env.

        :param obs: ``(G * N, d)`` observations in slot order
        :param states: states before this step
        :param episode_starts: ``(G * N,)``, 1 where a slot starts a new episode
        :param deterministic: greedy actions
        :return: actions ``(G * N, ...)``, normalised values ``(G * N, K)``, log-probs ``(G * N,)``, new states
        """
        obs = obs.float().reshape(obs.shape[0], -1)
        starts = episode_starts.float()
        latent_pi, actor_states = self._actor_latent(obs.unsqueeze(0), states.actor, starts.unsqueeze(0))
        distribution = self._distribution(latent_pi.squeeze(0))
        actions = distribution.get_actions(deterministic=deterministic)
        log_prob = distribution.log_prob(actions)
        # (G * N, d) -> (1, G, N, d); values (1, G, N, K) -> (G * N, K)
        values, critic_states = self._critic_values(self._to_games(obs), states.critic, self._to_games(starts))
        values = values.reshape(-1, self.n_scales)
        new_actor = actor_states if actor_states is not None else states.actor
        return actions, values, log_prob, MultiAgentStates(new_actor, critic_states)

    def predict_values(  # type: ignore[override]
        self, obs: th.Tensor, states: MultiAgentStates | None = None, episode_starts: th.Tensor | None = None
    ) -> th.Tensor:
        """Normalised values ``(G * N, K)`` of one step of observations ``(G * N, d)`` in slot order."""
        obs = obs.float().reshape(obs.shape[0], -1)
        n_games = obs.shape[0] // self.n_agents
        if states is None:
            states = self.initial_states(n_games)
        if episode_starts is None:
            episode_starts = th.zeros(obs.shape[0], device=obs.device)
        values, _ = self._critic_values(self._to_games(obs), states.critic, self._to_games(episode_starts.float()))
        return values.reshape(-1, self.n_scales)

    def evaluate_actions(  # type: ignore[override]
        self,
        obs: th.Tensor,
        actions: th.Tensor,
        actor_states: th.Tensor,
        critic_states: th.Tensor,
        episode_starts: th.Tensor,
    ) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        """Re-run actor and critics over chunks of whole games (training).

        :param obs: ``(L, B, N, d)``: L steps of B blocks (game, chunk), all N agents
        :param actions: ``(L, B, N, action_dim)``
        :param actor_states: ``(B, N, H)`` stored actor states at each chunk's first step
        :param critic_states: ``(K, B, N, H)`` stored critic states at each chunk's first step
        :param episode_starts: ``(L, B, N)``
        :return: normalised values ``(L, B, N, K)``, log-probs ``(L, B, N)``, entropy ``(L, B, N)``
        """
        log_prob, entropy = self.evaluate_actor(obs, actions, actor_states, episode_starts)
        values = th.stack(
            [self.evaluate_critic(k, obs, critic_states[k], episode_starts) for k in range(self.n_scales)], dim=-1
        )  # K x (L, B, N) -> (L, B, N, K)
        return values, log_prob, entropy

    def evaluate_actor(
        self, obs: th.Tensor, actions: th.Tensor, actor_states: th.Tensor, episode_starts: th.Tensor
    ) -> tuple[th.Tensor, th.Tensor]:
        """Re-run the actor over chunks of whole games: log-probs and entropy of the stored actions.

        :param obs: ``(L, B, N, d)``
        :param actions: ``(L, B, N, action_dim)``
        :param actor_states: ``(B, N, H)`` stored actor states at each chunk's first step
        :param episode_starts: ``(L, B, N)``
        :return: log-probs ``(L, B, N)`` and entropy ``(L, B, N)``
        """
        n_steps, n_blocks, n_agents = obs.shape[:3]
        flat_obs = obs.reshape(n_steps, n_blocks * n_agents, -1)  # (L, B * N, d)
        flat_starts = episode_starts.reshape(n_steps, n_blocks * n_agents)  # (L, B * N)
        flat_actor_states = actor_states.reshape(n_blocks * n_agents, -1)  # (B * N, H)
        latent_pi, _ = self._actor_latent(flat_obs, flat_actor_states, flat_starts)
        distribution = self._distribution(latent_pi.reshape(n_steps * n_blocks * n_agents, -1))
        flat_actions = actions.reshape(n_steps * n_blocks * n_agents, *actions.shape[3:])
        if isinstance(self.action_space, spaces.Discrete):
            flat_actions = flat_actions.reshape(-1)
        log_prob = distribution.log_prob(flat_actions).reshape(n_steps, n_blocks, n_agents)
        entropy = distribution.entropy()
        entropy = entropy.reshape(n_steps, n_blocks, n_agents) if entropy is not None else -log_prob
        return log_prob, entropy

    def evaluate_critic(
        self,
        k: int,
        obs: th.Tensor,
        critic_states: th.Tensor,
        episode_starts: th.Tensor,
        gumbel_uniform: th.Tensor | None = None,
    ) -> th.Tensor:
        """Re-run critic scale ``k`` over chunks of whole games (the algorithm back-propagates one network at a time).

        :param k: index of the scale in :attr:`scales`
        :param obs: ``(L, B, N, d)``
        :param critic_states: ``(B, N, H)`` the scale's stored states at each chunk's first step
        :param episode_starts: ``(L, B, N)``
        :param gumbel_uniform: the critic's Gumbel draws, ``(L * B, E, T_K)`` (:meth:`draw_gumbel_uniform`; drawn by
            the critic when ``None``)
        :return: normalised values ``(L, B, N)``
        """
        n_steps, n_blocks, n_agents = obs.shape[:3]
        if gumbel_uniform is None and self.critic_gumbel_noise:
            # drawn here rather than in the critic (the same numbers), outside any compiled code
            uniform = self.draw_gumbel_uniform(k, n_steps, n_blocks)  # (L, B, E, T_K) or None
            gumbel_uniform = None if uniform is None else uniform.flatten(0, 1)  # (L * B, E, T_K)
        # (L, B, N, *obs_shape) -> (L, B, N, d)
        obs = obs.reshape(n_steps, n_blocks, n_agents, -1)
        values, _ = self._run_critic(k, obs, critic_states, episode_starts, self.critic_gumbel_noise, gumbel_uniform)
        return values

    def draw_gumbel_uniform(self, k: int, n_steps: int, n_blocks: int) -> th.Tensor | None:
        """The uniform draws critic scale ``k`` makes for its Gumbel noise over ``n_steps`` steps of ``n_blocks``
        blocks, ``(n_steps, n_blocks, E, T_K)``, drawn from the global torch generator as the critic itself would;
        ``None`` for a critic without noise.

        The update draws them once for the padded minibatch and gives every part of it its rows, so that running the
        critic on the parts (no padded rows) sees the noise of the whole.
        """
        critic = list(self.critics.values())[k]
        shape = getattr(critic, "gumbel_shape", None)
        if shape is None or not self.critic_gumbel_noise:
            return None
        uniform = th.rand((n_steps * n_blocks, *shape), device=self.device)  # as the critic draws: rows (step, block)
        return uniform.reshape(n_steps, n_blocks, *shape)

    # ------------------------------------------------------------------------------------------------ inference
    def get_distribution(  # type: ignore[override]
        self, obs: PyTorchObs, actor_states: th.Tensor | None = None, episode_starts: th.Tensor | None = None
    ) -> Distribution:
        """Action distribution of one step for a batch of agents' observations ``(B, d)``."""
        obs = obs.float().reshape(obs.shape[0], -1)  # type: ignore[union-attr]
        if episode_starts is None:
            episode_starts = th.zeros(obs.shape[0], device=obs.device)
        latent_pi, _ = self._actor_latent(obs.unsqueeze(0), actor_states, episode_starts.float().unsqueeze(0))
        return self._distribution(latent_pi.squeeze(0))

    def _predict(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        return self.get_distribution(observation).get_actions(deterministic=deterministic)

    def predict(  # type: ignore[override]
        self,
        observation: np.ndarray,
        state: np.ndarray | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Actions for any number of agents' observations (the actor is decentralised).

        :param observation: ``(B, d)`` observations of B agents, or ``(d,)`` for one agent
        :param state: actor GRU states ``(B, H)`` from the previous call (``None``: zeros). An actor without GRU
            (``recurrent=False`` or ``recurrent_actor=False``) has no state: it takes ``None`` only (SB3's
            feed-forward ``predict`` ignores a state; here a state is refused, as a state of the wrong shape is for a
            recurrent actor)
        :param episode_start: ``(B,)``, 1 where an agent starts a new episode (resets its state)
        :param deterministic: greedy actions (``True`` or ``False``; a string such as ``"no"`` is refused)
        :return: actions and the new actor states (``None`` for an MLP actor)
        """
        check_bool("predict", deterministic=deterministic)
        if state is not None and not self.recurrent_actor:
            setting = "recurrent_actor=False" if self.recurrent else "recurrent=False"
            raise ValueError(
                f"predict: the model's actor is feed-forward ({setting}) and has no state, got a state of type "
                f"{type(state).__name__}; pass state=None (predict returns None as the next state)."
            )
        self.set_training_mode(False)
        obs_array = check_predict_observation(observation, tuple(self.observation_space.shape))  # type: ignore[arg-type]
        single = obs_array.ndim == len(self.observation_space.shape)  # type: ignore[arg-type]
        if single:
            obs_array = obs_array[None]
        n_agents = obs_array.shape[0]
        with th.no_grad():
            obs_tensor = th.as_tensor(obs_array, device=self.device).reshape(n_agents, -1)
            hidden = None
            if self.recurrent_actor:
                hidden = (
                    th.zeros(n_agents, self.hidden_size, device=self.device)
                    if state is None
                    else th.as_tensor(check_predict_array("state", state, (n_agents, self.hidden_size)), device=self.device)
                )
            starts = th.zeros(n_agents, device=self.device)
            if episode_start is not None:
                starts = th.as_tensor(check_predict_array("episode_start", episode_start, (n_agents,)), device=self.device)
            latent_pi, new_hidden = self._actor_latent(obs_tensor.unsqueeze(0), hidden, starts.unsqueeze(0))
            actions = self._distribution(latent_pi.squeeze(0)).get_actions(deterministic=deterministic)
        actions_np = actions.cpu().numpy().reshape((-1, *self.action_space.shape))  # type: ignore[misc, arg-type]
        if isinstance(self.action_space, spaces.Box):
            actions_np = np.clip(actions_np, self.action_space.low, self.action_space.high)
        new_state = new_hidden.cpu().numpy() if new_hidden is not None else None
        if single:
            actions_np = actions_np[0]
            new_state = new_state[0] if new_state is not None else None
        return actions_np, new_state


class MSHGPolicy(MultiAgentActorCriticPolicy):
    """SAEIR's multi-scale hypergraph (MSHG) critic with the parameter-shared recurrent actor.

    Three independent critics (team: one hyperedge with every agent; group: per-agent top-k cosine neighbours with
    ``n_edge_types`` Gumbel-softmax edge types; individual: one hyperedge per agent), each: encoder, GRU, node-to-edge
    attention, edge-type weights, edge-to-node aggregation, value head (spec §1.2-1.8). Each critic node gets its own
    agent's observation; the hypergraph provides the joint view (spec decision 12).

    :param scales: which critics to build (any non-empty subset of ``("team", "group", "individual")``, in that order).
        ``None`` (default): all three, except on 2-agent games with the default ``group_size``, where the group scale
        would copy the team scale and is left out (with a ``UserWarning`` saying so). On 1-agent games every scale's
        hypergraph is the one agent: a group scale there is kept, with a ``UserWarning`` that it is degenerate
    :param group_size: k, hyperedge size of the group scale (``num_in_group``; ``None``: 2). Set explicitly with the
        group scale, it must be smaller than the number of agents
    :param n_edge_types: edge types of the group scale (``num_group`` = 3)
    :param gumbel_tau: Gumbel-softmax temperature (0.5)
    :param kwargs: see :class:`MultiAgentActorCriticPolicy`
    """

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        lr_schedule: Schedule,
        scales: tuple[str, ...] | list[str] | None = None,
        group_size: int | None = None,
        n_edge_types: int = 3,
        gumbel_tau: float = 0.5,
        **kwargs: Any,
    ) -> None:
        n_agents = int(kwargs.get("n_agents", 1))
        scales = default_scales(n_agents) if scales is None and group_size is None else scales
        scales = SCALES if scales is None else scales
        group_size = DEFAULT_GROUP_SIZE if group_size is None else group_size
        unknown = [scale for scale in scales if scale not in SCALES]
        if isinstance(scales, str) or not scales or unknown or len(set(scales)) != len(scales):
            raise ValueError(f"MSHGPolicy: scales must be a non-empty subset of {SCALES}, each at most once, got {scales!r}.")
        self.critic_scales = tuple(scale for scale in SCALES if scale in scales)
        if group_size < 1 or n_edge_types < 1:
            raise ValueError(f"MSHGPolicy: group_size and n_edge_types must be >= 1, got {group_size} and {n_edge_types}.")
        if "group" in self.critic_scales and n_agents > 1 and group_size >= n_agents:
            raise ValueError(
                f"MSHGPolicy: group_size={group_size} must be smaller than the number of agents ({n_agents}): with k = N "
                "every group hyperedge holds the whole team and the group critic copies the team critic. Use a smaller "
                "group_size, or leave the group scale out (scales=('team', 'individual'))."
            )
        if "group" in self.critic_scales and n_agents == 1:
            warn_degenerate_group_scale(group_size)
        self.group_size = group_size
        self.n_edge_types = n_edge_types
        self.gumbel_tau = gumbel_tau
        super().__init__(observation_space, action_space, lr_schedule, **kwargs)

    def _build_critics(self) -> nn.ModuleDict:
        return nn.ModuleDict(
            {
                scale: HypergraphScaleCritic(
                    self.obs_dim,
                    self.n_agents,
                    scale,
                    group_size=self.group_size,
                    n_edge_types=self.n_edge_types,
                    hidden_size=self.hidden_size,
                    activation_fn=self.activation_fn,
                    gumbel_tau=self.gumbel_tau,
                    recurrent=self.recurrent,
                )
                for scale in self.critic_scales
            }
        )

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(
            scales=self.critic_scales, group_size=self.group_size, n_edge_types=self.n_edge_types, gumbel_tau=self.gumbel_tau
        )
        return data


class MAPPOPolicy(MultiAgentActorCriticPolicy):
    """Recurrent MAPPO (Yu et al., NeurIPS 2022 D&B): the same actor as :class:`MSHGPolicy`, one recurrent critic.

    The critic sees the concatenation of the game's agents' observations (``critic_input="joint"``, MAPPO's choice on
    MPE) or each agent's own observation (``"own"``, MAPPO's choice on football, whose observations are global).
    ``spectral_norm=("output",)`` gives SN-MAPPO (spectral normalisation of the critic's output layer, Mehta et al.
    2023); ``("output", "hidden")`` normalises every critic Linear layer.

    :param critic_input: ``"joint"`` or ``"own"``
    :param spectral_norm: critic layers to normalise (``"output"``, ``"hidden"``)
    :param kwargs: see :class:`MultiAgentActorCriticPolicy`
    """

    default_spectral_norm: tuple[str, ...] = ()

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        lr_schedule: Schedule,
        critic_input: str = "joint",
        spectral_norm: tuple[str, ...] | list[str] | None = None,
        **kwargs: Any,
    ) -> None:
        self.critic_input = critic_input
        self.spectral_norm = tuple(self.default_spectral_norm if spectral_norm is None else spectral_norm)
        super().__init__(observation_space, action_space, lr_schedule, **kwargs)

    def _build_critics(self) -> nn.ModuleDict:
        critic = RecurrentValueCritic(
            self.obs_dim,
            self.n_agents,
            critic_input=self.critic_input,
            hidden_size=self.hidden_size,
            activation_fn=self.activation_fn,
            spectral_norm=self.spectral_norm,
            recurrent=self.recurrent,
        )
        return nn.ModuleDict({"critic": critic})

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(critic_input=self.critic_input, spectral_norm=self.spectral_norm)
        return data


class SNMAPPOPolicy(MAPPOPolicy):
    """SN-MAPPO: :class:`MAPPOPolicy` with spectral normalisation on the critic's output layer by default."""

    default_spectral_norm = ("output",)
