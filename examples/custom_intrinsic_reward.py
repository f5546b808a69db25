"""Write your own intrinsic reward: subclass IntrinsicRewardCallback and implement compute_bonus.

    python examples/custom_intrinsic_reward.py

The bonus below is a count-based novelty bonus on each agent's discretised position (1 / sqrt(visits)). It reaches
training exactly as SAEIR, RND and Elign do: the callback adds ``coef * bonus`` to the rollout buffer's intrinsic
rewards and re-runs the GAE before the PPO update.
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from sb3_saeir import MAPPO, make_multiagent_vec_env
from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer
from sb3_saeir.common.utils import set_num_threads
from sb3_saeir.intrinsic import IntrinsicRewardCallback


class PositionCountBonus(IntrinsicRewardCallback):
    """1 / sqrt(number of visits) of the agent's position cell (mpe2 navigation: position = obs[2:4]).

    :param cell_size: side of a grid cell
    :param coef: scale of the bonus
    """

    def __init__(self, cell_size: float = 0.2, coef: float = 0.05) -> None:
        super().__init__(coef=coef, name="count")
        self.cell_size = cell_size
        self.visits: Counter = Counter()

    def compute_bonus(self, buffer: GroupedRecurrentRolloutBuffer) -> np.ndarray:
        cells = np.floor(buffer.observations[..., 2:4] / self.cell_size).astype(int)  # (T, E, 2)
        keys = [tuple(cell) for cell in cells.reshape(-1, 2)]
        self.visits.update(keys)
        counts = np.array([self.visits[key] for key in keys], dtype=np.float32).reshape(cells.shape[:2])  # (T, E)
        return 1.0 / np.sqrt(counts)  # one bonus per step and agent, shared by every critic scale


if __name__ == "__main__":
    set_num_threads(None)  # the free cores, at most 2 (OMP_NUM_THREADS wins); see docs/guide/faq.md
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=8, seed=0)
    model = MAPPO("MAPPOPolicy", env, seed=0, verbose=1)
    model.learn(20_000, callback=PositionCountBonus())
