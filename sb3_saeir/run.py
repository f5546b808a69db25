"""One training run in its folder: :class:`Run` owns the protocol (:meth:`Run.execute`: lock the folder, find the
resume point, build, check the settings against the record, record them, train, close) and the run's evaluations,
checkpoints, logger, Ctrl-C and final save. ``python -m sb3_saeir.train``, the benchmark and ``python -m sb3_saeir.zoo
train`` build only what differs (the :class:`~sb3_saeir.run_record.RunSpec`, the experiment, how the model is built).

The files of a run folder: ``docs/guide/training.md``, "The run folder"; what they record and how it is read:
:mod:`sb3_saeir.run_record`.
"""

from __future__ import annotations

import errno
import inspect
import shutil
import sys
import time
import zipfile
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import KVWriter
from stable_baselines3.common.utils import configure_logger
from stable_baselines3.common.vec_env import VecEnv

from sb3_saeir.common.run_files import (
    CHECKPOINT_NAME,
    CONFIG_FILE,
    DONE_FILE,
    EVALUATIONS_FILE,
    FINAL_MODEL,
    MONITOR_PREFIX,
    SEGMENTS_FILE,
    SHORTER_RUN_MODEL,
    SPEC_FILE,
)
from sb3_saeir.common.run_lock import RunFolderLock
from sb3_saeir.common.run_state import (
    RunCheckpointCallback,
    SegmentClock,
    capture_resume_state,
    describe_resume,
    is_exact,
    load_resume_state,
    progress_logger,
    save_checkpoint,
)
from sb3_saeir.common.stop_signals import STOP_SIGNALS, handlers_installed, signal_name
from sb3_saeir.common.vec_env import MultiAgentVecMonitor
from sb3_saeir.config import ConfigError
from sb3_saeir.evaluation import MultiAgentEvalCallback
from sb3_saeir.experiment import Experiment, evaluation_seed
from sb3_saeir.run_record import (
    ResumePoint,
    RunLog,
    RunSpec,
    checkpoint_steps,
    done_record,
    extended_budget,
    extension_record,
    keep_damaged_checkpoints,
    newest_loading_checkpoint,
    read_done_file,
    same_row,
    save_run_config,
    saved_timesteps,
    spec_differences,
    spec_record,
    split_rows,
    warn_other_version,
    write_done_file,
    write_rows,
    write_spec_file,
)

# errno values of a write that failed for want of space.
NO_SPACE_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


class RunStoppedError(RuntimeError):
    """Training stopped by the system (a full disk): the message names the run's folder and the checkpoint to resume
    from."""


# ---------------------------------------------------------------------------------------------------- evaluation
class RunEvalCallback(MultiAgentEvalCallback):
    """A run's evaluations: at the first agent-step count >= k * ``eval_freq`` (on the grid whether or not the run was
    resumed), each on the same episodes (the eval env is reseeded with ``eval_seed`` first); each becomes a row of
    ``evaluations.csv``, and ``evaluations.npz`` and ``best_model.zip`` are kept as SB3's ``EvalCallback`` keeps them.

    :param eval_env: the evaluation env
    :param spec: the run
    :param folder: the run's folder
    :param rows: evaluation rows already recorded (kept on resume)
    :param n_agents: agents per game (``env_steps = agent-steps / n_agents``)
    :param main_metric: the task's main metric
    :param eval_seed: seed given to the eval env before every evaluation
    :param lost_rows: rows made after the checkpoint by an interrupted segment, by agent-steps: they are re-done
    :param clock: the run's wall-time record
    :param log: the run's log
    :param verbose: print each evaluation's main metric
    """

    def __init__(
        self,
        eval_env: Any,
        spec: RunSpec,
        folder: Path,
        rows: list[dict[str, Any]],
        n_agents: int,
        main_metric: str,
        eval_seed: int,
        lost_rows: dict[int, dict[str, Any]],
        clock: SegmentClock,
        log: Callable[[str], None],
        verbose: int = 0,
    ) -> None:
        super().__init__(
            eval_env,
            spec.eval_episodes,
            spec.eval_freq,
            main_metric=main_metric,
            log_path=str(folder),
            best_model_save_path=str(folder),
            verbose=verbose,
        )
        self.spec = spec
        self.evaluations_path = folder / EVALUATIONS_FILE
        self.rows = rows
        self.n_agents = n_agents
        self.eval_seed = eval_seed
        self.lost_rows = dict(lost_rows)
        self.clock = clock
        self.log = log
        self.last_eval_timestep = int(rows[-1]["timesteps"]) if rows else 0
        self.next_eval = self.grid_after(self.last_eval_timestep) if rows else 0

    def grid_after(self, steps: int) -> int:
        """The first multiple of ``eval_freq`` after ``steps`` agent-steps."""
        return (steps // self.eval_freq + 1) * self.eval_freq if self.eval_freq > 0 else sys.maxsize

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_eval:
            self.last_eval_timestep = self.num_timesteps
            return self.evaluate()
        return True

    def evaluate(self) -> bool:
        self.num_timesteps = self.model.num_timesteps
        self.eval_env.seed(self.eval_seed)  # every evaluation plays the same episodes
        keep_going = super().evaluate()
        spec = self.spec
        row: dict[str, Any] = {"algo": spec.algo, "task": spec.task, "seed": spec.seed, "timesteps": self.num_timesteps}
        row["env_steps"] = self.num_timesteps // self.n_agents
        row.update({key: value for key, value in self.last_summary.items() if not key.endswith("_std")})
        row.update({key: value for key, value in self.last_summary.items() if key.endswith("_std")})
        self.next_eval = self.grid_after(self.num_timesteps)
        lost = self.lost_rows.pop(self.num_timesteps, None)
        if lost is not None:
            outcome = "identical to" if same_row(row, lost) else "different from"
            self.log(f"evaluation at {self.num_timesteps} agent-steps re-done: {outcome} the interrupted segment's")
        self.rows.append(row)
        write_rows(self.evaluations_path, self.rows)
        self.clock.tick(self.num_timesteps)
        return keep_going

    def get_resume_state(self) -> dict[str, Any]:
        return {**super().get_resume_state(), "next_eval": self.next_eval}

    def set_resume_state(self, state: dict[str, Any]) -> None:
        super().set_resume_state(state)
        self.next_eval = int(state.get("next_eval", self.grid_after(self.last_eval_timestep)))


# ---------------------------------------------------------------------------------------------------- the run
# ---------------------------------------------------------------------------------------------------- the run


@dataclass
class RunOutput:
    """How a run shows itself while it trains (default: quietly, as the benchmark's runs).

    :param command_line: a command line's run: SB3's stdout (``verbose`` >= 1) and tensorboard (the model's
        ``tensorboard_log``) writers besides ``progress.csv``, the latter going on in the latest ``<tb_log_name>_<N>``
        folder when the run or its model goes on (as SB3's ``reset_num_timesteps=False`` does); and the first Ctrl-C
        writes a checkpoint and stops cleanly (main thread only)
    :param verbose: the verbosity (>= 1: each evaluation printed too)
    :param progress_bar: SB3's progress bar
    :param callbacks: more callbacks of the caller (an ETA line, ...)
    """

    command_line: bool = False
    verbose: int = 0
    progress_bar: bool = False
    callbacks: list[BaseCallback] = field(default_factory=list)

    def writers(self, model: Any, continued: bool) -> list[KVWriter]:
        """The logger's writers besides ``progress.csv`` (none but for a command line's run).

        :param model: the run's model
        :param continued: the run or its model goes on (``--resume``, ``-i``)
        """
        if not self.command_line:
            return []
        tb_log_name = inspect.signature(type(model).learn).parameters["tb_log_name"].default
        sb3_logger = configure_logger(self.verbose, model.tensorboard_log, tb_log_name, reset_num_timesteps=not continued)
        return [output for output in sb3_logger.output_formats if type(output).__name__ != "CSVOutputFormat"]


class Run:
    """One training run in its folder (the files: ``docs/guide/training.md``, "The run folder").

    Build it with a folder and a :class:`~sb3_saeir.run_record.RunSpec`, then :meth:`execute` it with an
    :class:`~sb3_saeir.experiment.Experiment`: the whole run, from the folder's lock to the final save. Its steps
    (:meth:`open` or :meth:`check_resumable`, :meth:`make_env`, :meth:`check_settings`, :meth:`write_spec`,
    :meth:`start`, :meth:`train`) are public for a caller that needs them one by one.

    :param folder: the run's folder
    :param spec: the run's settings
    :param save_freq: agent-steps between checkpoints (0: at every rollout start)
    :param keep_checkpoints: checkpoints kept (the newest; ``None``: all, as SB3's ``CheckpointCallback``)
    :param command: the command as ``<task>/args.yml`` records it (rl-zoo3's file)
    :param continue_model: the model was loaded to be trained on (``-i``): its agent-step count goes on
    :param log: where the run says what happens (default: printed and appended to ``resume.log``)
    """

    def __init__(
        self,
        folder: Path,
        spec: RunSpec,
        save_freq: int = 0,
        keep_checkpoints: int | None = None,
        command: dict[str, Any] | None = None,
        continue_model: bool = False,
        log: Callable[[str], None] | None = None,
    ) -> None:
        self.folder = Path(folder)
        self.spec = spec
        self.save_freq = save_freq
        self.keep_checkpoints = keep_checkpoints
        self.command = dict(command or {})
        self.continue_model = continue_model
        self.target_timesteps = spec.n_timesteps
        self.log = log if log is not None else RunLog(self.folder)
        self.resume: ResumePoint | None = None
        self.stored: dict[str, Any] | None = None
        self.extended_from: int | None = None
        self.skipped: list[tuple[Path, str]] = []
        self.experiment: Experiment | None = None
        self.checkpoints: RunCheckpointCallback | None = None
        self.evaluator: RunEvalCallback | None = None
        self.clock: SegmentClock | None = None
        self.callbacks: list[BaseCallback] = []
        self.output = RunOutput()
        self.done: dict[str, Any] | None = None

    # ------------------------------------------------------------------------------------------------ the whole run
    def execute(
        self,
        experiment: Experiment,
        build: Callable[[Experiment, VecEnv], object] | None = None,
        resumed: dict[str, Any] | None = None,
        by_path: bool = False,
        lock: RunFolderLock | None = None,
        output: RunOutput | None = None,
        announce: Callable[[Run], None] | None = None,
    ) -> Path:
        """The whole run, holding the folder's lock: find where it continues (:meth:`check_resumable` for a run that
        ``--resume`` continues, else :meth:`open`), make the training env (:meth:`make_env`), build or load the model
        on it, refuse other settings than the record's (:meth:`check_settings`); then, nothing having been written
        before, record the settings (:meth:`write_spec`), :meth:`start` and :meth:`train`. The experiment is closed at
        the end, or when the run is refused.

        :param experiment: the run's experiment (its model is built here, unless it has one: a model rl-zoo3 built)
        :param build: builds (or loads) the model on the run's env, ``build(experiment, env)``; a bad setting raises.
            Default: :meth:`~sb3_saeir.experiment.Experiment.build`, unless the experiment has a model
        :param resumed: the settings record of the run that ``--resume`` continues
            (:func:`~sb3_saeir.run_record.stored_record`); ``None``: a new run, or one that goes on from the checkpoint
            its folder has, if any (the benchmark, after :meth:`check_budget`)
        :param by_path: ``--resume`` gave the run's folder by its path (``-f`` is not compared)
        :param lock: the folder's lock, when the caller holds it already (it read the run's record under it; it gives
            it back); ``None``: taken here and given back at the end
        :param output: how the run shows itself (default: quietly)
        :param announce: called once the run is set up and checked, before anything is written (what a command says
            about the run)
        :return: the final model's path
        :raises ~sb3_saeir.config.ConfigError: for a run that cannot be continued, a model that cannot be built, or
            other settings than the record's
        :raises ~sb3_saeir.common.run_lock.RunFolderInUseError: when another process trains the run
        """
        with ExitStack() as held:
            if lock is None:
                held.enter_context(RunFolderLock(self.folder))
            self._set_up(experiment, build, resumed, by_path)
            try:
                if announce is not None:
                    announce(self)
                self.write_spec()
                self.start(experiment, output)
                return self.train()
            finally:
                experiment.close()

    def _set_up(
        self,
        experiment: Experiment,
        build: Callable[[Experiment, VecEnv], object] | None,
        resumed: dict[str, Any] | None,
        by_path: bool,
    ) -> None:
        """:meth:`execute`'s checks, before anything is written: the resume point, the env and the model (what cannot
        be built is a :class:`~sb3_saeir.config.ConfigError`), the settings; the experiment is closed when one
        refuses."""
        try:
            if resumed is not None:
                self.check_resumable(resumed)
            else:
                self.open()
            try:
                env = self.make_env(experiment)
                if build is not None:
                    build(experiment, env)
                elif experiment.model is None:
                    experiment.build(env=env)
            except (ValueError, TypeError, KeyError, zipfile.BadZipFile) as error:
                if isinstance(error, ConfigError):
                    raise
                message = error.args[0] if isinstance(error, KeyError) and error.args else str(error)
                algo, task = self.spec.algo, self.spec.task
                raise ConfigError(f"cannot build {algo} on {task} with these settings: {message}") from error
            if resumed is not None:
                self.check_settings(resumed, by_path)
        except BaseException:
            experiment.close()
            raise

    @property
    def continued(self) -> bool:
        """Whether the run or its model goes on (``--resume``, ``-i``): the tensorboard writer continues too."""
        return self.resume is not None or self.continue_model

    # ------------------------------------------------------------------------------------------------ settings
    @property
    def final_model(self) -> Path:
        """The run's final model, ``<task>.zip`` (with the resume state of its last step: :meth:`train`)."""
        return self.folder / FINAL_MODEL.format(task=self.spec.task)

    def check_budget(self, stored: dict[str, Any]) -> None:
        """Compare the command's budget with the run's record: the same, or larger (the run is trained longer, an
        extension: :attr:`extended_from` is the record's budget, and :meth:`write_spec` records the extension); a
        smaller one is refused.

        :param stored: the run's settings record
        :raises ~sb3_saeir.config.ConfigError: for a smaller budget
        """
        budget = stored.get("n_timesteps")
        if isinstance(budget, (int, float)) and self.spec.n_timesteps < budget:
            raise ConfigError(
                f"--resume: -n {self.spec.n_timesteps:,} is smaller than the budget of the run in {self.folder} "
                f"({int(budget):,} agent-steps): a run is not shortened. Give -n {int(budget)} (or more, to train it "
                "longer)."
            )
        self.stored = stored
        self.extended_from = extended_budget(stored, self.spec.n_timesteps)
        warn_other_version(self.folder, stored)

    def check_resumable(self, stored: dict[str, Any]) -> None:
        """Find where ``--resume`` continues the run (:meth:`open`: its newest checkpoint that loads, or its final
        model); refuse a smaller budget than the record's (:meth:`check_budget`), a run with nothing to resume from,
        or a finished one whose budget the command does not raise.

        :param stored: the run's settings record (:func:`~sb3_saeir.run_record.stored_record`)
        :raises ~sb3_saeir.config.ConfigError: naming the run and the fix
        """
        self.check_budget(stored)
        folder, final = self.folder, self.final_model
        point = self.open()
        if point is None and not self.skipped:
            pattern = CHECKPOINT_NAME.format(steps="<steps>")
            if final.is_file():
                raise ConfigError(
                    f"--resume: {folder} has no checkpoint ({pattern}) and its final model {final.name} holds no resume "
                    f"state (written by an older version): continue that model with -i {final} instead (a fresh state)."
                )
            raise ConfigError(
                f"--resume: {folder} has no checkpoint ({pattern}) and no final model: nothing to resume from (a run "
                "writes checkpoints with --save-freq and on Ctrl-C). Start a new run without --resume."
            )
        if point is None:
            problems = "; ".join(f"{path.name}: {why}" for path, why in self.skipped)
            fix = f"continue its model with -i {final}" if final.is_file() else "start a new run without --resume"
            raise ConfigError(f"--resume: no checkpoint of {folder} loads ({problems}); {fix}.")
        if point.state is None:
            raise ConfigError(
                f"--resume: {point.checkpoint} has no resume state (written by an older version): continue it with -i instead."
            )
        final_steps = saved_timesteps(final) if final.is_file() else None
        target = point.total_timesteps(self.spec.n_timesteps)
        if point.steps >= target or (final_steps is not None and final_steps >= target):
            raise ConfigError(
                f"--resume: {folder} is finished ({final.name} at {final_steps or point.steps:,} agent-steps, its budget "
                f"{self.spec.n_timesteps:,}); give a larger -n to train it longer."
            )

    def check_settings(self, stored: dict[str, Any], by_path: bool) -> None:
        """Refuse to continue the run with other settings than its record's (one line per setting; ``-f`` is not
        compared for a run given by its folder's path; a larger budget is an extension, :meth:`check_budget`).

        :param stored: the run's settings record (:func:`~sb3_saeir.run_record.stored_record`)
        :param by_path: the run was given by its folder's path (``--resume FOLDER``)
        :raises ~sb3_saeir.config.ConfigError: naming what differs and the fix
        """
        differences = spec_differences(stored, spec_record(self.spec), ignored=("-f",) if by_path else ())
        if differences:
            moved = any(difference.startswith("-f ") for difference in differences)
            hint = f" If the run folder was moved, give its path instead: --resume {self.folder}." if moved else ""
            raise ConfigError(
                f"--resume: {self.folder} was made with other settings: {'; '.join(differences)}. Fix: resume with the "
                f"command that started it, or start a new run without --resume.{hint}"
            )

    def write_spec(self) -> None:
        """Write ``spec.json`` (unless the folder has one), ``<task>/config.yml`` and ``<task>/args.yml``; for an
        extension (:meth:`check_budget`), record it in ``spec.json``
        (:func:`~sb3_saeir.run_record.extension_record`) and keep the shorter run's final model as
        ``<task>_<steps>_steps.zip`` (its ``done.json`` goes into the record)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        if self.extended_from is not None and self.stored is not None:
            self._record_extension(self.stored)
        if not (self.folder / SPEC_FILE).is_file():
            write_spec_file(self.folder, spec_record(self.spec))
        params_path = self.folder / self.spec.task
        if not (params_path / CONFIG_FILE).is_file():
            params_path.mkdir(exist_ok=True)
            save_run_config(params_path, self.spec.resolved_config(), self.command)

    def _record_extension(self, stored: dict[str, Any]) -> None:
        final = self.final_model
        finished = read_done_file(self.folder)
        if finished is not None and final.is_file():
            kept = final.with_name(SHORTER_RUN_MODEL.format(task=self.spec.task, steps=saved_timesteps(final)))
            if not kept.exists():
                shutil.copy2(final, kept)
        record = extension_record(stored, self.spec.n_timesteps, finished)
        (self.folder / DONE_FILE).unlink(missing_ok=True)  # first: a run killed before the new record is not finished
        write_spec_file(self.folder, record)
        self.log(f"trained longer: budget {self.extended_from:,} -> {self.spec.n_timesteps:,} agent-steps")
        self.stored, self.extended_from = record, None

    # ------------------------------------------------------------------------------------------------ start
    def open(self) -> ResumePoint | None:
        """Find where the run continues: its newest checkpoint that loads, or its final model if that is newer and
        holds a resume state (:attr:`resume`; ``None``: the run starts from the beginning). The newer ones that do not
        load are :attr:`skipped`; :meth:`start` names them in the log and moves them aside. Nothing is written here.

        :return: the resume point
        """
        checkpoint, skipped = newest_loading_checkpoint(self.folder, self.final_model)
        self.skipped = skipped
        self.resume = ResumePoint(checkpoint, load_resume_state(checkpoint), tuple(skipped)) if checkpoint else None
        return self.resume

    def make_env(self, experiment: Experiment) -> VecEnv:
        """The run's training env: the experiment's, monitored into ``games.monitor.csv`` (continued on resume); or
        the env of a model built elsewhere (rl-zoo3's, in the monitor of
        :func:`~sb3_saeir.zoo.registration.games_to_agents`), whose monitor then continues its file on resume."""
        if experiment.env is not None:
            if isinstance(experiment.env, MultiAgentVecMonitor) and self.resume is not None:
                experiment.env.append = True
            return experiment.env
        return MultiAgentVecMonitor(
            experiment.make_env(),
            str(self.folder / MONITOR_PREFIX),
            env_id=self.spec.task,
            append=self.resume is not None,
            log=self.log,
        )

    def start(self, experiment: Experiment, output: RunOutput | None = None) -> None:
        """Set the run up on ``experiment``, whose model is built (or loaded) on :meth:`make_env`'s env: load the
        resume point's checkpoint, continue the logger, the wall-time record and the evaluations, make the
        checkpoints.

        :param experiment: the run's experiment, built
        :param output: how the run shows itself (default: quietly)
        """
        assert experiment.model is not None and experiment.env is not None
        self.experiment = experiment
        self.output = output if output is not None else RunOutput()
        resume = self.resume
        if self.skipped:
            self._keep_skipped_aside()
        elif resume is None and (self.folder / EVALUATIONS_FILE).is_file():
            self.log("nothing to resume from (no checkpoint, no final model with a resume state): the run starts over")
        state = None
        if resume is not None:
            model = experiment.model
            state = experiment.resume(resume.checkpoint, device=str(model.device), tensorboard_log=model.tensorboard_log)
            state = self._for_this_env(state)
            self.log(f"resumed from the checkpoint at {resume.steps} agent-steps ({resume.checkpoint.name})")
            for message in describe_resume(experiment.model, state):
                self.log(message)
        model = experiment.model
        done_steps = resume.steps if resume is not None else None
        if resume is not None:
            self.target_timesteps = resume.total_timesteps(self.spec.n_timesteps)
        else:
            self.target_timesteps = (model.num_timesteps if self.continue_model else 0) + self.spec.n_timesteps
        self.clock = SegmentClock(self.folder / SEGMENTS_FILE, done_steps or 0)
        rollout = int(getattr(model, "n_steps", 1)) * experiment.env.num_envs
        expected_rows = state.get("progress_rows") if state is not None else None
        offset = (done_steps or 0) // rollout
        writers = self.output.writers(model, self.continued)
        model.set_logger(progress_logger(self.folder, done_steps, offset, writers, expected_rows, self.log))
        extras: dict[str, Any] = {}
        self.callbacks = []
        if self.spec.eval_freq > 0:
            self.evaluator = self._evaluator(experiment, done_steps)
            extras["evaluation"] = self.evaluator
            self.callbacks.append(self.evaluator)
        self.checkpoints = RunCheckpointCallback(
            self.folder,
            CHECKPOINT_NAME,
            save_freq=self.save_freq,
            resumed_at=done_steps or 0,
            resume_state=state,
            extras=extras,
            previous_wall_s=self.clock.previous_s,
            on_checkpoint=self._on_checkpoint,
            log=self.log,
        )
        self.callbacks.insert(0, self.checkpoints)
        if resume is not None and not is_exact(model, state):  # approximate: learn() resets the env and the states
            model._last_obs = None  # type: ignore[assignment]

    def _keep_skipped_aside(self) -> None:
        """Name the checkpoints that do not load in the log and move them aside (``<name>.damaged-<UTC time>``)."""
        damaged = "; ".join(f"{path.name} does not load ({why})" for path, why in self.skipped)
        fallback = f"resuming from {self.resume.checkpoint.name}" if self.resume else "the run starts over from the beginning"
        keep_damaged_checkpoints(self.skipped)
        self.log(f"skipped the newest checkpoint(s): {damaged}; kept aside as <name>.damaged-<UTC time>; {fallback}")
        self.skipped = []

    def _for_this_env(self, state: dict[str, Any] | None) -> dict[str, Any] | None:
        """A resume state taken on the bare training env (a benchmark checkpoint of the older layout, with no monitor
        around its env) made fit for the monitored env: the monitor starts with no records."""
        assert self.experiment is not None and self.experiment.env is not None
        env = self.experiment.env
        if state is None or state["env"] is None or not isinstance(env, MultiAgentVecMonitor) or "venv" in state["env"]:
            return state
        self.log(f"the checkpoint has no monitor records: {MONITOR_PREFIX}.monitor.csv starts at the resume")
        monitor_state = {"venv": state["env"], "episodes": [], "n_finished_games": 0, "t_start": time.time()}
        return {**state, "env": monitor_state}

    def _evaluator(self, experiment: Experiment, done_steps: int | None) -> RunEvalCallback:
        assert experiment.env is not None and self.clock is not None
        eval_seed = evaluation_seed(self.spec.seed)
        rows, lost = split_rows(self.folder / EVALUATIONS_FILE, done_steps, self.log)
        return RunEvalCallback(
            experiment.make_eval_env(self.spec.eval_episodes, seed=eval_seed),
            self.spec,
            self.folder,
            rows,
            experiment.env.num_envs // experiment.n_games,
            experiment.main_metric,
            eval_seed,
            lost,
            self.clock,
            self.log,
            verbose=self.output.verbose,
        )

    def _on_checkpoint(self, steps: int) -> None:
        """After a checkpoint: record the wall time, and remove the oldest checkpoints beyond ``keep_checkpoints``."""
        assert self.clock is not None
        self.clock.tick(steps)
        if self.keep_checkpoints is None:
            return
        checkpoints = checkpoint_steps(self.folder)
        for old in sorted(checkpoints)[: -self.keep_checkpoints]:
            checkpoints[old].unlink(missing_ok=True)

    # ------------------------------------------------------------------------------------------------ train
    def train(self) -> Path:
        """Train to the budget (the first Ctrl-C, with ``stop_on_ctrl_c``: a checkpoint and a clean stop), evaluate at
        the end, save ``<task>.zip`` and, when the budget is reached, write ``done.json`` and remove the checkpoints a
        finished run no longer needs (with ``keep_checkpoints``). A full disk stops the run with a
        :class:`RunStoppedError` naming the checkpoint to resume from.

        :return: the final model's path
        """
        experiment, checkpoints = self.experiment, self.checkpoints
        assert experiment is not None and experiment.model is not None and checkpoints is not None
        model = experiment.model
        resume = self.resume
        remaining = self.target_timesteps - model.num_timesteps if resume is not None else self.spec.n_timesteps
        # the state at the last step, before the final evaluation: the final model carries it, so that a larger budget
        # continues the run exactly (as an uninterrupted run with that budget would go on from here)
        end_state = resume.state if resume is not None and remaining <= 0 else None
        try:
            if remaining > 0:
                if resume is None and self.evaluator is not None:
                    self.evaluator.init_callback(model)
                    self.evaluator.evaluate()  # the curve starts at the start
                with self._ctrl_c(checkpoints):
                    experiment.learn(
                        remaining,
                        callbacks=[*self.callbacks, *self.output.callbacks],
                        progress_bar=self.output.progress_bar,
                        reset_num_timesteps=resume is None and not self.continue_model,
                    )
                if checkpoints.stopped_at is None:
                    end_state = capture_resume_state(model, checkpoints.extras)
            if checkpoints.stopped_at is None and self.evaluator is not None:
                rows = self.evaluator.rows
                if not rows or rows[-1]["timesteps"] < model.num_timesteps:
                    self.evaluator.init_callback(model)
                    self.evaluator.evaluate()  # the final evaluation
            return self._finish(end_state)
        except OSError as error:
            if error.errno not in NO_SPACE_ERRNOS:
                raise
            self._close_quietly()
            raise RunStoppedError(self.no_space_message(error)) from None

    @contextmanager
    def _ctrl_c(self, checkpoints: RunCheckpointCallback) -> Iterator[None]:
        """For a command line's run, in the main thread: the first of :data:`STOP_SIGNALS` (Ctrl-C, ``kill``'s
        SIGTERM, a closed terminal's SIGHUP) asks for a checkpoint at the next rollout start and a stop there; a
        second stops at once (``KeyboardInterrupt``)."""
        if not self.output.command_line:
            yield
            return

        def handler(signum: int, frame: Any) -> None:
            if checkpoints.stop_requested:
                raise KeyboardInterrupt
            checkpoints.request_stop(signum)
            name = signal_name(signum)
            print(f"\n{name}: writing a checkpoint after this rollout and update, then stopping ({name} again: stop now)")

        with handlers_installed(STOP_SIGNALS, handler):
            yield

    def _finish(self, end_state: dict[str, Any] | None) -> Path:
        """Save ``<task>.zip`` (with ``end_state``, the resume state of its last step, when there is one); when the
        budget is reached, write ``done.json`` and drop the kept checkpoints (the final model is the resume point of a
        larger budget)."""
        assert self.experiment is not None and self.experiment.model is not None and self.clock is not None
        model = self.experiment.model
        if end_state is not None:
            path = self.final_model
            save_checkpoint(model, path, state=end_state)
        else:
            path = self.experiment.save(self.final_model)
        steps = model.num_timesteps
        self.clock.tick(steps)
        if steps >= self.target_timesteps:
            self.done = done_record(self.clock.total_s, len(self.clock.segments), steps)
            write_done_file(self.folder, self.done)
            if self.keep_checkpoints is not None:
                for checkpoint in checkpoint_steps(self.folder).values():
                    checkpoint.unlink(missing_ok=True)
        return path

    def no_space_message(self, error: OSError) -> str:
        """One line for a run stopped by a full disk: what failed, the run's folder, the checkpoint to resume from."""
        what = f"{error.strerror or 'no space left on the device'}" + (f" writing {error.filename}" if error.filename else "")
        checkpoint, _ = newest_loading_checkpoint(self.folder)
        if checkpoint is None:
            return (
                f"{what}: the run in {self.folder} stopped and has no checkpoint to resume from. Free some space and "
                "start it again (--save-freq writes resumable checkpoints)."
            )
        return (
            f"{what}: the run in {self.folder} stopped; its last good checkpoint is {checkpoint.name}. Free some space, "
            "then run the same command with --resume to continue from it."
        )

    def _close_quietly(self) -> None:
        """Close the run's open files (logger, monitor CSV) after a failed write: data still buffered for a full disk
        is dropped here rather than reported at exit."""
        experiment = self.experiment
        assert experiment is not None
        monitor = experiment.env
        writers = [experiment.model.logger if experiment.model is not None else None]
        writers.append(monitor.results_writer if isinstance(monitor, MultiAgentVecMonitor) else None)
        for writer in writers:
            if writer is not None:
                with suppress(OSError, ValueError):
                    writer.close()
