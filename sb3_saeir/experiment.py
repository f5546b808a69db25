"""One experiment object behind every command line: a method's config on a task, built, trained, saved.

:class:`Experiment` is what ``python -m sb3_saeir.train``, the benchmark, ``python -m sb3_saeir.zoo train`` and the
Optuna trials share, as rl-zoo3's ``ExperimentManager`` is for rl-zoo3: the training and evaluation envs, the model
from the packaged (or given) config, its callbacks, ``learn`` and ``save``; a run in a folder is a
:class:`~sb3_saeir.run.run.Run` of it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv

from sb3_saeir.common.atomic import save_model
from sb3_saeir.common.run_state import load_resume_state
from sb3_saeir.common.utils import MAX_SEED
from sb3_saeir.common.vec_env import make_multiagent_vec_env
from sb3_saeir.config import (
    ALGOS,
    DEFAULT_N_GAMES,
    ModelSettings,
    build_callbacks,
    check_algo,
    check_count,
    load_hyperparams,
    loaded_network,
    model_settings,
    parse_policy_kwargs,
)
from sb3_saeir.envs import get_task_spec

# Seed offset of evaluation envs: evaluation games never replay the training games' seeds.
EVAL_SEED_OFFSET = 10_000


def evaluation_seed(seed: int) -> int:
    """The base seed of a run's evaluation games: ``10_000 + seed``, wrapped into the seeds' range ``0 .. 2**32 - 1``
    (every seed the package accepts has one: ``--seed 4294967295`` evaluates on base seed 9999).

    :param seed: the run's seed
    """
    return (EVAL_SEED_OFFSET + seed) % (MAX_SEED + 1)


# At most this many games play an evaluation in parallel.
MAX_EVAL_GAMES = 10


class Experiment:
    """A method's config entry on a task: builds the envs and the model, trains and saves (nothing written but by
    :meth:`save`: a run in a folder, with its evaluations and checkpoints, is a :class:`~sb3_saeir.run.run.Run`)::

        experiment = Experiment("saeir_ppo", "cn-sparse-n3", seed=0, n_games=16)
        experiment.build()
        experiment.learn(200_000)
        experiment.save("saeir_cn3.zip")

    :param algo: method name (a key of :data:`sb3_saeir.config.ALGOS`, e.g. ``"saeir_ppo"``)
    :param task: task id (e.g. ``"cn-sparse-n3"``)
    :param hyperparams: the config entry (default: the packaged ``zoo_configs/<algo>.yml`` entry of ``task``)
    :param seed: seed of the model and the training env (game ``g`` gets ``seed + g``)
    :param n_games: override the config's ``n_envs`` (number of games)
    :param num_cpus: env worker processes of the training env (0: every game in this process); overrides the config's
        ``num_cpus``
    """

    def __init__(
        self,
        algo: str,
        task: str,
        hyperparams: dict[str, Any] | None = None,
        seed: int = 0,
        n_games: int | None = None,
        num_cpus: int | None = None,
    ) -> None:
        check_algo(algo)
        get_task_spec(task)  # an unknown id: a KeyError naming the registered tasks, here rather than at build()
        self.algo = algo
        self.task = task
        self.hyperparams = dict(load_hyperparams(algo, task) if hyperparams is None else hyperparams)
        self.seed = seed
        games = n_games if n_games is not None else self.hyperparams.get("n_envs", DEFAULT_N_GAMES)
        cpus = num_cpus if num_cpus is not None else self.hyperparams.get("num_cpus", 0)
        self.n_games = check_count("Experiment", "n_games", games, 1)
        self.num_cpus = check_count("Experiment", "num_cpus", cpus, 0)
        self.model: BaseAlgorithm | None = None
        self.env: VecEnv | None = None
        self.config_callbacks: list[BaseCallback] = []
        self.resolved_hyperparams: dict[str, Any] = {}
        self._eval_envs: list[VecEnv] = []

    # ------------------------------------------------------------------------------------------------ settings
    @property
    def env_kwargs(self) -> dict[str, Any]:
        """The task's keyword arguments from the config (``env_kwargs``)."""
        return parse_policy_kwargs(self.hyperparams.get("env_kwargs"))

    @property
    def n_timesteps(self) -> int:
        """Training budget in agent-steps (the config's ``n_timesteps``)."""
        return config_budget(self.hyperparams)

    @property
    def main_metric(self) -> str:
        """The task's main metric (``coverage_rate``, ``success`` or ``r``)."""
        return get_task_spec(self.task).main_metric

    # ------------------------------------------------------------------------------------------------ envs
    def make_env(self) -> VecEnv:
        """The training env: ``n_games`` games seeded from ``seed`` (a run monitors it into its folder:
        :meth:`~sb3_saeir.run.run.Run.make_env`)."""
        return make_multiagent_vec_env(
            self.task, n_games=self.n_games, seed=self.seed, num_cpus=self.num_cpus, **self.env_kwargs
        )

    def make_eval_env(self, n_episodes: int, seed: int | None = None) -> VecEnv:
        """An evaluation env of ``min(n_episodes, 10)`` games (closed by :meth:`close`).

        :param n_episodes: game episodes per evaluation
        :param seed: base seed (default ``10_000 + seed``, apart from the training games: :func:`evaluation_seed`)
        """
        eval_seed = evaluation_seed(self.seed) if seed is None else seed
        env = make_multiagent_vec_env(
            self.task, n_games=max(1, min(n_episodes, MAX_EVAL_GAMES)), seed=eval_seed, **self.env_kwargs
        )
        self._eval_envs.append(env)
        return env

    # ------------------------------------------------------------------------------------------------ model
    def build(
        self,
        env: VecEnv | None = None,
        verbose: int | None = None,
        device: str | None = None,
        tensorboard_log: str | None = None,
    ) -> OnPolicyAlgorithm:
        """Build the training env (unless given) and the model from the config entry
        (:func:`~sb3_saeir.config.model_settings`: its ``policy`` and ``policy_kwargs``, every algorithm argument) with
        the experiment's seed; the entry's ``callback`` entries become :attr:`config_callbacks` (passed to ``learn``
        by :meth:`learn`).

        :param env: use this multi-agent vec env (possibly wrapped) instead of :meth:`make_env`
        :param verbose: the algorithm's verbosity (default: the config's, else the algorithm's)
        :param device: torch device (default: the config's, else the algorithm's)
        :param tensorboard_log: tensorboard log folder (default: the config's, else none)
        :return: the model (also ``self.model``; the env is ``self.env``, the resolved config
            ``self.resolved_hyperparams``)
        """
        self.env = env if env is not None else self.make_env()
        settings = self._settings(verbose=verbose, device=device, tensorboard_log=tensorboard_log)
        arguments = settings.algorithm_kwargs
        model = ALGOS[self.algo](settings.policy, self.env, policy_kwargs=settings.policy_kwargs, seed=self.seed, **arguments)
        self.model = model
        return model

    def load(
        self,
        path: str | Path,
        env: VecEnv | None = None,
        device: str = "cpu",
        tensorboard_log: str | None = None,
        verbose: int | None = None,
        requested_policy_kwargs: Any = None,
    ) -> BaseAlgorithm:
        """Load a saved model of this method onto the training env (``env``, else the one built before, else a new
        one from :meth:`make_env`), to continue training it with the config's hyperparameters, as rl-zoo3's ``-i``
        does: every algorithm argument of the config (``learning_rate``, ``n_steps``, ``n_epochs``, ``compile``, ...)
        and the experiment's seed apply to the loaded model; its network is the one it was saved with (``policy`` and
        ``policy_kwargs`` do not apply: :func:`loaded_network`, whose record of that network
        :attr:`resolved_hyperparams` then holds). A setting that cannot apply to the saved model is refused by the
        algorithm's ``load``.

        :param path: the model zip
        :param env: use this multi-agent vec env as the training env
        :param device: torch device
        :param tensorboard_log: tensorboard log folder (default: the config's, else the saved model's)
        :param verbose: verbosity (default: the config's, else the saved model's)
        :param requested_policy_kwargs: the command's ``-params policy_kwargs`` (``None``: not given), refused when it
            asks for another network than the saved one
        """
        self._use_env(env)
        settings = self._settings(verbose=verbose, tensorboard_log=tensorboard_log)
        self.model = ALGOS[self.algo].load(path, env=self.env, device=device, seed=self.seed, **settings.algorithm_kwargs)
        network = loaded_network(self.model, path, requested_policy_kwargs, self.hyperparams.get("policy_kwargs"))
        if network is not None:  # the run's record says which network trains
            self.resolved_hyperparams["policy_kwargs"] = network
        return self.model

    def _use_env(self, env: VecEnv | None) -> None:
        """Take ``env`` as the training env of a model loaded onto it, else keep the one built before, else make one."""
        if env is not None:
            self.env = env
        elif self.env is None:
            self.env = self.make_env()

    def _settings(
        self, verbose: int | None = None, device: str | None = None, tensorboard_log: str | None = None
    ) -> ModelSettings:
        """The config entry's model settings on the training env, with the arguments given here in place of the
        config's; its callbacks and resolved entry become the experiment's."""
        assert self.env is not None
        settings = model_settings(self.hyperparams, self.n_games, self.env)
        for name, value in (("verbose", verbose), ("device", device), ("tensorboard_log", tensorboard_log)):
            if value is not None:
                settings.algorithm_kwargs[name] = value
        self.config_callbacks, self.resolved_hyperparams = settings.callbacks, settings.resolved
        return settings

    def attach(self, model: BaseAlgorithm) -> BaseAlgorithm:
        """Take a model built elsewhere (by rl-zoo3's ``ExperimentManager``) as this experiment's, its env as the
        training env.

        :param model: the model, on a multi-agent vec env
        """
        self.model, self.env = model, model.get_env()
        return model

    def resume(self, checkpoint: str | Path, device: str = "cpu", tensorboard_log: str | None = None) -> dict[str, Any] | None:
        """Load a checkpoint's model onto the training env, with the settings it was saved with (only the config's
        ``compile``, a setting of the machine, applies), and return its resume state, for a
        :class:`~sb3_saeir.common.run_state.RunCheckpointCallback` to restore at the first rollout (``None``: the zip
        is a plain model, with no resume state).

        :param checkpoint: a checkpoint zip written by :func:`~sb3_saeir.common.run_state.save_checkpoint`
        :param device: torch device
        :param tensorboard_log: tensorboard log folder
        """
        self._use_env(None)
        self.config_callbacks = build_callbacks(self.hyperparams.get("callback"))
        # the checkpoint's own settings; the config's compile (a setting of the machine, not saved) applies
        settings = {"compile": self.hyperparams["compile"]} if "compile" in self.hyperparams else {}
        self.model = ALGOS[self.algo].load(
            checkpoint, env=self.env, device=device, tensorboard_log=tensorboard_log, **settings
        )
        self.resolved_hyperparams = {**self.hyperparams, "n_envs": self.n_games}
        return load_resume_state(Path(checkpoint))

    def learn(
        self,
        total_timesteps: int | None = None,
        callbacks: list[BaseCallback] | None = None,
        progress_bar: bool = False,
        reset_num_timesteps: bool = True,
    ) -> BaseAlgorithm:
        """Train the built model with the config's callbacks plus ``callbacks``.

        :param total_timesteps: agent-steps (default: the config's ``n_timesteps``)
        :param callbacks: extra callbacks (evaluation, checkpoints, ...)
        :param progress_bar: SB3's progress bar
        :param reset_num_timesteps: start the step counter at 0 (``False`` to continue a loaded model)
        """
        if self.model is None:
            raise RuntimeError("Experiment.learn: call build() (or load()) first.")
        return self.model.learn(
            self.n_timesteps if total_timesteps is None else total_timesteps,
            callback=[*self.config_callbacks, *(callbacks or [])],
            progress_bar=progress_bar,
            reset_num_timesteps=reset_num_timesteps,
        )

    def save(self, path: str | Path) -> Path:
        """Save the model, atomically (:func:`~sb3_saeir.common.atomic.save_model`: an interrupted or failed save
        leaves the file that was there whole); returns the zip's path (``.zip`` added to a path without suffix)."""
        if self.model is None:
            raise RuntimeError("Experiment.save: nothing to save, call build() first.")
        return save_model(self.model, path)

    def close(self) -> None:
        """Close the training env and every eval env this experiment made."""
        for env in [self.env, *self._eval_envs]:
            if env is not None:
                env.close()
        self.env = None
        self._eval_envs = []


def config_budget(hyperparams: dict[str, Any]) -> int:
    """A config entry's training budget in agent-steps: its ``n_timesteps`` (default 1,000,000)."""
    return int(hyperparams.get("n_timesteps", 1_000_000))
