"""MAPPO: recurrent multi-agent PPO with centralised critics over each game's agents, and pluggable intrinsic rewards.

This module holds the machinery every method of the package shares (rollout of whole games, per-scale GAE, the
chunked recurrent PPO update); :class:`~sb3_saeir.SAEIR_PPO` is MAPPO with SAEIR's critic and bonus as defaults.
"""

from __future__ import annotations

import io
import os
import pathlib
from collections.abc import Iterable
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule
from stable_baselines3.common.utils import FloatSchedule, explained_variance, obs_as_tensor
from stable_baselines3.common.vec_env import VecEnv

from sb3_saeir.common import checks, method_arguments, saved_model_checks
from sb3_saeir.common.atomic import save_zip
from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer, split_by_valid_length, valid_rows
from sb3_saeir.common.callbacks import episode_metric_means, flatten_callbacks
from sb3_saeir.common.compilation import resolve_compile_backend
from sb3_saeir.common.policies import MAPPOPolicy, MSHGPolicy, MultiAgentActorCriticPolicy, SNMAPPOPolicy
from sb3_saeir.common.sampling import RolloutCollector, use_double_buffering
from sb3_saeir.common.type_aliases import MultiAgentStates
from sb3_saeir.common.utils import PACKAGE_VERSION, check_bool, check_seed
from sb3_saeir.intrinsic.base import IntrinsicRewardCallback  # importing sb3_saeir.intrinsic registers its bonuses
from sb3_saeir.mappo.losses import actor_losses, critic_loss, scale_advantage_weights

SelfMAPPO = TypeVar("SelfMAPPO", bound="MAPPO")


class MAPPO(OnPolicyAlgorithm):
    """Recurrent MAPPO (Yu et al., "The Surprising Effectiveness of PPO in Cooperative Multi-Agent Games", NeurIPS
    2022 D&B; code: https://github.com/marlbenchmark/on-policy), with critics over each game's agents and pluggable
    intrinsic rewards. The machinery of every method in the package; the differences are the policy and the bonus:

    - MAPPO: ``MAPPO("MAPPOPolicy", env)``
    - SN-MAPPO: ``MAPPO("SNMAPPOPolicy", env)`` (spectral norm on the critic's output layer)
    - RND / Elign: ``MAPPO("MAPPOPolicy", env, intrinsic_reward="rnd")`` (or ``learn(n, callback=RNDCallback())``)
    - MSHG-only ablation: ``MAPPO("MSHGPolicy", env)``
    - SAE-only ablation: ``MAPPO("MAPPOPolicy", env, intrinsic_reward="saeir")``
    - SAEIR: :class:`~sb3_saeir.SAEIR_PPO` (``"MSHGPolicy"`` and ``intrinsic_reward="saeir"`` by default)

    A drop-in for SB3's :class:`~stable_baselines3.PPO` on a multi-agent vec env from
    :func:`~sb3_saeir.make_multiagent_vec_env` (one slot per agent, parameter sharing). Differences from PPO: the
    buffer keeps games whole; the actor and every critic are GRUs trained on chunks of ``data_chunk_length`` steps from
    the stored states; each critic scale K has its own ValueNorm, GAE (with its own intrinsic reward) and clipped Huber
    value loss; the actor uses the W_K-mixed standardised advantages; gradients are clipped per network. Time limits
    count as terminal unless the env marks truncation.

    Order of one rollout (``docs/method.md``, "One rollout"): collect ``n_steps`` steps of every game; compute the
    bootstrap values; every intrinsic reward (added from ``intrinsic_reward`` or passed to ``learn``) writes
    ``coef * compute_bonus(buffer)`` into the buffer; GAE runs once; then the callbacks' ``on_rollout_end``.

    :param policy: ``"MAPPOPolicy"`` (``"MlpPolicy"``), ``"SNMAPPOPolicy"``, ``"MSHGPolicy"`` or a
        :class:`~sb3_saeir.common.policies.MultiAgentActorCriticPolicy` subclass
    :param env: a multi-agent vec env (:func:`~sb3_saeir.make_multiagent_vec_env`); it must expose ``n_agents``
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
    :param use_sde: must be ``False``: generalized State-Dependent Exploration is not supported (SB3's ``PPO``
        argument, taken so that PPO hyperparameters that set it off still apply)
    :param sde_sample_freq: with ``use_sde=False`` it has no effect (SB3's ``PPO`` argument)
    :param n_minibatches: minibatches per epoch when ``batch_size`` is ``None`` (blocks are split as evenly as possible)
    :param data_chunk_length: steps per recurrent training chunk (10); longer than ``n_steps`` it warns (the padding
        only costs compute)
    :param intrinsic_reward: ``None`` (default) for no bonus; ``"saeir"``, ``"rnd"`` or ``"elign"`` adds that
        :class:`~sb3_saeir.intrinsic.IntrinsicRewardCallback` (or pass your own callback to ``learn``)
    :param intrinsic_coef: beta, scale of the intrinsic reward; ``None``: the bonus's default (SAEIR 0.1, RND 0.5,
        Elign 1.0)
    :param intrinsic_kwargs: extra kwargs of the intrinsic-reward callback (e.g. ``variant="paper"``)
    :param normalize_values: ValueNorm per critic scale (``docs/method.md``, "Value normalisation")
    :param value_loss: ``"huber"`` (MAPPO) or ``"mse"``
    :param huber_delta: Huber delta (10)
    :param target_kl: stop an epoch's updates early when the approximate KL exceeds ``1.5 * target_kl``
    :param double_buffered: double-buffered sampling (:mod:`sb3_saeir.common.sampling`): with the games in worker
        processes (``num_cpus >= 2``), each worker's games step while the policy acts for another's. ``"auto"``
        (default): on whenever the env allows it (games in two or more workers, no wrapper that changes steps);
        ``True``: on, an error if the env does not allow it; ``False``: the synchronous loop. Same maths; the random
        draws are made group by group (same seed, same run; ``docs/guide/performance.md``)
    :param compile: run the forward of the actor and of every critic through ``torch.compile`` (rollout, ``predict``
        and the update, whose backward is compiled with it): ``True`` for the inductor backend, or a backend name.
        Where no C++ compiler is found, one warning line says so and the networks run eagerly. Not saved with the
        model (a setting of the machine, as ``device``: ``load(path, compile=True)`` compiles a loaded model). The same
        maths up to float rounding; ``docs/guide/performance.md``, "Compiled networks", has when it pays
    :param rollout_buffer_class: rollout buffer class (a
        :class:`~sb3_saeir.common.buffers.GroupedRecurrentRolloutBuffer` subclass; default that class)
    :param rollout_buffer_kwargs: extra keyword arguments of the rollout buffer
    :param stats_window_size: episodes averaged for ``rollout/`` logging
    :param tensorboard_log: tensorboard log folder
    :param policy_kwargs: policy kwargs (``n_agents`` is set from the env)
    :param verbose: verbosity
    :param seed: random seed
    :param device: torch device (``"cpu"`` is fastest for these small networks; ``"cuda"`` works)
    :param _init_setup_model: build networks and buffer now
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MlpPolicy": MAPPOPolicy,
        "MAPPOPolicy": MAPPOPolicy,
        "SNMAPPOPolicy": SNMAPPOPolicy,
        "MSHGPolicy": MSHGPolicy,
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
        use_sde: bool = False,
        sde_sample_freq: int = -1,
        n_minibatches: int = 1,
        data_chunk_length: int = 10,
        intrinsic_reward: str | None = None,
        intrinsic_coef: float | None = None,
        intrinsic_kwargs: dict[str, Any] | None = None,
        normalize_values: bool = True,
        value_loss: str = "huber",
        huber_delta: float = 10.0,
        target_kl: float | None = None,
        double_buffered: bool | str = "auto",
        compile: bool | str = False,
        rollout_buffer_class: type[GroupedRecurrentRolloutBuffer] | None = None,
        rollout_buffer_kwargs: dict[str, Any] | None = None,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "cpu",
        _init_setup_model: bool = True,
    ) -> None:
        # the callback of the intrinsic reward is built once, here: learn() adds it (docs/guide/algorithms.md)
        self._bonus, seed = checks.check_mappo_arguments(
            type(self).__name__,
            env=env,
            learning_rate=learning_rate,
            n_steps=n_steps,
            n_epochs=n_epochs,
            gamma=gamma,
            gae_lambda=gae_lambda,
            clip_range=clip_range,
            clip_range_vf=clip_range_vf,
            normalize_advantage=normalize_advantage,
            ent_coef=ent_coef,
            vf_coef=vf_coef,
            max_grad_norm=max_grad_norm,
            use_sde=use_sde,
            n_minibatches=n_minibatches,
            data_chunk_length=data_chunk_length,
            intrinsic_reward=intrinsic_reward,
            intrinsic_coef=intrinsic_coef,
            intrinsic_kwargs=intrinsic_kwargs,
            normalize_values=normalize_values,
            value_loss=value_loss,
            huber_delta=huber_delta,
            target_kl=target_kl,
            double_buffered=double_buffered,
            compile=compile,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
        )
        super().__init__(
            policy,
            env,  # type: ignore[arg-type]
            learning_rate=learning_rate,
            n_steps=n_steps,
            gamma=gamma,
            gae_lambda=gae_lambda,
            ent_coef=ent_coef,
            vf_coef=vf_coef,
            max_grad_norm=max_grad_norm,
            use_sde=use_sde,
            sde_sample_freq=sde_sample_freq,
            rollout_buffer_class=rollout_buffer_class,
            rollout_buffer_kwargs=rollout_buffer_kwargs,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            _init_setup_model=False,
            supported_action_spaces=(spaces.Box, spaces.Discrete, spaces.MultiDiscrete, spaces.MultiBinary),
        )
        self.batch_size = batch_size
        self.n_epochs = n_epochs
        self.clip_range = clip_range
        self.clip_range_vf = clip_range_vf
        self.normalize_advantage = normalize_advantage
        self.target_kl = target_kl
        self.double_buffered = double_buffered
        self.compile = compile
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
        self._intrinsic_rewards: list[IntrinsicRewardCallback] = []
        if self.env is not None:
            self.n_agents = checks.check_n_agents(type(self).__name__, self.env)
            self.n_minibatches = self._resolve_minibatches()
        if _init_setup_model:
            self._setup_model()

    # ------------------------------------------------------------------------------------------------ setup
    def _resolve_minibatches(self) -> int:
        """Number of minibatches from ``batch_size`` (checked) or ``n_minibatches``."""
        assert self.n_agents is not None
        n_games = self.n_envs // self.n_agents
        return checks.resolve_minibatches(
            self.n_steps, n_games, self.n_agents, self.data_chunk_length, self.batch_size, self.n_minibatches
        )

    def _setup_model(self) -> None:
        if self.n_agents is None:
            raise ValueError(f"{type(self).__name__} needs an env (make_multiagent_vec_env) or a loaded n_agents.")
        if self.env is not None:  # load(path, env) of a model onto games of another size
            checks.check_n_agents(type(self).__name__, self.env, self.n_agents)
            use_double_buffering(type(self).__name__, self.double_buffered, self.env)  # refused here, not at a rollout
        self._setup_lr_schedule()
        self.set_random_seed(self.seed)
        self.policy_kwargs = {**self.policy_kwargs, "n_agents": self.n_agents, "normalize_values": self.normalize_values}
        policy_class = checks.check_policy_class(type(self).__name__, self.policy_class, self.policy_aliases)
        self.policy = policy_class(self.observation_space, self.action_space, self.lr_schedule, **self.policy_kwargs)
        self.policy = self.policy.to(self.device)
        self.policy.set_compile(resolve_compile_backend(type(self).__name__, self.compile, self.device))
        if self.rollout_buffer_class is None:
            self.rollout_buffer_class = GroupedRecurrentRolloutBuffer
        buffer_class = checks.check_rollout_buffer_class(self.rollout_buffer_class)
        self.rollout_buffer = buffer_class(
            self.n_steps,
            self.observation_space,  # type: ignore[arg-type]
            self.action_space,
            device=self.device,
            gamma=self.gamma,
            gae_lambda=self.gae_lambda,
            n_envs=self.n_envs,
            n_agents=self.n_agents,
            n_scales=self.policy.n_scales,
            actor_hidden_size=self.policy.actor_state_size,
            critic_hidden_size=self.policy.critic_state_size,
            data_chunk_length=self.data_chunk_length,
            **self.rollout_buffer_kwargs,
        )
        self.clip_range = FloatSchedule(self.clip_range)
        if self.clip_range_vf is not None:
            self.clip_range_vf = FloatSchedule(self.clip_range_vf)

    def _setup_learn(
        self,
        total_timesteps: int,
        callback: MaybeCallback = None,
        reset_num_timesteps: bool = True,
        tb_log_name: str = "run",
        progress_bar: bool = False,
    ) -> tuple[int, BaseCallback]:
        reset = reset_num_timesteps or self._last_obs is None
        total_timesteps, callback = super()._setup_learn(
            total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar
        )
        # Fresh GRU states whenever the env is (re)started: a new learn() or an env set with set_env.
        if reset or self._last_states is None:
            assert self.env is not None
            self._last_states = self.policy.initial_states(self.env.num_envs // self.policy.n_agents)
        return total_timesteps, callback

    def _init_callback(self, callback: MaybeCallback, progress_bar: bool = False) -> BaseCallback:
        """Add the intrinsic reward named by ``intrinsic_reward`` (unless the user passed one of its class) and
        remember every intrinsic-reward callback: :meth:`collect_rollouts` asks them for their bonus before GAE."""
        callbacks = flatten_callbacks(callback)
        if self._bonus is None and self.intrinsic_reward is not None:  # a loaded model: built at its first learn()
            bonus = (self.intrinsic_reward, self.intrinsic_coef, self.intrinsic_kwargs or {})
            self._bonus = checks.build_intrinsic_reward(type(self).__name__, *bonus)
        if self._bonus is not None and not any(isinstance(c, type(self._bonus)) for c in callbacks):
            callbacks.append(self._bonus)
        self._intrinsic_rewards = [c for c in callbacks if isinstance(c, IntrinsicRewardCallback)]
        return super()._init_callback(callbacks, progress_bar)

    # ------------------------------------------------------------------------------------------------ rollout
    def collect_rollouts(
        self,
        env: VecEnv,
        callback: BaseCallback,
        rollout_buffer: RolloutBuffer,
        n_rollout_steps: int,
    ) -> bool:
        """Collect ``n_rollout_steps`` steps of every game (GRU states and per-scale values stored), then the
        bootstrap values, the intrinsic rewards and one GAE pass, in that order.

        The steps come from :class:`~sb3_saeir.common.sampling.RolloutCollector`: with ``double_buffered`` on, the
        worker processes' groups of games step on their own while the policy acts for the group that came back first;
        the buffer is filled as by the synchronous loop."""
        assert isinstance(rollout_buffer, GroupedRecurrentRolloutBuffer)
        assert self._last_obs is not None and self._last_states is not None
        self.policy.set_training_mode(False)
        rollout_buffer.reset()
        callback.on_rollout_start()
        collector = RolloutCollector(self, env, callback, rollout_buffer, n_rollout_steps)
        if not collector.collect(use_double_buffering(type(self).__name__, self.double_buffered, env)):
            return False
        new_obs, dones = self._last_obs, self._last_episode_starts
        assert new_obs is not None and dones is not None
        with th.no_grad():
            last_starts = th.as_tensor(dones, dtype=th.float32, device=self.device)
            last_values = self.policy.predict_values(obs_as_tensor(new_obs, self.device), self._last_states, last_starts)  # type: ignore[arg-type]
        # the bootstrap, and the rollout's values in return space (the ValueNorm changes only in train), once
        rollout_buffer.set_last_step(last_values, dones, self.policy.denormalize_values_numpy)  # type: ignore[arg-type]
        for intrinsic_reward in self._intrinsic_rewards:
            intrinsic_reward.add_to(rollout_buffer)
        rollout_buffer.compute_returns_and_advantage()
        callback.update_locals(locals())
        callback.on_rollout_end()
        return True

    # ------------------------------------------------------------------------------------------------ training
    def train(self) -> None:
        """PPO update on minibatches of whole-game chunks (``docs/method.md``, "The update"); one flat loop, to be
        read next to SB3's ``PPO.train``."""
        self.policy.set_training_mode(True)
        self._update_learning_rate(self.policy.optimizer)
        clip_range = self.clip_range(self._current_progress_remaining)  # type: ignore[operator]
        clip_range_vf = clip_range
        if self.clip_range_vf is not None:
            clip_range_vf = self.clip_range_vf(self._current_progress_remaining)  # type: ignore[operator]
        scales = self.policy.scales
        pg_losses, entropy_losses, clip_fractions, approx_kl_divs = [], [], [], []
        value_losses: dict[str, list[float]] = {scale: [] for scale in scales}
        advantage_weights: dict[str, list[float]] = {scale: [] for scale in scales}
        loss_value = 0.0
        continue_training = True
        # each network's parameters, listed once (the gradient norms are clipped per network at every minibatch)
        network_parameters = [self.policy.actor_parameters()] + [self.policy.critic_parameters(scale) for scale in scales]
        for epoch in range(self.n_epochs):
            for samples in self.rollout_buffer.get(self.n_minibatches, self.normalize_advantage):
                # the networks run on the blocks grouped by valid length (feed-forward networks: on all valid rows at
                # once): no padded row is computed
                groups = [valid_rows(samples)] if self.policy.feed_forward else split_by_valid_length(samples)
                n_valid = samples.mask.sum() * self.policy.n_agents  # valid (step, block, agent) rows
                # W_K-mixed advantages: the weights from the valid rows (n_valid_rows * N, K) -> (K,)
                weights = scale_advantage_weights(samples.advantages[samples.mask].reshape(-1, self.policy.n_scales))

                policy_loss, entropy_loss, clip_fraction, approx_kl_div = actor_losses(
                    self.policy, groups, weights, n_valid, clip_range
                )
                pg_losses.append(policy_loss.item())
                clip_fractions.append(clip_fraction)
                entropy_losses.append(entropy_loss.item())
                approx_kl_divs.append(approx_kl_div)
                if self.target_kl is not None and approx_kl_div > 1.5 * self.target_kl:
                    continue_training = False
                    if self.verbose >= 1:
                        print(f"Early stopping at step {epoch} due to reaching max kl: {approx_kl_div:.2f}")
                    break

                # Back-propagate one network at a time: the networks share no parameters, so each one's gradient is
                # that of the whole loss, and only one network's activations are alive at once.
                self.policy.optimizer.zero_grad()
                actor_loss = policy_loss + self.ent_coef * entropy_loss
                actor_loss.backward()
                loss_value = actor_loss.item()
                for k, scale in enumerate(scales):
                    scale_loss = critic_loss(
                        self.policy, k, samples, groups, n_valid, clip_range_vf,
                        self.normalize_values, self.value_loss, self.huber_delta,
                    )  # fmt: skip
                    (self.vf_coef * scale_loss).backward()
                    value_losses[scale].append(scale_loss.item())
                    advantage_weights[scale].append(weights[k].item())
                    loss_value += self.vf_coef * value_losses[scale][-1]

                # optimisation step; gradient norms clipped per network
                for parameters in network_parameters:
                    th.nn.utils.clip_grad_norm_(parameters, self.max_grad_norm)
                self.policy.optimizer.step()
            self._n_updates += 1
            if not continue_training:
                break

        values, returns = self.rollout_buffer.denormalized_values, self.rollout_buffer.returns  # (T, E, K), as GAE used
        for k, scale in enumerate(scales):
            self.logger.record(f"train/value_loss_{scale}", float(np.mean(value_losses[scale])))
            self.logger.record(f"train/advantage_weight_{scale}", float(np.mean(advantage_weights[scale])))
            explained = explained_variance(values[..., k].ravel(), returns[..., k].ravel())
            self.logger.record(f"train/explained_variance_{scale}", float(explained))
        # SB3's key: every scale's values against its returns, pooled (one critic: its own explained variance)
        self.logger.record("train/explained_variance", float(explained_variance(values.ravel(), returns.ravel())))
        self.logger.record("train/value_loss", float(sum(np.mean(value_losses[scale]) for scale in scales)))
        self.logger.record("train/entropy_loss", float(np.mean(entropy_losses)))
        self.logger.record("train/policy_gradient_loss", float(np.mean(pg_losses)))
        self.logger.record("train/approx_kl", float(np.mean(approx_kl_divs)))
        self.logger.record("train/clip_fraction", float(np.mean(clip_fractions)))
        self.logger.record("train/loss", loss_value)
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/clip_range", clip_range)
        self.logger.record("train/clip_range_vf", clip_range_vf)

    # ------------------------------------------------------------------------------------------------ SB3 API
    def dump_logs(self, iteration: int = 0) -> None:
        """SB3's logs plus the task metrics of the finished games (``rollout/coverage_rate``, ...)."""
        for name, value in episode_metric_means(list(self.ep_info_buffer or [])).items():
            self.logger.record(f"rollout/{name}", value)
        super().dump_logs(iteration)

    def learn(
        self: SelfMAPPO,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = 1,
        tb_log_name: str = "MAPPO",
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfMAPPO:
        total_timesteps = method_arguments.check_learn_arguments(
            type(self).__name__,
            self.env,
            total_timesteps,
            callback,
            log_interval,
            tb_log_name,
            reset_num_timesteps,
            progress_bar,
        )
        return super().learn(
            total_timesteps=total_timesteps,
            callback=callback,
            log_interval=log_interval,
            tb_log_name=tb_log_name,
            reset_num_timesteps=reset_num_timesteps,
            progress_bar=progress_bar,
        )

    @classmethod
    def load(  # type: ignore[override]
        cls: type[SelfMAPPO],
        path: str | pathlib.Path | io.BufferedIOBase,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        **kwargs: Any,
    ) -> SelfMAPPO:
        """SB3's ``load``, with the constructor's checks on overrides (``kwargs`` and ``custom_objects``; ``compile``
        is a keyword argument, not a custom object), the env's ``n_agents`` checked against the model's (as
        :meth:`set_env`, before SB3 compares the spaces), and one line for a path where there is no file or a folder,
        a model of another library (:func:`~sb3_saeir.common.method_arguments.check_load`), a file that is not a
        complete model zip, or ``custom_objects`` ``policy_kwargs`` that build a network the saved parameters do not fit
        (recurrent against feed-forward, other sizes: :func:`~sb3_saeir.common.saved_model_checks.model_zip_errors`).
        A model saved by another sb3-saeir version (``save`` records it) loads with a one-line warning naming both
        versions."""
        name = cls.__name__
        kwargs, data = method_arguments.check_load(name, path, env, device, custom_objects, kwargs)
        with saved_model_checks.model_zip_errors(name, path, custom_objects):
            model = super().load(path, env, device, custom_objects, print_system_info, force_reset, **kwargs)
        model._apply_overrides({**(custom_objects or {}), **kwargs})
        saved_model_checks.warn_other_version(name, path, data)
        return model

    def _apply_overrides(self, overrides: dict[str, Any]) -> None:
        """After :meth:`load`, the constructor's checks that need the loaded model: the minibatch split again for a
        ``batch_size``, ``n_minibatches``, ``n_steps`` or ``data_chunk_length`` override (SB3 sets the attribute
        only, so ``batch_size`` was ignored) and for an env given to ``load`` (its number of games sets the rollout
        that ``batch_size`` splits), and an intrinsic-reward override against the saved settings.

        :param overrides: the ``custom_objects`` and keyword arguments given to ``load``
        """
        resplit = checks.MINIBATCH_ARGUMENTS & set(overrides) or self.env is not None
        if resplit and self.n_agents is not None:
            if "n_minibatches" in overrides and "batch_size" not in overrides:
                self.batch_size = None  # as in the constructor: n_minibatches decides when batch_size is None
            self.n_minibatches = self._resolve_minibatches()
        self._bonus = None  # the constructor's, of the class defaults: the saved settings' is built at learn()
        if checks.INTRINSIC_ARGUMENTS & set(overrides):
            bonus = (self.intrinsic_reward, self.intrinsic_coef, self.intrinsic_kwargs)
            self._bonus = checks.check_intrinsic_reward(type(self).__name__, *bonus)
            self.intrinsic_kwargs = dict(self.intrinsic_kwargs or {})

    def set_parameters(
        self,
        load_path_or_dict: str | pathlib.Path | io.BufferedIOBase | dict[str, Any],
        exact_match: bool = True,
        device: th.device | str = "auto",
    ) -> None:
        """SB3's ``set_parameters``; with ``exact_match``, the parameters of a recurrent network given to a
        feed-forward model (or the reverse) are refused in one line before any is set (torch's ``load_state_dict``
        error listed every GRU key), and so are parameters with entries missing or unknown to the model (torch set the
        others first) and, with any ``exact_match``, of another shape
        (:func:`~sb3_saeir.common.method_arguments.check_parameters`).

        :param load_path_or_dict: a model zip (path or file object), or a dict of state dicts as ``get_parameters``
            returns it
        :param exact_match: every module and parameter must be given (SB3's meaning); ``False``: missing and
            unexpected keys are skipped (torch's ``strict=False``), and the kinds of network are not compared
        :param device: device the parameters are loaded onto
        """
        owner = f"{type(self).__name__}.set_parameters"
        check_bool(owner, exact_match=exact_match)
        if isinstance(load_path_or_dict, dict):
            params = load_path_or_dict
        else:
            method_arguments.check_parameters_file(owner, load_path_or_dict)
            _, params, _ = load_from_zip_file(load_path_or_dict, device=device, load_data=False)
        method_arguments.check_parameters(owner, params, self, exact_match)
        super().set_parameters(params, exact_match=exact_match, device=device)

    def set_random_seed(self, seed: int | None = None) -> None:
        """SB3's ``set_random_seed``, also for NumPy integers; a bad seed is one line naming ``seed``.

        :param seed: the seed (0 .. 2**32 - 1), or ``None``
        """
        super().set_random_seed(check_seed(type(self).__name__, seed))

    def save(
        self,
        path: str | pathlib.Path | io.BufferedIOBase,
        exclude: Iterable[str] | None = None,
        include: Iterable[str] | None = None,
    ) -> None:
        """SB3's ``save``, atomic for a path: the zip is written to a temporary file in the same folder and moved onto
        the path when complete (:func:`~sb3_saeir.common.atomic.save_zip`), so Ctrl-C, a kill or a full disk during
        the save leaves the file that was there whole. SB3's path rules are kept (``.zip`` added to a path without
        suffix); a file object is written to directly, as by SB3. A path that cannot be written is refused first, in
        one line (:func:`~sb3_saeir.common.checks.check_save_path`).

        :param path: path to the file where the model should be saved, or a binary file object
        :param exclude: name of parameters that should be excluded in addition to the default ones
        :param include: name of parameters that might be excluded but should be included anyway
        """
        checks.check_save_path(type(self).__name__, path)
        self.sb3_saeir_version = PACKAGE_VERSION  # saved with the model's data; load names another version
        if isinstance(path, (str, os.PathLike)):
            save_zip(path, lambda file: super(MAPPO, self).save(file, exclude=exclude, include=include))
        else:
            super().save(path, exclude=exclude, include=include)

    def _excluded_save_params(self) -> list[str]:
        # compile is a setting of the machine, as device: a model saved compiled loads eager unless load(compile=True)
        return [*super()._excluded_save_params(), "_last_states", "_intrinsic_rewards", "_bonus", "compile"]

    def set_env(self, env: GymEnv, force_reset: bool = True) -> None:
        if env is None:
            raise ValueError(f"{type(self).__name__}.set_env: env=None; pass a multi-agent vec env (make_multiagent_vec_env).")
        checks.check_env_argument(f"{type(self).__name__}.set_env", env)
        vec_env = env if isinstance(env, VecEnv) else self._wrap_env(env, self.verbose)  # type: ignore[arg-type]
        checks.check_n_agents(type(self).__name__, vec_env, self.n_agents)
        super().set_env(env, force_reset)
        self._last_states = None
