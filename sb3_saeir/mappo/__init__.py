from sb3_saeir.mappo.mappo import MAPPO
from sb3_saeir.mappo.policies import MAPPOPolicy, MlpPolicy, MSHGPolicy, SNMAPPOPolicy

__all__ = ["MAPPO", "MAPPOPolicy", "MSHGPolicy", "MlpPolicy", "SNMAPPOPolicy"]
