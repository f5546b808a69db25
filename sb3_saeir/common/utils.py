"""Small helpers shared by the command lines and the Python API."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import torch as th

# Measured on a 2-core machine (benchmarks/throughput.py, cn-sparse-n3, 128 games): one training job runs 1.58x faster
# with 2 torch threads than with 1 when the second core is free, and up to 10x slower when other processes compete
# for the cores. More than 2 threads were not measured.
MAX_DEFAULT_THREADS = 2


def default_num_threads() -> int:
    """Torch threads for one training job: ``OMP_NUM_THREADS`` when it is set, else the cores this process may use,
    at most :data:`MAX_DEFAULT_THREADS`.

    Jobs that run side by side (the benchmark's ``--jobs``, the test suite) use 1 thread each instead.
    """
    from_environment = os.environ.get("OMP_NUM_THREADS", "")
    if from_environment.isdigit() and int(from_environment) > 0:
        return int(from_environment)
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(MAX_DEFAULT_THREADS, cores))


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
