"""SAEIR_PPO: recurrent MAPPO-style PPO with multi-scale critics over each game's agents and an intrinsic reward."""

from __future__ import annotations

import warnings
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule
from stable_baselines3.common.utils import explained_variance, obs_as_tensor
from stable_baselines3.common.vec_env import VecEnv
from torch.nn import functional as F

from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer, GroupedRecurrentSamples
from sb3_saeir.common.callbacks import episode_metric_means
from sb3_saeir.common.policies import MAPPOPolicy, MSHGPolicy, MultiAgentActorCriticPolicy, MultiAgentStates, SNMAPPOPolicy
from sb3_saeir.intrinsic.base import IntrinsicRewardCallback
from sb3_saeir.intrinsic.elign import ElignCallback
from sb3_saeir.intrinsic.rnd import RNDCallback
from sb3_saeir.intrinsic.saeir import SAEIRCallback

SelfSAEIR_PPO = TypeVar("SelfSAEIR_PPO", bound="SAEIR_PPO")

INTRINSIC_REWARDS: dict[str, type[IntrinsicRewardCallback]] = {
    "saeir": SAEIRCallback,
    "rnd": RNDCallback,
    "elign": ElignCallback,
}


def valid_batch_sizes(n_steps: int, n_games: int, n_agents: int, data_chunk_length: int) -> list[int]:
    """Batch sizes (agent-samples) that split a rollout into equal minibatches of whole (game, chunk) blocks.

    When ``n_steps`` is not a multiple of ``data_chunk_length``, blocks differ in length and only the whole rollout
    (one minibatch) qualifies.
    """
    if n_steps % data_chunk_length != 0:
        return [n_steps * n_games * n_agents]
    block = data_chunk_length * n_agents
    n_blocks = n_games * (n_steps // data_chunk_length)
    return [block * per_batch for per_batch in range(1, n_blocks + 1) if n_blocks % per_batch == 0]


def scale_advantage_weights(advantages: th.Tensor) -> th.Tensor:
    """Weights W_K of the critic scales for one minibatch (spec §1.10, the authors' code):

    .. math:: W_K = \\frac{\\sum_j \\exp(\\hat A^K_j)}{\\sum_{K'} \\sum_j \\exp(\\hat A^{K'}_j)}

    computed as a softmax over K of per-scale log-sum-exps (no overflow). No gradient flows through them.

    :param advantages: standardised advantages of the minibatch's valid samples, ``(n_samples, K)``
    :return: ``(K,)`` weights summing to 1
    """
    return th.softmax(th.logsumexp(advantages.detach(), dim=0), dim=0)


class SAEIR_PPO(PPO):
    """Recurrent multi-agent PPO with SAEIR (IJCAI-24): multi-scale hypergraph critics + entropy intrinsic reward.

    Paper: He, Ge, Hou, Yu, "SAEIR: Sequentially Accumulated Entropy Intrinsic Reward for Cooperative Multi-Agent
    Reinforcement Learning with Sparse Reward", IJCAI 2024. Code: https://github.com/yvjc/SAEIR (authors'),
    behaviour as specified in ``docs/method.md``. Built on recurrent MAPPO (Yu et al., NeurIPS 2022 D&B).

    A drop-in for SB3's :class:`~stable_baselines3.PPO` on a multi-agent vec env from
    :func:`~sb3_saeir.make_multiagent_vec_env` (one slot per agent, parameter sharing)::

        model = SAEIR_PPO("MSHGPolicy", make_multiagent_vec_env("cn-sparse-n3", n_games=16, seed=0)).learn(500_000)

    Differences from PPO: the buffer keeps games whole; the actor and every critic are GRUs trained on chunks of
    ``data_chunk_length`` steps from the stored states; each critic scale K has its own ValueNorm, GAE (with its own
    intrinsic reward) and clipped Huber value loss; the actor uses the W_K-mixed standardised advantages; gradients
    are clipped per network. Time limits count as terminal unless the env marks truncation.

    :param policy: ``"MSHGPolicy"`` (SAEIR's critic) or a :class:`MultiAgentActorCriticPolicy` subclass
    :param env: a multi-agent vec env (``make_multiagent_vec_env``); it must expose ``n_agents``
    :param learning_rate: learning rate (actor and critics), constant or schedule
    :param n_steps: steps per game per rollout (buffer length; the SAEIR entropy window)
    :param batch_size: minibatch size in agent-samples; must be a multiple of ``data_chunk_length * n_agents`` that
        divides the rollout. ``None`` (default): ``n_minibatches`` decides
    :param n_epochs: epochs per rollout
    :param gamma: discount factor
    :param gae_lambda: GAE lambda
    :param clip_range: PPO clip range (also for the value clipping, as MAPPO)
    :param clip_range_vf: value clip range in normalised space; ``None`` uses ``clip_range``; a negative value
        turns value clipping off
    :param normalize_advantage: standardise advantages per scale
    :param ent_coef: entropy coefficient
    :param vf_coef: value loss coefficient (per scale)
    :param max_grad_norm: gradient-norm clip of each network (actor, each critic)
    :param n_minibatches: minibatches per epoch when ``batch_size`` is ``None`` (blocks are split as evenly as possible)
    :param data_chunk_length: steps per recurrent training chunk (10)
    :param intrinsic_reward: ``"saeir"`` (default) adds a :class:`~sb3_saeir.intrinsic.SAEIRCallback`; ``"rnd"`` and
        ``"elign"`` the baselines' bonuses; ``None`` for no bonus (or pass your own
        :class:`~sb3_saeir.intrinsic.IntrinsicRewardCallback` to ``learn``)
    :param intrinsic_coef: beta, scale of the intrinsic reward; ``None``: the bonus's default (SAEIR 0.1, RND 0.5,
        Elign 1.0)
    :param intrinsic_kwargs: extra kwargs of the intrinsic-reward callback (e.g. ``variant="paper"``)
    :param normalize_values: ValueNorm per critic scale (spec §1.9)
    :param value_loss: ``"huber"`` (MAPPO) or ``"mse"``
    :param huber_delta: Huber delta (10)
    :param target_kl: stop an epoch's updates early when the approximate KL exceeds ``1.5 * target_kl``
    :param stats_window_size: episodes averaged for ``rollout/`` logging
    :param tensorboard_log: tensorboard log folder
    :param policy_kwargs: policy kwargs (``n_agents`` is set from the env)
    :param verbose: verbosity
    :param seed: random seed
    :param device: torch device
    :param _init_setup_model: build networks and buffer now
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MSHGPolicy": MSHGPolicy,
        "MlpPolicy": MSHGPolicy,
        "MAPPOPolicy": MAPPOPolicy,
        "SNMAPPOPolicy": SNMAPPOPolicy,
    }
    policy: MultiAgentActorCriticPolicy
    rollout_buffer: GroupedRecurrentRolloutBuffer

    def __init__(
        self,
        policy: str | type[MultiAgentActorCriticPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = 7e-4,
        n_steps: int = 25,
        batch_size: int | None = None,
        n_epochs: int = 10,
        gamma: float = 0.99,
        gae_lambda: float = 0.95,
        clip_range: float | Schedule = 0.2,
        clip_range_vf: float | Schedule | None = None,
        normalize_advantage: bool = True,
        ent_coef: float = 0.01,
        vf_coef: float = 1.0,
        max_grad_norm: float = 10.0,
        n_minibatches: int = 1,
        data_chunk_length: int = 10,
        intrinsic_reward: str | None = "saeir",
        intrinsic_coef: float | None = None,
        intrinsic_kwargs: dict[str, Any] | None = None,
        normalize_values: bool = True,
        value_loss: str = "huber",
        huber_delta: float = 10.0,
        target_kl: float | None = None,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "cpu",
        _init_setup_model: bool = True,
    ) -> None:
        with warnings.catch_warnings():  # PPO's batch-size warning does not apply: minibatches are whole blocks
            warnings.simplefilter("ignore", UserWarning)
            self._init_ppo(
                policy,
                env,
                learning_rate,
                n_steps,
                n_epochs,
                gamma,
                gae_lambda,
                clip_range,
                clip_range_vf,
                normalize_advantage,
                ent_coef,
                vf_coef,
                max_grad_norm,
                target_kl,
                stats_window_size,
                tensorboard_log,
                policy_kwargs,
                verbose,
                seed,
                device,
            )
        if intrinsic_reward is not None and intrinsic_reward not in INTRINSIC_REWARDS:
            raise ValueError(f"Unknown intrinsic_reward {intrinsic_reward!r}; choose one of {[*INTRINSIC_REWARDS, None]}.")
        if value_loss not in ("huber", "mse"):
            raise ValueError(f"value_loss must be 'huber' or 'mse', got {value_loss!r}.")
        if data_chunk_length < 1:
            raise ValueError(f"data_chunk_length must be >= 1, got {data_chunk_length}.")
        self.batch_size = batch_size  # type: ignore[assignment]
        self.n_minibatches = n_minibatches
        self.data_chunk_length = data_chunk_length
        self.intrinsic_reward = intrinsic_reward
        self.intrinsic_coef = intrinsic_coef
        self.intrinsic_kwargs = dict(intrinsic_kwargs or {})
        self.normalize_values = normalize_values
        self.value_loss = value_loss
        self.huber_delta = huber_delta
        self.n_agents: int | None = None
        self._last_states: MultiAgentStates | None = None
        if self.env is not None:
            self.n_agents = self._check_env(self.env)
            self.n_minibatches = self._resolve_minibatches()
        if _init_setup_model:
            self._setup_model()

    # ------------------------------------------------------------------------------------------------ setup
    def _init_ppo(
        self,
        policy: Any,
        env: Any,
        learning_rate: Any,
        n_steps: int,
        n_epochs: int,
        gamma: float,
        gae_lambda: float,
        clip_range: Any,
        clip_range_vf: Any,
        normalize_advantage: bool,
        ent_coef: float,
        vf_coef: float,
        max_grad_norm: float,
        target_kl: float | None,
        stats_window_size: int,
        tensorboard_log: str | None,
        policy_kwargs: dict[str, Any] | None,
        verbose: int,
        seed: int | None,
        device: th.device | str,
    ) -> None:
        super().__init__(
            policy,
            env,
            learning_rate=learning_rate,
            n_steps=n_steps,
            batch_size=2,  # placeholder for PPO's checks; minibatches are set by _resolve_minibatches
            n_epochs=n_epochs,
            gamma=gamma,
            gae_lambda=gae_lambda,
            clip_range=clip_range,
            clip_range_vf=clip_range_vf,
            normalize_advantage=normalize_advantage,
            ent_coef=ent_coef,
            vf_coef=vf_coef,
            max_grad_norm=max_grad_norm,
            target_kl=target_kl,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            _init_setup_model=False,
        )

    @staticmethod
    def _check_env(env: VecEnv) -> int:
        n_agents = getattr(env, "n_agents", None)
        if n_agents is None:
            raise ValueError(
                f"{type(env).__name__} does not say how many agents a game has (no `n_agents`). SAEIR_PPO needs the "
                "multi-agent vec env of sb3_saeir.make_multiagent_vec_env(task, n_games), whose slots are "
                "game * n_agents + agent."
            )
        if env.num_envs % n_agents != 0:
            raise ValueError(f"env.num_envs={env.num_envs} is not a multiple of n_agents={n_agents}.")
        return int(n_agents)

    def _resolve_minibatches(self) -> int:
        """Number of minibatches from ``batch_size`` (checked) or ``n_minibatches``."""
        assert self.n_agents is not None
        n_games = self.n_envs // self.n_agents
        n_blocks = n_games * -(-self.n_steps // self.data_chunk_length)
        if self.batch_size is None:
            if not 1 <= self.n_minibatches <= n_blocks:
                raise ValueError(
                    f"n_minibatches={self.n_minibatches} must be between 1 and the number of (game, chunk) blocks "
                    f"{n_blocks} (= {n_games} games x ceil(n_steps={self.n_steps} / data_chunk_length="
                    f"{self.data_chunk_length}))."
                )
            return self.n_minibatches
        valid = valid_batch_sizes(self.n_steps, n_games, self.n_agents, self.data_chunk_length)
        if self.batch_size not in valid:
            hint = f"valid batch sizes: {valid}"
            if self.n_steps % self.data_chunk_length != 0:
                hint += (
                    f" (n_steps={self.n_steps} is not a multiple of data_chunk_length={self.data_chunk_length}, so only "
                    "the whole rollout splits into equal whole blocks)"
                )
            raise ValueError(
                f"batch_size={self.batch_size} cannot be formed from whole (game, {self.data_chunk_length}-step chunk) "
                f"blocks of {self.n_agents} agents ({self.data_chunk_length * self.n_agents} agent-samples each) in a "
                f"rollout of {self.n_steps} steps x {n_games} games; {hint}. Or leave batch_size=None and set "
                "n_minibatches instead."
            )
        return self.n_steps * self.n_envs // self.batch_size

    def _setup_model(self) -> None:
        if self.n_agents is None:
            raise ValueError("SAEIR_PPO needs an env (make_multiagent_vec_env) or a loaded n_agents to build its model.")
        self._setup_lr_schedule()
        self.set_random_seed(self.seed)
        self.policy_kwargs = {**self.policy_kwargs, "n_agents": self.n_agents, "normalize_values": self.normalize_values}
        self.policy = self.policy_class(self.observation_space, self.action_space, self.lr_schedule, **self.policy_kwargs)  # type: ignore[assignment]
        if not isinstance(self.policy, MultiAgentActorCriticPolicy):
            raise ValueError(
                f"SAEIR_PPO needs a MultiAgentActorCriticPolicy (e.g. 'MSHGPolicy'), got {type(self.policy).__name__}."
            )
        self.policy = self.policy.to(self.device)
        self.rollout_buffer_class = GroupedRecurrentRolloutBuffer
        self.rollout_buffer = GroupedRecurrentRolloutBuffer(
            self.n_steps,
            self.observation_space,  # type: ignore[arg-type]
            self.action_space,
            device=self.device,
            gamma=self.gamma,
            gae_lambda=self.gae_lambda,
            n_envs=self.n_envs,
            n_agents=self.n_agents,
            n_scales=self.policy.n_scales,
            actor_hidden_size=self.policy.hidden_size if self.policy.recurrent_actor else 0,
            critic_hidden_size=self.policy.hidden_size,
            data_chunk_length=self.data_chunk_length,
        )
        self.rollout_buffer.value_denormalizer = self.policy.denormalize_values_numpy
        self.clip_range = _float_schedule(self.clip_range)
        if self.clip_range_vf is not None:
            self.clip_range_vf = _float_schedule(self.clip_range_vf)

    def _setup_learn(self, total_timesteps: int, callback: MaybeCallback = None, *args: Any, **kwargs: Any) -> Any:
        reset = kwargs.get("reset_num_timesteps", args[0] if args else True) or self._last_obs is None
        total_timesteps, callback = super()._setup_learn(total_timesteps, callback, *args, **kwargs)
        if reset or self._last_states is None:
            assert self.env is not None
            self._last_states = self.policy.initial_states(self.env.num_envs // self.policy.n_agents)
        return total_timesteps, callback

    def _init_callback(self, callback: MaybeCallback, progress_bar: bool = False) -> BaseCallback:
        """Add the intrinsic-reward callback and run intrinsic-reward callbacks first, so that the other callbacks
        see the final advantages at ``on_rollout_end``."""
        if callback is None:
            callbacks: list[BaseCallback] = []
        elif isinstance(callback, CallbackList):
            callbacks = list(callback.callbacks)
        elif isinstance(callback, list):
            callbacks = list(callback)
        else:
            callbacks = [callback]  # type: ignore[list-item]
        if self.intrinsic_reward is not None:
            bonus_class = INTRINSIC_REWARDS[self.intrinsic_reward]
            if not any(isinstance(c, bonus_class) for c in callbacks):
                coef = {} if self.intrinsic_coef is None else {"coef": self.intrinsic_coef}
                callbacks.append(bonus_class(**coef, **self.intrinsic_kwargs))  # type: ignore[arg-type]
        callbacks.sort(key=lambda c: not isinstance(c, IntrinsicRewardCallback))  # stable: keeps the user's order
        return super()._init_callback(callbacks, progress_bar)

    # ------------------------------------------------------------------------------------------------ rollout
    def collect_rollouts(  # type: ignore[override]
        self,
        env: VecEnv,
        callback: BaseCallback,
        rollout_buffer: GroupedRecurrentRolloutBuffer,
        n_rollout_steps: int,
    ) -> bool:
        """Collect ``n_rollout_steps`` steps of every game, storing GRU states and per-scale values."""
        assert self._last_obs is not None and self._last_states is not None
        self.policy.set_training_mode(False)
        n_steps = 0
        rollout_buffer.reset()
        callback.on_rollout_start()
        while n_steps < n_rollout_steps:
            with th.no_grad():
                obs_tensor = obs_as_tensor(self._last_obs, self.device)  # type: ignore[arg-type]
                episode_starts = th.as_tensor(self._last_episode_starts, dtype=th.float32, device=self.device)
                actions, values, log_probs, states = self.policy(obs_tensor, self._last_states, episode_starts)
            actions_np = actions.cpu().numpy()
            clipped_actions = actions_np
            if isinstance(self.action_space, spaces.Box):
                clipped_actions = np.clip(actions_np, self.action_space.low, self.action_space.high)
            new_obs, rewards, dones, infos = env.step(clipped_actions)
            self.num_timesteps += env.num_envs
            callback.update_locals(locals())
            if not callback.on_step():
                return False
            self._update_info_buffer(infos, dones)
            n_steps += 1
            if isinstance(self.action_space, spaces.Discrete):
                actions_np = actions_np.reshape(-1, 1)
            rollout_buffer.add(
                self._last_obs,  # type: ignore[arg-type]
                actions_np,
                rewards,
                self._last_episode_starts,  # type: ignore[arg-type]
                values,
                log_probs,
                actor_states=self._last_states.actor,
                critic_states=self._last_states.critic,
            )
            self._bootstrap_truncated(rollout_buffer, infos, dones, states)
            self._last_obs = new_obs  # type: ignore[assignment]
            self._last_episode_starts = dones
            self._last_states = states
        with th.no_grad():
            last_starts = th.as_tensor(dones, dtype=th.float32, device=self.device)
            values = self.policy.predict_values(obs_as_tensor(new_obs, self.device), self._last_states, last_starts)  # type: ignore[arg-type]
        rollout_buffer.compute_returns_and_advantage(last_values=values, dones=dones)
        callback.update_locals(locals())
        callback.on_rollout_end()
        return True

    def _bootstrap_truncated(
        self, buffer: GroupedRecurrentRolloutBuffer, infos: list[dict], dones: np.ndarray, states: MultiAgentStates
    ) -> None:
        """Where a game hit a time limit (``TimeLimit.truncated``, only set on request), add gamma * V(final obs) per
        scale to the step's reward, computed by the critics on the game's final observations."""
        truncated_slots = [i for i, info in enumerate(infos) if dones[i] and info.get("TimeLimit.truncated", False)]
        if not truncated_slots:
            return
        n_agents = self.policy.n_agents
        games = sorted({slot // n_agents for slot in truncated_slots})
        terminal_obs = np.stack(
            [infos[g * n_agents + a]["terminal_observation"] for g in games for a in range(n_agents)]
        )  # (len(games) * N, d)
        with th.no_grad():
            obs = th.as_tensor(terminal_obs, dtype=th.float32, device=self.device)
            critic_states = states.critic[:, games]  # (K, g, N, H)
            sub_states = MultiAgentStates(actor=states.actor[: len(games) * n_agents], critic=critic_states)
            normalized = self.policy.predict_values(obs, sub_states)  # (len(games) * N, K)
            values = self.policy.denormalize_values(normalized).cpu().numpy()
        slots = [g * n_agents + a for g in games for a in range(n_agents)]
        buffer.bootstrap_rewards[buffer.pos - 1, slots] += self.gamma * values

    # ------------------------------------------------------------------------------------------------ training
    def train(self) -> None:
        """PPO update on minibatches of whole-game chunks (spec §4.1)."""
        self.policy.set_training_mode(True)
        self._update_learning_rate(self.policy.optimizer)
        clip_range = self.clip_range(self._current_progress_remaining)  # type: ignore[operator]
        clip_range_vf = clip_range
        if self.clip_range_vf is not None:
            clip_range_vf = self.clip_range_vf(self._current_progress_remaining)  # type: ignore[operator]
        scales = self.policy.scales
        stats: dict[str, list[float]] = {
            key: []
            for key in (
                "pg_loss",
                "entropy_loss",
                "approx_kl",
                "clip_fraction",
                "loss",
                *tuple(f"value_loss_{s}" for s in scales),
                *tuple(f"advantage_weight_{s}" for s in scales),
            )
        }
        continue_training = True
        for _epoch in range(self.n_epochs):
            for samples in self.rollout_buffer.get(self.n_minibatches, self.normalize_advantage):
                continue_training = self._train_minibatch(samples, clip_range, clip_range_vf, stats)
                if not continue_training:
                    break
            self._n_updates += 1
            if not continue_training:
                if self.verbose >= 1:
                    print(f"Early stopping at epoch {_epoch} due to reaching max kl")
                break
        self._log_train(stats, clip_range, clip_range_vf)

    def _train_minibatch(
        self, samples: GroupedRecurrentSamples, clip_range: float, clip_range_vf: float, stats: dict[str, list[float]]
    ) -> bool:
        mask = samples.mask[:, :, None].expand_as(samples.old_log_prob).float()  # (L, B, N)
        n_valid = mask.sum()

        def masked_mean(x: th.Tensor) -> th.Tensor:
            return (x * mask).sum() / n_valid

        values, log_prob, entropy = self.policy.evaluate_actions(
            samples.observations, samples.actions, samples.actor_states, samples.critic_states, samples.episode_starts
        )
        advantages = samples.advantages  # (L, B, N, K)
        # (n_valid_rows, N, K) -> (n_valid_rows * N, K)
        weights = scale_advantage_weights(advantages[samples.mask].reshape(-1, self.policy.n_scales))  # (K,)
        mixed_advantages = (advantages * weights).sum(dim=-1)  # (L, B, N)

        # clipped surrogate objective
        ratio = th.exp(log_prob - samples.old_log_prob)
        policy_loss_1 = mixed_advantages * ratio
        policy_loss_2 = mixed_advantages * th.clamp(ratio, 1 - clip_range, 1 + clip_range)
        policy_loss = -masked_mean(th.min(policy_loss_1, policy_loss_2))
        entropy_loss = -masked_mean(entropy)

        # clipped value loss per scale on ValueNorm-normalised returns
        value_losses = []
        for k, scale in enumerate(self.policy.scales):
            returns = samples.returns[..., k]
            if self.normalize_values:
                value_norm = self.policy._value_norm(scale)
                value_norm.update(returns[samples.mask])
                returns = value_norm.normalize(returns)
            value_losses.append(
                self._value_loss(values[..., k], samples.old_values[..., k], returns, clip_range_vf, masked_mean)
            )
            stats[f"value_loss_{scale}"].append(value_losses[-1].item())
            stats[f"advantage_weight_{scale}"].append(weights[k].item())

        loss = policy_loss + self.ent_coef * entropy_loss + self.vf_coef * th.stack(value_losses).sum()
        with th.no_grad():
            log_ratio = log_prob - samples.old_log_prob
            approx_kl = masked_mean((th.exp(log_ratio) - 1) - log_ratio).item()
        stats["pg_loss"].append(policy_loss.item())
        stats["entropy_loss"].append(entropy_loss.item())
        stats["clip_fraction"].append(masked_mean((th.abs(ratio - 1) > clip_range).float()).item())
        stats["approx_kl"].append(approx_kl)
        stats["loss"].append(loss.item())
        if self.target_kl is not None and approx_kl > 1.5 * self.target_kl:
            return False

        self.policy.optimizer.zero_grad()
        loss.backward()
        # gradient-norm clipping per network (the networks share no parameters)
        th.nn.utils.clip_grad_norm_(self.policy.actor_parameters(), self.max_grad_norm)
        for scale in self.policy.scales:
            th.nn.utils.clip_grad_norm_(self.policy.critic_parameters(scale), self.max_grad_norm)
        self.policy.optimizer.step()
        return True

    def _value_loss(
        self, values: th.Tensor, old_values: th.Tensor, returns: th.Tensor, clip_range_vf: float, masked_mean: Any
    ) -> th.Tensor:
        """max(loss(R - v), loss(R - v_clipped)) with v_clipped = v_old + clamp(v - v_old, +-clip) (MAPPO)."""

        def point_loss(error: th.Tensor) -> th.Tensor:
            if self.value_loss == "huber":
                return F.huber_loss(error, th.zeros_like(error), reduction="none", delta=self.huber_delta)
            return 0.5 * error**2

        loss = point_loss(returns - values)
        if clip_range_vf is not None and clip_range_vf > 0:
            values_clipped = old_values + th.clamp(values - old_values, -clip_range_vf, clip_range_vf)
            loss = th.max(loss, point_loss(returns - values_clipped))
        return masked_mean(loss)

    def _log_train(self, stats: dict[str, list[float]], clip_range: float, clip_range_vf: float) -> None:
        buffer = self.rollout_buffer
        values = buffer.value_denormalizer(buffer.values)
        for k, scale in enumerate(self.policy.scales):
            self.logger.record(f"train/value_loss_{scale}", float(np.mean(stats[f"value_loss_{scale}"])))
            self.logger.record(f"train/advantage_weight_{scale}", float(np.mean(stats[f"advantage_weight_{scale}"])))
            self.logger.record(
                f"train/explained_variance_{scale}",
                float(explained_variance(values[..., k].ravel(), buffer.returns[..., k].ravel())),
            )
        self.logger.record("train/value_loss", float(sum(np.mean(stats[f"value_loss_{s}"]) for s in self.policy.scales)))
        self.logger.record("train/entropy_loss", float(np.mean(stats["entropy_loss"])))
        self.logger.record("train/policy_gradient_loss", float(np.mean(stats["pg_loss"])))
        self.logger.record("train/approx_kl", float(np.mean(stats["approx_kl"])))
        self.logger.record("train/clip_fraction", float(np.mean(stats["clip_fraction"])))
        self.logger.record("train/loss", float(stats["loss"][-1]))
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/clip_range", clip_range)
        self.logger.record("train/clip_range_vf", clip_range_vf)

    def dump_logs(self, iteration: int = 0) -> None:
        """SB3's logs plus the task metrics of the finished games (``rollout/coverage_rate``, ...)."""
        for name, value in episode_metric_means(list(self.ep_info_buffer or [])).items():
            self.logger.record(f"rollout/{name}", value)
        super().dump_logs(iteration)

    def learn(  # type: ignore[override]
        self: SelfSAEIR_PPO,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = 1,
        tb_log_name: str = "SAEIR_PPO",
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfSAEIR_PPO:
        return super().learn(
            total_timesteps=total_timesteps,
            callback=callback,
            log_interval=log_interval,
            tb_log_name=tb_log_name,
            reset_num_timesteps=reset_num_timesteps,
            progress_bar=progress_bar,
        )

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "_last_states"]

    def set_env(self, env: GymEnv, force_reset: bool = True) -> None:
        n_agents = self._check_env(env if isinstance(env, VecEnv) else self._wrap_env(env, self.verbose))  # type: ignore[arg-type]
        if self.n_agents is not None and n_agents != self.n_agents:
            raise ValueError(f"The model was built for {self.n_agents} agents per game, the env has {n_agents}.")
        super().set_env(env, force_reset)
        self._last_states = None


def _float_schedule(value: float | Schedule) -> Schedule:
    from stable_baselines3.common.utils import FloatSchedule

    return FloatSchedule(value)
