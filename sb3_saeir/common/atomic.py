"""Atomic file replacement: every file the package writes over (models, checkpoints, ``evaluations.npz``, CSV files,
``args.yml``, ...) is written to a temporary file in the same folder, flushed to disk and moved into place with
``os.replace``, so an interrupt (Ctrl-C, a kill) or a failed write (a full disk) leaves either the old file or the new
one, never a part of the new one (see ``docs/guide/training.md``, "Stopping and resuming a run").

- :func:`atomic_path`: the core, a context manager yielding the temporary path, for libraries that write to a path;
- :func:`atomic_file`: the same, yielding the temporary file opened for writing;
- :func:`atomic_write_bytes` / :func:`atomic_write_text`: a whole file from bytes or text;
- :func:`keep_damaged`: a copy of a damaged file, kept before it is rewritten without what cannot be read;
- :func:`save_model`: an SB3 model's ``save`` (any ``BaseAlgorithm``) through :func:`atomic_file`, with SB3's
  path rules (:func:`sb3_save_path`: ``.zip`` added to a path without suffix).
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import secrets
import shutil
import signal
import stat
import warnings
from collections.abc import Callable, Iterator
from datetime import datetime, timezone
from pathlib import Path
from typing import IO, Any, cast

from sb3_saeir.common.stop_signals import STOP_SIGNALS, handlers_installed
from sb3_saeir.common.utils import user_stacklevel

# Modes of atomic_file.
ATOMIC_FILE_MODES = ("wb", "w+b", "w")
# How many temporary names are tried before giving up (each is random: a clash is all but impossible).
TEMP_ATTEMPTS = 100


def temp_name(path: Path) -> Path:
    """A new temporary path beside ``path``, hidden, ending with ``path``'s suffix (for libraries that choose the
    format by it): ``dir/.model.zip.<pid>-<random>.tmp.zip``.

    :param path: the file to replace
    """
    return path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}.tmp{path.suffix}")


# A temporary file of temp_name: .<name>.<pid>-<8 hex digits>.tmp<suffix>
_TEMP_NAME = re.compile(r"\.(?P<name>.+)\.(?P<pid>\d+)-[0-9a-f]{8}\.tmp(\.[^.]*)?")


def remove_stale_temporaries(folder: Path) -> list[Path]:
    """Remove the temporary files of :func:`temp_name` in ``folder`` left by processes that are gone (killed while
    they wrote: SIGKILL, or a benchmark job terminated with its driver); a live process's are kept. Returns what was
    removed.

    :param folder: a folder the caller owns (a run folder under its lock)
    """
    removed = []
    for path in folder.glob(".*.tmp*"):
        match = _TEMP_NAME.fullmatch(path.name)
        if match is None or not path.is_file() or _process_alive(int(match["pid"])):
            continue
        with contextlib.suppress(OSError):
            path.unlink()
            removed.append(path)
    return removed


def _process_alive(pid: int) -> bool:
    """Whether a process with this id runs (or might: one of another user's)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def _create_temp(path: Path) -> Path:
    """Create an empty temporary file beside ``path`` (exclusively: with the umask's permissions, or ``path``'s own
    when it exists) and return its path."""
    for _ in range(TEMP_ATTEMPTS):
        temp = temp_name(path)
        try:
            with open(temp, "xb"):
                pass
        except FileExistsError:
            continue
        except OSError as error:  # named by the file to write, not the temporary one
            raise OSError(error.errno, error.strerror, str(path)) from None
        with contextlib.suppress(OSError):
            os.chmod(temp, stat.S_IMODE(os.stat(path).st_mode))
        return temp
    raise FileExistsError(f"cannot create a temporary file beside {path}: {TEMP_ATTEMPTS} names taken.")


def _fsync_path(path: Path, folder: bool = False) -> None:
    """Flush a file (or a folder's entries, after a rename) to disk; a system that cannot sync a folder is let be."""
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    except OSError:
        if not folder:
            raise
    finally:
        os.close(descriptor)


@contextlib.contextmanager
def _stop_signals_deferred() -> Iterator[list[int]]:
    """In the main thread, let the stop signals (SIGINT, SIGTERM, SIGHUP) that arrive while the block runs only be
    noted (in the yielded list), the handlers put back when it ends, so that the caller delivers them where it can
    clean up (:func:`signal.raise_signal`). Elsewhere, or for a handler not set from Python, nothing is deferred."""
    arrived: list[int] = []
    python_handled = [signum for signum in STOP_SIGNALS if signal.getsignal(signum) is not None]
    with handlers_installed(python_handled, lambda signum, frame: arrived.append(signum)):
        yield arrived


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Replace ``path`` atomically: yields a temporary path in the same folder to write the new content to; when the
    block ends without an error, the temporary file is flushed to disk (``fsync``) and moved onto ``path``
    (``os.replace``). On any error, Ctrl-C included, it is removed and ``path`` is left as it was.

    Example::

        with atomic_path("curve.png") as temp:
            figure.savefig(temp)

    :param path: the file to write (its folder must exist); a symbolic link is written through, to the file it
        points to, as ``open(path, "wb")`` would (the link stays a link)
    :return: the temporary path (same folder as the file written, same suffix)
    """
    path = Path(path)
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    temp: Path | None = None
    try:
        with _stop_signals_deferred() as arrived:  # a Ctrl-C right after the file is made left it behind, empty
            temp = _create_temp(path)
        for signum in arrived:  # delivered now, where the file is removed
            signal.raise_signal(signum)
        yield temp
        _fsync_path(temp)
        os.replace(temp, path)
    except BaseException as error:
        if temp is not None:
            with contextlib.suppress(OSError):
                temp.unlink()
        if isinstance(error, OSError) and error.filename in (None, str(temp)):
            error.filename, error.filename2 = str(path), None  # named by the file being written
        raise
    _fsync_path(path.parent, folder=True)


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO[Any]]:
    """:func:`atomic_path` yielding the temporary file opened for writing (closed, flushed and moved into place when
    the block ends; removed on an error).

    :param path: the file to write (its folder must exist)
    :param mode: ``"wb"`` (bytes), ``"w+b"`` (bytes, also readable: to append to a zip written in the block) or
        ``"w"`` (UTF-8 text)
    :return: the open temporary file
    """
    if mode not in ATOMIC_FILE_MODES:
        raise ValueError(f"atomic_file: mode must be one of {', '.join(ATOMIC_FILE_MODES)}, got {mode!r}.")
    with atomic_path(path) as temp, open(temp, mode, encoding=None if "b" in mode else "utf-8") as file:
        yield file
        file.flush()
        os.fsync(file.fileno())


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``path`` through :func:`atomic_file`: an interrupt or a failed write leaves the old file or the new one.

    :param path: the file
    :param data: its new content
    """
    with atomic_file(path, "wb") as file:
        file.write(data)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """:func:`atomic_write_bytes` for text (UTF-8).

    :param path: the file
    :param text: its new content
    """
    atomic_write_bytes(path, text.encode())


def sb3_save_path(path: str | os.PathLike[str]) -> Path:
    """The file SB3's ``save`` writes for ``path`` (``stable_baselines3.common.save_util.open_path``): ``.zip``
    added to a path without suffix, ``<path>_2`` when ``path`` is a folder, missing parent folders created (SB3's
    warnings included).

    :param path: the path given to ``save``
    """
    target = Path(path)
    if target.suffix == "":
        target = Path(f"{target}.zip")
    while target.is_dir():
        warnings.warn(f"Path '{target}' is a folder. Will save instead to {target}_2", stacklevel=user_stacklevel())
        target = Path(f"{target}_2")
    if not target.parent.is_dir():
        warnings.warn(f"Path '{target.parent}' does not exist. Will create it.", stacklevel=user_stacklevel())
        target.parent.mkdir(parents=True, exist_ok=True)
    return target


def save_zip(path: str | os.PathLike[str], write: Callable[[io.BufferedIOBase], None]) -> Path:
    """Write an SB3 zip atomically: ``write`` gets the temporary file (an open binary file, which SB3's ``save``
    takes as it takes a path), moved onto :func:`sb3_save_path` of ``path`` when it returns.

    :param path: the path given to ``save``
    :param write: writes the zip into the file it is given
    :return: the zip's path
    """
    target = sb3_save_path(path)
    with atomic_file(target, "wb") as file:
        write(cast(io.BufferedIOBase, file))  # a BufferedWriter: SB3's open_path takes it
    return target


def save_model(model: Any, path: str | os.PathLike[str]) -> Path:
    """``model.save(path)`` for any SB3 model, atomically (see :func:`save_zip`).

    :param model: an SB3 ``BaseAlgorithm``
    :param path: where to save (``.zip`` added when it has no suffix, as SB3 does)
    :return: the zip's path
    """
    return save_zip(path, model.save)


def keep_damaged(path: str | os.PathLike[str]) -> Path:
    """Copy a damaged file to ``<name>.damaged-<UTC time>`` beside it, before it is rewritten without what cannot be
    read, so that nothing in it is lost; returns the copy's path.

    :param path: the damaged file
    """
    path = Path(path)
    copy = unused_name(path, "damaged")
    shutil.copy2(path, copy)
    return copy


def unused_name(path: Path, label: str) -> Path:
    """``<path>.<label>-<UTC time>`` (``-2``, ``-3``, ... appended while taken): a name beside ``path`` for a copy
    or a folder moved aside, so that nothing is overwritten.

    :param path: the file or folder kept
    :param label: what the copy is (``"damaged"``, ``"replaced"``)
    """
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    target = path.with_name(f"{path.name}.{label}-{stamp}")
    number = 1
    while target.exists():
        number += 1
        target = path.with_name(f"{path.name}.{label}-{stamp}-{number}")
    return target
