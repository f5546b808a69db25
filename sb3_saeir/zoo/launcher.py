"""``python -m sb3_saeir.zoo train|enjoy [rl-zoo3 arguments]``: the package's methods and tasks registered in rl-zoo3
(:mod:`sb3_saeir.zoo.registration`), the arguments adjusted for a package task, then rl-zoo3's own ``train()`` (with
:class:`~sb3_saeir.zoo.manager.RunExperimentManager`) or ``enjoy()``. The manual, commands and pitfalls:
``docs/guide/zoo.md``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from contextlib import nullcontext
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stable_baselines3.common.vec_env import DummyVecEnv

from sb3_saeir.command_line import (
    OneLineParser,
    check_folder,
    check_seed_option,
    one_line_warnings,
    resume_target,
)
from sb3_saeir.common.extras import MissingExtraError, require_extra
from sb3_saeir.common.stop_signals import (
    ctrl_c_to_the_command,
    interrupted_exit_status,
    signal_name,
    stop_signal_number,
    stop_signals_as_ctrl_c,
)
from sb3_saeir.config import ALGOS, ConfigError, check_n_envs, config_path, load_yaml, parse_params
from sb3_saeir.evaluation import summarise_episodes
from sb3_saeir.run.folder import RunFolder
from sb3_saeir.run.lock import RunFolderInUseError
from sb3_saeir.run.run import RunStoppedError
from sb3_saeir.zoo.registration import (
    WRAPPER_NAME,
    EnjoySession,
    GameMonitor,
    is_package_env,
    register_algorithms,
    register_gym_envs,
)

if TYPE_CHECKING:
    from sb3_saeir.zoo.manager import ZooTrain


def _load_zoo_entry(conf: str, env_id: str) -> dict[str, Any] | None:
    """The hyperparameters rl-zoo3 will read for ``env_id`` from ``conf`` (same lookup: yaml / .py / module, then
    ``default``), or ``None`` if they cannot be read here (rl-zoo3 then reports the problem itself)."""
    import importlib

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
    parser = OneLineParser(prog="sb3_saeir.zoo", add_help=False, allow_abbrev=False)  # its errors: one line
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
    :func:`prepare_train_args`), before rl-zoo3 creates anything: ``--seed`` is a seed (or -1), the log and
    tensorboard folders can be written, and
    ``n_envs`` (config entry or ``-params``) is a positive integer (rl-zoo3 fails on it after creating the run folder).

    :param argv: the arguments for ``rl_zoo3.train.train()``
    :raises ~sb3_saeir.config.ConfigError: naming the first bad option
    """
    parser = _mini_parser(
        [
            (["--env"], {"default": "CartPole-v1"}),
            (["-conf", "--conf-file"], {"default": None}),
            (["-f", "--log-folder"], {"default": "logs"}),
            (["-tb", "--tensorboard-log"], {"default": ""}),
            (["-params", "--hyperparams"], {"nargs": "+", "action": "append", "default": []}),
            (["--seed"], {"default": None}),
            (["-n", "--n-timesteps"], {"default": None}),
            (["--eval-freq"], {"default": None}),
            (["--eval-episodes"], {"default": None}),
        ]
    )
    args = parser.parse_known_args(list(argv))[0]
    if not is_package_env(args.env):
        return
    if {"-optimize", "--optimize", "--optimize-hyperparameters"} & set(argv):  # rl-zoo3's KeyError for the method
        raise ConfigError(
            "-optimize: rl-zoo3 has no samplers for the package's methods; tune them with python -m sb3_saeir.train "
            "--optimize (docs/guide/training.md)."
        )
    check_zoo_counts(args.n_timesteps, args.eval_freq, args.eval_episodes)
    seed = _whole_number(args.seed)  # not a whole number: rl-zoo3's parser refuses it
    if seed is not None:
        check_seed_option(seed, draw=-1)  # numpy's seeding would fail on it later, after the folder exists
    check_folder("-f/--log-folder", args.log_folder)
    check_folder("-tb/--tensorboard-log", args.tensorboard_log or None)
    for item in (item for group in args.hyperparams for item in group):
        check_zoo_param(item)
    items = [item for group in args.hyperparams for item in group if item.split(":")[0] == "n_envs"]
    entry = _load_zoo_entry(args.conf_file, args.env) if args.conf_file is not None else None
    check_n_envs(parse_params(items[-1:])["n_envs"] if items else (entry or {}).get("n_envs"))


def _whole_number(text: str | None) -> int | None:
    """An option's value as rl-zoo3's ``int`` options take it, or ``None`` (not given, or not a whole number written
    in ASCII digits: rl-zoo3's own parser refuses those)."""
    digits = text.removeprefix("-") if text is not None else ""
    return int(text) if text is not None and digits.isascii() and digits.isdigit() else None


def check_zoo_counts(n_timesteps: str | None, eval_freq: str | None, eval_episodes: str | None) -> None:
    """Refuse, before rl-zoo3 starts, a ``-n`` below 1 (rl-zoo3 reads ``-n 0`` as "not given" and trains the config's
    whole budget) and ``--eval-episodes`` below 1 with evaluations on (the run failed at its first evaluation, its
    folder written). Values rl-zoo3's own parser refuses (not whole numbers) are left to it.

    :param n_timesteps: ``-n`` as given (``None``: not given)
    :param eval_freq: ``--eval-freq`` as given
    :param eval_episodes: ``--eval-episodes`` as given
    """
    budget, frequency, episodes = _whole_number(n_timesteps), _whole_number(eval_freq), _whole_number(eval_episodes)
    if budget is not None and budget < 1:
        raise ConfigError(
            f"-n {n_timesteps}: a budget is a number of agent-steps >= 1 (rl-zoo3 reads -n <= 0 as not given and would "
            "train the config's n_timesteps); leave -n out for the config's budget."
        )
    if episodes is not None and episodes < 1 and (frequency is None or frequency > 0):
        raise ConfigError(f"--eval-episodes {eval_episodes}: an evaluation plays >= 1 game episode (--eval-freq 0: none).")


def check_zoo_param(item: str) -> None:
    """Refuse a ``-params`` entry that rl-zoo3 cannot read (it evaluates each value as a Python expression, so a bare
    word such as ``compile:bogus`` is a ``NameError`` there), naming the value and how to write a string.

    :param item: one ``key:value`` entry
    :raises ~sb3_saeir.config.ConfigError: naming the entry and the fix
    """
    from rl_zoo3.utils import StoreDict

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
    ctrl_c_to_the_command()
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in ("train", "enjoy"):
        print(
            "usage: python -m sb3_saeir.zoo {train,enjoy} [rl-zoo3 arguments]\n"
            f"  algorithms added to rl-zoo3: {', '.join(register_algorithms())}\n"
            f"  env ids (--env): {', '.join(register_gym_envs())}\n"
            "  see `python -m sb3_saeir.zoo train --help` and docs/guide/zoo.md.",
            file=sys.stderr,
        )
        return 2
    command, rest = argv[0], argv[1:]
    try:
        require_extra("rl_zoo3", "zoo", "python -m sb3_saeir.zoo")
    except MissingExtraError as error:
        print(f"sb3_saeir.zoo: error: {error}", file=sys.stderr)
        return 2
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
    from sb3_saeir.zoo.manager import ZooTrain

    command = ZooTrain(package_env, resume.resume)
    try:
        with stop_signals_as_ctrl_c():
            if package_env:  # the run's folder, held until the command ends (a refused new run's removed)
                command.folder, new_argv = claim_run_folder(new_argv, resume.resume)
            sys.argv = ["python -m sb3_saeir.zoo train", *new_argv]
            with command.folder or nullcontext():
                train_with_manager(command)
    except (ConfigError, RunFolderInUseError) as error:
        print(f"sb3_saeir.zoo: error: {error}", file=sys.stderr)
        return 2
    except RunStoppedError as error:  # a full disk, a run folder moved, deleted or made read-only
        print(f"sb3_saeir.zoo: error: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as stop:  # before the run started (the run handles its own stop)
        signum = stop_signal_number(stop)
        print(f"sb3_saeir.zoo: {signal_name(signum)}: stopped before the run started: nothing was written", file=sys.stderr)
        return interrupted_exit_status(signum)
    if command.stop_line is not None:
        print(command.stop_line)
        return interrupted_exit_status(command.stop_signal)
    return 0


def train_with_manager(command: ZooTrain) -> None:
    """rl-zoo3's ``train()`` (its arguments in ``sys.argv``) with :class:`~sb3_saeir.zoo.manager.RunExperimentManager`
    as its ``ExperimentManager``.

    :param command: the launcher's :class:`~sb3_saeir.zoo.manager.ZooTrain`
    """
    import rl_zoo3.train

    from sb3_saeir.zoo.manager import RunExperimentManager

    # rl-zoo3's train() parses its ~50 options, then builds `ExperimentManager(args, ...)` by the name its module
    # imported, with no way to pass a subclass: that name is bound to the package's subclass here, the one place, for
    # this call only (rl-zoo3's class is put back after it)
    original = rl_zoo3.train.ExperimentManager
    rl_zoo3.train.ExperimentManager = partial(RunExperimentManager, zoo_train=command)  # type: ignore[assignment,misc]
    try:
        rl_zoo3.train.train()
    finally:
        rl_zoo3.train.ExperimentManager = original  # type: ignore[misc]


def claim_run_folder(argv: list[str], resume: int | Path | None) -> tuple[RunFolder, list[str]]:
    """The run's folder, held (:class:`~sb3_saeir.run.folder.RunFolder`): a new run's, claimed in rl-zoo3's
    numbering (``<log-folder>/<algo>/<env>_<run>``), or the one ``--resume`` names (the latest run, run ``N`` or a
    folder's path), with rl-zoo3's arguments given the run's own seed (a ``--seed`` other than the run's, or -1,
    rl-zoo3's default, is refused).

    :param argv: rl-zoo3's ``train`` arguments
    :param resume: ``--resume``'s value (``None``: a new run)
    :raises ~sb3_saeir.config.ConfigError: naming the problem and the fix
    :raises ~sb3_saeir.run.lock.RunFolderInUseError: when another process trains the run
    """
    from rl_zoo3.utils import EnvironmentName

    options, _ = _mini_parser(
        [
            (["--algo"], {"default": "ppo"}),
            (["--env"], {"default": "CartPole-v1"}),
            (["-f", "--log-folder"], {"default": "logs"}),
            (["--seed"], {"type": int, "default": -1}),
        ]
    ).parse_known_args(argv)
    task = EnvironmentName(options.env).gym_id
    if resume is None:
        return RunFolder.claim(options.log_folder, options.algo, task), argv
    folder = RunFolder.find(options.log_folder, options.algo, task, resume)
    try:
        seed = folder.resumed_seed(options.seed)
    except BaseException:
        folder.close()
        raise
    seed_free = _mini_parser([(["--seed"], {"default": None})]).parse_known_args(argv)[1]
    return folder, [*seed_free, "--seed", str(seed)]


def _run_enjoy(argv: Sequence[str]) -> int:
    from rl_zoo3.enjoy import enjoy
    from rl_zoo3.exp_manager import ExperimentManager

    from sb3_saeir.zoo.manager import one_line

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
