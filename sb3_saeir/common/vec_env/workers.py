"""PettingZoo games in worker processes: :class:`MultiAgentSubprocVecEnv` over a :class:`GameWorkerPool`.

Each worker steps a contiguous block of games; observations, actions, rewards and dones sit in shared memory laid out
as the slots, so a step is one message per worker. Each worker's games form a sampling group that steps on its own
(double-buffered sampling). Same seeds and actions give the same streams as
:class:`~sb3_saeir.common.vec_env.MultiAgentDummyVecEnv` (tested). Details: ``docs/guide/custom_env.md``.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import traceback
from collections.abc import Callable, Sequence
from multiprocessing import connection as mp_connection
from multiprocessing.connection import Connection
from typing import Any

import cloudpickle
import numpy as np
from gymnasium import spaces
from pettingzoo.utils.env import ParallelEnv

from sb3_saeir.common.vec_env.base import MultiAgentVecEnv, RawStep
from sb3_saeir.common.vec_env.game_checks import CheckedGameFactory, GameFaultError, ParallelEnvFactory, probe_game

# Seconds a worker gets to answer "close" before it is terminated.
CLOSE_TIMEOUT_S = 10.0


class GameWorkerError(RuntimeError):
    """A game worker process raised an error or died."""


# Exit status of a worker process that found the main module creating game workers while it was being imported again
# (a script without the ``if __name__ == "__main__":`` guard); the parent reports it in one line.
UNGUARDED_MAIN_EXIT_CODE = 87


def exit_if_importing_main() -> None:
    """End this process at once, silently, with :data:`UNGUARDED_MAIN_EXIT_CODE` if it is a worker process that is
    importing the main module again: a script that creates an env with workers at import time, without the
    ``if __name__ == "__main__":`` guard, would otherwise start workers of its own here and fail with
    multiprocessing's traceback, once per worker. The parent then reports the missing guard in one line."""
    if getattr(mp.current_process(), "_inheriting", False):
        os._exit(UNGUARDED_MAIN_EXIT_CODE)


def split_games(n_games: int, n_workers: int) -> list[range]:
    """Contiguous, balanced blocks of games, one per worker (the first ``n_games % n_workers`` get one more).

    :param n_games: games in all
    :param n_workers: worker processes (at most ``n_games``)
    :return: ``n_workers`` ranges of game indices covering ``0 .. n_games - 1`` in order
    """
    base, extra = divmod(n_games, n_workers)
    blocks, start = [], 0
    for worker in range(n_workers):
        size = base + (1 if worker < extra else 0)
        blocks.append(range(start, start + size))
        start += size
    return blocks


class SharedSlots:
    """The shared arrays of a pool: one row per slot (``n_games * n_agents`` rows).

    :param ctx: the multiprocessing context
    :param n_slots: rows
    :param observation_space: one agent's observation space (a ``Box``)
    :param action_space: one agent's action space
    """

    def __init__(self, ctx: Any, n_slots: int, observation_space: spaces.Box, action_space: spaces.Space) -> None:
        self.n_slots = n_slots
        self.obs_shape = tuple(observation_space.shape)  # type: ignore[arg-type]
        self.obs_dtype = np.dtype(observation_space.dtype)
        self.action_shape = tuple(action_space.shape or ())
        self.action_dtype = np.dtype(action_space.dtype if action_space.dtype is not None else np.int64)
        obs_bytes = n_slots * int(np.prod(self.obs_shape, dtype=np.int64)) * self.obs_dtype.itemsize
        action_bytes = n_slots * int(np.prod(self.action_shape, dtype=np.int64)) * self.action_dtype.itemsize
        self.raw = {
            "obs": ctx.RawArray("b", max(obs_bytes, 1)),
            "actions": ctx.RawArray("b", max(action_bytes, 1)),
            "rewards": ctx.RawArray("b", n_slots * 4),
            "terminations": ctx.RawArray("b", n_slots),
            "truncations": ctx.RawArray("b", n_slots),
        }
        self.attach()

    def attach(self) -> None:
        """Make the numpy views of the raw arrays (in the parent and, after unpickling, in a worker)."""
        n = self.n_slots
        self.obs = np.frombuffer(self.raw["obs"], dtype=self.obs_dtype, count=n * int(np.prod(self.obs_shape)))
        self.obs = self.obs.reshape(n, *self.obs_shape)  # (n_slots * prod(shape),) -> (n_slots, *obs_shape)
        count = n * int(np.prod(self.action_shape, dtype=np.int64))
        self.actions = np.frombuffer(self.raw["actions"], dtype=self.action_dtype, count=count)
        self.actions = self.actions.reshape(n, *self.action_shape)  # (n_slots * prod(shape),) -> (n_slots, ...)
        self.rewards = np.frombuffer(self.raw["rewards"], dtype=np.float32, count=n)
        self.terminations = np.frombuffer(self.raw["terminations"], dtype=np.bool_, count=n)
        self.truncations = np.frombuffer(self.raw["truncations"], dtype=np.bool_, count=n)

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        for view in ("obs", "actions", "rewards", "terminations", "truncations"):
            state.pop(view, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.attach()


class GameBlock:
    """The games of one worker, stepped as SuperSuit steps them in
    :class:`~sb3_saeir.common.vec_env.MultiAgentDummyVecEnv`: a game whose agents are all done puts each agent's last
    observation into its info as ``terminal_observation``, is reset without a seed, and its reset infos are merged into
    the step's infos.

    :param games: parallel envs (already wrapped as the vec env wraps them)
    :param first_slot: slot of the block's first agent
    :param slots: the pool's shared arrays
    """

    def __init__(self, games: list[ParallelEnv], first_slot: int, slots: SharedSlots) -> None:
        self.games = games
        self.slots = slots
        self.agents = list(games[0].possible_agents)
        self.n_agents = len(self.agents)
        self.first_slot = first_slot
        for index, game in enumerate(games, start=first_slot // self.n_agents):
            if hasattr(game, "game_index"):  # the vec env's check around each game: for its messages
                game.game_index = index

    def _rows(self, game: int) -> slice:
        start = self.first_slot + game * self.n_agents
        return slice(start, start + self.n_agents)

    def _write_obs(self, game: int, observations: dict[str, Any]) -> None:
        """Copy one game's observations into its rows. The assignment casts without a check (floats into an integer
        array are truncated): the check around each game (:class:`~sb3_saeir.common.vec_env.game_checks.CheckedParallelEnv`)
        has refused an observation of another shape or of a dtype that does not cast by NumPy's ``same_kind`` rule
        already."""
        rows = self.slots.obs[self._rows(game)]
        for agent_index, agent in enumerate(self.agents):
            rows[agent_index] = observations[agent]

    def reset(self, seeds: Sequence[int | None], options: dict | None) -> list[dict]:
        """Reset every game (game ``i`` with ``seeds[i]``); write the observations; return the slots' infos."""
        infos: list[dict] = []
        for game, (env, seed) in enumerate(zip(self.games, seeds)):
            observations, game_infos = env.reset(seed=seed, options=options)
            self._write_obs(game, observations)
            rows = self._rows(game)
            self.slots.rewards[rows] = 0.0
            self.slots.terminations[rows] = False
            self.slots.truncations[rows] = False
            infos.extend(game_infos.get(agent, {}) for agent in self.agents)
        return infos

    def step(self) -> list[dict]:
        """Step every game with the actions in the shared array; auto-reset finished games; return the infos."""
        infos: list[dict] = []
        for game, env in enumerate(self.games):
            rows = self._rows(game)
            actions = self.slots.actions[rows]
            live = set(env.agents)
            action_dict = {agent: actions[i] for i, agent in enumerate(self.agents) if agent in live}
            observations, rewards, terminations, truncations, game_infos = env.step(action_dict)
            terminated = np.array([bool(terminations.get(agent, False)) for agent in self.agents])
            truncated = np.array([bool(truncations.get(agent, False)) for agent in self.agents])
            self.slots.rewards[rows] = [rewards.get(agent, 0) for agent in self.agents]
            self.slots.terminations[rows] = terminated
            self.slots.truncations[rows] = truncated
            slot_infos = [game_infos.get(agent, {}) for agent in self.agents]
            if (terminated | truncated).all():
                for agent, info in zip(self.agents, slot_infos):
                    if agent in observations:
                        info["terminal_observation"] = observations[agent]
                observations, reset_infos = env.reset()
                slot_infos = [{**info, **reset_infos.get(agent, {})} for agent, info in zip(self.agents, slot_infos)]
            self._write_obs(game, observations)
            infos.extend(slot_infos)
        return infos

    def close(self) -> None:
        for env in self.games:
            env.close()


def worker_main(make_games: bytes, first_slot: int, slots: SharedSlots, pipe: Connection, parent_end: Connection) -> None:
    """A worker's loop: build the block's games, then answer ``reset``, ``step`` and ``close`` messages.

    :param make_games: cloudpickled callable returning the block's list of games
    :param first_slot: slot of the block's first agent
    :param slots: the shared arrays
    :param pipe: this worker's end of the pipe
    :param parent_end: the parent's end (closed here, so that the worker sees EOF if the parent dies)
    """
    parent_end.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle: it closes the workers
    block: GameBlock | None = None
    try:
        block = GameBlock(cloudpickle.loads(make_games)(), first_slot, slots)
        pipe.send(("ok", None))
        while True:
            command, data = pipe.recv()
            if command == "step":
                pipe.send(("ok", block.step()))
            elif command == "reset":
                pipe.send(("ok", block.reset(*data)))
            elif command == "render":
                pipe.send(("ok", block.games[0].render()))
            elif command == "close":
                block.close()
                pipe.send(("ok", None))
                return
            else:
                raise ValueError(f"unknown command {command!r}")
    except EOFError:  # the parent is gone
        return
    except GameFaultError as fault:  # re-raised as it is by the parent: the same error as with the games in-process
        try:
            pipe.send(("fault", fault))
        except (BrokenPipeError, OSError):
            pass
    except BaseException as error:
        try:
            pipe.send(("error", (f"{type(error).__name__}: {error}", traceback.format_exc())))
        except (BrokenPipeError, OSError):
            pass


def unguarded_main_message(start_method: str) -> str:
    """The one line for a script that creates game workers when it is imported (:func:`exit_if_importing_main`).

    :param start_method: the workers' multiprocessing start method
    """
    main = sys.modules.get("__main__")
    script = getattr(main, "__file__", None) or "the main script"
    return (
        f"The game workers could not start: {script} creates an env with num_cpus >= 2 when it is imported, and "
        f"every worker (started with multiprocessing's {start_method!r} method) imports it again; put the script's "
        'code under `if __name__ == "__main__":` (docs/guide/custom_env.md).'
    )


class GameWorkerPool:
    """``n_workers`` processes stepping contiguous blocks of ``n_games`` games (worker ``w``: the block
    ``games_of_worker[w]``), with observations, actions, rewards and dones in shared arrays laid out as the slots. A step
    is one message to each worker and one reply (its slots' infos); workers can be stepped one at a time. A worker's
    error comes back as :class:`GameWorkerError` with its traceback (a game's :class:`GameFaultError` as it is), a
    worker that dies is reported as one, and either closes the pool.

    :param env_fn: callable returning one game (a PettingZoo ``ParallelEnv``), called ``n_games`` times in the workers
    :param n_games: games in all
    :param n_workers: worker processes, ``1 <= n_workers <= n_games``
    :param n_agents: agents per game
    :param observation_space: one agent's observation space
    :param action_space: one agent's action space
    :param start_method: multiprocessing start method; ``None``: ``"forkserver"`` where available, else ``"spawn"``
        (as SB3's ``SubprocVecEnv``; ``"fork"`` is faster to start but unsafe with threads in the parent)
    """

    def __init__(
        self,
        env_fn: Callable[[], ParallelEnv],
        n_games: int,
        n_workers: int,
        n_agents: int,
        observation_space: spaces.Box,
        action_space: spaces.Space,
        start_method: str | None = None,
    ) -> None:
        if not 1 <= n_workers <= n_games:
            raise ValueError(f"n_workers must be between 1 and n_games={n_games}, got {n_workers}.")
        exit_if_importing_main()
        if start_method is None:
            start_method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        ctx = mp.get_context(start_method)
        self.start_method = start_method
        self.n_games = n_games
        self.n_agents = n_agents
        self.games_of_worker = split_games(n_games, n_workers)
        self.slots_of_worker = [range(b.start * n_agents, b.stop * n_agents) for b in self.games_of_worker]
        self.slots = SharedSlots(ctx, n_games * n_agents, observation_space, action_space)
        self.pipes: list[Connection] = []
        self.processes: list[Any] = []
        self._waiting: set[int] = set()
        self.closed = False
        for games, slot_range in zip(self.games_of_worker, self.slots_of_worker):
            make_games = cloudpickle.dumps(_GameFactory(env_fn, len(games)))
            parent_end, child_end = ctx.Pipe()
            process = ctx.Process(  # type: ignore[attr-defined]
                target=worker_main,
                args=(make_games, slot_range.start, self.slots, child_end, parent_end),
                daemon=True,
            )
            process.start()
            child_end.close()
            self.pipes.append(parent_end)
            self.processes.append(process)
        self._waiting = set(range(n_workers))
        try:
            self._receive(range(n_workers))
        except BaseException:
            self.close()
            raise

    @property
    def n_workers(self) -> int:
        return len(self.pipes)

    @property
    def busy(self) -> set[int]:
        """The workers with a step (or reset) in flight."""
        return set(self._waiting)

    def _send(self, workers: Sequence[int], message: tuple[str, Any]) -> None:
        if self.closed:
            raise GameWorkerError(
                "The game workers are closed (by close() or after a worker's error): create a new env to go on."
            )
        for worker in workers:
            if worker in self._waiting:
                raise RuntimeError(f"worker {worker} is still stepping: call step_wait before sending it more work.")
            self.pipes[worker].send(message)
            self._waiting.add(worker)

    def _receive(self, workers: Sequence[int]) -> list[Any]:
        """The replies of ``workers`` (in that order); a worker's error is raised here, after every reply is read."""
        replies, failure = [], None
        for worker in workers:
            if worker not in self._waiting:
                raise RuntimeError(f"worker {worker} has no work in flight (step_async first).")
            try:
                status, data = self.pipes[worker].recv()
            except (EOFError, ConnectionResetError, OSError):
                data = self._death_report(worker)
                status = "unguarded" if isinstance(data, str) else "error"
            self._waiting.discard(worker)
            if status != "ok" and (failure is None or (failure[0] == "error" and status != "error")):
                failure = (status, worker, data)  # a game's fault or the missing guard first: they say what to fix
            replies.append(data)
        if failure is None:
            return replies
        status, worker, data = failure
        self.close()
        if status == "fault":
            raise data
        if status == "unguarded":
            raise GameWorkerError(data)
        message, trace = data
        games = self.games_of_worker[worker]
        raise GameWorkerError(
            f"Game worker {worker} (games {games.start}-{games.stop - 1}) failed: {message}\nWorker traceback:\n{trace}"
        )

    def first_done(self, workers: Sequence[int]) -> int:
        """Block until one of ``workers`` (with work in flight) has answered; return the first in ``workers`` order
        that has."""
        pipes = [self.pipes[worker] for worker in workers]
        ready = set(mp_connection.wait(pipes))
        return next(worker for worker, pipe in zip(workers, pipes) if pipe in ready)

    def _death_report(self, worker: int) -> tuple[str, str] | str:
        """Message and hint for a worker that ended without answering; for a worker that found the main module
        unguarded (:func:`exit_if_importing_main`), the one line that says so."""
        process = self.processes[worker]
        process.join(timeout=1.0)
        if process.exitcode == UNGUARDED_MAIN_EXIT_CODE:
            return unguarded_main_message(self.start_method)
        return (
            f"the worker process ended without answering (exit code {process.exitcode})",
            "Workers start with multiprocessing's forkserver or spawn method, which imports the main module again: a "
            'script that creates the env at import time needs its code under `if __name__ == "__main__":`. '
            "Otherwise the worker was killed (out of memory?) or crashed inside the game's native code.",
        )

    def reset(self, seeds: Sequence[int | None], options: dict | None) -> list[dict]:
        """Reset every game (game ``g`` with ``seeds[g]``) and wait; the observations are in :attr:`slots`.

        :param seeds: one seed (or ``None``) per game
        :param options: reset options for every game
        :return: the infos of every slot
        """
        workers = range(self.n_workers)
        for worker in workers:
            block = self.games_of_worker[worker]
            self._send([worker], ("reset", ([seeds[g] for g in block], options)))
        return [info for infos in self._receive(workers) for info in infos]

    def step_async(self, actions: np.ndarray, workers: Sequence[int] | None = None) -> None:
        """Write the actions of the workers' slots into shared memory and tell those workers to step.

        :param actions: the actions of the workers' slots, ``(rows of the workers, ...)`` in ``workers`` order:
            ``(n_slots, ...)`` for all workers
        :param workers: the workers to step (default: all)
        """
        workers = range(self.n_workers) if workers is None else workers
        start = 0
        for worker in workers:
            rows = self.slots_of_worker[worker]
            self.slots.actions[rows.start : rows.stop] = actions[start : start + len(rows)]
            start += len(rows)
        if start != len(actions):
            raise ValueError(f"step_async got actions for {len(actions)} slots; workers {list(workers)} have {start}.")
        self._send(workers, ("step", None))

    def step_wait(self, workers: Sequence[int] | None = None) -> list[dict]:
        """Wait for the workers' step; their rows of :attr:`slots` then hold the new observations, rewards and dones.

        :param workers: the workers to wait for (default: all)
        :return: the infos of those workers' slots, in slot order
        """
        workers = range(self.n_workers) if workers is None else workers
        return [info for infos in self._receive(workers) for info in infos]

    def render_first_game(self) -> Any:
        """The ``render()`` result of game 0 (in worker 0)."""
        self._send([0], ("render", None))
        return self._receive([0])[0]

    def close(self) -> None:
        """Ask every worker to close its games, then end the processes (terminated after :data:`CLOSE_TIMEOUT_S`)."""
        if self.closed:
            return
        self.closed = True
        for worker, (pipe, process) in enumerate(zip(self.pipes, self.processes)):
            if not process.is_alive():
                continue
            try:
                if worker in self._waiting:  # a step in flight: let it finish first
                    if pipe.poll(CLOSE_TIMEOUT_S):
                        pipe.recv()
                pipe.send(("close", None))
                if pipe.poll(CLOSE_TIMEOUT_S):
                    pipe.recv()
            except (BrokenPipeError, EOFError, ConnectionResetError, OSError):
                pass
        for process in self.processes:
            process.join(timeout=CLOSE_TIMEOUT_S)
            if process.is_alive():
                process.terminate()
                process.join(timeout=CLOSE_TIMEOUT_S)
        for pipe in self.pipes:
            pipe.close()
        self._waiting.clear()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass


class _GameFactory:
    """Picklable ``() -> list of n games`` (each game ``env_fn()``)."""

    def __init__(self, env_fn: Callable[[], ParallelEnv], n: int) -> None:
        self.env_fn = env_fn
        self.n = n

    def __call__(self) -> list[ParallelEnv]:
        return [self.env_fn() for _ in range(self.n)]


class MultiAgentSubprocVecEnv(MultiAgentVecEnv):
    """SB3 ``VecEnv`` over ``n_games`` copies of a PettingZoo parallel game stepped in worker processes, one slot per
    agent (a :class:`~sb3_saeir.common.vec_env.base.MultiAgentVecEnv`; one sampling group per worker), as SB3's
    ``SubprocVecEnv`` steps its envs in subprocesses.

    Use :func:`~sb3_saeir.common.vec_env.factory.make_multiagent_vec_env` with ``num_cpus >= 2`` to build one. It
    gives what :class:`~sb3_saeir.common.vec_env.MultiAgentDummyVecEnv` gives for the same seeds and actions, but
    per-game access (``get_attr`` / ``set_attr`` / ``env_method`` / ``get_state`` of the games' own attributes) needs
    the games in this process.

    :param env_fn: callable returning one PettingZoo ``ParallelEnv`` (one game), called once here and ``n_games``
        times in the workers (it is pickled with cloudpickle)
    :param n_games: number of game copies G; the vec env has ``G * n_agents`` slots
    :param num_cpus: worker processes, at most one per game (``min(num_cpus, n_games)`` start)
    :param mark_truncation: set ``infos[i]["TimeLimit.truncated"]`` when a game is truncated (not terminated)
    :param check_finite: raise :class:`~sb3_saeir.common.vec_env.game_checks.NonFiniteValueError` (naming the game,
        agent and step) as soon as an observation or reward is NaN or infinite
    :param start_method: the workers' multiprocessing start method (:class:`GameWorkerPool`)
    """

    def __init__(
        self,
        env_fn: ParallelEnvFactory,
        n_games: int,
        num_cpus: int = 2,
        mark_truncation: bool = False,
        check_finite: bool = True,
        start_method: str | None = None,
    ) -> None:
        exit_if_importing_main()  # before anything is built: a worker importing an unguarded script again
        probe_env = probe_game(env_fn)
        self._probe_env = probe_env
        possible_agents = list(probe_env.possible_agents)
        observation_space = probe_env.observation_space(possible_agents[0])
        action_space = probe_env.action_space(possible_agents[0])
        n_games = int(n_games)
        #: the worker processes and their shared arrays
        self.pool = GameWorkerPool(
            CheckedGameFactory(env_fn),
            n_games,
            min(num_cpus, n_games),
            len(possible_agents),
            observation_space,
            action_space,
            start_method=start_method,
        )
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
            sampling_groups=self.pool.slots_of_worker,
            game_name=type(probe_env).__name__,
        )

    # ------------------------------------------------------------------ the games (MultiAgentVecEnv)
    def _game_objects(self) -> list[Any]:
        raise RuntimeError(
            "Per-game access (get_attr/set_attr/env_method/get_state on arbitrary attributes) is only available "
            "when the games run in this process: create the env with num_cpus=0."
        )

    def _reset_games(self, seed: int | None, options: dict | None) -> tuple[np.ndarray, list[dict[str, Any]]]:
        seeds = [None if seed is None else seed + game for game in range(self.n_games)]
        infos = self.pool.reset(seeds, options)
        return self.pool.slots.obs.copy(), [dict(info) for info in infos]

    def _step_games_async(self, actions: np.ndarray, group: int | None) -> None:
        # a group's rows only, written once into shared memory
        self.pool.step_async(np.asarray(actions), None if group is None else [group])

    def _step_games_wait(self, group: int | None, episode_steps: np.ndarray) -> RawStep:
        infos = self.pool.step_wait(None if group is None else [group])
        rows = range(self.num_envs) if group is None else self.sampling_groups[group]
        slots, rows_slice = self.pool.slots, slice(rows.start, rows.stop)
        return self._raw_step(
            group,
            episode_steps,
            slots.obs[rows_slice].copy(),
            slots.rewards[rows_slice].copy(),
            slots.terminations[rows_slice].copy(),
            slots.truncations[rows_slice].copy(),
            infos,
        )

    def _first_done_group(self, groups: list[int]) -> int:
        return self.pool.first_done(groups)

    def _abandon_steps(self, groups: list[int]) -> None:
        if not self.pool.closed:  # a failed worker closes the pool: nothing left to wait for
            self.pool.step_wait(groups)

    def _render_game_zero(self) -> Any:
        return self.pool.render_first_game()  # game 0 is in worker 0

    def _close_games(self) -> None:
        self.pool.close()
        if hasattr(self._probe_env, "close"):
            self._probe_env.close()
