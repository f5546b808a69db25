"""Sparse Cooperative Navigation: the SAEIR paper's sparse-reward variant of MPE ``simple_spread``, as the PettingZoo
``ParallelEnv`` :class:`SparseCooperativeNavigation` (one game). Its engine,
:class:`~sb3_saeir.envs.navigation_core.NavigationCore`, also drives the native vec env
:class:`~sb3_saeir.envs.navigation_vec_env.NavigationVecEnv` (G games, the fast path ``make_multiagent_vec_env``
builds for these tasks; the two faces do not import each other). The team
reward, its two readings (``reward="occupancy"``, the default, and ``"reach"``), the two worlds (``world="mpe"``, the
paper's and the default, and ``"mpe2"``) and the per-episode metrics (``coverage_rate``, ``coverage_over_steps``,
``collision_steps``, ``success``, ``reach_events``) are defined in ``docs/tasks.md``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from pettingzoo.utils.env import ParallelEnv

from sb3_saeir.common.vec_env import EPISODE_METRICS_KEY
from sb3_saeir.envs.navigation_core import (
    AGENT_SIZE,
    COVER_RADIUS,
    METADATA,
    N_ACTIONS,
    REWARDS,
    WORLDS,
    NavigationCore,
    check_finite_option,
    check_positive_int,
    navigation_spaces,
)

__all__ = [
    "COVER_RADIUS",
    "REWARDS",
    "WORLDS",
    "SparseCooperativeNavigation",
    "any_collision",
    "count_covered_landmarks",
    "navigation_spaces",
    "sparse_navigation_reward",
]


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
    """Sparse-reward Cooperative Navigation, one game, as a PettingZoo ``ParallelEnv``.

    :param N: number of agents (and landmarks)
    :param max_cycles: episode length in steps
    :param continuous_actions: continuous ``Box(0, 1, (5,))`` actions (force ``(a2 - a1, a4 - a3)``) instead of
        ``Discrete(5)`` (no-op, -x, +x, -y, +y)
    :param render_mode: ``None`` or ``"rgb_array"`` (an RGB picture drawn with NumPy)
    :param cover_radius: a landmark counts as reached when its nearest agent is closer than this (0.1; a larger radius
        makes the task easier)
    :param collision_penalty: team penalty for a step in which any two agents collide (1.0; 0 switches it off)
    :param world: ``"mpe"`` (the original MPE of Lowe et al. 2017, the paper's world; default) or ``"mpe2"`` (mpe2
        1.1.1's integration order and landmark range; the same seed gives the same episodes as mpe2's
        ``simple_spread_v3``)
    :param reward: ``"occupancy"`` (+1 per landmark reached at this step; default) or ``"reach"`` (+1 per landmark
        that became reached at this step)
    """

    metadata: ClassVar[dict[str, Any]] = dict(METADATA)

    def __init__(
        self,
        N: int = 3,
        max_cycles: int = 25,
        continuous_actions: bool = False,
        render_mode: str | None = None,
        cover_radius: float = COVER_RADIUS,
        collision_penalty: float = 1.0,
        world: str = "mpe",
        reward: str = "occupancy",
    ) -> None:
        EzPickle.__init__(
            self,
            N=N,
            max_cycles=max_cycles,
            continuous_actions=continuous_actions,
            render_mode=render_mode,
            cover_radius=cover_radius,
            collision_penalty=collision_penalty,
            world=world,
            reward=reward,
        )
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}.")
        self.core = NavigationCore(
            1,
            N=N,
            max_cycles=max_cycles,
            continuous_actions=continuous_actions,
            world=world,
            reward=reward,
            cover_radius=cover_radius,
            collision_penalty=collision_penalty,
        )
        self.N = int(N)
        self.n_landmarks = self.N
        self.world = self.core.world
        self.reward = self.core.reward
        self.continuous_actions = bool(continuous_actions)
        self.render_mode = render_mode
        self.possible_agents = [f"agent_{i}" for i in range(self.N)]
        self.agents: list[str] = []
        self._observation_space, self._action_space = navigation_spaces(self.N, self.continuous_actions)
        self.state_space = spaces.Box(
            low=-np.float32(np.inf), high=+np.float32(np.inf), shape=(self.N * self.core.obs_dim,), dtype=np.float32
        )
        self._observations = np.zeros((self.N, self.core.obs_dim), dtype=np.float32)

    # Per-game parameters live in the core (so that changing them changes the game).
    @property
    def max_cycles(self) -> int:
        """Episode length in steps."""
        return int(self.core.max_cycles[0])

    @max_cycles.setter
    def max_cycles(self, value: int) -> None:
        check_positive_int("max_cycles", value)
        self.core.max_cycles[0] = int(value)

    @property
    def cover_radius(self) -> float:
        """Cover radius of a landmark."""
        return float(self.core.cover_radius[0])

    @cover_radius.setter
    def cover_radius(self, value: float) -> None:
        check_finite_option("cover_radius", value)
        self.core.cover_radius[0] = float(value)

    @property
    def collision_penalty(self) -> float:
        """Team penalty of a step with a collision."""
        return float(self.core.collision_penalty[0])

    @collision_penalty.setter
    def collision_penalty(self, value: float) -> None:
        check_finite_option("collision_penalty", value)
        self.core.collision_penalty[0] = float(value)

    # PettingZoo API -----------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Space:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Space:
        return self._action_space

    def _observation_dict(self) -> dict[str, np.ndarray]:
        return {agent: self._observations[i] for i, agent in enumerate(self.possible_agents)}

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, np.ndarray], dict[str, dict]]:
        """Start an episode: agents and landmarks drawn from the game's generator (re-created from ``seed`` if given)."""
        if seed is not None:
            self.core.seed([seed])
        self.core.reset_games()
        self._observations = self.core.observations()[0]
        self.agents = list(self.possible_agents)
        return self._observation_dict(), {agent: {} for agent in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """One step; agents missing from ``actions`` take the no-op (zero force)."""
        if not self.agents:
            raise RuntimeError("step() called on a finished episode: call reset() first.")
        if self.continuous_actions:
            zero = np.zeros(N_ACTIONS, dtype=np.float32)
            values = [np.asarray(actions.get(agent, zero)) for agent in self.possible_agents]
            result = self.core.step(np.stack(values)[None])  # (N, 5) -> (1, N, 5)
        else:
            result = self.core.step(np.array([[int(actions.get(agent, 0)) for agent in self.possible_agents]]))
        self._observations = result.observations[0]
        reward = float(result.rewards[0])
        covered, collided = int(result.covered[0]), bool(result.collided[0])
        truncated = bool(result.truncated[0])
        observations = self._observation_dict()
        rewards = dict.fromkeys(self.possible_agents, reward)
        terminations = dict.fromkeys(self.possible_agents, False)
        truncations = dict.fromkeys(self.possible_agents, truncated)
        infos: dict[str, dict] = {
            agent: {"covered_landmarks": covered, "reached_landmarks": int(result.reached[0]), "collision": collided}
            for agent in self.possible_agents
        }
        if truncated:
            metrics = self.core.episode_metrics(0)
            for agent in self.possible_agents:
                infos[agent][EPISODE_METRICS_KEY] = dict(metrics)
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def positions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Agent positions (N, 2), landmark positions (L, 2) and agent sizes (N,) of the current state (copies)."""
        return self.core.positions[0].copy(), self.core.landmarks[0].copy(), np.full(self.N, AGENT_SIZE)

    def velocities(self) -> np.ndarray:
        """Agent velocities (N, 2) of the current state (a copy)."""
        return self.core.velocities[0].copy()

    def place(self, agent_positions: Any, landmark_positions: Any | None = None, velocities: Any | None = None) -> None:
        """Put agents (and landmarks) at given positions, velocities zero unless given (for tests and set-ups).

        :param agent_positions: ``(N, 2)``
        :param landmark_positions: ``(N, 2)``; ``None`` keeps them
        :param velocities: ``(N, 2)``; ``None`` sets them to zero
        """
        self.core.place(0, agent_positions, landmark_positions, velocities)
        self._observations = self.core.observations()[0]

    def state(self) -> np.ndarray:
        """Global state: every agent's observation concatenated in ``possible_agents`` order, ``(N * obs_dim,)``."""
        return self.core.observations()[0].reshape(-1)  # (N, obs_dim) -> (N * obs_dim,)

    def render(self) -> np.ndarray | None:
        """An RGB picture of the game in ``rgb_array`` mode (``None`` without a render mode)."""
        if self.render_mode != "rgb_array":
            return None
        return self.core.render(0)

    def close(self) -> None:
        pass
