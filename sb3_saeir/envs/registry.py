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


# The readings of sparse navigation that have a task id (docs/tasks.md): (id prefix, game keywords, what the reward is).
# ``cn-sparse-n<N>`` is the task as the paper words it; ``cn-sparse-no-penalty-n<N>`` drops the collision penalty, the
# reading on which MAPPO and SAEIR_PPO reach the paper's Table 1 at its budget (docs/results/navigation-calibrated.md).
NAVIGATION_READINGS: tuple[tuple[str, dict[str, float], str], ...] = (
    ("cn-sparse", {}, "+1 per landmark covered per step, -1 per step with a collision (the paper's words)"),
    (
        "cn-sparse-no-penalty",
        {"collision_penalty": 0.0},
        "+1 per landmark covered per step, no collision penalty (the reading that reaches Table 1)",
    ),
)


def register_packaged_tasks() -> None:
    """Register the package's tasks: sparse Cooperative Navigation with 3 and 4 agents in two reward readings
    (:data:`NAVIGATION_READINGS`), and two football scenarios."""
    for prefix, reward_kwargs, reward in NAVIGATION_READINGS:
        for n_agents in (3, 4):
            register_task(
                f"{prefix}-n{n_agents}",
                NAVIGATION,
                kwargs={"N": n_agents, **reward_kwargs},
                main_metric="coverage_rate",
                description=(
                    f"Sparse Cooperative Navigation, {n_agents} agents / {n_agents} landmarks, 25 steps (original MPE "
                    f"world): {reward}"
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
