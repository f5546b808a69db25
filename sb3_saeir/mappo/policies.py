"""Policy aliases of MAPPO."""

from sb3_saeir.common.policies import MAPPOPolicy, MSHGPolicy, SNMAPPOPolicy

MlpPolicy = MAPPOPolicy

__all__ = ["MAPPOPolicy", "MSHGPolicy", "MlpPolicy", "SNMAPPOPolicy"]
