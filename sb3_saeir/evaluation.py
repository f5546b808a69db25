"""Multi-agent evaluation: per-game team return and the task's metrics (coverage rate, success rate)."""

from __future__ import annotations

import copy
import os
import warnings
from typing import Any, Literal, overload

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.callbacks import BaseCallback, EventCallback
from stable_baselines3.common.vec_env import VecEnv

from sb3_saeir.common.atomic import atomic_file, save_model
from sb3_saeir.common.run_state import resumable_env
from sb3_saeir.common.utils import check_number, check_writable_folder
from sb3_saeir.common.vec_env import is_multiagent_vec_env


class RandomMultiAgentPolicy:
    """
    Uniformly random actions for every agent slot, with SB3's ``predict`` signature: the random-policy reference
    for :func:`evaluate_multiagent_policy` (e.g. the coverage rate a policy must beat).

    :param action_space: one agent's action space (the vector env's ``action_space``)
    :param seed: seed of the action draws
    """

    def __init__(self, action_space: spaces.Space, seed: int = 0) -> None:
        self.action_space = copy.deepcopy(action_space)  # seeded here without touching the env's space
        self.action_space.seed(seed)
        self.rng = np.random.default_rng(seed)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, None]:
        """One random action per row of ``observation`` (``deterministic`` is ignored)."""
        n_slots = len(observation)
        if isinstance(self.action_space, spaces.Discrete):
            low = int(self.action_space.start)
            return low + self.rng.integers(0, int(self.action_space.n), size=n_slots), None
        return np.stack([self.action_space.sample() for _ in range(n_slots)]), None


# Steps of an evaluation without any game episode ending after which it warns (football's longest: 3,001 steps).
STEPS_WITHOUT_AN_END = 100_000


@overload
def evaluate_multiagent_policy(
    model: Any, env: VecEnv, n_episodes: int = ..., deterministic: bool = ..., return_episodes: Literal[False] = ...
) -> dict[str, float]: ...


@overload
def evaluate_multiagent_policy(
    model: Any, env: VecEnv, n_episodes: int, deterministic: bool, return_episodes: Literal[True]
) -> tuple[dict[str, float], list[dict[str, float]]]: ...


def evaluate_multiagent_policy(
    model: Any,
    env: VecEnv,
    n_episodes: int = 10,
    deterministic: bool = True,
    return_episodes: bool = False,
) -> dict[str, float] | tuple[dict[str, float], list[dict[str, float]]]:
    """Run a policy on a multi-agent vec env and summarise the finished games.

    Like :func:`stable_baselines3.common.evaluation.evaluate_policy`, every game contributes the same number of
    episodes (``n_episodes`` split over the games), so short episodes are not over-represented. Recurrent policies
    get their state back at every step and ``episode_start`` at episode boundaries.

    :param model: anything with SB3's ``predict(obs, state, episode_start, deterministic)``
    :param env: a :class:`~sb3_saeir.common.vec_env.MultiAgentVecEnv` (possibly wrapped)
    :param n_episodes: number of game episodes to evaluate
    :param deterministic: greedy actions
    :param return_episodes: also return the list of per-episode dicts
    :return: ``{"ep_rew_mean", "ep_rew_std", "ep_len_mean", "ep_len_std", "<metric>_mean", "<metric>_std", ...,
        "n_episodes"}`` for every task metric (e.g. ``coverage_rate_mean``, ``success_mean`` = success rate)
    """
    if not is_multiagent_vec_env(env):
        raise TypeError("evaluate_multiagent_policy needs an env from sb3_saeir.make_multiagent_vec_env.")
    owner = "evaluate_multiagent_policy"
    check_number(owner, "n_episodes (game episodes)", n_episodes, ">= 1", lambda x: x >= 1, integer=True)
    n_games, n_agents = env.n_games, env.n_agents  # type: ignore[attr-defined]
    targets = np.array([(n_episodes + g) // n_games for g in range(n_games)])  # sums to n_episodes
    counts = np.zeros(n_games, dtype=int)
    episodes: list[dict[str, float]] = []
    observations = env.reset()
    states = None
    episode_starts = np.ones(env.num_envs, dtype=bool)
    steps_without_an_end = 0
    while (counts < targets).any():
        actions, states = model.predict(observations, state=states, episode_start=episode_starts, deterministic=deterministic)
        observations, _, dones, infos = env.step(actions)
        episode_starts = dones
        steps_without_an_end = 0 if dones.any() else steps_without_an_end + 1
        if steps_without_an_end == STEPS_WITHOUT_AN_END:  # it would wait for ever on games that never end
            warnings.warn(
                f"{owner}: no game episode has ended in {STEPS_WITHOUT_AN_END:,} steps; the evaluation waits for "
                f"{n_episodes} to end: do the games end (truncate them at a max_cycles)?",
                UserWarning,
                stacklevel=2,
            )
        for game in range(n_games):
            episode = infos[game * n_agents].get("episode")
            if episode is not None and counts[game] < targets[game]:
                episodes.append({key: float(value) for key, value in episode.items() if key != "t"})
                counts[game] += 1
    summary = summarise_episodes(episodes)
    return (summary, episodes) if return_episodes else summary


def summarise_episodes(episodes: list[dict[str, float]]) -> dict[str, float]:
    """Mean and std of every per-episode quantity (``r`` -> ``ep_rew``, ``l`` -> ``ep_len``, metrics by name)."""
    renamed = {"r": "ep_rew", "l": "ep_len"}
    keys = sorted({key for episode in episodes for key in episode})
    summary: dict[str, float] = {"n_episodes": float(len(episodes))}
    for key in keys:
        values = np.array([episode[key] for episode in episodes if key in episode], dtype=np.float64)
        name = renamed.get(key, key)
        summary[f"{name}_mean"] = float(values.mean())
        summary[f"{name}_std"] = float(values.std())
    return summary


def score(summary: dict[str, float], metric: str) -> float:
    """The value of a task's main metric in an evaluation summary (``"r"``: the team return).

    :param summary: a summary from :func:`evaluate_multiagent_policy`
    :param metric: the task's main metric (``coverage_rate``, ``success`` or ``r``)
    :raises ValueError: when no evaluated episode recorded ``metric`` (a misspelt ``main_metric`` scored every
        evaluation ``-inf``, so no best model was ever kept)
    """
    if metric == "r":
        return summary["ep_rew_mean"]
    if f"{metric}_mean" not in summary:
        recorded = sorted(key[: -len("_mean")] for key in summary if key.endswith("_mean"))
        metrics = [key for key in recorded if key not in ("ep_rew", "ep_len")]
        raise ValueError(
            f"main_metric={metric!r} is not recorded by the evaluated episodes; pass one they record "
            f"({', '.join(metrics) or 'none'}) or 'r' for the team return."
        )
    return summary[f"{metric}_mean"]


def metric_name(key: str) -> str:
    """Logger name of an episode quantity: ``success`` -> ``success_rate``, others unchanged."""
    return "success_rate" if key == "success" else key


class MultiAgentEvalCallback(EventCallback):
    """Evaluate every ``eval_freq`` agent-steps on a multi-agent vec env; log under ``eval/``; keep the best model.

    Like SB3's ``EvalCallback``, but it counts games (not agents) as episodes, reports the task's metrics
    (``eval/coverage_rate``, ``eval/success_rate``, ...) and picks the best model by the task's main metric
    (coverage rate for navigation, success rate for football; team return otherwise). ``evaluations.npz`` holds
    ``timesteps``, ``results`` (team returns), ``ep_lengths`` and one array per metric, each ``(n_evaluations, n_episodes)``.

    :param eval_env: a :class:`~sb3_saeir.common.vec_env.MultiAgentVecEnv`
    :param n_eval_episodes: game episodes per evaluation
    :param eval_freq: evaluate every this many agent-steps (``model.num_timesteps``)
    :param main_metric: episode key to maximise for the best model (``"r"`` = team return)
    :param log_path: folder for ``evaluations.npz`` (``None``: not saved)
    :param best_model_save_path: folder for ``best_model.zip`` (``None``: not saved)
    :param deterministic: greedy actions
    :param callback_on_new_best: callback run when a new best model is found
    :param verbose: verbosity
    """

    def __init__(
        self,
        eval_env: VecEnv,
        n_eval_episodes: int = 10,
        eval_freq: int = 10_000,
        main_metric: str = "r",
        log_path: str | None = None,
        best_model_save_path: str | None = None,
        deterministic: bool = True,
        callback_on_new_best: BaseCallback | None = None,
        verbose: int = 1,
    ) -> None:
        super().__init__(callback_on_new_best, verbose=verbose)
        if not is_multiagent_vec_env(eval_env):
            raise TypeError("MultiAgentEvalCallback needs an eval env from sb3_saeir.make_multiagent_vec_env.")
        if isinstance(n_eval_episodes, bool) or not isinstance(n_eval_episodes, int) or n_eval_episodes < 1:
            raise ValueError(
                f"n_eval_episodes (game episodes per evaluation) must be an integer >= 1, got {n_eval_episodes!r}."
            )
        if isinstance(eval_freq, bool) or not isinstance(eval_freq, int) or eval_freq < 0:
            raise ValueError(
                f"eval_freq must be an integer >= 0 agent-steps (0: only explicit evaluate()), got {eval_freq!r}."
            )
        check_writable_folder("MultiAgentEvalCallback", "log_path", log_path)  # now, not at the first evaluation
        check_writable_folder("MultiAgentEvalCallback", "best_model_save_path", best_model_save_path)
        self.eval_env = eval_env
        self.n_eval_episodes = n_eval_episodes
        self.eval_freq = eval_freq
        self.main_metric = main_metric
        self.log_path = log_path
        self.best_model_save_path = best_model_save_path
        self.deterministic = deterministic
        self.best_score = -np.inf
        self.last_eval_timestep = 0
        self.history: dict[str, list[list[float]]] = {}
        self.timesteps: list[int] = []
        self.last_summary: dict[str, float] = {}

    def _init_callback(self) -> None:
        for path in (self.log_path, self.best_model_save_path):
            if path is not None:
                os.makedirs(path, exist_ok=True)
        self.last_eval_timestep = max(self.last_eval_timestep, self.model.num_timesteps)

    def _on_step(self) -> bool:
        if self.eval_freq > 0 and self.num_timesteps - self.last_eval_timestep >= self.eval_freq:
            self.last_eval_timestep = self.num_timesteps
            return self.evaluate()
        return True

    def evaluate(self) -> bool:
        """Run one evaluation now; returns whether training should continue."""
        summary, episodes = evaluate_multiagent_policy(
            self.model, self.eval_env, self.n_eval_episodes, self.deterministic, True
        )
        self.last_summary = summary
        self.timesteps.append(self.num_timesteps)
        for key in sorted({key for episode in episodes for key in episode}):
            self.history.setdefault(key, []).append([episode.get(key, np.nan) for episode in episodes])
        self.logger.record("eval/mean_reward", summary["ep_rew_mean"])
        self.logger.record("eval/mean_ep_length", summary["ep_len_mean"])
        for key in self.history:
            if key not in ("r", "l"):
                self.logger.record(f"eval/{metric_name(key)}", summary[f"{key}_mean"])
        self.logger.record("time/total_timesteps", self.num_timesteps, exclude="tensorboard")
        self.logger.dump(self.num_timesteps)
        if self.log_path is not None:
            self._save_evaluations()
        main_score = score(summary, self.main_metric)
        if self.verbose >= 1:
            print(f"Eval num_timesteps={self.num_timesteps}, {self.main_metric}={main_score:.3f} over {len(episodes)} games")
        if main_score > self.best_score:
            self.best_score = main_score
            if self.best_model_save_path is not None:
                save_model(self.model, os.path.join(self.best_model_save_path, "best_model"))
            if self.callback is not None:
                return self.callback.on_step()
        return True

    def get_resume_state(self) -> dict[str, Any]:
        """What the next evaluations depend on: the records so far, the best score, when the last evaluation was, and
        the eval env's state when it can save it (see :mod:`sb3_saeir.common.run_state`).

        :return: a dict for :meth:`set_resume_state`
        """
        env = resumable_env(self.eval_env)
        return {
            "best_score": self.best_score,
            "last_eval_timestep": self.last_eval_timestep,
            "history": copy.deepcopy(self.history),
            "timesteps": list(self.timesteps),
            "last_summary": dict(self.last_summary),
            "eval_env": env.get_resume_state() if env is not None else None,
        }

    def set_resume_state(self, state: dict[str, Any]) -> None:
        """Go back to the state of :meth:`get_resume_state` (an eval env that cannot take its state back keeps its own:
        the evaluations after the resume then play other episodes than uninterrupted ones would)."""
        self.best_score = state["best_score"]
        self.last_eval_timestep = state["last_eval_timestep"]
        self.history = copy.deepcopy(state["history"])
        self.timesteps = list(state["timesteps"])
        self.last_summary = dict(state["last_summary"])
        env = resumable_env(self.eval_env)
        if env is not None and state["eval_env"] is not None:
            env.set_resume_state(state["eval_env"])

    def _save_evaluations(self) -> None:
        assert self.log_path is not None
        arrays = {"timesteps": np.array(self.timesteps)}
        renamed = {"r": "results", "l": "ep_lengths"}
        for key, values in self.history.items():
            arrays[renamed.get(key, key)] = np.array(values)
        with atomic_file(os.path.join(self.log_path, "evaluations.npz")) as file:
            np.savez(file, **arrays)  # type: ignore[arg-type]
