"""Tasks: PettingZoo parallel envs and the registry of task ids (importing this registers the package's tasks).

The registry's functions (``register_task``, ``list_tasks``, ``get_task_spec``, ``get_task_factory``,
``get_native_vec_env_factory``, ``make_task``, ``TaskSpec``) are re-exported from :mod:`sb3_saeir.envs.registry`.
"""

from sb3_saeir.envs import registry
from sb3_saeir.envs.registry import *  # noqa: F403 (the registry's API, listed in its __all__)

__all__ = list(registry.__all__)
