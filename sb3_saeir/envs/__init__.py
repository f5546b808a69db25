"""Tasks: PettingZoo parallel envs and the registry of task ids."""

from sb3_saeir.envs.registry import TaskSpec, get_task_factory, get_task_spec, list_tasks, make_task, register_task

register_task(
    "cn-sparse-n3",
    "sb3_saeir.envs.navigation:SparseCooperativeNavigation",
    kwargs={"N": 3},
    main_metric="coverage_rate",
    description="Sparse Cooperative Navigation, 3 agents / 3 landmarks, 25 steps (mpe2 simple_spread_v3)",
)
register_task(
    "cn-sparse-n4",
    "sb3_saeir.envs.navigation:SparseCooperativeNavigation",
    kwargs={"N": 4},
    main_metric="coverage_rate",
    description="Sparse Cooperative Navigation, 4 agents / 4 landmarks, 25 steps (mpe2 simple_spread_v3)",
)

__all__ = ["TaskSpec", "get_task_factory", "get_task_spec", "list_tasks", "make_task", "register_task"]
