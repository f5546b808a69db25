"""Reference policies for sparse Cooperative Navigation: a scripted oracle (the task is solvable) and uniform random.

    python benchmarks/scripted_navigation.py --task-n 3 --episodes 100
    python benchmarks/scripted_navigation.py --policy random --task-n 3 --episodes 500

Random: uniform actions (seed 0) through ``evaluate_multiagent_policy`` on 10 games (seed 12345), as the slow
learning test measures it.

Each episode, agents are assigned to landmarks by the permutation with the least total distance (from the true
positions, so this is an oracle, not a decentralised policy); every step each agent takes the discrete action along
the larger axis of (target - position - 0.5 * velocity), or no-op within 0.03. Prints the episode metrics.
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np

from sb3_saeir.common.vec_env import EPISODE_METRICS_KEY, make_multiagent_vec_env
from sb3_saeir.envs.navigation import SparseCooperativeNavigation
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy

NOOP, LEFT, RIGHT, DOWN, UP = range(5)  # mpe2 discrete actions


def steer(offset: np.ndarray) -> int:
    """Discrete action that reduces the larger component of ``offset`` (2,)."""
    if np.abs(offset).max() < 0.03:
        return NOOP
    if abs(offset[0]) > abs(offset[1]):
        return RIGHT if offset[0] > 0 else LEFT
    return UP if offset[1] > 0 else DOWN


def run_episode(env: SparseCooperativeNavigation, seed: int) -> tuple[dict[str, float], float]:
    """One episode of the scripted policy; returns the episode metrics and one agent's return."""
    observations, _ = env.reset(seed=seed)
    agents, landmarks, _ = env.positions()  # (N, 2), (N, 2), (N,)
    n = len(agents)
    assignment = min(
        itertools.permutations(range(n)), key=lambda p: sum(np.linalg.norm(agents[i] - landmarks[p[i]]) for i in range(n))
    )
    episode_return = 0.0
    infos: dict[str, dict] = {}
    while env.agents:
        agents, landmarks, _ = env.positions()
        actions = {}
        for i, name in enumerate(env.agents):
            velocity = observations[name][0:2]  # simple_spread observation starts with the agent's velocity
            actions[name] = steer(landmarks[assignment[i]] - agents[i] - 0.5 * velocity)
        observations, rewards, _, _, infos = env.step(actions)
        episode_return += float(rewards[env.possible_agents[0]])
    return infos[env.possible_agents[0]][EPISODE_METRICS_KEY], episode_return


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task-n", type=int, default=3, help="agents = landmarks")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--policy", choices=["scripted", "random"], default="scripted")
    args = parser.parse_args()
    if args.policy == "random":
        env_id = f"cn-sparse-n{args.task_n}"
        eval_env = make_multiagent_vec_env(env_id, n_games=10, seed=12_345)
        metrics = evaluate_multiagent_policy(RandomMultiAgentPolicy(eval_env.action_space), eval_env, args.episodes)
        for key, value in metrics.items():
            if key.endswith("_mean"):
                print(f"{key[: -len('_mean')]}: {value:.3f}")
        return
    env = SparseCooperativeNavigation(N=args.task_n)
    results = [run_episode(env, seed) for seed in range(args.episodes)]
    for key in results[0][0]:
        print(f"{key}: {np.mean([metrics[key] for metrics, _ in results]):.3f}")
    print(f"return: {np.mean([ret for _, ret in results]):.2f}")


if __name__ == "__main__":
    main()
