"""The base of the multi-agent vec envs: ``n_games`` games of ``n_agents`` agents, one SB3 ``VecEnv`` slot per agent.

:class:`MultiAgentVecEnv` holds what every backend shares (slot layout ``slot = game * n_agents + agent``, per-game
seeds, lockstep resets, NaN/inf checks, one episode record per game, per-game access, grouped stepping); a backend
only steps its games. The backends and their choice: ``docs/guide/custom_env.md``.
"""

from __future__ import annotations

import collections
import copy
import time
import warnings
from abc import abstractmethod
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from sb3_saeir.common.utils import check_seed
from sb3_saeir.common.vec_env.game_checks import check_finite

# Key under which a task env reports its per-episode metrics in ``infos[agent]`` at the last step of an episode.
EPISODE_METRICS_KEY = "episode_metrics"

# What resetting or stepping a closed env says (the worker backend's pool says the same of workers closed by an error).
CLOSED_MESSAGE = "The games are closed (by close()): create a new env to go on."

# One step of games as their engine returns it, before the episode records: observations ``(rows, ...)``, rewards
# ``(rows,)`` float32, terminations and truncations ``(rows,)`` bool, one info dict per slot (the vec env's own copies).
RawStep = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]


class MultiAgentVecEnv(VecEnv):
    """What the algorithms train on: an SB3 ``VecEnv`` of ``n_games`` games of ``n_agents`` agents, one slot per
    agent (``slot = game * n_agents + agent``), whose games step all at once or group by group.

    It holds what every such env shares: the layout (:attr:`n_games`, :attr:`n_agents`, :attr:`possible_agents`,
    :meth:`game_of`), per-game seeds (game ``g`` reset with ``seed + g``), lockstep resets, the NaN/inf check of what
    the games return (``check_finite``), ``TimeLimit.truncated`` (``mark_truncation``), one ``episode`` record per game
    (team return ``r``, length ``l``, the task metrics of ``infos[slot][EPISODE_METRICS_KEY]``) in the info of its
    first slot, per-game ``get_attr`` / ``set_attr`` / ``env_method``, rendering of game 0, and the grouped stepping
    of double-buffered sampling (:attr:`sampling_groups`, :meth:`step_group_async`, :meth:`step_any_group_wait`,
    :attr:`n_staged_steps`, :meth:`drain_groups`; :mod:`sb3_saeir.common.sampling`). Three envs implement it:
    :class:`~sb3_saeir.common.vec_env.pettingzoo.MultiAgentDummyVecEnv` (PettingZoo games in this process, through
    SuperSuit), :class:`~sb3_saeir.common.vec_env.workers.MultiAgentSubprocVecEnv` (PettingZoo games in worker
    processes) and :class:`~sb3_saeir.envs.navigation_vec_env.NavigationVecEnv` (the navigation tasks' batched NumPy
    engine).

    With SB3's own callbacks, remember that one ``env.step`` is ``n_games * n_agents`` agent-steps:
    ``CheckpointCallback(save_freq=...)`` and ``EvalCallback(eval_freq=...)`` count ``env.step`` calls, and
    ``EvalCallback``'s ``n_eval_episodes`` counts agent slots (each agent's return is an episode). Use
    :class:`~sb3_saeir.evaluation.MultiAgentEvalCallback` (frequency in agent-steps, episodes per game, the task's
    metrics) and wrap other callbacks in :class:`~sb3_saeir.common.callbacks.EveryAgentSteps`. SB3's evaluation warns
    that the env is not wrapped in a ``Monitor``: expected, since episodes are recorded per game by this env itself
    (a ``VecMonitor`` would count every agent as an episode); do not add one.

    A subclass implements the games: :meth:`_reset_games`, :meth:`_step_games_async`, :meth:`_step_games_wait`,
    :meth:`_abandon_steps`, :meth:`_game_objects`, :meth:`_render_game_zero` (for ``render`` and ``get_images``) and
    :meth:`_close_games` (for ``close``, which sets :attr:`closed`: a closed env refuses to reset or step); and, when
    its games run in worker processes, :attr:`sampling_groups` (one group per worker) and :meth:`_first_done_group`.
    ``repr`` shows the class name, the layout and the settings of :meth:`_repr_settings`.
    An env that can save its exact state for resumed training also has ``get_resume_state`` / ``set_resume_state``
    (:class:`~sb3_saeir.envs.navigation_vec_env.NavigationVecEnv`; :meth:`_records_state` holds this class's part).

    :param n_games: number of games G; the vec env has ``G * n_agents`` slots
    :param possible_agents: the agents' names in slot order within a game
    :param observation_space: one agent's observation space
    :param action_space: one agent's action space
    :param num_cpus: worker processes stepping the games (0: all in this process)
    :param mark_truncation: set ``infos[i]["TimeLimit.truncated"]`` when a game is truncated (not terminated)
    :param check_finite: raise :class:`~sb3_saeir.common.vec_env.game_checks.NonFiniteValueError` (naming the game,
        agent and step) when an observation or reward is NaN or infinite
    :param render_mode: the games' render mode
    :param metadata: the games' metadata (its ``name`` names the env in messages)
    :param sampling_groups: slot ranges of the groups of games that step on their own, in slot order; ``None``: one
        group of all slots
    :param game_name: the env's name in messages when the metadata has no ``name`` (default: this class's name)
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
        game_name: str | None = None,
    ) -> None:
        self.n_games = int(n_games)
        self.possible_agents: list[str] = list(possible_agents)
        self.n_agents = len(self.possible_agents)
        self.num_cpus = num_cpus
        self.mark_truncation = mark_truncation
        self.check_finite = check_finite
        self._game_name = game_name
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
        #: Set by ``close``: the games cannot be reset or stepped any more (:meth:`_check_open`).
        self.closed = False
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
    def _render_game_zero(self) -> Any:
        """What ``render()`` of game 0 returns (its frame in ``rgb_array`` mode), for ``render`` and ``get_images``."""

    @abstractmethod
    def _close_games(self) -> None:
        """Close the games and whatever steps them (``close`` has marked the env :attr:`closed`)."""

    def _repr_settings(self) -> dict[str, Any]:
        """The settings that ``repr`` shows (with ``repr``) after the layout; here: ``num_cpus``."""
        return {"num_cpus": int(self.num_cpus)}

    def _first_done_group(self, groups: list[int]) -> int:
        """Block until one of ``groups`` (each with a step in flight) has made its step; return it (here: the first,
        for games stepped in this process).

        :param groups: groups with a step in flight, in order
        """
        return groups[0]

    def _check_open(self) -> None:
        """Refuse to reset or step games that ``close`` closed (they stepped on as if open, in this process)."""
        if self.closed:
            raise RuntimeError(CLOSED_MESSAGE)

    # ------------------------------------------------------------------ layout
    def game_of(self, slot: int) -> int:
        """Game index of a vec env slot (``slot // n_agents``)."""
        return slot // self.n_agents

    def _games_of_indices(self, indices: VecEnvIndices) -> list[int]:
        return [self.game_of(i) for i in self._get_indices(indices)]

    def _env_name(self) -> str:
        """The env's name in messages: its metadata's ``name``, else ``game_name``, else the class name."""
        metadata_name = (self.metadata or {}).get("name")
        return str(metadata_name) if metadata_name else self._game_name or type(self).__name__

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
        self._check_open()
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
        self._check_open()
        if self._staged or self._in_flight:
            raise RuntimeError(
                "step_async called while groups of games step on their own (double-buffered sampling): wait for them "
                "and return their steps with step_wait, or call drain_groups() and reset()."
            )
        self._step_games_async(self._checked_actions(actions), None)

    def _checked_actions(self, actions: Any) -> np.ndarray:
        """``step``'s actions as an array of one action per slot, each in the action space: a count of other than
        ``num_envs`` was a raw reshape error, and a ``Discrete`` action outside ``0 .. n - 1`` reached the games (the
        native navigation took -1 as a move)."""
        actions = np.asarray(actions)
        if actions.ndim == 0 or len(actions) != self.num_envs:
            count = "one action" if actions.ndim == 0 else f"actions for {len(actions)} slots"
            raise ValueError(
                f"step: {count}; the env has {self.num_envs} slots ({self.n_games} games x {self.n_agents} agents): pass "
                "one action per slot."
            )
        space = self.action_space
        if isinstance(space, (spaces.Discrete, spaces.MultiDiscrete)):
            high = space.n if isinstance(space, spaces.Discrete) else space.nvec
            numbers = np.issubdtype(actions.dtype, np.number) and not np.issubdtype(actions.dtype, np.complexfloating)
            if numbers:
                bad = (actions != np.round(actions)) | (actions < 0) | (actions >= high)
            else:
                bad = np.ones(actions.shape, dtype=bool)
            if bad.any():
                slot = int(np.argwhere(bad)[0][0])
                raise ValueError(
                    f"step: slot {slot} (game {slot // self.n_agents}, agent {slot % self.n_agents}) got the action "
                    f"{actions[slot]!r}, outside the action space {space}: actions are whole numbers 0 .. n - 1."
                )
            return actions.astype(np.int64, copy=False)  # 0.0, 1.0, ... as SuperSuit's int64 action arrays take them
        return actions

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
        self._check_open()
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

    def _raw_step(
        self,
        group: int | None,
        episode_steps: np.ndarray,
        obs: np.ndarray,
        rewards: Any,
        terminations: Any,
        truncations: Any,
        infos: Sequence[dict[str, Any]],
    ) -> RawStep:
        """A step of games as :meth:`_step_games_wait` returns it: float32 rewards, bool dones, the vec env's own
        copies of the infos; checked for NaN/inf with ``check_finite`` (:meth:`_check_step_finite`).

        :param group: the group that stepped (index into :attr:`sampling_groups`), or ``None`` for every game
        :param episode_steps: the step of each game's episode that produced the values (for the messages)
        """
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

    def _check_step_finite(
        self, obs: np.ndarray, rewards: np.ndarray, infos: list[dict], steps: np.ndarray, first_game: int
    ) -> None:
        """Raise :class:`~sb3_saeir.common.vec_env.game_checks.NonFiniteValueError` for a NaN/inf observation, reward
        or terminal observation of the games ``first_game ..`` (``steps``: the step of each game's episode)."""
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
        frame = self._render_game_zero()
        return frame if self.render_mode == "rgb_array" else None

    def get_images(self) -> Sequence[np.ndarray | None]:
        """Frame of game 0 (the games render the first one only); ``None`` for the other slots."""
        return [self._render_game_zero()] + [None] * (self.num_envs - 1)

    def close(self) -> None:
        """Close the games; the env then refuses to reset or step (:attr:`closed`)."""
        self.closed = True
        self._close_games()

    def __repr__(self) -> str:
        settings = {"n_games": self.n_games, "n_agents": self.n_agents, "num_envs": self.num_envs}
        settings.update(self._repr_settings())
        shown = ", ".join(f"{name}={value!r}" for name, value in settings.items())
        return f"{type(self).__name__}({shown})"

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


def is_multiagent_vec_env(env: Any) -> bool:
    """True if ``env`` (possibly inside SB3 ``VecEnvWrapper`` objects) exposes ``n_agents`` and ``n_games`` (as every
    :class:`MultiAgentVecEnv` does; wrappers forward the attributes)."""
    return getattr(env, "n_agents", None) is not None and getattr(env, "n_games", None) is not None


def joint_observation_space(observation_space: spaces.Box, n_agents: int) -> spaces.Box:
    """Observation space of the concatenation of all agents' observations of one game."""
    low = np.tile(observation_space.low.reshape(-1), n_agents)
    high = np.tile(observation_space.high.reshape(-1), n_agents)
    return spaces.Box(low=low, high=high, dtype=observation_space.dtype)  # type: ignore[arg-type]
