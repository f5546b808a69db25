"""One training run in its folder: :class:`Run` owns the protocol (:meth:`Run.execute`: find the resume point, build,
check the settings against the record, record them, train, close) and the run's evaluations, checkpoints, logger,
Ctrl-C and final save, in a :class:`~sb3_saeir.run.folder.RunFolder` that its caller claimed, found or took.
``python -m sb3_saeir.train``, the benchmark and ``python -m sb3_saeir.zoo train`` build only what differs (the
:class:`~sb3_saeir.run.record.RunSpec`, the experiment, how the model is built).

The files of a run folder: ``docs/guide/training.md``, "The run folder"; what they record and how it is read:
:mod:`sb3_saeir.run.record`.
"""

from __future__ import annotations

import errno
import shutil
import signal
import time
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv

from sb3_saeir.common.atomic import remove_stale_temporaries
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
from sb3_saeir.experiment import Experiment, evaluation_seed
from sb3_saeir.run.files import (
    CHECKPOINT_NAME,
    CONFIG_FILE,
    DONE_FILE,
    EVALUATIONS_FILE,
    FINAL_MODEL,
    MONITOR_PREFIX,
    PROGRESS_FILE,
    SEGMENTS_FILE,
    SHORTER_RUN_MODEL,
    SPEC_FILE,
)
from sb3_saeir.run.folder import RunFolder, no_space_message, unwritable_message
from sb3_saeir.run.lock import RunFolderWatch
from sb3_saeir.run.output import RunEvalCallback, RunFolderCheck, RunOutput
from sb3_saeir.run.record import (
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
    save_run_config,
    saved_timesteps,
    spec_differences,
    spec_record,
    split_rows,
    train_command,
    warn_other_version,
    write_done_file,
    write_spec_file,
)

# errno values of a write that failed for want of space.
NO_SPACE_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
# What a write into a folder made read-only (or a read-only mount) fails with.
UNWRITABLE_ERRNOS = (errno.EACCES, errno.EPERM, errno.EROFS)


class RunStoppedError(RuntimeError):
    """Training stopped by the system (a full disk): the message names the run's folder and the checkpoint to resume
    from."""


class Run:
    """One training run in its folder (the files: ``docs/guide/training.md``, "The run folder").

    Build it with the run's settings (a :class:`~sb3_saeir.run.record.RunSpec`), then :meth:`execute` it in a
    :class:`~sb3_saeir.run.folder.RunFolder` with an :class:`~sb3_saeir.experiment.Experiment`: the whole run, from
    its resume point to the final save.

    :param spec: the run's settings
    :param save_freq: agent-steps between checkpoints (0: at every rollout start)
    :param keep_checkpoints: checkpoints kept (the newest; ``None``: all, as SB3's ``CheckpointCallback``)
    :param continue_model: the model was loaded to be trained on (``-i``): its agent-step count goes on
    :param name: the run's name in what it says (the benchmark's runs, side by side; ``""``: a command's one run)
    """

    def __init__(
        self,
        spec: RunSpec,
        save_freq: int = 0,
        keep_checkpoints: int | None = None,
        continue_model: bool = False,
        name: str = "",
    ) -> None:
        self.spec = spec
        self.save_freq = save_freq
        self.keep_checkpoints = keep_checkpoints
        self.continue_model = continue_model
        self.name = name
        self.start_timesteps = 0  # the model's agent-steps when this segment starts (from :meth:`execute`'s set-up)
        self.target_timesteps = spec.n_timesteps  # the model's agent-steps when the run ends (the same)
        self.folder = Path()  # the run folder's path, from :meth:`execute`
        self.log: Callable[[str], None] = print  # printed, and appended to the folder's resume.log from :meth:`execute`
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
        self.stop_signal: int | None = None  # the first stop signal (Ctrl-C, SIGTERM, SIGHUP) of a command line's run
        self.stopping_now = False  # the same signal came again: the run stops at once (:meth:`_stop_at_once`)
        self.stopped_at_once: Path | None = None
        self.trained = False  # the training part has ended (what is left: the final evaluation and save)
        self.end_state: dict[str, Any] | None = None  # the resume state of the last step, once trained
        self.final_evaluation_left_out = False  # a second stop signal came during the final evaluation
        self.watch: RunFolderWatch | None = None
        self.shorter_run_done: dict[str, Any] | None = None  # at an extension: the done.json of the shorter run

    # ------------------------------------------------------------------------------------------------ the whole run
    def execute(
        self,
        folder: RunFolder,
        experiment: Experiment,
        build: Callable[[Experiment, VecEnv], object] | None = None,
        output: RunOutput | None = None,
    ) -> Path:
        """The whole run in ``folder``, which its caller holds: find where it continues (:meth:`check_resumable` for
        a run that ``--resume`` continues; else :meth:`open`, after :meth:`check_budget` for a folder with a record),
        make the training env (:meth:`make_env`), build or load the model on it, refuse other settings than the
        record's (:meth:`check_settings`); then, nothing having been written before, record the settings
        (:meth:`write_spec`), :meth:`start` and :meth:`train`. The experiment is closed at the end, or when the run is
        refused.

        :param folder: the run's folder, locked, its record read (:class:`~sb3_saeir.run.folder.RunFolder`)
        :param experiment: the run's experiment (its model is built here, unless it has one: a model rl-zoo3 built)
        :param build: builds (or loads) the model on the run's env, ``build(experiment, env)``; a bad setting raises.
            Default: :meth:`~sb3_saeir.experiment.Experiment.build`, unless the experiment has a model
        :param output: how the run shows itself (default: quietly; its ``announce`` is called once the run is set up
            and checked, before anything is written)
        :return: the final model's path
        :raises ~sb3_saeir.config.ConfigError: for a run that cannot be continued, a model that cannot be built, or
            other settings than the record's
        """
        self.folder = folder.path
        self.log = RunLog(folder.path, self.name)
        self._set_up(experiment, build, folder)
        self.output = output if output is not None else RunOutput()
        try:
            with self._stop_signals():
                try:
                    if self.output.announce is not None:
                        self.output.announce(self, experiment)
                    self.write_spec()
                    self.start(experiment, self.output)
                    return self.train()
                except KeyboardInterrupt:
                    if not self.stopping_now:
                        raise
                    return self._stop_at_once()
        finally:
            experiment.close()
            if self.watch is not None:
                self.watch.close()

    def _set_up(self, experiment: Experiment, build: Callable[[Experiment, VecEnv], object] | None, folder: RunFolder) -> None:
        """:meth:`execute`'s checks, before anything is written: the resume point, the env and the model (what cannot
        be built is a :class:`~sb3_saeir.config.ConfigError`), the settings; the experiment is closed when one
        refuses."""
        try:
            if folder.resumed and folder.record is not None:
                self.check_resumable(folder.record)
            else:
                if folder.record is not None:
                    self.check_budget(folder.record)
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
            if folder.resumed and folder.record is not None:
                self.check_settings(folder.record, folder.by_path)
            self._set_bounds(experiment)
        except BaseException:
            experiment.close()
            raise

    def _set_bounds(self, experiment: Experiment) -> None:
        """Where this segment starts and the run ends, in the model's agent-steps: from the resume point, else from 0
        (or a ``-i`` model's count) plus the budget."""
        assert experiment.model is not None
        if self.resume is not None:
            self.start_timesteps = self.resume.steps
            self.target_timesteps = self.resume.total_timesteps(self.spec.n_timesteps)
        else:
            self.start_timesteps = experiment.model.num_timesteps if self.continue_model else 0
            self.target_timesteps = self.start_timesteps + self.spec.n_timesteps

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
        # the shorter run's done.json, read (a damaged one refused) before anything is written; the extension records it
        self.shorter_run_done = read_done_file(self.folder) if self.extended_from is not None else None
        warn_other_version(self.folder, stored)

    def check_resumable(self, stored: dict[str, Any]) -> None:
        """Find where ``--resume`` continues the run (:meth:`open`: its newest checkpoint that loads, or its final
        model); refuse a smaller budget than the record's (:meth:`check_budget`), a run with nothing to resume from,
        or a finished one whose budget the command does not raise.

        :param stored: the run's settings record (:func:`~sb3_saeir.run.record.stored_record`)
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
                    "state (a run stopped at once by a second Ctrl-C or stop signal before its first checkpoint, or one "
                    f"of an older version): continue that model with -i {final} instead (a fresh state)."
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

        :param stored: the run's settings record (:func:`~sb3_saeir.run.record.stored_record`)
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
        (:func:`~sb3_saeir.run.record.extension_record`) and keep the shorter run's final model as
        ``<task>_<steps>_steps.zip`` (its ``done.json`` goes into the record)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        if self.extended_from is not None and self.stored is not None:
            self._record_extension(self.stored)
        if not (self.folder / SPEC_FILE).is_file():
            write_spec_file(self.folder, spec_record(self.spec))
        params_path = self.folder / self.spec.task
        if not (params_path / CONFIG_FILE).is_file():
            params_path.mkdir(exist_ok=True)
            save_run_config(params_path, self.spec.resolved_config(), train_command(self.spec))

    def _record_extension(self, stored: dict[str, Any]) -> None:
        final = self.final_model
        finished = self.shorter_run_done
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
        for stale in remove_stale_temporaries(self.folder):  # a killed segment's unfinished writes
            self.log(f"removed {stale.name}, a file a killed process was writing")
        self.clock = SegmentClock(self.folder / SEGMENTS_FILE, done_steps or 0, self.log)
        self.watch = RunFolderWatch(self.folder)
        rollout = int(getattr(model, "n_steps", 1)) * experiment.env.num_envs
        expected_rows = state.get("progress_rows") if state is not None else None
        offset = (done_steps or 0) // rollout
        writers = self.output.writers(model, self.continued)
        model.set_logger(progress_logger(self.folder / PROGRESS_FILE, done_steps, offset, writers, expected_rows, self.log))
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
        self.callbacks[:0] = [RunFolderCheck(self.check_folder), self.checkpoints]
        if self.stop_signal is not None:  # a stop asked for while the run was set up: at the first rollout start
            self.checkpoints.request_stop(self.stop_signal)
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
                experiment.learn(
                    remaining,
                    callbacks=[*self.callbacks, *self.output.callbacks],
                    progress_bar=self.output.progress_bar,
                    reset_num_timesteps=resume is None and not self.continue_model,
                )
                if checkpoints.stopped_at is None:
                    end_state = capture_resume_state(model, checkpoints.extras)
            self.trained = checkpoints.stopped_at is None
            self.end_state = end_state
            if checkpoints.stopped_at is None and self.evaluator is not None:
                rows = self.evaluator.rows
                if not rows or rows[-1]["timesteps"] < model.num_timesteps:
                    self.evaluator.init_callback(model)
                    self.evaluator.evaluate()  # the final evaluation
            return self._finish(end_state)
        except OSError as error:
            change = self.folder_change()
            if change is not None:
                message = self.moved_message(change)
            elif error.errno in NO_SPACE_ERRNOS:
                message = no_space_message(self.folder, error)
            elif error.errno in UNWRITABLE_ERRNOS:
                message = unwritable_message(self.folder, error, model.num_timesteps)
            else:
                raise
            self._close_quietly()
            raise RunStoppedError(message) from None

    @contextmanager
    def _stop_signals(self) -> Iterator[None]:
        """For a command line's run, in the main thread, from its set-up to its final save: the first of
        :data:`STOP_SIGNALS` (Ctrl-C, ``kill``'s SIGTERM, a closed terminal's SIGHUP) asks for a checkpoint at the next
        rollout start and a stop there (after the training part: the run finishes); a second stops at once
        (``KeyboardInterrupt``: :meth:`_stop_at_once`); later ones wait for that save."""
        if not self.output.command_line:
            yield
            return

        def handler(signum: int, frame: Any) -> None:
            name = signal_name(signum)
            if self.stopping_now:
                print(f"\n{name}: saving the model, then stopping")
                return
            if self.stop_signal is not None:
                self.stopping_now = True
                raise KeyboardInterrupt
            self.stop_signal = signum
            if self.trained:
                print(f"\n{name}: the training is done; finishing the final evaluation and save ({name} again: stop now)")
                return
            if self.checkpoints is not None:
                self.checkpoints.request_stop(signum)
            print(f"\n{name}: writing a checkpoint after this rollout and update, then stopping ({name} again: stop now)")

        with handlers_installed(STOP_SIGNALS, handler):
            yield

    def _stop_at_once(self) -> Path:
        """The second stop signal: save ``<task>.zip`` where the model is (the newest checkpoint stays the resume
        point: :meth:`stop_line`)."""
        assert self.experiment is not None and self.experiment.model is not None
        if self.trained:  # during the final evaluation: the run is trained to its budget, and finishes without it
            self.final_evaluation_left_out = True
            return self._finish(self.end_state)
        path = self.experiment.save(self.final_model)
        if self.clock is not None:
            self.clock.tick(self.experiment.model.num_timesteps)
        self.stopped_at_once = path
        return path

    def stop_line(self) -> str | None:
        """The one line a command prints for a run stopped early by a signal (``None``: the run was not stopped
        early): the checkpoint ``--resume`` continues from, or for a run stopped at once before its first
        checkpoint, the model ``-i`` continues."""
        if self.final_evaluation_left_out:
            name = signal_name(self.stop_signal or signal.SIGINT)
            return (
                f"Stopped at once ({name} twice) during the final evaluation: the run is trained to its budget and "
                f"saved ({self.final_model.name}, {DONE_FILE}); its final evaluation was left out (python -m "
                "sb3_saeir.enjoy evaluates the model)."
            )
        if self.stopped_at_once is not None:
            name = signal_name(self.stop_signal or signal.SIGINT)
            steps = saved_timesteps(self.stopped_at_once)
            checkpoint, _ = newest_loading_checkpoint(self.folder)
            then = (
                f"the same command with --resume continues from the checkpoint {checkpoint}"
                if checkpoint is not None
                else f"no checkpoint was written yet: continue that model with -i {self.stopped_at_once} (a fresh "
                "state), or start the run again"
            )
            return f"Stopped at once ({name} twice): saved {self.stopped_at_once} at {steps or 0:,} agent-steps; {then}."
        if self.checkpoints is not None and self.checkpoints.stopped_at is not None:
            return f"Stopped at the checkpoint {self.checkpoints.stopped_at}: the same command with --resume continues it."
        return None

    def _finish(self, end_state: dict[str, Any] | None) -> Path:
        """Save ``<task>.zip`` (with ``end_state``, the resume state of its last step, when there is one); when the
        budget is reached, write ``done.json`` and drop the kept checkpoints (the final model is the resume point of a
        larger budget)."""
        assert self.experiment is not None and self.experiment.model is not None and self.clock is not None
        self.check_folder()
        model = self.experiment.model
        if end_state is not None:
            path = self.final_model
            save_checkpoint(model, path, state=end_state)
        else:
            path = self.experiment.save(self.final_model)
        steps = model.num_timesteps
        self.clock.tick(steps)
        if steps >= self.target_timesteps:
            start = self.target_timesteps - self.spec.n_timesteps  # a -i model's count before the run (else 0)
            self.done = done_record(self.clock.total_s, len(self.clock.segments), steps - start, start)
            write_done_file(self.folder, self.done)
            if self.keep_checkpoints is not None:
                for checkpoint in checkpoint_steps(self.folder).values():
                    checkpoint.unlink(missing_ok=True)
        return path

    def check_folder(self) -> None:
        """Stop the run before it writes, when its folder was moved or deleted while it trained (:meth:`start`'s
        :class:`~sb3_saeir.run.lock.RunFolderWatch`): a :class:`RunStoppedError` that says what happened and
        what can be resumed (:meth:`moved_message`). The old path is never made again."""
        change = self.folder_change()
        if change is not None:
            self._close_quietly()
            raise RunStoppedError(self.moved_message(change))

    def folder_change(self) -> str | None:
        """What happened to the run's folder while it trained: moved or deleted
        (:meth:`~sb3_saeir.run.lock.RunFolderWatch.change`), or emptied (being deleted file by file: its
        ``spec.json`` is gone); ``None`` while it is in place."""
        change = self.watch.change() if self.watch is not None else None
        if change is None and self.watch is not None and not (self.folder / SPEC_FILE).is_file():
            change = f"emptied ({SPEC_FILE} deleted)"
        return change

    def moved_message(self, change: str) -> str:
        """One line for a run whose folder was moved or deleted while it trained (``change``:
        :meth:`~sb3_saeir.run.lock.RunFolderWatch.change`)."""
        assert self.experiment is not None and self.experiment.model is not None
        stopped = (
            f"the run folder {self.folder} was {change} while the run trained: the run stopped at "
            f"{self.experiment.model.num_timesteps:,} agent-steps and wrote nothing more (the old path is not made again)"
        )
        if change == "deleted" or change.startswith("emptied"):
            return f"{stopped}; nothing is left to resume: start the run again."
        now = self.watch.current_path() if self.watch is not None else None
        checkpoint = newest_loading_checkpoint(now)[0] if now is not None else None
        if now is None or checkpoint is None:
            return f"{stopped}; it has no checkpoint to resume from: start the run again."
        return (
            f"{stopped}; its newest checkpoint is {checkpoint}: move the folder back to {self.folder} and run the "
            f"same command (train and zoo train: with --resume, or --resume {now} where it is now)."
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
