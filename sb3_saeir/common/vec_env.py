"""PettingZoo parallel games -> one SB3 ``VecEnv`` with one slot per agent.

SuperSuit turns a PettingZoo :class:`~pettingzoo.utils.env.ParallelEnv` into a vector env with one slot per agent
(``pettingzoo_env_to_vec_env_v1``) and concatenates ``n_games`` copies (``concat_vec_envs_v1``). Its own SB3 wrapper
is broken with SB3 2.9 (no ``seed``, ``get_attr``, ``env_method``, ``metadata``; wrong ``reset_infos`` with
subprocesses; overlapping per-game seeds with ``num_cpus > 1``), so :class:`MultiAgentVecEnv` is a proper SB3
:class:`~stable_baselines3.common.vec_env.VecEnv` over SuperSuit's gymnasium-style vector env (games in this
process) or over :class:`~sb3_saeir.common.game_workers.GameWorkerVecEnv` (games in worker processes, with shared-memory
buffers and one message per worker and step; SuperSuit's own worker path kept the second core idle a quarter of the
time, ``docs/guide/performance.md``). The games step alike on both paths (same seeds, same streams; tested).
Double-buffered sampling steps each worker's games on their own (:attr:`GroupedVecEnv.sampling_groups`).

:class:`GroupedVecEnv` is what the algorithms train on and what :class:`MultiAgentVecEnv` and the navigation tasks'
:class:`~sb3_saeir.envs.navigation_vec_env.NavigationVecEnv` share: the layout, seeding, resets, NaN/inf checks, episode
records, per-game access and grouped stepping; each subclass only steps its games.

Slot layout: ``slot = game * n_agents + agent`` with agents in ``possible_agents`` order. All agents of a game
reset together. Episode statistics are recorded once per game (not once per agent, as ``VecMonitor`` would).
"""

from __future__ import annotations

import collections
import copy
import csv
import io
import json
import os
import time
import warnings
from abc import abstractmethod
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from pettingzoo.utils.env import AECEnv, ParallelEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn, VecEnvWrapper

from sb3_saeir.common.atomic import atomic_write_text, keep_damaged
from sb3_saeir.common.checks import check_action_space
from sb3_saeir.common.game_workers import GameFaultError, GameWorkerPool, GameWorkerVecEnv, exit_if_importing_main
from sb3_saeir.common.registry import get_native_vec_env_factory, get_task_factory
from sb3_saeir.common.utils import check_bool, check_seed, usable_cores

ParallelEnvFactory = Callable[..., ParallelEnv]

# Key under which a task env reports its per-episode metrics in ``infos[agent]`` at the last step of an episode.
EPISODE_METRICS_KEY = "episode_metrics"


class AgentDeathError(GameFaultError, RuntimeError):
    """Raised when agents of a game leave it before the game ends (not supported without ``black_death``)."""


# dtype kinds of the numbers a game may return as observations and rewards: bool, signed, unsigned, float
NUMBER_KINDS = "biuf"


class _NoAgentDeath(BaseParallelWrapper):
    """Parallel-env wrapper that checks what one game returns, the same way in this process and in the env workers.

    SuperSuit's ``MarkovVectorEnv`` needs every agent in every step; an env whose agents can die must be wrapped with
    ``supersuit.black_death_v3`` first. A missing or non-numeric observation or reward is refused with a
    :class:`~sb3_saeir.common.game_workers.GameFaultError` naming the env, the game, the agent and the step of its
    episode; ``agents`` are given in ``possible_agents`` order whatever order the game lists them in.

    :param env: the wrapped parallel env
    :param game_index: the game's index in its vec env (for the messages)
    """

    def __getattr__(self, name: str) -> Any:
        if name == "env":  # not yet set (e.g. while unpickling): avoid infinite recursion
            raise AttributeError(name)
        return super().__getattr__(name)

    def __init__(self, env: ParallelEnv, game_index: int = 0) -> None:
        super().__init__(env)
        self._agent_names = list(env.possible_agents)  # as vectorized: SuperSuit keeps the first names
        self._agent_set = set(self._agent_names)
        self._warned: set[str] = set()
        self.game_index = game_index
        self.episode_step = 0  # steps since the last reset

    @property
    def agents(self) -> list:
        """The game's live agents in ``possible_agents`` order (the slot order), whatever order the game uses."""
        live = self.env.agents
        if live == self._agent_names:
            return live
        present = set(live)
        return [agent for agent in self._agent_names if agent in present]

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        observations, infos = self.env.reset(seed=seed, options=options)
        self.episode_step = 0
        self._check_observations(observations)
        return observations, infos

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        observations, rewards, terminations, truncations, infos = self.env.step(actions)
        self.episode_step += 1
        remaining = set(self.env.agents)
        if remaining and remaining != set(self.env.possible_agents):
            missing = sorted(set(self.env.possible_agents) - remaining)
            raise AgentDeathError(
                f"{self._where()}: agents {missing} left the game before it ended. make_multiagent_vec_env needs every "
                "agent in every step: wrap the parallel env with supersuit.black_death_v3(env) so that finished agents "
                "receive zero observations and rewards until the game ends."
            )
        self._check_observations(observations)
        values = self._check_rewards(rewards)
        self._warn_faults(values, terminations, truncations)
        return observations, rewards, terminations, truncations, infos

    def _game_name(self) -> str:
        return str((getattr(self.env, "metadata", None) or {}).get("name") or type(self.env.unwrapped).__name__)

    def _where(self, agent: str | None = None) -> str:
        """``"<env>: game <g>, agent <i> (<name>), step <t> of its episode"`` (``reset`` for a reset)."""
        when = f"step {self.episode_step} of its episode" if self.episode_step else "reset"
        if agent is None:
            return f"{self._game_name()}: game {self.game_index}, {when}"
        index = self._agent_names.index(agent) if agent in self._agent_names else "?"
        return f"{self._game_name()}: game {self.game_index}, agent {index} ({agent}), {when}"

    def _check_observations(self, observations: dict) -> None:
        """Raise one line naming the env, game, agent and step when an observation is missing, unknown, not made of
        numbers (a string, ``None``, an object), of another shape than the declared observation space, or of a dtype
        that does not cast to the declared one by NumPy's ``same_kind`` rule (floats for an integer space). That rule
        is the one of gymnasium's ``concatenate`` on the in-process path (which raised NumPy's raw cast error), so the
        check refuses nothing that path took; in the workers the shared array's assignment truncated such floats
        without a word, and the same check refuses them there too."""
        possible = self._agent_names
        if observations.keys() != self._agent_set:
            unknown = sorted(set(observations) - self._agent_set, key=str)
            if unknown:
                raise GameFaultError(
                    f"{self._where()}: observations of agents {unknown} not in the game's first possible_agents "
                    f"{possible} (agents renamed?); keep the agent names in every reset and step."
                )
            agent = next(agent for agent in possible if agent not in observations)
            raise GameFaultError(
                f"{self._where(agent)}: no observation; every agent of possible_agents needs one in every reset and "
                "step (supersuit.black_death_v3 for finished agents)."
            )
        for agent in possible:
            observation = np.asarray(observations[agent])
            if observation.dtype.kind not in NUMBER_KINDS:
                raise GameFaultError(
                    f"{self._where(agent)}: the observation is {_describe(observations[agent])}, not numbers; return "
                    f"a numeric array as the observation space declares ({self.env.observation_space(agent)})."
                )
            declared = self.env.observation_space(agent)
            expected = declared.shape
            if expected is not None and observation.shape != tuple(expected):
                raise GameFaultError(
                    f"{self._where(agent)}: an observation of shape {observation.shape}, its observation space "
                    f"declares {tuple(expected)}; return observations of the declared shape."
                )
            dtype = declared.dtype
            if dtype is not None and observation.dtype != dtype and not np.can_cast(observation.dtype, dtype, "same_kind"):
                raise GameFaultError(
                    f"{self._where(agent)}: an observation of dtype {observation.dtype}, its observation space declares "
                    f"{dtype}, which {observation.dtype} does not cast to (NumPy's same_kind rule); return observations "
                    f"of the declared dtype, or declare dtype={observation.dtype} in the observation space."
                )

    def _check_rewards(self, rewards: dict) -> np.ndarray:
        """The agents' rewards in ``possible_agents`` order as an array, or one line naming the env, game, agent and
        step of a reward that is missing or not a number (``None``, a string)."""
        possible = self._agent_names
        try:
            values = np.asarray([rewards[agent] for agent in possible])
        except KeyError as error:
            raise GameFaultError(
                f"{self._where(error.args[0])}: no reward; every agent of possible_agents needs one in every step "
                "(0.0 when it earned nothing; supersuit.black_death_v3 for finished agents)."
            ) from None
        if values.dtype.kind not in NUMBER_KINDS or values.shape != (len(possible),):
            for agent in possible:
                value = np.asarray(rewards[agent])
                if value.dtype.kind not in NUMBER_KINDS or value.size != 1:
                    raise GameFaultError(
                        f"{self._where(agent)}: the reward is {_describe(rewards[agent])}, not a number; return a "
                        "float (0.0 when the agent earned nothing)."
                    )
        return values

    def _warn_faults(self, rewards: np.ndarray, terminations: dict, truncations: dict) -> None:
        """Warn once per game instance about rewards of huge magnitude and agents terminated while others continue.

        :param rewards: the agents' rewards in ``possible_agents`` order (checked: numbers)
        """
        warned = self._warned
        if "reward" not in warned:
            values = rewards.astype(np.float64).reshape(-1)
            huge = np.isfinite(values) & (np.abs(values) >= HUGE_REWARD)
            if huge.any():
                warned.add("reward")
                agent = self._agent_names[int(np.flatnonzero(huge)[0])]
                warnings.warn(
                    f"{self._game_name()}: agent {agent!r} received a reward of {values[huge][0]:.3g} (|r| >= "
                    f"{HUGE_REWARD:.0e}); returns and advantages overflow float32: scale the rewards down.",
                    stacklevel=2,
                )
        if "termination" not in warned:
            done = {agent for agent in terminations if terminations[agent] or truncations.get(agent, False)}
            if done and done != set(terminations):
                warned.add("termination")
                warnings.warn(
                    f"{self._game_name()}: agents {sorted(done, key=str)} are done while others continue; "
                    "the game's slots are reset together only when every agent is done, so a done agent's slot "
                    "keeps stepping: end all agents of a game together (or wrap with supersuit.black_death_v3).",
                    stacklevel=2,
                )


def _describe(value: Any) -> str:
    """A short description of a value a game returned, for the messages: its type and a clipped ``repr``."""
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 40 else text[:37] + '...'}"


def _as_vectorized(game: ParallelEnv) -> _NoAgentDeath:
    """One game as the vec env steps it: with a ``render_mode`` (optional in PettingZoo, required by SuperSuit) and
    wrapped in :class:`_NoAgentDeath`."""
    if not hasattr(game.unwrapped, "render_mode"):
        game.unwrapped.render_mode = None
    return _NoAgentDeath(game)


class _WrappedGameFactory:
    """Picklable factory of one game as the vec env steps it, ``_as_vectorized(env_fn())`` (for the worker processes).

    :param env_fn: callable returning one PettingZoo ``ParallelEnv``
    """

    def __init__(self, env_fn: ParallelEnvFactory) -> None:
        self.env_fn = env_fn

    def __call__(self) -> ParallelEnv:
        return _as_vectorized(self.env_fn())


# Rewards of this magnitude or more get a warning: the value loss squares value errors of this size in float32, whose
# largest value is 3.4e38, so a reward of 1e19 already gives inf losses; 1e18 leaves one order of margin.
HUGE_REWARD = 1e18


def check_parallel_env(par_env: Any) -> None:
    """Check that ``par_env`` can be vectorized with one slot per agent and parameter sharing.

    :param par_env: an instance returned by the task factory
    :raises TypeError: for an AEC env or anything that is not a PettingZoo ``ParallelEnv``
    :raises ValueError: when agents have different observation or action spaces
    """
    if isinstance(par_env, AECEnv):
        raise TypeError(
            f"Got a PettingZoo AEC env ({type(par_env).__name__}); make_multiagent_vec_env needs a ParallelEnv. "
            "Convert it with `from pettingzoo.utils.conversions import aec_to_parallel; env = aec_to_parallel(env)` "
            "or use the module's `parallel_env()` constructor."
        )
    if not isinstance(par_env, ParallelEnv) and not (hasattr(par_env, "possible_agents") and hasattr(par_env, "step")):
        raise TypeError(
            f"Expected a PettingZoo ParallelEnv, got {type(par_env).__name__}. For a single-agent gymnasium env use "
            "stable_baselines3.common.env_util.make_vec_env instead."
        )
    agents = list(par_env.possible_agents)
    if len(agents) == 0:
        raise ValueError("The parallel env has no agents (`possible_agents` is empty).")
    obs_space = par_env.observation_space(agents[0])
    act_space = par_env.action_space(agents[0])
    odd_obs = [a for a in agents if par_env.observation_space(a) != obs_space]
    odd_act = [a for a in agents if par_env.action_space(a) != act_space]
    problems, wrappers = [], []
    if odd_obs:
        problems.append(f"agents {odd_obs} have an observation space different from {agents[0]}'s ({obs_space})")
        wrappers.append("supersuit.pad_observations_v0")
    if odd_act:
        problems.append(f"agents {odd_act} have an action space different from {agents[0]}'s ({act_space})")
        wrappers.append("supersuit.pad_action_space_v0")
    if problems:
        raise ValueError(
            f"{'; '.join(problems)}. Parameter sharing needs identical spaces: wrap the env with "
            f"{' and '.join(wrappers)} (and, to tell the agents apart, supersuit.agent_indicator_v0)."
        )


def check_vec_env_options(n_games: Any, num_cpus: Any, mark_truncation: Any, check_finite: Any) -> None:
    """Refuse bad sizes and non-bool flags of :func:`make_multiagent_vec_env` with one line naming the argument.

    :param n_games: an integer >= 1
    :param num_cpus: an integer >= 0
    :param mark_truncation: a bool
    :param check_finite: a bool
    :raises ValueError: for a bad size
    :raises ~sb3_saeir.common.utils.NotABoolError: for a non-bool flag (a ``TypeError`` and a ``ValueError``)
    """
    if isinstance(n_games, bool) or not isinstance(n_games, (int, np.integer)) or n_games < 1:
        raise ValueError(f"n_games must be a positive integer (number of game copies), got {n_games!r}.")
    if isinstance(num_cpus, bool) or not isinstance(num_cpus, (int, np.integer)) or num_cpus < 0:
        raise ValueError(f"num_cpus must be an integer >= 0 (0: every game in this process), got {num_cpus!r}.")
    check_bool("make_multiagent_vec_env", mark_truncation=mark_truncation, check_finite=check_finite)


def warn_more_workers_than_cores(num_cpus: int, n_games: int) -> None:
    """Warn (one line) when ``num_cpus`` starts more env worker processes than this process may use cores: the
    workers then take turns on the cores and the games step slower than with fewer workers.

    :param num_cpus: the ``num_cpus`` argument (>= 2)
    :param n_games: games (at most one worker per game)
    """
    workers, cores = min(int(num_cpus), int(n_games)), usable_cores()
    if workers > cores:
        fix = f"num_cpus={cores} or less" if cores >= 2 else "num_cpus=0 (every game in this process)"
        warnings.warn(
            f"make_multiagent_vec_env: num_cpus={num_cpus} starts {workers} env worker processes, but this machine "
            f"gives this process {cores} core(s): the workers take turns and step slower than fewer would; pass {fix}.",
            UserWarning,
            stacklevel=4,
        )


class NonFiniteValueError(ValueError):
    """An env returned a NaN or infinite observation or reward."""


def check_finite(
    env_name: str,
    observations: np.ndarray,
    rewards: np.ndarray | None,
    n_agents: int,
    agent_names: Sequence[str],
    episode_steps: np.ndarray,
    first_game: int = 0,
) -> None:
    """Raise :class:`NonFiniteValueError` naming the first slot whose observation or reward is NaN or infinite.

    :param env_name: the env, for the message
    :param observations: ``(n_games * n_agents, ...)``
    :param rewards: ``(n_games * n_agents,)``, or ``None`` after a reset
    :param n_agents: agents per game (slot = game * n_agents + agent)
    :param agent_names: the agents' names, in slot order within a game
    :param episode_steps: ``(n_games,)`` the step of each game's episode that produced these values
    :param first_game: index of the first game of these arrays in its vec env (for the message)
    """
    flat = np.asarray(observations).reshape(len(observations), -1)  # (G * N, ...) -> (G * N, d)
    if np.issubdtype(flat.dtype, np.integer) and rewards is None:
        return
    bad_obs = ~np.isfinite(flat).all(axis=1)
    bad_rewards = ~np.isfinite(rewards) if rewards is not None else np.zeros(len(flat), dtype=bool)
    if not (bad_obs.any() or bad_rewards.any()):
        return
    slot = int(np.flatnonzero(bad_obs | bad_rewards)[0])
    game, agent = divmod(slot, n_agents)
    if bad_rewards[slot]:
        what = f"reward {float(rewards[slot])}"  # type: ignore[index]
    else:
        bad_entries = np.flatnonzero(~np.isfinite(flat[slot]))
        what = f"observation has {flat[slot, bad_entries[0]]} at entry {int(bad_entries[0])}"
    step = int(episode_steps[game])
    raise NonFiniteValueError(
        f"{env_name}: game {first_game + game}, agent {agent} ({agent_names[agent]}): {what} at step {step} of its episode "
        f"({int(bad_obs.sum())} observations and {int(bad_rewards.sum())} rewards of this step are not finite). "
        "Fix the env; SB3's VecCheckNan(env, raise_exception=True) also checks the actions that led there; "
        "make_multiagent_vec_env(..., check_finite=False) turns this check off."
    )


# One step of games as their engine returns it, before the episode records: observations ``(rows, ...)``, rewards
# ``(rows,)`` float32, terminations and truncations ``(rows,)`` bool, one info dict per slot (the vec env's own copies).
RawStep = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]


class GroupedVecEnv(VecEnv):
    """What the algorithms train on: an SB3 ``VecEnv`` of ``n_games`` games of ``n_agents`` agents, one slot per
    agent (``slot = game * n_agents + agent``), whose games step all at once or group by group.

    It holds what every such env shares: the layout (:attr:`n_games`, :attr:`n_agents`, :attr:`possible_agents`,
    :meth:`game_of`), per-game seeds (game ``g`` reset with ``seed + g``), lockstep resets, the NaN/inf check of what
    the games return (``check_finite``), ``TimeLimit.truncated`` (``mark_truncation``), one ``episode`` record per game
    (team return ``r``, length ``l``, the task metrics of ``infos[slot][EPISODE_METRICS_KEY]``) in the info of its
    first slot, per-game ``get_attr`` / ``set_attr`` / ``env_method``, rendering of game 0, and the grouped stepping
    of double-buffered sampling (:attr:`sampling_groups`, :meth:`step_group_async`, :meth:`step_any_group_wait`,
    :attr:`n_staged_steps`, :meth:`drain_groups`; :mod:`sb3_saeir.common.sampling`). Two envs implement it:
    :class:`MultiAgentVecEnv` (PettingZoo games, in this process through SuperSuit or in worker processes) and
    :class:`~sb3_saeir.envs.navigation_vec_env.NavigationVecEnv` (the navigation tasks' batched NumPy engine).

    A subclass implements the games: :meth:`_reset_games`, :meth:`_step_games_async`, :meth:`_step_games_wait`,
    :meth:`_abandon_steps`, :meth:`_game_objects`, :meth:`_render_game_zero`, ``get_images`` and ``close``; and, when
    its games run in worker processes, :attr:`sampling_groups` (one group per worker) and :meth:`_first_done_group`.
    An env that can save its exact state for resumed training also has ``get_resume_state`` / ``set_resume_state``
    (:class:`~sb3_saeir.envs.navigation_vec_env.NavigationVecEnv`; :meth:`_records_state` holds this class's part).

    :param n_games: number of games G; the vec env has ``G * n_agents`` slots
    :param possible_agents: the agents' names in slot order within a game
    :param observation_space: one agent's observation space
    :param action_space: one agent's action space
    :param num_cpus: worker processes stepping the games (0: all in this process)
    :param mark_truncation: set ``infos[i]["TimeLimit.truncated"]`` when a game is truncated (not terminated)
    :param check_finite: raise :class:`NonFiniteValueError` (naming the game, agent and step) when an observation or
        reward is NaN or infinite
    :param render_mode: the games' render mode
    :param metadata: the games' metadata (its ``name`` names the env in messages)
    :param sampling_groups: slot ranges of the groups of games that step on their own, in slot order; ``None``: one
        group of all slots
    """

    def __init__(
        self,
        n_games: int,
        possible_agents: Sequence[str],
        observation_space: spaces.Space,
        action_space: spaces.Space,
        num_cpus: int = 0,
        mark_truncation: bool = False,
        check_finite: bool = True,
        render_mode: str | None = None,
        metadata: dict[str, Any] | None = None,
        sampling_groups: Sequence[range] | None = None,
    ) -> None:
        self.n_games = int(n_games)
        self.possible_agents: list[str] = list(possible_agents)
        self.n_agents = len(self.possible_agents)
        self.num_cpus = num_cpus
        self.mark_truncation = mark_truncation
        self.check_finite = check_finite
        self._probe_render_mode = render_mode  # read by VecEnv.__init__ through get_attr("render_mode")
        n_slots = self.n_games * self.n_agents
        #: Slot ranges of the groups of games that step on their own (double-buffered sampling), in slot order: one
        #: per worker process; one group of all slots when the games run in this process.
        self.sampling_groups: list[range] = list(sampling_groups) if sampling_groups is not None else [range(n_slots)]
        super().__init__(n_slots, observation_space, action_space)
        self.metadata = dict(metadata or {})
        self._game_seed: int | None = None
        # grouped stepping: groups with a step in flight, and per group its steps not yet returned by step_wait
        self._in_flight: set[int] = set()
        self._staged: dict[int, collections.deque[RawStep]] = {}
        self._init_episode_records()

    # ------------------------------------------------------------------ what a subclass implements
    @abstractmethod
    def _reset_games(self, seed: int | None, options: dict | None) -> tuple[np.ndarray, list[dict[str, Any]]]:
        """Reset every game (game ``g`` with ``seed + g``, or unseeded).

        :param seed: the base seed, or ``None``
        :param options: reset options for every game
        :return: the first observations ``(n_slots, ...)`` and every slot's reset info
        """

    @abstractmethod
    def _step_games_async(self, actions: np.ndarray, group: int | None) -> None:
        """Start a step of every game (``group`` ``None``) or of one of :attr:`sampling_groups`.

        :param actions: ``(n_slots, ...)`` the actions of every slot, or ``(len(sampling_groups[group]), ...)`` those
            of the group's slots
        :param group: index into :attr:`sampling_groups`, or ``None``
        """

    @abstractmethod
    def _step_games_wait(self, group: int | None, episode_steps: np.ndarray) -> RawStep:
        """Wait for the step started by :meth:`_step_games_async`; finished games are reset (their last observations
        in their slots' infos as ``terminal_observation``) and, with ``check_finite``, the step is checked
        (:meth:`_check_step_finite`).

        :param group: as given to :meth:`_step_games_async`
        :param episode_steps: ``(games of the step,)`` the step of each game's episode that produced the values (for
            the messages)
        :return: the step of the games' slots (``(rows, ...)`` arrays, rows of the group or of every slot)
        """

    @abstractmethod
    def _abandon_steps(self, groups: list[int]) -> None:
        """Wait for (or forget) the steps of ``groups`` in flight, whose results are dropped (:meth:`drain_groups`).

        :param groups: the groups with a step in flight
        """

    @abstractmethod
    def _game_objects(self) -> Sequence[Any]:
        """One object per game for ``get_attr`` / ``set_attr`` / ``env_method`` (its ``unwrapped`` holds the
        attributes); raise when the games cannot be reached from this process."""

    @abstractmethod
    def _render_game_zero(self) -> np.ndarray | None:
        """The frame of game 0 (``render`` has checked the render mode)."""

    def _first_done_group(self, groups: list[int]) -> int:
        """Block until one of ``groups`` (each with a step in flight) has made its step; return it (here: the first,
        for games stepped in this process).

        :param groups: groups with a step in flight, in order
        """
        return groups[0]

    # ------------------------------------------------------------------ layout
    def game_of(self, slot: int) -> int:
        """Game index of a vec env slot (``slot // n_agents``)."""
        return slot // self.n_agents

    def _games_of_indices(self, indices: VecEnvIndices) -> list[int]:
        return [self.game_of(i) for i in self._get_indices(indices)]

    def _env_name(self) -> str:
        """The env's name in messages: its metadata's ``name``, else the class name."""
        metadata_name = (self.metadata or {}).get("name")
        return str(metadata_name) if metadata_name else type(self).__name__

    # ------------------------------------------------------------------ seeding / reset
    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Seed all games at the next reset: game ``g`` gets ``seed + g`` (agents of a game share its seed).

        :param seed: base seed; ``None`` draws one
        :return: the seed of every slot
        """
        seed = check_seed(f"{type(self).__name__}.seed", seed)
        if seed is None:
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max, dtype=np.uint32))
        self._game_seed = int(seed)
        self._seeds = [self._game_seed + self.game_of(i) for i in range(self.num_envs)]
        return self._seeds

    def reset(self, seed: int | None = None, options: dict | None = None) -> VecEnvObs:
        """Reset every game.

        :param seed: optional base seed (game ``g`` gets ``seed + g``); same as calling :meth:`seed` first
        :param options: optional reset options for every game (else those set by ``set_options``)
        :return: the first observations, shape ``(n_games * n_agents, *obs_shape)``
        """
        if seed is not None:
            self.seed(seed)
        if options is None:
            options = self._options[0] if self._options and self._options[0] else None
        if self._staged or self._in_flight:
            self.drain_groups()
        obs, infos = self._reset_games(self._game_seed, options)
        self.reset_infos = infos
        self._game_seed = None
        self._reset_seeds()
        self._reset_options()
        self._episode_returns[:] = 0.0
        self._episode_lengths[:] = 0
        if self.check_finite:
            check_finite(self._env_name(), obs, None, self.n_agents, self.possible_agents, self._episode_lengths)
        return obs

    # ------------------------------------------------------------------ stepping
    def step_async(self, actions: np.ndarray) -> None:
        if self._staged or self._in_flight:
            raise RuntimeError(
                "step_async called while groups of games step on their own (double-buffered sampling): wait for them "
                "and return their steps with step_wait, or call drain_groups() and reset()."
            )
        self._step_games_async(actions, None)

    def step_wait(self) -> VecEnvStepReturn:
        if self._staged:
            obs, rewards, terminations, truncations, infos = self._staged_step()
        else:
            obs, rewards, terminations, truncations, infos = self._step_games_wait(None, self._episode_lengths + 1)
        dones = terminations | truncations
        if self.mark_truncation:
            for slot in np.flatnonzero(truncations & ~terminations):
                infos[slot]["TimeLimit.truncated"] = True
        self._record_episodes(rewards, dones, infos)
        return obs, rewards, dones, infos

    # ------------------------------------------------------------------ grouped stepping (double-buffered sampling)
    def step_group_async(self, group: int, actions: np.ndarray) -> None:
        """Start a step of the games of one of :attr:`sampling_groups`.

        Groups step independently: each may be several steps ahead of another. Once every group has made step ``t``
        (counted from the last reset), :meth:`step_wait` returns step ``t`` of all slots, as if :meth:`step_async`
        had been called with all the actions: the episode records, monitors and wrappers see the steps in order.

        :param group: index into :attr:`sampling_groups`
        :param actions: ``(len(sampling_groups[group]), ...)`` the group's actions
        """
        self._step_games_async(actions, group)
        self._in_flight.add(group)

    def step_any_group_wait(self) -> tuple[int, np.ndarray, np.ndarray]:
        """Wait for the first group in flight to finish its step (checked for NaN/inf, as :meth:`step_wait`).

        :return: the group, its new observations ``(rows, ...)`` and its dones ``(rows,)``
        """
        if not self._in_flight:
            raise RuntimeError("No group of games is stepping: call step_group_async first.")
        group = self._first_done_group(sorted(self._in_flight))
        slots = self.sampling_groups[group]
        first_game = slots.start // self.n_agents
        ahead = len(self._staged.get(group, ()))  # this group's steps ahead of the records
        steps = self._episode_lengths[first_game : first_game + len(slots) // self.n_agents] + 1 + ahead
        try:
            result = self._step_games_wait(group, steps)
        finally:
            self._in_flight.discard(group)
        self._staged.setdefault(group, collections.deque()).append(result)
        obs, _, terminations, truncations, _ = result
        return group, obs, terminations | truncations

    @property
    def n_staged_steps(self) -> int:
        """Steps that every group has made and :meth:`step_wait` has not yet returned."""
        if len(self._staged) < len(self.sampling_groups):
            return 0
        return min(len(queue) for queue in self._staged.values())

    def _staged_step(self) -> RawStep:
        """The oldest step that every group has made, in slot order."""
        if self.n_staged_steps == 0:
            raise RuntimeError(
                "step_wait called before every group of games made the step: wait for every group (step_any_group_wait) first."
            )
        parts = [self._staged[group].popleft() for group in range(len(self.sampling_groups))]
        if len(parts) == 1:
            return parts[0]
        # the groups' (rows_g, ...) arrays -> (n_slots, ...), groups in slot order
        obs, rewards, terminations, truncations = (np.concatenate([part[i] for part in parts]) for i in range(4))
        infos = [info for part in parts for info in part[4]]
        return obs, rewards, terminations, truncations, infos

    def drain_groups(self) -> None:
        """Wait for the groups' steps in flight and drop the staged ones: the games are then out of step with each
        other and with the records, so :meth:`reset` must follow (it calls this itself)."""
        self._staged = {}
        in_flight, self._in_flight = sorted(self._in_flight), set()
        if in_flight:
            self._abandon_steps(in_flight)

    def _check_step_finite(
        self, obs: np.ndarray, rewards: np.ndarray, infos: list[dict], steps: np.ndarray, first_game: int
    ) -> None:
        """Raise :class:`NonFiniteValueError` for a NaN/inf observation, reward or terminal observation of the
        games ``first_game ..`` (``steps``: the step of each game's episode)."""
        names = self.possible_agents
        check_finite(self._env_name(), obs, rewards, self.n_agents, names, steps, first_game)
        with_terminal_observation = [info.get("terminal_observation") is not None for info in infos]
        for slot in np.flatnonzero(with_terminal_observation):
            terminal = infos[slot]["terminal_observation"]
            if not np.isfinite(np.asarray(terminal, dtype=np.float64)).all():
                game = slot // self.n_agents
                check_finite(
                    self._env_name(),
                    np.asarray([terminal]),
                    None,
                    1,
                    [names[slot % self.n_agents]],
                    steps[[game]],
                    first_game + int(game),
                )

    # ------------------------------------------------------------------ episode records
    def _init_episode_records(self) -> None:
        """Per-game episode accumulators (team return = per-step reward averaged over the game's agents)."""
        self._episode_returns = np.zeros(self.n_games, dtype=np.float64)
        self._episode_lengths = np.zeros(self.n_games, dtype=np.int64)
        self._t_start = time.time()
        self.episode_count = 0

    def _record_episodes(self, rewards: np.ndarray, dones: np.ndarray, infos: list[dict[str, Any]]) -> None:
        """Accumulate per-game statistics; at a game's end put one ``episode`` dict into its first agent's info."""
        # (G * N,) -> (G, N)
        rewards_per_game = rewards.reshape(self.n_games, self.n_agents)
        self._episode_returns += rewards_per_game.mean(axis=1)
        self._episode_lengths += 1
        game_done = dones.reshape(self.n_games, self.n_agents).all(axis=1)  # (G * N,) -> (G, N) -> (G,)
        for game in np.flatnonzero(game_done):
            first_slot = game * self.n_agents
            episode: dict[str, Any] = {
                "r": float(self._episode_returns[game]),
                "l": int(self._episode_lengths[game]),
                "t": round(time.time() - self._t_start, 6),
            }
            metrics = infos[first_slot].get(EPISODE_METRICS_KEY)
            if metrics:
                episode.update({key: float(value) for key, value in metrics.items()})
                if "success" in metrics:
                    infos[first_slot]["is_success"] = bool(metrics["success"])
            infos[first_slot]["episode"] = episode
            self._episode_returns[game] = 0.0
            self._episode_lengths[game] = 0
            self.episode_count += 1

    def _records_state(self) -> dict[str, Any]:
        """This class's part of an env's resume state: the running episode returns and lengths, the episode counter
        and any seed or options waiting for the next reset (copies). Between steps only (no group in flight)."""
        return {
            "episode_returns": self._episode_returns.copy(),
            "episode_lengths": self._episode_lengths.copy(),
            "episode_count": self.episode_count,
            "game_seed": self._game_seed,
            "seeds": list(self._seeds),
            "options": copy.deepcopy(self._options),
        }

    def _set_records_state(self, state: dict[str, Any]) -> None:
        """Go back to the part of the state returned by :meth:`_records_state`.

        :param state: a dict holding the keys of :meth:`_records_state`
        """
        self._episode_returns = np.array(state["episode_returns"], dtype=np.float64, copy=True)
        self._episode_lengths = np.array(state["episode_lengths"], dtype=np.int64, copy=True)
        self.episode_count = int(state["episode_count"])
        self._game_seed = state["game_seed"]
        self._seeds = list(state["seeds"])
        self._options = copy.deepcopy(state["options"])

    # ------------------------------------------------------------------ SB3 VecEnv API
    def render(self, mode: str | None = None) -> np.ndarray | None:
        """Render game 0.

        :param mode: must be ``None`` or the ``render_mode`` given to the task (``"rgb_array"`` returns the frame)
        :return: an RGB array of game 0 in ``rgb_array`` mode, else ``None``
        """
        if mode is not None and mode != self.render_mode:
            warnings.warn(
                f"render(mode={mode!r}) ignored: the render mode is fixed when the task is created "
                f"(here {self.render_mode!r}); pass render_mode={mode!r} to make_multiagent_vec_env.",
                stacklevel=2,
            )
            return None
        if self.render_mode is None:
            warnings.warn("render() called but the task was created without render_mode.", stacklevel=2)
            return None
        return self._render_game_zero()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Attribute of the game each slot belongs to (``render_mode``, ``metadata``, ``possible_agents``,
        ``n_agents`` and ``n_games`` also with the games in worker processes)."""
        n_slots = len(list(self._get_indices(indices)))
        if attr_name == "render_mode":
            return [self._probe_render_mode] * n_slots
        if attr_name in ("metadata", "possible_agents", "n_agents", "n_games"):
            return [getattr(self, attr_name)] * n_slots
        games = self._game_objects()
        return [getattr(games[g].unwrapped, attr_name) for g in self._games_of_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute on the game of each slot."""
        games = self._game_objects()
        for g in sorted(set(self._games_of_indices(indices))):
            setattr(games[g].unwrapped, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Call a method of the game each slot belongs to (once per slot)."""
        games = self._game_objects()
        results = []
        for g in self._games_of_indices(indices):
            game = games[g]
            target = game if hasattr(game, method_name) else game.unwrapped
            results.append(getattr(target, method_name)(*method_args, **method_kwargs))
        return results

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        """Games are not gymnasium envs, never gymnasium-wrapped: all ``False``."""
        return [False] * len(list(self._get_indices(indices)))

    def get_state(self) -> np.ndarray:
        """Global state of every game, ``(n_games, *state_shape)``."""
        return np.stack([game.state() for game in self._game_objects()])


class MultiAgentVecEnv(GroupedVecEnv):
    """SB3 ``VecEnv`` over ``n_games`` copies of a PettingZoo parallel game, one slot per agent (a
    :class:`GroupedVecEnv`).

    Use :func:`make_multiagent_vec_env` to build one.

    With SB3's own callbacks, remember that one ``env.step`` is ``n_games * n_agents`` agent-steps:
    ``CheckpointCallback(save_freq=...)`` and ``EvalCallback(eval_freq=...)`` count ``env.step`` calls, and
    ``EvalCallback``'s ``n_eval_episodes`` counts agent slots (each agent's return is an episode). Use
    :class:`~sb3_saeir.evaluation.MultiAgentEvalCallback` (frequency in agent-steps, episodes per game, the task's
    metrics) and wrap other callbacks in :class:`~sb3_saeir.common.callbacks.EveryAgentSteps`. SB3's evaluation warns
    that the env is not wrapped in a ``Monitor``: expected, since episodes are recorded per game by this env itself
    (a ``VecMonitor`` would count every agent as an episode); do not add one.

    :param env_fn: callable returning one PettingZoo ``ParallelEnv`` (one game)
    :param n_games: number of game copies G; the vec env has ``G * n_agents`` slots
    :param num_cpus: worker processes stepping the games (:mod:`sb3_saeir.common.game_workers`; at most one per game;
        0 or 1: all games in this process, through SuperSuit)
    :param mark_truncation: set ``infos[i]["TimeLimit.truncated"]`` when a game is truncated (not terminated), so
        that SB3 bootstraps the value of the final observation. Off by default: time limits are treated as terminal,
        as MAPPO does on MPE, since the observation carries no time feature.
    :param check_finite: raise :class:`NonFiniteValueError` (naming the game, agent and step) as soon as an
        observation or reward is NaN or infinite; ``False`` skips the check (it costs well under 1% of a training step)
    """

    def __init__(
        self,
        env_fn: ParallelEnvFactory,
        n_games: int,
        num_cpus: int = 0,
        mark_truncation: bool = False,
        check_finite: bool = True,
    ) -> None:
        check_vec_env_options(n_games, num_cpus, mark_truncation, check_finite)
        if num_cpus >= 2:
            exit_if_importing_main()  # before anything is built: a worker importing an unguarded script again
            warn_more_workers_than_cores(num_cpus, n_games)
        probe_env = env_fn()
        check_parallel_env(probe_env)
        possible_agents = list(probe_env.possible_agents)
        check_action_space("make_multiagent_vec_env", probe_env.action_space(possible_agents[0]))
        self._probe_env = probe_env
        observation_space = probe_env.observation_space(possible_agents[0])
        action_space = probe_env.action_space(possible_agents[0])
        self.venv: Any = self._game_stepper(env_fn, probe_env, int(n_games), num_cpus, observation_space, action_space)
        self._in_process = not isinstance(self.venv, GameWorkerVecEnv)
        super().__init__(
            n_games,
            possible_agents,
            observation_space,
            action_space,
            num_cpus=num_cpus,
            mark_truncation=mark_truncation,
            check_finite=check_finite,
            render_mode=getattr(probe_env, "render_mode", None),
            metadata=getattr(probe_env, "metadata", {}) or {},
            sampling_groups=None if self._in_process else self.venv.pool.slots_of_worker,
        )

    @staticmethod
    def _game_stepper(
        env_fn: ParallelEnvFactory,
        probe_env: ParallelEnv,
        n_games: int,
        num_cpus: int,
        observation_space: spaces.Box,
        action_space: spaces.Space,
    ) -> Any:
        """The gymnasium-style vector env stepping the games: a :class:`~sb3_saeir.common.game_workers.GameWorkerVecEnv`
        over ``min(num_cpus, n_games)`` worker processes (``num_cpus >= 2``), else SuperSuit's concatenated
        ``MarkovVectorEnv`` copies of ``probe_env`` in this process."""
        if num_cpus >= 2:
            n_agents = len(probe_env.possible_agents)
            pool = GameWorkerPool(
                _WrappedGameFactory(env_fn), n_games, min(num_cpus, n_games), n_agents, observation_space, action_space
            )
            return GameWorkerVecEnv(pool)
        import supersuit as ss

        markov_env = ss.pettingzoo_env_to_vec_env_v1(_as_vectorized(probe_env))
        venv = ss.concat_vec_envs_v1(markov_env, n_games, num_cpus=0, base_class="gymnasium")
        for game, vec in enumerate(venv.vec_envs):  # copies of markov_env: number their checks' messages
            vec.par_env.game_index = game
        return venv

    def _env_name(self) -> str:
        metadata_name = (self.metadata or {}).get("name")
        return str(metadata_name) if metadata_name else type(self._probe_env).__name__

    # ------------------------------------------------------------------ the games (GroupedVecEnv)
    def _game_objects(self) -> list[Any]:
        if not self._in_process:
            raise RuntimeError(
                "Per-game access (get_attr/set_attr/env_method/get_state on arbitrary attributes) is only available "
                "when the games run in this process: create the env with num_cpus=0."
            )
        return [vec.par_env.env for vec in self.venv.vec_envs]  # MarkovVectorEnv -> _NoAgentDeath -> game

    def _reset_games(self, seed: int | None, options: dict | None) -> tuple[np.ndarray, list[dict[str, Any]]]:
        obs, infos = self.venv.reset(seed=seed, options=options)
        return obs, [dict(info) for info in infos]

    def _step_games_async(self, actions: np.ndarray, group: int | None) -> None:
        if group is None or self._in_process:
            self.venv.step_async(actions)
        else:
            self.venv.step_async(actions, [group])  # the group's rows only, written once into shared memory

    def _step_games_wait(self, group: int | None, episode_steps: np.ndarray) -> RawStep:
        if group is None or self._in_process:
            obs, rewards, terminations, truncations, infos = self.venv.step_wait()
        else:
            obs, rewards, terminations, truncations, infos = self.venv.step_wait([group])
        step: RawStep = (
            obs,
            np.asarray(rewards, dtype=np.float32),
            np.asarray(terminations, dtype=bool),
            np.asarray(truncations, dtype=bool),
            [dict(info) for info in infos],
        )
        if self.check_finite:
            first_game = 0 if group is None else self.sampling_groups[group].start // self.n_agents
            self._check_step_finite(step[0], step[1], step[4], episode_steps, first_game)
        return step

    def _first_done_group(self, groups: list[int]) -> int:
        return groups[0] if self._in_process else self.venv.pool.first_done(groups)

    def _abandon_steps(self, groups: list[int]) -> None:
        if self._in_process:
            self.venv.step_wait()
        elif not self.venv.pool.closed:  # a failed worker closes the pool: nothing left to wait for
            self.venv.step_wait(groups)

    # ------------------------------------------------------------------ SB3 VecEnv API
    def close(self) -> None:
        self.venv.close()
        if hasattr(self._probe_env, "close"):
            self._probe_env.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        """Frame of game 0 (SuperSuit renders the first game only); ``None`` for the other slots."""
        frame = self.venv.render()
        return [frame] + [None] * (self.num_envs - 1)

    def _render_game_zero(self) -> np.ndarray | None:
        frame = self.venv.render()
        return frame if self.render_mode == "rgb_array" else None

    def __repr__(self) -> str:
        return (
            f"MultiAgentVecEnv(n_games={self.n_games}, n_agents={self.n_agents}, num_envs={self.num_envs}, "
            f"num_cpus={self.num_cpus})"
        )


# Values of make_multiagent_vec_env's ``backend``.
VEC_ENV_BACKENDS = (None, "native", "supersuit")


def make_multiagent_vec_env(
    task: str | ParallelEnvFactory,
    n_games: int,
    seed: int | None = None,
    num_cpus: int = 0,
    mark_truncation: bool = False,
    backend: str | None = None,
    check_finite: bool = True,
    **task_kwargs: Any,
) -> GroupedVecEnv:
    """Create an SB3 ``VecEnv`` over ``n_games`` copies of a PettingZoo parallel game, one slot per agent.

    Mirrors :func:`stable_baselines3.common.env_util.make_vec_env`: all agents share one policy (parameter sharing);
    slot ``game * n_agents + agent`` holds agent ``agent`` of game ``game``.

    Example::

        env = make_multiagent_vec_env("cn-sparse-n3", n_games=16, seed=0)
        model = PPO("MlpPolicy", env, seed=0).learn(100_000)

    :param task: a registered task id (see :func:`sb3_saeir.envs.list_tasks`, e.g. ``"cn-sparse-n3"``) or a callable
        returning a PettingZoo ``ParallelEnv`` (called with ``task_kwargs``)
    :param n_games: number of game copies
    :param seed: base seed, an integer from 0 to 2**32 - 1 (NumPy integers too); game ``g`` is reset with
        ``seed + g``. ``None``: unseeded (games still differ)
    :param num_cpus: worker processes stepping the games (:mod:`sb3_saeir.common.game_workers`, at most one per
        game); 0 keeps every game in this process. More workers than this process has cores is warned about. A
        script that passes ``num_cpus >= 2`` needs its code under ``if __name__ == "__main__":`` (the workers import
        it again); without the guard, the error says so in one line
    :param mark_truncation: set ``TimeLimit.truncated`` in infos when a game hits its time limit
    :param backend: ``"native"``: the task's own batched vec env (the navigation tasks have one, see
        ``docs/tasks.md``; all games in this process); ``"supersuit"``: the games through SuperSuit, as any
        PettingZoo env; ``None`` (default): native when the task has one and ``num_cpus <= 1``, else SuperSuit
    :param check_finite: raise an error naming the game, agent and step when an observation or reward is NaN or
        infinite (on by default, for games through SuperSuit and the native navigation env alike; ``False`` skips it)
    :param task_kwargs: keyword arguments for the task constructor (e.g. ``N=4``, ``render_mode="rgb_array"``)
    :return: the vector env; ``env.n_agents``, ``env.n_games`` and ``env.possible_agents`` describe the layout
    """
    check_vec_env_options(n_games, num_cpus, mark_truncation, check_finite)
    seed = check_seed("make_multiagent_vec_env", seed)
    if backend not in VEC_ENV_BACKENDS:
        raise ValueError(f"backend must be one of {VEC_ENV_BACKENDS[1:]} or None (the task's default), got {backend!r}.")
    if backend != "supersuit" and (isinstance(task, str) or callable(task)):
        native = get_native_vec_env_factory(task)
        if native is None and backend == "native":
            raise ValueError(f"Task {task!r} has no native vec env; use backend='supersuit' (or None).")
        if native is not None and backend == "native" and num_cpus > 1:
            raise ValueError(
                f"backend='native' steps every game in this process; num_cpus={num_cpus} (worker processes) needs "
                "backend='supersuit'."
            )
        if native is not None and (backend == "native" or num_cpus <= 1):
            native_env: GroupedVecEnv = native(n_games, mark_truncation=mark_truncation, **task_kwargs)
            native_env.check_finite = check_finite
            if seed is not None:
                native_env.seed(seed)
            return native_env

    if isinstance(task, str):
        factory = get_task_factory(task)
    elif callable(task):
        factory = task
    else:
        raise TypeError(f"task must be a registered task id or a callable returning a ParallelEnv, got {task!r}.")

    def env_fn() -> ParallelEnv:
        return factory(**task_kwargs)

    vec_env = MultiAgentVecEnv(
        env_fn, n_games=n_games, num_cpus=num_cpus, mark_truncation=mark_truncation, check_finite=check_finite
    )
    if seed is not None:
        vec_env.seed(seed)
    return vec_env


def is_multiagent_vec_env(env: Any) -> bool:
    """True if ``env`` (possibly inside SB3 ``VecEnvWrapper`` objects) exposes ``n_agents`` and ``n_games`` (as every
    :class:`GroupedVecEnv` does; wrappers forward the attributes)."""
    return getattr(env, "n_agents", None) is not None and getattr(env, "n_games", None) is not None


def joint_observation_space(observation_space: spaces.Box, n_agents: int) -> spaces.Box:
    """Observation space of the concatenation of all agents' observations of one game."""
    low = np.tile(observation_space.low.reshape(-1), n_agents)
    high = np.tile(observation_space.high.reshape(-1), n_agents)
    return spaces.Box(low=low, high=high, dtype=observation_space.dtype)  # type: ignore[arg-type]


class MultiAgentVecMonitor(VecEnvWrapper):
    """Per-game episode records of a :class:`GroupedVecEnv` (a :class:`MultiAgentVecEnv`, a native vec env),
    optionally written as a monitor CSV.

    The multi-agent vec env puts one ``episode`` dict (team return ``r``, game steps ``l``, task metrics) into the info
    of a game's first slot when the game ends; this wrapper keeps the last 10,000 of them in :attr:`episodes` and
    writes each as a row of ``<filename>.monitor.csv`` (SB3's monitor format, readable by
    ``stable_baselines3.common.monitor.load_results`` and rl-zoo3's plot scripts; ``t`` is counted from this wrapper's
    creation, the header's ``t_start``). Unlike SB3's ``VecMonitor`` it counts games, not agents. Attribute access
    falls through to the wrapped env (``n_agents``, ``n_games``, ...).

    With ``append``, an existing CSV is continued (its header and rows kept) rather than started anew: a resumed run
    (``python -m sb3_saeir.train --resume``) writes on into its file. :meth:`get_resume_state` and
    :meth:`set_resume_state` carry the records and the wrapped env's state through a checkpoint
    (:mod:`sb3_saeir.common.run_state`); restoring cuts the CSV back to the rows written by then.

    :param venv: a multi-agent vec env
    :param filename: path prefix of the CSV (``"<dir>/games"`` -> ``<dir>/games.monitor.csv``); ``None``: no file
    :param env_id: written in the CSV header
    :param append: continue an existing CSV instead of overwriting it
    :param log: where :meth:`set_resume_state` says which rows of the CSV were missing or damaged and could or could
        not be restored (default: a warning)
    """

    # observations, rewards and dones pass through unchanged (double-buffered sampling may run under this wrapper)
    passes_steps_through = True

    def __init__(
        self,
        venv: VecEnv,
        filename: str | None = None,
        env_id: str = "games",
        append: bool = False,
        log: Callable[[str], None] | None = None,
    ) -> None:
        super().__init__(venv)
        self.log = log if log is not None else _warn
        self.filename = filename
        self.env_id = env_id
        check_bool("MultiAgentVecMonitor", append=append)
        self.append = append
        self.t_start = time.time()
        self.results_writer: Any = None
        self.episodes: collections.deque[dict[str, Any]] = collections.deque(maxlen=10_000)
        self.n_finished_games = 0

    def reset(self) -> VecEnvObs:
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        for info in infos:
            episode = info.get("episode")
            if episode is not None:
                self._record(dict(episode))
        return obs, rewards, dones, infos

    def _record(self, episode: dict[str, Any]) -> None:
        from stable_baselines3.common.monitor import ResultsWriter

        row = {"r": episode.pop("r"), "l": episode.pop("l"), "t": round(time.time() - self.t_start, 6)}
        episode.pop("t", None)
        row.update(episode)
        self.episodes.append(row)
        self.n_finished_games += 1
        if self.filename is None:
            return
        if self.results_writer is None:
            header: dict[str, float | str] = {"t_start": self.t_start, "env_id": self.env_id}
            keep = self.append and os.path.isfile(self.csv_path)
            self.results_writer = ResultsWriter(
                self.filename, header=header, extra_keys=tuple(episode), override_existing=not keep
            )
        try:
            self.results_writer.write_row(row)
        except OSError as error:  # a full disk: named by the file
            error.filename = error.filename or self.csv_path
            raise

    @property
    def csv_path(self) -> str:
        """The monitor CSV's path (``<filename>.monitor.csv``)."""
        assert self.filename is not None
        return self.filename if self.filename.endswith("monitor.csv") else f"{self.filename}.monitor.csv"

    def get_resume_state(self) -> dict[str, Any]:
        """The wrapped env's state (its ``get_resume_state``) and the records so far.

        :return: a dict for :meth:`set_resume_state`
        """
        return {
            "venv": self.venv.get_resume_state(),  # type: ignore[attr-defined]
            "episodes": list(self.episodes),
            "n_finished_games": self.n_finished_games,
            "t_start": self.t_start,
        }

    def set_resume_state(self, state: dict[str, Any]) -> None:
        """Go back to the state of :meth:`get_resume_state`: the wrapped env's, the records, and the CSV cut back to
        its header and the rows written by then (rows written after, by an interrupted process, are dropped)."""
        self.venv.set_resume_state(state["venv"])  # type: ignore[attr-defined]
        self.episodes = collections.deque(state["episodes"], maxlen=self.episodes.maxlen)
        self.n_finished_games = state["n_finished_games"]
        self.t_start = state["t_start"]
        if self.results_writer is not None:
            self.results_writer.close()
            self.results_writer = None
        if self.filename is not None and (self.n_finished_games or os.path.isfile(self.csv_path)):
            kept = self._restored_csv_lines()
            atomic_write_text(self.csv_path, "".join(line + "\n" for line in kept))
            self.append = bool(kept)

    def _restored_csv_lines(self) -> list[str]:
        """The CSV's lines at the checkpoint: its header's two lines, then one row per game finished by then (rows
        written after it, by an interrupted process, are left out). A row that is missing or damaged (the file cut
        short, deleted or edited) is written again from :attr:`episodes` when it is among the last 10,000 games;
        :attr:`log` says how many rows were written again and how many cannot be restored, and the damaged file is
        kept beside it (:func:`~sb3_saeir.common.atomic.keep_damaged`)."""
        path, n_rows = self.csv_path, self.n_finished_games
        exists = os.path.isfile(path)
        if exists:
            with open(path, newline="") as file:
                lines = file.read().split("\n")[:-1]  # after the last newline: a row cut by a kill
        else:
            lines = []
        if not n_rows:
            return []
        records = list(self.episodes)
        columns = _monitor_columns(lines[:2])
        new_header = not columns
        if new_header:
            columns = ["r", "l", "t", *[key for key in records[-1] if key not in ("r", "l", "t")]]
        header = self._csv_header(columns) if new_header else lines[:2]
        rows = lines[2 : 2 + n_rows]
        first_record = n_rows - len(records)  # the game of records[0]
        kept, restored, lost = [], 0, 0
        for game in range(n_rows):
            if game < len(rows) and _is_monitor_row(rows[game], columns):
                kept.append(rows[game])
            elif game >= first_record:
                kept.append(_monitor_row(records[game - first_record], columns))
                restored += 1
            else:
                lost += 1
        if restored or lost or new_header:
            self._report_restored(path, exists, restored, lost, new_header and exists)
        return [*header, *kept]

    def _csv_header(self, columns: list[str]) -> list[str]:
        """The two header lines of the CSV as SB3's ``ResultsWriter`` writes them (a JSON line, the column names)."""
        return ["#" + json.dumps({"t_start": self.t_start, "env_id": self.env_id}), _monitor_row({}, columns, header=True)]

    def _report_restored(self, path: str, existed: bool, restored: int, lost: int, new_header: bool) -> None:
        """Say which rows of the monitor CSV were missing or damaged, which were written again from the checkpoint and
        how many cannot be restored; keep the damaged file."""
        where = f"the damaged file is kept as {os.path.basename(keep_damaged(path))}" if existed else "it was missing"
        parts = [f"{restored} written again from the checkpoint"] if restored else []
        if lost:
            parts.append(f"{lost} older than its last {self.episodes.maxlen:,} games cannot be restored and are left out")
        if new_header:
            parts.append("the header written again")
        self.log(
            f"{path}: {restored + lost} rows of the games finished by the checkpoint were missing or damaged "
            f"({'; '.join(parts)}; {where}); the run goes on from the checkpoint."
        )

    def close(self) -> None:
        if self.results_writer is not None:
            self.results_writer.close()
        super().close()


def _warn(message: str) -> None:
    """A monitor's default ``log``: a warning."""
    warnings.warn(message, stacklevel=3)


def _monitor_columns(header: list[str]) -> list[str]:
    """The column names of a monitor CSV from its two header lines (empty when they are missing or damaged)."""
    if len(header) < 2 or not header[0].startswith("#"):
        return []
    try:
        json.loads(header[0][1:])
    except ValueError:
        return []
    columns = next(csv.reader([header[1].rstrip("\r")]), [])
    return columns if columns[:3] == ["r", "l", "t"] else []


def _is_monitor_row(line: str, columns: list[str]) -> bool:
    """Whether a line of a monitor CSV is a whole row: one cell per column, numbers as ``r``, ``l`` and ``t``."""
    values = next(csv.reader([line.rstrip("\r")]), [])
    if len(values) != len(columns):
        return False
    try:
        [float(value) for value in values[:3]]
    except ValueError:
        return False
    return True


def _monitor_row(record: dict[str, Any], columns: list[str], header: bool = False) -> str:
    """A row (or, with ``header``, the column line) of a monitor CSV as SB3's ``ResultsWriter`` writes it, without the
    final newline."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns, extrasaction="ignore")
    writer.writeheader() if header else writer.writerow(record)
    return text.getvalue()[:-1]
