"""Multi-agent vec envs: PettingZoo games as one SB3 ``VecEnv`` with one slot per agent (``docs/guide/custom_env.md``)."""

from sb3_saeir.common.vec_env.base import (
    EPISODE_METRICS_KEY,
    MultiAgentVecEnv,
    RawStep,
    is_multiagent_vec_env,
    joint_observation_space,
)
from sb3_saeir.common.vec_env.black_death import BlackDeathWrapper, black_death
from sb3_saeir.common.vec_env.factory import VEC_ENV_BACKENDS, make_multiagent_vec_env
from sb3_saeir.common.vec_env.game_checks import (
    AgentDeathError,
    CheckedParallelEnv,
    GameFaultError,
    NonFiniteValueError,
    ParallelEnvFactory,
    check_action_space,
    check_finite,
    check_parallel_env,
    check_vec_env_options,
)
from sb3_saeir.common.vec_env.monitor import MultiAgentVecMonitor
from sb3_saeir.common.vec_env.pettingzoo import MultiAgentDummyVecEnv
from sb3_saeir.common.vec_env.workers import GameWorkerError, GameWorkerPool, MultiAgentSubprocVecEnv

__all__ = [
    "EPISODE_METRICS_KEY",
    "VEC_ENV_BACKENDS",
    "AgentDeathError",
    "BlackDeathWrapper",
    "CheckedParallelEnv",
    "GameFaultError",
    "GameWorkerError",
    "GameWorkerPool",
    "MultiAgentDummyVecEnv",
    "MultiAgentSubprocVecEnv",
    "MultiAgentVecEnv",
    "MultiAgentVecMonitor",
    "NonFiniteValueError",
    "ParallelEnvFactory",
    "RawStep",
    "black_death",
    "check_action_space",
    "check_finite",
    "check_parallel_env",
    "check_vec_env_options",
    "is_multiagent_vec_env",
    "joint_observation_space",
    "make_multiagent_vec_env",
]
