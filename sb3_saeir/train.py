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
import sys
import time
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback
from stable_baselines3.common.utils import set_random_seed

from sb3_saeir.common.callbacks import BudgetEstimate, EveryAgentSteps
from sb3_saeir.common.extras import MissingExtraError, require_extra
from sb3_saeir.common.utils import set_num_threads
from sb3_saeir.common.vec_env import MultiAgentVecMonitor
from sb3_saeir.config import (
    ALGOS,
    CONFIG_KEYS,
    ConfigError,
    OneLineParser,
    check_device,
    check_folder,
    check_hyperparams,
    check_range,
    config_path,
    count,
    load_hyperparams,
    parse_params,
    valid_keys,
)
from sb3_saeir.envs import list_tasks
from sb3_saeir.experiment import Experiment, model_method_mismatch, next_run_folder

__all__ = [
    "CONFIG_KEYS",
    "BudgetEstimate",
    "ConfigError",
    "check_arguments",
    "check_hyperparams",
    "main",
    "make_parser",
    "parse_params",
    "train",
    "valid_keys",
]


def check_arguments(args: argparse.Namespace) -> None:
    """The command-line options that no config check sees: sizes, paths, device (a
    :class:`~sb3_saeir.config.ConfigError` naming the first bad one), checked before anything is built or written."""
    check_range("--eval-freq", args.eval_freq, 0, " (0: never)")
    check_range("--eval-episodes", args.eval_episodes, 1)
    check_range("--save-freq", args.save_freq, -1, " (-1 or 0: never)")
    check_range("--num-threads", args.num_threads, 0, " (0: the free cores)")
    check_folder("-f/--log-folder", args.log_folder)
    check_folder("-tb/--tensorboard-log", args.tensorboard_log)
    check_device(args.device)
    if args.optimize:
        check_range("--n-trials", args.n_trials, 1)
        check_range("--n-evaluations", args.n_evaluations, 1)
        if args.n_jobs != -1:
            check_range("--n-jobs", args.n_jobs, 1, " (or -1: one per CPU)")
        if args.storage is not None:
            check_storage(args.storage)


def check_storage(storage: str) -> None:
    """Refuse an Optuna storage URL whose database kind SQLAlchemy does not know (without connecting to it)."""
    import sqlalchemy.exc
    from sqlalchemy.engine import make_url

    try:
        make_url(storage).get_dialect()
    except (sqlalchemy.exc.ArgumentError, ValueError) as error:
        raise ConfigError(
            f"--storage {storage!r} is not a database URL SQLAlchemy knows ({error}); e.g. sqlite:///study.db or "
            "postgresql://user:password@host/db."
        ) from None


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
    if args.num_cpus is not None:
        overrides["num_cpus"] = args.num_cpus
    check_hyperparams(args.algo, hyperparams, overrides)
    resolved = {**hyperparams, **overrides}
    check_folder("tensorboard_log", resolved.get("tensorboard_log"))
    return resolved


def run_callbacks(args: argparse.Namespace, experiment: Experiment) -> list[BaseCallback]:
    """Checkpoints every ``--save-freq`` and evaluation every ``--eval-freq`` agent-steps."""
    callbacks: list[BaseCallback] = []
    assert experiment.log_folder is not None
    if args.save_freq > 0:
        checkpoint = CheckpointCallback(save_freq=1, save_path=str(experiment.log_folder), name_prefix="rl_model", verbose=0)
        callbacks.append(EveryAgentSteps(checkpoint, args.save_freq))
    if args.eval_freq > 0:
        callbacks.append(experiment.eval_callback(args.eval_freq, args.eval_episodes, verbose=args.verbose))
    return callbacks


def save_run_config(params_path: Path, hyperparams: dict[str, Any], args: argparse.Namespace) -> None:
    """``<task>/config.yml`` (resolved hyperparameters) and ``<task>/args.yml`` (the command line), as rl-zoo."""
    saved = {
        key: (str(value) if not isinstance(value, (int, float, str, bool, list, dict, type(None))) else value)
        for key, value in sorted(hyperparams.items())
    }
    (params_path / "config.yml").write_text(yaml.safe_dump(saved, sort_keys=True))
    (params_path / "args.yml").write_text(yaml.safe_dump({k: v for k, v in sorted(vars(args).items())}))


def train(args: argparse.Namespace) -> Path:
    """Train one run; returns its folder.

    Everything that can fail on a bad setting (config, env, model, saved model) is built before the run folder is
    created, so a bad command leaves no empty run behind.
    """
    check_arguments(args)
    hyperparams = resolve_hyperparams(args)
    if args.trained_agent:
        if not Path(args.trained_agent).is_file():
            raise ConfigError(f"--trained-agent {args.trained_agent} is not a file.")
        mismatch = model_method_mismatch(args.trained_agent, args.algo, args.task, hyperparams)
        if mismatch:
            raise ConfigError(f"--trained-agent {mismatch}")
    set_num_threads(args.num_threads)
    seed = int(np.random.randint(2**31 - 1)) if args.seed < 0 else args.seed
    set_random_seed(seed)
    save_path = next_run_folder(args.log_folder, args.algo, args.task)
    experiment = Experiment(args.algo, args.task, hyperparams, seed=seed, log_folder=save_path)
    build_experiment(experiment, args)
    try:
        callbacks = [*run_callbacks(args, experiment), BudgetEstimate(experiment.n_timesteps)]
    except (ValueError, TypeError) as error:
        experiment.close()
        raise ConfigError(f"cannot set up evaluation or checkpoints: {error}") from error
    params_path = save_path / args.task
    params_path.mkdir(parents=True, exist_ok=False)
    assert experiment.model is not None and experiment.env is not None
    experiment.model.set_env(MultiAgentVecMonitor(experiment.env, str(save_path / "games"), env_id=args.task))
    save_run_config(params_path, experiment.resolved_hyperparams, argparse.Namespace(**{**vars(args), "seed": seed}))
    n_timesteps = experiment.n_timesteps
    n_agents = experiment.env.num_envs // experiment.n_games
    print(f"Training {args.algo} on {args.task}: {experiment.n_games} games x {n_agents} agents, {n_timesteps:,} agent-steps")
    if args.n_timesteps is None:
        print("(n_timesteps from the config; -n sets a shorter budget. The time it takes is printed after the first rollout.)")
    print(f"Log folder: {save_path}")
    start = time.time()
    try:
        experiment.learn(
            n_timesteps, callbacks=callbacks, progress_bar=args.progress, reset_num_timesteps=not args.trained_agent
        )
    except KeyboardInterrupt:
        print("Interrupted: saving the model.")
    model_path = experiment.save(save_path / f"{args.task}.zip")
    experiment.close()
    print(f"Saved {model_path} after {time.time() - start:.0f} s")
    return save_path


def build_experiment(experiment: Experiment, args: argparse.Namespace) -> None:
    """Build the env and the model (or load ``--trained-agent``); a bad setting becomes a
    :class:`~sb3_saeir.config.ConfigError`."""
    try:
        if args.trained_agent:
            experiment.load(args.trained_agent, device=args.device, tensorboard_log=args.tensorboard_log)
        else:
            experiment.build(verbose=args.verbose, device=args.device, tensorboard_log=args.tensorboard_log)
    except (ValueError, TypeError, KeyError, zipfile.BadZipFile) as error:
        experiment.close()
        if isinstance(error, ConfigError):
            raise
        message = error.args[0] if isinstance(error, KeyError) and error.args else str(error)
        raise ConfigError(f"cannot build {args.algo} on {args.task} with these settings: {message}") from error


def make_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="python -m sb3_saeir.train",
        description="Train a method from its rl-zoo style YAML config.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--algo", required=True, help=f"method: {', '.join(sorted(ALGOS))}")
    parser.add_argument("--task", "--env", dest="task", default="cn-sparse-n3", help=f"task id: {', '.join(list_tasks())}")
    parser.add_argument("--seed", type=int, default=0, help="random seed (-1: draw one)")
    parser.add_argument("-conf", "--conf-file", default=None, help="zoo-format YAML (default: zoo_configs/<algo>.yml)")
    parser.add_argument("-n", "--n-timesteps", type=count, default=None, help="override n_timesteps (agent-steps)")
    parser.add_argument("--n-games", type=count, default=None, help="override n_envs (number of games)")
    parser.add_argument("--eval-freq", type=count, default=25_000, help="evaluate every this many agent-steps (0: never)")
    parser.add_argument("--eval-episodes", type=count, default=20, help="game episodes per evaluation")
    parser.add_argument("--save-freq", type=count, default=-1, help="checkpoint every this many agent-steps (-1: never)")
    parser.add_argument("-f", "--log-folder", default="logs", help="log folder")
    parser.add_argument("-tb", "--tensorboard-log", default=None, help="tensorboard log folder")
    parser.add_argument("--device", default="cpu", help="torch device")
    parser.add_argument(
        "--num-threads",
        type=int,
        default=0,
        help="torch threads; 0: the free cores, at most 2 (measured fastest for one job on 2 cores); use 1 when several "
        "jobs share the machine",
    )
    parser.add_argument(
        "--num-cpus", type=int, default=None, help="env worker processes (overrides the config's num_cpus; 0: in this process)"
    )
    parser.add_argument("--progress", action="store_true", help="show a progress bar")
    parser.add_argument("-params", "--hyperparams", dest="params", nargs="+", default=None, help="overrides key:value")
    parser.add_argument("-i", "--trained-agent", default="", help="continue training this saved model")
    parser.add_argument("--verbose", type=int, default=1)
    parser.add_argument("-optimize", "--optimize-hyperparameters", "--optimize", dest="optimize", action="store_true")
    parser.add_argument("--n-trials", type=count, default=10, help="Optuna trials (this worker)")
    parser.add_argument("--n-jobs", type=int, default=1, help="parallel trials in this process")
    parser.add_argument("--sampler", choices=["random", "tpe"], default="tpe")
    parser.add_argument("--pruner", choices=["median", "none"], default="median")
    parser.add_argument("--n-evaluations", type=count, default=2, help="evaluations per trial (for pruning)")
    parser.add_argument("--storage", default=None, help="Optuna storage URL (default: SQLite file in the log folder)")
    parser.add_argument("--study-name", default=None, help="Optuna study name (default: <algo>_<task>)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = make_parser().parse_args(argv)
    try:
        if args.optimize:
            require_extra("optuna", "zoo", "--optimize")
            from sb3_saeir.hyperparams_opt import optimize

            check_arguments(args)
            optimize(args, resolve_hyperparams(args))
        else:
            train(args)
    except (ConfigError, FileExistsError, MissingExtraError) as error:
        print(f"sb3_saeir.train: error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
