"""Plain SB3 PPO (and a random policy) on variants of the sparse navigation reward: which part blocks learning?

    python benchmarks/reward_variants.py --timesteps 1000000 \
        --variants '{}' '{"collision_penalty": 0.0}' '{"cover_radius": 0.2}'

Each variant is a JSON dict of ``SparseCooperativeNavigation`` keyword arguments (``cover_radius``,
``collision_penalty``). PPO uses the same settings as ``examples/train_cn_sparse.py --algo ppo`` (16 games,
``n_steps=125``, ``batch_size=500``, ``n_epochs=10``, SB3 defaults otherwise); the random policy draws uniform
actions. Each line printed is one JSON record: final-step coverage rate over ``--eval-episodes`` episodes with
deterministic and stochastic actions (the random policy: stochastic only), coverage averaged over steps, wall time.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import torch as th
from stable_baselines3 import PPO

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy


def run(algo: str, task: str, variant: dict[str, Any], timesteps: int, eval_episodes: int, seed: int) -> dict[str, Any]:
    """Train (PPO) or draw (random) on one reward variant and evaluate; returns one record."""
    start = time.perf_counter()
    env = make_multiagent_vec_env(task, n_games=16, seed=seed, **variant)
    eval_env = make_multiagent_vec_env(task, n_games=10, seed=12_345, **variant)
    record: dict[str, Any] = {"algo": algo, "task": task, "variant": variant, "seed": seed}
    if algo == "ppo":
        model = PPO("MlpPolicy", env, n_steps=125, batch_size=500, n_epochs=10, seed=seed).learn(timesteps)
        deterministic = evaluate_multiagent_policy(model, eval_env, n_episodes=eval_episodes, deterministic=True)
        stochastic = evaluate_multiagent_policy(model, eval_env, n_episodes=eval_episodes, deterministic=False)
        record.update(
            timesteps=timesteps,
            coverage_deterministic=round(deterministic["coverage_rate_mean"], 4),
            coverage_over_steps_deterministic=round(deterministic["coverage_over_steps_mean"], 4),
            coverage_stochastic=round(stochastic["coverage_rate_mean"], 4),
        )
    else:
        result = evaluate_multiagent_policy(RandomMultiAgentPolicy(env.action_space, seed), eval_env, n_episodes=eval_episodes)
        record.update(
            coverage_stochastic=round(result["coverage_rate_mean"], 4),
            coverage_over_steps_stochastic=round(result["coverage_over_steps_mean"], 4),
        )
    record["wall_s"] = round(time.perf_counter() - start)
    env.close()
    eval_env.close()
    return record


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algos", nargs="+", choices=["random", "ppo"], default=["random", "ppo"])
    parser.add_argument("--task", default="cn-sparse-n3")
    parser.add_argument("--variants", nargs="+", default=["{}", '{"collision_penalty": 0.0}', '{"cover_radius": 0.2}'])
    parser.add_argument("--timesteps", type=int, default=1_000_000, help="PPO agent-steps per variant")
    parser.add_argument("--eval-episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    th.set_num_threads(1)
    for raw in args.variants:
        variant = json.loads(raw)
        for algo in args.algos:
            print(json.dumps(run(algo, args.task, variant, args.timesteps, args.eval_episodes, args.seed)), flush=True)


if __name__ == "__main__":
    main()
