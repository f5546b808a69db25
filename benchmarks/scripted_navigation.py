"""Reference policies for sparse Cooperative Navigation, for each world and reward reading: uniform random and a
scripted oracle (the task is solvable).

    python benchmarks/scripted_navigation.py                      # every world x reward x N in {3, 4}, both policies
    python benchmarks/scripted_navigation.py --worlds mpe --rewards reach --n 3 --policies scripted --episodes 200
    python benchmarks/scripted_navigation.py --worlds mpe2 --rewards occupancy --policy random --task-n 3   # earlier figures

Each figure is the mean over ``--episodes`` episodes of ``evaluate_multiagent_policy`` on 10 games (seed 12345, the
evaluation set of the slow learning test) of the navigation task with ``N``, ``world`` and ``reward`` set
(``docs/tasks.md`` describes them). Random: uniform discrete actions (seed 0). Scripted oracle: at each episode start
the agents of a game are assigned to landmarks by the permutation with the least total distance (from the true
positions, so this is an oracle, not a decentralised policy); every step each agent takes the discrete action along
the larger axis of (target - position - c * velocity), or the no-op within 0.03, where c * velocity is how far the
agent would coast without force (c = dt (1 - damping) / damping = 0.3 in the original MPE, dt / damping = 0.4 in
mpe2, whose step moves with the old velocity). The oracle aims at coverage; it does not avoid collisions. ``return``
is the team return of an episode (one agent's reward summed over the 25 steps).
"""

from __future__ import annotations

import argparse
import itertools
from typing import Any

import numpy as np

from sb3_saeir.common.vec_env import make_multiagent_vec_env
from sb3_saeir.envs.navigation_core import DAMPING, DT, REWARDS, WORLDS
from sb3_saeir.envs.navigation_vec_env import NavigationVecEnv
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy

NOOP, LEFT, RIGHT, DOWN, UP = range(5)  # mpe2's discrete actions
METRICS = ("coverage_rate", "coverage_over_steps", "collision_steps", "success", "reach_events", "ep_rew")


class ScriptedOracle:
    """Scripted near-optimal policy reading the true positions of a native navigation vec env (``predict`` as SB3's).

    :param env: the native vec env it plays
    """

    def __init__(self, env: NavigationVecEnv) -> None:
        self.env = env
        core = env.core
        self.permutations = np.array(list(itertools.permutations(range(core.N))))  # (P, N)
        self.targets = np.zeros((core.n_games, core.N), dtype=np.int64)  # landmark of each agent
        # distance coasted without force per unit of velocity: sum over later steps of the velocity's decay times dt
        self.coast = DT * (1 - DAMPING) / DAMPING if core.world == "mpe" else DT / DAMPING

    def assign(self, games: np.ndarray) -> None:
        """Give each agent of ``games`` its landmark: the permutation with the least total distance."""
        core = self.env.core
        # (G, N, 1, 2) - (G, 1, L, 2) -> (G, N, L): agent-landmark distances
        distances = np.linalg.norm(core.positions[:, :, None, :] - core.landmarks[:, None, :, :], axis=-1)
        agents = np.arange(core.N)
        costs = distances[:, agents, self.permutations].sum(axis=-1)  # (G, P)
        self.targets[games] = self.permutations[costs.argmin(axis=1)][games]

    def predict(
        self, observation: np.ndarray, state: Any = None, episode_start: np.ndarray | None = None, deterministic: bool = True
    ) -> tuple[np.ndarray, None]:
        core = self.env.core
        if episode_start is not None and episode_start.any():
            # (G * N,) -> (G, N): games whose episode starts now
            self.assign(np.flatnonzero(episode_start.reshape(core.n_games, core.N).any(axis=1)))
        target = np.take_along_axis(core.landmarks, self.targets[..., None], axis=1)  # (G, N, 2)
        offset = target - core.positions - self.coast * core.velocities
        horizontal = np.abs(offset[..., 0]) > np.abs(offset[..., 1])
        actions = np.where(
            horizontal,
            np.where(offset[..., 0] > 0, RIGHT, LEFT),
            np.where(offset[..., 1] > 0, UP, DOWN),
        )
        actions = np.where(np.abs(offset).max(axis=-1) < 0.03, NOOP, actions)
        return actions.reshape(-1), None  # (G, N) -> (G * N,)


def evaluate(policy: str, world: str, reward: str, N: int, episodes: int) -> dict[str, float]:
    """Mean episode metrics of a reference policy on one variant of the task."""
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=10, seed=12_345, N=N, world=world, reward=reward, backend="native")
    assert isinstance(env, NavigationVecEnv)
    model: Any = RandomMultiAgentPolicy(env.action_space) if policy == "random" else ScriptedOracle(env)
    summary = evaluate_multiagent_policy(model, env, episodes)
    env.close()
    return {key: summary[f"{key}_mean"] for key in METRICS}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--worlds", nargs="+", choices=WORLDS, default=list(WORLDS))
    parser.add_argument("--rewards", nargs="+", choices=REWARDS, default=list(REWARDS))
    parser.add_argument("--n", "--task-n", type=int, nargs="+", default=[3, 4], help="agents = landmarks")
    parser.add_argument("--policies", "--policy", nargs="+", choices=["random", "scripted"], default=["random", "scripted"])
    parser.add_argument("--episodes", type=int, default=1000)
    args = parser.parse_args()
    header = ["world", "reward", "N", "policy", *(("return" if key == "ep_rew" else key) for key in METRICS)]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for world, reward, N, policy in itertools.product(args.worlds, args.rewards, args.n, args.policies):
        metrics = evaluate(policy, world, reward, N, args.episodes)
        cells = [world, reward, str(N), policy, *(f"{metrics[key]:.3f}" for key in METRICS)]
        print("| " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
