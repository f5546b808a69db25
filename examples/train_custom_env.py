"""Train on your own PettingZoo env: a small cooperative ParallelEnv through make_multiagent_vec_env(callable, ...).

    python examples/train_custom_env.py                        # MAPPO, 150k agent-steps, about a minute
    python examples/train_custom_env.py --algo saeir_ppo --timesteps 300000

The game, ``LineSpread``: N agents on a line must spread over N targets. Each step every agent moves left, stays or
moves right; the team reward is sparse (+1 per target with an agent within ``radius``, 0 otherwise); the episode
metric ``coverage_rate`` (targets covered at the last step / N) is reported through ``infos[agent]["episode_metrics"]``,
so it is logged as ``rollout/coverage_rate`` and evaluated like the packaged tasks' metrics.
"""

from __future__ import annotations

import argparse
import functools
from typing import ClassVar

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.utils import set_num_threads
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy


class LineSpread(ParallelEnv):
    """N agents and N targets on the segment [-1, 1]; actions: 0 left, 1 stay, 2 right (step 0.1).

    Observation of an agent (``2N`` numbers): its position, the N targets relative to it, the other agents relative
    to it. All agents stay in the game until the last step (as the multi-agent vec env requires).

    :param n_agents: agents (= targets)
    :param max_steps: episode length
    :param radius: an agent closer than this to a target covers it
    """

    metadata: ClassVar[dict] = {"name": "line_spread_v0", "render_modes": []}

    def __init__(self, n_agents: int = 3, max_steps: int = 20, radius: float = 0.1) -> None:
        self.n = n_agents
        self.max_steps = max_steps
        self.radius = radius
        self.possible_agents = [f"agent_{i}" for i in range(n_agents)]
        self.agents: list[str] = []
        self.rng = np.random.default_rng()
        self.positions = np.zeros(n_agents)
        self.targets = np.zeros(n_agents)
        self.steps = 0
        self._observation_space = spaces.Box(-2.0, 2.0, shape=(2 * n_agents,), dtype=np.float32)
        self._action_space = spaces.Discrete(3)

    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_space  # the same object for every agent (homogeneous agents)

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._action_space

    def _observations(self) -> dict[str, np.ndarray]:
        observations = {}
        for i, agent in enumerate(self.possible_agents):
            others = np.delete(self.positions, i) - self.positions[i]
            obs = np.concatenate([[self.positions[i]], self.targets - self.positions[i], others])
            observations[agent] = obs.astype(np.float32)
        return observations

    def _covered(self) -> int:
        distances = np.abs(self.targets[:, None] - self.positions[None, :])  # (targets, agents)
        return int((distances.min(axis=1) < self.radius).sum())

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, np.ndarray], dict[str, dict]]:
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self.agents = list(self.possible_agents)
        self.positions = self.rng.uniform(-1, 1, self.n)
        self.targets = self.rng.uniform(-1, 1, self.n)
        self.steps = 0
        return self._observations(), {agent: {} for agent in self.agents}

    def step(
        self, actions: dict[str, int]
    ) -> tuple[dict[str, np.ndarray], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict]]:
        moves = np.array([int(actions[agent]) - 1 for agent in self.possible_agents], dtype=np.float64)
        self.positions = np.clip(self.positions + 0.1 * moves, -1.0, 1.0)
        self.steps += 1
        covered = self._covered()
        reward = float(covered)  # sparse: nothing unless an agent sits on a target
        last = self.steps >= self.max_steps
        infos: dict[str, dict] = {agent: {} for agent in self.agents}
        if last:  # the first agent's info carries the episode metrics (read by the multi-agent vec env)
            metrics = {"coverage_rate": covered / self.n, "success": covered == self.n}
            infos[self.possible_agents[0]]["episode_metrics"] = metrics
        observations = self._observations()
        rewards = {agent: reward for agent in self.agents}
        terminations = {agent: False for agent in self.agents}
        truncations = {agent: last for agent in self.agents}
        if last:
            self.agents = []
        return observations, rewards, terminations, truncations, infos


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", choices=["mappo", "saeir_ppo"], default="mappo")
    parser.add_argument("--n-agents", type=int, default=3)
    parser.add_argument("--n-games", type=int, default=32)
    parser.add_argument("--timesteps", type=int, default=150_000, help="agent-steps")
    parser.add_argument("--eval-episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    set_num_threads(None)  # the free cores, at most 2 (OMP_NUM_THREADS wins); see docs/guide/faq.md

    # A callable that returns a new ParallelEnv: one per game, wrapped by SuperSuit into one slot per agent.
    make_game = functools.partial(LineSpread, n_agents=args.n_agents)
    env = make_multiagent_vec_env(make_game, n_games=args.n_games, seed=args.seed)
    print(f"{env.n_games} games x {env.n_agents} agents = {env.num_envs} slots, observation {env.observation_space.shape}")
    if args.algo == "mappo":
        model = MAPPO("MAPPOPolicy", env, n_steps=20, seed=args.seed)
    else:
        model = SAEIR_PPO("MSHGPolicy", env, n_steps=20, seed=args.seed)
    model.learn(args.timesteps)

    results = {}
    policies = {"trained": model, "random": RandomMultiAgentPolicy(env.action_space, seed=args.seed)}
    for name, policy in policies.items():
        eval_env = make_multiagent_vec_env(make_game, n_games=10, seed=10_000 + args.seed)
        results[name] = evaluate_multiagent_policy(policy, eval_env, n_episodes=args.eval_episodes)
        eval_env.close()
    env.close()
    for name, summary in results.items():
        print(
            f"{name:8} coverage rate {summary['coverage_rate_mean']:.3f}, success rate {summary['success_mean']:.3f}, "
            f"team return {summary['ep_rew_mean']:.2f} ({int(summary['n_episodes'])} episodes)"
        )


if __name__ == "__main__":
    main()
