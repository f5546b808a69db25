"""The package's registries: task ids (a name -> a factory of one PettingZoo ``ParallelEnv``, one game, and optionally a
native vec env of many games: ``vec_env_entry_point`` or a ``native_vec_env`` classmethod,
:func:`get_native_vec_env_factory`) and intrinsic-reward names (``intrinsic_reward="saeir"`` -> the callback class).
The storage and lookups live here; :mod:`sb3_saeir.envs.registry` and ``sb3_saeir.intrinsic`` register the package's
tasks and bonuses on ``import sb3_saeir`` (``docs/tasks.md``, ``docs/guide/custom_env.md``).
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from pettingzoo.utils.env import ParallelEnv
from stable_baselines3.common.callbacks import BaseCallback

BonusClass = TypeVar("BonusClass", bound=type[BaseCallback])


def load_entry_point(entry_point: str) -> Callable[..., Any]:
    """Import the callable an entry point names.

    :param entry_point: ``"module:callable"``
    :return: the callable
    """
    module_name, attr = entry_point.split(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name is None or not module_name.startswith(error.name):
            raise  # a module the entry point's module imports: its own error
        raise ModuleNotFoundError(
            f"entry point {entry_point!r}: no module {module_name!r} ({error})", name=error.name
        ) from None
    if not hasattr(module, attr):
        raise AttributeError(f"entry point {entry_point!r}: module {module_name!r} has no {attr!r}.")
    return getattr(module, attr)


@dataclass(frozen=True)
class TaskSpec:
    """A registered task.

    :param task_id: the id used on the command line and in zoo configs (e.g. ``"cn-sparse-n3"``)
    :param entry_point: ``"module:callable"`` returning a ``ParallelEnv``; imported lazily so that optional extras
        (football) are only needed when their task is created
    :param kwargs: default keyword arguments of the entry point (overridden by the caller's)
    :param main_metric: the per-episode metric that says how good a policy is on this task (used for "best model")
    :param description: one line for ``list_tasks``
    :param vec_env_entry_point: ``"module:callable"`` building the task's native vec env,
        ``(n_games, mark_truncation=False, **kwargs)`` with the entry point's keywords; ``None``: the constructor's
        ``native_vec_env`` classmethod if it has one, else none (the games go through SuperSuit)
    """

    task_id: str
    entry_point: str
    kwargs: dict[str, Any] = field(default_factory=dict)
    main_metric: str = "r"
    description: str = ""
    vec_env_entry_point: str | None = None

    def load(self) -> Callable[..., ParallelEnv]:
        """Import the game's constructor."""
        return load_entry_point(self.entry_point)

    def load_vec_env(self) -> Callable[..., Any] | None:
        """Import the native vec env's builder: the registered one, else the constructor's ``native_vec_env``
        classmethod, else ``None``."""
        if self.vec_env_entry_point is not None:
            return load_entry_point(self.vec_env_entry_point)
        return getattr(self.load(), "native_vec_env", None)


_TASKS: dict[str, TaskSpec] = {}


def register_task(
    task_id: str,
    entry_point: str,
    kwargs: dict[str, Any] | None = None,
    main_metric: str = "r",
    description: str = "",
    vec_env_entry_point: str | None = None,
) -> None:
    """Register a task id (re-registering the same id replaces it).

    :param task_id: the id
    :param entry_point: ``"module:callable"`` returning a PettingZoo ``ParallelEnv``
    :param kwargs: default keyword arguments for the entry point
    :param main_metric: episode metric maximised by "best model" selection (``"r"`` = team return)
    :param description: one line shown by :func:`list_tasks`
    :param vec_env_entry_point: ``"module:callable"`` building a native vec env of the task,
        ``(n_games, mark_truncation=False, **kwargs)``; ``None``: the games go through SuperSuit (unless the
        constructor has a ``native_vec_env`` classmethod)
    """
    if not isinstance(task_id, str) or not task_id.strip():
        raise TypeError(f"register_task: task_id={task_id!r} must be a non-empty string, such as 'my-task-v0'.")
    for name, value in (("entry_point", entry_point), ("vec_env_entry_point", vec_env_entry_point)):
        if value is not None and (not isinstance(value, str) or not re.fullmatch(r"[\w.]+:[\w.]+", value)):
            raise ValueError(
                f"register_task({task_id!r}): {name}={value!r} must be a string 'module:callable' (such as "
                "'my_package.envs:parallel_env'), imported when the task is made."
            )
    if kwargs is not None and not isinstance(kwargs, dict):
        raise TypeError(f"register_task({task_id!r}): kwargs must be a dict of the entry point's keywords, got {kwargs!r}.")
    if not isinstance(main_metric, str) or not main_metric:
        raise TypeError(f"register_task({task_id!r}): main_metric={main_metric!r} must be an episode metric's name ('r').")
    _TASKS[task_id] = TaskSpec(task_id, entry_point, dict(kwargs or {}), main_metric, description, vec_env_entry_point)


def list_tasks() -> list[str]:
    """Registered task ids, sorted."""
    return sorted(_TASKS)


def get_task_spec(task_id: str) -> TaskSpec:
    """The :class:`TaskSpec` of a task id.

    :raises KeyError: with the list of valid ids, for an unknown id
    """
    if task_id not in _TASKS:
        raise KeyError(f"Unknown task {task_id!r}. Registered tasks: {', '.join(list_tasks())}.")
    return _TASKS[task_id]


# Keyword of ``make_multiagent_vec_env`` that may travel with a task's kwargs (``env_kwargs`` of a config, the rl-zoo3
# bridge); it selects how games are vectorised and is not passed to the game's constructor.
VEC_ENV_KEYS = ("backend",)


def game_kwargs(task_id: str, env_kwargs: Any) -> dict[str, Any]:
    """The keyword arguments each game of a task is built with: the task's registered defaults (for navigation, its
    reward options: ``docs/tasks.md``) under ``env_kwargs`` (a config's), without :data:`VEC_ENV_KEYS`.

    :param task_id: the task id (one that is not registered: ``env_kwargs`` alone)
    :param env_kwargs: the config's ``env_kwargs`` (anything but a dict: none)
    """
    registered = _TASKS[task_id].kwargs if task_id in _TASKS else {}
    merged = {**registered, **(env_kwargs if isinstance(env_kwargs, dict) else {})}
    return {key: value for key, value in merged.items() if key not in VEC_ENV_KEYS}


def get_task_factory(task_id: str) -> Callable[..., ParallelEnv]:
    """A callable building one game of ``task_id``; caller kwargs override the registered defaults (a ``backend``
    keyword, which selects the vec env, is ignored)."""
    spec = get_task_spec(task_id)
    constructor = spec.load()

    def factory(**kwargs: Any) -> ParallelEnv:
        return constructor(**game_kwargs(task_id, kwargs))

    factory.__name__ = f"make_{task_id.replace('-', '_')}"
    return factory


def _task_vec_env_factory(spec: TaskSpec) -> Callable[..., Any] | None:
    """The native vec env builder of a registered task, its registered kwargs merged under the caller's.

    :param spec: the task
    """
    native = spec.load_vec_env()
    if native is None:
        return None

    def build(n_games: int, mark_truncation: bool = False, **kwargs: Any) -> Any:
        return native(n_games, mark_truncation=mark_truncation, **{**spec.kwargs, **kwargs})

    return build


def _constructor_vec_env_factory(constructor: Callable[..., Any]) -> Callable[..., Any] | None:
    """The native vec env builder of a game constructor: its ``native_vec_env`` classmethod, else the registered
    ``vec_env_entry_point`` of the first task whose entry point names it (without that task's kwargs), else ``None``.

    :param constructor: the game constructor
    """
    native = getattr(constructor, "native_vec_env", None)
    if native is not None:
        return native
    entry_point = f"{getattr(constructor, '__module__', '')}:{getattr(constructor, '__qualname__', '')}"
    for spec in _TASKS.values():
        if spec.entry_point == entry_point and spec.vec_env_entry_point is not None:
            return load_entry_point(spec.vec_env_entry_point)
    return None


def get_native_vec_env_factory(task: str | Callable[..., Any]) -> Callable[..., Any] | None:
    """The native vec env builder of a task, or ``None`` when the task has none (it then goes through SuperSuit).

    :param task: a registered task id or a game constructor; a task registered with a ``vec_env_entry_point``, or
        whose constructor has a ``native_vec_env`` attribute (a classmethod ``native_vec_env(n_games,
        mark_truncation=False, **kwargs)``), has a native vec env, and so has the constructor a registered task names
    :return: a callable ``(n_games, mark_truncation=..., **kwargs)`` returning the vec env (for a task id, the
        registered defaults merged with the caller's kwargs)
    """
    if isinstance(task, str):
        return _task_vec_env_factory(get_task_spec(task))
    return _constructor_vec_env_factory(task)


def make_task(task_id: str, **kwargs: Any) -> ParallelEnv:
    """Build one game (a PettingZoo ``ParallelEnv``) of a registered task."""
    return get_task_factory(task_id)(**kwargs)


# ------------------------------------------------------------------------------------------------ intrinsic rewards
# ``intrinsic_reward=<name>`` -> the IntrinsicRewardCallback subclass the algorithm adds (:func:`register_intrinsic_reward`)
INTRINSIC_REWARDS: dict[str, type[BaseCallback]] = {}


def register_intrinsic_reward(name: str) -> Callable[[BonusClass], BonusClass]:
    """Class decorator: make an :class:`~sb3_saeir.intrinsic.IntrinsicRewardCallback` subclass available as
    ``MAPPO(..., intrinsic_reward=name)`` (and in configs), without editing the algorithm. Re-registering a name
    replaces it, as :func:`register_task` does (``docs/guide/examples.md``, "Your own intrinsic reward")::

        @register_intrinsic_reward("count")
        class CountBonus(IntrinsicRewardCallback): ...

    :param name: the ``intrinsic_reward`` value that selects the class
    :return: the decorator, which returns the class unchanged
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"register_intrinsic_reward: the name must be a non-empty string, got {name!r}.")

    def register(bonus_class: BonusClass) -> BonusClass:
        # IntrinsicRewardCallback lives above this module (sb3_saeir.intrinsic): its interface is checked instead
        if not (isinstance(bonus_class, type) and issubclass(bonus_class, BaseCallback) and hasattr(bonus_class, "add_to")):
            raise TypeError(
                f"register_intrinsic_reward({name!r}): {bonus_class!r} is not a subclass of "
                "sb3_saeir.intrinsic.IntrinsicRewardCallback."
            )
        INTRINSIC_REWARDS[name] = bonus_class
        return bonus_class

    return register
