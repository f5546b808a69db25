"""Tasks: PettingZoo parallel envs and the registry of task ids (importing this registers the package's tasks)."""

from sb3_saeir.envs.registry import (
    TaskSpec,
    get_native_vec_env_factory,
    get_task_factory,
    get_task_spec,
    list_tasks,
    make_task,
    register_task,
)

__all__ = [
    "TaskSpec",
    "get_native_vec_env_factory",
    "get_task_factory",
    "get_task_spec",
    "list_tasks",
    "make_task",
    "register_task",
]
