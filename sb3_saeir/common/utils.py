"""Small helpers shared by the command lines and the Python API."""

from __future__ import annotations

import inspect
import math
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np
import torch as th

# Measured on a 2-core machine (benchmarks/throughput.py, cn-sparse-n3, 128 games): one training job runs 1.58x faster
# with 2 torch threads than with 1 when the second core is free, and up to 10x slower when other processes compete
# for the cores. More than 2 threads were not measured.
MAX_DEFAULT_THREADS = 2


_PACKAGE_FOLDER = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep  # sb3_saeir/


# The package's version (``sb3_saeir.__version__``), readable below the package's top level: model zips, run records and
# segments record it.
PACKAGE_VERSION = (Path(__file__).parent.parent / "version.txt").read_text().strip()


def user_stacklevel() -> int:
    """The ``stacklevel`` that makes :func:`warnings.warn`, called where this is called, name the first line outside
    this package: the user's call, as SB3's warnings do, however deep the package's calls behind it run
    (``SAEIR_PPO``'s constructor is one level deeper than ``MAPPO``'s).
    """
    level = 1
    frame: FrameType | None = sys._getframe(1)  # the function that warns
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE_FOLDER):
        level += 1
        frame = frame.f_back
    return level


def default_num_threads() -> int:
    """Torch threads for one training job: ``OMP_NUM_THREADS`` when it is set, else the cores this process may use,
    at most :data:`MAX_DEFAULT_THREADS`.

    Jobs that run side by side (the benchmark's ``--jobs``, the test suite) use 1 thread each instead.
    """
    from_environment = os.environ.get("OMP_NUM_THREADS", "")
    if from_environment.isdigit() and int(from_environment) > 0:
        return int(from_environment)
    return max(1, min(MAX_DEFAULT_THREADS, usable_cores()))


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity on Linux, else ``os.cpu_count()``)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def set_num_threads(num_threads: int | None) -> int:
    """Set torch's intra-op threads; ``None`` or a value < 1 means :func:`default_num_threads`.

    :return: the number of threads set
    """
    threads = default_num_threads() if num_threads is None or num_threads < 1 else num_threads
    th.set_num_threads(threads)
    return threads


class NotABoolError(TypeError, ValueError):
    """A boolean option given anything but ``True`` or ``False``: a wrong type and a wrong value at once, so code that
    catches either (the algorithms' and the envs' callers) sees it."""


def check_bool(owner: str, **values: Any) -> None:
    """Raise a one-line :class:`NotABoolError` naming the first boolean option that is not ``True`` or ``False``.

    Strings are refused on purpose: ``"no"`` and ``"False"`` are truthy and would switch the option on.

    :param owner: class or function name for the message
    :param values: option name -> value
    """
    for name, value in values.items():
        if not isinstance(value, (bool, np.bool_)):
            raise NotABoolError(f"{owner}: {name} must be True or False, got {value!r} ({type(value).__name__}).")


def check_number(
    owner: str,
    name: str,
    value: Any,
    rule: str,
    test: Callable[[float], bool],
    integer: bool = False,
    out_of_range: bool = False,
) -> None:
    """Raise a one-line ``ValueError`` naming ``name`` when ``value`` is not a finite number (a whole one with
    ``integer``; booleans and strings are refused) for which ``test`` holds. The one check of a number against a rule:
    the algorithms' arguments (:func:`~sb3_saeir.common.checks.check_ranges`), the bonuses' and the evaluation's.

    :param owner: class or function name for the message
    :param name: the argument's name
    :param value: its value
    :param rule: the valid range in words, e.g. ``"> 0"`` or ``"in [0, 1]"``
    :param test: whether a value is in the range
    :param integer: whether the value must be a whole number
    :param out_of_range: word the refusal as the algorithms' arguments word it: ``"<name> must be an integer, got
        <value>."`` (or ``a finite number``) for a value that is not one, ``"<name>=<value> is out of range; it must be
        <rule>."`` for one outside the range; otherwise ``"<name> must be an integer <rule>, got <value>."`` for both
    """
    kinds = (int, np.integer) if integer else (int, float, np.integer, np.floating)
    is_number = isinstance(value, kinds) and not isinstance(value, (bool, np.bool_))
    # a whole number is finite (and math.isfinite cannot convert a Python int beyond the float range)
    is_number = is_number and (isinstance(value, (int, np.integer)) or math.isfinite(value))
    if is_number and test(value):
        return
    kind = "an integer" if integer else "a finite number"
    if not out_of_range:
        raise ValueError(f"{owner}: {name} must be {kind} {rule}, got {value!r}.")
    if not is_number:
        raise ValueError(f"{owner}: {name} must be {kind}, got {value!r}.")
    raise ValueError(f"{owner}: {name}={value!r} is out of range; it must be {rule}.")


def keywords_taken(function: Callable[..., Any]) -> tuple[str, ...] | None:
    """The names ``function`` takes as keyword arguments, in signature order (a class: its constructor's, without
    ``self``), or ``None`` where its signature cannot tell: it takes ``**kwargs``, or it has no signature to read (a
    builtin). The argument checks refuse an unknown keyword only where this is not ``None``.

    :param function: a function or class
    :return: the keyword parameter names, or ``None``
    """
    try:
        parameters = inspect.signature(function).parameters
    except (TypeError, ValueError):  # no signature to read
        return None
    if any(parameter.kind is inspect.Parameter.VAR_KEYWORD for parameter in parameters.values()):
        return None
    keyword_kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return tuple(name for name, parameter in parameters.items() if parameter.kind in keyword_kinds)


# Largest seed: SB3's ``set_random_seed`` seeds NumPy's legacy generator, which takes 0 .. 2**32 - 1.
MAX_SEED = 2**32 - 1
# The --seed of the training commands that draws a seed (rl-zoo's convention).
DRAW_SEED = -1


def check_seed(owner: str, seed: Any, name: str = "seed", hint: str = " (or None)") -> int | None:
    """The seed as a Python ``int`` (``None`` kept), or a one-line ``ValueError`` naming the argument.

    NumPy integers are accepted (Python's ``random.seed`` refuses them); booleans, floats, strings and seeds outside
    ``0 .. 2**32 - 1`` (the range of SB3's ``set_random_seed``) are refused.

    :param owner: class or function for the message (``""``: none, for a command-line option)
    :param seed: the seed given
    :param name: the argument's name, e.g. ``"seed"`` or ``"--seed"``
    :param hint: what else the argument takes, appended to the message
    :return: ``int(seed)``, or ``None``
    """
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or not 0 <= seed <= MAX_SEED:
        prefix = f"{owner}: " if owner else ""
        raise ValueError(f"{prefix}{name}={seed!r} is not a seed; pass an integer from 0 to 2**32 - 1{hint}.")
    return int(seed)


def unwritable_folder(folder: str | os.PathLike) -> str:
    """Why no file could be written in ``folder`` (created with its missing parents, as the writers do), or ``""``.

    The nearest existing folder is tried with a probe file, removed at once, and the folder's access and modification
    times are put back (a check changes nothing a user sees): permission bits alone pass for root where the file
    system refuses (``/proc``, ``/sys``, a read-only mount).

    :param folder: the folder a file is to be written in (it need not exist yet)
    :return: one clause naming the folder and the problem, or ``""`` when a file can be written
    """
    path = Path(folder)
    existing = next(parent for parent in (path, *path.parents) if parent.exists() or parent == Path(parent.anchor))
    if not existing.is_dir():
        return f"{existing} is a file, not a folder"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"{existing} is not writable"
    times = existing.stat()
    try:
        handle, probe = tempfile.mkstemp(dir=existing, prefix=".sb3_saeir-write-test-")
    except OSError as error:
        return f"no file can be created in {existing} ({error.strerror})"
    os.close(handle)
    os.remove(probe)
    try:
        os.utime(existing, ns=(times.st_atime_ns, times.st_mtime_ns))
    except OSError:  # a folder the user may write in but not own: its times stay as the probe left them
        pass
    return ""


def check_writable_folder(owner: str, name: str, folder: Any, example: str = "a folder") -> None:
    """Raise a one-line ``ValueError`` naming ``name`` when ``folder`` is neither ``None`` nor a path of a folder in
    which a file can be written (:func:`unwritable_folder`), checked when the argument is given rather than at the
    first write.

    :param owner: class or function name for the message
    :param name: the argument's name
    :param folder: its value
    :param example: what to pass instead of a value that is not a path, e.g. ``"a path such as './tensorboard/'"``
    """
    if folder is None:
        return
    if not isinstance(folder, (str, os.PathLike)):
        raise ValueError(f"{owner}: {name}={folder!r} is not a folder path; pass {example} (or None).")
    problem = unwritable_folder(folder)
    if problem:
        raise ValueError(f"{owner}: {name}={str(folder)!r}: {problem}; pass a folder you can write (or None).")
