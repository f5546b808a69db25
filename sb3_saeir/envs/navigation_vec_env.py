"""Native multi-agent vec env of sparse Cooperative Navigation: ``n_games`` games stepped at once by the batched core.

It offers what :class:`~sb3_saeir.common.vec_env.MultiAgentDummyVecEnv` offers over SuperSuit (slot
``game * N + agent``, ``n_agents`` / ``n_games`` / ``possible_agents``, per-game seeds ``seed + g``, lockstep resets,
bool dones, ``terminal_observation``, one ``episode`` dict per game with the task metrics, ``get_state``, per-game
``get_attr`` / ``set_attr`` / ``env_method``, ``render()`` of game 0) and gives the same streams as
:class:`~sb3_saeir.envs.navigation.SparseCooperativeNavigation` through SuperSuit for the same seed (observations,
rewards, dones, episode records). Physics, rewards and observations have no Python loop over games or agents; Python
only builds the per-slot info dicts the SB3 API asks for (empty during an episode: the per-step
``covered_landmarks`` / ``collision`` infos of the ParallelEnv are left out for speed; the task metrics come at a
game's end). The task is described in ``docs/tasks.md``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from sb3_saeir.common.utils import check_bool
from sb3_saeir.common.vec_env import EPISODE_METRICS_KEY, MultiAgentVecEnv, RawStep
from sb3_saeir.common.vec_env import check_finite as check_finite_values
from sb3_saeir.envs.navigation_core import (
    AGENT_SIZE,
    COVER_RADIUS,
    METADATA,
    NavigationCore,
    check_finite_option,
    check_positive_int,
    navigation_spaces,
)

# Per-game parameters: arrays of the core, one value per game.
_PER_GAME = {"max_cycles": int, "cover_radius": float, "collision_penalty": float}


def check_per_game(name: str, value: Any) -> None:
    """Refuse a bad value of a per-game parameter (a whole number >= 1 for ``max_cycles``, a finite number else).

    :param name: the parameter
    :param value: its value
    """
    if _PER_GAME[name] is int:
        check_positive_int(name, value)
    else:
        check_finite_option(name, value)


class NavigationGame:
    """One game of a :class:`NavigationVecEnv`, for ``get_attr`` / ``set_attr`` / ``env_method``.

    Reads and writes the game's own parameters (``max_cycles``, ``cover_radius``, ``collision_penalty``) in the core;
    other attributes (``N``, ``world``, ``reward``, ``continuous_actions``, ``metadata``, ...) are shared by all games.
    Setting another attribute stores it on this object only.

    :param vec_env: the vec env
    :param game: the game's index
    """

    def __init__(self, vec_env: NavigationVecEnv, game: int) -> None:
        object.__setattr__(self, "_vec_env", vec_env)
        object.__setattr__(self, "game", game)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        core = self._vec_env.core
        if name in _PER_GAME:
            return _PER_GAME[name](getattr(core, name)[self.game])
        if name in ("N", "world", "reward", "continuous_actions"):
            return getattr(core, name)
        if name == "n_landmarks":
            return core.N
        if name in ("metadata", "possible_agents", "render_mode", "state_space"):
            return getattr(self._vec_env, name)
        raise AttributeError(f"The navigation game has no attribute {name!r}.")

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _PER_GAME:
            check_per_game(name, value)
            getattr(self._vec_env.core, name)[self.game] = _PER_GAME[name](value)
        else:
            object.__setattr__(self, name, value)

    @property
    def unwrapped(self) -> NavigationGame:
        return self

    def observation_space(self, agent: str) -> gym.spaces.Space:
        return self._vec_env.observation_space

    def action_space(self, agent: str) -> gym.spaces.Space:
        return self._vec_env.action_space

    def state(self) -> np.ndarray:
        """The game's global state, every agent's observation concatenated, ``(N * obs_dim,)``."""
        return self._vec_env.core.observations()[self.game].reshape(-1)  # (N, obs_dim) -> (N * obs_dim,)

    def positions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Agent positions (N, 2), landmark positions (L, 2) and agent sizes (N,) (copies)."""
        core = self._vec_env.core
        return core.positions[self.game].copy(), core.landmarks[self.game].copy(), np.full(core.N, AGENT_SIZE)

    def render(self) -> np.ndarray:
        """An RGB picture of the game."""
        return self._vec_env.core.render(self.game)


class NavigationVecEnv(MultiAgentVecEnv):
    """SB3 ``VecEnv`` of ``n_games`` sparse Cooperative Navigation games, one slot per agent, stepped in NumPy (a
    :class:`~sb3_saeir.common.vec_env.MultiAgentVecEnv`, as :class:`~sb3_saeir.common.vec_env.MultiAgentDummyVecEnv`).

    Build it with :func:`~sb3_saeir.make_multiagent_vec_env` (the default backend of the navigation tasks) or
    directly. All games run in this process (there are no worker processes: ``num_cpus`` is 0; one sampling group).

    :param n_games: number of games G; the vec env has ``G * N`` slots
    :param N: agents per game (= landmarks)
    :param max_cycles: episode length in steps
    :param continuous_actions: ``Box(0, 1, (5,))`` actions instead of ``Discrete(5)``
    :param render_mode: ``None`` or ``"rgb_array"`` (``render()`` draws game 0)
    :param cover_radius: a landmark is reached when its nearest agent is closer than this
    :param collision_penalty: team penalty of a step in which any two agents collide
    :param world: ``"mpe"`` (original MPE, the paper's world) or ``"mpe2"`` (mpe2 1.1.1)
    :param reward: ``"occupancy"`` or ``"reach"``
    :param mark_truncation: set ``infos[i]["TimeLimit.truncated"]`` when a game hits its time limit
    :param check_finite: raise :class:`~sb3_saeir.common.vec_env.NonFiniteValueError` (naming the game, agent and
        step) when an observation or reward is NaN or infinite, as for games through SuperSuit; ``False`` skips it
    """

    def __init__(
        self,
        n_games: int,
        N: int = 3,
        max_cycles: int = 25,
        continuous_actions: bool = False,
        render_mode: str | None = None,
        cover_radius: float = COVER_RADIUS,
        collision_penalty: float = 1.0,
        world: str = "mpe",
        reward: str = "occupancy",
        mark_truncation: bool = False,
        check_finite: bool = True,
    ) -> None:
        check_positive_int("n_games", n_games)
        check_bool(type(self).__name__, mark_truncation=mark_truncation, check_finite=check_finite)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}.")
        self.core = NavigationCore(
            int(n_games),
            N=N,
            max_cycles=max_cycles,
            continuous_actions=continuous_actions,
            world=world,
            reward=reward,
            cover_radius=cover_radius,
            collision_penalty=collision_penalty,
        )
        n_agents = self.core.N
        self.state_space = gym.spaces.Box(-np.inf, np.inf, (n_agents * self.core.obs_dim,), dtype=np.float32)
        observation_space, action_space = navigation_spaces(n_agents, self.core.continuous_actions)
        super().__init__(
            n_games,
            [f"agent_{i}" for i in range(n_agents)],
            observation_space,
            action_space,
            mark_truncation=mark_truncation,
            check_finite=check_finite,
            render_mode=render_mode,
            metadata=METADATA,
        )
        self.games = [NavigationGame(self, g) for g in range(self.n_games)]
        self._actions: np.ndarray | None = None
        self.core.reset_games()

    # ------------------------------------------------------------------ the games (MultiAgentVecEnv)
    def _reset_games(self, seed: int | None, options: dict | None) -> tuple[np.ndarray, list[dict[str, Any]]]:
        """Reset every game (``options`` are ignored: the task has none)."""
        if seed is not None:
            self.core.seed([seed + g for g in range(self.n_games)])
        self.core.reset_games()
        self._actions = None
        obs = self.core.observations().reshape(self.num_envs, -1)  # (G, N, obs_dim) -> (G * N, obs_dim)
        return obs, [{} for _ in range(self.num_envs)]

    def _step_games_async(self, actions: np.ndarray, group: int | None) -> None:
        self._actions = np.asarray(actions)  # one group: every slot

    def _step_games_wait(self, group: int | None, episode_steps: np.ndarray) -> RawStep:
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async().")
        G, N = self.n_games, self.n_agents
        # (G * N, 5) -> (G, N, 5) for continuous actions; (G * N,) or (G * N, 1) -> (G, N) for discrete ones
        actions: np.ndarray = self._actions.reshape(G, N, -1) if self.core.continuous_actions else self._actions.reshape(G, N)
        self._actions = None
        result = self.core.step(actions)
        obs: np.ndarray = result.observations.reshape(G * N, -1)  # (G, N, obs_dim) -> (G * N, obs_dim)
        rewards = np.repeat(result.rewards.astype(np.float32), N)  # (G,) -> (G * N,)
        truncations = np.repeat(result.truncated, N)  # (G,) -> (G * N,)
        if self.check_finite:  # the games' last observations, before the finished ones are reset
            check_finite_values(self._env_name(), obs, rewards, N, self.possible_agents, episode_steps)
        infos: list[dict[str, Any]] = [{} for _ in range(G * N)]
        finished = np.flatnonzero(result.truncated)
        if len(finished):
            terminal_obs = obs.copy()
            for game in finished:
                metrics = self.core.episode_metrics(int(game))
                for slot in range(game * N, (game + 1) * N):
                    infos[slot]["terminal_observation"] = terminal_obs[slot]
                    infos[slot][EPISODE_METRICS_KEY] = dict(metrics)
            self.core.reset_games(finished)
            # (G, N, obs_dim) -> (G * N, obs_dim): the first observations of the new episodes replace the last ones
            obs = self.core.observations().reshape(G * N, -1)
        return obs, rewards, np.zeros(G * N, dtype=bool), truncations, infos

    def _abandon_steps(self, groups: list[int]) -> None:
        self._actions = None  # the games step in step_wait: nothing has run yet

    def _game_objects(self) -> list[NavigationGame]:
        return self.games

    def _render_game_zero(self) -> np.ndarray:
        """The frame of game 0, drawn by the engine."""
        return self.core.render(0)

    def _close_games(self) -> None:
        """Nothing to close: the games are arrays of this process."""

    def _repr_settings(self) -> dict[str, Any]:
        return {"world": self.core.world, "reward": self.core.reward}

    # ------------------------------------------------------------------ resume state
    def get_resume_state(self) -> dict[str, Any]:
        """Everything that determines the env's future streams, for exact resumption of training (the benchmark's
        checkpoints): the core's arrays and each game's generator state, the running episode returns and lengths, the
        episode counter and any seed or options waiting for the next reset. Copies, safe to pickle.

        Call it between steps (not between ``step_async`` and ``step_wait``). The ``t`` of the episode records
        (seconds since the env was made) is wall-clock time and is not part of the state.

        :return: a dict for :meth:`set_resume_state`
        """
        return {"core": self.core.get_resume_state(), **self._records_state()}

    def set_resume_state(self, state: dict[str, Any]) -> None:
        """Put the env back in the state returned by :meth:`get_resume_state` of an env made with the same settings:
        the next ``step`` gives what the original env's next ``step`` gave.

        :param state: a dict from :meth:`get_resume_state`
        :raises ValueError: when the state comes from an env with another number of games, agents, world, reward
            reading or action type
        """
        self.core.set_resume_state(state["core"])
        self._set_records_state(state)
        self._actions = None

    # ------------------------------------------------------------------ SB3 VecEnv API
    def get_state(self) -> np.ndarray:
        """Global state of every game, ``(n_games, N * obs_dim)``."""
        return self.core.observations().reshape(self.n_games, -1)  # (G, N, obs_dim) -> (G, N * obs_dim)
