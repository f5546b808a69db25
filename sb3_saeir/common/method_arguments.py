"""Checks of the arguments of an algorithm's methods after construction (``learn``, ``load``, ``set_parameters``): each bad
argument is one line naming it and what it must be, before SB3 or torch fail on it with their own errors
(``docs/guide/algorithms.md``). The constructor's checks are in :mod:`sb3_saeir.common.checks`, those of a saved
model in :mod:`sb3_saeir.common.saved_model_checks`.
"""

from __future__ import annotations

import os
from typing import Any

import torch as th
from stable_baselines3.common.callbacks import BaseCallback

from sb3_saeir.common import checks, saved_model_checks
from sb3_saeir.common.saved_model_checks import ParameterNamesError
from sb3_saeir.common.utils import check_bool, check_seed


class ParameterShapesError(ParameterNamesError):
    """Parameters of another shape than the model's (:func:`check_parameter_shapes`); as for names, ``load`` says
    which of its arguments caused it (``custom_objects`` ``policy_kwargs`` of other sizes, or a damaged zip)."""


def check_learn_arguments(
    algo_name: str,
    env: Any,
    total_timesteps: Any,
    callback: Any,
    log_interval: Any,
    tb_log_name: Any,
    reset_num_timesteps: Any,
    progress_bar: Any,
) -> int:
    """The checks of ``learn``, before SB3 sets anything up, in order: ``total_timesteps`` (a whole float such as
    ``1e6`` is taken, as SB3 takes it; a fraction is refused), ``callback``, ``log_interval``, then the model's env and
    the other options (:func:`check_learn_options`).

    :param algo_name: class name for the message
    :param env: the model's env
    :param total_timesteps: the ``total_timesteps`` argument (agent-steps)
    :param callback: the ``callback`` argument
    :param log_interval: the ``log_interval`` argument
    :param tb_log_name: the ``tb_log_name`` argument
    :param reset_num_timesteps: the ``reset_num_timesteps`` argument
    :param progress_bar: the ``progress_bar`` argument
    :return: ``total_timesteps`` as an ``int``
    """
    if isinstance(total_timesteps, float) and total_timesteps.is_integer():
        total_timesteps = int(total_timesteps)
    checks.check_ranges(algo_name, total_timesteps=total_timesteps)
    owner = f"{algo_name}.learn"
    check_callback(owner, callback)
    check_log_interval(owner, log_interval)
    check_learn_options(owner, env, tb_log_name, reset_num_timesteps, progress_bar)
    return total_timesteps


def check_callback(owner: str, callback: Any) -> None:
    """Refuse a ``learn`` callback SB3 cannot use: it takes ``None``, a ``BaseCallback``, a callable ``(locals,
    globals) -> bool`` or a list of these (SB3 failed with ``'int' object is not callable`` in the first step).

    :param owner: who checks, for the message (``"MAPPO.learn"``)
    :param callback: the ``callback`` argument
    """
    items = callback if isinstance(callback, list) else [callback]
    for item in items:
        if item is not None and not isinstance(item, BaseCallback) and not callable(item):
            where = f"callback list item {item!r}" if isinstance(callback, list) else f"callback={item!r}"
            raise TypeError(
                f"{owner}: {where} is not a callback; pass an SB3 BaseCallback, a function (locals, globals) -> bool, "
                "a list of these, or None."
            )


def check_log_interval(owner: str, log_interval: Any) -> None:
    """Refuse a ``log_interval`` that is not a whole number >= 1 (SB3 divided by it: ``log_interval=0`` was a
    ``ZeroDivisionError`` after the first rollout).

    :param owner: who checks, for the message (``"MAPPO.learn"``)
    :param log_interval: the ``log_interval`` argument (rollouts between two logger dumps)
    """
    if isinstance(log_interval, bool) or not isinstance(log_interval, int) or log_interval < 1:
        raise ValueError(
            f"{owner}: log_interval={log_interval!r} must be a whole number >= 1 (rollouts between two logger dumps)."
        )


def check_parameter_shapes(owner: str, params: dict[str, Any], model: Any) -> None:
    """For ``set_parameters``: refuse tensors of another shape than the model's, before any is set (torch's
    ``load_state_dict`` listed each over several lines, having set the others).

    :param owner: who sets them, for the message (``"MAPPO.set_parameters"``)
    :param params: object name (``"policy"``, ...) -> state dict, as ``get_parameters`` returns them
    :param model: the model whose parameters are set
    :raises ParameterShapesError: one line naming a few mismatched entries, their shapes and the fix
    """
    from stable_baselines3.common.save_util import recursive_getattr

    mismatched = []
    for name, given in params.items():
        try:
            target = recursive_getattr(model, name) if isinstance(given, dict) else None
        except AttributeError:  # not the model's: exact_match=False skips it, exact_match=True has named it
            continue
        if not isinstance(target, th.nn.Module):
            continue
        own = target.state_dict()
        for key, tensor in given.items():
            if key in own and isinstance(tensor, th.Tensor) and tuple(tensor.shape) != tuple(own[key].shape):
                mismatched.append(f"{name}[{key!r}] {tuple(tensor.shape)} for {tuple(own[key].shape)}")
    if mismatched:
        shown = "; ".join(mismatched[:3]) + (f" and {len(mismatched) - 3} more" if len(mismatched) > 3 else "")
        raise ParameterShapesError(
            f"{owner}: parameters of another shape than this model's: {shown}; nothing was set. Pass the parameters of "
            "a model built with the same network settings (policy_kwargs) and env.",
            f"size mismatch: {shown}",
        )


def check_learn_options(owner: str, env: Any, tb_log_name: Any, reset_num_timesteps: Any, progress_bar: Any) -> None:
    """Refuse ``learn`` options SB3 misreads: a model without an env (loaded without ``env=``: SB3's empty
    ``AssertionError``), a ``tb_log_name`` that is not a folder name (``None`` failed in ``os.path``; a path wrote
    outside ``tensorboard_log``), and ``reset_num_timesteps`` / ``progress_bar`` that are not bools (``"no"`` was
    read as True).

    :param owner: who checks, for the message (``"MAPPO.learn"``)
    :param env: the model's env
    :param tb_log_name: the ``tb_log_name`` argument
    :param reset_num_timesteps: the ``reset_num_timesteps`` argument
    :param progress_bar: the ``progress_bar`` argument
    """
    if env is None:
        raise ValueError(
            f"{owner}: the model has no env to train on (loaded without env=?); pass env= to load, or call "
            "model.set_env(env) first."
        )
    check_bool(owner, reset_num_timesteps=reset_num_timesteps, progress_bar=progress_bar)
    separators = {"/", os.sep} | ({os.altsep} if os.altsep else set())
    if not isinstance(tb_log_name, str) or tb_log_name in ("", ".", "..") or any(sep in tb_log_name for sep in separators):
        raise ValueError(
            f"{owner}: tb_log_name={tb_log_name!r} must be a folder name such as 'MAPPO' (no path): tensorboard writes "
            "into <tensorboard_log>/<tb_log_name>_<N>."
        )


def check_custom_objects(owner: str, custom_objects: Any) -> None:
    """Refuse ``load``'s ``custom_objects`` that are not a dict (``None`` passes).

    :param owner: who checks, for the message (``"MAPPO.load"``)
    :param custom_objects: the ``custom_objects`` argument
    """
    if custom_objects is not None and not isinstance(custom_objects, dict):
        raise TypeError(
            f"{owner}: custom_objects={custom_objects!r} must be a dict of attribute name -> value, such as "
            "{'learning_rate': 0.0}."
        )


def check_parameters_file(owner: str, path: Any) -> None:
    """For ``set_parameters`` from a file: one line for a path where there is no file (SB3 named ``<path>.zip``, the
    second name it tries). A file object passes.

    :param owner: who checks, for the message (``"MAPPO.set_parameters"``)
    :param path: the ``load_path_or_dict`` argument
    """
    if isinstance(path, (str, os.PathLike)) and not os.path.isfile(path) and not os.path.isfile(f"{os.fspath(path)}.zip"):
        raise FileNotFoundError(f"{owner}: no such file {os.fspath(path)!r}; pass a model zip or get_parameters()'s dict.")


def check_load(
    algo_name: str, path: Any, env: Any, device: Any, custom_objects: Any, kwargs: dict[str, Any]
) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """The checks of ``load``, before SB3 reads the model, in order: ``custom_objects``, the constructor's checks on
    the overrides (``kwargs`` and ``custom_objects``: :func:`~sb3_saeir.common.checks.check_overrides`; with
    ``custom_objects={"learning_rate": 0.0}``, rl-zoo3's load for inference, ``learning_rate`` is not checked), the
    ``seed`` override, ``device``, ``env``, the path (:func:`~sb3_saeir.common.saved_model_checks.check_load_arguments`)
    and the saved model against the env (:func:`~sb3_saeir.common.saved_model_checks.check_saved_model`).

    :param algo_name: class name for the message
    :param path: the ``path`` argument of ``load``
    :param env: the ``env`` argument of ``load``
    :param device: the ``device`` argument of ``load``
    :param custom_objects: the ``custom_objects`` argument of ``load``
    :param kwargs: the other keyword arguments of ``load`` (attributes set on the loaded model)
    :return: ``kwargs``, with a ``seed`` as a Python ``int``, and the zip's ``data``
        (:func:`~sb3_saeir.common.saved_model_checks.saved_data`; ``None`` when it cannot be read)
    """
    check_custom_objects(f"{algo_name}.load", custom_objects)
    overrides = {**(custom_objects or {}), **kwargs}
    checks.check_overrides(algo_name, overrides, inference=(custom_objects or {}).get("learning_rate") == 0.0)
    if "seed" in kwargs:
        kwargs = {**kwargs, "seed": check_seed(algo_name, kwargs["seed"])}
    checks.check_device(algo_name, device)
    if env is not None:
        checks.check_env_argument(algo_name, env)
    saved_model_checks.check_load_arguments(algo_name, path, custom_objects)
    data = saved_model_checks.saved_data(path)
    if data is not None:
        saved_model_checks.check_saved_model(algo_name, path, data, env)
    return kwargs, data


def check_parameters(owner: str, params: dict[str, Any], model: Any, exact_match: bool) -> None:
    """The checks of the parameters given to ``set_parameters``, before any is set: with ``exact_match`` (and a built
    policy), a network of the other kind (:func:`~sb3_saeir.common.saved_model_checks.check_network_kind`) and entries
    missing or unknown (:func:`~sb3_saeir.common.saved_model_checks.check_parameter_names`); then the shapes
    (:func:`check_parameter_shapes`).

    :param owner: who sets them, for the message (``"MAPPO.set_parameters"``)
    :param params: object name (``"policy"``, ...) -> state dict, as ``get_parameters`` returns them
    :param model: the model whose parameters are set
    :param exact_match: the ``exact_match`` argument (already checked to be a bool)
    """
    policy = getattr(model, "policy", None)
    if exact_match and policy is not None:
        saved_policy = params.get("policy")
        if isinstance(saved_policy, dict):
            saved_model_checks.check_network_kind(owner, saved_policy, policy)
        saved_model_checks.check_parameter_names(owner, params, model)
    check_parameter_shapes(owner, params, model)
