"""One interface for intrinsic rewards: a callback that writes a bonus into the rollout buffer before training."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer


class IntrinsicRewardCallback(BaseCallback, ABC):
    """Base class of intrinsic-reward callbacks (SAEIR, RND, Elign, your own).

    At the end of each rollout, :meth:`compute_bonus` reads the rollout buffer and returns an unscaled bonus; the
    callback adds ``coef * bonus`` to the buffer's intrinsic rewards and re-runs the buffer's GAE, so the returns and
    advantages that training uses include it. (SB3 computes GAE right before ``on_rollout_end``; the buffer keeps the
    last values and dones, so recomputing is exact.) Every bonus reaches training this way.

    Subclass it and implement :meth:`compute_bonus`; optionally override :meth:`_on_step` to see every transition
    (``self.locals``) or :meth:`train_bonus_model` to fit a model on the rollout (RND, Elign)::

        class CountBonus(IntrinsicRewardCallback):
            def compute_bonus(self, buffer):
                return 1.0 / np.sqrt(1.0 + visit_counts(buffer.observations))  # (n_steps, n_envs)

    :param coef: scale of the bonus (beta)
    :param name: prefix of the logged keys (``rollout/<name>_reward_mean``)
    :param verbose: verbosity
    """

    def __init__(self, coef: float = 0.1, name: str = "intrinsic", verbose: int = 0) -> None:
        super().__init__(verbose)
        self.coef = coef
        self.name = name
        self.last_bonus: np.ndarray | None = None

    @abstractmethod
    def compute_bonus(self, buffer: GroupedRecurrentRolloutBuffer) -> np.ndarray:
        """Unscaled bonus of the rollout: ``(n_steps, n_envs)`` for every critic scale, or ``(n_steps, n_envs, K)``.

        :param buffer: the full rollout buffer (observations, actions, rewards, values, episode starts, ...)
        """

    def train_bonus_model(self, buffer: GroupedRecurrentRolloutBuffer) -> None:
        """Hook to update a learned bonus model on the rollout, called after the bonus is computed."""

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        buffer = getattr(self.model, "rollout_buffer", None)
        if not isinstance(buffer, GroupedRecurrentRolloutBuffer):
            raise TypeError(
                f"{type(self).__name__} needs the GroupedRecurrentRolloutBuffer of SAEIR_PPO / MAPPO, got "
                f"{type(buffer).__name__}."
            )
        bonus = np.asarray(self.compute_bonus(buffer), dtype=np.float32)
        buffer.add_intrinsic_rewards(self.coef * bonus)
        buffer.recompute_returns_and_advantage()
        self.train_bonus_model(buffer)
        self.last_bonus = bonus
        self._log_bonus(bonus, buffer)

    def _log_bonus(self, bonus: np.ndarray, buffer: GroupedRecurrentRolloutBuffer) -> None:
        self.logger.record(f"rollout/{self.name}_reward_mean", float(bonus.mean()))
