"""Callbacks shared by every algorithm of the package."""

from __future__ import annotations

import time

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, ConvertCallback
from stable_baselines3.common.type_aliases import MaybeCallback

# Keys of SB3's own episode dicts, logged by SB3 itself (``rollout/ep_rew_mean``, ``rollout/ep_len_mean``).
_SB3_EPISODE_KEYS = ("r", "l", "t")


def episode_metric_means(ep_info_buffer: list[dict] | None) -> dict[str, float]:
    """Mean of every task metric (every numeric key except SB3's ``r``, ``l``, ``t``) over an episode buffer.

    :param ep_info_buffer: the algorithm's ``ep_info_buffer`` (one dict per finished game)
    :return: ``{metric name: mean}``
    """
    if not ep_info_buffer:
        return {}
    names = sorted({key for info in ep_info_buffer for key in info if key not in _SB3_EPISODE_KEYS})
    means = {}
    for name in names:
        values = [float(info[name]) for info in ep_info_buffer if name in info]
        means[name] = float(np.mean(values))
    return means


def flatten_callbacks(callback: MaybeCallback) -> list[BaseCallback]:
    """The callbacks given to ``learn`` as a flat list (``CallbackList`` and lists unpacked, recursively; a function
    wrapped in SB3's ``ConvertCallback``).

    :param callback: the ``callback`` argument of ``learn``
    """
    if callback is None:
        return []
    if isinstance(callback, CallbackList):
        return [c for inner in callback.callbacks for c in flatten_callbacks(inner)]
    if isinstance(callback, list):
        return [c for inner in callback for c in flatten_callbacks(inner)]
    if isinstance(callback, BaseCallback):
        return [callback]
    return [ConvertCallback(callback)]


class EpisodeMetricsCallback(BaseCallback):
    """Log the task's per-episode metrics (``coverage_rate``, ``success``, ...) under ``rollout/``.

    :class:`~sb3_saeir.common.vec_env.MultiAgentVecEnv` records one episode per game, with the task metrics, in the
    ``episode`` info that SB3 collects into ``model.ep_info_buffer``; SB3 itself only logs ``r`` and ``l`` from it.
    ``SAEIR_PPO`` logs the metrics by itself; add this callback to log them with plain SB3 algorithms::

        PPO("MlpPolicy", env).learn(100_000, callback=EpisodeMetricsCallback())

    The means cover the same window as ``rollout/ep_rew_mean`` (the last ``stats_window_size`` games).
    """

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        for name, value in episode_metric_means(list(self.model.ep_info_buffer or [])).items():
            self.logger.record(f"rollout/{name}", value)


class EveryAgentSteps(BaseCallback):
    """Run a callback every ``frequency`` agent-steps.

    SB3's own frequencies (``CheckpointCallback(save_freq=...)``, ``EvalCallback(eval_freq=...)``) count calls of
    ``env.step``, and one call of a multi-agent vec env is ``n_games * n_agents`` agent-steps; wrap such a callback
    (built with frequency 1) to count agent-steps instead::

        EveryAgentSteps(CheckpointCallback(save_freq=1, save_path="logs"), frequency=100_000)

    :param callback: the callback to run
    :param frequency: agent-steps (``model.num_timesteps``) between two runs
    """

    def __init__(self, callback: BaseCallback, frequency: int) -> None:
        super().__init__()
        if not isinstance(callback, BaseCallback):
            raise TypeError(f"EveryAgentSteps: callback={callback!r} must be an SB3 BaseCallback (such as EvalCallback).")
        if isinstance(frequency, (bool, np.bool_)) or not isinstance(frequency, (int, np.integer)) or frequency < 1:
            raise ValueError(f"frequency must be a positive number of agent-steps, got {frequency!r}.")
        frequency = int(frequency)
        self.callback = callback
        self.frequency = frequency
        self.last = 0

    def _init_callback(self) -> None:
        self.callback.init_callback(self.model)
        self.last = self.num_timesteps

    def _on_step(self) -> bool:
        if self.num_timesteps - self.last >= self.frequency:
            self.last = self.num_timesteps
            self.callback.update_locals(self.locals)
            return self.callback.on_step()
        return True


class BudgetEstimate(BaseCallback):
    """After the first rollout and update, print how long the whole budget will take at that rate (the ETA line of
    ``python -m sb3_saeir.train`` and ``python -m sb3_saeir.zoo train``); for a resumed run, how long the rest takes.

    :param total_timesteps: the run's budget in agent-steps
    """

    def __init__(self, total_timesteps: int) -> None:
        super().__init__()
        if (
            isinstance(total_timesteps, (bool, np.bool_))
            or not isinstance(total_timesteps, (int, np.integer))
            or total_timesteps < 1
        ):
            raise ValueError(
                f"BudgetEstimate: total_timesteps={total_timesteps!r} must be the run's budget, a whole number >= 1."
            )
        self.total_timesteps = int(total_timesteps)
        self.start = 0.0
        self.start_steps = 0
        self.printed = False

    def _on_training_start(self) -> None:
        self.start = time.time()
        self.start_steps = self.model.num_timesteps

    def _on_step(self) -> bool:
        return True

    def _on_rollout_start(self) -> None:
        done = self.model.num_timesteps - self.start_steps  # agent-steps of this process
        if self.printed or done <= 0:
            return
        self.printed = True
        rate = done / max(time.time() - self.start, 1e-9)
        remaining = max(int(getattr(self.model, "_total_timesteps", self.total_timesteps)) - self.model.num_timesteps, 0)
        resumed = self.start_steps > 0
        what = f"the remaining {remaining + done:,}" if resumed else f"the {self.total_timesteps:,}"
        hours = (remaining + done) / rate / 3600
        print(
            f"First rollout and update: {rate:,.0f} agent-steps/s; {what} agent-steps take about "
            f"{hours:.1f} h at this rate (Ctrl-C saves the model and stops).",
            flush=True,
        )
