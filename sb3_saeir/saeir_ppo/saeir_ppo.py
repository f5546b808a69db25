"""SAEIR_PPO: MAPPO with SAEIR's multi-scale hypergraph critic and sequentially accumulated entropy reward."""

from __future__ import annotations

from typing import Any, ClassVar, TypeVar

import torch as th
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule

from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer
from sb3_saeir.common.policies import MAPPOPolicy, MSHGPolicy, MultiAgentActorCriticPolicy, SNMAPPOPolicy
from sb3_saeir.mappo.mappo import MAPPO

SelfSAEIR_PPO = TypeVar("SelfSAEIR_PPO", bound="SAEIR_PPO")


class SAEIR_PPO(MAPPO):
    """Recurrent multi-agent PPO with SAEIR (IJCAI-24): multi-scale hypergraph critics + entropy intrinsic reward.

    Paper: He, Ge, Hou, Yu, "SAEIR: Sequentially Accumulated Entropy Intrinsic Reward for Cooperative Multi-Agent
    Reinforcement Learning with Sparse Reward", IJCAI 2024. Code: https://github.com/yvjc/SAEIR (authors'),
    behaviour as specified in ``docs/method.md``.

    SAEIR is a special case of recurrent MAPPO (as SB3 treats DDPG as a special case of TD3): :class:`~sb3_saeir.MAPPO`
    with ``"MSHGPolicy"`` (three hypergraph critics: team, group, individual) as ``"MlpPolicy"`` and
    ``intrinsic_reward="saeir"`` by default. A drop-in for SB3's :class:`~stable_baselines3.PPO` on a multi-agent
    vec env from :func:`~sb3_saeir.make_multiagent_vec_env`::

        model = SAEIR_PPO("MSHGPolicy", make_multiagent_vec_env("cn-sparse-n3", n_games=16, seed=0)).learn(500_000)

    Every argument is :class:`~sb3_saeir.MAPPO`'s; only the defaults of ``policy`` aliases and ``intrinsic_reward``
    differ.

    :param policy: ``"MSHGPolicy"`` (``"MlpPolicy"``; SAEIR's critic), ``"MAPPOPolicy"``, ``"SNMAPPOPolicy"`` or a
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
    :param use_sde: must be ``False`` (generalized State-Dependent Exploration is not supported; SB3's ``PPO`` argument)
    :param sde_sample_freq: no effect with ``use_sde=False`` (SB3's ``PPO`` argument)
    :param n_minibatches: minibatches per epoch when ``batch_size`` is ``None`` (blocks are split as evenly as possible)
    :param data_chunk_length: steps per recurrent training chunk (10)
    :param intrinsic_reward: ``"saeir"`` (default) adds a :class:`~sb3_saeir.intrinsic.SAEIRCallback`; ``"rnd"`` and
        ``"elign"`` the baselines' bonuses; ``None`` for no bonus (or pass your own
        :class:`~sb3_saeir.intrinsic.IntrinsicRewardCallback` to ``learn``)
    :param intrinsic_coef: beta, scale of the intrinsic reward; ``None``: the bonus's default (SAEIR 0.1, RND 0.5,
        Elign 1.0)
    :param intrinsic_kwargs: extra kwargs of the intrinsic-reward callback (e.g. ``variant="paper"``)
    :param normalize_values: ValueNorm per critic scale (``docs/method.md``, "Value normalisation")
    :param value_loss: ``"huber"`` (MAPPO) or ``"mse"``
    :param huber_delta: Huber delta (10)
    :param target_kl: stop an epoch's updates early when the approximate KL exceeds ``1.5 * target_kl``
    :param double_buffered: double-buffered sampling with the games in worker processes (``True``, ``False`` or
        ``"auto"``: on whenever the env allows it); see :class:`~sb3_saeir.MAPPO`
    :param compile: ``torch.compile`` of the actor's and the critics' forward (``True``: inductor, or a backend name;
        eager with one warning line where no C++ compiler is found; not saved); see :class:`~sb3_saeir.MAPPO`
    :param rollout_buffer_class: rollout buffer class (default
        :class:`~sb3_saeir.common.buffers.GroupedRecurrentRolloutBuffer`)
    :param rollout_buffer_kwargs: extra keyword arguments of the rollout buffer
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
        intrinsic_reward: str | None = "saeir",
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
        super().__init__(
            policy,
            env,
            learning_rate=learning_rate,
            n_steps=n_steps,
            batch_size=batch_size,
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
            sde_sample_freq=sde_sample_freq,
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
            rollout_buffer_class=rollout_buffer_class,
            rollout_buffer_kwargs=rollout_buffer_kwargs,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            _init_setup_model=_init_setup_model,
        )

    def learn(
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
