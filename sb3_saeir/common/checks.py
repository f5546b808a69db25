"""Argument checks of the algorithms and the command line: each one refuses a bad value in one line that names the
argument, the value and the fix, before anything is built or written (``docs/guide/algorithms.md``).

One implementation per check, used by every caller: :class:`~sb3_saeir.MAPPO` / :class:`~sb3_saeir.SAEIR_PPO`
(constructor: :func:`check_mappo_arguments`; ``load``, ``save``) and ``python -m sb3_saeir.train`` (the device,
through :func:`sb3_saeir.command_line.check_arguments`). The checks of a saved model (``load``'s file,
``set_parameters``' parameters) are in :mod:`sb3_saeir.common.saved_model_checks`, those of ``learn`` and
``set_parameters``' other arguments in :mod:`sb3_saeir.common.method_arguments`.
"""

from __future__ import annotations

import inspect
import os
import pathlib
import warnings
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv

from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer, n_blocks
from sb3_saeir.common.compilation import check_compile_setting
from sb3_saeir.common.policies import MultiAgentActorCriticPolicy
from sb3_saeir.common.policy_arguments import GSDE_UNSUPPORTED
from sb3_saeir.common.registry import INTRINSIC_REWARDS, list_tasks
from sb3_saeir.common.utils import (
    check_bool,
    check_number,
    check_seed,
    check_writable_folder,
    unwritable_folder,
    user_stacklevel,
)
from sb3_saeir.common.vec_env.game_checks import check_action_space

# The largest agent-step count a budget may have: integers up to 2**53 are exact as floats (SB3's progress and the
# logger compute with floats).
MAX_TIMESTEPS = 2**53
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
    "total_timesteps": (lambda x: 1 <= x <= MAX_TIMESTEPS, f">= 1 and at most 2**53 ({MAX_TIMESTEPS:,})"),
}
MINIBATCH_ARGUMENTS = {"batch_size", "n_minibatches", "n_steps", "data_chunk_length"}
INTRINSIC_ARGUMENTS = {"intrinsic_reward", "intrinsic_coef", "intrinsic_kwargs"}
_INTEGER_ARGUMENTS = ("n_steps", "n_epochs", "n_minibatches", "data_chunk_length", "stats_window_size", "total_timesteps")
_BOOL_ARGUMENTS = ("normalize_advantage", "normalize_values")
VALUE_CLIPPING_OFF = -1  # the clip_range_vf that turns value clipping off
_ENV_EXAMPLE = "make_multiagent_vec_env('cn-sparse-n3', n_games=16)"


# ------------------------------------------------------------------------------------------------ the constructor
def check_mappo_arguments(
    algo_name: str,
    *,
    env: Any,
    learning_rate: Any,
    n_steps: Any,
    n_epochs: Any,
    gamma: Any,
    gae_lambda: Any,
    clip_range: Any,
    clip_range_vf: Any,
    normalize_advantage: Any,
    ent_coef: Any,
    vf_coef: Any,
    max_grad_norm: Any,
    use_sde: Any,
    n_minibatches: Any,
    data_chunk_length: Any,
    intrinsic_reward: Any,
    intrinsic_coef: Any,
    intrinsic_kwargs: Any,
    normalize_values: Any,
    value_loss: Any,
    huber_delta: Any,
    target_kl: Any,
    double_buffered: Any,
    compile: Any,
    stats_window_size: Any,
    tensorboard_log: Any,
    policy_kwargs: Any,
    verbose: Any,
    seed: Any,
    device: Any,
) -> tuple[BaseCallback | None, int | None]:
    """The checks of :class:`~sb3_saeir.MAPPO`'s constructor (and so :class:`~sb3_saeir.SAEIR_PPO`'s), before SB3
    builds anything; the first bad argument is refused in one line. In order: the env, ``compile``, the numbers
    (:func:`check_ranges`), the switches, ``use_sde``, ``policy_kwargs``, the intrinsic reward (its callback is built
    here), ``tensorboard_log``, ``verbose``, ``device``, ``double_buffered``, ``value_loss`` and ``seed``. The split
    into minibatches needs the env's games: :func:`resolve_minibatches`, after SB3's constructor.

    Each argument is the constructor's argument of that name (:class:`~sb3_saeir.MAPPO` documents them).

    :param algo_name: class name for the message
    :param env: ``env``
    :param learning_rate: ``learning_rate`` (a schedule passes)
    :param n_steps: ``n_steps``
    :param n_epochs: ``n_epochs``
    :param gamma: ``gamma``
    :param gae_lambda: ``gae_lambda``
    :param clip_range: ``clip_range`` (a schedule passes)
    :param clip_range_vf: ``clip_range_vf`` (a schedule and ``None`` pass)
    :param normalize_advantage: ``normalize_advantage``
    :param ent_coef: ``ent_coef``
    :param vf_coef: ``vf_coef``
    :param max_grad_norm: ``max_grad_norm``
    :param use_sde: ``use_sde``
    :param n_minibatches: ``n_minibatches``
    :param data_chunk_length: ``data_chunk_length``
    :param intrinsic_reward: ``intrinsic_reward``
    :param intrinsic_coef: ``intrinsic_coef``
    :param intrinsic_kwargs: ``intrinsic_kwargs``
    :param normalize_values: ``normalize_values``
    :param value_loss: ``value_loss``
    :param huber_delta: ``huber_delta``
    :param target_kl: ``target_kl``
    :param double_buffered: ``double_buffered``
    :param compile: ``compile``
    :param stats_window_size: ``stats_window_size``
    :param tensorboard_log: ``tensorboard_log``
    :param policy_kwargs: ``policy_kwargs``
    :param verbose: ``verbose``
    :param seed: ``seed``
    :param device: ``device``
    :return: the intrinsic-reward callback (:func:`check_intrinsic_reward`; ``None`` without a bonus), for the
        algorithm to add at ``learn``, and the seed as a Python ``int`` (or ``None``)
    """
    check_env_argument(algo_name, env)
    check_compile_setting(algo_name, compile)
    check_ranges(
        algo_name,
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
    check_bool(algo_name, normalize_advantage=normalize_advantage, normalize_values=normalize_values)
    check_use_sde(algo_name, use_sde)
    check_policy_kwargs(algo_name, policy_kwargs)
    bonus = check_intrinsic_reward(algo_name, intrinsic_reward, intrinsic_coef, intrinsic_kwargs)
    check_tensorboard_log(algo_name, tensorboard_log)
    check_verbose(algo_name, verbose)
    check_device(algo_name, device)
    check_double_buffered(algo_name, double_buffered)
    check_value_loss(algo_name, value_loss)
    return bonus, check_seed(algo_name, seed)


# ------------------------------------------------------------------------------------------------ numbers and switches
def check_ranges(algo_name: str, **values: Any) -> None:
    """Check the algorithms' numeric arguments against their ranges (``_RANGES``), in the order given, with
    :func:`~sb3_saeir.common.utils.check_number`: the first one that is no number, or outside its range, is refused
    in one line (``None`` and schedules pass).

    :param algo_name: class name for the message
    :param values: argument name -> value, for names in ``_RANGES``
    """
    for name, value in values.items():
        if value is None or callable(value):
            continue
        test, rule = _RANGES[name]
        check_number(algo_name, name, value, rule, test, integer=name in _INTEGER_ARGUMENTS, out_of_range=True)


def check_overrides(algo_name: str, overrides: dict[str, Any], inference: bool = False) -> None:
    """The constructor's checks on the values ``load`` sets without the constructor (``kwargs`` and
    ``custom_objects``): ranges, booleans, ``value_loss``, ``double_buffered``, ``tensorboard_log`` and ``verbose``.

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
    if "tensorboard_log" in overrides:
        check_tensorboard_log(algo_name, overrides["tensorboard_log"])
    if "verbose" in overrides:
        check_verbose(algo_name, overrides["verbose"])


def check_use_sde(algo_name: str, use_sde: Any) -> None:
    """Refuse ``use_sde`` other than ``False``: generalized State-Dependent Exploration is not supported (SB3's ``PPO``
    argument, taken so that PPO hyperparameters that set it off still apply).

    :param algo_name: class name for the message
    :param use_sde: ``use_sde`` argument
    """
    check_bool(algo_name, use_sde=use_sde)
    if use_sde:
        raise ValueError(f"{algo_name}: use_sde=True is not supported: {GSDE_UNSUPPORTED}.")


def check_policy_kwargs(algo_name: str, policy_kwargs: Any) -> None:
    """Refuse ``policy_kwargs`` that are not a dict (``None`` passes), and a ``normalize_values`` in them that is not a
    bool. The policy checks its own keys when it is built.

    :param algo_name: class name for the message
    :param policy_kwargs: ``policy_kwargs`` argument
    """
    if policy_kwargs is None:
        return
    if not isinstance(policy_kwargs, dict):
        raise TypeError(f"{algo_name}: policy_kwargs must be a dict, such as dict(hidden_size=64), got {policy_kwargs!r}.")
    if "normalize_values" in policy_kwargs:
        check_bool(algo_name, normalize_values=policy_kwargs["normalize_values"])


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


def resolve_minibatches(
    n_steps: int, n_games: int, n_agents: int, data_chunk_length: int, batch_size: int | None, n_minibatches: int
) -> int:
    """The number of minibatches per epoch: from ``batch_size`` when given (it must split the rollout into equal
    minibatches of whole (game, chunk) blocks), else ``n_minibatches`` (at most one per block).

    :param n_steps: steps per game per rollout
    :param n_games: games of the env
    :param n_agents: agents per game
    :param data_chunk_length: steps per training chunk
    :param batch_size: ``batch_size`` argument (agent-samples), or ``None``
    :param n_minibatches: ``n_minibatches`` argument
    """
    if data_chunk_length > n_steps:
        warnings.warn(
            f"data_chunk_length={data_chunk_length} is longer than n_steps={n_steps}: each game's rollout is one chunk "
            f"padded to {data_chunk_length} steps, the same update as data_chunk_length={n_steps} at more recurrent "
            f"compute; set data_chunk_length={n_steps} (or less).",
            UserWarning,
            stacklevel=user_stacklevel(),
        )
    blocks = n_blocks(n_steps, n_games, data_chunk_length)
    if batch_size is None:
        if not 1 <= n_minibatches <= blocks:
            raise ValueError(
                f"n_minibatches={n_minibatches} must be between 1 and the number of (game, chunk) blocks "
                f"{blocks} (= {n_games} games x ceil(n_steps={n_steps} / data_chunk_length={data_chunk_length}))."
            )
        return n_minibatches
    valid = valid_batch_sizes(n_steps, n_games, n_agents, data_chunk_length)
    if batch_size not in valid:
        hint = f"valid batch sizes: {valid}"
        if n_steps % data_chunk_length != 0:
            hint += (
                f" (n_steps={n_steps} is not a multiple of data_chunk_length={data_chunk_length}, so only the whole "
                "rollout splits into equal whole blocks)"
            )
        raise ValueError(
            f"batch_size={batch_size} cannot be formed from whole (game, {data_chunk_length}-step chunk) blocks of "
            f"{n_agents} agents ({data_chunk_length * n_agents} agent-samples each) in a rollout of {n_steps} steps x "
            f"{n_games} games; {hint}. Or leave batch_size=None and set n_minibatches instead."
        )
    return n_steps * n_games * n_agents // batch_size


# ------------------------------------------------------------------------------------------------ env and spaces
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
    if isinstance(env, str):
        what = f"the task id {env!r}" if env in list_tasks() else f"the string {env!r}"
        raise ValueError(
            f"{algo_name} needs a multi-agent vec env, got {what}; build it with sb3_saeir.make_multiagent_vec_env("
            f"{env!r}, n_games=...) (e.g. {_ENV_EXAMPLE}). Tasks: sb3_saeir.list_tasks()."
        )
    if type(env).__module__.startswith("pettingzoo") or hasattr(env, "possible_agents"):
        raise ValueError(
            f"{algo_name} needs a multi-agent vec env, got the PettingZoo env {type(env).__name__}; wrap copies of it "
            "with sb3_saeir.make_multiagent_vec_env(<a function returning one ParallelEnv>, n_games=...) "
            "(an AEC env first goes through pettingzoo.utils.aec_to_parallel)."
        )
    raise ValueError(
        f"{algo_name} needs a multi-agent vec env (one slot per agent of each game), got {type(env).__name__}; "
        f"build one with sb3_saeir.make_multiagent_vec_env (e.g. {_ENV_EXAMPLE})."
    )


def check_n_agents(algo_name: str, env: VecEnv, expected: int | None = None) -> int:
    """The agents per game of a multi-agent vec env (its ``n_agents``), refused when missing, when not dividing
    ``num_envs``, or when not the ``expected`` number of a built model (``load(path, env)``, ``set_env``).

    :param algo_name: class name for the message
    :param env: the vec env
    :param expected: the model's agents per game (``None``: any)
    """
    n_agents = getattr(env, "n_agents", None)
    if n_agents is None:
        raise ValueError(
            f"{type(env).__name__} does not say how many agents a game has (no `n_agents`). MAPPO and SAEIR_PPO "
            "need the multi-agent vec env of sb3_saeir.make_multiagent_vec_env(task, n_games), whose slots are "
            "game * n_agents + agent."
        )
    if env.num_envs % n_agents != 0:
        raise ValueError(f"env.num_envs={env.num_envs} is not a multiple of n_agents={n_agents}.")
    if expected is not None and n_agents != expected:
        raise ValueError(
            f"{algo_name}: the model was built for {expected} agents per game, the env has {n_agents}; pass an env "
            f"with {expected} agents per game."
        )
    return int(n_agents)


def check_policy_class(algo_name: str, policy_class: Any, aliases: Iterable[str]) -> type[MultiAgentActorCriticPolicy]:
    """Refuse a policy that is not a :class:`~sb3_saeir.common.policies.MultiAgentActorCriticPolicy`.

    :param algo_name: class name for the message
    :param policy_class: the policy class (an alias already resolved)
    :param aliases: the algorithm's policy aliases, for the message
    :return: the class
    """
    if not (isinstance(policy_class, type) and issubclass(policy_class, MultiAgentActorCriticPolicy)):
        name = getattr(policy_class, "__name__", repr(policy_class))
        raise ValueError(
            f"{algo_name} needs a MultiAgentActorCriticPolicy: one of {sorted(aliases)} or a subclass of "
            f"sb3_saeir.common.policies.MultiAgentActorCriticPolicy, got {name}."
        )
    return policy_class


def check_rollout_buffer_class(rollout_buffer_class: Any) -> type[GroupedRecurrentRolloutBuffer]:
    """Refuse a rollout buffer that is not a :class:`~sb3_saeir.common.buffers.GroupedRecurrentRolloutBuffer`.

    :param rollout_buffer_class: ``rollout_buffer_class`` argument (``None`` already replaced by the default)
    :return: the class
    """
    if not (isinstance(rollout_buffer_class, type) and issubclass(rollout_buffer_class, GroupedRecurrentRolloutBuffer)):
        raise ValueError(f"rollout_buffer_class must be a GroupedRecurrentRolloutBuffer subclass, got {rollout_buffer_class}.")
    return rollout_buffer_class


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


# ------------------------------------------------------------------------------------------------ intrinsic rewards
def check_intrinsic_reward(
    algo_name: str, intrinsic_reward: Any, intrinsic_coef: float | None, intrinsic_kwargs: dict[str, Any] | None
) -> BaseCallback | None:
    """Check the intrinsic-reward arguments at construction by building the callback (unknown names and keys, bad
    variants and kwargs given without a bonus fail here, not at ``learn``); the callback built is returned, for the
    algorithm to add at ``learn`` (``None`` without a bonus).

    :param algo_name: class name for the message
    :param intrinsic_reward: ``intrinsic_reward`` argument: a name registered with
        :func:`~sb3_saeir.common.registry.register_intrinsic_reward`, or ``None``
    :param intrinsic_coef: ``intrinsic_coef`` argument
    :param intrinsic_kwargs: ``intrinsic_kwargs`` argument
    """
    if intrinsic_reward is None:
        given = {"intrinsic_coef": intrinsic_coef, "intrinsic_kwargs": intrinsic_kwargs or None}
        given = {name: value for name, value in given.items() if value is not None}
        if given:
            named = " and ".join(f"{name}={value!r}" for name, value in given.items())
            raise ValueError(
                f"{algo_name}: {named} given with intrinsic_reward=None would be ignored; set intrinsic_reward (one of "
                f"{sorted(INTRINSIC_REWARDS)}) or remove {' and '.join(given)}."
            )
        return None
    if not isinstance(intrinsic_reward, str) or intrinsic_reward not in INTRINSIC_REWARDS:
        raise ValueError(f"Unknown intrinsic_reward {intrinsic_reward!r}; choose one of {[*sorted(INTRINSIC_REWARDS), None]}.")
    if intrinsic_kwargs is not None and not isinstance(intrinsic_kwargs, dict):
        raise ValueError(f"{algo_name}: intrinsic_kwargs must be a dict, got {intrinsic_kwargs!r}.")
    return build_intrinsic_reward(algo_name, intrinsic_reward, intrinsic_coef, intrinsic_kwargs or {})


def build_intrinsic_reward(
    algo_name: str, intrinsic_reward: str, intrinsic_coef: float | None, intrinsic_kwargs: dict[str, Any]
) -> BaseCallback:
    """The callback registered as ``intrinsic_reward``; an unknown keyword, or a value the callback refuses, is one
    ``ValueError`` naming it.

    :param algo_name: class name for the message
    :param intrinsic_reward: a registered name
    :param intrinsic_coef: the bonus's scale (``None``: the callback's default)
    :param intrinsic_kwargs: the callback's other keyword arguments
    """
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
    try:
        return bonus_class(**coef, **intrinsic_kwargs)  # type: ignore[arg-type]
    except TypeError as error:  # e.g. a keyword-only argument missing: the callback's own ValueErrors pass through
        raise ValueError(
            f"{algo_name}: intrinsic_kwargs={intrinsic_kwargs!r} of intrinsic_reward={intrinsic_reward!r}: {error}"
        ) from None


# ------------------------------------------------------------------------------------------------ machine and files
def check_device(owner: str, device: Any, cpu_fallback: bool = True) -> None:
    """Refuse a device torch does not know. Where ``"cuda"`` is asked for without CUDA, SB3 falls back to the CPU
    silently: with ``cpu_fallback`` (the Python API; SB3 users expect the fallback) one warning line says so, without
    (the command line) the device is refused.

    :param owner: who checks, for the message: a class name (``"MAPPO: device='gpu2' is not ..."``) or a
        command-line option (``"--device"``: ``"--device 'gpu2' is not ..."``)
    :param device: the device asked for
    :param cpu_fallback: warn and let SB3 train on the CPU (``True``), or refuse (``False``), where CUDA is missing
    """
    if isinstance(device, str) and device == "auto":
        return
    named = f"{owner} {device!r}" if owner.startswith("-") else f"{owner}: device={device!r}"
    try:
        torch_device = th.device(device)
    except (RuntimeError, TypeError, ValueError):
        raise ValueError(f"{named} is not a torch device; use 'auto', 'cpu', 'cuda' or 'cuda:<index>'.") from None
    if torch_device.type != "cuda" or th.cuda.is_available():
        return
    if not cpu_fallback:
        raise ValueError(f"{named}: no CUDA device is available here; use 'cpu' (or 'auto').")
    warnings.warn(f"{named} but CUDA is not available; training on the CPU.", UserWarning, stacklevel=user_stacklevel())


def check_verbose(algo_name: str, verbose: Any) -> None:
    """Refuse a ``verbose`` that is not a whole number from 0 up (SB3 compares it with ``>=`` at ``learn``: a string
    ended there in a ``TypeError`` naming no argument). ``True`` and ``False`` pass, as 1 and 0 do in SB3.

    :param algo_name: class name for the message
    :param verbose: ``verbose`` argument
    """
    if not isinstance(verbose, (int, np.integer)) or verbose < 0:
        raise ValueError(f"{algo_name}: verbose={verbose!r} is not a verbosity level; pass 0 (silent), 1 (info) or 2 (debug).")


def check_tensorboard_log(algo_name: str, tensorboard_log: Any) -> None:
    """Refuse a ``tensorboard_log`` that is an existing file or a folder where no file can be written (``/proc/tb``,
    a read-only mount: the probe of :func:`~sb3_saeir.common.utils.unwritable_folder`, as ``-tb`` of the command
    lines); SB3 would fail only at ``learn``, with the OS's error.

    :param algo_name: class name for the message
    :param tensorboard_log: ``tensorboard_log`` argument
    """
    is_path = isinstance(tensorboard_log, (str, os.PathLike))
    if is_path and os.path.exists(tensorboard_log) and not os.path.isdir(tensorboard_log):
        raise ValueError(
            f"{algo_name}: tensorboard_log={str(tensorboard_log)!r} is an existing file, not a folder; pass a folder path."
        )
    check_writable_folder(algo_name, "tensorboard_log", tensorboard_log, "a path such as './tensorboard/'")


def check_save_path(algo_name: str, path: Any) -> None:
    """Refuse a ``save`` path where no file can be written, before anything is written: an empty name, a folder (SB3
    saved to ``<path>_2`` instead), a path under a file, or in a folder that is not writable (SB3 would recurse without
    end under ``/proc``, or fail with the OS's message), or ``None``. A file object passes (SB3 writes to it).

    :param algo_name: class name for the message
    :param path: the ``path`` argument of ``save``
    """
    if not isinstance(path, (str, os.PathLike)):
        if hasattr(path, "write"):  # a file object: SB3 writes to it
            return
        raise TypeError(f"{algo_name}.save: path={path!r}; pass a file path (such as 'model.zip') or a binary file object.")
    if str(path) in ("", "."):
        raise ValueError(f"{algo_name}.save: {str(path)!r} is not a file name; pass e.g. 'model.zip'.")
    target = pathlib.Path(path)
    if target.suffix == "":
        target = target.with_suffix(".zip")  # as SB3's save names it
    if target.is_dir():  # SB3 saved to <path>_2, which load(path) does not read
        raise ValueError(
            f"{algo_name}.save: {str(target)!r} is a folder; save to a file path such as {str(target / 'model.zip')!r}."
        )
    problem = unwritable_folder(target.parent)
    if problem:
        raise ValueError(f"{algo_name}.save: cannot write {str(target)!r}: {problem}; save to a folder you can write.")
    if target.exists() and not os.access(target, os.W_OK):
        raise ValueError(f"{algo_name}.save: {str(target)!r} exists and is not writable; save to another path.")
