"""Google Research Football (gfootball 2.10.2) academy scenarios as a PettingZoo ``ParallelEnv``: the SAEIR authors'
wrapper (``docs/method.md``, "Football wrapper") rebuilt on PettingZoo. ``simple115v2`` observations (115 floats per
agent), ``Discrete(19)`` actions, the ``scoring`` reward (with ``share_reward=True``, the authors' choice, summed over
the controlled players and given to each), the built-in AI as opponent, no rendering. Agents are gfootball's
controlled-player slots (``infos[agent]["active_player"]`` says which physical player a slot drives); every env has
its own seeded generator for the engine seeds, so the same seed and actions give the same episodes. Per-episode
metrics: ``success`` (the left team scored) and ``goal_diff``. The whole definition: ``docs/guide/football.md``.
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from pettingzoo.utils.env import ParallelEnv

from sb3_saeir.common.utils import check_bool
from sb3_saeir.common.vec_env import EPISODE_METRICS_KEY
from sb3_saeir.envs.navigation_core import check_positive_int

OBSERVATION_SIZE = 115  # simple115v2
N_ACTIONS = 19  # gfootball's default action set
# simple115v2 layout: positions/directions 0-87, ball 88-93, ball owner 94-96, active player 97-107, game mode 108-114
ACTIVE_PLAYER_SLICE = slice(97, 108)
MAX_ENGINE_SEED = 2_000_000_000  # gfootball draws its own seeds from [0, 2e9]

INSTALL_HINT = (
    "Google Research Football (gfootball 2.10.2) is needed for the football (grf-*) tasks. Install it with "
    "`bash scripts/install_football.sh` (run as root: apt build dependencies, a 6-15 minute build of the engine, then "
    "the `football` extra, i.e. `pip install 'sb3-saeir[football]'`). See docs/guide/football.md."
)


class FootballNotInstalledError(ImportError):
    """Raised when a football task is created without a working gfootball installation."""


def import_gfootball() -> Any:
    """Import ``gfootball.env``, or fail with an error that says how to install it.

    :return: the ``gfootball.env`` module
    :raises FootballNotInstalledError: when gfootball (or one of its dependencies) is missing, or ``gym`` is too new
    """
    try:
        football_env = importlib.import_module("gfootball.env")
        gym = importlib.import_module("gym")
    except ImportError as error:
        raise FootballNotInstalledError(f"{INSTALL_HINT} (import failed: {error})") from error
    major_minor = tuple(int(part) for part in gym.__version__.split(".")[:2])
    if major_minor >= (0, 26):
        raise FootballNotInstalledError(
            f"gym {gym.__version__} is installed, but gfootball 2.10.2 needs gym < 0.26 (its wrappers use the old "
            f"reset/step API). {INSTALL_HINT}"
        )
    return football_env


def check_scenario(scenario: str) -> None:
    """Fail early on an unknown scenario name (gfootball itself logs an error and calls ``sys.exit``).

    :param scenario: a module name of ``gfootball.scenarios``
    :raises ValueError: listing the available scenarios
    """
    scenarios = importlib.import_module("gfootball.scenarios")
    available = sorted(module.name for module in pkgutil.iter_modules(scenarios.__path__) if module.name != "tests")
    if scenario not in available:
        raise ValueError(f"Unknown gfootball scenario {scenario!r}. Available: {', '.join(available)}.")


# The parts of gfootball's ``rewards`` spec (comma-separated; ``scoring`` is required by gfootball)
REWARD_PARTS = ("scoring", "checkpoints")


def check_rewards(rewards: object) -> None:
    """Refuse a ``rewards`` spec gfootball would reject with an empty ``AssertionError`` (or ignore in part), before
    gfootball is imported.

    :param rewards: ``"scoring"`` or ``"scoring,checkpoints"`` (parts in any order)
    :raises ValueError: one line naming ``rewards`` and the valid values
    """
    parts = rewards.split(",") if isinstance(rewards, str) else []
    if "scoring" not in parts or any(part not in REWARD_PARTS for part in parts) or len(set(parts)) != len(parts):
        raise ValueError(
            f"FootballEnv: rewards={rewards!r} is not a gfootball reward spec; use 'scoring' (+-1 per goal) or "
            "'scoring,checkpoints' (plus gfootball's checkpoint rewards on the way to the goal)."
        )


class FootballEnv(ParallelEnv, EzPickle):
    """A gfootball scenario with ``N`` controlled left-team players (PettingZoo ``ParallelEnv``).

    :param scenario: gfootball scenario name, e.g. ``"academy_3_vs_1_with_keeper"``, ``"academy_counterattack_easy"``
    :param N: number of controlled left-team players (agent slots)
    :param share_reward: give every agent the sum of the controlled players' rewards (the SAEIR/MAPPO wrapper, +-N per
        goal); ``False``: gfootball's own per-player reward (+-1 per goal)
    :param rewards: gfootball reward spec (``"scoring"`` or ``"scoring,checkpoints"``); ``success`` and ``goal_diff``
        always come from the score
    :param render_mode: only ``None`` (rendering needs an OpenGL context; not supported)
    :param other_config_options: extra values of gfootball's ``Config`` (keep the default 19-action set)
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": [], "name": "grf_v0", "is_parallelizable": True}

    def __init__(
        self,
        scenario: str = "academy_3_vs_1_with_keeper",
        N: int = 3,
        share_reward: bool = True,
        rewards: str = "scoring",
        render_mode: str | None = None,
        other_config_options: dict[str, Any] | None = None,
    ) -> None:
        EzPickle.__init__(
            self,
            scenario=scenario,
            N=N,
            share_reward=share_reward,
            rewards=rewards,
            render_mode=render_mode,
            other_config_options=other_config_options,
        )
        check_positive_int("N", N)
        check_bool(type(self).__name__, share_reward=share_reward)
        check_rewards(rewards)
        if render_mode is not None:
            raise ValueError(f"render_mode={render_mode!r} is not supported by the football tasks (only None).")
        football_env = import_gfootball()
        check_scenario(scenario)
        self.scenario = scenario
        self.n_agents = N
        self.share_reward = share_reward
        self.render_mode = render_mode
        self._rng = np.random.default_rng()
        config = {"game_engine_random_seed": self._draw_engine_seed(), **(other_config_options or {})}
        try:
            self._env: Any = football_env.create_environment(
                env_name=scenario,
                stacked=False,
                representation="simple115v2",
                rewards=rewards,
                number_of_left_players_agent_controls=N,
                number_of_right_players_agent_controls=0,
                render=False,
                other_config_options=config,
            )
        except IndexError as error:  # gfootball's message is "Index out of range"
            raise ValueError(f"N={N} is more than the left team of {scenario!r} has players ({error}).") from error
        self.possible_agents = [f"player_{i}" for i in range(N)]
        self.agents: list[str] = []
        self._observation_space = spaces.Box(low=-np.inf, high=np.inf, shape=(OBSERVATION_SIZE,), dtype=np.float32)
        self._action_space = spaces.Discrete(N_ACTIONS)
        self.state_space = spaces.Box(low=-np.inf, high=np.inf, shape=(N * OBSERVATION_SIZE,), dtype=np.float32)
        self._last_obs = np.zeros((N, OBSERVATION_SIZE), dtype=np.float32)
        self._goal_diff = 0

    # PettingZoo API -----------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Space:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Space:
        return self._action_space

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, np.ndarray], dict[str, dict]]:
        """Start an episode.

        :param seed: re-seed this env's generator, which draws the engine seed of this and every later episode
        :param options: unused
        :return: observations and infos (``active_player`` per agent)
        """
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self._seed_engine(self._draw_engine_seed())
        observation = self._env.reset()
        self._last_obs = self._to_array(observation)
        self._goal_diff = 0
        self.agents = list(self.possible_agents)
        observations = {agent: self._last_obs[i] for i, agent in enumerate(self.possible_agents)}
        infos = {agent: {"active_player": player} for agent, player in zip(self.possible_agents, self.active_players())}
        return observations, infos

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """One step of the game (one action per controlled player).

        :param actions: ``{agent: action in [0, 19)}`` for every agent
        :return: observations, rewards, terminations, truncations, infos
        :raises RuntimeError: if the episode has ended (call :meth:`reset`)
        """
        if not self.agents:
            raise RuntimeError("The football episode has ended (or reset() was never called): call reset() first.")
        observation, reward, done, info = self._env.step([int(actions[agent]) for agent in self.possible_agents])
        self._last_obs = self._to_array(observation)
        score_reward = int(info["score_reward"])
        self._goal_diff += score_reward
        player_rewards = np.asarray(reward, dtype=np.float64).reshape(self.n_agents)  # (N,)
        if self.share_reward:
            rewards = dict.fromkeys(self.possible_agents, float(player_rewards.sum()))
        else:
            rewards = {agent: float(player_rewards[i]) for i, agent in enumerate(self.possible_agents)}

        truncated = bool(done) and self._raw_observation()[0]["steps_left"] <= 0 and score_reward == 0
        terminations = dict.fromkeys(self.possible_agents, bool(done) and not truncated)
        truncations = dict.fromkeys(self.possible_agents, truncated)
        infos: dict[str, dict[str, Any]] = {
            agent: {"score_reward": score_reward, "active_player": player}
            for agent, player in zip(self.possible_agents, self.active_players())
        }
        if done:
            metrics = {"success": float(score_reward > 0), "goal_diff": float(self._goal_diff)}
            for agent in self.possible_agents:
                infos[agent][EPISODE_METRICS_KEY] = dict(metrics)
            self.agents = []
        observations = {agent: self._last_obs[i] for i, agent in enumerate(self.possible_agents)}
        return observations, rewards, terminations, truncations, infos

    def state(self) -> np.ndarray:
        """The agents' observations concatenated, ``(n_agents * 115,)`` (they differ only in the active-player part)."""
        return self._last_obs.reshape(-1).copy()

    def render(self) -> None:
        return None

    def close(self) -> None:
        """Release the engine (gfootball keeps it in a per-process pool that later envs reuse)."""
        if self._env is not None:
            self._env.close()
            self._env = None

    # Helpers ------------------------------------------------------------------------
    def active_players(self) -> list[int]:
        """Left-team index of the physical player each agent slot controls now (gfootball's ``active``)."""
        return [int(obs["active"]) for obs in self._raw_observation()]

    def _raw_observation(self) -> list[dict[str, Any]]:
        """gfootball's raw per-slot observation dicts of the current step (cached by gfootball, no copy)."""
        return self._env.unwrapped.observation()

    def _to_array(self, observation: Any) -> np.ndarray:
        # (115,) for one agent, (N, 115) otherwise -> (N, 115)
        return np.asarray(observation, dtype=np.float32).reshape(self.n_agents, OBSERVATION_SIZE)

    def _draw_engine_seed(self) -> int:
        return int(self._rng.integers(0, MAX_ENGINE_SEED))

    def _seed_engine(self, engine_seed: int) -> None:
        """Make the next episode use ``engine_seed`` (gfootball reads both values when it builds the scenario)."""
        config = self._env.unwrapped._config
        config["game_engine_random_seed"] = engine_seed
        # gfootball derives the team processing order from the seed's parity, but only for the first episode of an env
        # (it then stays in the config); set it every episode so that a seeded reset does not depend on the env's past.
        config["reverse_team_processing"] = bool(engine_seed % 2)
