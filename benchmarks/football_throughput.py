"""Env steps per second on the football tasks: random actions (1 and 2 games) and SAEIR_PPO training.

    python benchmarks/football_throughput.py                                   # everything below, ~3 min
    python benchmarks/football_throughput.py --tasks grf-3v1-keeper --n-games 1 2 4 --seconds 30 --num-cpus 0 2
    python benchmarks/football_throughput.py --no-random --train-iterations 2  # training only

"Env steps" are game steps (one step of one game, all its agents together), the unit of the paper's 25e6 budget;
agent-steps are env steps x N. Random stepping goes through ``make_multiagent_vec_env``: ``--num-cpus 0`` runs every game
in this process, one after the other (so more games do not mean more steps/s), ``--num-cpus k`` spreads them over k
worker processes. Training uses the method's packaged config (the paper's hyperparameters: 200-step buffer, 15 epochs,
2 minibatches) with fewer games and ``--train-iterations`` iterations. CPU-seconds count this process and its workers.
Timings on shared machines are noisy: they are lower bounds.
"""

from __future__ import annotations

import argparse
import os
import resource
import time

import numpy as np
import torch as th

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.config import build_model


def cpu_seconds() -> float:
    """CPU time (user + system) of this process and its running child processes (SuperSuit workers), in seconds."""
    import psutil  # installed with the football extra

    process = psutil.Process()
    return sum(sum(proc.cpu_times()[:2]) for proc in [process, *process.children(recursive=True)])


def random_stepping(task: str, n_games: int, seconds: float, num_cpus: int, seed: int) -> dict[str, float]:
    """Env steps/s (and per CPU-second) of uniformly random actions for about ``seconds`` seconds."""
    env = make_multiagent_vec_env(task, n_games=n_games, seed=seed, num_cpus=num_cpus)
    rng = np.random.default_rng(seed)
    env.reset()
    vec_steps = 0
    cpu_start, start = cpu_seconds(), time.perf_counter()
    while time.perf_counter() - start < seconds:
        env.step(rng.integers(0, env.action_space.n, size=env.num_envs))
        vec_steps += 1
    elapsed, cpu = time.perf_counter() - start, cpu_seconds() - cpu_start
    episodes = env.episode_count
    env.close()
    env_steps = vec_steps * n_games
    return {"env_steps_per_s": env_steps / elapsed, "env_steps_per_cpu_s": env_steps / max(cpu, 1e-9), "episodes": episodes}


def training(algo: str, task: str, n_games: int, iterations: int, seed: int) -> dict[str, float]:
    """Env steps/s of ``learn`` (rollouts + updates) with the packaged config, ``iterations`` iterations."""
    model, env, callbacks, _ = build_model(algo, task, n_games=n_games, seed=seed)
    n_agents = env.num_envs // n_games
    agent_steps = iterations * model.n_steps * env.num_envs
    cpu_start, start = cpu_seconds(), time.perf_counter()
    model.learn(agent_steps, callback=callbacks)
    elapsed, cpu = time.perf_counter() - start, cpu_seconds() - cpu_start
    env.close()
    env_steps = model.num_timesteps / n_agents
    return {"env_steps_per_s": env_steps / elapsed, "env_steps_per_cpu_s": env_steps / max(cpu, 1e-9), "seconds": elapsed}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=["grf-3v1-keeper", "grf-counterattack-easy"])
    parser.add_argument("--n-games", nargs="+", type=int, default=[1, 2], help="game counts for random stepping")
    parser.add_argument("--num-cpus", nargs="+", type=int, default=[0], help="SuperSuit worker processes (0: in-process)")
    parser.add_argument("--seconds", type=float, default=20.0, help="duration of each random-stepping measurement")
    parser.add_argument("--no-random", action="store_true", help="skip random stepping")
    parser.add_argument("--train-algo", default="saeir_ppo", help="method trained from its packaged config ('' to skip)")
    parser.add_argument("--train-task", default="grf-3v1-keeper")
    parser.add_argument("--train-games", type=int, default=2)
    parser.add_argument("--train-iterations", type=int, default=2, help="PPO iterations (each n_steps x games env steps)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    th.set_num_threads(1)

    if not args.no_random:
        for task in args.tasks:
            for num_cpus in args.num_cpus:
                for n_games in args.n_games:
                    result = random_stepping(task, n_games, args.seconds, num_cpus, args.seed)
                    print(
                        f"random {task:>22} games={n_games} num_cpus={num_cpus}: {result['env_steps_per_s']:7.1f} env steps/s "
                        f"({result['env_steps_per_cpu_s']:6.1f} per CPU-s, {result['episodes']:.0f} episodes)",
                        flush=True,
                    )
    if args.train_algo:
        result = training(args.train_algo, args.train_task, args.train_games, args.train_iterations, args.seed)
        print(
            f"train  {args.train_algo} {args.train_task} games={args.train_games} iterations={args.train_iterations}: "
            f"{result['env_steps_per_s']:7.1f} env steps/s ({result['env_steps_per_cpu_s']:6.1f} per CPU-s, "
            f"{result['seconds']:.0f} s)",
            flush=True,
        )
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {peak_mb:.0f} MB; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
