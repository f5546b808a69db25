"""rl-zoo style training from YAML configs: ``python -m sb3_saeir.train --algo saeir_ppo --task cn-sparse-n3``.

A run goes into rl-zoo's folders, ``<log-folder>/<algo>/<task>_<run>/`` (a new run number each time, the folder
claimed: :class:`~sb3_saeir.run.folder.RunFolder`), and is a :class:`~sb3_saeir.run.run.Run`
(:meth:`~sb3_saeir.run.run.Run.execute`): this module builds what differs, the settings of the command, the
experiment and its model (or the ``-i`` model loaded). The files of a
run folder: ``docs/guide/training.md``, "The run folder"; ``--resume``, Ctrl-C, a full disk and training a run longer:
its "Stopping and resuming a run". ``--optimize`` tunes hyperparameters with Optuna (``sb3_saeir.hyperparams_opt``).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecEnv

from sb3_saeir.command_line import (
    DOUBLE_BUFFERED_FLAGS,
    DRAW_SEED,
    OneLineParser,
    budget,
    check_arguments,
    count,
    one_line_warnings,
    resolve_hyperparams,
    resume_target,
)
from sb3_saeir.common.callbacks import BudgetEstimate
from sb3_saeir.common.extras import MissingExtraError, require_extra
from sb3_saeir.common.stop_signals import (
    INTERRUPTED_EXIT_STATUS,
    ctrl_c_to_the_command,
    exit_after_the_command,
    interrupted_exit_status,
    signal_name,
    stop_signal_number,
    stop_signals_as_ctrl_c,
)
from sb3_saeir.common.utils import set_num_threads
from sb3_saeir.config import ALGOS, ConfigError, model_method_mismatch, parse_params
from sb3_saeir.envs import list_tasks
from sb3_saeir.experiment import Experiment, config_budget
from sb3_saeir.run.folder import RunFolder
from sb3_saeir.run.lock import RunFolderInUseError
from sb3_saeir.run.output import RunOutput
from sb3_saeir.run.record import RunSpec, config_record
from sb3_saeir.run.run import Run, RunStoppedError

__all__ = [
    "INTERRUPTED_EXIT_STATUS",
    "RunInterruptedError",
    "legacy_train_record",
    "main",
    "make_parser",
    "run_spec",
    "train",
]


class RunInterruptedError(KeyboardInterrupt):
    """A run stopped early by Ctrl-C (or SIGTERM, SIGHUP), cleanly: its checkpoint is written and ``--resume``
    continues it. A ``KeyboardInterrupt``, so that a Python caller sees the stop; ``main`` exits with
    :attr:`exit_status`.

    :param folder: the run's folder
    :param signum: the signal that stopped it (``None``: Ctrl-C)
    """

    def __init__(self, folder: Path, signum: int | None = None) -> None:
        how = signal_name(signum) if signum is not None else "Ctrl-C"
        super().__init__(f"the run in {folder} was stopped early by {how}; the same command with --resume continues it")
        self.folder = folder
        self.exit_status = interrupted_exit_status(signum)


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
    """The command's settings a resume must repeat beyond a :class:`~sb3_saeir.run.record.RunSpec`'s own fields, by flag
    (an option the command lacks, as in an older ``args.yml``, counts as its default)."""
    parser = make_parser()
    free = {*RESUME_FREE_OPTIONS, *OPTIMIZE_OPTIONS, *SPEC_OPTIONS}
    options = {action.dest for action in parser._actions if action.dest != "help"} - free
    return {_flag(option): command.get(option, parser.get_default(option)) for option in sorted(options)}


def run_spec(
    args: argparse.Namespace, params: dict[str, Any], seed: int, n_timesteps: int, n_games: int, config: dict[str, Any]
) -> RunSpec:
    """The settings of the run a ``train`` command makes.

    :param args: the command
    :param params: its ``-params`` overrides, parsed
    :param seed: the run's seed (drawn for ``--seed -1``)
    :param n_timesteps: its budget in agent-steps
    :param n_games: its games
    :param config: its resolved hyperparameters (the model's, after building)
    """
    command = vars(args)
    options = compared_options(command)
    return RunSpec(
        args.algo, args.task, seed, n_timesteps, n_games, args.eval_freq, args.eval_episodes, params, config, options,
        {**command, "seed": seed},
    )  # fmt: skip


def legacy_train_record(stored_args: dict[str, Any], stored_config: dict[str, Any]) -> dict[str, Any]:
    """The settings record of a run folder written before ``spec.json`` (its ``<task>/args.yml`` and
    ``<task>/config.yml``), as :func:`~sb3_saeir.run.record.spec_record` writes one."""
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
    built and checked before anything is written in the run folder; a new run's folder is claimed
    (:meth:`~sb3_saeir.run.folder.RunFolder.claim`) and removed again when the command is refused, so a bad command
    leaves nothing behind and runs started together get different numbers. The run itself is a
    :class:`~sb3_saeir.run.run.Run`: a full disk stops it with a :class:`~sb3_saeir.run.run.RunStoppedError` naming
    the checkpoint to resume from.
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
    with claimed_or_found_folder(args) as folder:  # held to the end; a refused new run's removed
        if folder.record is None:
            seed = int(np.random.randint(2**31 - 1)) if args.seed == DRAW_SEED else (args.seed or 0)
        else:
            check_not_a_benchmark_run(folder.path, folder.record)
            seed = folder.resumed_seed(args.seed)
        return _execute(args, hyperparams, folder, seed)


def claimed_or_found_folder(args: argparse.Namespace) -> RunFolder:
    """The command's run folder, held: a new run's claimed, or the one ``--resume`` names found.

    :param args: the command
    """
    if args.resume is None:
        return RunFolder.claim(args.log_folder, args.algo, args.task)
    return RunFolder.find(args.log_folder, args.algo, args.task, args.resume, legacy_train_record)


def check_not_a_benchmark_run(folder: Path, stored: dict[str, Any]) -> None:
    """Refuse ``--resume`` of a benchmark run's folder (``<out>/runs/<algo>/<task>_s<seed>``, whose record has no
    ``train`` options) with the benchmark command that resumes it, instead of a list of ``train``'s defaults that
    differ from its record.

    :param folder: the folder ``--resume`` names
    :param stored: its settings record
    :raises ~sb3_saeir.config.ConfigError: naming the benchmark command
    """
    if "options" in stored or folder.parent.parent.name != "runs" or not folder.name.endswith(f"_s{stored.get('seed')}"):
        return
    command = [
        "python -m sb3_saeir.benchmark", f"--algos {stored.get('algo')}", f"--tasks {stored.get('task')}",
        f"--seeds {stored.get('seed')}", f"-n {stored.get('n_timesteps')}",
    ]  # fmt: skip
    if stored.get("n_games") is not None:
        command.append(f"--n-games {stored['n_games']}")
    command += [f"--eval-freq {stored.get('eval_freq')}", f"--eval-episodes {stored.get('eval_episodes')}"]
    if stored.get("params"):
        command.append("-params " + " ".join(f"'{key}:{value!r}'" for key, value in sorted(stored["params"].items())))
    command.append(f"--out {folder.parent.parent.parent}")
    raise ConfigError(
        f"--resume: {folder} is a run of the benchmark, not of train; the benchmark resumes it with the command that "
        f"made it: {' '.join(command)}"
    )


def _execute(args: argparse.Namespace, hyperparams: dict[str, Any], folder: RunFolder, seed: int) -> Path:
    """:func:`train`'s run in ``folder``: the experiment, the run's settings and how its model is built, then
    :meth:`~sb3_saeir.run.run.Run.execute`."""
    n_timesteps = config_budget(hyperparams)
    params = parse_params(args.params)
    set_random_seed(seed)
    experiment = Experiment(args.algo, args.task, hyperparams, seed=seed)
    run = Run(
        run_spec(args, params, seed, n_timesteps, experiment.n_games, {}),
        save_freq=args.save_freq if args.save_freq > 0 else sys.maxsize,  # never but on Ctrl-C
        continue_model=bool(args.trained_agent),
    )

    def build(experiment: Experiment, env: VecEnv) -> None:
        build_command_model(experiment, env, args, params)
        run.spec = replace(run.spec, config=config_record(experiment.resolved_hyperparams))  # what spec.json records

    output = RunOutput(
        command_line=True,
        verbose=args.verbose,
        progress_bar=args.progress,
        callbacks=[BudgetEstimate(n_timesteps)],
        announce=partial(announce_run, budget_from_config=args.n_timesteps is None),
    )
    model_path = run.execute(
        folder,
        experiment,
        build,
        output=output,
    )
    assert run.clock is not None and run.checkpoints is not None
    print(f"Saved {model_path} after {time.time() - run.clock.start:.0f} s")
    stop_line = run.stop_line()
    if stop_line is not None:
        print(stop_line)
        raise RunInterruptedError(folder.path, run.stop_signal)
    return folder.path


def announce_run(run: Run, experiment: Experiment, budget_from_config: bool = False) -> None:
    """Say what is trained, with which seed, where, and (resuming) from which checkpoint.

    :param run: the run, set up
    :param experiment: its experiment, the model built
    :param budget_from_config: the budget is the config's (no ``-n``)
    """
    assert experiment.env is not None
    spec, n_agents = run.spec, experiment.env.num_envs // experiment.n_games
    print(
        f"Training {spec.algo} on {spec.task}: {experiment.n_games} games x {n_agents} agents, {spec.n_timesteps:,} "
        f"agent-steps, seed {spec.seed}"
    )
    if run.extended_from is not None:
        print(f"Training longer: budget {run.extended_from:,} -> {spec.n_timesteps:,} agent-steps")
    if run.resume is not None:
        remaining = run.target_timesteps - run.start_timesteps
        print(f"Resuming {run.folder} from {run.resume.checkpoint.name}: {remaining:,} agent-steps to go")
    elif budget_from_config:
        print("(n_timesteps from the config; -n sets a shorter budget. The time it takes is printed after the first rollout.)")
    note = budget_note(experiment, run)
    if note:
        print(note)
    print(f"Log folder: {run.folder}")


def budget_note(experiment: Experiment, run: Run) -> str:
    """The note of a budget that is not a whole number of rollouts: training stops at the end of the rollout that
    reaches it, as SB3's ``learn`` does (``""`` when the budget ends a rollout).

    :param experiment: the run's experiment, its model built
    :param run: the run, set up (where it starts and ends)
    """
    assert experiment.model is not None and experiment.env is not None
    n_steps, n_games = int(getattr(experiment.model, "n_steps", 1)), experiment.n_games
    n_agents = experiment.env.num_envs // n_games
    rollout = n_steps * experiment.env.num_envs
    start, target = run.start_timesteps, run.target_timesteps
    end = start + -(-(target - start) // rollout) * rollout  # the first rollout end at or past the target
    if end == target:
        return ""
    return (
        f"Note: the budget is not a whole number of rollouts (a rollout: {n_steps} steps x {n_games} games x {n_agents} "
        f"agents = {rollout:,} agent-steps): the run stops at the end of the rollout that reaches it, after {end:,} "
        "agent-steps."
    )


def build_command_model(experiment: Experiment, env: VecEnv, args: argparse.Namespace, params: dict[str, Any]) -> None:
    """Build the model of the command on the run's training env, or load ``--trained-agent`` onto it (resumed too:
    the record then names the same network; the checkpoint's model replaces it).

    :param experiment: the run's experiment
    :param env: the run's training env (:meth:`~sb3_saeir.run.run.Run.make_env`)
    :param args: the command
    :param params: its ``-params`` overrides, parsed
    """
    if args.trained_agent:
        experiment.load(
            args.trained_agent,
            env=env,
            device=args.device,
            tensorboard_log=args.tensorboard_log,
            verbose=args.verbose,
            requested_policy_kwargs=params.get("policy_kwargs"),
        )
    else:
        experiment.build(env=env, verbose=args.verbose, device=args.device, tensorboard_log=args.tensorboard_log)


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
        type=count,  # 1e3 as -n takes it
        default=None,
        help=f"random seed, 0 .. 2**32 - 1 ({DRAW_SEED}: draw one); default 0, at --resume the run's own",
    )
    parser.add_argument("-conf", "--conf-file", default=None, help="zoo-format YAML (default: zoo_configs/<algo>.yml)")
    parser.add_argument("-n", "--n-timesteps", type=budget, default=None, help="override n_timesteps (agent-steps)")
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
    ctrl_c_to_the_command()
    args = make_parser().parse_args(argv)
    try:
        with one_line_warnings("sb3_saeir.train"), stop_signals_as_ctrl_c():
            return _main(args)
    except (ConfigError, FileExistsError, MissingExtraError, RunFolderInUseError) as error:
        print(f"sb3_saeir.train: error: {error}", file=sys.stderr)
        return 2
    except RunStoppedError as error:
        print(f"sb3_saeir.train: error: {error}", file=sys.stderr)
        return 1
    except RunInterruptedError as stop:
        return stop.exit_status
    except KeyboardInterrupt as stop:  # before the run started (a run's own stop is a RunInterruptedError)
        signum = stop_signal_number(stop)
        done = "stopped" if args.optimize else "stopped before the run started: nothing was written"
        print(f"sb3_saeir.train: {signal_name(signum)}: {done}", file=sys.stderr)
        return interrupted_exit_status(signum)


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
    exit_after_the_command(main())
