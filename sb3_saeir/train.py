"""rl-zoo style training from YAML configs: ``python -m sb3_saeir.train --algo saeir_ppo --task cn-sparse-n3``.

Writes rl-zoo's folder layout, ``<log-folder>/<algo>/<task>_<run>/``:

- ``<task>.zip`` (final model), ``best_model.zip`` (best evaluation by the task's main metric),
  ``rl_model_<steps>_steps.zip`` (checkpoints), ``evaluations.npz``, ``games.monitor.csv`` (one row per game episode),
- ``<task>/config.yml`` (resolved hyperparameters), ``<task>/args.yml`` (command-line arguments), and tensorboard
  events under ``--tensorboard-log``.

- ``progress.csv`` (SB3's logger: every ``rollout/``, ``train/``, ``eval/`` and ``time/`` row).

A new run number is used for every run, so nothing already saved is overwritten; the run folder is created
exclusively, so runs started together get different numbers. Every file is replaced atomically
(:mod:`sb3_saeir.common.atomic`). ``--optimize`` tunes hyperparameters with Optuna (``sb3_saeir.hyperparams_opt``).

**Resuming.** The checkpoints of ``--save-freq`` are resumable: each holds, besides the model, everything the rest of
the run depends on (:mod:`sb3_saeir.common.run_state`). The same command with ``--resume`` continues the latest run
of that algo and task (``--resume N``: run ``N``; ``--resume FOLDER``: the run in that folder, e.g. one moved
elsewhere) from its newest checkpoint that loads (those that do not are skipped, saying so), in its own folder, and
ends as the run would have ended uninterrupted: same parameters, same ``progress.csv`` rows (but the ``time/``
columns), same evaluations. It refuses a command whose settings differ from the run's (``<task>/args.yml``,
``<task>/config.yml``), naming them. The first Ctrl-C finishes the rollout and update in progress, writes a
checkpoint and stops (a second Ctrl-C stops at once); a killed run resumes from its last ``--save-freq`` checkpoint;
a full disk stops it with one line naming the checkpoint to resume from. ``-i`` keeps its meaning: continue a saved
model with a fresh state (new run, new generators, fresh env). See ``docs/guide/training.md``, "Stopping and
resuming a run".
"""

from __future__ import annotations

import argparse
import errno
import inspect
import json
import signal
import sys
import threading
import time
import zipfile
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.utils import configure_logger, set_random_seed

from sb3_saeir.common.atomic import atomic_write_text
from sb3_saeir.common.callbacks import BudgetEstimate
from sb3_saeir.common.extras import MissingExtraError, require_extra
from sb3_saeir.common.run_state import (
    RunCheckpointCallback,
    checkpoint_problem,
    describe_resume,
    load_resume_state,
    progress_logger,
)
from sb3_saeir.common.utils import set_num_threads
from sb3_saeir.common.vec_env import MultiAgentVecMonitor
from sb3_saeir.config import (
    ALGOS,
    CONFIG_KEYS,
    DRAW_SEED,
    ConfigError,
    OneLineParser,
    check_device,
    check_folder,
    check_hyperparams,
    check_range,
    check_seed_option,
    config_path,
    count,
    load_hyperparams,
    one_line_warnings,
    parse_params,
    valid_keys,
)
from sb3_saeir.envs import list_tasks
from sb3_saeir.experiment import (
    CHECKPOINT_NAME,
    Experiment,
    checkpoint_steps,
    claimed_run_folder,
    config_budget,
    model_method_mismatch,
    run_numbers,
)

__all__ = [
    "CONFIG_KEYS",
    "BudgetEstimate",
    "ConfigError",
    "RunStoppedError",
    "check_arguments",
    "check_hyperparams",
    "main",
    "make_parser",
    "parse_params",
    "resume_differences",
    "train",
    "valid_keys",
]


class RunStoppedError(RuntimeError):
    """Training stopped by the system (a full disk): the message names the run's folder and the checkpoint
    ``--resume`` continues from."""


# errno values of a write that failed for want of space.
NO_SPACE_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def resume_target(text: str) -> int | Path:
    """argparse type of ``--resume``'s value: a run number (``3``, as rl-zoo's ``--exp-id``; a number that is not
    whole is refused), or else the path of a run folder (a run moved to another log folder:
    ``--resume /data/logs/mappo/cn-sparse-n3_3``)."""
    try:
        float(text)
    except ValueError:
        return Path(text)
    return count(text)


def check_arguments(args: argparse.Namespace) -> None:
    """The command-line options that no config check sees: sizes, paths, device (a
    :class:`~sb3_saeir.config.ConfigError` naming the first bad one), checked before anything is built or written."""
    check_range("--eval-freq", args.eval_freq, 0, " (0: never)")
    check_range("--eval-episodes", args.eval_episodes, 1)
    check_range("--save-freq", args.save_freq, -1, " (-1 or 0: never)")
    check_range("--num-threads", args.num_threads, 0, " (0: the free cores)")
    check_seed_option(args.seed, draw=DRAW_SEED)
    check_folder("-f/--log-folder", args.log_folder)
    check_folder("-tb/--tensorboard-log", args.tensorboard_log)
    check_device(args.device)
    if args.resume is not None and args.optimize:
        raise ConfigError("--resume continues one training run; it does not apply to --optimize (drop one of them).")
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
    if args.double_buffered is not None:
        overrides["double_buffered"] = DOUBLE_BUFFERED_FLAGS[args.double_buffered]
    if getattr(args, "compile", None) is not None:
        overrides["compile"] = args.compile == "on"
    check_hyperparams(args.algo, hyperparams, overrides)
    resolved = {**hyperparams, **overrides}
    check_folder("tensorboard_log", resolved.get("tensorboard_log"))
    return resolved


# Values of --double-buffered -> the algorithms' double_buffered.
DOUBLE_BUFFERED_FLAGS = {"auto": "auto", "on": True, "off": False}
# Command-line options that may change between a run and its --resume: they do not change what is trained.
RESUME_FREE_OPTIONS = ("resume", "progress", "verbose", "compile")
# Config keys that may change between a run and its --resume: settings of the machine, not of what is trained.
RESUME_FREE_CONFIG_KEYS = ("compile",)
# Options of --optimize only, not part of a training run.
OPTIMIZE_OPTIONS = ("optimize", "n_trials", "n_jobs", "sampler", "pruner", "n_evaluations", "storage", "study_name")
# Flags of the options whose flag is not "--" + the name with dashes.
OPTION_FLAGS = {"conf_file": "-conf", "params": "-params", "trained_agent": "-i", "log_folder": "-f", "tensorboard_log": "-tb"}


@dataclass(frozen=True)
class ResumePoint:
    """Where ``--resume`` continues: a run's folder, its last checkpoint and the checkpoint's resume state.

    :param folder: the run's folder
    :param checkpoint: its last resumable checkpoint
    :param state: the checkpoint's resume state
    :param stored_args: the run's command line (its ``<task>/args.yml``)
    :param skipped: the newer checkpoints that do not load, with why (the resume falls back past them)
    :param by_path: the run was given by its folder's path (``--resume FOLDER``): ``-f`` is not compared
    """

    folder: Path
    checkpoint: Path
    state: dict[str, Any]
    stored_args: dict[str, Any]
    skipped: tuple[tuple[Path, str], ...] = ()
    by_path: bool = False

    @property
    def steps(self) -> int:
        """Agent-steps of the checkpoint."""
        return int(self.state["num_timesteps"])

    @property
    def seed(self) -> int:
        """The run's seed (the drawn one when it was started with ``--seed -1``)."""
        return int(self.stored_args["seed"])

    def total_timesteps(self, n_timesteps: int) -> int:
        """The agent-step count at which the run ends: where its ``learn`` started (0, or the ``-i`` model's count)
        plus its budget ``n_timesteps``."""
        return int(self.state["model"].get("_num_timesteps_at_start", 0)) + n_timesteps


def run_callbacks(
    args: argparse.Namespace, experiment: Experiment, resume: ResumePoint | None
) -> tuple[RunCheckpointCallback, list[BaseCallback]]:
    """The run's checkpoints (every ``--save-freq`` agent-steps, resumable; also on Ctrl-C) and its evaluation every
    ``--eval-freq`` agent-steps, whose state the checkpoints carry.

    :return: the checkpoint callback and every callback of the run (it first)
    """
    assert experiment.log_folder is not None
    callbacks: list[BaseCallback] = []
    extras: dict[str, Any] = {}
    if args.eval_freq > 0:
        evaluation = experiment.eval_callback(args.eval_freq, args.eval_episodes, verbose=args.verbose)
        extras["evaluation"] = evaluation
        callbacks.append(evaluation)
    checkpoints = RunCheckpointCallback(
        experiment.log_folder,
        CHECKPOINT_NAME,
        save_freq=args.save_freq if args.save_freq > 0 else sys.maxsize,  # never but on Ctrl-C
        resumed_at=resume.steps if resume is not None else 0,
        resume_state=resume.state if resume is not None else None,
        extras=extras,
    )
    return checkpoints, [checkpoints, *callbacks]


def config_record(hyperparams: dict[str, Any]) -> dict[str, Any]:
    """The resolved hyperparameters as ``<task>/config.yml`` holds them (objects as their ``str``)."""
    return {
        key: (str(value) if not isinstance(value, (int, float, str, bool, list, dict, type(None))) else value)
        for key, value in sorted(hyperparams.items())
    }


def save_run_config(params_path: Path, hyperparams: dict[str, Any], args: argparse.Namespace) -> None:
    """``<task>/config.yml`` (resolved hyperparameters) and ``<task>/args.yml`` (the command line), as rl-zoo."""
    atomic_write_text(params_path / "config.yml", yaml.safe_dump(config_record(hyperparams), sort_keys=True))
    atomic_write_text(params_path / "args.yml", yaml.safe_dump({k: v for k, v in sorted(vars(args).items())}))


def _flag(option: str) -> str:
    return OPTION_FLAGS.get(option, "--" + option.replace("_", "-"))


def resume_differences(
    stored_args: dict[str, Any],
    stored_config: dict[str, Any],
    args: argparse.Namespace,
    resolved: dict[str, Any],
    ignored: tuple[str, ...] = (),
) -> list[str]:
    """What differs between a run (its ``args.yml`` and ``config.yml``) and the command resuming it, as
    ``"<flag> <old> -> <new>"`` and ``"config <key> <old> -> <new>"``.

    An option the run's ``args.yml`` lacks (an older version) counts as its default; ``--seed -1`` takes the run's
    seed; :data:`RESUME_FREE_OPTIONS`, :data:`RESUME_FREE_CONFIG_KEYS`, the ``--optimize`` options and ``ignored`` are
    not compared.

    :param stored_args: the run's ``args.yml``
    :param stored_config: the run's ``config.yml``
    :param args: the command
    :param resolved: the command's resolved hyperparameters (the model's, after building)
    :param ignored: more options not compared (``("log_folder",)`` for a run resumed by its folder's path)
    """
    parser = make_parser()
    command = vars(args)
    differences = []
    for option in sorted(set(command) - {*RESUME_FREE_OPTIONS, *OPTIMIZE_OPTIONS, *ignored}):
        old = stored_args.get(option, parser.get_default(option))
        new = command[option]
        if option == "seed" and new == -1:
            continue
        if old != new:
            differences.append(f"{_flag(option)} {json.dumps(old)} -> {json.dumps(new)}")
    new_config = config_record(resolved)
    differences += [
        f"config {key} {json.dumps(stored_config.get(key))} -> {json.dumps(new_config.get(key))}"
        for key in sorted(set(stored_config) | set(new_config))
        if stored_config.get(key) != new_config.get(key) and key not in RESUME_FREE_CONFIG_KEYS
    ]
    return differences


def saved_timesteps(path: Path) -> int:
    """The agent-steps a saved model zip records (``num_timesteps`` in its ``data``), without loading it."""
    with zipfile.ZipFile(path) as archive:
        return int(json.loads(archive.read("data"))["num_timesteps"])


# What <task>/args.yml and <task>/config.yml hold, for the message on a damaged one.
RUN_FILES = {
    "args.yml": "the command line that started the run, one 'option: value' line per option",
    "config.yml": "the run's resolved hyperparameters, one 'key: value' line per key",
}


def read_run_file(path: Path) -> dict[str, Any]:
    """A run's ``<task>/args.yml`` or ``<task>/config.yml``: a YAML mapping (``args.yml`` with an integer ``seed``).

    :param path: the file
    :raises ~sb3_saeir.config.ConfigError: naming the file, what is wrong with it and the fix
    """
    try:
        content = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = f"not valid YAML{where}: {getattr(error, 'problem', None) or error}"
    else:
        problem = ""
        if not isinstance(content, dict) or not content:
            problem = f"not a mapping of {path.stem}, but {type(content).__name__} {str(content)[:40]!r}"
        elif path.name == "args.yml" and (isinstance(content.get("seed"), bool) or not isinstance(content.get("seed"), int)):
            problem = f"no integer seed (seed: {content.get('seed')!r})"
    if problem:
        raise ConfigError(
            f"--resume: {path} is damaged ({problem}). It holds {RUN_FILES[path.name]}: restore it from a copy, or "
            f"write it again as another run's {path.name} (the run's own values), then resume; or start a new run "
            "without --resume."
        )
    return content


def find_run_folder(args: argparse.Namespace) -> Path:
    """The run folder ``--resume`` names: the latest run of ``--algo`` on ``--task`` in ``--log-folder``, run ``N``,
    or a run folder's path (a moved run).

    :raises ~sb3_saeir.config.ConfigError: naming what is missing and the fix
    """
    if isinstance(args.resume, Path):
        if not args.resume.is_dir():
            raise ConfigError(
                f"--resume {args.resume}: no such folder; give a run's number, or the path of a run folder such as "
                f"logs/{args.algo}/{args.task}_1 (the folder holding rl_model_<steps>_steps.zip and {args.task}/)."
            )
        return args.resume
    runs = run_numbers(args.log_folder, args.algo, args.task)
    where = Path(args.log_folder) / args.algo
    if not runs:
        raise ConfigError(
            f"--resume: no run of {args.algo} on {args.task} in {where}; start one without --resume (or, for a run "
            "folder moved elsewhere, give its path: --resume FOLDER)."
        )
    number = args.resume or max(runs)
    if number not in runs:
        raise ConfigError(
            f"--resume {number}: no run {number} of {args.algo} on {args.task} in {where}; runs: {sorted(runs)}."
        )
    return runs[number]


def newest_loading_checkpoint(folder: Path) -> tuple[Path | None, list[tuple[Path, str]]]:
    """The newest checkpoint of a run folder that loads (:func:`~sb3_saeir.common.run_state.checkpoint_problem`;
    ``None``: none does), and the newer ones that do not, with why.

    :param folder: the run's folder
    """
    checkpoints = checkpoint_steps(folder)
    skipped: list[tuple[Path, str]] = []
    for steps in sorted(checkpoints, reverse=True):
        problem = checkpoint_problem(checkpoints[steps])
        if not problem:
            return checkpoints[steps], skipped
        skipped.append((checkpoints[steps], problem))
    return None, skipped


def resume_checkpoint(folder: Path) -> tuple[Path, list[tuple[Path, str]]]:
    """The checkpoint ``--resume`` continues from: the newest that loads, and the newer ones skipped, with why.

    :param folder: the run's folder
    :raises ~sb3_saeir.config.ConfigError: when there is no checkpoint, or none loads
    """
    if not checkpoint_steps(folder):
        raise ConfigError(
            f"--resume: {folder} has no checkpoint ({CHECKPOINT_NAME.format(steps='<steps>')}): it ran without "
            "--save-freq and was not stopped with Ctrl-C. Continue its model with -i instead (a fresh state)."
        )
    checkpoint, skipped = newest_loading_checkpoint(folder)
    if checkpoint is None:
        raise ConfigError(
            f"--resume: no checkpoint of {folder} loads ({'; '.join(f'{path.name}: {why}' for path, why in skipped)}); "
            "continue its model with -i if it has one, or start a new run without --resume."
        )
    return checkpoint, skipped


def find_resume_point(args: argparse.Namespace, n_timesteps: int) -> ResumePoint:
    """The run ``--resume`` continues (the latest of ``--algo`` on ``--task`` in ``--log-folder``, run ``N``, or the
    run folder given by its path) and its newest checkpoint that loads; refuses a run that is finished, has no
    resumable checkpoint, or whose ``args.yml`` is damaged.

    :param args: the command
    :param n_timesteps: the command's budget in agent-steps
    :raises ~sb3_saeir.config.ConfigError: naming the run and the fix
    """
    folder = find_run_folder(args)
    args_path = folder / args.task / "args.yml"
    if not args_path.is_file():
        raise ConfigError(f"--resume: {folder} has no {args.task}/args.yml: it is not a run of this command.")
    stored_args = read_run_file(args_path)
    checkpoint, skipped = resume_checkpoint(folder)
    state = load_resume_state(checkpoint)
    if state is None:
        raise ConfigError(
            f"--resume: {checkpoint} has no resume state (written by an older version): continue it with -i instead."
        )
    by_path = isinstance(args.resume, Path)
    resume = ResumePoint(folder, checkpoint, state, stored_args, tuple(skipped), by_path)
    final = folder / f"{args.task}.zip"
    if final.is_file() and not checkpoint_problem(final) and saved_timesteps(final) >= resume.total_timesteps(n_timesteps):
        raise ConfigError(f"--resume: {folder} is finished ({final.name} at {saved_timesteps(final):,} agent-steps).")
    return resume


def check_resume_settings(resume: ResumePoint, args: argparse.Namespace, experiment: Experiment) -> None:
    """Refuse a ``--resume`` whose command differs from the run's (one line per setting); ``-f`` is not compared
    for a run given by its folder's path.

    :raises ~sb3_saeir.config.ConfigError: naming what differs and the fix
    """
    stored_config = read_run_file(resume.folder / args.task / "config.yml")
    ignored = ("log_folder",) if resume.by_path else ()
    differences = resume_differences(resume.stored_args, stored_config, args, experiment.resolved_hyperparams, ignored)
    if differences:
        moved = any(difference.startswith("-f ") for difference in differences)
        hint = f" If the run folder was moved, give its path instead: --resume {resume.folder}." if moved else ""
        raise ConfigError(
            f"--resume: {resume.folder} was made with other settings: {'; '.join(differences)}. Fix: resume with the "
            f"command that started it, or start a new run without --resume.{hint}"
        )


def run_logger(args: argparse.Namespace, experiment: Experiment, resume: ResumePoint | None) -> Logger:
    """SB3's logger of the run (stdout with ``--verbose`` >= 1, tensorboard with ``-tb``) writing ``progress.csv`` in
    its folder, continued after the checkpoint's rows on ``--resume`` (tensorboard then goes on in the latest
    ``<tb_log_name>_<N>`` folder, as SB3's ``reset_num_timesteps=False`` does)."""
    assert experiment.model is not None and experiment.log_folder is not None
    tb_log_name = inspect.signature(type(experiment.model).learn).parameters["tb_log_name"].default
    tensorboard_log = getattr(experiment.model, "tensorboard_log", None)
    continued = resume is not None or bool(args.trained_agent)
    sb3_logger = configure_logger(args.verbose, tensorboard_log, tb_log_name, reset_num_timesteps=not continued)
    formats = [output for output in sb3_logger.output_formats if type(output).__name__ != "CSVOutputFormat"]
    if resume is None:
        return progress_logger(experiment.log_folder, None, 0, formats)
    rollout = int(getattr(experiment.model, "n_steps", 1)) * experiment.model.n_envs
    expected_rows = resume.state.get("progress_rows")
    return progress_logger(experiment.log_folder, resume.steps, resume.steps // rollout, formats, expected_rows, log=note)


def note(message: str) -> None:
    """Say something the user should know about the run (a row that cannot be restored, a checkpoint skipped)."""
    print(f"Note: {message}", flush=True)


@contextmanager
def checkpoint_on_ctrl_c(checkpoints: RunCheckpointCallback) -> Iterator[None]:
    """While training: the first Ctrl-C asks for a checkpoint at the next rollout start and a stop there; a second
    stops at once (``KeyboardInterrupt``). Outside the main thread (where signals cannot be handled) Ctrl-C stops at
    once."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        if checkpoints.stop_requested:
            raise KeyboardInterrupt
        checkpoints.request_stop()
        print("\nCtrl-C: writing a checkpoint after this rollout and update, then stopping (Ctrl-C again: stop now)")

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def train(args: argparse.Namespace) -> Path:
    """Train one run (or, with ``--resume``, continue one from its newest checkpoint that loads); returns its folder.

    Everything that can fail on a bad setting (config, env, model, saved model, the settings of the run resumed) is
    built and checked before anything is written in the run folder; a new run's folder is claimed exclusively
    (:func:`~sb3_saeir.experiment.claimed_run_folder`) and removed again when the command is refused, so a bad command
    leaves nothing behind and runs started together get different numbers. A full disk stops the run with a
    :class:`RunStoppedError` naming the folder and the checkpoint to resume from.
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
    resume = find_resume_point(args, n_timesteps) if args.resume is not None else None
    folder: AbstractContextManager[Path]
    if resume is not None:
        seed, folder = resume.seed, nullcontext(resume.folder)
    else:
        seed = int(np.random.randint(2**31 - 1)) if args.seed == DRAW_SEED else args.seed
        folder = claimed_run_folder(args.log_folder, args.algo, args.task)
    with folder as save_path:  # a new run's folder is removed again if the set-up fails
        set_random_seed(seed)
        experiment = Experiment(args.algo, args.task, hyperparams, seed=seed, log_folder=save_path)
        # the model is built on the monitored env (the monitor writes its CSV at the first finished game)
        monitor = MultiAgentVecMonitor(
            experiment.make_env(), str(save_path / "games"), env_id=args.task, append=resume is not None, log=note
        )
        build_experiment(experiment, args, monitor, resume)
        try:
            checkpoints, callbacks = run_callbacks(args, experiment, resume)
        except (ValueError, TypeError) as error:
            experiment.close()
            raise ConfigError(f"cannot set up evaluation or checkpoints: {error}") from error
    callbacks.append(BudgetEstimate(n_timesteps))
    announce_run(args, experiment, resume, n_timesteps)
    try:
        write_run_files(args, experiment, resume, seed)
        run_training(args, experiment, checkpoints, callbacks, resume, n_timesteps)
    except OSError as error:
        if error.errno not in NO_SPACE_ERRNOS:
            raise
        close_quietly(experiment)
        raise RunStoppedError(no_space_message(error, save_path)) from None
    finally:
        experiment.close()
    return save_path


def write_run_files(args: argparse.Namespace, experiment: Experiment, resume: ResumePoint | None, seed: int) -> None:
    """Set the run's logger on the model, and write ``<task>/config.yml`` and ``<task>/args.yml`` of a new run."""
    assert experiment.model is not None and experiment.log_folder is not None
    params_path = experiment.log_folder / args.task
    params_path.mkdir(exist_ok=resume is not None)
    experiment.model.set_logger(run_logger(args, experiment, resume))
    if resume is None:
        save_run_config(params_path, experiment.resolved_hyperparams, argparse.Namespace(**{**vars(args), "seed": seed}))


def announce_run(args: argparse.Namespace, experiment: Experiment, resume: ResumePoint | None, n_timesteps: int) -> None:
    """Say what is trained, where, and (resuming) from which checkpoint, which newer ones were skipped and what cannot
    be restored exactly."""
    assert experiment.env is not None and experiment.log_folder is not None
    save_path = experiment.log_folder
    n_agents = experiment.env.num_envs // experiment.n_games
    print(f"Training {args.algo} on {args.task}: {experiment.n_games} games x {n_agents} agents, {n_timesteps:,} agent-steps")
    if resume is not None:
        remaining = resume.total_timesteps(n_timesteps) - resume.steps
        if resume.skipped:
            skipped = ", ".join(f"{path.name} ({why})" for path, why in resume.skipped)
            note(f"skipped the newest checkpoint(s) of {save_path}, which do not load: {skipped}")
        print(f"Resuming {save_path} from {resume.checkpoint.name}: {remaining:,} agent-steps to go")
        for message in describe_resume(experiment.model, resume.state):
            note(message)
    elif args.n_timesteps is None:
        print("(n_timesteps from the config; -n sets a shorter budget. The time it takes is printed after the first rollout.)")
    print(f"Log folder: {save_path}")


def run_training(
    args: argparse.Namespace,
    experiment: Experiment,
    checkpoints: RunCheckpointCallback,
    callbacks: list[BaseCallback],
    resume: ResumePoint | None,
    n_timesteps: int,
) -> None:
    """Train (the first Ctrl-C: a checkpoint and a clean stop) and save the final model, saying what happens."""
    assert experiment.log_folder is not None
    save_path = experiment.log_folder
    remaining = n_timesteps if resume is None else resume.total_timesteps(n_timesteps) - resume.steps
    start = time.time()
    try:
        with checkpoint_on_ctrl_c(checkpoints):
            experiment.learn(
                remaining,
                callbacks=callbacks,
                progress_bar=args.progress,
                reset_num_timesteps=not (args.trained_agent or resume is not None),
            )
    except KeyboardInterrupt:
        print("Interrupted: saving the model (resume from the last checkpoint, if any, with --resume).")
    if checkpoints.stopped_at is not None:
        print(f"Stopped at the checkpoint {checkpoints.stopped_at}: the same command with --resume continues it.")
    model_path = experiment.save(save_path / f"{args.task}.zip")
    print(f"Saved {model_path} after {time.time() - start:.0f} s")


def no_space_message(error: OSError, folder: Path) -> str:
    """One line for a run stopped by a full disk: what failed, the run's folder, the checkpoint to resume from."""
    what = f"{error.strerror or 'no space left on the device'}" + (f" writing {error.filename}" if error.filename else "")
    checkpoint, _ = newest_loading_checkpoint(folder)
    if checkpoint is None:
        return (
            f"{what}: the run in {folder} stopped and has no checkpoint to resume from. Free some space and start it "
            "again (--save-freq writes resumable checkpoints)."
        )
    return (
        f"{what}: the run in {folder} stopped; its last good checkpoint is {checkpoint.name}. Free some space, then "
        "run the same command with --resume to continue from it."
    )


def close_quietly(experiment: Experiment) -> None:
    """Close the run's open files (logger, monitor CSV) after a failed write: data still buffered for a full disk is
    dropped here rather than reported at exit."""
    monitor = experiment.env
    assert isinstance(monitor, MultiAgentVecMonitor)
    for file_owner in (experiment.model.logger if experiment.model is not None else None, monitor.results_writer):
        if file_owner is not None:
            with suppress(OSError, ValueError):
                file_owner.close()


def build_experiment(
    experiment: Experiment, args: argparse.Namespace, env: MultiAgentVecMonitor, resume: ResumePoint | None = None
) -> None:
    """Build the model on ``env`` (or load ``--trained-agent`` onto it, or, with ``--resume``, check the run's settings
    and load its checkpoint); a bad setting becomes a :class:`~sb3_saeir.config.ConfigError`.

    :param experiment: the run's experiment
    :param args: the command
    :param env: the run's training env, monitored
    :param resume: where ``--resume`` continues
    """
    # -tb, else the config's tensorboard_log (passing None would switch the config's off)
    tensorboard_log = args.tensorboard_log
    if tensorboard_log is None:
        tensorboard_log = experiment.hyperparams.get("tensorboard_log")
    try:
        if args.trained_agent and resume is None:
            experiment.load(args.trained_agent, env=env, device=args.device, tensorboard_log=tensorboard_log)
        else:
            experiment.build(env=env, verbose=args.verbose, device=args.device, tensorboard_log=tensorboard_log)
        if resume is not None:
            check_resume_settings(resume, args, experiment)
            experiment.resume(resume.checkpoint, device=args.device, tensorboard_log=tensorboard_log)
    except (ValueError, TypeError, KeyError, zipfile.BadZipFile, ConfigError) as error:
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
    parser.add_argument("--seed", type=int, default=0, help=f"random seed, 0 .. 2**32 - 1 ({DRAW_SEED}: draw one)")
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
    except (ConfigError, FileExistsError, MissingExtraError) as error:
        print(f"sb3_saeir.train: error: {error}", file=sys.stderr)
        return 2
    except RunStoppedError as error:
        print(f"sb3_saeir.train: error: {error}", file=sys.stderr)
        return 1


def _main(args: argparse.Namespace) -> int:
    if args.optimize:
        require_extra("optuna", "zoo", "--optimize")
        from sb3_saeir.hyperparams_opt import optimize

        check_arguments(args)
        optimize(args, resolve_hyperparams(args))
    else:
        train(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
