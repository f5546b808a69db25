"""rl-zoo3 interoperability: rl-zoo3's own ``train`` and ``enjoy`` run the package's methods on its tasks (the
manual: ``docs/guide/zoo.md``).

Importing this package registers every task as a gymnasium id (``--gym-packages sb3_saeir.zoo``), and
``sb3_saeir.zoo.games_to_agents`` is the ``vec_env_wrapper`` of a config entry (:mod:`sb3_saeir.zoo.registration`).
``python -m sb3_saeir.zoo train|enjoy`` is the launcher (:mod:`sb3_saeir.zoo.launcher`); its ``train`` runs rl-zoo3
with :class:`~sb3_saeir.zoo.manager.RunExperimentManager`.
"""

from sb3_saeir.zoo.registration import (
    ENTRY_POINT,
    WRAPPER_NAME,
    GameMonitor,
    SAEIRGameEnv,
    games_to_agents,
    gym_id,
    is_package_env,
    register_algorithms,
    register_gym_envs,
)

__all__ = [
    "ENTRY_POINT",
    "WRAPPER_NAME",
    "GameMonitor",
    "SAEIRGameEnv",
    "games_to_agents",
    "gym_id",
    "is_package_env",
    "register_algorithms",
    "register_gym_envs",
]
