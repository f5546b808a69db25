"""Policy aliases of SAEIR_PPO."""

from sb3_saeir.common.policies import MSHGPolicy

MlpPolicy = MSHGPolicy

__all__ = ["MSHGPolicy", "MlpPolicy"]
