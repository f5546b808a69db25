"""rl-zoo style training from YAML configs: ``python -m sb3_saeir.train --algo saeir_ppo --task cn-sparse-n3``.

Runs go into rl-zoo's folders, ``<log-folder>/<algo>/<task>_<run>/``; the inside of a run folder is a
:class:`~sb3_saeir.run.Run`'s (the same as the benchmark's; :mod:`sb3_saeir.run` lists the files): ``spec.json``,
``<task>/config.yml`` and ``<task>/args.yml``, checkpoints ``rl_model_<steps>_steps.zip`` (every ``--save-freq``
agent-steps), ``evaluations.csv``, ``evaluations.npz`` and ``best_model.zip`` (evaluations at the start, every
``--eval-freq`` agent-steps on the grid and at the end), ``progress.csv``, ``games.monitor.csv``, ``segments.json``,
``resume.log``, and ``<task>.zip`` with ``done.json`` when finished; tensorboard events go under
``--tensorboard-log``.

A new run number is used for every run, so nothing already saved is overwritten; the run folder is created
exclusively, so runs started together get different numbers. Every file is replaced atomically
(:mod:`sb3_saeir.common.atomic`). ``--optimize`` tunes hyperparameters with Optuna (``sb3_saeir.hyperparams_opt``).

**Resuming.** The checkpoints are resumable: each holds, besides the model, everything the rest of the run depends
on (:mod:`sb3_saeir.common.run_state`). The same command with ``--resume`` continues the latest run of that algo and
task (``--resume N``: run ``N``; ``--resume FOLDER``: the run in that folder, e.g. one moved elsewhere) from its
newest checkpoint that loads (those that do not are skipped and kept aside, saying so), in its own folder, and ends
as the run would have ended uninterrupted: same parameters, same ``progress.csv`` rows (but the ``time/`` columns),
same evaluations. It refuses a command whose settings differ from the run's (``spec.json``; for a run of an older
version, ``<task>/args.yml`` and ``<task>/config.yml``), naming them. The first Ctrl-C finishes the rollout and
update in progress, writes a checkpoint and stops (a second Ctrl-C stops at once); a killed run resumes from its last
checkpoint; a full disk stops it with one line naming the checkpoint to resume from. ``-i`` keeps its meaning:
continue a saved model with a fresh state (new run, new generators, fresh env). See ``docs/guide/training.md``,
"Stopping and resuming a run".
"""

from __future__ import annotations

import argparse
import inspect
import sys
import time
import zipfile
from contextlib import AbstractContextManager, nullcontext
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.utils import set_random_seed

from sb3_saeir.common.callbacks import BudgetEstimate
from sb3_saeir.common.extras import MissingExtraError, require_extra
from sb3_saeir.common.run_lock import RunFolderInUseError, RunFolderLock
from sb3_saeir.common.utils import set_num_threads
from sb3_saeir.config import (
    ALGOS,
    CONFIG_KEYS,
    DOUBLE_BUFFERED_FLAGS,
    DRAW_SEED,
    ConfigError,
    OneLineParser,
    check_arguments,
    check_hyperparams,
    count,
    one_line_warnings,
    parse_params,
    parse_policy_kwargs,
    resolve_hyperparams,
    resume_target,
    valid_keys,
)
from sb3_saeir.envs import list_tasks
from sb3_saeir.experiment import Experiment, claimed_run_folder, config_budget, find_run_folder, model_method_mismatch
from sb3_saeir.run import Run, RunSpec, RunStoppedError, command_output, config_record, stored_record

__all__ = [
    "CONFIG_KEYS",
    "INTERRUPTED_EXIT_STATUS",
    "BudgetEstimate",
    "ConfigError",
    "RunInterruptedError",
    "RunStoppedError",
    "check_arguments",
    "check_hyperparams",
    "main",
    "make_parser",
    "parse_params",
    "run_spec",
    "train",
    "valid_keys",
]


# The exit status of a run stopped early by Ctrl-C (as shells give a command ended by SIGINT: 128 + 2).
INTERRUPTED_EXIT_STATUS = 130


class RunInterruptedError(KeyboardInterrupt):
    """A run stopped early by Ctrl-C, cleanly: its checkpoint is written and ``--resume`` continues it. A
    ``KeyboardInterrupt``, so that a Python caller sees the Ctrl-C; ``main`` exits with
    :data:`INTERRUPTED_EXIT_STATUS`.

    :param folder: the run's folder
    """

    def __init__(self, folder: Path) -> None:
        super().__init__(f"the run in {folder} was stopped early by Ctrl-C; the same command with --resume continues it")
        self.folder = folder


# Command-line options that may change between a run and its --resume: they do not change what is trained.
RESUME_FREE_OPTIONS = ("resume", "progress", "verbose", "compile")
# Options of --optimize only, not part of a training run.
OPTIMIZE_OPTIONS = ("optimize", "n_trials", "n_jobs", "sampler", "pruner", "n_evaluations", "storage", "study_name")
# Flags of the options whose flag is not "--" + the name with dashes.
OPTION_FLAGS = {"conf_file": "-conf", "params": "-params", "trained_agent": "-i", "log_folder": "-f", "tensorboard_log": "-tb"}


# Options of the command that a RunSpec holds as its own fields (the others go into its options, by flag).
SPEC_OPTIONS = ("algo", "task", "seed", "n_timesteps", "n_games", "eval_freq", "eval_episodes", "params")


def _flag(option: str) -> str:
    return OPTION_FLAGS.get(option, "--" + option.replace("_", "-"))


def compared_options(command: dict[str, Any]) -> dict[str, Any]:
    """The command's settings a resume must repeat beyond a :class:`~sb3_saeir.run.RunSpec`'s own fields, by flag
    (an option the command lacks, as in an older ``args.yml``, counts as its default)."""
    parser = make_parser()
    free = {*RESUME_FREE_OPTIONS, *OPTIMIZE_OPTIONS, *SPEC_OPTIONS}
    options = {action.dest for action in parser._actions if action.dest != "help"} - free
    return {_flag(option): command.get(option, parser.get_default(option)) for option in sorted(options)}


def run_spec(args: argparse.Namespace, seed: int, n_timesteps: int, n_games: int, config: dict[str, Any]) -> RunSpec:
    """The settings of the run a ``train`` command makes.

    :param args: the command
    :param seed: the run's seed (drawn for ``--seed -1``)
    :param n_timesteps: its budget in agent-steps
    :param n_games: its games
    :param config: its resolved hyperparameters (the model's, after building)
    """
    params = parse_params(args.params)
    options = compared_options(vars(args))
    return RunSpec(
        args.algo, args.task, seed, n_timesteps, n_games, args.eval_freq, args.eval_episodes, params, config, options
    )


def legacy_train_record(stored_args: dict[str, Any], stored_config: dict[str, Any]) -> dict[str, Any]:
    """The settings record of a run folder written before ``spec.json`` (its ``<task>/args.yml`` and
    ``<task>/config.yml``), as :func:`~sb3_saeir.run.spec_record` writes one."""
    budget = stored_config.get("n_timesteps", stored_args.get("n_timesteps"))
    return {
        "algo": stored_args.get("algo"),
        "task": stored_args.get("task"),
        "seed": stored_args.get("seed"),
        "n_timesteps": int(budget) if budget is not None else None,
        "n_games": stored_config.get("n_envs"),
        "eval_freq": stored_args.get("eval_freq"),
        "eval_episodes": stored_args.get("eval_episodes"),
        "params": parse_params(stored_args.get("params")),
        "config": stored_config,
        "options": compared_options(stored_args),
    }


def train(args: argparse.Namespace) -> Path:
    """Train one run (or, with ``--resume``, continue one from its newest checkpoint that loads); returns its folder.

    Everything that can fail on a bad setting (config, env, model, saved model, the settings of the run resumed) is
    built and checked before anything is written in the run folder; a new run's folder is claimed exclusively
    (:func:`~sb3_saeir.experiment.claimed_run_folder`) and removed again when the command is refused, so a bad command
    leaves nothing behind and runs started together get different numbers. The run itself is a
    :class:`~sb3_saeir.run.Run`: a full disk stops it with a :class:`~sb3_saeir.run.RunStoppedError` naming the
    checkpoint to resume from.
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
    n_timesteps = config_budget(hyperparams)
    folder: AbstractContextManager[Path]
    stored: dict[str, Any] | None = None
    locks: list[RunFolderLock] = []
    try:
        if args.resume is not None:
            run_folder = find_run_folder(args.log_folder, args.algo, args.task, args.resume)
            locks.append(RunFolderLock(run_folder).acquire())  # before anything is read for the run or written
            stored = stored_record(run_folder, args.algo, args.task, legacy_train_record)
            seed, folder = resumed_seed(args.seed, stored, run_folder), nullcontext(run_folder)
        else:
            seed = int(np.random.randint(2**31 - 1)) if args.seed == DRAW_SEED else (args.seed or 0)
            folder = claimed_run_folder(args.log_folder, args.algo, args.task)
        return _train_in(folder, args, hyperparams, seed, n_timesteps, stored, locks)
    finally:
        for held in locks:
            held.release()


def resumed_seed(seed: int | None, stored: dict[str, Any], folder: Path) -> int:
    """The seed of a resumed run: its record's; the command's ``--seed`` must be that seed, or left out (``None``), or
    -1.

    :param seed: the command's ``--seed`` (``None``: not given)
    :param stored: the run's settings record
    :param folder: the run's folder
    :raises ~sb3_saeir.config.ConfigError: when the command gives another seed
    """
    stored_seed = int(stored["seed"])
    if seed is not None and seed not in (stored_seed, DRAW_SEED):
        raise ConfigError(
            f"--resume: {folder} was made with --seed {stored_seed}, not --seed {seed}: a run goes on with its own seed. "
            f"Give --seed {stored_seed} (or no --seed), or start a new run without --resume."
        )
    return stored_seed


def _train_in(
    folder: AbstractContextManager[Path],
    args: argparse.Namespace,
    hyperparams: dict[str, Any],
    seed: int,
    n_timesteps: int,
    stored: dict[str, Any] | None,
    locks: list[RunFolderLock],
) -> Path:
    """:func:`train` in the run's folder: the one resumed, whose lock is in ``locks``, or a new one claimed, whose lock
    is taken here and added to ``locks`` (and removed with the folder when the set-up fails)."""
    with folder as save_path:  # a new run's folder is removed again if the set-up fails
        if not locks:
            locks.append(RunFolderLock(save_path).acquire())
        try:
            experiment, run = _set_up(save_path, args, hyperparams, seed, n_timesteps, stored)
        except BaseException:
            if stored is None:  # the new run's folder goes
                locks.pop().release()
            raise
    announce_run(args, experiment, run, n_timesteps, seed)
    return _run(experiment, run, args, n_timesteps, save_path)


def _set_up(
    save_path: Path,
    args: argparse.Namespace,
    hyperparams: dict[str, Any],
    seed: int,
    n_timesteps: int,
    stored: dict[str, Any] | None,
) -> tuple[Experiment, Run]:
    """The run's experiment, built (or its model loaded), and the run, checked against its record when resumed."""
    set_random_seed(seed)
    experiment = Experiment(args.algo, args.task, hyperparams, seed=seed, log_folder=save_path)
    run = Run(
        save_path,
        run_spec(args, seed, n_timesteps, experiment.n_games, {}),
        save_freq=args.save_freq if args.save_freq > 0 else sys.maxsize,  # never but on Ctrl-C
        command={**vars(args), "seed": seed},
        continue_model=bool(args.trained_agent),
    )
    if stored is not None:
        run.check_resumable(stored)
    build_experiment(experiment, args, run)
    run.spec = replace(run.spec, config=config_record(experiment.resolved_hyperparams))
    if stored is not None:
        try:
            run.check_settings(stored, by_path=isinstance(args.resume, Path))
        except ConfigError:
            experiment.close()
            raise
    return experiment, run


def _run(experiment: Experiment, run: Run, args: argparse.Namespace, n_timesteps: int, save_path: Path) -> Path:
    """Train the run set up by :func:`_set_up`; returns its folder."""
    try:
        run.write_spec()
        start = time.time()
        continued = run.resume is not None or bool(args.trained_agent)
        assert experiment.model is not None
        output = command_output(experiment.model, args.verbose, args.progress, continued, [BudgetEstimate(n_timesteps)])
        run.start(experiment, output)
        model_path = run.train()
        print(f"Saved {model_path} after {time.time() - start:.0f} s")
        if run.checkpoints is not None and run.checkpoints.stopped_at is not None:
            print(f"Stopped at the checkpoint {run.checkpoints.stopped_at}: the same command with --resume continues it.")
            raise RunInterruptedError(save_path)
    finally:
        experiment.close()
    return save_path


def announce_run(args: argparse.Namespace, experiment: Experiment, run: Run, n_timesteps: int, seed: int) -> None:
    """Say what is trained, with which seed, where, and (resuming) from which checkpoint."""
    assert experiment.env is not None
    n_agents = experiment.env.num_envs // experiment.n_games
    print(
        f"Training {args.algo} on {args.task}: {experiment.n_games} games x {n_agents} agents, {n_timesteps:,} "
        f"agent-steps, seed {seed}"
    )
    if run.extended_from is not None:
        print(f"Training longer: budget {run.extended_from:,} -> {n_timesteps:,} agent-steps")
    if run.resume is not None:
        remaining = run.resume.total_timesteps(n_timesteps) - run.resume.steps
        print(f"Resuming {run.folder} from {run.resume.checkpoint.name}: {remaining:,} agent-steps to go")
    elif args.n_timesteps is None:
        print("(n_timesteps from the config; -n sets a shorter budget. The time it takes is printed after the first rollout.)")
    print(f"Log folder: {run.folder}")


def build_experiment(experiment: Experiment, args: argparse.Namespace, run: Run) -> None:
    """Build the run's training env (:meth:`~sb3_saeir.run.Run.make_env`) and the model on it (or load
    ``--trained-agent`` onto it); a bad setting becomes a :class:`~sb3_saeir.config.ConfigError`.

    :param experiment: the run's experiment
    :param args: the command
    :param run: the run
    """
    # -tb, else the config's tensorboard_log (passing None would switch the config's off)
    tensorboard_log = args.tensorboard_log
    if tensorboard_log is None:
        tensorboard_log = experiment.hyperparams.get("tensorboard_log")
    try:
        env = run.make_env(experiment)
        if args.trained_agent and args.resume is None:
            experiment.load(args.trained_agent, env=env, device=args.device, tensorboard_log=tensorboard_log)
            record_loaded_network(experiment, args.trained_agent, parse_params(args.params))
        else:
            experiment.build(env=env, verbose=args.verbose, device=args.device, tensorboard_log=tensorboard_log)
    except (ValueError, TypeError, KeyError, zipfile.BadZipFile, ConfigError) as error:
        experiment.close()
        if isinstance(error, ConfigError):
            raise
        message = error.args[0] if isinstance(error, KeyError) and error.args else str(error)
        raise ConfigError(f"cannot build {args.algo} on {args.task} with these settings: {message}") from error


def record_loaded_network(experiment: Experiment, path: str, params: dict[str, Any]) -> None:
    """``-i``: the loaded model trains the network it was saved with. Refuse a ``-params policy_kwargs`` that asks for
    another network (SB3's ``load`` would drop it without a word); when the config's ``policy_kwargs`` describe another
    network than the loaded one, the run's record (``spec.json``) gets the loaded network's.

    :param experiment: the experiment, its model loaded
    :param path: the loaded model (``-i``)
    :param params: the command's ``-params``
    :raises ~sb3_saeir.config.ConfigError: naming the settings that cannot apply
    """
    assert experiment.model is not None
    saved = dict(getattr(experiment.model, "policy_kwargs", {}) or {})
    defaults = {
        name: parameter.default
        for name, parameter in inspect.signature(type(experiment.model.policy).__init__).parameters.items()
        if parameter.default is not inspect.Parameter.empty
    }

    def differing(kwargs: dict[str, Any], keys: set[str]) -> list[str]:
        """The keys of ``keys`` whose value (a policy default where not given) differs between ``kwargs`` and the
        loaded network's."""
        return [key for key in sorted(keys) if kwargs.get(key, defaults.get(key)) != saved.get(key, defaults.get(key))]

    requested = parse_policy_kwargs(params["policy_kwargs"]) if "policy_kwargs" in params else {}
    keys = differing(requested, set(requested))
    if keys:
        asked = ", ".join(f"{key}={show_kwarg(requested[key])}" for key in keys)
        has = ", ".join(f"{key}={show_kwarg(saved.get(key, defaults.get(key)))}" for key in keys)
        raise ConfigError(
            f"-i {path}: -params policy_kwargs {asked} cannot apply to the loaded model, whose network has {has}: a "
            "loaded model trains the network it was saved with. Drop the policy_kwargs override, or start a new run "
            "without -i."
        )
    configured = parse_policy_kwargs(experiment.hyperparams.get("policy_kwargs"))
    if differing(configured, set(configured) | set(saved)):
        experiment.resolved_hyperparams["policy_kwargs"] = policy_kwargs_text(saved)


def show_kwarg(value: Any) -> str:
    """A policy keyword's value as a config writes it (``nn.Tanh`` for a torch module class)."""
    if isinstance(value, type) and value.__module__.startswith("torch.nn"):
        return f"nn.{value.__name__}"
    return repr(value)


def policy_kwargs_text(kwargs: dict[str, Any]) -> str:
    """``policy_kwargs`` as a config writes them: ``"dict(activation_fn=nn.Tanh, hidden_size=64)"``."""
    return "dict(" + ", ".join(f"{key}={show_kwarg(value)}" for key, value in sorted(kwargs.items())) + ")"


def make_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="python -m sb3_saeir.train",
        description="Train a method from its rl-zoo style YAML config.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--algo", required=True, help=f"method: {', '.join(sorted(ALGOS))}")
    parser.add_argument("--task", "--env", dest="task", default="cn-sparse-n3", help=f"task id: {', '.join(list_tasks())}")
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        help=f"random seed, 0 .. 2**32 - 1 ({DRAW_SEED}: draw one); default 0, at --resume the run's own",
    )
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
    parser.add_argument(
        "--double-buffered",
        choices=list(DOUBLE_BUFFERED_FLAGS),
        default=None,
        help="double-buffered sampling with env workers (overrides the config's double_buffered; default auto: on when "
        "num_cpus >= 2)",
    )
    parser.add_argument(
        "--compile",
        choices=["on", "off"],
        default=None,
        help="torch.compile of the networks (overrides the config's compile; needs a C++ compiler; pays off on long "
        "runs: docs/guide/performance.md); may change at --resume",
    )
    parser.add_argument("--progress", action="store_true", help="show a progress bar")
    parser.add_argument("-params", "--hyperparams", dest="params", nargs="+", default=None, help="overrides key:value")
    parser.add_argument("-i", "--trained-agent", default="", help="continue training this saved model (fresh state)")
    parser.add_argument(
        "--resume",
        nargs="?",
        type=resume_target,
        const=0,
        default=None,
        metavar="RUN|FOLDER",
        help="continue the latest run of this algo and task (or run RUN, or the run folder FOLDER, e.g. one moved to "
        "another log folder) from its newest checkpoint that loads, exactly; give the command that started it",
    )
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
        with one_line_warnings("sb3_saeir.train"):
            return _main(args)
    except (ConfigError, FileExistsError, MissingExtraError, RunFolderInUseError) as error:
        print(f"sb3_saeir.train: error: {error}", file=sys.stderr)
        return 2
    except RunStoppedError as error:
        print(f"sb3_saeir.train: error: {error}", file=sys.stderr)
        return 1
    except RunInterruptedError:
        return INTERRUPTED_EXIT_STATUS


def _main(args: argparse.Namespace) -> int:
    if args.optimize:
        require_extra("optuna", "zoo", "--optimize")
        from sb3_saeir.hyperparams_opt import optimize

        check_arguments(args)
        args.seed = args.seed or 0
        optimize(args, resolve_hyperparams(args))
    else:
        train(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
