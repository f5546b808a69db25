"""Train on sparse Cooperative Navigation, evaluate, and print where the model and metrics are.

    python examples/train_cn_sparse.py --timesteps 300000

This is the README's main job (``bash scripts/quickstart.sh``).
"""

from __future__ import annotations

import argparse
import json
import os

import torch as th
from stable_baselines3 import PPO
from stable_baselines3.common.logger import configure

from sb3_saeir import SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.callbacks import EpisodeMetricsCallback
from sb3_saeir.evaluation import evaluate_multiagent_policy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", choices=["saeir_ppo", "ppo"], default="saeir_ppo", help="ppo: plain SB3 PPO (IPPO)")
    parser.add_argument("--task", default="cn-sparse-n3")
    parser.add_argument(
        "--n-games", type=int, default=128, help="games per rollout (128: the paper's; 16 stalls with its hyperparameters)"
    )
    parser.add_argument("--timesteps", type=int, default=300_000, help="agent-steps")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-episodes", type=int, default=100)
    parser.add_argument("--out", default="runs/quickstart")
    args = parser.parse_args()
    th.set_num_threads(1)

    env = make_multiagent_vec_env(args.task, n_games=args.n_games, seed=args.seed)
    if args.algo == "saeir_ppo":  # the paper's Cooperative Navigation settings are SAEIR_PPO's defaults
        model = SAEIR_PPO("MSHGPolicy", env, seed=args.seed)
        callback = None
    else:
        model = PPO("MlpPolicy", env, n_steps=125, batch_size=500, n_epochs=10, seed=args.seed)
        callback = EpisodeMetricsCallback()
    model.set_logger(configure(args.out, ["stdout", "csv", "tensorboard"]))
    model.learn(args.timesteps, callback=callback, log_interval=10)
    model_path = os.path.join(args.out, "model.zip")
    model.save(model_path)

    eval_env = make_multiagent_vec_env(args.task, n_games=10, seed=args.seed + 10_000)
    metrics = evaluate_multiagent_policy(model, eval_env, n_episodes=args.eval_episodes)
    with open(os.path.join(args.out, "eval.json"), "w") as file:
        json.dump(metrics, file, indent=2)
    print(f"model:    {model_path}")
    print(f"metrics:  {os.path.join(args.out, 'progress.csv')} (training), {os.path.join(args.out, 'eval.json')} (evaluation)")
    print(
        f"eval on {int(metrics['n_episodes'])} episodes: coverage rate {metrics['coverage_rate_mean']:.3f} "
        f"(final step; mean over steps {metrics['coverage_over_steps_mean']:.3f}), team return {metrics['ep_rew_mean']:.2f}"
    )


if __name__ == "__main__":
    main()
