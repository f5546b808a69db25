"""rl-zoo style training from YAML configs: ``python -m sb3_saeir.train --algo saeir_ppo --task cn-sparse-n3``.

Writes rl-zoo's folder layout, ``<log-folder>/<algo>/<task>_<run>/``:

- ``<task>.zip`` (final model), ``best_model.zip`` (best evaluation by the task's main metric),
  ``rl_model_<steps>_steps.zip`` (checkpoints), ``evaluations.npz``, ``games.monitor.csv`` (one row per game episode),
- ``<task>/config.yml`` (resolved hyperparameters), ``<task>/args.yml`` (command-line arguments), and tensorboard
  events under ``--tensorboard-log``.

A new run number is used for every run, so nothing already saved is overwritten. ``--optimize`` tunes
hyperparameters with Optuna (``sb3_saeir.hyperparams_opt``).
"""

from __future__ import annotations

import argparse
import inspect
import sys
import time
import types
import typing
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
import yaml
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback
from stable_baselines3.common.utils import set_random_seed

from sb3_saeir.common.vec_env import MultiAgentVecMonitor, make_multiagent_vec_env
from sb3_saeir.config import ALGOS, build_model, config_path, load_hyperparams
from sb3_saeir.envs import get_task_spec, list_tasks
from sb3_saeir.evaluation import MultiAgentEvalCallback

# Keys a config entry may hold besides the algorithm's constructor arguments.
CONFIG_KEYS = ("n_timesteps", "n_envs", "env_kwargs", "policy", "policy_kwargs", "callback")


class ConfigError(ValueError):
    """A bad command line or config: the message names the problem and the valid choices."""


def parse_params(items: list[str] | None) -> dict[str, Any]:
    """``-params key:value key=value ...`` -> dict, values parsed as YAML (numbers, booleans, lists, dicts)."""
    params: dict[str, Any] = {}
    for item in items or []:
        separator = min((i for i in (item.find(":"), item.find("=")) if i > 0), default=-1)
        if separator < 0:
            raise ConfigError(f"-params entry {item!r} is not key:value (or key=value).")
        key, raw = item[:separator], item[separator + 1 :]
        try:
            params[key] = yaml.safe_load(raw)
        except yaml.YAMLError as error:
            raise ConfigError(f"-params {key}: cannot parse {raw!r} ({error}).") from error
    return params


def valid_keys(algo: str) -> list[str]:
    """Config keys accepted for a method: the special keys plus the algorithm's constructor arguments."""
    excluded = {"policy", "env", "_init_setup_model", "args", "kwargs"}
    return sorted({*CONFIG_KEYS, *(name for name in _constructor_parameters(algo) if name not in excluded)})


def _constructor_parameters(algo: str) -> dict[str, inspect.Parameter]:
    """Constructor parameters of a method's algorithm class (every class spells out its full signature)."""
    return dict(inspect.signature(ALGOS[algo]).parameters)


def _type_ok(value: Any, reference: Any) -> bool:
    if reference is None or value is None:
        return True
    if isinstance(reference, bool):
        return isinstance(value, bool)
    if isinstance(reference, (int, float)):
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if isinstance(reference, str):
        return isinstance(value, str)
    if isinstance(reference, (list, tuple)):
        return isinstance(value, (list, tuple))
    if isinstance(reference, dict):
        return isinstance(value, dict)
    return True


def _matches(value: Any, annotation: Any) -> bool:
    """Whether a YAML value fits a constructor annotation (int accepted for float; unknown annotations accept)."""
    if isinstance(annotation, str):  # postponed annotations, e.g. "float | None"
        options = [option.strip() for option in annotation.split("|")]
    elif isinstance(annotation, (type, types.UnionType)):
        members = typing.get_args(annotation) if isinstance(annotation, types.UnionType) else (annotation,)
        options = ["None" if member is type(None) else getattr(member, "__name__", "?") for member in members]
    else:
        return True
    checks = {"float": (int, float), "int": (int,), "bool": (bool,), "str": (str,), "None": (type(None),)}
    if any(option not in checks for option in options):
        return True  # Schedules, classes, dicts...: left to the algorithm
    if isinstance(value, bool) and "bool" not in options:
        return False
    return any(isinstance(value, checks[option]) for option in options)


def _annotations(algo: str) -> dict[str, Any]:
    """Constructor annotations of a method's algorithm class."""
    return {
        name: parameter.annotation
        for name, parameter in _constructor_parameters(algo).items()
        if parameter.annotation is not inspect.Parameter.empty
    }


def check_hyperparams(algo: str, hyperparams: dict[str, Any], overrides: dict[str, Any]) -> None:
    """Unknown keys and values of the wrong type raise a :class:`ConfigError` naming the valid choices."""
    keys = valid_keys(algo)
    for key in [*hyperparams, *overrides]:
        if key not in keys:
            raise ConfigError(f"unknown config key {key!r} for {algo}; valid keys: {', '.join(keys)}.")
    annotations = _annotations(algo)
    for key, value in overrides.items():
        reference = hyperparams.get(key)
        if reference is not None and not _type_ok(value, reference):
            expected = f"{type(reference).__name__} (like the configured {reference!r})"
        elif reference is None and not _matches(value, annotations.get(key)):
            expected = str(annotations[key])
        else:
            continue
        raise ConfigError(f"hyperparameter {key}={value!r} has type {type(value).__name__}, expected {expected}.")
    if "n_envs" in overrides and (not isinstance(overrides["n_envs"], int) or overrides["n_envs"] < 1):
        raise ConfigError(f"n_envs (number of games) must be a positive integer, got {overrides['n_envs']!r}.")


def next_run_folder(log_folder: str, algo: str, task: str) -> Path:
    """``<log_folder>/<algo>/<task>_<run>`` with the first unused run number (rl-zoo's numbering)."""
    algo_folder = Path(log_folder) / algo
    runs = [int(p.name.rsplit("_", 1)[1]) for p in algo_folder.glob(f"{task}_*") if p.name.rsplit("_", 1)[1].isdigit()]
    return algo_folder / f"{task}_{max(runs, default=0) + 1}"


def resolve_hyperparams(args: argparse.Namespace) -> dict[str, Any]:
    """The config entry (packaged or ``-conf``) with ``-params`` and ``--n-games`` / ``--n-timesteps`` applied."""
    if args.algo not in ALGOS:
        raise ConfigError(f"unknown algorithm {args.algo!r}; valid choices: {', '.join(sorted(ALGOS))}.")
    if args.task not in list_tasks():
        raise ConfigError(f"unknown task {args.task!r}; valid choices: {', '.join(list_tasks())}.")
    conf_file = args.conf_file or config_path(args.algo)
    if not Path(conf_file).is_file():
        raise ConfigError(f"config file {conf_file} does not exist.")
    try:
        hyperparams = load_hyperparams(args.algo, args.task, conf_file)
    except KeyError as error:
        raise ConfigError(str(error.args[0])) from error
    overrides = parse_params(args.params)
    if args.n_games is not None:
        overrides["n_envs"] = args.n_games
    if args.n_timesteps is not None:
        overrides["n_timesteps"] = args.n_timesteps
    check_hyperparams(args.algo, hyperparams, overrides)
    return {**hyperparams, **overrides}


def build_callbacks(args: argparse.Namespace, save_path: Path, n_games: int, env_kwargs: dict[str, Any]) -> list[BaseCallback]:
    """Checkpoints every ``--save-freq`` and evaluation every ``--eval-freq`` agent-steps."""
    callbacks: list[BaseCallback] = []
    if args.save_freq > 0:
        callbacks.append(CheckpointCallback(save_freq=1, save_path=str(save_path), name_prefix="rl_model", verbose=0))
        callbacks[-1] = _every_agent_steps(callbacks[-1], args.save_freq)
    if args.eval_freq > 0:
        eval_games = max(1, min(args.eval_episodes, 10))
        eval_env = make_multiagent_vec_env(args.task, n_games=eval_games, seed=args.seed + 10_000, **env_kwargs)
        callbacks.append(
            MultiAgentEvalCallback(
                eval_env,
                n_eval_episodes=args.eval_episodes,
                eval_freq=args.eval_freq,
                main_metric=get_task_spec(args.task).main_metric,
                log_path=str(save_path),
                best_model_save_path=str(save_path),
                verbose=args.verbose,
            )
        )
    return callbacks


class _EveryAgentSteps(BaseCallback):
    """Run a callback every ``frequency`` agent-steps (SB3's frequencies count vec steps of n_envs slots)."""

    def __init__(self, callback: BaseCallback, frequency: int) -> None:
        super().__init__()
        self.callback = callback
        self.frequency = frequency
        self.last = 0

    def _init_callback(self) -> None:
        self.callback.init_callback(self.model)
        self.last = self.num_timesteps

    def _on_step(self) -> bool:
        if self.num_timesteps - self.last >= self.frequency:
            self.last = self.num_timesteps
            self.callback.update_locals(self.locals)
            return self.callback.on_step()
        return True


def _every_agent_steps(callback: BaseCallback, frequency: int) -> BaseCallback:
    return _EveryAgentSteps(callback, frequency)


def train(args: argparse.Namespace) -> Path:
    """Train one run; returns its folder."""
    hyperparams = resolve_hyperparams(args)
    th.set_num_threads(args.num_threads)
    if args.seed < 0:
        args.seed = int(np.random.randint(2**31 - 1))
    set_random_seed(args.seed)
    save_path = next_run_folder(args.log_folder, args.algo, args.task)
    params_path = save_path / args.task
    params_path.mkdir(parents=True, exist_ok=False)
    n_games = int(hyperparams.get("n_envs", 8))
    env_kwargs = dict(hyperparams.get("env_kwargs") or {})
    env = MultiAgentVecMonitor(
        make_multiagent_vec_env(args.task, n_games=n_games, seed=args.seed, **env_kwargs),
        str(save_path / "games"),
        env_id=args.task,
    )
    extra = dict(verbose=args.verbose, device=args.device, tensorboard_log=args.tensorboard_log)
    if args.trained_agent:
        if not Path(args.trained_agent).is_file():
            raise ConfigError(f"--trained-agent {args.trained_agent} is not a file.")
        model = ALGOS[args.algo].load(args.trained_agent, env=env, device=args.device, tensorboard_log=args.tensorboard_log)
        config_callbacks: list[BaseCallback] = []
        reset_num_timesteps = False
    else:
        model, _, config_callbacks, resolved = build_model(args.algo, args.task, hyperparams, env=env, seed=args.seed, **extra)
        hyperparams = resolved
        reset_num_timesteps = True
    saved = {
        key: (str(value) if not isinstance(value, (int, float, str, bool, list, dict, type(None))) else value)
        for key, value in sorted(hyperparams.items())
    }
    (params_path / "config.yml").write_text(yaml.safe_dump(saved, sort_keys=True))
    (params_path / "args.yml").write_text(yaml.safe_dump({k: v for k, v in sorted(vars(args).items())}))
    callbacks = [*config_callbacks, *build_callbacks(args, save_path, n_games, env_kwargs)]
    n_timesteps = int(hyperparams.get("n_timesteps", 1e6))
    print(f"Training {args.algo} on {args.task}: {n_games} games x {env.n_agents} agents, {n_timesteps} agent-steps")
    print(f"Log folder: {save_path}")
    start = time.time()
    try:
        model.learn(n_timesteps, callback=callbacks, progress_bar=args.progress, reset_num_timesteps=reset_num_timesteps)
    except KeyboardInterrupt:
        print("Interrupted: saving the model.")
    model.save(save_path / f"{args.task}.zip")
    env.close()
    print(f"Saved {save_path / (args.task + '.zip')} after {time.time() - start:.0f} s")
    return save_path


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m sb3_saeir.train", description="Train a method from its rl-zoo style YAML config."
    )
    parser.add_argument("--algo", required=True, help=f"method: {', '.join(sorted(ALGOS))}")
    parser.add_argument("--task", "--env", dest="task", default="cn-sparse-n3", help=f"task id: {', '.join(list_tasks())}")
    parser.add_argument("--seed", type=int, default=0, help="random seed (-1: draw one)")
    parser.add_argument("-conf", "--conf-file", default=None, help="zoo-format YAML (default: zoo_configs/<algo>.yml)")
    parser.add_argument("-n", "--n-timesteps", type=int, default=None, help="override n_timesteps (agent-steps)")
    parser.add_argument("--n-games", type=int, default=None, help="override n_envs (number of games)")
    parser.add_argument("--eval-freq", type=int, default=25_000, help="evaluate every this many agent-steps (0: never)")
    parser.add_argument("--eval-episodes", type=int, default=20, help="game episodes per evaluation")
    parser.add_argument("--save-freq", type=int, default=-1, help="checkpoint every this many agent-steps (-1: never)")
    parser.add_argument("-f", "--log-folder", default="logs", help="log folder")
    parser.add_argument("-tb", "--tensorboard-log", default=None, help="tensorboard log folder")
    parser.add_argument("--device", default="cpu", help="torch device")
    parser.add_argument("--num-threads", type=int, default=1, help="torch threads (1 is fastest on small machines)")
    parser.add_argument("--progress", action="store_true", help="show a progress bar")
    parser.add_argument("-params", "--hyperparams", dest="params", nargs="+", default=None, help="overrides key:value")
    parser.add_argument("-i", "--trained-agent", default="", help="continue training this saved model")
    parser.add_argument("--verbose", type=int, default=1)
    parser.add_argument("-optimize", "--optimize-hyperparameters", "--optimize", dest="optimize", action="store_true")
    parser.add_argument("--n-trials", type=int, default=10, help="Optuna trials (this worker)")
    parser.add_argument("--n-jobs", type=int, default=1, help="parallel trials in this process")
    parser.add_argument("--sampler", choices=["random", "tpe"], default="tpe")
    parser.add_argument("--pruner", choices=["median", "none"], default="median")
    parser.add_argument("--n-evaluations", type=int, default=2, help="evaluations per trial (for pruning)")
    parser.add_argument("--storage", default=None, help="Optuna storage URL (default: SQLite file in the log folder)")
    parser.add_argument("--study-name", default=None, help="Optuna study name (default: <algo>_<task>)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = make_parser().parse_args(argv)
    try:
        if args.optimize:
            from sb3_saeir.hyperparams_opt import optimize

            optimize(args, resolve_hyperparams(args))
        else:
            train(args)
    except (ConfigError, FileExistsError) as error:
        print(f"sb3_saeir.train: error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
