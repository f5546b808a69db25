"""Registry of task ids: a name -> a factory returning one PettingZoo ``ParallelEnv`` (one game)."""

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


def get_task_factory(task_id: str) -> Callable[..., ParallelEnv]:
    """A callable building one game of ``task_id``; caller kwargs override the registered defaults."""
    spec = get_task_spec(task_id)
    constructor = spec.load()

    def factory(**kwargs: Any) -> ParallelEnv:
        return constructor(**{**spec.kwargs, **kwargs})

    factory.__name__ = f"make_{task_id.replace('-', '_')}"
    return factory


def make_task(task_id: str, **kwargs: Any) -> ParallelEnv:
    """Build one game (a PettingZoo ``ParallelEnv``) of a registered task."""
    return get_task_factory(task_id)(**kwargs)
