"""MAPPO: recurrent multi-agent PPO with a centralised critic, in the same machinery as SAEIR_PPO."""

from __future__ import annotations

from typing import Any, ClassVar

from stable_baselines3.common.policies import BasePolicy

from sb3_saeir.common.policies import MAPPOPolicy, MSHGPolicy, SNMAPPOPolicy
from sb3_saeir.saeir_ppo.saeir_ppo import SAEIR_PPO


class MAPPO(SAEIR_PPO):
    """Recurrent MAPPO (Yu et al., "The Surprising Effectiveness of PPO in Cooperative Multi-Agent Games", NeurIPS
    2022 D&B; code: https://github.com/marlbenchmark/on-policy).

    :class:`~sb3_saeir.SAEIR_PPO` with ``intrinsic_reward=None`` by default and ``"MAPPOPolicy"`` (a single recurrent
    critic on the game's joint observation) as ``"MlpPolicy"``: same actor, rollout, buffer, PPO update, ValueNorm,
    Huber value loss and chunked recurrent training, so that comparisons with SAEIR differ only in the critic and the
    bonus. Baselines and ablations:

    - MAPPO: ``MAPPO("MAPPOPolicy", env)``
    - SN-MAPPO: ``MAPPO("SNMAPPOPolicy", env)`` (spectral norm on the critic's output layer)
    - RND / Elign: ``MAPPO("MAPPOPolicy", env).learn(n, callback=RNDCallback())`` / ``ElignCallback()``
    - MSHG-only ablation: ``MAPPO("MSHGPolicy", env)``
    - SAE-only ablation: ``MAPPO("MAPPOPolicy", env, intrinsic_reward="saeir")``

    All arguments are :class:`~sb3_saeir.SAEIR_PPO`'s.
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MlpPolicy": MAPPOPolicy,
        "MAPPOPolicy": MAPPOPolicy,
        "SNMAPPOPolicy": SNMAPPOPolicy,
        "MSHGPolicy": MSHGPolicy,
    }

    def __init__(self, policy: Any, env: Any, intrinsic_reward: str | None = None, **kwargs: Any) -> None:
        super().__init__(policy, env, intrinsic_reward=intrinsic_reward, **kwargs)

    def learn(self, total_timesteps: int, tb_log_name: str = "MAPPO", **kwargs: Any) -> MAPPO:  # type: ignore[override]
        return super().learn(total_timesteps, tb_log_name=tb_log_name, **kwargs)
