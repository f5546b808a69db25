"""One interface for intrinsic rewards: a callback that writes a bonus into the rollout buffer before training."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer
from sb3_saeir.common.utils import check_number


class IntrinsicRewardCallback(BaseCallback, ABC):
    """Base class of intrinsic-reward callbacks (SAEIR, RND, Elign, your own).

    At the end of each rollout, after the bootstrap values and before GAE, the algorithm
    (:class:`~sb3_saeir.MAPPO`, :class:`~sb3_saeir.SAEIR_PPO`) calls :meth:`add_to`: :meth:`compute_bonus` reads the
    rollout buffer and returns an unscaled bonus, ``coef * bonus`` goes into the buffer's intrinsic rewards, then
    :meth:`train_bonus_model` runs. GAE then runs once with every bonus in, and only then do the callbacks'
    ``on_rollout_end`` run, so every callback sees the final advantages whatever the order of the callback list
    (``docs/method.md``, "One rollout").

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
        check_number(type(self).__name__, "coef", coef, ">= 0", lambda x: x >= 0)
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

    def _init_callback(self) -> None:
        if not isinstance(getattr(self.model, "rollout_buffer", None), GroupedRecurrentRolloutBuffer):
            raise TypeError(
                f"{type(self).__name__} needs the GroupedRecurrentRolloutBuffer of MAPPO / SAEIR_PPO (which add the "
                f"bonus before GAE), got {type(getattr(self.model, 'rollout_buffer', None)).__name__} "
                f"of {type(self.model).__name__}."
            )

    def add_to(self, buffer: GroupedRecurrentRolloutBuffer) -> np.ndarray:
        """Compute the bonus of the rollout in ``buffer``, add ``coef * bonus`` to its intrinsic rewards, train the
        bonus model and log. Called by the algorithm before GAE.

        :param buffer: the full rollout buffer, with its bootstrap (``last_values``, ``last_dones``) set
        :return: the unscaled bonus
        """
        bonus = np.asarray(self.compute_bonus(buffer), dtype=np.float32)
        buffer.add_intrinsic_rewards(self.coef * bonus)
        self.train_bonus_model(buffer)
        self.last_bonus = bonus
        self._log_bonus(bonus, buffer)
        return bonus

    def _log_bonus(self, bonus: np.ndarray, buffer: GroupedRecurrentRolloutBuffer) -> None:
        self.logger.record(f"rollout/{self.name}_reward_mean", float(bonus.mean()))


def true_next_observations(new_obs: np.ndarray, dones: np.ndarray, infos: Sequence[dict[str, Any]]) -> np.ndarray:
    """The observation that followed each slot's action: ``new_obs``, except where the game ended, where SB3's
    ``VecEnv`` has already put the reset observation into ``new_obs`` and the real one into
    ``infos[i]["terminal_observation"]``.

    :param new_obs: ``(n_envs, *obs_shape)`` as returned by ``env.step``
    :param dones: ``(n_envs,)``
    :param infos: one dict per slot
    :return: a float32 copy, ``(n_envs, *obs_shape)``
    """
    next_obs = np.array(new_obs, dtype=np.float32, copy=True)
    for slot in np.flatnonzero(dones):
        terminal = infos[int(slot)].get("terminal_observation")
        if terminal is not None:
            next_obs[slot] = terminal
    return next_obs


class NextObservationRecorder(IntrinsicRewardCallback):
    """Base class of intrinsic rewards computed from transitions: records the true next observation
    :math:`o'_{t+1}` of every step of the rollout (:func:`true_next_observations`), which the rollout buffer does not
    keep. :meth:`rollout_next_observations` returns them, checked against the buffer.

    :param coef: scale of the bonus (beta)
    :param name: prefix of the logged keys
    :param verbose: verbosity
    """

    def __init__(self, coef: float = 0.1, name: str = "intrinsic", verbose: int = 0) -> None:
        super().__init__(coef=coef, name=name, verbose=verbose)
        self.next_observations: list[np.ndarray] = []  # o'_{t+1} of every step of the current rollout, (n_envs, d)

    def _on_rollout_start(self) -> None:
        self.next_observations = []

    def _on_step(self) -> bool:
        self.next_observations.append(
            true_next_observations(self.locals["new_obs"], self.locals["dones"], self.locals["infos"])
        )
        return True

    def rollout_next_observations(self, buffer: GroupedRecurrentRolloutBuffer) -> np.ndarray:
        """The recorded next observations of the rollout in ``buffer``, ``(n_steps, n_envs, *obs_shape)``.

        :raises RuntimeError: when the callback did not see every step (it was not passed to ``learn``)
        """
        if len(self.next_observations) != buffer.buffer_size:
            raise RuntimeError(
                f"{type(self).__name__} recorded {len(self.next_observations)} transitions, the buffer holds "
                f"{buffer.buffer_size}: pass the callback to learn() so that it sees every step."
            )
        return np.stack(self.next_observations)  # (T, E, *obs_shape)
