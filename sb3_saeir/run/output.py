"""What a :class:`~sb3_saeir.run.run.Run` shows and records while it trains: its evaluations (:class:`RunEvalCallback`:
``evaluations.csv``, ``evaluations.npz``, ``best_model.zip``) and its output (:class:`RunOutput`: SB3's stdout and
tensorboard writers, the caller's callbacks). The run folder's files: ``docs/guide/training.md``, "The run folder".
"""

from __future__ import annotations

import inspect
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import KVWriter
from stable_baselines3.common.utils import configure_logger

from sb3_saeir.common.run_state import SegmentClock
from sb3_saeir.evaluation import MultiAgentEvalCallback
from sb3_saeir.run.files import EVALUATIONS_FILE
from sb3_saeir.run.record import RunSpec, same_row, write_rows


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


# ---------------------------------------------------------------------------------------------------- output
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
    :param announce: what the command says about the run once it is set up and checked, before anything is written,
        ``announce(run, experiment)`` (``None``: nothing)
    """

    command_line: bool = False
    verbose: int = 0
    progress_bar: bool = False
    callbacks: list[BaseCallback] = field(default_factory=list)
    announce: Callable[[Any, Any], None] | None = None

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


class RunFolderCheck(BaseCallback):
    """Calls ``check`` (:meth:`~sb3_saeir.run.run.Run.check_folder`) at each rollout start and step, before the other
    callbacks of the run write: a run whose folder was moved or deleted stops before it writes again.

    :param check: raises when the run must stop
    """

    def __init__(self, check: Callable[[], None]) -> None:
        super().__init__()
        self.check = check

    def _on_rollout_start(self) -> None:
        self.check()

    def _on_step(self) -> bool:
        self.check()
        return True
