"""Agent-steps per second on a multi-agent vec env: random stepping and training of each method, in one run.

    python benchmarks/throughput.py --task cn-sparse-n3 --n-games 16 --steps 100000 --algos random ippo mappo saeir_ppo

Each method trains with its packaged config (``zoo_configs/<algo>.yml``) except the number of games; all configs
share ``n_steps=25``, ``n_epochs=10`` and one minibatch per epoch (the whole rollout), so every method gets the same
rollout and update schedule. Ratios to the first trained method are printed. Timings on shared machines are noisy:
compare ratios from one run, not absolute figures across runs.
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np
import torch as th

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.config import ALGOS, build_model


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


def training(algo: str, task: str, n_games: int, agent_steps: int, seed: int) -> float:
    """Agent-steps/s of ``learn`` (rollout + update) with the method's packaged config (``zoo_configs/<algo>.yml``)."""
    model, env, callbacks, _ = build_model(algo, task, n_games=n_games, seed=seed)
    start = time.perf_counter()
    model.learn(agent_steps, callback=callbacks)
    elapsed = time.perf_counter() - start
    steps = model.num_timesteps
    env.close()
    return steps / elapsed


def update_gflop(algo: str, task: str, n_games: int, seed: int) -> tuple[float, int]:
    """Floating-point work of one PPO update (all epochs and minibatches) after one rollout, counted by
    ``torch.utils.flop_counter`` (matrix products, which dominate these networks).

    :return: GFLOP of the update and the agent-steps of the rollout it trains on
    """
    from torch.utils.flop_counter import FlopCounterMode

    model, env, callbacks, _ = build_model(algo, task, n_games=n_games, seed=seed)
    model.learn(model.n_steps * env.num_envs, callback=callbacks)  # one rollout and one update
    with FlopCounterMode(display=False) as counter:
        model.train()
    env.close()
    return counter.get_total_flops() / 1e9, model.n_steps * env.num_envs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="cn-sparse-n3")
    parser.add_argument("--n-games", type=int, default=16)
    parser.add_argument("--steps", type=int, default=100_000, help="agent-steps per measurement")
    parser.add_argument("--algos", nargs="+", default=["random", "ippo", "saeir_ppo"], help=f"random or {sorted(ALGOS)}")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--flops", action="store_true", help="also print the GFLOP of one update per agent-step")
    args = parser.parse_args()
    th.set_num_threads(1)

    results: dict[str, float] = {}
    for algo in args.algos:
        if algo == "random":
            results[algo] = random_stepping(args.task, args.n_games, args.steps, args.seed)
        elif algo in ALGOS:
            results[algo] = training(algo, args.task, args.n_games, args.steps, args.seed)
        else:
            print(f"skipping {algo}: not available")
            continue
        print(f"{algo:>12}: {results[algo]:9.0f} agent-steps/s", flush=True)
    trained = [algo for algo in results if algo != "random"]
    if trained:
        reference = trained[0]
        for algo in trained[1:]:
            print(f"ratio {algo}/{reference}: {results[algo] / results[reference]:.2f}")
    if args.flops:
        for algo in trained:
            gflop, n_agent_steps = update_gflop(algo, args.task, args.n_games, args.seed)
            print(f"{algo:>12}: {gflop:.2f} GFLOP per update, {gflop / n_agent_steps * 1e6:.0f} kFLOP per agent-step")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"task {args.task}, {args.n_games} games, {args.steps} agent-steps per method; peak RSS {peak_mb:.0f} MB")


if __name__ == "__main__":
    main()
