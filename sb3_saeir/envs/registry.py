"""The package's tasks, registered into the task registry :mod:`sb3_saeir.common.registry` (on ``import sb3_saeir``).

The registry's functions are re-exported here and from ``sb3_saeir.envs``: ``register_task``, ``list_tasks``,
``get_task_spec``, ``get_task_factory``, ``get_native_vec_env_factory``, ``make_task`` and ``TaskSpec``. The navigation
tasks register their native vec env
(:class:`~sb3_saeir.envs.navigation_vec_env.NavigationVecEnv`) as ``vec_env_entry_point``, so that the ParallelEnv and
the vec env, two faces of :mod:`sb3_saeir.envs.navigation_core`, do not import each other.
"""

from __future__ import annotations

from sb3_saeir.common.registry import (
    VEC_ENV_KEYS,
    TaskSpec,
    get_native_vec_env_factory,
    get_task_factory,
    get_task_spec,
    list_tasks,
    make_task,
    register_task,
)

__all__ = [
    "VEC_ENV_KEYS",
    "TaskSpec",
    "get_native_vec_env_factory",
    "get_task_factory",
    "get_task_spec",
    "list_tasks",
    "make_task",
    "register_task",
]

NAVIGATION = "sb3_saeir.envs.navigation:SparseCooperativeNavigation"
NAVIGATION_VEC_ENV = "sb3_saeir.envs.navigation_vec_env:NavigationVecEnv"
FOOTBALL = "sb3_saeir.envs.football:FootballEnv"
# The football tasks: (task id, scenario, agents, title).
FOOTBALL_TASKS = (
    ("grf-3v1-keeper", "academy_3_vs_1_with_keeper", 3, "3 vs 1 with keeper"),
    ("grf-counterattack-easy", "academy_counterattack_easy", 4, "counterattack easy"),
)


def register_packaged_tasks() -> None:
    """Register the package's tasks (sparse Cooperative Navigation with 3 and 4 agents, two football scenarios)."""
    for n_agents in (3, 4):
        register_task(
            f"cn-sparse-n{n_agents}",
            NAVIGATION,
            kwargs={"N": n_agents},
            main_metric="coverage_rate",
            description=(
                f"Sparse Cooperative Navigation, {n_agents} agents / {n_agents} landmarks, 25 steps (original MPE "
                "world; world, reward options)"
            ),
            vec_env_entry_point=NAVIGATION_VEC_ENV,
        )
    for task, scenario, n_agents, title in FOOTBALL_TASKS:
        register_task(
            task,
            FOOTBALL,
            kwargs={"scenario": scenario, "N": n_agents},
            main_metric="success",
            description=(
                f"Google Research Football academy {title}, {n_agents} agents, <= 401 steps (needs the football extra)"
            ),
        )


register_packaged_tasks()
