"""Tasks: PettingZoo parallel envs and the registry of task ids."""

from sb3_saeir.envs.registry import (
    TaskSpec,
    get_native_vec_env_factory,
    get_task_factory,
    get_task_spec,
    list_tasks,
    make_task,
    register_task,
)

register_task(
    "cn-sparse-n3",
    "sb3_saeir.envs.navigation:SparseCooperativeNavigation",
    kwargs={"N": 3},
    main_metric="coverage_rate",
    description="Sparse Cooperative Navigation, 3 agents / 3 landmarks, 25 steps (original MPE world; world, reward options)",
)
register_task(
    "cn-sparse-n4",
    "sb3_saeir.envs.navigation:SparseCooperativeNavigation",
    kwargs={"N": 4},
    main_metric="coverage_rate",
    description="Sparse Cooperative Navigation, 4 agents / 4 landmarks, 25 steps (original MPE world; world, reward options)",
)
register_task(
    "grf-3v1-keeper",
    "sb3_saeir.envs.football:FootballEnv",
    kwargs={"scenario": "academy_3_vs_1_with_keeper", "N": 3},
    main_metric="success",
    description="Google Research Football academy 3 vs 1 with keeper, 3 agents, <= 400 steps (needs the football extra)",
)
register_task(
    "grf-counterattack-easy",
    "sb3_saeir.envs.football:FootballEnv",
    kwargs={"scenario": "academy_counterattack_easy", "N": 4},
    main_metric="success",
    description="Google Research Football academy counterattack easy, 4 agents, <= 400 steps (needs the football extra)",
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
