"""The arguments of the multi-agent policies (:mod:`sb3_saeir.common.policies`): the SB3 ``ActorCriticPolicy``
arguments they refuse or accept only as no-ops, the checks of their optimizer arguments and their optimizer defaults, and
``MSHGPolicy``'s default critic scales."""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import torch as th

from sb3_saeir.common.hypergraph import SCALES
from sb3_saeir.common.utils import keywords_taken, user_stacklevel

# What to use instead of gSDE (SB3's use_sde), refused by the policies and by the algorithms alike.
GSDE_UNSUPPORTED = "gSDE is not supported; continuous actions use a diagonal Gaussian (log_std_init sets its start)"
# SB3 ActorCriticPolicy arguments these policies cannot honour, with what to use instead.
_UNSUPPORTED_SB3_ARGUMENTS = {
    "net_arch": "the networks follow the paper's layout; set their width with hidden_size",
    "features_extractor_class": "observations go to the actor and critics as flat vectors; flatten them in the env "
    "(supersuit.flatten_v0)",
    "features_extractor_kwargs": "features extractors are not used; flatten observations in the env",
    "use_sde": GSDE_UNSUPPORTED,
}
# SB3 arguments accepted when their value does nothing here (SB3 passes them when it rebuilds a saved policy).
_SB3_NOOP_VALUES: dict[str, tuple[Any, ...]] = {
    "net_arch": (None,),
    "features_extractor_class": (None, "FlattenExtractor"),
    "features_extractor_kwargs": (None,),
    "use_sde": (False,),
    "squash_output": (None, False),
    "full_std": (None, True),
    "use_expln": (None, False),
    "normalize_images": (None, True, False),
    "share_features_extractor": (True,),
}


def _is_noop(key: str, value: Any) -> bool:
    if key in ("net_arch", "features_extractor_kwargs") and isinstance(value, (dict, list)) and not value:
        return True
    if key == "features_extractor_class" and isinstance(value, type):
        value = value.__name__
    accepted_values = _SB3_NOOP_VALUES[key]
    return any(value is accepted or (type(value) is type(accepted) and value == accepted) for accepted in accepted_values)


def check_sb3_policy_kwargs(policy_name: str, sb3_kwargs: dict[str, Any], ortho_init: bool) -> None:
    """Reject SB3 policy arguments that would be silently ignored, naming the argument to use instead.

    :param policy_name: class name for the message
    :param sb3_kwargs: the extra keyword arguments the policy received
    :param ortho_init: the ``ortho_init`` argument (only ``True`` is supported)
    :raises ValueError: for an unknown key, ``ortho_init=False``, or an SB3 argument with a value that would do nothing
    """
    if not ortho_init:
        raise ValueError(
            f"{policy_name}: ortho_init=False is not supported (every layer uses the paper's orthogonal "
            "initialisation); remove the argument."
        )
    for key, value in sb3_kwargs.items():
        if key not in _SB3_NOOP_VALUES:
            raise ValueError(
                f"{policy_name}: unknown policy argument {key!r}. Valid arguments: hidden_size, activation_fn, "
                "recurrent, recurrent_actor, normalize_values, value_norm_beta, critic_gumbel_noise, log_std_init, "
                "optimizer_class, optimizer_kwargs, and the critic's own options (see the policy's docstring)."
            )
        if _is_noop(key, value):
            continue
        if key == "share_features_extractor":
            raise ValueError(
                f"{policy_name}: share_features_extractor=False is not supported (the actor and every critic have "
                "their own networks and there is no features extractor to share); remove the argument."
            )
        hint = _UNSUPPORTED_SB3_ARGUMENTS.get(key, "remove the argument")
        raise ValueError(f"{policy_name}: policy argument {key}={value!r} is not supported: {hint}.")


def check_optimizer_arguments(
    policy_name: str, optimizer_class: Any, optimizer_kwargs: dict[str, Any] | None
) -> dict[str, Any]:
    """Check ``optimizer_class`` and ``optimizer_kwargs`` before the networks are built, and give the kwargs the
    optimizer is built with (:func:`default_optimizer_kwargs` when ``None``). PyTorch's own messages named neither
    argument (``'str' object is not callable``, ``got multiple values for keyword argument 'lr'``).

    :param policy_name: class name for the message
    :param optimizer_class: the ``optimizer_class`` argument: a subclass of ``torch.optim.Optimizer``
    :param optimizer_kwargs: the ``optimizer_kwargs`` argument: ``None`` or a dict of the class's keyword arguments,
        without ``params`` and ``lr`` (the model's ``learning_rate`` sets the learning rate)
    :return: the keyword arguments the optimizer is built with
    :raises ValueError: for a class that is not an optimizer, kwargs that are not a dict, ``params`` or ``lr`` among
        them, or a keyword the class does not take
    """
    if not (isinstance(optimizer_class, type) and issubclass(optimizer_class, th.optim.Optimizer)):
        raise ValueError(
            f"{policy_name}: optimizer_class={optimizer_class!r} is not a PyTorch optimizer class; pass a subclass of "
            "torch.optim.Optimizer, e.g. optimizer_class=torch.optim.Adam (the class, not its name)."
        )
    if optimizer_kwargs is None:
        return default_optimizer_kwargs(optimizer_class)
    if not isinstance(optimizer_kwargs, dict) or not all(isinstance(key, str) for key in optimizer_kwargs):
        raise ValueError(
            f"{policy_name}: optimizer_kwargs={optimizer_kwargs!r} is not a dict of keyword arguments; pass e.g. "
            "optimizer_kwargs=dict(eps=1e-5)."
        )
    if "lr" in optimizer_kwargs or "params" in optimizer_kwargs:
        key = "lr" if "lr" in optimizer_kwargs else "params"
        fix = "pass learning_rate= to the algorithm (a float or a schedule)" if key == "lr" else "remove it"
        raise ValueError(f"{policy_name}: optimizer_kwargs sets {key!r}, which the policy sets itself; {fix}.")
    accepted = keywords_taken(optimizer_class)
    if accepted is None:  # **kwargs or no signature to read: the class itself will check
        return dict(optimizer_kwargs)
    unknown = sorted(set(optimizer_kwargs) - set(accepted))
    if unknown:
        takes = ", ".join(name for name in accepted if name not in ("params", "lr"))
        raise ValueError(
            f"{policy_name}: optimizer_kwargs has {', '.join(map(repr, unknown))}, which "
            f"{optimizer_class.__name__} does not take; it takes: {takes}."
        )
    return dict(optimizer_kwargs)


def default_optimizer_kwargs(optimizer_class: type[th.optim.Optimizer]) -> dict[str, Any]:
    """The policies' optimizer kwargs when none are given: MAPPO's ``eps=1e-5``, and PyTorch's fused kernel for Adam
    and AdamW (one kernel over all parameter tensors instead of several multi-tensor ``_foreach_*`` ops; the same
    update up to float rounding, ``docs/guide/performance.md``), ``foreach=True`` for other optimizer classes. A class
    is given only the keywords its constructor takes (``torch.optim.SGD`` has no ``eps``: it gets ``foreach`` alone);
    a class whose keywords its signature cannot tell (``**kwargs``) gets none: pass ``optimizer_kwargs`` to set them.

    :param optimizer_class: the policy's optimizer class
    :return: the keyword arguments the optimizer is built with
    """
    if optimizer_class in (th.optim.Adam, th.optim.AdamW):
        return {"eps": 1e-5, "fused": True}
    defaults = {"eps": 1e-5, "foreach": True}
    accepted = keywords_taken(optimizer_class)
    if accepted is None:  # **kwargs or no signature to read: PyTorch's defaults, which never name a keyword it lacks
        return {}
    return {name: value for name, value in defaults.items() if name in accepted}


DEFAULT_GROUP_SIZE = 2  # k of the group scale (the authors' ``num_in_group``)


def default_scales(n_agents: int) -> tuple[str, ...]:
    """The default critic scales for ``n_agents`` agents: all of ``SCALES`` (:mod:`sb3_saeir.common.hypergraph`),
    without the group scale where the default group size is not smaller than the team (its hyperedges would hold the
    whole team), with a warning."""
    if n_agents <= 1 or DEFAULT_GROUP_SIZE < n_agents:
        return SCALES
    warnings.warn(
        f"MSHGPolicy: the group scale is left out with {n_agents} agents per game (group_size={DEFAULT_GROUP_SIZE} "
        "groups would hold the whole team and copy the team critic); the critics are ('team', 'individual').",
        UserWarning,
        stacklevel=user_stacklevel(),
    )
    return tuple(scale for scale in SCALES if scale != "group")


def warn_degenerate_group_scale(group_size: int) -> None:
    """Warn (one line) that the group scale is degenerate on one-agent games: with ``group_size >= N`` its hyperedges
    are the team's one all-ones edge, which with a single agent is also the individual scale's edge
    (``docs/method.md``, "The critic"), so every critic sees the same one-node hypergraph.

    :param group_size: k of the group scale
    """
    warnings.warn(
        f"MSHGPolicy: the group scale is degenerate with 1 agent per game (group_size={group_size} >= N = 1 makes its "
        "hyperedge the team's, and with one agent the team and individual hyperedges are the same one-agent edge): "
        "every critic sees the same hypergraph; train on games of 2 or more agents, or pass "
        "policy_kwargs=dict(scales=('team',)) for one critic.",
        UserWarning,
        stacklevel=user_stacklevel(),
    )


# NumPy dtype kinds that predict takes as observations: bool, signed and unsigned integers, floats.
NUMBER_KINDS = "biuf"


def check_predict_observation(observation: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``observation`` of a policy's ``predict`` as float32, checked: ``(d,)`` or ``(B, d)`` of finite numbers, of a
    bool, integer or float dtype (NumPy casts strings such as ``"0.5"`` and complex numbers to float32 without an
    error).

    :param observation: what ``predict`` was given
    :param shape: one agent's observation shape (the observation space's)
    :raises ValueError: one line naming ``observation`` and the shape or dtype expected
    """
    try:
        given = np.asarray(observation)
    except (TypeError, ValueError) as error:
        raise ValueError(
            f"predict: observation must be an array of numbers of shape {shape} or (n_agents, *{shape}); {error}"
        ) from None
    if given.dtype.kind not in NUMBER_KINDS:
        raise ValueError(
            f"predict: the observation must be an array of numbers, got dtype {given.dtype}; pass bool, integer or "
            "float values."
        )
    obs_array = given.astype(np.float32)
    if obs_array.shape != shape and obs_array.shape[1:] != shape:
        raise ValueError(
            f"predict: observation of shape {obs_array.shape} does not match the observation space: expected one "
            f"agent's {shape} or a batch (n_agents, *{shape})."
        )
    if not np.isfinite(obs_array).all():
        raise ValueError("predict: observation holds NaN or infinite values; pass finite observations.")
    return obs_array


def check_predict_array(name: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``state`` or ``episode_start`` of a policy's ``predict`` as float32 of the shape the observations imply.

    :param name: the argument's name
    :param value: what ``predict`` was given
    :param shape: the shape expected
    :raises ValueError: one line naming the argument and the shape expected
    """
    try:
        array = np.asarray(value, dtype=np.float32)
    except (TypeError, ValueError) as error:
        raise ValueError(f"predict: {name} must be an array of numbers of shape {shape}; {error}") from None
    if array.size != int(np.prod(shape)) or (array.ndim > 0 and array.shape[-1] != shape[-1]):
        raise ValueError(
            f"predict: {name} of shape {array.shape} does not match the observations: expected {shape} "
            "(one row per agent; pass the state predict returned, or None)."
        )
    return array.reshape(shape)
