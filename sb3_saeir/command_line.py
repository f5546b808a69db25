"""What the command lines share: the one-line argument parser, the ``count`` type, ``--resume``'s value, the checks of
the options that no config check sees (sizes, seeds, folders, device, Optuna storage), and ``train``'s config entry
with its command-line overrides applied. The configs and models are :mod:`sb3_saeir.config`.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import typing
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from sb3_saeir.common.checks import MAX_TIMESTEPS, check_device
from sb3_saeir.common.utils import DRAW_SEED, check_seed, unwritable_folder
from sb3_saeir.config import (
    ConfigError,
    check_algo,
    check_hyperparams,
    check_params_against_flags,
    config_path,
    load_hyperparams,
    parse_params,
)
from sb3_saeir.envs import list_tasks


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, ``<prog>: error: <message> (see --help)``, exit status 2."""

    def error(self, message: str) -> typing.NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help).\n")


def count(text: str) -> int:
    """argparse type of a count: an integer, also written as rl-zoo3 users write big numbers (``1e6``, ``2.5e5``)."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid integer {text!r}") from None
    if not value.is_integer():
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number")
    return int(value)


def budget(text: str) -> int:
    """argparse type of an agent-step budget (``-n``): a count (:func:`count`) of at most 2**53."""
    value = count(text)
    if value > MAX_TIMESTEPS:
        raise argparse.ArgumentTypeError(f"{text!r} agent-steps is more than 2**53 ({MAX_TIMESTEPS:,}), the largest budget")
    return value


def check_range(option: str, value: int | None, low: int, meaning: str = "") -> None:
    """Refuse ``value < low`` of a command-line option (``None``: not given, accepted).

    :param option: the option's name, e.g. ``--eval-episodes``
    :param value: its value
    :param low: smallest valid value
    :param meaning: what the smallest values mean, appended to the message (e.g. ``"; 0: never"``)
    """
    if value is not None and value < low:
        raise ConfigError(f"{option} must be >= {low}{meaning}, got {value}.")


def check_seed_option(seed: int, option: str = "--seed", draw: int | None = None) -> None:
    """Refuse a ``--seed`` outside ``0 .. 2**32 - 1`` (and other than ``draw``, the value that draws one) with the
    check of the Python API (:func:`~sb3_saeir.common.utils.check_seed`).

    :param seed: the option's value
    :param option: the option's name
    :param draw: the value that draws a seed (``None``: none does)
    """
    if draw is not None and seed == draw:
        return
    try:
        check_seed("", seed, option, hint="" if draw is None else f" (or {draw} to draw one)")
    except ValueError as error:
        raise ConfigError(str(error)) from None


def check_folder(option: str, folder: str | os.PathLike | None) -> None:
    """Refuse an output folder that cannot be created or written: empty, a file, under a file, or not writable.

    :param option: the option's name, e.g. ``-f``
    :param folder: the folder (``None``: not given, accepted)
    """
    if folder is None:
        return
    if str(folder) == "":
        raise ConfigError(f"{option} is empty: give a folder (e.g. {option} logs).")
    path = Path(folder)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{option} {path} is a file, not a folder.")
    dangling = next((part for part in (path, *path.parents) if part.is_symlink() and not part.exists()), None)
    if dangling is not None:  # mkdir failed on it with "[Errno 17] File exists"
        raise ConfigError(
            f"{option} {path}: {dangling} is a link to {os.readlink(dangling)}, which does not exist; make that folder "
            "or give another one."
        )
    problem = unwritable_folder(path)
    if problem:
        raise ConfigError(f"{option} {path}: {problem}; give a folder you can write.")


def check_output_file(option: str, file: str | os.PathLike | None) -> None:
    """Refuse an output file that cannot be written: empty, a folder, or in a folder that does not exist or is not
    writable.

    :param option: the option's name, e.g. ``--gif``
    :param file: the file (``None``: not given, accepted)
    """
    if file is None:
        return
    path = Path(file)
    if str(file) == "" or path.is_dir():
        raise ConfigError(f"{option} {str(file)!r} is not a file name (e.g. {option} replay.gif).")
    parent = path.parent
    if not parent.is_dir():
        raise ConfigError(f"{option} {path}: the folder {parent} does not exist.")
    if unwritable_folder(parent) or (path.exists() and not os.access(path, os.W_OK)):
        raise ConfigError(f"{option} {path} is not writable.")


@contextlib.contextmanager
def one_line_warnings(prog: str) -> Iterator[None]:
    """While a command runs, show each warning as one ``<prog>: warning: <message>`` line on stderr (Python's default
    adds the file, the line number and the source line).

    :param prog: the command, e.g. ``sb3_saeir.train``
    """
    previous = warnings.showwarning

    def show(
        message: Warning | str, category: type[Warning], filename: str, lineno: int, file: Any = None, line: Any = None
    ) -> None:
        print(f"{prog}: warning: {message}", file=sys.stderr if file is None else file)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = previous


def resume_target(text: str) -> int | Path:
    """argparse type of ``--resume``'s value: a run number (``3``, as rl-zoo's ``--exp-id``; a number that is not
    whole is refused), or else the path of a run folder (a run moved to another log folder:
    ``--resume /data/logs/mappo/cn-sparse-n3_3``)."""
    if not text.strip():  # Path("") is the current folder: a run there would be resumed without a word
        raise argparse.ArgumentTypeError("give a run number or a run folder (no value: the latest run)")
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
    if args.resume is not None and args.optimize:
        raise ConfigError("--resume continues one training run; it does not apply to --optimize (drop one of them).")
    if args.optimize:
        check_range("--n-trials", args.n_trials, 1)
        check_range("--n-evaluations", args.n_evaluations, 1)
        if args.n_jobs != -1:
            check_range("--n-jobs", args.n_jobs, 1, " (or -1: one per CPU)")
        if args.storage is not None:
            check_storage(args.storage)
    check_folder("-f/--log-folder", args.log_folder)
    check_folder("-tb/--tensorboard-log", args.tensorboard_log)
    if args.seed is not None:  # None: not given (0, or the run's at --resume)
        check_seed_option(args.seed, draw=DRAW_SEED)
    try:
        check_device("--device", args.device, cpu_fallback=False)  # cuda refused where there is none (no CPU fallback)
    except ValueError as error:
        raise ConfigError(str(error)) from None


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
    check_algo(args.algo)
    if args.task not in list_tasks():
        raise ConfigError(f"unknown task {args.task!r}; valid choices: {', '.join(list_tasks())}.")
    conf_file = args.conf_file or config_path(args.algo)
    if Path(conf_file).is_dir():
        example = Path(conf_file) / f"{args.algo}.yml"
        raise ConfigError(f"config file {conf_file} is a folder; give a YAML file such as {example}.")
    if not Path(conf_file).is_file():
        raise ConfigError(f"config file {conf_file} does not exist.")
    try:
        hyperparams = load_hyperparams(args.algo, args.task, conf_file)
    except KeyError as error:
        raise ConfigError(str(error.args[0])) from error
    overrides = parse_params(args.params)
    double_buffered = DOUBLE_BUFFERED_FLAGS[args.double_buffered] if args.double_buffered is not None else None
    compile_on = None if getattr(args, "compile", None) is None else args.compile == "on"
    flags = {
        "n_envs": ("--n-games", args.n_games),
        "n_timesteps": ("-n", args.n_timesteps),
        "num_cpus": ("--num-cpus", args.num_cpus),
        "double_buffered": ("--double-buffered", double_buffered),
        "compile": ("--compile", compile_on),
    }
    check_params_against_flags(overrides, flags)
    overrides.update({key: value for key, (_, value) in flags.items() if value is not None})
    check_hyperparams(args.algo, hyperparams, overrides)
    resolved = {**hyperparams, **overrides}
    check_folder("tensorboard_log", resolved.get("tensorboard_log"))
    return resolved


# Values of --double-buffered -> the algorithms' double_buffered.
DOUBLE_BUFFERED_FLAGS = {"auto": "auto", "on": True, "off": False}
