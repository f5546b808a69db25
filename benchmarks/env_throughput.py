"""Speed of the navigation engine: random stepping of three env paths, and training per backend, in one run.

    OMP_NUM_THREADS=1 python benchmarks/env_throughput.py
    OMP_NUM_THREADS=1 python benchmarks/env_throughput.py --n 4 --games 16 128 --rollouts 3 --algos ippo mappo saeir_ppo

Random stepping (uniform random discrete actions, drawn beforehand), agent-steps/s of

- ``native``: the batched engine's own multi-agent vec env (the default of ``cn-sparse-n3`` / ``cn-sparse-n4``);
- ``core+supersuit``: the same engine's one-game PettingZoo env through SuperSuit (``backend="supersuit"``);
- ``mpe2+supersuit``: mpe2's ``simple_spread_v3`` through SuperSuit with the sparse reward computed from its world (the
  path the package took before the engine),

at each number of games, with the ratios to ``mpe2+supersuit``. Training: agent-steps/s of ``learn`` (rollouts and
updates) of IPPO (SB3 ``PPO``), ``MAPPO`` and ``SAEIR_PPO`` at the largest number of games, with the packaged config
hyperparameters (``zoo_configs/<algo>.yml``, built through the public classes), on each backend. Timings on shared
machines are noisy: compare ratios from one run.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
import torch as th
from gymnasium.utils import EzPickle

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.vec_env import EPISODE_METRICS_KEY
from sb3_saeir.config import load_hyperparams, parse_policy_kwargs
from sb3_saeir.envs.navigation import SparseCooperativeNavigation, any_collision, count_covered_landmarks

ENV_PATHS = ("native", "core+supersuit", "mpe2+supersuit")
# config keys that are not algorithm arguments
NOT_ALGO_KEYS = ("n_timesteps", "n_envs", "env_kwargs", "policy", "policy_kwargs", "callback")


class Mpe2Navigation(SparseCooperativeNavigation):
    """The sparse task on mpe2's own ``simple_spread_v3`` (the package's path before the engine), for comparison."""

    def __init__(self, N: int = 3, max_cycles: int = 25) -> None:
        from mpe2 import simple_spread_v3

        super().__init__(N=N, max_cycles=max_cycles, world="mpe2")
        EzPickle.__init__(self, N=N, max_cycles=max_cycles)  # copies (SuperSuit pickles the game) are built like this one
        self._mpe2 = simple_spread_v3.parallel_env(N=N, local_ratio=0.0, max_cycles=max_cycles)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        observations, _ = self._mpe2.reset(seed=seed, options=options)
        self.agents = list(self._mpe2.agents)
        self._steps, self._covered_sum, self._collisions = 0, 0.0, 0
        return observations, {agent: {} for agent in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        observations, _, terminations, truncations, _ = self._mpe2.step(actions)
        world = self._mpe2.unwrapped.world
        agents = np.array([a.state.p_pos for a in world.agents])
        covered = count_covered_landmarks(agents, np.array([lm.state.p_pos for lm in world.landmarks]))
        collided = any_collision(agents, np.full(self.N, 0.15))
        self._steps += 1
        self._covered_sum += covered / self.N
        self._collisions += int(collided)
        infos: dict[str, dict] = {agent: {} for agent in self.possible_agents}
        if all(truncations.values()):
            metrics = {
                "coverage_rate": covered / self.N,
                "coverage_over_steps": self._covered_sum / self._steps,
                "collision_steps": float(self._collisions),
                "success": float(covered == self.N),
            }
            for agent in self.possible_agents:
                infos[agent][EPISODE_METRICS_KEY] = dict(metrics)
        self.agents = list(self._mpe2.agents)
        rewards = dict.fromkeys(self.possible_agents, float(covered - int(collided)))
        return observations, rewards, terminations, truncations, infos


def make_env(path: str, N: int, n_games: int, seed: int) -> Any:
    """The multi-agent vec env of one path (seeded)."""
    if path == "native":
        return make_multiagent_vec_env("cn-sparse-n3", n_games=n_games, seed=seed, N=N, backend="native")
    if path == "core+supersuit":
        return make_multiagent_vec_env("cn-sparse-n3", n_games=n_games, seed=seed, N=N, backend="supersuit")
    return make_multiagent_vec_env(lambda: Mpe2Navigation(N=N), n_games=n_games, seed=seed)


def random_stepping(path: str, N: int, n_games: int, seconds: float, seed: int = 0) -> float:
    """Agent-steps/s of uniformly random actions (drawn before the clock starts), measured over ``seconds``."""
    env = make_env(path, N, n_games, seed)
    actions = np.random.default_rng(seed).integers(0, 5, size=(64, env.num_envs))
    env.reset()
    for step in range(5):  # warm-up
        env.step(actions[step])
    steps, start = 0, time.perf_counter()
    while True:
        env.step(actions[steps % 64])
        steps += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds and steps >= 25:
            break
    env.close()
    return steps * env.num_envs / elapsed


def build(algo: str, env: Any, seed: int) -> Any:
    """A model of ``algo`` on ``env`` with the packaged config's hyperparameters (task ``cn-sparse-n<N>``)."""
    from stable_baselines3 import PPO

    params = load_hyperparams(algo, f"cn-sparse-n{env.n_agents}")
    kwargs = {key: value for key, value in params.items() if key not in NOT_ALGO_KEYS}
    if "intrinsic_kwargs" in kwargs:
        kwargs["intrinsic_kwargs"] = parse_policy_kwargs(kwargs["intrinsic_kwargs"])
    if "batch_size" in kwargs:  # the configs' batch is the whole rollout: keep it so with this number of games
        kwargs["batch_size"] = params["n_steps"] * env.num_envs
    algo_class = {"ippo": PPO, "mappo": MAPPO, "saeir_ppo": SAEIR_PPO}[algo]
    policy_kwargs = parse_policy_kwargs(params.get("policy_kwargs"))
    return algo_class(params["policy"], env, policy_kwargs=policy_kwargs, seed=seed, device="cpu", **kwargs)


def training(algo: str, path: str, N: int, n_games: int, rollouts: int, seed: int = 0) -> float:
    """Agent-steps/s of ``learn`` over ``rollouts`` rollouts and updates (after one untimed warm-up iteration)."""
    env = make_env(path, N, n_games, seed)
    model = build(algo, env, seed)
    rollout = model.n_steps * env.num_envs
    model.learn(rollout)  # warm-up: first rollout and update
    start = time.perf_counter()
    model.learn(rollouts * rollout, reset_num_timesteps=False)
    elapsed = time.perf_counter() - start
    env.close()
    return rollouts * rollout / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=3, help="agents = landmarks")
    parser.add_argument("--games", type=int, nargs="+", default=[16, 128], help="numbers of games for random stepping")
    parser.add_argument("--seconds", type=float, default=2.0, help="timed seconds per random-stepping figure")
    parser.add_argument("--algos", nargs="*", default=["ippo", "mappo", "saeir_ppo"], help="methods to train ([] skips)")
    parser.add_argument("--backends", nargs="*", default=list(ENV_PATHS), help="env paths to train on")
    parser.add_argument("--rollouts", type=int, default=2, help="timed rollouts (+ updates) per training figure")
    args = parser.parse_args()
    th.set_num_threads(1)

    print(f"random stepping, N={args.n}, agent-steps/s (ratio to mpe2+supersuit)")
    for n_games in args.games:
        rates = {path: random_stepping(path, args.n, n_games, args.seconds) for path in ENV_PATHS}
        cells = "  ".join(f"{path} {rate:>10,.0f} ({rate / rates['mpe2+supersuit']:5.1f}x)" for path, rate in rates.items())
        print(f"  {n_games:>4} games: {cells}", flush=True)

    if args.algos:
        n_games = max(args.games)
        print(f"training, N={args.n}, {n_games} games, {args.rollouts} rollouts of 25 steps, agent-steps/s")
        for algo in args.algos:
            rates = {path: training(algo, path, args.n, n_games, args.rollouts) for path in args.backends}
            first = rates[args.backends[-1]]
            cells = "  ".join(f"{path} {rate:>8,.0f} ({rate / first:4.2f}x)" for path, rate in rates.items())
            print(f"  {algo:>10}: {cells}", flush=True)


if __name__ == "__main__":
    main()
