"""Intrinsic rewards: pure functions and the callbacks that put them into training."""

from sb3_saeir.intrinsic.base import IntrinsicRewardCallback
from sb3_saeir.intrinsic.saeir import SAEIRCallback, saeir_bonus

__all__ = ["IntrinsicRewardCallback", "SAEIRCallback", "saeir_bonus"]
