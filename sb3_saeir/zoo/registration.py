"""The package's tasks and methods in rl-zoo3: every task registered as a gymnasium id (its task id; the entry point,
:class:`SAEIRGameEnv`, is one game), :func:`games_to_agents` (rl-zoo3's ``vec_env_wrapper``: its game envs become the
package's one-slot-per-agent vec env, with a per-game monitor) and :func:`register_algorithms` (the methods added to
rl-zoo3's ``ALGOS``). The gymnasium ids are registered on import (``--gym-packages sb3_saeir.zoo``). The manual:
``docs/guide/zoo.md``.
"""

from __future__ import annotations

import os
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecEnvWrapper

from sb3_saeir.common.vec_env import (
    EPISODE_METRICS_KEY,
    MultiAgentVecEnv,
    MultiAgentVecMonitor,
    check_parallel_env,
    make_multiagent_vec_env,
)
from sb3_saeir.envs import list_tasks, make_task
from sb3_saeir.run.files import MONITOR_PREFIX

ENTRY_POINT = "sb3_saeir.zoo:SAEIRGameEnv"
WRAPPER_NAME = "sb3_saeir.zoo.games_to_agents"


class EnjoySession:
    """The launcher's replay: collects the :class:`GameMonitor` of every env :func:`games_to_agents` builds while it
    is active, for the per-game summary at the end.

    rl-zoo3 calls the ``vec_env_wrapper`` by its dotted name with YAML keyword arguments only, so the launcher cannot
    hand the session to :func:`games_to_agents` as an argument; the active session is the module's one piece of state,
    set and cleared by the launcher's ``enjoy`` (:mod:`sb3_saeir.zoo.launcher`).
    """

    active: EnjoySession | None = None

    def __init__(self) -> None:
        self.monitors: list[GameMonitor] = []

    def __enter__(self) -> EnjoySession:
        EnjoySession.active = self
        return self

    def __exit__(self, *exc_info: object) -> None:
        EnjoySession.active = None


# ------------------------------------------------------------------------------------------------ gymnasium ids
def gym_id(task: str) -> str:
    """Gymnasium id of a package task: the task id itself (so rl-zoo3 finds the packaged configs' entries)."""
    return task


def register_gym_envs() -> list[str]:
    """Register a gymnasium id for every package task not registered yet (called at import; call it again after
    :func:`sb3_saeir.register_task`).

    :return: the gymnasium ids of the package's tasks
    """
    ids = []
    for task in list_tasks():
        env_id = gym_id(task)
        existing = gym.registry.get(env_id)
        if existing is None:
            gym.register(id=env_id, entry_point=ENTRY_POINT, kwargs={"task": task})
        elif existing.entry_point != ENTRY_POINT:
            warnings.warn(
                f"Gymnasium id {env_id!r} is already registered by {existing.entry_point}; task {task!r} "
                "is not available to rl-zoo3.",
                stacklevel=2,
            )
            continue
        ids.append(env_id)
    return ids


def is_package_env(env_id: str) -> bool:
    """True if ``env_id`` is the gymnasium id of a package task."""
    spec = gym.registry.get(env_id)
    return spec is not None and spec.entry_point == ENTRY_POINT


class SAEIRGameEnv(gym.Env):
    """One game of a package task as a gymnasium env: what rl-zoo3 constructs (and :func:`games_to_agents` replaces).

    Also usable on its own (a centralised controller of all agents): observation ``(N, obs_dim)`` (agents in
    ``possible_agents`` order), action ``MultiDiscrete`` of the per-agent action counts (``Box(N, ...)`` for continuous
    actions), reward = mean of the agents' rewards, ``terminated`` / ``truncated`` when every agent is. At a game's
    end, ``info`` has the task's ``episode_metrics`` (and ``is_success``); ``info["agents"]`` holds the agents' infos.

    :param task: package task id
    :param render_mode: passed to the task when not ``None``
    :param task_kwargs: keyword arguments of the task (e.g. ``N=3``); kept in :attr:`saeir_task_kwargs`
    """

    metadata: dict[str, Any] = {"render_modes": ["human", "rgb_array"]}  # noqa: RUF012 (gymnasium's convention)

    def __init__(self, task: str, render_mode: str | None = None, **task_kwargs: Any) -> None:
        self.saeir_task = task
        self.saeir_task_kwargs = dict(task_kwargs)
        if render_mode is not None:
            self.saeir_task_kwargs["render_mode"] = render_mode
        self.render_mode = render_mode
        self.game = make_task(task, **self.saeir_task_kwargs)
        check_parallel_env(self.game)
        self.possible_agents = list(self.game.possible_agents)
        self.n_agents = len(self.possible_agents)
        self.metadata = {**self.metadata, **dict(getattr(self.game, "metadata", {}) or {})}
        obs_space = self.game.observation_space(self.possible_agents[0])
        act_space = self.game.action_space(self.possible_agents[0])
        if not isinstance(obs_space, spaces.Box):
            raise NotImplementedError(f"SAEIRGameEnv needs Box observations, task {task!r} has {obs_space}.")
        self._agent_obs_shape = obs_space.shape
        shape = (self.n_agents, *obs_space.shape)
        self.observation_space = spaces.Box(
            np.broadcast_to(obs_space.low, shape), np.broadcast_to(obs_space.high, shape), dtype=obs_space.dtype.type
        )
        self.action_space: spaces.Space
        if isinstance(act_space, spaces.Discrete):
            self.action_space = spaces.MultiDiscrete(
                np.full(self.n_agents, act_space.n), start=np.full(self.n_agents, act_space.start)
            )
        elif isinstance(act_space, spaces.Box):
            act_shape = (self.n_agents, *act_space.shape)
            self.action_space = spaces.Box(
                np.broadcast_to(act_space.low, act_shape),
                np.broadcast_to(act_space.high, act_shape),
                dtype=act_space.dtype.type,
            )
        else:
            raise NotImplementedError(f"SAEIRGameEnv supports Discrete and Box actions, task {task!r} has {act_space}.")

    def _stack(self, observations: dict[str, Any]) -> np.ndarray:
        zeros = np.zeros(self._agent_obs_shape, dtype=self.observation_space.dtype)
        return np.stack([np.asarray(observations.get(agent, zeros)) for agent in self.possible_agents])

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        observations, infos = self.game.reset(seed=seed, options=options)
        return self._stack(observations), {"agents": infos}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        action = np.asarray(action)
        discrete = isinstance(self.action_space, spaces.MultiDiscrete)
        alive = set(self.game.agents)
        actions = {
            agent: (int(action[i]) if discrete else action[i])
            for i, agent in enumerate(self.possible_agents)
            if agent in alive
        }
        observations, rewards, terminations, truncations, infos = self.game.step(actions)
        reward = float(np.mean([rewards[agent] for agent in rewards])) if rewards else 0.0
        terminated = bool(terminations) and all(terminations.values())
        truncated = not terminated and all(terminations[agent] or truncations[agent] for agent in terminations)
        info: dict[str, Any] = {"agents": infos}
        for agent_info in infos.values():
            if EPISODE_METRICS_KEY in agent_info:
                metrics = dict(agent_info[EPISODE_METRICS_KEY])
                info[EPISODE_METRICS_KEY] = metrics
                if "success" in metrics:
                    info["is_success"] = bool(metrics["success"])
                break
        return self._stack(observations), reward, terminated, truncated, info

    def render(self) -> Any:
        return self.game.render()

    def close(self) -> None:
        self.game.close()


# ------------------------------------------------------------------------------------------------ vec_env_wrapper
GameMonitor = MultiAgentVecMonitor  # one monitor class for the package; the name is kept for rl-zoo users


def _unwrap(venv: VecEnv) -> VecEnv:
    while isinstance(venv, VecEnvWrapper):
        venv = venv.venv
    return venv


def _monitor_files(venv: VecEnv) -> list[str]:
    """Paths of the ``Monitor`` CSVs of rl-zoo3's game envs (``DummyVecEnv`` only; ``[]`` when not logged)."""
    base = _unwrap(venv)
    if isinstance(base, DummyVecEnv):
        files = []
        for env in base.envs:
            try:
                writer = env.get_wrapper_attr("results_writer")
            except AttributeError:
                writer = None
            if writer is not None:
                files.append(os.path.abspath(writer.file_handler.name))
        return files
    if isinstance(base, SubprocVecEnv):  # Python shows this warning once per process (the default warnings filter)
        warnings.warn(
            "games_to_agents: rl-zoo3 built the game envs in subprocesses (train --vec-env subproc, or plain "
            "rl_zoo3.enjoy with --n-envs > 1), where the location of its monitor files cannot be read: if it logs "
            "this env (training env; enjoy --reward-log), no games.monitor.csv is written. The game envs are only "
            "constructed, never stepped: use --vec-env dummy (or the sb3_saeir.zoo launcher for enjoy) and "
            "games_to_agents' num_cpus for env worker processes.",
            stacklevel=3,
        )
    return []


def _remove_if_empty(path: str) -> None:
    """Delete a monitor CSV that holds only its two header lines (a game env that was never stepped)."""
    try:
        with open(path) as file:
            n_lines = sum(1 for _ in file)
        if n_lines <= 2:
            os.remove(path)
    except OSError:
        pass


def games_to_agents(venv: VecEnv, num_cpus: int = 0, mark_truncation: bool = False) -> GameMonitor:
    """rl-zoo3 ``vec_env_wrapper``: replace rl-zoo3's vec env of G games by the package's multi-agent vec env.

    Reads the task id and kwargs from the game envs, takes the seed rl-zoo3 gave them (``venv.seed(seed)`` of
    ``make_vec_env``; game ``g`` is then reset with ``seed + g``), closes them, and builds
    ``make_multiagent_vec_env(task, n_games=G, seed, num_cpus, mark_truncation, **kwargs)``. When rl-zoo3 logs
    monitor files for this env (the training env, or enjoy's ``--reward-log``), their header-only per-game files are
    deleted and ``games.monitor.csv`` (one row per finished game) is written in the same folder instead.

    YAML entry (rl-zoo3's ``vec_env_wrapper`` syntax)::

        vec_env_wrapper: sb3_saeir.zoo.games_to_agents
        vec_env_wrapper: [{sb3_saeir.zoo.games_to_agents: {num_cpus: 2, mark_truncation: true}}]

    :param venv: rl-zoo3's vec env over :class:`SAEIRGameEnv` games (``DummyVecEnv`` or ``SubprocVecEnv``)
    :param num_cpus: env worker processes (the game worker pool; 0: all games in this process)
    :param mark_truncation: see :func:`~sb3_saeir.make_multiagent_vec_env`
    :return: the multi-agent vec env (``n_games * n_agents`` slots) in a :class:`GameMonitor`
    """
    if not venv.has_attr("saeir_task"):
        raise TypeError(
            "games_to_agents needs rl-zoo3 envs built from a package task id (gymnasium ids registered by "
            f"sb3_saeir.zoo: {', '.join(register_gym_envs())}); this vec env's envs have no `saeir_task`."
        )
    tasks = venv.get_attr("saeir_task")
    all_kwargs = venv.get_attr("saeir_task_kwargs")
    if any(task != tasks[0] for task in tasks) or any(kwargs != all_kwargs[0] for kwargs in all_kwargs):
        raise ValueError(f"games_to_agents needs identical games, got tasks {tasks} with kwargs {all_kwargs}.")
    task, task_kwargs = tasks[0], dict(all_kwargs[0])
    seeds = getattr(_unwrap(venv), "_seeds", None)
    seed = int(seeds[0]) if seeds and seeds[0] is not None else None
    n_games = venv.num_envs
    monitor_files = _monitor_files(venv)
    venv.close()
    for path in monitor_files:
        _remove_if_empty(path)
    agents: MultiAgentVecEnv = make_multiagent_vec_env(
        task, n_games=n_games, seed=seed, num_cpus=num_cpus, mark_truncation=mark_truncation, **task_kwargs
    )
    filename = os.path.join(os.path.dirname(monitor_files[0]), MONITOR_PREFIX) if monitor_files else None
    monitor = GameMonitor(agents, filename=filename, env_id=gym_id(task))
    if EnjoySession.active is not None:
        EnjoySession.active.monitors.append(monitor)
    return monitor


# ------------------------------------------------------------------------------------------------ algorithms
def register_algorithms() -> list[str]:
    """Add every method of :data:`sb3_saeir.config.ALGOS` to ``rl_zoo3.utils.ALGOS`` (the dict rl-zoo3's train,
    enjoy and ExperimentManager use).

    :return: the method names
    :raises ValueError: when rl-zoo3 already has one of the names for another class
    """
    from rl_zoo3.utils import ALGOS as ZOO_ALGOS

    from sb3_saeir.config import ALGOS

    for name, algo_class in ALGOS.items():
        existing = ZOO_ALGOS.setdefault(name, algo_class)
        if existing is not algo_class:
            raise ValueError(f"rl_zoo3.utils.ALGOS[{name!r}] is already {existing.__name__}, not {algo_class.__name__}.")
    return list(ALGOS)


register_gym_envs()
