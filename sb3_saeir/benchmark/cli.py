"""The command line of ``python -m sb3_saeir.benchmark``: arguments, checks made before any training, the refusal
of settings that differ from the runs already in ``--out``, then training and the reports.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from sb3_saeir.benchmark.execution import RERUN_COPY, run_all
from sb3_saeir.benchmark.reports import plot_system_entropy, report
from sb3_saeir.benchmark.runs import move_aside, parse_seeds, run_folder
from sb3_saeir.command_line import OneLineParser, budget, check_folder, count
from sb3_saeir.common.atomic import atomic_write_text
from sb3_saeir.common.extras import MissingExtraError, require_extra
from sb3_saeir.common.stop_signals import (
    StopSignal,
    ctrl_c_to_the_command,
    interrupted_exit_status,
    stop_signals_as_ctrl_c,
)
from sb3_saeir.config import (
    ALGOS,
    DEFAULT_N_GAMES,
    ConfigError,
    check_hyperparams,
    check_params_against_flags,
    load_hyperparams,
    parse_params,
)
from sb3_saeir.run.files import DONE_FILE, PROGRESS_FILE
from sb3_saeir.run.folder import check_run_folder_writable, folders_in_use
from sb3_saeir.run.record import (
    RunSpec,
    ensure_spec_file,
    is_finished,
    read_spec_file,
    spec_record,
    stored_spec_differences,
)

# The line Ctrl-C ends with (exit status 130).
INTERRUPTED = "sb3_saeir.benchmark: interrupted: re-run the same command to resume"


# The command's one-line description (its --help).
DESCRIPTION = "Benchmark runner: methods x tasks x seeds -> runs.csv, the paper's Table 1 layout and learning curves."


def refusal(out: Path, mismatches: list[tuple[RunSpec, list[str]]], report_only: bool = False) -> str:
    """The message of a command whose runs differ from those already in ``out``: one line per run, then the fix.

    :param out: the benchmark folder
    :param mismatches: each mismatching run with its differences (:func:`~sb3_saeir.run.record.spec_differences`)
    :param report_only: the command only reports (``--rerun-changed`` does not apply)
    """
    lines = [f"sb3_saeir.benchmark: error: {len(mismatches)} run(s) in {out} were made with other settings:"]
    lines += [f"  {spec.name}: {'; '.join(differences)}" for spec, differences in mismatches]
    if report_only:
        lines.append("fix: give --report-only the settings these runs were made with (the old values above)")
    else:
        lines.append(
            "fix: use another --out for these settings, or add --rerun-changed to move these runs aside "
            "(to <folder>.replaced-<UTC time>, nothing deleted) and train them again"
        )
    return "\n".join(lines)


def unwritable_runs(out: Path, specs: list[RunSpec]) -> list[str]:
    """Why each run folder this command would go on writing cannot be written (a run that is not finished, or whose
    budget the command raises: :func:`~sb3_saeir.run.folder.check_run_folder_writable`), before anything is written.

    :param out: the benchmark folder
    :param specs: the command's runs
    """
    problems = []
    for spec in specs:
        folder = run_folder(out, spec)
        if not folder.is_dir() or is_finished(folder, _stored_or_none(folder), spec.n_timesteps):
            continue
        try:
            check_run_folder_writable(folder, spec.name, RERUN_COPY)
        except ConfigError as error:
            problems.append(str(error))
    return problems


def _stored_or_none(folder: Path) -> dict[str, Any] | None:
    """A run folder's ``spec.json``, ``None`` when there is none or it is damaged (the settings check names that)."""
    try:
        return read_spec_file(folder)
    except ConfigError:
        return None


def _parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="python -m sb3_saeir.benchmark", description=DESCRIPTION)
    parser.add_argument("--algos", nargs="+", default=["saeir_ppo", "mappo"], help=f"methods: {', '.join(sorted(ALGOS))}")
    parser.add_argument("--tasks", nargs="+", default=["cn-sparse-n3"])
    parser.add_argument("--seeds", default="1-3", help="e.g. 1-5 or 1,3,7")
    parser.add_argument("-n", "--n-timesteps", type=budget, default=1_000_000, help="agent-steps per run")
    parser.add_argument("--n-games", type=count, default=None, help="override the configs' n_envs (games)")
    parser.add_argument("--eval-freq", type=count, default=50_000, help="agent-steps between evaluations")
    parser.add_argument("--eval-episodes", type=count, default=20, help="game episodes per evaluation")
    parser.add_argument("-params", "--hyperparams", dest="params", nargs="+", default=None, help="overrides key:value")
    parser.add_argument("--jobs", type=count, default=1, help="parallel local processes")
    parser.add_argument(
        "--num-threads",
        type=count,
        default=1,
        help="torch threads per run (1; 2 for one job whose games run in 2 env workers, -params num_cpus:2)",
    )
    parser.add_argument("--ray-address", default=None, help="run on a Ray cluster (e.g. 'auto' or host:port)")
    parser.add_argument("--out", default="benchmark", help="output folder")
    parser.add_argument(
        "--rerun-changed",
        action="store_true",
        help="move runs made with other settings aside (<folder>.replaced-<UTC time>) and train them again",
    )
    parser.add_argument(
        "--rliable", action="store_true", help="also write aggregate.md (IQM, bootstrap CIs, pairwise Mann-Whitney tests)"
    )
    parser.add_argument("--report-only", action="store_true", help="rebuild runs.csv/table/curves without training")
    parser.add_argument("--entropy-plot", default=None, help="RUN_FOLDER: plot the SAEIR bonus, fire rate and value entropy")
    return parser


def _error(message: str) -> int:
    print(f"sb3_saeir.benchmark: error: {message}", file=sys.stderr)
    return 2


def _check_arguments(args: argparse.Namespace) -> str | None:
    """The first bad argument, as a message (``None``: all good)."""
    from sb3_saeir.envs import list_tasks

    for flag, names in (("--algos", args.algos), ("--tasks", args.tasks)):
        repeated = sorted({name for name in names if names.count(name) > 1})
        if repeated:  # each run twice in the table, and two jobs on one run folder
            return f"{flag} names {repeated} more than once: give each once"
    unknown = [algo for algo in args.algos if algo not in ALGOS]
    if unknown:
        return f"unknown methods {unknown}; valid: {', '.join(sorted(ALGOS))}"
    unknown = [task for task in args.tasks if task not in list_tasks()]
    if unknown:
        return f"unknown tasks {unknown}; valid: {', '.join(list_tasks())}"
    for flag, value in (("-n", args.n_timesteps), ("--eval-freq", args.eval_freq), ("--eval-episodes", args.eval_episodes)):
        if value < 1:
            return f"{flag} must be >= 1, got {value}"
    for flag, value in (("--n-games", args.n_games), ("--jobs", args.jobs), ("--num-threads", args.num_threads)):
        if value is not None and value < 1:
            return f"{flag} must be >= 1, got {value}"
    try:
        parse_seeds(args.seeds)
        if not args.report_only:
            check_folder("--out", args.out)
    except ConfigError as error:
        return str(error)
    return None


def check_runs_build(specs: list[RunSpec], out: Path) -> None:
    """Build (and close) the model of every run still to train, once per method, task and number of games, so that a
    setting only the algorithm, the env or a config callback refuses stops the command before any run folder is made.

    :raises ~sb3_saeir.config.ConfigError: naming the run and the problem
    """
    from sb3_saeir.experiment import Experiment

    checked: set[tuple[str, str, int | None]] = set()
    for spec in specs:
        key = (spec.algo, spec.task, spec.n_games)
        if key in checked or (run_folder(out, spec) / DONE_FILE).is_file():
            continue
        checked.add(key)
        experiment = Experiment(
            spec.algo,
            spec.task,
            spec.resolved_config(),
            seed=spec.seed,
            n_games=spec.n_games,
        )
        try:
            experiment.build(verbose=0)
            experiment.make_eval_env(spec.eval_episodes)
        except (ValueError, TypeError, KeyError) as error:
            message = error.args[0] if isinstance(error, KeyError) and error.args else error
            raise ConfigError(f"cannot build {spec.algo} on {spec.task} with these settings: {message}") from error
        finally:
            experiment.close()


def plan_runs(args: argparse.Namespace, params: dict[str, Any]) -> list[RunSpec]:
    """The command's runs, with the number of games resolved (``--n-games`` or the config's ``n_envs``)."""
    specs = []
    for task in args.tasks:
        for algo in args.algos:
            config = {**load_hyperparams(algo, task), **params}
            n_games = args.n_games if args.n_games is not None else int(config.get("n_envs", DEFAULT_N_GAMES))
            for seed in parse_seeds(args.seeds):
                specs.append(
                    RunSpec(algo, task, seed, args.n_timesteps, n_games, args.eval_freq, args.eval_episodes, params, config)
                )
    return specs


def prepare_folders(out: Path, specs: list[RunSpec], mismatches: list[tuple[RunSpec, list[str]]]) -> None:
    """Move the mismatching runs aside and write every planned run's ``spec.json`` (before any training)."""
    for spec, _ in mismatches:
        folder = run_folder(out, spec)
        print(f"{spec.name}: made with other settings, moved to {move_aside(folder)}", flush=True)
    for spec in specs:
        ensure_spec_file(run_folder(out, spec), spec_record(spec))


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit status (0 done, 1 some run failed, 2 bad arguments or settings that differ
    from the runs in ``--out``, 130 interrupted by Ctrl-C, 143 by SIGTERM, 129 by SIGHUP: the jobs are stopped and
    every run resumes from its newest checkpoint when the command is run again)."""
    ctrl_c_to_the_command()
    args = _parser().parse_args(argv)
    try:
        with stop_signals_as_ctrl_c():
            return _main(args)
    except KeyboardInterrupt as stop:
        print(INTERRUPTED, file=sys.stderr, flush=True)
        return interrupted_exit_status(stop.signum if isinstance(stop, StopSignal) else None)


def _missing_extra(args: argparse.Namespace) -> str | None:
    """Check, before any training, that the optional packages this command needs are installed."""
    needed = [("matplotlib", "plots", "the benchmark's curves.png")]
    if args.rliable:
        needed += [("rliable", "plots", "--rliable"), ("scipy", "plots", "--rliable")]
    if args.ray_address is not None:
        needed.append(("ray", "ray", "--ray-address"))
    for module, extra, purpose in needed:
        try:
            require_extra(module, extra, purpose)
        except MissingExtraError as error:
            return str(error)
    return None


def check_run_folder(option: str, run: Path) -> None:
    """Refuse a run folder that does not exist or has no ``progress.csv`` (it used to be reported as a run without
    SAEIR logs).

    :param option: the option's name, e.g. ``--entropy-plot``
    :param run: the folder given
    :raises ~sb3_saeir.config.ConfigError: naming the option and the folder
    """
    if not run.is_dir():
        raise ConfigError(f"{option} {run} is not a folder; give a SAEIR run's folder (it holds progress.csv).")
    if not (run / PROGRESS_FILE).is_file():
        raise ConfigError(f"{option} {run} has no progress.csv; give the folder of a SAEIR training run.")


def _entropy_plot(run: Path) -> int:
    """``--entropy-plot``: the figure and the table of a SAEIR run (exit 2 on a folder that is not one)."""
    try:
        check_run_folder("--entropy-plot", run)
        summary = plot_system_entropy(run, run / "system_entropy.png")
    except (ConfigError, ValueError) as error:
        return _error(f"--entropy-plot {error}" if not isinstance(error, ConfigError) else str(error))
    print(f"wrote {run / 'system_entropy.png'}")
    print("| scale | fire rate (all rollouts) | fire rate (last 10%) | value entropy (first -> last rollout) |")
    print("|---|---|---|---|")
    for scale, figures in summary.items():
        print(
            f"| {scale} | {figures['fire_rate']:.2e} | {figures['fire_rate_late']:.2e} "
            f"| {figures['entropy_first']:.3f} -> {figures['entropy_last']:.3f} |"
        )
    return 0


def _main(args: argparse.Namespace) -> int:
    out = Path(args.out)
    missing = _missing_extra(args)
    if missing is not None:
        print(f"sb3_saeir.benchmark: error: {missing}", file=sys.stderr)
        return 2
    if args.entropy_plot:
        return _entropy_plot(Path(args.entropy_plot))
    problem = _check_arguments(args)
    if problem is not None:
        return _error(problem)
    try:
        params = parse_params(args.params)
        check_params_against_flags(params, {"n_envs": ("--n-games", args.n_games), "n_timesteps": ("-n", args.n_timesteps)})
        for algo in args.algos:
            for task in args.tasks:
                check_hyperparams(algo, load_hyperparams(algo, task), params)
    except (ConfigError, KeyError) as error:
        return _error(str(error.args[0] if isinstance(error, KeyError) else error))
    specs = plan_runs(args, params)
    if not args.report_only:
        try:
            check_runs_build(specs, out)
        except ConfigError as error:
            return _error(str(error))
    mismatches = [(spec, stored_spec_differences(run_folder(out, spec), spec_record(spec))) for spec in specs]
    mismatches = [(spec, differences) for spec, differences in mismatches if differences]
    if mismatches and (args.report_only or not args.rerun_changed):
        print(refusal(out, mismatches, args.report_only), file=sys.stderr)
        return 2
    busy = folders_in_use([run_folder(out, spec) for spec in specs]) if not args.report_only else []
    if busy:
        return _error(busy[0] + (f" ({len(busy) - 1} more run folders of this command are in use)" if len(busy) > 1 else ""))
    moved = {spec.name for spec, _ in mismatches}  # --rerun-changed: moved aside, trained anew
    going_on = [spec for spec in specs if spec.name not in moved]
    unwritable = unwritable_runs(out, going_on) if not args.report_only else []
    if unwritable:
        more = f" ({len(unwritable) - 1} more run folders cannot be written)" if len(unwritable) > 1 else ""
        return _error(unwritable[0] + more)
    failures: list[str] = []
    if not args.report_only:
        out.mkdir(parents=True, exist_ok=True)
        prepare_folders(out, specs, mismatches)
        start = time.time()
        results = run_all(specs, out, args.jobs, args.ray_address, args.num_threads)
        failures = [f"{RunSpec(**r['spec']).name}\n{r['error']}" for r in results if r["status"] == "failed"]
        atomic_write_text(out / "failures.txt", "\n".join(failures))
        print(f"{len(specs)} runs ({len(failures)} failed) in {time.time() - start:.0f} s")
    elif not out.is_dir():
        return _error(f"{out} does not exist: nothing to report")
    report(out, specs, args.rliable)
    print(f"results in {out}: runs.csv, table.md, curves.png" + (", aggregate.md" if args.rliable else ""))
    return 1 if failures else 0
