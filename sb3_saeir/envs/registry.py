"""Registry of task ids: a name -> a factory returning one PettingZoo ``ParallelEnv`` (one game).

A task's constructor may also offer a native multi-agent vec env of many games (a classmethod
``native_vec_env(n_games, mark_truncation=False, **kwargs)``, as the navigation tasks do, see ``docs/tasks.md``);
:func:`get_native_vec_env_factory` finds it and ``make_multiagent_vec_env`` uses it instead of SuperSuit.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pettingzoo.utils.env import ParallelEnv


@dataclass(frozen=True)
class TaskSpec:
    """A registered task.

    :param task_id: the id used on the command line and in zoo configs (e.g. ``"cn-sparse-n3"``)
    :param entry_point: ``"module:callable"`` returning a ``ParallelEnv``; imported lazily so that optional extras
        (football) are only needed when their task is created
    :param kwargs: default keyword arguments of the entry point (overridden by the caller's)
    :param main_metric: the per-episode metric that says how good a policy is on this task (used for "best model")
    :param description: one line for ``list_tasks``
    """

    task_id: str
    entry_point: str
    kwargs: dict[str, Any] = field(default_factory=dict)
    main_metric: str = "r"
    description: str = ""

    def load(self) -> Callable[..., ParallelEnv]:
        module_name, attr = self.entry_point.split(":")
        return getattr(importlib.import_module(module_name), attr)


_TASKS: dict[str, TaskSpec] = {}


def register_task(
    task_id: str,
    entry_point: str,
    kwargs: dict[str, Any] | None = None,
    main_metric: str = "r",
    description: str = "",
) -> None:
    """Register a task id (re-registering the same id replaces it).

    :param task_id: the id
    :param entry_point: ``"module:callable"`` returning a PettingZoo ``ParallelEnv``
    :param kwargs: default keyword arguments for the entry point
    :param main_metric: episode metric maximised by "best model" selection (``"r"`` = team return)
    :param description: one line shown by :func:`list_tasks`
    """
    _TASKS[task_id] = TaskSpec(task_id, entry_point, dict(kwargs or {}), main_metric, description)


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


def get_task_factory(task_id: str) -> Callable[..., ParallelEnv]:
    """A callable building one game of ``task_id``; caller kwargs override the registered defaults (a ``backend``
    keyword, which selects the vec env, is ignored)."""
    spec = get_task_spec(task_id)
    constructor = spec.load()

    def factory(**kwargs: Any) -> ParallelEnv:
        game_kwargs = {key: value for key, value in kwargs.items() if key not in VEC_ENV_KEYS}
        return constructor(**{**spec.kwargs, **game_kwargs})

    factory.__name__ = f"make_{task_id.replace('-', '_')}"
    return factory


def get_native_vec_env_factory(task: str | Callable[..., Any]) -> Callable[..., Any] | None:
    """The native vec env builder of a task, or ``None`` when the task has none (it then goes through SuperSuit).

    :param task: a registered task id or a game constructor; a constructor with a ``native_vec_env`` attribute (a
        classmethod ``native_vec_env(n_games, mark_truncation=False, **kwargs)``) has a native vec env
    :return: a callable ``(n_games, mark_truncation=..., **kwargs)`` returning the vec env (registered defaults merged
        with the caller's kwargs)
    """
    if isinstance(task, str):
        spec = get_task_spec(task)
        native = getattr(spec.load(), "native_vec_env", None)
        if native is None:
            return None

        def build(n_games: int, mark_truncation: bool = False, **kwargs: Any) -> Any:
            return native(n_games, mark_truncation=mark_truncation, **{**spec.kwargs, **kwargs})

        return build
    return getattr(task, "native_vec_env", None)


def make_task(task_id: str, **kwargs: Any) -> ParallelEnv:
    """Build one game (a PettingZoo ``ParallelEnv``) of a registered task."""
    return get_task_factory(task_id)(**kwargs)
