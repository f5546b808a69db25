"""Intrinsic rewards: pure functions and the callbacks that put them into training."""

from sb3_saeir.intrinsic.base import IntrinsicRewardCallback, NextObservationRecorder, true_next_observations
from sb3_saeir.intrinsic.elign import ElignCallback, elign_team_bonus
from sb3_saeir.intrinsic.rnd import RNDCallback
from sb3_saeir.intrinsic.saeir import SAEIRCallback, saeir_bonus

__all__ = [
    "ElignCallback",
    "IntrinsicRewardCallback",
    "NextObservationRecorder",
    "RNDCallback",
    "SAEIRCallback",
    "elign_team_bonus",
    "saeir_bonus",
    "true_next_observations",
]
