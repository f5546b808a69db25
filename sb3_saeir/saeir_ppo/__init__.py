from sb3_saeir.saeir_ppo.policies import MlpPolicy, MSHGPolicy
from sb3_saeir.saeir_ppo.saeir_ppo import SAEIR_PPO

__all__ = ["SAEIR_PPO", "MSHGPolicy", "MlpPolicy"]
