"""The launcher's ``train``: rl-zoo3's ``ExperimentManager`` with the package's hooks (:class:`RunExperimentManager`),
bound by :func:`sb3_saeir.zoo.launcher.train_with_manager`. On a package task the run is a :class:`~sb3_saeir.run.run.Run`
in rl-zoo3's run folder: rl-zoo3 builds the config, the env and the model, the run does the rest.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from rl_zoo3.exp_manager import ExperimentManager
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback

from sb3_saeir.common.callbacks import BudgetEstimate
from sb3_saeir.config import ConfigError, load_yaml, loaded_network
from sb3_saeir.experiment import Experiment
from sb3_saeir.run.folder import RunFolder
from sb3_saeir.run.output import RunOutput
from sb3_saeir.run.record import RunSpec, config_record
from sb3_saeir.run.run import Run


@dataclass
class ZooTrain:
    """What the launcher knows of a ``train`` command before rl-zoo3 starts.

    :param package_env: the env is a package task (the run is a :class:`~sb3_saeir.run.run.Run`); else rl-zoo3 trains
        as it does, but for the YAML loader
    :param resume: ``--resume``'s value (``None``: a new run)
    :param folder: on a package task, the run's folder (a new run's claimed, or the one ``--resume`` names:
        :func:`~sb3_saeir.zoo.launcher.claim_run_folder`), held by the launcher
    :param stop_line: the line of a run stopped early (Ctrl-C, SIGTERM, SIGHUP; set by ``learn``:
        :meth:`~sb3_saeir.run.run.Run.stop_line`)
    :param stop_signal: the signal that stopped it
    """

    package_env: bool
    resume: int | Path | None = None
    folder: RunFolder | None = None
    stop_line: str | None = None
    stop_signal: int | None = None


class RunExperimentManager(ExperimentManager):
    """rl-zoo3's ``ExperimentManager`` for ``python -m sb3_saeir.zoo train``.

    It reads a YAML ``--conf-file`` with the package's loader (``5e-4`` is a float, a key given twice is refused). On
    a package task: its setup runs in the run's folder that the launcher holds (claimed for a new run; the one
    ``--resume`` continues, with its seed) and a failure becomes one line; ``config.yml`` and ``args.yml`` are
    written for a new run only; ``learn`` is a :class:`~sb3_saeir.run.run.Run`, which
    saves the final model itself.

    :param args: rl-zoo3's ``ExperimentManager`` arguments
    :param zoo_train: the launcher's command
    :param kwargs: rl-zoo3's ``ExperimentManager`` keyword arguments
    """

    def __init__(self, *args: Any, zoo_train: ZooTrain, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.zoo_train = zoo_train
        self.saeir_config: dict[str, Any] = {}
        if zoo_train.folder is not None:  # the run's folder (rl-zoo3's numbering, claimed), not one of rl-zoo3's own
            self.save_path = str(zoo_train.folder.path)
            self.params_path = f"{zoo_train.folder.path}/{self.env_name}"
            if zoo_train.folder.record is not None:  # resumed: the run's own seed
                self.seed = int(zoo_train.folder.record["seed"])

    def read_hyperparameters(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """rl-zoo3's ``read_hyperparameters``, with a YAML file read by :func:`~sb3_saeir.config.load_yaml` instead of
        ``yaml.safe_load`` (which leaves ``5e-4`` a string and takes a key given twice): rl-zoo3 has no option for
        its loader, so the ``yaml`` name its module reads is bound, for this call only, to one whose ``safe_load`` is
        the package's (rl-zoo3's module is put back after it)."""
        import rl_zoo3.exp_manager

        rl_yaml = rl_zoo3.exp_manager.yaml
        rl_zoo3.exp_manager.yaml = SimpleNamespace(safe_load=load_yaml)  # type: ignore[assignment]
        try:
            return super().read_hyperparameters()
        finally:
            rl_zoo3.exp_manager.yaml = rl_yaml

    def setup_experiment(self) -> tuple[BaseAlgorithm, dict[str, Any]] | None:
        """rl-zoo3's setup (config, env, model) in the run's folder; on a package task a failure becomes a
        :class:`~sb3_saeir.config.ConfigError` of one line (the launcher removes a new run's folder)."""
        if not self.zoo_train.package_env:
            return super().setup_experiment()
        try:
            result = super().setup_experiment()
            loaded = None
            if result is not None and self.trained_agent:  # -i: what trains (resumed too: the record compares it)
                requested = (self.custom_hyperparams or {}).get("policy_kwargs")
                loaded = loaded_network(result[0], self.trained_agent, requested, result[1].get("policy_kwargs"))
        except Exception as error:
            raise ConfigError(f"cannot set up {self.algo} on {self.env_name}: {one_line(error)}") from error
        self.saeir_config = dict(result[1]) if result is not None else {}
        if loaded is not None:  # the run's record says which network trains
            self.saeir_config["policy_kwargs"] = loaded
        return result

    def _save_config(self, saved_hyperparams: dict[str, Any]) -> None:
        """rl-zoo3's ``config.yml`` and ``args.yml``, for a new run only (a resumed run keeps its own)."""
        if self.zoo_train.folder is None or self.zoo_train.folder.record is None:
            super()._save_config(saved_hyperparams)

    def learn(self, model: BaseAlgorithm) -> None:
        """On a package task, the run: :meth:`~sb3_saeir.run.run.Run.execute` in rl-zoo3's run folder, on the env and the
        model rl-zoo3 built (or loaded with ``-i``). Its evaluations (game episodes, the task's main metric; at the
        start, every ``--eval-freq // n_envs`` vec steps on the grid, at the end) and resumable checkpoints (every
        ``--save-freq // n_envs`` vec steps) take the place of rl-zoo3's evaluation and checkpoint callbacks (the
        effective periods are rl-zoo3's); with ``--resume``, the run goes on from its folder's checkpoint.

        :param model: the model rl-zoo3 built
        """
        if not self.zoo_train.package_env:
            super().learn(model)
            return
        env = model.get_env()
        assert env is not None
        for callback in self.callbacks:
            if isinstance(callback, EvalCallback):
                callback.eval_env.close()
        callbacks = [c for c in self.callbacks if not isinstance(c, (EvalCallback, CheckpointCallback))]
        task = self.env_name.gym_id

        def period(freq: int) -> int:
            """rl-zoo3's callback period in agent-steps (0: off); its setup already made ``--eval-freq`` and
            ``--save-freq`` ``freq // n_envs`` vec steps, and a vec step is ``env.num_envs`` agent-steps."""
            return freq * env.num_envs if freq > 0 else 0

        options = {"--save-freq": self.save_freq, "-i": self.trained_agent, "--device": self.device}
        spec = RunSpec(
            self.algo, task, self.seed, int(self.n_timesteps), self.n_envs, period(self.eval_freq),
            self.n_eval_episodes, {}, config_record(self.saeir_config), options, vars(self.args),
        )  # fmt: skip
        run = Run(
            spec,
            save_freq=period(self.save_freq) or sys.maxsize,  # never but on Ctrl-C
            continue_model=bool(self.trained_agent),
        )
        experiment = Experiment(self.algo, task, {"env_kwargs": dict(self.env_kwargs)}, seed=self.seed, n_games=self.n_envs)
        experiment.attach(model)
        callbacks.append(BudgetEstimate(spec.n_timesteps))
        assert self.zoo_train.folder is not None
        run.execute(
            self.zoo_train.folder,
            experiment,
            output=RunOutput(
                command_line=True,
                verbose=self.verbose,
                progress_bar=self.show_progress,
                callbacks=callbacks,
                announce=_announce_resume,
            ),
        )
        assert run.checkpoints is not None
        self.zoo_train.stop_line, self.zoo_train.stop_signal = run.stop_line(), run.stop_signal

    def save_trained_model(self, model: BaseAlgorithm) -> None:
        """On a package task nothing: the run saved ``<task>.zip`` (:meth:`learn`)."""
        if not self.zoo_train.package_env:
            super().save_trained_model(model)


def _announce_resume(run: Run, experiment: Experiment) -> None:
    if run.resume is not None:
        print(f"Resuming {run.folder} from {run.resume.checkpoint.name}")


def one_line(error: BaseException) -> str:
    """An error as one line: our messages as they are, another library's with its type (first line only)."""
    text = error.args[0] if isinstance(error, KeyError) and error.args else str(error)
    first = str(text).strip().splitlines()[0] if str(text).strip() else "(no message)"
    return first if isinstance(error, ConfigError) else f"{type(error).__name__}: {first}"
