"""One process per run folder: an OS lock (``fcntl.flock``) on the run folder itself, held while a process trains the
run and released by the OS when that process ends, however it ends (a SIGKILLed holder leaves no stale lock). Nothing
is written for it; the refusal names the holding process as the kernel's lock table gives it (``/proc/locks``, on
Linux). See ``docs/guide/training.md``, "One process per run folder".
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path


class RunFolderInUseError(ValueError):
    """Another process trains the run folder: the message names the folder and that process."""


class RunFolderLock:
    """The lock of one run folder (:meth:`acquire`, :meth:`release`; a context manager).

    :param folder: the run folder (created by :meth:`acquire` when missing)
    """

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        """Whether this object holds the lock."""
        return self._fd is not None

    def acquire(self) -> RunFolderLock:
        """Take the lock, or refuse at once (no waiting) when another process holds it.

        :raises RunFolderInUseError: naming the folder and the process that holds it
        """
        if self._fd is not None:
            return self
        self.folder.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = lock_holder(fd)
            os.close(fd)
            raise RunFolderInUseError(
                f"{self.folder} is in use by {holder}: one process trains a run folder at a time. Wait for it to end "
                "(or stop it), then run this command again."
            ) from None
        self._fd = fd
        return self

    def release(self) -> None:
        """Give the lock back."""
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> RunFolderLock:
        return self.acquire()

    def __exit__(self, *exc_info: object) -> None:
        self.release()


def lock_holder(fd: int) -> str:
    """The process that holds the ``flock`` of the file open as ``fd``, as ``process <pid> (<command line>)``, from
    the kernel's lock table (``"another process"`` where there is none to read)."""
    inode = os.fstat(fd).st_ino
    try:
        lines = Path("/proc/locks").read_text().splitlines()
    except OSError:
        return "another process"
    for line in lines:
        fields = line.split()  # "1: FLOCK  ADVISORY  WRITE 1234 08:01:5678 0 EOF"
        if len(fields) >= 6 and fields[1] == "FLOCK" and fields[5].rsplit(":", 1)[-1] == str(inode):
            return f"process {fields[4]}{_command_line(fields[4])}{_stopped(fields[4])}"
    return "another process"


def _stopped(pid: str) -> str:
    """``", which is stopped (...)"`` when process ``pid`` is stopped (SIGSTOP, Ctrl-Z: waiting for it to end would
    wait forever), else ``""``."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return ""
    if state not in ("T", "t"):
        return ""
    return f", which is stopped (SIGSTOP or Ctrl-Z): it will not end by itself; let it go on with kill -CONT {pid}, or end it"


def _command_line(pid: str) -> str:
    """`` (<command line>)`` of process ``pid`` (``""`` when it cannot be read)."""
    try:
        words = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return ""
    text = " ".join(word.decode(errors="replace") for word in words if word)
    return f" ({text if len(text) <= 300 else text[:300] + ' ...'})" if text else ""


class RunFolderWatch:
    """Where a run's folder is while its run trains: an open descriptor of the folder taken at the start, so that a
    folder moved, deleted or replaced is told apart from one in place, and a moved folder's new path is found (Linux:
    ``/proc/self/fd``; macOS: ``F_GETPATH``). A run checks it before it writes (``docs/guide/training.md``, "The run
    folder moved, deleted or read-only"): it never writes at, or makes again, a path its folder has left; a refused
    command removes only the folders it made that are still in place.

    :param folder: the run folder (it exists)
    """

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        self._fd: int | None = os.open(self.folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        self._identity = _identity(os.fstat(self._fd))

    def change(self) -> str | None:
        """What happened to the folder: ``"deleted"``, ``"moved to <path>"`` (``"moved"`` where the new path cannot be
        read), or ``None`` while it is in place."""
        if self._fd is None:
            return None
        try:
            in_place = _identity(os.stat(self.folder)) == self._identity
        except OSError:
            in_place = False
        if in_place:
            return None
        if os.fstat(self._fd).st_nlink == 0:
            return "deleted"
        now = self.current_path()
        return f"moved to {now}" if now is not None else "moved"

    def current_path(self) -> Path | None:
        """The folder's path now (``None`` where the system cannot tell, or the folder is deleted)."""
        if self._fd is None:
            return None
        try:
            if hasattr(fcntl, "F_GETPATH"):  # macOS
                path = fcntl.fcntl(self._fd, fcntl.F_GETPATH, bytes(1024)).rstrip(b"\0").decode()
            else:
                path = os.readlink(f"/proc/self/fd/{self._fd}")
        except OSError:
            return None
        return None if path.endswith(" (deleted)") else Path(path)

    def close(self) -> None:
        """Close the descriptor."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def _identity(status: os.stat_result) -> tuple[int, int]:
    return status.st_dev, status.st_ino
