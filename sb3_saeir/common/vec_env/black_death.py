"""Games whose agents can finish early: :func:`black_death` keeps every agent in every step until the game ends.

A multi-agent vec env has one slot per agent for the whole game (``docs/guide/custom_env.md``, "Agents that finish
early"). SuperSuit's ``black_death_v3`` (3.11.0) ends a game only when its agents are terminated *and* truncated at
once, so a game whose agents terminate or are truncated, as PettingZoo's games do, is stepped once more with no
agent left and ends a step late, on a step the game never made (fixed upstream after 3.11.0). This wrapper ends the
game at the step where its last agent finishes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper


class BlackDeathWrapper(BaseParallelWrapper):
    """A parallel game in which an agent that has finished stays until the game ends, with a zero observation, a zero
    reward and an empty info; the game ends (every agent terminated or truncated) at the step where its last agent
    finishes. Then an agent that finished at that step keeps its own termination and truncation, and one that had
    finished before is terminated.

    :param env: the parallel game; every agent's observation space a ``Box`` (the zero observation is its shape)
    """

    def __init__(self, env: ParallelEnv) -> None:
        super().__init__(env)
        for agent in env.possible_agents:
            space = env.observation_space(agent)
            if not isinstance(space, spaces.Box):
                raise TypeError(
                    f"black_death: agent {agent!r} observes a {type(space).__name__}, not a Box: a finished agent's "
                    "zero observation needs a Box (flatten the observation first, e.g. supersuit.flatten_v0)."
                )
        self._zero_observations = {
            agent: np.zeros(env.observation_space(agent).shape, env.observation_space(agent).dtype)
            for agent in env.possible_agents
        }
        self.agents: list[str] = []

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        observations, infos = self.env.reset(seed=seed, options=options)
        self.agents = list(self.env.agents)
        return {**self._finished_observations(observations), **observations}, infos

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        playing = list(self.env.agents)
        observations, rewards, terminations, truncations, infos = self.env.step({agent: actions[agent] for agent in playing})
        finished_now = [agent for agent in playing if terminations.get(agent, False) or truncations.get(agent, False)]
        game_over = len(finished_now) == len(playing)
        finished_before = [agent for agent in self.agents if agent not in playing]
        all_terminations = {agent: False for agent in self.agents}
        all_truncations = {agent: False for agent in self.agents}
        if game_over:
            all_terminations.update({agent: bool(terminations.get(agent, False)) for agent in playing})
            all_truncations.update({agent: bool(truncations.get(agent, False)) for agent in playing})
            all_terminations.update(dict.fromkeys(finished_before, True))
        all_observations = {**self._finished_observations(observations), **observations}
        all_rewards = {**{agent: 0.0 for agent in self.agents if agent not in rewards}, **rewards}
        all_infos = {**{agent: {} for agent in self.agents if agent not in infos}, **infos}
        if game_over:
            self.agents = []
        return all_observations, all_rewards, all_terminations, all_truncations, all_infos

    def _finished_observations(self, observations: dict[str, Any]) -> dict[str, np.ndarray]:
        """Zero observations of the game's agents that ``observations`` leaves out (copies: a caller may write them)."""
        return {agent: self._zero_observations[agent].copy() for agent in self.agents if agent not in observations}


def black_death(env: ParallelEnv) -> BlackDeathWrapper:
    """Keep every agent of a parallel game in every step until the game ends (:class:`BlackDeathWrapper`), for
    :func:`~sb3_saeir.common.vec_env.make_multiagent_vec_env`::

        env = make_multiagent_vec_env(lambda: black_death(my_game()), n_games=8, seed=0)

    :param env: the parallel game
    :return: the wrapped game
    """
    return BlackDeathWrapper(env)
