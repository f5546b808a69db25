"""Sparse Cooperative Navigation: the SAEIR paper's sparse-reward variant of MPE ``simple_spread``.

The paper's supplement: "N agents, N landmarks ... reward +l when l landmarks are reached, -1 when any agents
collide, the collision penalty applied at most once per time step"; metric "coverage rate". The authors did not
release this scenario; the definition below is this package's (see the README, "Tasks").

Per step, every agent receives the same team reward

.. math::

    r_t = \\#\\{l : \\min_a \\lVert p_a - p_l \\rVert < 0.1\\}
          - \\mathbb{1}[\\exists a \\neq b : \\lVert p_a - p_b \\rVert < s_a + s_b]

(landmark covered: its nearest agent is within 0.1, mpe2's "occupied" threshold; collision: two agents closer than
the sum of their sizes, 0.15 + 0.15). Per episode: ``coverage_rate`` = covered landmarks at the final step / N,
``coverage_over_steps`` = covered fraction averaged over the episode's steps, ``collision_steps`` = steps with a
collision, ``success`` = every landmark covered at the final step.

Everything else is mpe2 ``simple_spread_v3``: agents and landmarks uniform in [-1, 1]^2, 5 discrete actions
(continuous optional), 18-d observations for N=3 (24-d for N=4), ``max_cycles`` steps (25) then truncation.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from pettingzoo.utils.env import ParallelEnv

from sb3_saeir.common.vec_env import EPISODE_METRICS_KEY

COVER_RADIUS = 0.1


def count_covered_landmarks(agent_positions: np.ndarray, landmark_positions: np.ndarray, radius: float = COVER_RADIUS) -> int:
    """Number of landmarks whose nearest agent is closer than ``radius``.

    :param agent_positions: (N_agents, 2)
    :param landmark_positions: (N_landmarks, 2)
    :param radius: cover radius
    :return: the count
    """
    # (L, 1, 2) - (1, A, 2) -> (L, A)
    distances = np.linalg.norm(landmark_positions[:, None, :] - agent_positions[None, :, :], axis=-1)
    return int((distances.min(axis=1) < radius).sum())


def any_collision(agent_positions: np.ndarray, agent_sizes: np.ndarray) -> bool:
    """True if two distinct agents are closer than the sum of their sizes.

    :param agent_positions: (N, 2)
    :param agent_sizes: (N,)
    """
    # (N, 1, 2) - (1, N, 2) -> (N, N)
    distances = np.linalg.norm(agent_positions[:, None, :] - agent_positions[None, :, :], axis=-1)
    limits = agent_sizes[:, None] + agent_sizes[None, :]
    off_diagonal = ~np.eye(len(agent_positions), dtype=bool)
    return bool(((distances < limits) & off_diagonal).any())


def sparse_navigation_reward(
    agent_positions: np.ndarray,
    landmark_positions: np.ndarray,
    agent_sizes: np.ndarray,
    cover_radius: float = COVER_RADIUS,
    collision_penalty: float = 1.0,
) -> float:
    """Team reward of one step: covered landmarks minus ``collision_penalty`` if any two agents collide.

    :param agent_positions: agents' positions, shape (N, 2)
    :param landmark_positions: landmarks' positions, shape (L, 2)
    :param agent_sizes: agents' radii, shape (N,)
    :param cover_radius: a landmark is covered when its nearest agent is closer than this
    :param collision_penalty: subtracted once per step when any two agents collide
    """
    covered = count_covered_landmarks(agent_positions, landmark_positions, radius=cover_radius)
    return float(covered - collision_penalty * int(any_collision(agent_positions, agent_sizes)))


class SparseCooperativeNavigation(ParallelEnv, EzPickle):
    """Sparse-reward Cooperative Navigation on mpe2 ``simple_spread_v3`` (PettingZoo ``ParallelEnv``).

    :param N: number of agents (and landmarks)
    :param max_cycles: episode length in steps
    :param continuous_actions: continuous ``Box(0, 1, (5,))`` actions instead of ``Discrete(5)``
    :param render_mode: ``None``, ``"rgb_array"`` or ``"human"``
    :param cover_radius: a landmark counts as covered when its nearest agent is closer than this (0.1, the paper's
        task as this package defines it; a larger radius makes the task easier)
    :param collision_penalty: team penalty for a step in which any two agents collide (1.0; 0 switches it off)
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["human", "rgb_array"],
        "name": "cn_sparse_v0",
        "is_parallelizable": True,
    }

    def __init__(
        self,
        N: int = 3,
        max_cycles: int = 25,
        continuous_actions: bool = False,
        render_mode: str | None = None,
        cover_radius: float = COVER_RADIUS,
        collision_penalty: float = 1.0,
    ) -> None:
        EzPickle.__init__(
            self,
            N=N,
            max_cycles=max_cycles,
            continuous_actions=continuous_actions,
            render_mode=render_mode,
            cover_radius=cover_radius,
            collision_penalty=collision_penalty,
        )
        from mpe2 import simple_spread_v3

        if N < 1:
            raise ValueError(f"N must be >= 1, got {N}.")
        if cover_radius <= 0:
            raise ValueError(f"cover_radius must be positive, got {cover_radius}.")
        if collision_penalty < 0:
            raise ValueError(f"collision_penalty must be >= 0 (it is subtracted), got {collision_penalty}.")
        self.cover_radius = float(cover_radius)
        self.collision_penalty = float(collision_penalty)
        self.n_landmarks = N
        self.max_cycles = max_cycles
        self.render_mode = render_mode
        # local_ratio=0: mpe2's dense reward is ignored anyway, the sparse reward replaces it.
        self._env = simple_spread_v3.parallel_env(
            N=N, local_ratio=0.0, max_cycles=max_cycles, continuous_actions=continuous_actions, render_mode=render_mode
        )
        self.possible_agents = list(self._env.possible_agents)
        self.state_space = self._env.state_space
        self.agents: list[str] = []
        self._covered_sum = 0.0
        self._collision_steps = 0
        self._steps = 0

    # PettingZoo API -----------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Space:
        return self._env.observation_space(agent)

    def action_space(self, agent: str) -> spaces.Space:
        return self._env.action_space(agent)

    @property
    def world(self) -> Any:
        """The mpe2 world (agents' and landmarks' physical state)."""
        return self._env.unwrapped.world

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, np.ndarray], dict[str, dict]]:
        observations, _infos = self._env.reset(seed=seed, options=options)
        self.agents = list(self._env.agents)
        self._covered_sum = 0.0
        self._collision_steps = 0
        self._steps = 0
        return observations, {agent: {} for agent in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        observations, _, terminations, truncations, _ = self._env.step(actions)
        agent_positions, landmark_positions, agent_sizes = self.positions()
        covered = count_covered_landmarks(agent_positions, landmark_positions, radius=self.cover_radius)
        collided = any_collision(agent_positions, agent_sizes)
        reward = float(covered - self.collision_penalty * int(collided))
        self._steps += 1
        self._covered_sum += covered / self.n_landmarks
        self._collision_steps += int(collided)

        rewards = {agent: reward for agent in self.possible_agents}
        infos: dict[str, dict] = {
            agent: {"covered_landmarks": covered, "collision": collided} for agent in self.possible_agents
        }
        if all(terminations.get(a, False) or truncations.get(a, False) for a in self.possible_agents):
            metrics = {
                "coverage_rate": covered / self.n_landmarks,
                "coverage_over_steps": self._covered_sum / self._steps,
                "collision_steps": float(self._collision_steps),
                "success": float(covered == self.n_landmarks),
            }
            for agent in self.possible_agents:
                infos[agent][EPISODE_METRICS_KEY] = dict(metrics)
        self.agents = list(self._env.agents)
        return observations, rewards, terminations, truncations, infos

    def positions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Agent positions (N, 2), landmark positions (L, 2) and agent sizes (N,) of the current state."""
        world = self.world
        agent_positions = np.array([a.state.p_pos for a in world.agents])
        landmark_positions = np.array([lm.state.p_pos for lm in world.landmarks])
        agent_sizes = np.array([a.size for a in world.agents])
        return agent_positions, landmark_positions, agent_sizes

    def state(self) -> np.ndarray:
        return self._env.state()

    def render(self) -> Any:
        return self._env.render()

    def close(self) -> None:
        self._env.close()
