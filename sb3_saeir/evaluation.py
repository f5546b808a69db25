"""Multi-agent evaluation: per-game team return and the task's metrics (coverage rate, success rate)."""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from sb3_saeir.common.vec_env import is_multiagent_vec_env


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
    if n_episodes < 1:
        raise ValueError(f"n_episodes must be >= 1, got {n_episodes}.")
    n_games, n_agents = env.n_games, env.n_agents  # type: ignore[attr-defined]
    targets = np.array([(n_episodes + g) // n_games for g in range(n_games)])  # sums to n_episodes
    counts = np.zeros(n_games, dtype=int)
    episodes: list[dict[str, float]] = []
    observations = env.reset()
    states = None
    episode_starts = np.ones(env.num_envs, dtype=bool)
    while (counts < targets).any():
        actions, states = model.predict(observations, state=states, episode_start=episode_starts, deterministic=deterministic)
        observations, _, dones, infos = env.step(actions)
        episode_starts = dones
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
