"""sb3-saeir: cooperative multi-agent RL with sparse rewards for Stable-Baselines3 (SAEIR, IJCAI-24)."""

from sb3_saeir.common.stop_signals import exit_on_ctrl_c_while_starting

exit_on_ctrl_c_while_starting()  # python -m sb3_saeir.train (zoo, benchmark): Ctrl-C while importing exits in one line

from sb3_saeir.common.utils import PACKAGE_VERSION  # noqa: E402
from sb3_saeir.common.vec_env import MultiAgentDummyVecEnv, MultiAgentVecEnv, make_multiagent_vec_env  # noqa: E402

# Importing sb3_saeir.envs registers the package's tasks into sb3_saeir.common.registry. Importing any sb3_saeir module
# runs this file first, so they are registered before any code can look a task up.
from sb3_saeir.envs import list_tasks, make_task, register_task  # noqa: E402
from sb3_saeir.mappo import MAPPO, MAPPOPolicy, SNMAPPOPolicy  # noqa: E402
from sb3_saeir.saeir_ppo import SAEIR_PPO, MSHGPolicy  # noqa: E402

__version__ = PACKAGE_VERSION

__all__ = [
    "MAPPO",
    "SAEIR_PPO",
    "MAPPOPolicy",
    "MSHGPolicy",
    "MultiAgentDummyVecEnv",
    "MultiAgentVecEnv",
    "SNMAPPOPolicy",
    "__version__",
    "list_tasks",
    "make_multiagent_vec_env",
    "make_task",
    "register_task",
]
