"""Sanity check of the learners on the dense reward: mpe2 ``simple_spread_v3`` (reward = minus distances).

If SAEIR_PPO fails the sparse task, this tells "the learner is broken" apart from "the task is hard at this budget".

    python benchmarks/dense_spread.py --algos random saeir_ppo ppo --timesteps 300000

Same vector env (16 games, seed 0) and evaluation (10 games, seed 999, 100 episodes, deterministic) for every method;
plain PPO uses ``n_steps=125, batch_size=500, n_epochs=10``. Prints the mean team return of each.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import torch as th
from gymnasium import spaces
from mpe2 import simple_spread_v3
from pettingzoo import ParallelEnv
from stable_baselines3 import PPO

from sb3_saeir import SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy


def dense_spread() -> ParallelEnv:
    """Dense Cooperative Navigation with 3 agents, 25 steps, discrete actions."""
    return simple_spread_v3.parallel_env(N=3, max_cycles=25, continuous_actions=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algos", nargs="+", default=["random", "saeir_ppo", "ppo"], choices=["random", "saeir_ppo", "ppo"])
    parser.add_argument("--timesteps", type=int, default=300_000, help="agent-steps per learner")
    args = parser.parse_args()
    th.set_num_threads(1)
    for algo in args.algos:
        start = time.time()
        env = make_multiagent_vec_env(dense_spread, n_games=16, seed=0)
        assert isinstance(env.action_space, spaces.Discrete)
        policy: Any
        if algo == "random":
            policy = RandomMultiAgentPolicy(env.action_space)
        elif algo == "saeir_ppo":
            policy = SAEIR_PPO("MSHGPolicy", env, seed=0).learn(args.timesteps)
        else:
            policy = PPO("MlpPolicy", env, n_steps=125, batch_size=500, n_epochs=10, seed=0).learn(args.timesteps)
        eval_env = make_multiagent_vec_env(dense_spread, n_games=10, seed=999)
        metrics = evaluate_multiagent_policy(policy, eval_env, n_episodes=100)
        budget = 0 if algo == "random" else args.timesteps
        print(f"{algo:10s} {budget:>9d} agent-steps: team return {metrics['ep_rew_mean']:.2f} ({time.time() - start:.0f} s)")


if __name__ == "__main__":
    main()
