"""rl-zoo3 interoperability: train and replay the package's methods with rl-zoo3's own ``train`` and ``enjoy``.

rl-zoo3 builds every environment as ``make_vec_env(gym id, n_envs, seed)``: one gymnasium env per slot. The package
trains on :class:`~sb3_saeir.MultiAgentVecEnv` (one slot per *agent*, ``n_games * n_agents`` slots). This module
bridges the two:

- **Gymnasium ids.** At import, every package task (:func:`sb3_saeir.envs.list_tasks`) is registered in gymnasium
  under its task id (``cn-sparse-n3``, ``cn-sparse-n4``, ...; a valid unversioned gymnasium id). So ``--env`` takes the
  task id, rl-zoo3 reads the packaged ``zoo_configs/<method>.yml`` (keyed by task id) unchanged, and the run folder is
  ``<log folder>/<method>/<task id>_<run>/``. The entry point, :class:`SAEIRGameEnv`, is one game as a gymnasium env
  (joint ``Box(N, obs_dim)`` observation, ``MultiDiscrete`` action, mean team reward); it keeps its task id and
  kwargs and is what rl-zoo3 constructs.
- **vec_env_wrapper.** :func:`games_to_agents` reads the task from rl-zoo3's game envs, closes them, and returns the
  package's multi-agent vec env with ``n_games = n_envs`` games, seeded with rl-zoo3's seed (game ``g`` gets
  ``seed + g``), inside :class:`GameMonitor`, which writes one CSV row per finished *game*.
- **Algorithms.** :func:`register_algorithms` adds every method of :data:`sb3_saeir.config.ALGOS` (``saeir_ppo``,
  ``mappo``, ``sn_mappo``, ``rnd``, ``elign``, ``mshg_only``, ``sae_only``, ``ippo``) to ``rl_zoo3.utils.ALGOS``.
  rl-zoo3 builds its ``--algo`` choices from that dict before it imports ``--gym-packages``, so this needs a launcher.
- **Launcher.** ``python -m sb3_saeir.zoo train|enjoy [rl-zoo3 arguments]`` registers both, then runs
  ``rl_zoo3.train.train()`` / ``rl_zoo3.enjoy.enjoy()``. For a package task it also (train) defaults ``--conf-file`` to
  the packaged ``zoo_configs/<algo>.yml`` and adds ``vec_env_wrapper:'sb3_saeir.zoo.games_to_agents'`` to
  ``-params`` unless the config entry or ``-params`` already sets a ``vec_env_wrapper``; (enjoy) runs at least 2 games
  and builds the construction-only game envs in-process. The wrapper lands in the run's ``config.yml``, so the
  replay (and any rl-zoo3 tool reading ``config.yml``) rebuilds the same multi-agent env. On a package task,
  ``train`` prints the ETA line of ``python -m sb3_saeir.train`` after the first rollout and update
  (:class:`~sb3_saeir.common.callbacks.BudgetEstimate`); the config file is read with the package's YAML loader
  (``5e-4`` is a float; a key given twice is refused with one line, exit status 2).

Commands (``--num-threads 1`` matters on small CPUs; ``--device cpu`` avoids rl-zoo3's ``auto``)::

    # train SAEIR with the packaged config (n_envs=128 games, 6e7 agent-steps); logs/saeir_ppo/cn-sparse-n3_1/
    python -m sb3_saeir.zoo train --algo saeir_ppo --env cn-sparse-n3 --num-threads 1 --device cpu --seed 0 -f logs

    # same, explicit config and overrides: 8 games, 200k agent-steps, evaluate every 4000 * 3 agent-steps
    python -m sb3_saeir.zoo train --algo mappo --env cn-sparse-n3 --conf-file zoo_configs/mappo.yml \\
        --num-threads 1 --device cpu --seed 0 -f logs -n 200000 -params n_envs:8 --eval-freq 4000 --eval-episodes 6

    # replay the latest run for 200 game steps, without a window (2 games; prints per-game statistics)
    python -m sb3_saeir.zoo enjoy --algo saeir_ppo --env cn-sparse-n3 -f logs --num-threads 1 --device cpu \\
        --no-render -n 200

    # stock rl-zoo3 with a stock algorithm: the YAML entry must name the wrapper itself
    python -m rl_zoo3.train --algo ppo --env cn-sparse-n3 --gym-packages sb3_saeir.zoo --conf-file my_ppo.yml ...
    #   my_ppo.yml:  cn-sparse-n3: {n_envs: 8, n_timesteps: 200000, policy: MlpPolicy, env_kwargs: {N: 3},
    #                               vec_env_wrapper: [{sb3_saeir.zoo.games_to_agents: {num_cpus: 0}}]}

Pitfalls (rl-zoo3 2.9.2):

- ``n_envs`` is the number of *games*; the model sees ``n_envs * n_agents`` slots. ``n_timesteps`` / ``-n`` of
  ``train`` count agent-steps.
- ``--eval-freq`` and ``--save-freq`` are divided by ``n_envs`` (games), but the callbacks fire once per vec step,
  i.e. every ``n_games * n_agents`` agent-steps: the effective period is ``freq * n_agents`` agent-steps (3 agents,
  ``--eval-freq 4000``: every 12,000 agent-steps). Pass ``freq / n_agents`` for a period in agent-steps.
- On a package task the launcher's ``train`` runs as a :class:`~sb3_saeir.run.Run` in rl-zoo3's run folder
  (:func:`learn_in_run`): rl-zoo3 builds the config, the env and the model; the run's evaluations (``--eval-episodes``
  game episodes, the task's main metric for ``best_model.zip``, at the start, every ``--eval-freq // n_envs`` vec steps
  on the grid, at the end), its resumable checkpoints (every ``--save-freq // n_envs`` vec steps), ``progress.csv``,
  Ctrl-C's checkpoint and the final ``<task>.zip`` take the place of rl-zoo3's ``EvalCallback`` and
  ``CheckpointCallback`` (the config's own callbacks and the progress bar stay). ``--resume`` (``N``, a run folder's
  path, or the latest run) continues a stopped run exactly, with its own seed, and keeps its ``config.yml`` and
  ``args.yml``. With a stock algorithm or env, rl-zoo3's evaluation (SB3's ``evaluate_policy``) counts
  *agent*-episodes: ``--eval-episodes`` is split over the ``n_eval_envs * n_agents`` slots.
- Monitor files: rl-zoo3's per-game ``<i>.monitor.csv`` would stay empty (the game envs are never stepped), so
  :func:`games_to_agents` deletes these header-only files and writes ``games.monitor.csv`` in the run folder: one row
  per finished game (``r`` team return = per-step reward averaged over the game's agents, summed over the episode;
  ``l`` game steps (``l * n_agents`` agent-steps); ``t``; and the task's episode metrics, e.g. ``coverage_rate``).
  It is the same statistic as the training log's ``rollout/ep_rew_mean``. It is written only with ``--vec-env dummy``
  (the default): with ``subproc`` the monitor location is out of reach (a warning says so). ``--vec-env subproc``
  brings nothing anyway (the game envs are only constructed); for env worker processes use
  ``vec_env_wrapper: [{sb3_saeir.zoo.games_to_agents: {num_cpus: 2}}]``.
- ``enjoy``: ``rl_zoo3.enjoy`` imports ``requests`` (an undeclared dependency: ``pip install requests``). With
  ``--n-envs 1`` it crashes (``ValueError: The truth value of an array ... is ambiguous``) because it assumes one slot
  per env; it prints no episode statistics for ``--n-envs`` >= 2. The launcher therefore replays at least 2 games
  (``--n-envs 1`` becomes 2, with a note) and prints per-game statistics itself at the end; ``--reward-log DIR``
  writes ``DIR/games.monitor.csv``. The tasks have no ``"human"`` render mode, so the launcher adds ``--no-render``
  (with a note). ``-n`` counts game steps (vec steps: each is one step of every game). Plain
  ``rl_zoo3.enjoy`` builds the game envs of ``--n-envs`` >= 2 in subprocesses (slow start, no monitor file); the
  launcher builds them in-process (``ExperimentManager.default_vec_env_cls = DummyVecEnv``). Recurrent actors work:
  enjoy passes the GRU states back to ``predict``.
- ``ippo`` (SB3 ``PPO``) has ``batch_size: 9600`` (the whole rollout of 128 games): set ``batch_size`` too when
  overriding ``n_envs`` (``sb3_saeir.config.build_model`` rescales it; rl-zoo3 does not).
- ``-optimize`` is not supported (no samplers registered for the package's methods); neither is ``--resume`` with a
  stock env.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecEnvWrapper

from sb3_saeir.common.extras import MissingExtraError, require_extra
from sb3_saeir.common.vec_env import (
    EPISODE_METRICS_KEY,
    GroupedVecEnv,
    MultiAgentVecMonitor,
    check_parallel_env,
    make_multiagent_vec_env,
)
from sb3_saeir.envs import list_tasks, make_task
from sb3_saeir.evaluation import summarise_episodes

ENTRY_POINT = "sb3_saeir.zoo:SAEIRGameEnv"
WRAPPER_NAME = "sb3_saeir.zoo.games_to_agents"
GAMES_MONITOR = "games"  # -> games.monitor.csv


class EnjoySession:
    """The launcher's replay: collects the :class:`GameMonitor` of every env :func:`games_to_agents` builds while it
    is active, for the per-game summary at the end.

    rl-zoo3 calls the ``vec_env_wrapper`` by its dotted name with YAML keyword arguments only, so the launcher cannot
    hand the session to :func:`games_to_agents` as an argument; the active session is the module's one piece of state,
    set and cleared by the ``with`` block of :func:`_run_enjoy`.
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
    agents: GroupedVecEnv = make_multiagent_vec_env(
        task, n_games=n_games, seed=seed, num_cpus=num_cpus, mark_truncation=mark_truncation, **task_kwargs
    )
    filename = os.path.join(os.path.dirname(monitor_files[0]), GAMES_MONITOR) if monitor_files else None
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


# ------------------------------------------------------------------------------------------------ launcher
def _load_zoo_entry(conf: str, env_id: str) -> dict[str, Any] | None:
    """The hyperparameters rl-zoo3 will read for ``env_id`` from ``conf`` (same lookup: yaml / .py / module, then
    ``default``), or ``None`` if they cannot be read here (rl-zoo3 then reports the problem itself)."""
    import importlib
    from pathlib import Path

    from sb3_saeir.config import ConfigError, load_yaml

    try:
        if conf.endswith((".yml", ".yaml")):
            with open(conf) as file:
                entries = load_yaml(file) or {}
        elif conf.endswith(".py"):
            namespace: dict[str, Any] = {}
            exec(Path(conf).read_text(), namespace)
            entries = namespace["hyperparams"]
        else:
            entries = importlib.import_module(conf).hyperparams
    except ConfigError as error:  # a duplicate key: rl-zoo3 would keep the last value without a word
        raise ConfigError(f"--conf-file {conf}: {error}") from error
    except Exception:
        return None
    entry = entries.get(env_id, entries.get("default"))
    return dict(entry) if isinstance(entry, dict) else None


def _mini_parser(options: Sequence[tuple[Sequence[str], dict[str, Any]]]) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(add_help=False, allow_abbrev=False)
    for flags, kwargs in options:
        parser.add_argument(*flags, **kwargs)
    return parser


def prepare_train_args(argv: Sequence[str]) -> list[str]:
    """rl-zoo3 ``train`` arguments for a package task: default ``--conf-file`` to the packaged config of the method and
    add the ``vec_env_wrapper`` to ``-params`` unless the config entry or ``-params`` has one. Several ``-params`` groups
    are merged into one (rl-zoo3 would keep only the last). Arguments for other envs are returned unchanged.

    :param argv: the arguments after ``train``
    :return: the arguments for ``rl_zoo3.train.train()``
    """
    from sb3_saeir.config import ALGOS, config_path

    parser = _mini_parser(
        [
            (["--algo"], {"default": "ppo"}),
            (["--env"], {"default": "CartPole-v1"}),
            (["-conf", "--conf-file"], {"default": None}),
            (["-params", "--hyperparams"], {"nargs": "+", "action": "append", "default": []}),
        ]
    )
    args, rest = parser.parse_known_args(list(argv))
    if not is_package_env(args.env):
        return list(argv)
    conf = args.conf_file
    if conf is None and args.algo in ALGOS:
        conf = str(config_path(args.algo))
    params = [item for group in args.hyperparams for item in group]
    keys = {item.split(":")[0] for item in params}
    entry = _load_zoo_entry(conf, args.env) if conf is not None else None
    if "vec_env_wrapper" not in keys and not (entry is not None and entry.get("vec_env_wrapper")):
        params.append(f"vec_env_wrapper:{WRAPPER_NAME!r}")
    new_argv = [*rest, "--algo", args.algo, "--env", args.env]
    if conf is not None:
        new_argv += ["--conf-file", conf]
    if params:
        new_argv += ["-params", *params]
    return new_argv


def check_train_args(argv: Sequence[str]) -> None:
    """The checks of ``python -m sb3_saeir.train`` on the rl-zoo3 ``train`` arguments of a package task (made by
    :func:`prepare_train_args`), before rl-zoo3 creates anything: the log and tensorboard folders can be written, and
    ``n_envs`` (config entry or ``-params``) is a positive integer (rl-zoo3 fails on it after creating the run folder).

    :param argv: the arguments for ``rl_zoo3.train.train()``
    :raises ~sb3_saeir.config.ConfigError: naming the first bad option
    """
    from sb3_saeir.config import check_folder, check_n_envs, parse_params

    parser = _mini_parser(
        [
            (["--env"], {"default": "CartPole-v1"}),
            (["-conf", "--conf-file"], {"default": None}),
            (["-f", "--log-folder"], {"default": "logs"}),
            (["-tb", "--tensorboard-log"], {"default": ""}),
            (["-params", "--hyperparams"], {"nargs": "+", "action": "append", "default": []}),
        ]
    )
    args = parser.parse_known_args(list(argv))[0]
    if not is_package_env(args.env):
        return
    check_folder("-f/--log-folder", args.log_folder)
    check_folder("-tb/--tensorboard-log", args.tensorboard_log or None)
    for item in (item for group in args.hyperparams for item in group):
        check_zoo_param(item)
    items = [item for group in args.hyperparams for item in group if item.split(":")[0] == "n_envs"]
    entry = _load_zoo_entry(args.conf_file, args.env) if args.conf_file is not None else None
    check_n_envs(parse_params(items[-1:])["n_envs"] if items else (entry or {}).get("n_envs"))


def check_zoo_param(item: str) -> None:
    """Refuse a ``-params`` entry that rl-zoo3 cannot read (it evaluates each value as a Python expression, so a bare
    word such as ``compile:bogus`` is a ``NameError`` there), naming the value and how to write a string.

    :param item: one ``key:value`` entry
    :raises ~sb3_saeir.config.ConfigError: naming the entry and the fix
    """
    from rl_zoo3.utils import StoreDict

    from sb3_saeir.config import ConfigError

    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("-params", nargs="+", action=StoreDict)
    key, _, value = item.partition(":")
    try:
        parser.parse_args(["-params", item])
    except Exception as error:  # rl-zoo3's eval: NameError, SyntaxError, ...
        raise ConfigError(
            f"-params {item}: rl-zoo3 reads each value as a Python expression and {value!r} is not one "
            f"({type(error).__name__}: {str(error).splitlines()[0] if str(error) else 'no detail'}); write a string in "
            f"quotes: -params \"{key}:'{value}'\"."
        ) from None


def parse_enjoy_args(argv: Sequence[str]) -> tuple[list[str], argparse.Namespace]:
    """rl-zoo3 ``enjoy`` arguments for a package task (:func:`prepare_enjoy_args`) and the options the launcher reads
    itself (``env``, ``verbose``), from one parse.

    :param argv: the arguments after ``enjoy``
    :return: the arguments for ``rl_zoo3.enjoy.enjoy()`` and the launcher's options
    """
    parser = _mini_parser(
        [
            (["--env"], {"default": "CartPole-v1"}),
            (["--n-envs"], {"type": int, "default": None}),
            (["--verbose"], {"type": int, "default": 1}),
        ]
    )
    args, rest = parser.parse_known_args(list(argv))
    if not is_package_env(args.env):
        return list(argv), args
    if "--verbose" in argv or any(item.startswith("--verbose=") for item in argv):
        rest += ["--verbose", str(args.verbose)]
    n_envs = args.n_envs if args.n_envs is not None else 2
    if n_envs < 2:
        print(
            f"sb3_saeir.zoo: replaying 2 games instead of --n-envs {n_envs} (rl_zoo3.enjoy needs one slot per env "
            "when --n-envs is 1; a game has one slot per agent)."
        )
        n_envs = 2
    if "--no-render" not in rest:
        print(
            "sb3_saeir.zoo: replaying without a window (--no-render added): the package's tasks have no 'human' "
            "render mode (python -m sb3_saeir.enjoy --gif writes a GIF of a game)."
        )
        rest.append("--no-render")
    return [*rest, "--env", args.env, "--n-envs", str(n_envs)], args


def prepare_enjoy_args(argv: Sequence[str]) -> list[str]:
    """rl-zoo3 ``enjoy`` arguments for a package task: at least 2 games (``rl_zoo3.enjoy`` crashes with ``--n-envs 1``
    on a multi-agent env) and ``--no-render`` (the tasks have no ``"human"`` render mode, which rl-zoo3 asks for
    otherwise). Arguments for other envs are returned unchanged."""
    return parse_enjoy_args(argv)[0]


def _print_enjoy_summary(monitors: Sequence[GameMonitor]) -> None:
    episodes = [
        {key: float(value) for key, value in episode.items() if key != "t" and value is not None}
        for monitor in monitors
        for episode in monitor.episodes
    ]
    n_games = sum(monitor.num_envs // monitor.get_attr("n_agents")[0] for monitor in monitors)
    if not episodes:
        print(f"sb3_saeir.zoo: no game finished (each of the {n_games} games needs a full episode; raise -n).")
        return
    summary = summarise_episodes(episodes)
    print(f"sb3_saeir.zoo: {len(episodes)} finished games ({n_games} in parallel)")
    print(f"Mean team return: {summary['ep_rew_mean']:.2f} +/- {summary['ep_rew_std']:.2f}")
    print(f"Mean episode length (game steps): {summary['ep_len_mean']:.2f} +/- {summary['ep_len_std']:.2f}")
    for name in sorted({key for episode in episodes for key in episode} - {"r", "l"}):
        print(f"Mean {name}: {summary[f'{name}_mean']:.3f}")


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m sb3_saeir.zoo train|enjoy [rl-zoo3 arguments]``: register the package's algorithms and envs in
    rl-zoo3, adjust the arguments (:func:`prepare_train_args`, :func:`prepare_enjoy_args`) and run rl-zoo3's
    ``train()`` / ``enjoy()``.

    :param argv: the arguments (default: ``sys.argv[1:]``)
    :return: exit status
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in ("train", "enjoy"):
        print(
            "usage: python -m sb3_saeir.zoo {train,enjoy} [rl-zoo3 arguments]\n"
            f"  algorithms added to rl-zoo3: {', '.join(register_algorithms())}\n"
            f"  env ids (--env): {', '.join(register_gym_envs())}\n"
            "  see `python -m sb3_saeir.zoo train --help` and the module docstring (pydoc sb3_saeir.zoo).",
            file=sys.stderr,
        )
        return 2
    command, rest = argv[0], argv[1:]
    try:
        require_extra("rl_zoo3", "zoo", "python -m sb3_saeir.zoo")
    except MissingExtraError as error:
        print(f"sb3_saeir.zoo: error: {error}", file=sys.stderr)
        return 2
    from sb3_saeir.config import one_line_warnings

    register_algorithms()
    register_gym_envs()
    saved_argv = sys.argv
    try:
        with one_line_warnings("sb3_saeir.zoo"):
            if command == "train":
                return _run_train(rest)
            return _run_enjoy(rest)
    finally:
        sys.argv = saved_argv


def _run_train(argv: Sequence[str]) -> int:
    from sb3_saeir.common.run_lock import RunFolderInUseError, RunFolderLock
    from sb3_saeir.config import ConfigError, resume_target

    try:
        resume, argv = _mini_parser(
            [(["--resume"], {"nargs": "?", "type": resume_target, "const": 0, "default": None})]
        ).parse_known_args(list(argv))
        new_argv = prepare_train_args(argv)
        check_train_args(new_argv)
    except ConfigError as error:
        print(f"sb3_saeir.zoo: error: {error}", file=sys.stderr)
        return 2
    sys.argv = ["python -m sb3_saeir.zoo train", *new_argv]
    package_env = is_package_env(_mini_parser([(["--env"], {"default": "CartPole-v1"})]).parse_known_args(new_argv)[0].env)
    if resume.resume is not None and not package_env:
        print("sb3_saeir.zoo: error: --resume continues runs of the package's tasks only.", file=sys.stderr)
        return 2
    locks: list[RunFolderLock] = []
    try:
        return _train_holding(new_argv, resume.resume, package_env, locks)
    except (ConfigError, RunFolderInUseError) as error:
        print(f"sb3_saeir.zoo: error: {error}", file=sys.stderr)
        return 2
    finally:
        for lock in locks:
            lock.release()


def _train_holding(new_argv: list[str], resume_target: int | Path | None, package_env: bool, locks: list[Any]) -> int:
    """rl-zoo3's ``train`` with the package's hooks, holding the run folder's lock (added to ``locks``): the folder
    resumed (locked and its seed given to rl-zoo3 before it starts), or the new run's (locked before rl-zoo3 creates
    it, so that two commands racing for one run number do not share it)."""
    from unittest import mock

    import yaml
    from rl_zoo3.exp_manager import ExperimentManager
    from rl_zoo3.train import train

    from sb3_saeir.common.run_lock import RunFolderLock
    from sb3_saeir.config import ConfigError, load_yaml

    resumed: tuple[Path, dict[str, Any]] | None = None
    if resume_target is not None:
        folder, record, new_argv = claim_resumed_run(new_argv, resume_target, locks)
        resumed = (folder, record)
    sys.argv = ["python -m sb3_saeir.zoo train", *new_argv]
    original_setup = ExperimentManager.setup_experiment
    original_save_config = ExperimentManager._save_config

    def setup_or_clean_up(manager: Any) -> Any:
        """rl-zoo3's setup (config, env, model) in the run's folder (the one resumed, with its seed); a failure
        removes the folders it created and becomes one line."""
        if resumed is not None:
            _continue_in_run_folder(manager, *resumed)
        folders = [Path(manager.log_path).parent, Path(manager.log_path), Path(manager.save_path)]
        created = [folder for folder in folders if not folder.exists()]
        if resumed is None:
            locks.append(RunFolderLock(manager.save_path).acquire())
        try:
            result = original_setup(manager)
        except Exception as error:
            if resumed is None:
                locks.pop().release()
            remove_created_folders(created)
            raise ConfigError(f"cannot set up {manager.algo} on {manager.env_name}: {one_line(error)}") from error
        manager.saeir_config = dict(result[1]) if result is not None else {}
        return result

    def save_config_of_new_runs(manager: Any, saved_hyperparams: dict[str, Any]) -> None:
        """rl-zoo3's config.yml and args.yml, for a new run only (a resumed run keeps its own)."""
        if resumed is None:
            original_save_config(manager, saved_hyperparams)

    # rl-zoo3 reads --conf-file with yaml.safe_load, which leaves 5e-4 a string: read it as the package's configs are
    try:
        with mock.patch.object(yaml, "safe_load", load_yaml):
            if package_env:
                with (
                    mock.patch.object(
                        ExperimentManager, "learn", lambda manager, model: learn_in_run(manager, model, resume_target)
                    ),
                    mock.patch.object(ExperimentManager, "save_trained_model", lambda manager, model: None),
                    mock.patch.object(ExperimentManager, "setup_experiment", setup_or_clean_up),
                    mock.patch.object(ExperimentManager, "_save_config", save_config_of_new_runs),
                ):
                    train()
            else:
                train()
    except ConfigError as error:
        print(f"sb3_saeir.zoo: error: {error}", file=sys.stderr)
        return 2
    return 0


def claim_resumed_run(argv: list[str], resume: int | Path, locks: list[Any]) -> tuple[Path, dict[str, Any], list[str]]:
    """The run folder ``--resume`` names (the latest run, run ``N`` or a folder's path), locked (the lock added to
    ``locks``), its settings record, and rl-zoo3's arguments with the run's own seed: a ``--seed`` other than the
    run's (or -1, rl-zoo3's default) is refused.

    :param argv: rl-zoo3's ``train`` arguments
    :param resume: ``--resume``'s value
    :param locks: where the folder's lock goes
    :raises ~sb3_saeir.config.ConfigError: naming the problem and the fix
    """
    from rl_zoo3.utils import EnvironmentName

    from sb3_saeir.common.run_lock import RunFolderLock
    from sb3_saeir.config import ConfigError
    from sb3_saeir.experiment import find_run_folder
    from sb3_saeir.run import read_spec_file

    options, _ = _mini_parser(
        [
            (["--algo"], {"default": "ppo"}),
            (["--env"], {"default": "CartPole-v1"}),
            (["-f", "--log-folder"], {"default": "logs"}),
            (["--seed"], {"type": int, "default": -1}),
        ]
    ).parse_known_args(argv)
    folder = find_run_folder(options.log_folder, options.algo, EnvironmentName(options.env).gym_id, resume)
    locks.append(RunFolderLock(folder).acquire())
    try:
        record = read_spec_file(folder)
    except ConfigError as error:
        raise ConfigError(f"--resume: {error}") from None
    if record is None:
        raise ConfigError(f"--resume: {folder} has no spec.json: it is not a run of this command.")
    seed = int(record["seed"])
    if options.seed not in (-1, seed):
        raise ConfigError(
            f"--resume: {folder} was made with --seed {seed}, not --seed {options.seed}: a run goes on with its own "
            f"seed. Give --seed {seed} (or no --seed), or start a new run without --resume."
        )
    seed_free = _mini_parser([(["--seed"], {"default": None})]).parse_known_args(argv)[1]
    return folder, record, [*seed_free, "--seed", str(seed)]


def _continue_in_run_folder(manager: Any, folder: Path, record: dict[str, Any]) -> None:
    """Point rl-zoo3's run at the resumed run's folder (:func:`claim_resumed_run`) and its seed, instead of a new run
    folder."""
    manager.save_path = str(folder)
    manager.params_path = f"{folder}/{manager.env_name}"
    manager.seed = int(record["seed"])
    manager.saeir_stored = record


def learn_in_run(manager: Any, model: Any, resume: int | Path | None) -> None:
    """rl-zoo3's ``learn`` for a package task, as a :class:`~sb3_saeir.run.Run` in rl-zoo3's run folder: the package's
    evaluations (game episodes, the task's main metric; at the start, every ``--eval-freq // n_envs`` vec steps on the
    grid, at the end), resumable checkpoints every ``--save-freq // n_envs`` vec steps, ``progress.csv``, Ctrl-C's
    checkpoint, the final ``<task>.zip`` and ``done.json``; with ``--resume``, the run folder's checkpoint. rl-zoo3's
    own evaluation and checkpoint callbacks give way to the run's (the effective periods are rl-zoo3's).

    :param manager: rl-zoo3's ``ExperimentManager``, set up
    :param model: the model it built (or loaded with ``-i``)
    :param resume: ``--resume``'s value (``None``: a new run)
    """
    from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback

    from sb3_saeir.common.callbacks import BudgetEstimate
    from sb3_saeir.experiment import Experiment
    from sb3_saeir.run import Run, RunLog, RunSpec, command_output, config_record

    task, env = manager.env_name.gym_id, model.get_env()
    vec_step = env.num_envs  # agent-steps

    def period(freq: int) -> int:
        """rl-zoo3's callback period in agent-steps (0: off); its setup already made ``--eval-freq`` and ``--save-freq``
        ``freq // n_envs`` vec steps."""
        return freq * vec_step if freq > 0 else 0

    for callback in manager.callbacks:
        if isinstance(callback, EvalCallback):
            callback.eval_env.close()
    callbacks = [c for c in manager.callbacks if not isinstance(c, (EvalCallback, CheckpointCallback))]
    folder = Path(manager.save_path)
    options = {"--save-freq": manager.save_freq, "-i": manager.trained_agent, "--device": manager.device}
    spec = RunSpec(
        manager.algo, task, manager.seed, int(manager.n_timesteps), manager.n_envs, period(manager.eval_freq),
        manager.n_eval_episodes, {}, config_record(manager.saeir_config), options,
    )  # fmt: skip
    save_freq = period(manager.save_freq) or sys.maxsize  # never but on Ctrl-C
    run = Run(folder, spec, save_freq=save_freq, command=vars(manager.args) if hasattr(manager, "args") else {},
              continue_model=bool(manager.trained_agent), log=RunLog(folder))  # fmt: skip
    if resume is not None:
        run.check_resumable(manager.saeir_stored)
        run.check_settings(manager.saeir_stored, by_path=isinstance(resume, Path))
        env.append = True  # the monitor goes on with its CSV
        print(f"Resuming {folder} from {run.resume.checkpoint.name if run.resume else '?'}")
    experiment = Experiment(manager.algo, task, {"env_kwargs": dict(manager.env_kwargs)}, seed=manager.seed,
                            log_folder=folder, n_games=manager.n_envs)  # fmt: skip
    experiment.env, experiment.model = env, model
    continued = resume is not None or bool(manager.trained_agent)
    output = command_output(
        model, manager.verbose, manager.show_progress, continued, [*callbacks, BudgetEstimate(spec.n_timesteps)]
    )
    try:
        run.write_spec()
        run.start(experiment, output)
        run.train()
    finally:
        experiment.close()


def one_line(error: BaseException) -> str:
    """An error as one line: our messages as they are, another library's with its type (first line only)."""
    from sb3_saeir.config import ConfigError

    text = error.args[0] if isinstance(error, KeyError) and error.args else str(error)
    first = str(text).strip().splitlines()[0] if str(text).strip() else "(no message)"
    return first if isinstance(error, ConfigError) else f"{type(error).__name__}: {first}"


def remove_created_folders(created: Sequence[Path]) -> None:
    """Remove the folders a failed command created (listed outermost first): the innermost with what it holds, the
    others only when they are left empty."""
    import shutil

    for folder in reversed(created):
        if folder == created[-1]:
            shutil.rmtree(folder, ignore_errors=True)
        elif folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()


def _run_enjoy(argv: Sequence[str]) -> int:
    from rl_zoo3.enjoy import enjoy
    from rl_zoo3.exp_manager import ExperimentManager

    from sb3_saeir.config import ConfigError, check_seed_option

    new_argv, options = parse_enjoy_args(argv)
    if is_package_env(options.env):
        try:
            check_seed_option(_mini_parser([(["--seed"], {"type": int, "default": 0})]).parse_known_args(new_argv)[0].seed)
        except ConfigError as error:
            print(f"sb3_saeir.zoo: error: {error}", file=sys.stderr)
            return 2
    # rl_zoo3.enjoy builds its envs with this class attribute (no option for it): the game envs are only constructed,
    # so build them in this process, not in SubprocVecEnv workers; restored afterwards
    saved_vec_env_cls = ExperimentManager.default_vec_env_cls
    if is_package_env(options.env):
        ExperimentManager.default_vec_env_cls = DummyVecEnv
    sys.argv = ["python -m sb3_saeir.zoo enjoy", *new_argv]
    try:
        with EnjoySession() as session:
            enjoy()
        if options.verbose > 0 and session.monitors:
            _print_enjoy_summary(session.monitors)
    except (AssertionError, ValueError, TypeError, KeyError, OSError, MemoryError) as error:
        if not is_package_env(options.env):
            raise
        # rl-zoo3's own checks (a missing -f folder or --exp-id run are assertions), a model or env that cannot load
        print(f"sb3_saeir.zoo: error: enjoy: {one_line(error)}", file=sys.stderr)
        return 2
    finally:
        ExperimentManager.default_vec_env_cls = saved_vec_env_cls
    return 0


register_gym_envs()

if __name__ == "__main__":
    # run the launcher from the importable module, so that rl-zoo3 (which imports "sb3_saeir.zoo") sees its state
    from sb3_saeir import zoo

    sys.exit(zoo.main())
