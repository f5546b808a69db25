"""A run's folder with one owner: :class:`RunFolder` claims a new numbered folder, finds the one ``--resume``
names, or takes a given one (the benchmark's); each way locks it, checks that a run that goes on can write it, and
reads its settings record. ``python -m sb3_saeir.train``, the benchmark and ``python -m sb3_saeir.zoo train`` hand
the folder to :meth:`~sb3_saeir.run.run.Run.execute`. rl-zoo's run numbering
(``<log-folder>/<algo>/<task>_<run>``) lives here too. The layout: ``docs/guide/training.md``, "The run folder".
"""

from __future__ import annotations

import os
import shutil
from contextlib import suppress
from pathlib import Path
from types import TracebackType
from typing import Any

from sb3_saeir.common.utils import DRAW_SEED, MAX_SEED, unwritable_folder
from sb3_saeir.config import ConfigError
from sb3_saeir.run.files import (
    ARGS_FILE,
    BEST_MODEL_FILE,
    DONE_FILE,
    EVALUATIONS_FILE,
    FINAL_MODEL,
    MONITOR_PREFIX,
    PROGRESS_FILE,
    RESUME_LOG,
    SEGMENTS_FILE,
    SPEC_FILE,
    numbered_paths,
)
from sb3_saeir.run.lock import RunFolderInUseError, RunFolderLock, RunFolderWatch
from sb3_saeir.run.record import (
    LegacyRecord,
    RunSpec,
    newest_loading_checkpoint,
    settle_spec_file,
    stored_record,
)


class RunFolder:
    """A run's folder, held by one command: locked (:class:`~sb3_saeir.run.lock.RunFolderLock`), writable, its settings
    record read. Made by one of three ways in, and a context manager that gives the lock back at the end:

    - :meth:`claim`: a new run's folder, ``<log-folder>/<algo>/<task>_<run>`` with the first unused run number, made
      exclusively (runs started together get different numbers); a command refused before the run recorded itself
      removes it again, with the parents made for it;
    - :meth:`find`: the run that ``--resume`` names (the latest, run ``N``, or a folder's path), its record read;
    - :meth:`take`: a given folder (the benchmark's ``<out>/runs/<algo>/<task>_s<seed>``), made when missing, its
      record written when it has none and compared when it has one; a finished run is told (:attr:`finished`).

    :param path: the folder
    :param lock: its lock, held
    :param record: the settings record of the run that goes on in it (``None``: a new run)
    :param resumed: ``--resume`` continues the run: it must have a resume point, and its settings are compared
    :param by_path: ``--resume`` gave the folder by its path (``-f`` is not compared)
    :param made: the folders a claim made (the run's, then its parents, deepest first), watched, to remove when the
        command is refused
    """

    def __init__(
        self,
        path: Path,
        lock: RunFolderLock,
        record: dict[str, Any] | None = None,
        resumed: bool = False,
        by_path: bool = False,
        made: dict[Path, RunFolderWatch] | None = None,
    ) -> None:
        self.path = path
        self.lock = lock
        self.record = record
        self.resumed = resumed
        self.by_path = by_path
        self.made = made or {}
        self.finished = False  # the run is finished for the command's budget (:meth:`take`)

    # ------------------------------------------------------------------------------------------------ ways in
    @classmethod
    def claim(cls, log_folder: str | Path, algo: str, task: str) -> RunFolder:
        """Make and lock a new run's folder ``<log_folder>/<algo>/<task>_<run>`` with the first unused run number
        (``os.mkdir`` fails on a folder that exists: the next number is tried).

        :param log_folder: the log folder (``-f``)
        :param algo: the method
        :param task: the task
        :raises ~sb3_saeir.config.ConfigError: when a file stands where a folder of the runs must go
        """
        parent = Path(log_folder) / algo
        in_the_way = next((path for path in (parent, *parent.parents) if path.exists() and not path.is_dir()), None)
        if in_the_way is not None:
            raise ConfigError(
                f"-f {log_folder}: {in_the_way} is a file, where a folder of the runs ({parent}) must go; move that "
                "file away or give another -f."
            )
        parents = [parent, *parent.parents]
        parents = parents[: next(index for index, folder in enumerate(parents) if folder.is_dir())]  # deepest first
        parent.mkdir(parents=True, exist_ok=True)
        number = max(numbered_paths(parent, f"{task}_"), default=0) + 1  # files counted too: their names are taken
        while True:
            path = parent / f"{task}_{number}"
            try:
                path.mkdir()
                break
            except FileExistsError:
                number += 1
        # what this command made, held open: another folder at the path (the run's was deleted and the user made one)
        # cannot take the same inode, and is left alone
        made = {folder: RunFolderWatch(folder) for folder in (path, *parents)}
        claimed = cls(path, RunFolderLock(path), made=made)
        try:
            claimed.lock.acquire()
        except BaseException:
            claimed.close(refused=True)
            raise
        return claimed

    @classmethod
    def find(
        cls, log_folder: str | Path, algo: str, task: str, resume: int | Path, legacy_record: LegacyRecord | None = None
    ) -> RunFolder:
        """Lock the run folder ``--resume`` names (:func:`find_run_folder`), check that the run can go on there
        (:func:`check_run_folder_writable`) and read its settings record (:func:`~sb3_saeir.run.record.stored_record`).

        :param log_folder: the log folder (``-f``)
        :param algo: the method of the command
        :param task: the task of the command
        :param resume: ``--resume``'s value: a run number (0: the latest) or a run folder's path
        :param legacy_record: how the command reads a run of an older version (``None``: such a run is refused)
        :raises ~sb3_saeir.config.ConfigError: naming what is missing or damaged and the fix
        :raises ~sb3_saeir.run.lock.RunFolderInUseError: when another process trains the run
        """
        path = find_run_folder(log_folder, algo, task, resume)
        found = cls(path, RunFolderLock(path).acquire(), resumed=True, by_path=isinstance(resume, Path))
        try:  # before anything is read for the run or written
            check_run_folder_writable(path)
            found.record = stored_record(path, algo, task, legacy_record)
        except BaseException:
            found.close()
            raise
        return found

    @classmethod
    def take(cls, path: Path, spec: RunSpec, copy: str = "--resume the copy") -> RunFolder:
        """Lock a given run folder (made when missing), write its settings record when it has none and refuse one
        of other settings (:func:`~sb3_saeir.run.record.settle_spec_file`), tell whether the run is :attr:`finished`
        for ``spec``'s budget, and, if not, check that the run can write the folder (a finished run's folder may stay
        read-only).

        :param path: the run's folder
        :param spec: the run's settings
        :param copy: how the command continues a copy of the run that cannot be written, for the fix
        :raises ValueError: when the folder holds a run made with other settings
        :raises ~sb3_saeir.config.ConfigError: when a run that goes on cannot write the folder
        """
        taken = cls(path, RunFolderLock(path).acquire())
        try:
            taken.record, taken.finished = settle_spec_file(path, spec)
            if not taken.finished:
                check_run_folder_writable(path, spec.name, copy)
        except BaseException:
            taken.close()
            raise
        return taken

    def resumed_seed(self, seed: int | None) -> int:
        """The seed of the run that ``--resume`` continues: its record's; the command's ``--seed`` must be that seed,
        or left out (``None``), or -1 (``DRAW_SEED``, rl-zoo3's default).

        :param seed: the command's ``--seed`` (``None``: not given)
        :raises ~sb3_saeir.config.ConfigError: when the command gives another seed, or the record's seed is not a seed
        """
        stored_seed = stored_record_seed(self.record or {}, self.path)
        if seed is not None and seed not in (stored_seed, DRAW_SEED):
            raise ConfigError(
                f"--resume: {self.path} was made with --seed {stored_seed}, not --seed {seed}: a run goes on with its own "
                f"seed. Give --seed {stored_seed} (or no --seed), or start a new run without --resume."
            )
        return stored_seed

    def close(self, refused: bool = False) -> None:
        """Give the lock back. A claimed folder of a command ``refused`` before its run recorded itself (no
        ``spec.json``) is removed with what it holds, and the parents made for it when they are left empty, each only
        while it is still the folder the claim made, in place."""
        if refused and not (self.path / SPEC_FILE).exists():
            for folder, watch in self.made.items():
                if watch.change() is not None:  # moved or deleted: not ours to remove any more
                    continue
                if folder == self.path:
                    shutil.rmtree(folder, ignore_errors=True)
                else:
                    with suppress(OSError):  # not empty: another run's
                        folder.rmdir()
        self.lock.release()
        for watch in self.made.values():
            watch.close()
        self.made = {}

    def __enter__(self) -> RunFolder:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, traceback: TracebackType | None) -> None:
        self.close(refused=error is not None)


def folders_in_use(folders: list[Path]) -> list[str]:
    """Why each run folder that another process trains cannot be trained by this command (one refusal per folder;
    the folders are only tried, not held: each run takes its folder when it starts, :meth:`RunFolder.take`).

    :param folders: the folders (those missing are left out)
    """
    busy = []
    for folder in folders:
        if not folder.is_dir():
            continue
        try:
            RunFolderLock(folder).acquire().release()
        except RunFolderInUseError as error:
            busy.append(str(error))
    return busy


# ---------------------------------------------------------------------------------------------------- run numbers
def run_numbers(log_folder: str | Path, algo: str, task: str) -> dict[int, Path]:
    """Run folders ``<log_folder>/<algo>/<task>_<run>`` by run number."""
    return {number: path for number, path in numbered_paths(Path(log_folder) / algo, f"{task}_").items() if path.is_dir()}


def find_run_folder(log_folder: str | Path, algo: str, task: str, resume: int | Path) -> Path:
    """The run folder ``--resume`` names: the latest run of ``--algo`` on ``--task`` in ``--log-folder``, run ``N``,
    or a run folder's path (a moved run).

    :param log_folder: the log folder (``-f``)
    :param algo: the method
    :param task: the task
    :param resume: ``--resume``'s value: a run number (0: the latest) or a run folder's path
    :raises ~sb3_saeir.config.ConfigError: naming what is missing and the fix
    """
    if isinstance(resume, Path):
        if resume.is_file():
            raise ConfigError(
                f"--resume {resume}: a file, not a run folder; give the folder that holds the run (such as "
                f"logs/{algo}/{task}_1, with rl_model_<steps>_steps.zip and {task}/), or a run's number."
            )
        if not resume.is_dir():
            raise ConfigError(
                f"--resume {resume}: no such folder; give a run's number, or the path of a run folder such as "
                f"logs/{algo}/{task}_1 (the folder holding rl_model_<steps>_steps.zip and {task}/)."
            )
        return resume
    runs = run_numbers(log_folder, algo, task)
    where = Path(log_folder) / algo
    if not runs:
        raise ConfigError(
            f"--resume: no run of {algo} on {task} in {where}; start one without --resume (or, for a run "
            "folder moved elsewhere, give its path: --resume FOLDER)."
        )
    number = resume or max(runs)
    if number not in runs:
        raise ConfigError(f"--resume {number}: no run {number} of {algo} on {task} in {where}; runs: {sorted(runs)}.")
    return runs[number]


def find_model(log_folder: str | Path, algo: str, task: str, exp_id: int = 0, load_best: bool = False) -> Path:
    """Path of a run's final (or best) model; ``exp_id=0`` means the latest run that has one.

    :raises FileNotFoundError: naming the folder searched
    """
    runs = run_numbers(log_folder, algo, task)
    if not runs:
        raise FileNotFoundError(f"no run of {algo} on {task} in {Path(log_folder) / algo}.")
    name = BEST_MODEL_FILE if load_best else FINAL_MODEL.format(task=task)
    if exp_id:
        if exp_id not in runs:
            raise FileNotFoundError(f"no run {exp_id} of {algo} on {task}; runs: {sorted(runs)}.")
        path = runs[exp_id] / name
        if not path.is_file():
            raise FileNotFoundError(f"{path} does not exist.")
        return path
    with_model = [runs[number] / name for number in sorted(runs) if (runs[number] / name).is_file()]
    if not with_model:
        raise FileNotFoundError(f"no run of {algo} on {task} in {Path(log_folder) / algo} has a {name}.")
    return with_model[-1]


# ---------------------------------------------------------------------------------------------------- writable
# The files of a run folder that a run goes on writing in place (appended to, or opened for writing); the others are
# replaced atomically, which needs the folder itself writable.
WRITTEN_IN_PLACE = (RESUME_LOG, PROGRESS_FILE, f"{MONITOR_PREFIX}.monitor.csv")


def unwritable_run_folder(folder: Path) -> str:
    """What of a run folder a run that goes on in it could not write, or ``""``: the folder itself (a probe file,
    :func:`~sb3_saeir.common.utils.unwritable_folder`), or one of :data:`WRITTEN_IN_PLACE`.

    :param folder: the run's folder (it exists)
    :return: one clause naming what cannot be written, or ``""``
    """
    problem = unwritable_folder(folder)
    if problem:
        return problem
    for path in (folder / name for name in WRITTEN_IN_PLACE):
        if path.exists() and not os.access(path, os.W_OK):
            return f"{path} is not writable"
    for path in (folder / name for name in REPLACED_FILES):
        if path.is_dir():  # the atomic writer cannot move a file onto it: the run failed at its first evaluation
            return f"{path} is a folder, where the run writes a file"
    return ""


# The files a run replaces as a whole (written beside, then moved onto the name).
REPLACED_FILES = (SPEC_FILE, DONE_FILE, SEGMENTS_FILE, EVALUATIONS_FILE, "evaluations.npz", BEST_MODEL_FILE)


def check_run_folder_writable(folder: Path, refused: str = "--resume", copy: str = "--resume the copy") -> None:
    """Refuse to go on with the run in ``folder`` when it cannot be written (:func:`unwritable_run_folder`), before
    anything is printed or written (a run printed ``Resuming ...``, then failed on ``resume.log``).

    :param folder: the run's folder, locked
    :param refused: what is refused, the start of the message (``"--resume"``, a benchmark run's name)
    :param copy: how the command continues a copy of the run, for the fix
    :raises ~sb3_saeir.config.ConfigError: one line naming the folder, what cannot be written and the fix
    """
    problem = unwritable_run_folder(folder)
    if problem:
        raise ConfigError(
            f"{refused}: the run in {folder} cannot go on there ({problem}); make the folder and its files writable "
            f"(e.g. chmod -R u+w {folder}), or copy the run to a folder you can write and {copy}."
        )


def unwritable_message(folder: Path, error: OSError, steps: int) -> str:
    """One line for a run stopped by a folder that cannot be written any more (made read-only while it trained).

    :param folder: the run's folder
    :param error: the write that failed
    :param steps: the model's agent-steps when it stopped
    """
    what = f"{error.strerror or 'permission denied'}" + (f" writing {error.filename}" if error.filename else "")
    checkpoint, _ = newest_loading_checkpoint(folder)
    then = (
        f"run the same command with --resume to continue from {checkpoint.name}"
        if checkpoint is not None
        else "start the run again (it has no checkpoint to resume from)"
    )
    return (
        f"{what}: the run folder {folder} cannot be written any more; the run stopped at {steps:,} agent-steps. Make "
        f"it writable (chmod -R u+w {folder}), then {then}."
    )


def no_space_message(folder: Path, error: OSError) -> str:
    """One line for a run stopped by a full disk: what failed, the run's folder, the checkpoint to resume from.

    :param folder: the run's folder
    :param error: the write that failed
    """
    what = f"{error.strerror or 'no space left on the device'}" + (f" writing {error.filename}" if error.filename else "")
    checkpoint, _ = newest_loading_checkpoint(folder)
    if checkpoint is None:
        return (
            f"{what}: the run in {folder} stopped and has no checkpoint to resume from. Free some space and start it "
            "again (--save-freq writes resumable checkpoints)."
        )
    return (
        f"{what}: the run in {folder} stopped; its last good checkpoint is {checkpoint.name}. Free some space, then run "
        "the same command with --resume to continue from it."
    )


# ---------------------------------------------------------------------------------------------------- the record's seed
def stored_record_seed(stored: dict[str, Any], folder: Path) -> int:
    """The seed a run's settings record holds, refused when it is not a seed (missing, a bool, not an integer, out of
    ``0 .. 2**32 - 1``): the record is damaged.

    :param stored: the run's settings record (``spec.json``, or an older run's ``<task>/args.yml``)
    :param folder: the run's folder
    :raises ~sb3_saeir.config.ConfigError: naming the file, the value and the fix
    """
    seed = stored.get("seed", _NO_SEED)
    if isinstance(seed, int) and not isinstance(seed, bool) and 0 <= seed <= MAX_SEED:
        return seed
    spec = folder / SPEC_FILE
    record = spec if spec.is_file() else folder / str(stored.get("task")) / ARGS_FILE
    shown = "missing" if seed is _NO_SEED else repr(seed)
    raise ConfigError(
        f"--resume: {record} is damaged (its seed is {shown}, not a seed 0 .. 2**32 - 1); restore it from a copy."
    )


_NO_SEED = object()  # stored_record_seed: a record without a seed
