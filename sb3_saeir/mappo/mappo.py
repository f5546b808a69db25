"""MAPPO: recurrent multi-agent PPO with centralised critics over each game's agents, and pluggable intrinsic rewards.

This module holds the machinery every method of the package shares (rollout of whole games, per-scale GAE, the
chunked recurrent PPO update); :class:`~sb3_saeir.SAEIR_PPO` is MAPPO with SAEIR's critic and bonus as defaults.
"""

from __future__ import annotations

import inspect
import io
import json
import os
import pathlib
import pickle
import warnings
import zipfile
from collections.abc import Callable, Iterable
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule
from stable_baselines3.common.utils import FloatSchedule, explained_variance, obs_as_tensor
from stable_baselines3.common.vec_env import VecEnv
from torch.nn import functional as F

from sb3_saeir.common.atomic import save_zip
from sb3_saeir.common.buffers import ChunkGroup, GroupedRecurrentRolloutBuffer, n_blocks, split_by_valid_length, valid_rows
from sb3_saeir.common.callbacks import episode_metric_means
from sb3_saeir.common.compilation import check_compile_setting, resolve_compile_backend
from sb3_saeir.common.policies import MAPPOPolicy, MSHGPolicy, MultiAgentActorCriticPolicy, MultiAgentStates, SNMAPPOPolicy
from sb3_saeir.common.sampling import RolloutCollector, use_double_buffering
from sb3_saeir.common.type_aliases import GroupedRecurrentSamples
from sb3_saeir.common.utils import check_bool, check_seed, unwritable_folder
from sb3_saeir.intrinsic.base import IntrinsicRewardCallback
from sb3_saeir.intrinsic.elign import ElignCallback
from sb3_saeir.intrinsic.rnd import RNDCallback
from sb3_saeir.intrinsic.saeir import SAEIRCallback

SelfMAPPO = TypeVar("SelfMAPPO", bound="MAPPO")

# ``intrinsic_reward=<name>`` -> the callback class added automatically (register your own here).
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
    blocks = n_blocks(n_steps, n_games, data_chunk_length)
    return [block * per_batch for per_batch in range(1, blocks + 1) if blocks % per_batch == 0]


def scale_advantage_weights(advantages: th.Tensor) -> th.Tensor:
    """Weights W_K of the critic scales for one minibatch (``docs/method.md``, "Advantage mixing"):

    .. math:: W_K = \\frac{\\sum_j \\exp(\\hat A^K_j)}{\\sum_{K'} \\sum_j \\exp(\\hat A^{K'}_j)}

    computed as a softmax over K of per-scale log-sum-exps (no overflow). No gradient flows through them; with one
    critic the weight is 1.

    :param advantages: standardised advantages of the minibatch's valid samples, ``(n_samples, K)``
    :return: ``(K,)`` weights summing to 1
    """
    return th.softmax(th.logsumexp(advantages.detach(), dim=0), dim=0)


def in_order(terms: list[th.Tensor]) -> th.Tensor:
    """``terms[0] + terms[1] + ...``, left to right (one term: the term itself, so one group sums as the whole batch)."""
    total = terms[0]
    for term in terms[1:]:
        total = total + term
    return total


def in_joint_layout(values: th.Tensor, k: int, n_scales: int) -> th.Tensor:
    """Scale ``k``'s values ``(L, B, N)`` seen through the ``(L, B, N, K)`` stack of every scale's values, as the
    update computed them before it back-propagated one network at a time.

    The values are unchanged; what this keeps is the layout of the gradient that reaches the critic's value head (a
    stride-K slice), so that the head's bias gradient is summed in the same order as before, bit for bit (the
    golden runs, ``tests/test_golden.py``, amplify a last-bit difference through the group scale's top-k
    incidence). The other scales enter the stack detached: no gradient reaches them.

    :param values: the scale's values, ``(L, B, N)``
    :param k: the scale's index
    :param n_scales: the number of scales K
    """
    stacked = th.stack([values if j == k else values.detach() for j in range(n_scales)], dim=-1)  # (L, B, N, K)
    return stacked[..., k]


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


# Valid range of each numeric argument: (test, description). Schedules (callables) are not checked.
_RANGES: dict[str, tuple[Callable[[float], bool], str]] = {
    "learning_rate": (lambda x: x > 0, "> 0"),
    "n_steps": (lambda x: x >= 1, ">= 1"),
    "n_epochs": (lambda x: x >= 1, ">= 1"),
    "gamma": (lambda x: 0 <= x <= 1, "in [0, 1]"),
    "gae_lambda": (lambda x: 0 <= x <= 1, "in [0, 1]"),
    "clip_range": (lambda x: x > 0, "> 0"),
    "ent_coef": (lambda x: x >= 0, ">= 0"),
    "vf_coef": (lambda x: x >= 0, ">= 0"),
    "max_grad_norm": (lambda x: x > 0, "> 0"),
    "n_minibatches": (lambda x: x >= 1, ">= 1"),
    "data_chunk_length": (lambda x: x >= 1, ">= 1"),
    "intrinsic_coef": (lambda x: x >= 0, ">= 0 (or None for the bonus's default)"),
    "huber_delta": (lambda x: x > 0, "> 0"),
    "target_kl": (lambda x: x > 0, "> 0 (or None)"),
    "clip_range_vf": (lambda x: x > 0 or x == VALUE_CLIPPING_OFF, "> 0, or -1 to turn value clipping off (or None)"),
    "stats_window_size": (lambda x: x >= 1, ">= 1"),
    "total_timesteps": (lambda x: x >= 1, ">= 1"),
}
_MINIBATCH_ARGUMENTS = {"batch_size", "n_minibatches", "n_steps", "data_chunk_length"}
_INTRINSIC_ARGUMENTS = {"intrinsic_reward", "intrinsic_coef", "intrinsic_kwargs"}
_INTEGER_ARGUMENTS = ("n_steps", "n_epochs", "n_minibatches", "data_chunk_length", "stats_window_size", "total_timesteps")
_BOOL_ARGUMENTS = ("normalize_advantage", "normalize_values")
VALUE_CLIPPING_OFF = -1  # the clip_range_vf that turns value clipping off


def check_ranges(algo_name: str, **values: Any) -> None:
    """Raise a ``ValueError`` naming the first argument outside its valid range (``None`` and schedules pass).

    :param algo_name: class name for the message
    :param values: argument name -> value, for names in ``_RANGES``
    """
    for name, value in values.items():
        if value is None or callable(value):
            continue
        if name in _INTEGER_ARGUMENTS and (isinstance(value, bool) or not isinstance(value, (int, np.integer))):
            raise ValueError(f"{algo_name}: {name} must be an integer, got {value!r}.")
        if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not np.isfinite(value):
            raise ValueError(f"{algo_name}: {name} must be a finite number, got {value!r}.")
        test, rule = _RANGES[name]
        if not test(float(value)):
            raise ValueError(f"{algo_name}: {name}={value!r} is out of range; it must be {rule}.")


def check_overrides(algo_name: str, overrides: dict[str, Any], inference: bool = False) -> None:
    """The constructor's checks on the values ``load`` sets without the constructor (``kwargs`` and
    ``custom_objects``): ranges, booleans, ``value_loss`` and ``double_buffered``.

    :param algo_name: class name for the message
    :param overrides: argument name -> value
    :param inference: loaded for inference only (rl-zoo3's enjoy: ``custom_objects={"learning_rate": 0.0, ...}``), so
        ``learning_rate`` is not checked
    """
    skipped = {"learning_rate"} if inference else set()
    check_ranges(algo_name, **{key: value for key, value in overrides.items() if key in _RANGES and key not in skipped})
    check_bool(algo_name, **{key: value for key, value in overrides.items() if key in _BOOL_ARGUMENTS})
    if "value_loss" in overrides:
        check_value_loss(algo_name, overrides["value_loss"])
    if "double_buffered" in overrides:
        check_double_buffered(algo_name, overrides["double_buffered"])


def check_env_argument(algo_name: str, env: Any) -> None:
    """Reject an env that is not a (multi-agent) vec env with a message naming ``make_multiagent_vec_env``.

    :param algo_name: class name for the message
    :param env: the ``env`` argument
    """
    if isinstance(env, VecEnv):
        check_observation_space(algo_name, env.observation_space)
        check_action_space(algo_name, env.action_space)
    if env is None or isinstance(env, VecEnv):
        return
    example = "make_multiagent_vec_env('cn-sparse-n3', n_games=16)"
    if isinstance(env, str):
        from sb3_saeir.envs import list_tasks

        what = f"the task id {env!r}" if env in list_tasks() else f"the string {env!r}"
        raise ValueError(
            f"{algo_name} needs a multi-agent vec env, got {what}; build it with "
            f"sb3_saeir.make_multiagent_vec_env({env!r}, n_games=...) (e.g. {example}). Tasks: sb3_saeir.list_tasks()."
        )
    module = type(env).__module__
    if module.startswith("pettingzoo") or hasattr(env, "possible_agents"):
        raise ValueError(
            f"{algo_name} needs a multi-agent vec env, got the PettingZoo env {type(env).__name__}; wrap copies of it "
            "with sb3_saeir.make_multiagent_vec_env(<a function returning one ParallelEnv>, n_games=...) "
            "(an AEC env first goes through pettingzoo.utils.aec_to_parallel)."
        )
    raise ValueError(
        f"{algo_name} needs a multi-agent vec env (one slot per agent of each game), got {type(env).__name__}; "
        f"build one with sb3_saeir.make_multiagent_vec_env (e.g. {example})."
    )


def check_observation_space(algo_name: str, observation_space: spaces.Space) -> None:
    """Reject observations that are not flat ``Box`` vectors, showing the env's own shape (before SB3 transposes
    images) and the SuperSuit wrapper that flattens them.

    :param algo_name: class name for the message
    :param observation_space: one agent's observation space, as the env declares it
    """
    if isinstance(observation_space, spaces.Box) and len(observation_space.shape) == 1:
        return
    shape = getattr(observation_space, "shape", None)
    described = f"{type(observation_space).__name__} of shape {shape}" if shape else str(observation_space)
    raise ValueError(
        f"{algo_name} needs flat Box observations per agent (a vector), got {described}. Flatten them in the env: "
        "supersuit.flatten_v0(parallel_env) before make_multiagent_vec_env (images: supersuit.resize_v1 first to keep "
        "them small)."
    )


def check_action_space(algo_name: str, action_space: spaces.Space) -> None:
    """Reject ``Discrete`` / ``MultiDiscrete`` action spaces whose ``start`` is not 0: the policy samples actions
    ``0 .. n - 1`` (as SB3 does), so every action the env received would be off by ``start``.

    :param algo_name: class name for the message
    :param action_space: one agent's action space, as the env declares it
    """
    start = getattr(action_space, "start", None)
    if isinstance(action_space, (spaces.Discrete, spaces.MultiDiscrete)) and np.any(np.asarray(start) != 0):
        raise ValueError(
            f"{algo_name} needs Discrete/MultiDiscrete actions that start at 0, got {action_space} (start={start!r}): "
            "the policy samples 0 .. n-1, so the env would get every action shifted; declare start=0 and add the "
            "offset in the env."
        )


def check_intrinsic_reward(
    algo_name: str, intrinsic_reward: Any, intrinsic_coef: float | None, intrinsic_kwargs: dict[str, Any] | None
) -> None:
    """Check the intrinsic-reward arguments at construction by building the callback once (unknown names and keys,
    bad variants and kwargs given without a bonus fail here, not at ``learn``).

    :param algo_name: class name for the message
    :param intrinsic_reward: ``intrinsic_reward`` argument
    :param intrinsic_coef: ``intrinsic_coef`` argument
    :param intrinsic_kwargs: ``intrinsic_kwargs`` argument
    """
    if intrinsic_reward is None:
        if intrinsic_kwargs:
            raise ValueError(
                f"{algo_name}: intrinsic_kwargs={intrinsic_kwargs!r} given with intrinsic_reward=None would be ignored; "
                f"set intrinsic_reward (one of {sorted(INTRINSIC_REWARDS)}) or remove intrinsic_kwargs."
            )
        return
    if not isinstance(intrinsic_reward, str) or intrinsic_reward not in INTRINSIC_REWARDS:
        raise ValueError(f"Unknown intrinsic_reward {intrinsic_reward!r}; choose one of {[*INTRINSIC_REWARDS, None]}.")
    if intrinsic_kwargs is not None and not isinstance(intrinsic_kwargs, dict):
        raise ValueError(f"{algo_name}: intrinsic_kwargs must be a dict, got {intrinsic_kwargs!r}.")
    _build_intrinsic_reward(algo_name, intrinsic_reward, intrinsic_coef, intrinsic_kwargs or {})


def _build_intrinsic_reward(
    algo_name: str, intrinsic_reward: str, intrinsic_coef: float | None, intrinsic_kwargs: dict[str, Any]
) -> IntrinsicRewardCallback:
    """The callback named by ``intrinsic_reward``; an unknown keyword is one ``ValueError`` naming it."""
    bonus_class = INTRINSIC_REWARDS[intrinsic_reward]
    coef = {} if intrinsic_coef is None else {"coef": intrinsic_coef}
    parameters = inspect.signature(bonus_class.__init__).parameters
    unknown = [key for key in intrinsic_kwargs if key not in parameters or key in ("self", "coef")]
    if unknown:
        valid = [name for name in parameters if name not in ("self", "coef", "verbose")]
        raise ValueError(
            f"{algo_name}: unknown intrinsic_kwargs key {unknown[0]!r} for intrinsic_reward={intrinsic_reward!r}; "
            f"valid keys: {valid} (set the scale with intrinsic_coef)."
        )
    return bonus_class(**coef, **intrinsic_kwargs)  # type: ignore[arg-type]


def check_tensorboard_log(algo_name: str, tensorboard_log: Any) -> None:
    """Refuse a ``tensorboard_log`` that is an existing file (SB3 would fail only at ``learn``).

    :param algo_name: class name for the message
    :param tensorboard_log: ``tensorboard_log`` argument
    """
    if tensorboard_log is not None and os.path.exists(tensorboard_log) and not os.path.isdir(tensorboard_log):
        raise ValueError(
            f"{algo_name}: tensorboard_log={str(tensorboard_log)!r} is an existing file, not a folder; pass a folder path."
        )


def check_device(algo_name: str, device: Any) -> None:
    """Refuse a device torch does not know; warn (one line) where ``"cuda"`` is asked for without CUDA, since SB3
    then falls back to the CPU silently (the fallback is kept: SB3 users expect it).

    :param algo_name: class name for the message
    :param device: ``device`` argument
    """
    if isinstance(device, str) and device == "auto":
        return
    try:
        torch_device = th.device(device)
    except (RuntimeError, TypeError, ValueError):
        raise ValueError(
            f"{algo_name}: device={device!r} is not a torch device; use 'auto', 'cpu', 'cuda' or 'cuda:<index>'."
        ) from None
    if torch_device.type == "cuda" and not th.cuda.is_available():
        warnings.warn(
            f"{algo_name}: device={device!r} but CUDA is not available; training on the CPU.", UserWarning, stacklevel=3
        )


def check_value_loss(algo_name: str, value_loss: Any) -> None:
    """Refuse a ``value_loss`` other than ``"huber"`` or ``"mse"``.

    :param algo_name: class name for the message
    :param value_loss: ``value_loss`` argument
    """
    if value_loss not in ("huber", "mse"):
        raise ValueError(f"{algo_name}: value_loss must be 'huber' or 'mse', got {value_loss!r}.")


def check_double_buffered(algo_name: str, double_buffered: Any) -> None:
    """Refuse a ``double_buffered`` other than ``True``, ``False`` or ``"auto"``.

    :param algo_name: class name for the message
    :param double_buffered: ``double_buffered`` argument
    """
    if not (isinstance(double_buffered, bool) or double_buffered == "auto"):
        raise ValueError(f"{algo_name}: double_buffered must be True, False or 'auto', got {double_buffered!r}.")


def check_save_path(algo_name: str, path: Any) -> None:
    """Refuse a ``save`` path where no file can be written, before anything is written: an empty name, a path under a
    file, or in a folder that is not writable (SB3 would recurse without end under ``/proc``, or fail with the OS's
    message). A file object passes (SB3 writes to it).

    :param algo_name: class name for the message
    :param path: the ``path`` argument of ``save``
    """
    if not isinstance(path, (str, os.PathLike)):
        return
    if str(path) in ("", "."):
        raise ValueError(f"{algo_name}.save: {str(path)!r} is not a file name; pass e.g. 'model.zip'.")
    target = pathlib.Path(path)
    if target.suffix == "":
        target = target.with_suffix(".zip")  # as SB3's save names it (an existing folder: SB3 saves to <path>_2)
    problem = unwritable_folder(target.parent)
    if problem:
        raise ValueError(f"{algo_name}.save: cannot write {str(target)!r}: {problem}; save to a folder you can write.")
    if target.exists() and not os.access(target, os.W_OK):
        raise ValueError(f"{algo_name}.save: {str(target)!r} exists and is not writable; save to another path.")


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
    :param n_minibatches: minibatches per epoch when ``batch_size`` is ``None`` (blocks are split as evenly as possible)
    :param data_chunk_length: steps per recurrent training chunk (10)
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
        check_env_argument(type(self).__name__, env)
        check_compile_setting(type(self).__name__, compile)
        check_ranges(
            type(self).__name__,
            learning_rate=learning_rate,
            n_steps=n_steps,
            n_epochs=n_epochs,
            gamma=gamma,
            gae_lambda=gae_lambda,
            clip_range=clip_range,
            ent_coef=ent_coef,
            vf_coef=vf_coef,
            max_grad_norm=max_grad_norm,
            n_minibatches=n_minibatches,
            data_chunk_length=data_chunk_length,
            intrinsic_coef=intrinsic_coef,
            huber_delta=huber_delta,
            target_kl=target_kl,
            clip_range_vf=clip_range_vf,
            stats_window_size=stats_window_size,
        )
        check_bool(type(self).__name__, normalize_advantage=normalize_advantage, normalize_values=normalize_values)
        if isinstance(policy_kwargs, dict) and "normalize_values" in policy_kwargs:
            check_bool(type(self).__name__, normalize_values=policy_kwargs["normalize_values"])
        check_intrinsic_reward(type(self).__name__, intrinsic_reward, intrinsic_coef, intrinsic_kwargs)
        check_tensorboard_log(type(self).__name__, tensorboard_log)
        check_device(type(self).__name__, device)
        check_double_buffered(type(self).__name__, double_buffered)
        check_value_loss(type(self).__name__, value_loss)
        seed = check_seed(type(self).__name__, seed)
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
            use_sde=False,
            sde_sample_freq=-1,
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
            self.n_agents = self._check_env(self.env)
            self.n_minibatches = self._resolve_minibatches()
        if _init_setup_model:
            self._setup_model()

    # ------------------------------------------------------------------------------------------------ setup
    @staticmethod
    def _check_env(env: VecEnv) -> int:
        n_agents = getattr(env, "n_agents", None)
        if n_agents is None:
            raise ValueError(
                f"{type(env).__name__} does not say how many agents a game has (no `n_agents`). MAPPO and SAEIR_PPO "
                "need the multi-agent vec env of sb3_saeir.make_multiagent_vec_env(task, n_games), whose slots are "
                "game * n_agents + agent."
            )
        if env.num_envs % n_agents != 0:
            raise ValueError(f"env.num_envs={env.num_envs} is not a multiple of n_agents={n_agents}.")
        return int(n_agents)

    def _resolve_minibatches(self) -> int:
        """Number of minibatches from ``batch_size`` (checked) or ``n_minibatches``."""
        assert self.n_agents is not None
        n_games = self.n_envs // self.n_agents
        blocks = n_blocks(self.n_steps, n_games, self.data_chunk_length)
        if self.batch_size is None:
            if not 1 <= self.n_minibatches <= blocks:
                raise ValueError(
                    f"n_minibatches={self.n_minibatches} must be between 1 and the number of (game, chunk) blocks "
                    f"{blocks} (= {n_games} games x ceil(n_steps={self.n_steps} / data_chunk_length="
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
            raise ValueError(f"{type(self).__name__} needs an env (make_multiagent_vec_env) or a loaded n_agents.")
        if self.env is not None and self._check_env(self.env) != self.n_agents:
            # load(path, env) of a model onto games of another size (set_env refuses the same env)
            raise ValueError(
                f"{type(self).__name__}: the model was built for {self.n_agents} agents per game, the env has "
                f"{self._check_env(self.env)}; pass an env with {self.n_agents} agents per game."
            )
        self._setup_lr_schedule()
        self.set_random_seed(self.seed)
        self.policy_kwargs = {**self.policy_kwargs, "n_agents": self.n_agents, "normalize_values": self.normalize_values}
        if not (isinstance(self.policy_class, type) and issubclass(self.policy_class, MultiAgentActorCriticPolicy)):
            name = getattr(self.policy_class, "__name__", repr(self.policy_class))
            raise ValueError(
                f"{type(self).__name__} needs a MultiAgentActorCriticPolicy: one of {sorted(self.policy_aliases)} or a "
                f"subclass of sb3_saeir.common.policies.MultiAgentActorCriticPolicy, got {name}."
            )
        self.policy = self.policy_class(self.observation_space, self.action_space, self.lr_schedule, **self.policy_kwargs)
        self.policy = self.policy.to(self.device)
        self.policy.set_compile(resolve_compile_backend(type(self).__name__, self.compile, self.device))
        if self.rollout_buffer_class is None:
            self.rollout_buffer_class = GroupedRecurrentRolloutBuffer
        if not issubclass(self.rollout_buffer_class, GroupedRecurrentRolloutBuffer):
            raise ValueError(
                f"rollout_buffer_class must be a GroupedRecurrentRolloutBuffer subclass, got {self.rollout_buffer_class}."
            )
        self.rollout_buffer = self.rollout_buffer_class(
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
        callbacks = _flatten_callbacks(callback)
        if self.intrinsic_reward is not None:
            bonus_class = INTRINSIC_REWARDS[self.intrinsic_reward]
            if not any(isinstance(c, bonus_class) for c in callbacks):
                name = type(self).__name__
                callbacks.append(
                    _build_intrinsic_reward(name, self.intrinsic_reward, self.intrinsic_coef, self.intrinsic_kwargs)
                )
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
        collector = RolloutCollector(self.policy, self.action_space, self.gamma, self.device)
        double_buffered = use_double_buffering(type(self).__name__, self.double_buffered, env)
        if not collector.collect(self, env, callback, rollout_buffer, n_rollout_steps, double_buffered):
            return False
        new_obs, dones = self._last_obs, self._last_episode_starts
        assert new_obs is not None and dones is not None
        with th.no_grad():
            last_starts = th.as_tensor(dones, dtype=th.float32, device=self.device)
            last_values = self.policy.predict_values(obs_as_tensor(new_obs, self.device), self._last_states, last_starts)  # type: ignore[arg-type]
        rollout_buffer.set_last_step(last_values, dones)  # type: ignore[arg-type]
        for intrinsic_reward in self._intrinsic_rewards:
            intrinsic_reward.add_to(rollout_buffer)
        rollout_buffer.compute_returns_and_advantage(
            last_values=last_values,
            dones=dones,
            denormalize=self.policy.denormalize_values_numpy,  # type: ignore[arg-type]
        )
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

                policy_loss, entropy_loss, clip_fraction, approx_kl_div = self._actor_losses(
                    groups, weights, n_valid, clip_range
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
                    scale_loss = self._critic_loss(k, samples, groups, n_valid, clip_range_vf)
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

        values_in_return_space = self.policy.denormalize_values_numpy(self.rollout_buffer.values)  # (T, E, K)
        for k, scale in enumerate(scales):
            self.logger.record(f"train/value_loss_{scale}", float(np.mean(value_losses[scale])))
            self.logger.record(f"train/advantage_weight_{scale}", float(np.mean(advantage_weights[scale])))
            self.logger.record(
                f"train/explained_variance_{scale}",
                float(explained_variance(values_in_return_space[..., k].ravel(), self.rollout_buffer.returns[..., k].ravel())),
            )
        self.logger.record("train/value_loss", float(sum(np.mean(value_losses[scale]) for scale in scales)))
        self.logger.record("train/entropy_loss", float(np.mean(entropy_losses)))
        self.logger.record("train/policy_gradient_loss", float(np.mean(pg_losses)))
        self.logger.record("train/approx_kl", float(np.mean(approx_kl_divs)))
        self.logger.record("train/clip_fraction", float(np.mean(clip_fractions)))
        self.logger.record("train/loss", loss_value)
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/clip_range", clip_range)
        self.logger.record("train/clip_range_vf", clip_range_vf)

    def _actor_losses(
        self, groups: list[ChunkGroup], weights: th.Tensor, n_valid: th.Tensor, clip_range: float
    ) -> tuple[th.Tensor, th.Tensor, float, float]:
        """The clipped surrogate loss and the entropy loss of a minibatch (means over its valid rows), the share of
        clipped ratios and the approximate KL (Schulman's estimator), the actor run on each group of blocks.

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
            log_prob, entropy = self.policy.evaluate_actor(
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
        valid = float(n_valid)
        return -in_order(policy_sums) / n_valid, -in_order(entropy_sums) / n_valid, clipped / valid, kl_sum / valid

    def _critic_loss(
        self,
        k: int,
        samples: GroupedRecurrentSamples,
        groups: list[ChunkGroup],
        n_valid: th.Tensor,
        clip_range_vf: float | None,
    ) -> th.Tensor:
        """Critic scale ``k``'s clipped value loss on a minibatch (mean over its valid rows), on returns normalised by
        the scale's ValueNorm (updated here with the minibatch's valid returns), the critic run on each group of blocks
        with its rows of the Gumbel draws of the whole minibatch (the noise is that of the padded minibatch).

        :param k: the scale's index
        :param samples: the minibatch (padded)
        :param groups: its blocks by valid length
        :param n_valid: valid rows of the minibatch (steps x blocks x agents)
        :param clip_range_vf: the value clip range (``None``: no clipping)
        :return: the loss, with its graph
        """
        n_steps, n_blocks = samples.mask.shape
        uniform = self.policy.draw_gumbel_uniform(k, n_steps, n_blocks)  # (L, B, E, T_K) or None
        if self.normalize_values:
            value_norm = self.policy.value_norm(self.policy.scales[k])
            value_norm.update(samples.returns[..., k][samples.mask])
        loss_sums = []
        for group in groups:
            part = group.samples
            # the group's rows of the draws: (L, B, E, T_K) -> (length * B_g, E, T_K), rows (step, block)
            part_uniform = None if uniform is None else group.take(uniform)
            values = self.policy.evaluate_critic(
                k, part.observations, part.critic_states[k], part.episode_starts, part_uniform
            )  # (length, B_g, N)
            values = in_joint_layout(values, k, self.policy.n_scales)
            returns = part.returns[..., k]
            if self.normalize_values:
                returns = value_norm.normalize(returns)
            per_sample = clipped_value_loss(
                values, part.old_values[..., k], returns, clip_range_vf, self.value_loss, self.huber_delta
            )
            loss_sums.append(per_sample.sum())
        return in_order(loss_sums) / n_valid

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
        check_ranges(type(self).__name__, total_timesteps=total_timesteps)
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
        """SB3's ``load``, with the constructor's checks on overrides (``kwargs`` and ``custom_objects``), the env's
        ``n_agents`` checked against the model's (as :meth:`set_env`), and one line for a file that is not a complete
        model zip."""
        name = cls.__name__
        overrides = {**(custom_objects or {}), **kwargs}
        check_overrides(name, overrides, inference=(custom_objects or {}).get("learning_rate") == 0.0)
        if "seed" in kwargs:
            kwargs["seed"] = check_seed(name, kwargs["seed"])
        check_device(name, device)
        if env is not None:
            check_env_argument(name, env)
        try:
            model = super().load(path, env, device, custom_objects, print_system_info, force_reset, **kwargs)
        except (zipfile.BadZipFile, EOFError, pickle.UnpicklingError, KeyError, RuntimeError, AssertionError) as error:
            raise _incomplete_model_error(name, path, error) from None
        except ValueError as error:
            # SB3's own ValueErrors for a damaged zip; ours (n_agents, ranges) pass through
            if isinstance(error, json.JSONDecodeError) or "Names of parameters do not match" in str(error):
                raise _incomplete_model_error(name, path, error) from None
            raise
        model._apply_overrides(overrides)
        return model

    def _apply_overrides(self, overrides: dict[str, Any]) -> None:
        """After :meth:`load`, the constructor's checks that need the loaded model: the minibatch split of a
        ``batch_size``, ``n_minibatches``, ``n_steps`` or ``data_chunk_length`` override (SB3 sets the attribute
        only, so ``batch_size`` was ignored), and an intrinsic-reward override against the saved settings.

        :param overrides: the ``custom_objects`` and keyword arguments given to ``load``
        """
        if _MINIBATCH_ARGUMENTS & set(overrides) and self.n_agents is not None:
            if "n_minibatches" in overrides and "batch_size" not in overrides:
                self.batch_size = None  # as in the constructor: n_minibatches decides when batch_size is None
            self.n_minibatches = self._resolve_minibatches()
        if _INTRINSIC_ARGUMENTS & set(overrides):
            check_intrinsic_reward(type(self).__name__, self.intrinsic_reward, self.intrinsic_coef, self.intrinsic_kwargs)
            self.intrinsic_kwargs = dict(self.intrinsic_kwargs or {})

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
        one line (:func:`check_save_path`).

        :param path: path to the file where the model should be saved, or a binary file object
        :param exclude: name of parameters that should be excluded in addition to the default ones
        :param include: name of parameters that might be excluded but should be included anyway
        """
        check_save_path(type(self).__name__, path)
        if isinstance(path, (str, os.PathLike)):
            save_zip(path, lambda file: super(MAPPO, self).save(file, exclude=exclude, include=include))
        else:
            super().save(path, exclude=exclude, include=include)

    def _excluded_save_params(self) -> list[str]:
        # compile is a setting of the machine, as device: a model saved compiled loads eager unless load(compile=True)
        return [*super()._excluded_save_params(), "_last_states", "_intrinsic_rewards", "compile"]

    def set_env(self, env: GymEnv, force_reset: bool = True) -> None:
        n_agents = self._check_env(env if isinstance(env, VecEnv) else self._wrap_env(env, self.verbose))  # type: ignore[arg-type]
        if self.n_agents is not None and n_agents != self.n_agents:
            raise ValueError(f"The model was built for {self.n_agents} agents per game, the env has {n_agents}.")
        super().set_env(env, force_reset)
        self._last_states = None


def _incomplete_model_error(algo_name: str, path: Any, error: BaseException) -> ValueError:
    """One line for a model file that SB3 could not read back (truncated or edited zip)."""
    detail = str(error).splitlines()[0] if str(error) else "no detail"
    return ValueError(
        f"{algo_name}.load: {str(path)!r} is not a complete sb3-saeir model zip ({type(error).__name__}: {detail}); "
        "save the model again with model.save."
    )


def _flatten_callbacks(callback: MaybeCallback) -> list[BaseCallback]:
    """The user's callbacks as a flat list (``CallbackList`` and lists unpacked, recursively)."""
    if callback is None:
        return []
    if isinstance(callback, CallbackList):
        return [c for inner in callback.callbacks for c in _flatten_callbacks(inner)]
    if isinstance(callback, list):
        return [c for inner in callback for c in _flatten_callbacks(inner)]
    if isinstance(callback, BaseCallback):
        return [callback]
    from stable_baselines3.common.callbacks import ConvertCallback

    return [ConvertCallback(callback)]
