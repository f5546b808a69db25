""":func:`make_multiagent_vec_env`: the one place that checks the vec env's options and picks its backend.

A task's native vec env (all games in this process), the PettingZoo games in this process through SuperSuit
(:class:`~sb3_saeir.common.vec_env.MultiAgentDummyVecEnv`), or in worker processes
(:class:`~sb3_saeir.common.vec_env.MultiAgentSubprocVecEnv`); the rules: ``docs/guide/custom_env.md``.
"""

from __future__ import annotations

import warnings
from typing import Any

from pettingzoo.utils.env import ParallelEnv

from sb3_saeir.common.registry import VEC_ENV_KEYS, get_native_vec_env_factory, get_task_factory, get_task_spec
from sb3_saeir.common.utils import check_seed, keywords_taken, usable_cores, user_stacklevel
from sb3_saeir.common.vec_env.base import MultiAgentVecEnv
from sb3_saeir.common.vec_env.game_checks import ParallelEnvFactory, check_vec_env_options
from sb3_saeir.common.vec_env.pettingzoo import MultiAgentDummyVecEnv
from sb3_saeir.common.vec_env.workers import MultiAgentSubprocVecEnv, exit_if_importing_main

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
) -> MultiAgentVecEnv:
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
    :param num_cpus: worker processes stepping the games (:mod:`sb3_saeir.common.vec_env.workers`, at most one per
        game); 0 or 1 keeps every game in this process. More workers than this process has cores is warned about. A
        script that passes ``num_cpus >= 2`` needs its code under ``if __name__ == "__main__":`` (the workers import
        it again); without the guard, the error says so in one line
    :param mark_truncation: set ``TimeLimit.truncated`` in infos when a game hits its time limit
    :param backend: ``"native"``: the task's own batched vec env (the navigation tasks have one, see
        ``docs/tasks.md``; all games in this process); ``"supersuit"``: the games as any PettingZoo env (through
        SuperSuit, or in worker processes with ``num_cpus >= 2``); ``None`` (default): native when the task has one and
        ``num_cpus <= 1``, else as any PettingZoo env
    :param check_finite: raise an error naming the game, agent and step when an observation or reward is NaN or
        infinite (on by default, for games through SuperSuit and the native navigation env alike; ``False`` skips it)
    :param task_kwargs: keyword arguments for the task constructor (e.g. ``N=4``, ``render_mode="rgb_array"``)
    :return: the vector env; ``env.n_agents``, ``env.n_games`` and ``env.possible_agents`` describe the layout
    """
    check_vec_env_options(n_games, num_cpus, mark_truncation, check_finite)
    seed = check_seed("make_multiagent_vec_env", seed)
    check_task_kwargs(task, task_kwargs)
    if backend not in VEC_ENV_BACKENDS:
        raise ValueError(f"backend must be one of {VEC_ENV_BACKENDS[1:]} or None (the task's default), got {backend!r}.")
    native = _native_vec_env_factory(task, backend, num_cpus)
    vec_env: MultiAgentVecEnv
    if native is not None:
        vec_env = native(n_games, mark_truncation=mark_truncation, **task_kwargs)
        vec_env.check_finite = check_finite
    else:
        env_fn = _game_factory(task, task_kwargs)
        if num_cpus >= 2:
            exit_if_importing_main()  # a worker importing an unguarded script again ends here, before any warning
            warn_more_workers_than_cores(num_cpus, n_games)
            vec_env = MultiAgentSubprocVecEnv(
                env_fn, n_games, num_cpus=num_cpus, mark_truncation=mark_truncation, check_finite=check_finite
            )
        else:
            vec_env = MultiAgentDummyVecEnv(env_fn, n_games, mark_truncation=mark_truncation, check_finite=check_finite)
    if seed is not None:
        vec_env.seed(seed)
    return vec_env


def check_task_kwargs(task: Any, task_kwargs: dict[str, Any]) -> None:
    """Refuse task keyword arguments the task's game constructor does not take, listing those it takes, before any
    game is built (in env workers the constructor's ``TypeError`` came from another process).

    :param task: a registered task id or a callable returning a ParallelEnv (another value is refused later)
    :param task_kwargs: the keyword arguments for the task constructor
    :raises ValueError: for a keyword the constructor does not take (one without ``**kwargs`` whose signature can be
        read; others are left to the constructor)
    """
    if isinstance(task, str):
        constructor = get_task_spec(task).load()  # an unknown task id: its KeyError names the registered ones
    elif callable(task):
        constructor = task
    else:
        return
    taken = keywords_taken(constructor)
    if taken is None:  # **kwargs or no signature to read (a builtin): the constructor checks its own arguments
        return
    unknown = sorted(set(task_kwargs) - set(taken) - set(VEC_ENV_KEYS))
    if unknown:
        takes = ", ".join(taken) or "none"
        name = getattr(constructor, "__name__", repr(constructor))
        raise ValueError(
            f"make_multiagent_vec_env({task!r}): {', '.join(map(repr, unknown))} is not an argument of the task's "
            f"constructor {name}; it takes: {takes}."
        )


def _native_vec_env_factory(task: Any, backend: str | None, num_cpus: int) -> Any:
    """The task's native vec env factory when it is to be used, else ``None`` (the games as any PettingZoo env).

    :raises ValueError: ``backend="native"`` for a task without one, or with ``num_cpus >= 2``
    """
    if backend == "supersuit" or not (isinstance(task, str) or callable(task)):
        return None
    native = get_native_vec_env_factory(task)
    if native is None and backend == "native":
        raise ValueError(f"Task {task!r} has no native vec env; use backend='supersuit' (or None).")
    if native is not None and backend == "native" and num_cpus > 1:
        raise ValueError(
            f"backend='native' steps every game in this process; num_cpus={num_cpus} (worker processes) needs "
            "backend='supersuit'."
        )
    return native if native is not None and (backend == "native" or num_cpus <= 1) else None


def _game_factory(task: Any, task_kwargs: dict[str, Any]) -> ParallelEnvFactory:
    """``() -> one game`` of a registered task id or a callable, with ``task_kwargs``."""
    if isinstance(task, str):
        factory = get_task_factory(task)
    elif callable(task):
        factory = task
    else:
        raise TypeError(f"task must be a registered task id or a callable returning a ParallelEnv, got {task!r}.")

    def env_fn() -> ParallelEnv:
        return factory(**task_kwargs)

    return env_fn


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
            stacklevel=user_stacklevel(),
        )
