"""The per-game episode records of a multi-agent vec env and their monitor CSV: :class:`MultiAgentVecMonitor`.

The CSV is SB3's monitor format, one row per game (not per agent, as SB3's ``VecMonitor`` would write); a resumed run
continues it, and restoring a checkpoint writes missing or damaged rows again from the records.
"""

from __future__ import annotations

import collections
import csv
import io
import json
import os
import time
import warnings
from collections.abc import Callable
from typing import Any

from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvObs, VecEnvStepReturn, VecEnvWrapper

from sb3_saeir.common.atomic import atomic_write_text, keep_damaged
from sb3_saeir.common.utils import check_bool


class MultiAgentVecMonitor(VecEnvWrapper):
    """Per-game episode records of a :class:`~sb3_saeir.common.vec_env.MultiAgentVecEnv` (any backend), optionally
    written as a monitor CSV.

    The multi-agent vec env puts one ``episode`` dict (team return ``r``, game steps ``l``, task metrics) into the info
    of a game's first slot when the game ends; this wrapper keeps the last 10,000 of them in :attr:`episodes` and
    writes each as a row of ``<filename>.monitor.csv`` (SB3's monitor format, readable by
    ``stable_baselines3.common.monitor.load_results`` and rl-zoo3's plot scripts; ``t`` is counted from this wrapper's
    creation, the header's ``t_start``). Unlike SB3's ``VecMonitor`` it counts games, not agents. Attribute access
    falls through to the wrapped env (``n_agents``, ``n_games``, ...).

    With ``append``, an existing CSV is continued (its header and rows kept) rather than started anew: a resumed run
    (``python -m sb3_saeir.train --resume``) writes on into its file. :meth:`get_resume_state` and
    :meth:`set_resume_state` carry the records and the wrapped env's state through a checkpoint
    (:mod:`sb3_saeir.common.run_state`); restoring cuts the CSV back to the rows written by then.

    :param venv: a multi-agent vec env
    :param filename: path prefix of the CSV (``"<dir>/games"`` -> ``<dir>/games.monitor.csv``); ``None``: no file
    :param env_id: written in the CSV header
    :param append: continue an existing CSV instead of overwriting it
    :param log: where :meth:`set_resume_state` says which rows of the CSV were missing or damaged and could or could
        not be restored (default: a warning)
    """

    # observations, rewards and dones pass through unchanged (double-buffered sampling may run under this wrapper)
    passes_steps_through = True

    def __init__(
        self,
        venv: VecEnv,
        filename: str | None = None,
        env_id: str = "games",
        append: bool = False,
        log: Callable[[str], None] | None = None,
    ) -> None:
        super().__init__(venv)
        self.log = log if log is not None else _warn
        self.filename = filename
        self.env_id = env_id
        check_bool("MultiAgentVecMonitor", append=append)
        self.append = append
        self.t_start = time.time()
        self.results_writer: Any = None
        self.episodes: collections.deque[dict[str, Any]] = collections.deque(maxlen=10_000)
        self.n_finished_games = 0

    def reset(self) -> VecEnvObs:
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        for info in infos:
            episode = info.get("episode")
            if episode is not None:
                self._record(dict(episode))
        return obs, rewards, dones, infos

    def _record(self, episode: dict[str, Any]) -> None:
        from stable_baselines3.common.monitor import ResultsWriter

        row = {"r": episode.pop("r"), "l": episode.pop("l"), "t": round(time.time() - self.t_start, 6)}
        episode.pop("t", None)
        row.update(episode)
        self.episodes.append(row)
        self.n_finished_games += 1
        if self.filename is None:
            return
        if self.results_writer is None:
            header: dict[str, float | str] = {"t_start": self.t_start, "env_id": self.env_id}
            keep = self.append and os.path.isfile(self.csv_path)
            self.results_writer = ResultsWriter(
                self.filename, header=header, extra_keys=tuple(episode), override_existing=not keep
            )
        try:
            self.results_writer.write_row(row)
        except OSError as error:  # a full disk: named by the file
            error.filename = error.filename or self.csv_path
            raise

    @property
    def csv_path(self) -> str:
        """The monitor CSV's path (``<filename>.monitor.csv``)."""
        assert self.filename is not None
        return self.filename if self.filename.endswith("monitor.csv") else f"{self.filename}.monitor.csv"

    def get_resume_state(self) -> dict[str, Any]:
        """The wrapped env's state (its ``get_resume_state``) and the records so far.

        :return: a dict for :meth:`set_resume_state`
        """
        return {
            "venv": self.venv.get_resume_state(),  # type: ignore[attr-defined]
            "episodes": list(self.episodes),
            "n_finished_games": self.n_finished_games,
            "t_start": self.t_start,
        }

    def set_resume_state(self, state: dict[str, Any]) -> None:
        """Go back to the state of :meth:`get_resume_state`: the wrapped env's, the records, and the CSV cut back to
        its header and the rows written by then (rows written after, by an interrupted process, are dropped)."""
        self.venv.set_resume_state(state["venv"])  # type: ignore[attr-defined]
        self.episodes = collections.deque(state["episodes"], maxlen=self.episodes.maxlen)
        self.n_finished_games = state["n_finished_games"]
        self.t_start = state["t_start"]
        if self.results_writer is not None:
            self.results_writer.close()
            self.results_writer = None
        if self.filename is not None and (self.n_finished_games or os.path.isfile(self.csv_path)):
            kept = self._restored_csv_lines()
            atomic_write_text(self.csv_path, "".join(line + "\n" for line in kept))
            self.append = bool(kept)

    def _restored_csv_lines(self) -> list[str]:
        """The CSV's lines at the checkpoint: its header's two lines, then one row per game finished by then (rows
        written after it, by an interrupted process, are left out). A row that is missing or damaged (the file cut
        short, deleted or edited) is written again from :attr:`episodes` when it is among the last 10,000 games;
        :attr:`log` says how many rows were written again and how many cannot be restored, and the damaged file is
        kept beside it (:func:`~sb3_saeir.common.atomic.keep_damaged`)."""
        path, n_rows = self.csv_path, self.n_finished_games
        exists = os.path.isfile(path)
        if exists:
            with open(path, newline="") as file:
                lines = file.read().split("\n")[:-1]  # after the last newline: a row cut by a kill
        else:
            lines = []
        if not n_rows:
            return []
        records = list(self.episodes)
        columns = _monitor_columns(lines[:2])
        new_header = not columns
        if new_header:
            columns = ["r", "l", "t", *[key for key in records[-1] if key not in ("r", "l", "t")]]
        header = self._csv_header(columns) if new_header else lines[:2]
        rows = lines[2 : 2 + n_rows]
        first_record = n_rows - len(records)  # the game of records[0]
        kept, restored, lost = [], 0, 0
        for game in range(n_rows):
            if game < len(rows) and _is_monitor_row(rows[game], columns):
                kept.append(rows[game])
            elif game >= first_record:
                kept.append(_monitor_row(records[game - first_record], columns))
                restored += 1
            else:
                lost += 1
        if restored or lost or new_header:
            self._report_restored(path, exists, restored, lost, new_header and exists)
        return [*header, *kept]

    def _csv_header(self, columns: list[str]) -> list[str]:
        """The two header lines of the CSV as SB3's ``ResultsWriter`` writes them (a JSON line, the column names)."""
        return ["#" + json.dumps({"t_start": self.t_start, "env_id": self.env_id}), _monitor_row({}, columns, header=True)]

    def _report_restored(self, path: str, existed: bool, restored: int, lost: int, new_header: bool) -> None:
        """Say which rows of the monitor CSV were missing or damaged, which were written again from the checkpoint and
        how many cannot be restored; keep the damaged file."""
        where = f"the damaged file is kept as {os.path.basename(keep_damaged(path))}" if existed else "it was missing"
        parts = [f"{restored} written again from the checkpoint"] if restored else []
        if lost:
            parts.append(f"{lost} older than its last {self.episodes.maxlen:,} games cannot be restored and are left out")
        if new_header:
            parts.append("the header written again")
        self.log(
            f"{path}: {restored + lost} rows of the games finished by the checkpoint were missing or damaged "
            f"({'; '.join(parts)}; {where}); the run goes on from the checkpoint."
        )

    def close(self) -> None:
        if self.results_writer is not None:
            self.results_writer.close()
        super().close()


def _warn(message: str) -> None:
    """A monitor's default ``log``: a warning."""
    warnings.warn(message, stacklevel=3)


def _monitor_columns(header: list[str]) -> list[str]:
    """The column names of a monitor CSV from its two header lines (empty when they are missing or damaged)."""
    if len(header) < 2 or not header[0].startswith("#"):
        return []
    try:
        json.loads(header[0][1:])
    except ValueError:
        return []
    columns = next(csv.reader([header[1].rstrip("\r")]), [])
    return columns if columns[:3] == ["r", "l", "t"] else []


def _is_monitor_row(line: str, columns: list[str]) -> bool:
    """Whether a line of a monitor CSV is a whole row: one cell per column, numbers as ``r``, ``l`` and ``t``."""
    values = next(csv.reader([line.rstrip("\r")]), [])
    if len(values) != len(columns):
        return False
    try:
        [float(value) for value in values[:3]]
    except ValueError:
        return False
    return True


def _monitor_row(record: dict[str, Any], columns: list[str], header: bool = False) -> str:
    """A row (or, with ``header``, the column line) of a monitor CSV as SB3's ``ResultsWriter`` writes it, without the
    final newline."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns, extrasaction="ignore")
    writer.writeheader() if header else writer.writerow(record)
    return text.getvalue()[:-1]
