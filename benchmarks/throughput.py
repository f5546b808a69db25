"""Agent-steps per second on a multi-agent vec env: random stepping and training, in one run.

    python benchmarks/throughput.py --task cn-sparse-n3 --n-games 16 --steps 100000 --algos random ppo

Every algorithm gets the same ``n_steps``, ``n_epochs`` and ``batch_size``; the ratios to the first trained algorithm
are printed. Timings on shared machines are noisy: compare ratios from one run, not absolute figures across runs.
"""

from __future__ import annotations

import argparse
import resource
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch as th
from stable_baselines3 import PPO

from sb3_saeir import make_multiagent_vec_env


def random_stepping(task: str, n_games: int, agent_steps: int, seed: int) -> float:
    """Agent-steps/s of uniformly random actions."""
    env = make_multiagent_vec_env(task, n_games=n_games, seed=seed)
    rng = np.random.default_rng(seed)
    env.reset()
    n_vec_steps = max(1, agent_steps // env.num_envs)
    start = time.perf_counter()
    for _ in range(n_vec_steps):
        env.step(rng.integers(0, env.action_space.n, size=env.num_envs))
    elapsed = time.perf_counter() - start
    env.close()
    return n_vec_steps * env.num_envs / elapsed


def algorithm_builders() -> dict[str, Callable[..., Any]]:
    """Name -> ``builder(env, **common_kwargs)``; algorithms that are not installed yet are skipped."""
    builders: dict[str, Callable[..., Any]] = {"ppo": lambda env, **kw: PPO("MlpPolicy", env, **kw)}
    try:
        from sb3_saeir import SAEIR_PPO  # type: ignore[attr-defined]

        builders["saeir_ppo"] = lambda env, **kw: SAEIR_PPO("MSHGPolicy", env, **kw)
    except ImportError:
        pass
    return builders


def training(builder: Callable[..., Any], task: str, n_games: int, agent_steps: int, seed: int, **kwargs: Any) -> float:
    """Agent-steps/s of ``learn`` (rollout + update)."""
    env = make_multiagent_vec_env(task, n_games=n_games, seed=seed)
    model = builder(env, seed=seed, **kwargs)
    start = time.perf_counter()
    model.learn(agent_steps)
    elapsed = time.perf_counter() - start
    steps = model.num_timesteps
    env.close()
    return steps / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="cn-sparse-n3")
    parser.add_argument("--n-games", type=int, default=16)
    parser.add_argument("--steps", type=int, default=100_000, help="agent-steps per measurement")
    parser.add_argument("--algos", nargs="+", default=["random", "ppo", "saeir_ppo"])
    parser.add_argument("--n-steps", type=int, default=25)
    parser.add_argument("--n-epochs", type=int, default=10)
    parser.add_argument("--batch-size", type=int, default=None, help="default: the whole rollout (one minibatch)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    th.set_num_threads(1)

    n_agents = make_multiagent_vec_env(args.task, n_games=1).n_agents
    batch_size = args.batch_size or args.n_steps * args.n_games * n_agents
    common = dict(n_steps=args.n_steps, n_epochs=args.n_epochs, batch_size=batch_size)
    builders = algorithm_builders()
    results: dict[str, float] = {}
    for algo in args.algos:
        if algo == "random":
            results[algo] = random_stepping(args.task, args.n_games, args.steps, args.seed)
        elif algo in builders:
            results[algo] = training(builders[algo], args.task, args.n_games, args.steps, args.seed, **common)
        else:
            print(f"skipping {algo}: not available")
            continue
        print(f"{algo:>12}: {results[algo]:9.0f} agent-steps/s", flush=True)
    trained = [algo for algo in results if algo != "random"]
    if trained:
        reference = trained[0]
        for algo in trained[1:]:
            print(f"ratio {algo}/{reference}: {results[algo] / results[reference]:.2f}")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"task {args.task}, {args.n_games} games, {args.steps} agent-steps, {common}; peak RSS {peak_mb:.0f} MB")


if __name__ == "__main__":
    main()
