"""Hyperparameter search with Optuna (rl-zoo's conventions): search spaces and the ``--optimize`` loop.

Several workers, on one machine or many, share a study through one storage URL::

    python -m sb3_saeir.train --algo saeir_ppo --task cn-sparse-n3 --optimize --n-trials 20 -n 200000 \\
        --storage postgresql://user:password@host/db --study-name saeir_cn3

Without ``--storage`` the study lives in a SQLite file in the log folder. Each trial trains with the sampled
hyperparameters, evaluates ``--n-evaluations`` times (intermediate values feed the pruner) and returns the task's main
metric (coverage rate for navigation, success rate for football). Trials record their worker (``host:pid``).
"""

from __future__ import annotations

import argparse
import os
import random
import socket
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import optuna
import sqlalchemy.exc
from stable_baselines3.common.callbacks import BaseCallback

from sb3_saeir.common.callbacks import EveryAgentSteps
from sb3_saeir.common.utils import MAX_SEED
from sb3_saeir.config import parse_policy_kwargs
from sb3_saeir.envs import get_task_spec, make_task
from sb3_saeir.evaluation import evaluate_multiagent_policy, score
from sb3_saeir.experiment import EVAL_SEED_OFFSET, Experiment


def sample_ppo_params(trial: optuna.Trial) -> dict[str, Any]:
    """Search space shared by every method: learning rate, epochs, entropy coefficient, recurrent chunk length."""
    return {
        "learning_rate": trial.suggest_float("learning_rate", 1e-4, 2e-3, log=True),
        "n_epochs": trial.suggest_categorical("n_epochs", [5, 10, 15]),
        "ent_coef": trial.suggest_float("ent_coef", 1e-3, 5e-2, log=True),
        "data_chunk_length": trial.suggest_categorical("data_chunk_length", [5, 10]),
    }


def sample_saeir_ppo_params(trial: optuna.Trial, n_agents: int) -> dict[str, Any]:
    """SAEIR_PPO: the shared space plus beta, the group size k and the number of edge types."""
    params = sample_ppo_params(trial)
    params["intrinsic_coef"] = trial.suggest_float("intrinsic_coef", 1e-2, 1.0, log=True)
    params["policy_kwargs"] = {
        # k < N: with k = N every group hyperedge holds the whole team and the group critic copies the team critic
        "group_size": trial.suggest_int("group_size", 2, max(2, n_agents - 1)),
        "n_edge_types": trial.suggest_int("n_edge_types", 1, 4),
    }
    return params


def sample_mshg_only_params(trial: optuna.Trial, n_agents: int) -> dict[str, Any]:
    """MSHG-only ablation: SAEIR's space without the bonus coefficient."""
    params = sample_saeir_ppo_params(trial, n_agents)
    params.pop("intrinsic_coef")
    return params


def sample_ippo_params(trial: optuna.Trial, n_agents: int) -> dict[str, Any]:
    """IPPO (SB3 PPO): learning rate, epochs, entropy coefficient."""
    return {
        "learning_rate": trial.suggest_float("learning_rate", 1e-4, 2e-3, log=True),
        "n_epochs": trial.suggest_categorical("n_epochs", [5, 10, 15]),
        "ent_coef": trial.suggest_float("ent_coef", 1e-3, 5e-2, log=True),
    }


def sample_mappo_params(trial: optuna.Trial, n_agents: int) -> dict[str, Any]:
    """MAPPO and SN-MAPPO: the shared space."""
    return sample_ppo_params(trial)


def sample_bonus_params(trial: optuna.Trial, n_agents: int) -> dict[str, Any]:
    """Methods with a bonus on MAPPO's critic (RND, Elign, SAE-only): the shared space plus the bonus coefficient."""
    params = sample_ppo_params(trial)
    params["intrinsic_coef"] = trial.suggest_float("intrinsic_coef", 1e-2, 2.0, log=True)
    return params


# Method -> its search space (rl-zoo's HYPERPARAMS_SAMPLER).
HYPERPARAMS_SAMPLER: dict[str, Callable[[optuna.Trial, int], dict[str, Any]]] = {
    "saeir_ppo": sample_saeir_ppo_params,
    "mshg_only": sample_mshg_only_params,
    "ippo": sample_ippo_params,
    "mappo": sample_mappo_params,
    "sn_mappo": sample_mappo_params,
    "rnd": sample_bonus_params,
    "elign": sample_bonus_params,
    "sae_only": sample_bonus_params,
}


def sample_params(trial: optuna.Trial, algo: str, n_agents: int) -> dict[str, Any]:
    """Hyperparameters of one trial for a method."""
    return HYPERPARAMS_SAMPLER[algo](trial, n_agents)


def merge_params(hyperparams: dict[str, Any], sampled: dict[str, Any]) -> dict[str, Any]:
    """Config entry updated with sampled values (``policy_kwargs`` merged key by key)."""
    merged = dict(hyperparams)
    for key, value in sampled.items():
        if key == "policy_kwargs":
            merged["policy_kwargs"] = {**parse_policy_kwargs(hyperparams.get("policy_kwargs")), **value}
        else:
            merged[key] = value
    return merged


class TrialEvalCallback(BaseCallback):
    """Evaluate (each time it runs), report to Optuna, stop the run when the pruner says so. Wrapped in
    :class:`~sb3_saeir.common.callbacks.EveryAgentSteps` to run every ``eval_freq`` agent-steps."""

    def __init__(self, trial: optuna.Trial, eval_env: Any, n_episodes: int, metric: str) -> None:
        super().__init__()
        self.trial = trial
        self.eval_env = eval_env
        self.n_episodes = n_episodes
        self.metric = metric
        self.n_evaluations = 0
        self.last_score = float("-inf")
        self.is_pruned = False

    def _on_step(self) -> bool:
        self.last_score = score(evaluate_multiagent_policy(self.model, self.eval_env, self.n_episodes), self.metric)
        self.n_evaluations += 1
        self.trial.report(self.last_score, self.n_evaluations)
        if self.trial.should_prune():
            self.is_pruned = True
            return False
        return True


def objective_factory(args: argparse.Namespace, hyperparams: dict[str, Any]) -> Callable[[optuna.Trial], float]:
    """The Optuna objective: one :class:`~sb3_saeir.experiment.Experiment` per trial, with sampled hyperparameters,
    evaluated ``--n-evaluations`` times (for the pruner), scored by the task's main metric at the end."""
    metric = get_task_spec(args.task).main_metric
    probe = make_task(args.task, **dict(hyperparams.get("env_kwargs") or {}))
    n_agents = len(probe.possible_agents)
    probe.close()
    n_timesteps = int(hyperparams.get("n_timesteps", 1e5))

    def objective(trial: optuna.Trial) -> float:
        trial.set_user_attr("worker", f"{socket.gethostname()}:{os.getpid()}")
        params = merge_params(hyperparams, sample_params(trial, args.algo, n_agents))
        seed = (args.seed + trial.number) % (MAX_SEED + 1)  # trial k: seed + k, wrapped as evaluation seeds are
        experiment = Experiment(args.algo, args.task, params, seed=seed)
        experiment.build(verbose=0)
        eval_env = experiment.make_eval_env(args.eval_episodes, seed=EVAL_SEED_OFFSET)
        evaluator = TrialEvalCallback(trial, eval_env, args.eval_episodes, metric)
        try:
            experiment.learn(n_timesteps, callbacks=[EveryAgentSteps(evaluator, max(1, n_timesteps // args.n_evaluations))])
            final = score(evaluate_multiagent_policy(experiment.model, eval_env, args.eval_episodes), metric)
        finally:
            experiment.close()
        if evaluator.is_pruned:
            raise optuna.TrialPruned()
        return final

    return objective


def create_or_load_study(
    study_name: str,
    storage: str,
    sampler: optuna.samplers.BaseSampler,
    pruner: optuna.pruners.BasePruner,
    max_attempts: int = 5,
) -> optuna.Study:
    """Create the study, or load it if another worker already did.

    Workers started together on a fresh database race to create Optuna's tables: the loser gets a database error
    (a duplicate table or type) even though the schema is now there. Retry a few times after a short random pause;
    a storage that keeps failing (wrong URL, server down) re-raises the last error.

    :param study_name: Study name shared by the workers.
    :param storage: Optuna storage URL.
    :param sampler: Sampler of this worker.
    :param pruner: Pruner of this worker.
    :param max_attempts: Attempts before giving up.
    :return: The study.
    """
    for attempt in range(1, max_attempts + 1):
        try:
            return optuna.create_study(
                study_name=study_name,
                storage=storage,
                sampler=sampler,
                pruner=pruner,
                direction="maximize",
                load_if_exists=True,
            )
        except sqlalchemy.exc.DBAPIError as error:
            if attempt == max_attempts:
                raise
            print(f"Study storage not ready ({type(error).__name__}), retrying ({attempt}/{max_attempts - 1})")
            time.sleep(random.uniform(0.5, 2.0) * attempt)
    raise AssertionError("unreachable")


def optimize(args: argparse.Namespace, hyperparams: dict[str, Any]) -> optuna.Study:
    """Run ``args.n_trials`` trials of this worker in the shared (or local SQLite) study."""
    study_name = args.study_name or f"{args.algo}_{args.task}"
    storage = args.storage
    if storage is None:
        folder = Path(args.log_folder) / args.algo
        folder.mkdir(parents=True, exist_ok=True)
        storage = f"sqlite:///{(folder / f'{study_name}.db').resolve()}"
    sampler = optuna.samplers.RandomSampler(seed=args.seed) if args.sampler == "random" else optuna.samplers.TPESampler()
    pruner = optuna.pruners.MedianPruner(n_startup_trials=2) if args.pruner == "median" else optuna.pruners.NopPruner()
    study = create_or_load_study(study_name, storage, sampler, pruner)
    study.optimize(objective_factory(args, hyperparams), n_trials=args.n_trials, n_jobs=args.n_jobs)
    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    if complete:
        print(f"Best trial of study {study_name!r} ({len(study.trials)} trials): value {study.best_value:.4f}")
        for key, value in study.best_params.items():
            print(f"    {key}: {value}")
    print(f"Study storage: {storage}")
    return study
