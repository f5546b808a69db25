"""How a command line stops on a signal (``docs/guide/training.md``, "Signals"): Ctrl-C (SIGINT), SIGTERM and SIGHUP
stop ``train``, ``zoo train`` and the benchmark at a checkpoint, and the command exits with 128 + the signal's number.
:class:`~sb3_saeir.run.run.Run` handles them during training; :func:`stop_signals_as_ctrl_c` makes SIGTERM and SIGHUP a
``KeyboardInterrupt`` for a command that stops on Ctrl-C (the benchmark driver).
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from typing import Any

# The signals on which a command line's run writes a checkpoint and stops, as on Ctrl-C (docs/guide/training.md,
# "Signals"): a terminal's Ctrl-C (SIGINT), what kill, timeout, container stops and batch schedulers send first
# (SIGTERM), and a closed terminal (SIGHUP). The command then exits with 128 + the signal's number.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def signal_name(signum: int) -> str:
    """How a stop signal is named to the user: ``Ctrl-C`` for SIGINT, else its name (``SIGTERM``, ``SIGHUP``)."""
    return "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name


# The exit status of a command line's run stopped early by Ctrl-C (as shells give a command ended by SIGINT: 128 + 2).
INTERRUPTED_EXIT_STATUS = 130


def interrupted_exit_status(signum: int | None) -> int:
    """The exit status of a command line's run stopped early by a signal: 128 + its number, as shells give (130 for
    Ctrl-C, 143 for SIGTERM, 129 for SIGHUP).

    :param signum: the signal (``None``: Ctrl-C)
    """
    return INTERRUPTED_EXIT_STATUS if signum is None else 128 + int(signum)


class StopSignal(KeyboardInterrupt):
    """SIGTERM or SIGHUP received by a command that stops on it as on Ctrl-C (:func:`stop_signals_as_ctrl_c`).

    :param signum: the signal
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextlib.contextmanager
def handlers_installed(signums: Iterable[int], handler: Callable[[int, Any], None]) -> Iterator[None]:
    """In the main thread (the only one where Python sets signal handlers): ``handler`` handles ``signums`` while the
    block runs, and the previous handlers are put back when it ends. Elsewhere nothing is installed.

    :param signums: the signals
    :param handler: ``handler(signum, frame)``
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signum: signal.signal(signum, handler) for signum in signums}
    try:
        yield
    finally:
        for signum, previous_handler in previous.items():
            signal.signal(signum, previous_handler)


@contextlib.contextmanager
def stop_signals_as_ctrl_c() -> Iterator[None]:
    """In the main thread: SIGTERM (kill, timeout, container stops, batch schedulers) and SIGHUP (a closed terminal)
    raise :class:`StopSignal`, a ``KeyboardInterrupt``, so that the command stops as on Ctrl-C
    (``docs/guide/training.md``, "Signals"); the previous handlers are put back afterwards."""

    def handler(signum: int, frame: Any) -> None:
        raise StopSignal(signum)

    with handlers_installed((signal.SIGTERM, signal.SIGHUP), handler):
        yield


# The command lines that stop on these signals, as ``python -m <name>`` starts them.
TRAINING_COMMANDS = ("sb3_saeir.train", "sb3_saeir.zoo", "sb3_saeir.benchmark")


def started_command() -> str | None:
    """The training command this process was started as (``python -m sb3_saeir.train ...``: one of
    :data:`TRAINING_COMMANDS`), else ``None`` (a script or a session that imports the package)."""
    argv = list(getattr(sys, "orig_argv", []))
    if "-m" not in argv[:-1]:
        return None
    name = argv[argv.index("-m") + 1]
    return name if name in TRAINING_COMMANDS else None


def _interrupted_while_starting(signum: int, frame: Any) -> None:
    print(f"{started_command()}: {signal_name(signum)} while starting: stopped, nothing was written", file=sys.stderr)
    raise SystemExit(interrupted_exit_status(signum))


def exit_on_ctrl_c_while_starting() -> None:
    """In a process started as a training command (:func:`started_command`), from the package's import on: Ctrl-C,
    SIGTERM and SIGHUP end it with one line and exit status 130 / 143 / 129 instead of an import traceback (or no word
    at all), until the command's ``main`` takes them over (:func:`ctrl_c_to_the_command`). Nothing changes in any
    other process."""
    if started_command() is None or threading.current_thread() is not threading.main_thread():
        return
    for signum in STOP_SIGNALS:
        if signal.getsignal(signum) in (signal.default_int_handler, signal.SIG_DFL):
            signal.signal(signum, _interrupted_while_starting)


def ctrl_c_to_the_command() -> None:
    """At the start of a training command's ``main``: the stop signals act as Python's defaults again (Ctrl-C raises
    ``KeyboardInterrupt``), for the command to handle (:func:`exit_on_ctrl_c_while_starting` handled them while the
    package was imported)."""
    if threading.current_thread() is not threading.main_thread():
        return
    for signum in STOP_SIGNALS:
        if signal.getsignal(signum) is _interrupted_while_starting:
            signal.signal(signum, signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL)


def exit_after_the_command(status: int) -> None:
    """End a training command's process with ``status``: its work is done and said, so a stop signal that comes
    while the interpreter shuts down (a second or more) is ignored rather than killing it with another status.

    :param status: the command's exit status
    """
    for signum in STOP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)
    sys.exit(status)


def stop_signal_number(stop: KeyboardInterrupt) -> int:
    """The signal behind a ``KeyboardInterrupt``: a :class:`StopSignal`'s, else SIGINT (Ctrl-C)."""
    return stop.signum if isinstance(stop, StopSignal) else int(signal.SIGINT)
