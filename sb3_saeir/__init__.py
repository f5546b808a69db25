"""sb3-saeir: cooperative multi-agent RL with sparse rewards for Stable-Baselines3 (SAEIR, IJCAI-24)."""

import os

from sb3_saeir.common.vec_env import MultiAgentVecEnv, make_multiagent_vec_env
from sb3_saeir.envs import list_tasks, make_task, register_task
from sb3_saeir.mappo import MAPPO, MAPPOPolicy, SNMAPPOPolicy
from sb3_saeir.saeir_ppo import SAEIR_PPO, MSHGPolicy

with open(os.path.join(os.path.dirname(__file__), "version.txt")) as file_handler:
    __version__ = file_handler.read().strip()

__all__ = [
    "MAPPO",
    "SAEIR_PPO",
    "MAPPOPolicy",
    "MSHGPolicy",
    "MultiAgentVecEnv",
    "SNMAPPOPolicy",
    "__version__",
    "list_tasks",
    "make_multiagent_vec_env",
    "make_task",
    "register_task",
]
