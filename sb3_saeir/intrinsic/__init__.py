"""Intrinsic rewards: pure functions and the callbacks that put them into training.

Each callback registers its ``intrinsic_reward`` name with :func:`register_intrinsic_reward` (``"saeir"``, ``"rnd"``,
``"elign"``); :data:`INTRINSIC_REWARDS` maps the names to the classes.
"""

from sb3_saeir.common.registry import INTRINSIC_REWARDS, register_intrinsic_reward
from sb3_saeir.intrinsic.base import IntrinsicRewardCallback, NextObservationRecorder, true_next_observations
from sb3_saeir.intrinsic.elign import ElignCallback, elign_team_bonus
from sb3_saeir.intrinsic.rnd import RNDCallback
from sb3_saeir.intrinsic.saeir import SAEIRCallback, saeir_bonus

__all__ = [
    "INTRINSIC_REWARDS",
    "ElignCallback",
    "IntrinsicRewardCallback",
    "NextObservationRecorder",
    "RNDCallback",
    "SAEIRCallback",
    "elign_team_bonus",
    "register_intrinsic_reward",
    "saeir_bonus",
    "true_next_observations",
]
