"""The random policy's score on tasks: the floor a learning curve must leave (e.g. football's success rate).

    python benchmarks/random_baseline.py --tasks grf-3v1-keeper grf-counterattack-easy --episodes 500

Uniform random actions for every agent (:class:`~sb3_saeir.evaluation.RandomMultiAgentPolicy`) on ``--games``
games of each task (the paper's task settings: the packaged task defaults, ``--env-kwargs`` to change them), episodes
shared equally over the games as the benchmark's evaluations do. Prints one Markdown row per task: episodes, the
success rate (football) or coverage rate (navigation) with its 95% normal-approximation interval, the episode
reward and length (mean ± std), and the wall time.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.envs import get_task_spec
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy


def random_scores(task: str, episodes: int, games: int, seed: int, env_kwargs: dict[str, Any]) -> dict[str, Any]:
    """Play ``episodes`` random-policy episodes of ``task``; the summary of :func:`evaluate_multiagent_policy`."""
    start = time.perf_counter()
    env = make_multiagent_vec_env(task, n_games=games, seed=seed, **env_kwargs)
    try:
        summary = evaluate_multiagent_policy(RandomMultiAgentPolicy(env.action_space, seed), env, n_episodes=episodes)
    finally:
        env.close()
    return {**summary, "wall_s": time.perf_counter() - start}


def markdown_row(task: str, summary: dict[str, Any]) -> str:
    """``| task | metric | episodes | rate [95% CI] | reward | length | wall |``."""
    metric = get_task_spec(task).main_metric
    rate, n = summary[f"{metric}_mean"], summary["n_episodes"]
    half = 1.96 * math.sqrt(max(rate * (1 - rate), 0.0) / n)
    return (
        f"| {task} | {metric} | {n:.0f} | {100 * rate:.2f}% [{100 * max(rate - half, 0):.2f}, {100 * min(rate + half, 1):.2f}]"
        f" | {summary['ep_rew_mean']:.3f} ± {summary['ep_rew_std']:.3f} | {summary['ep_len_mean']:.1f} ± "
        f"{summary['ep_len_std']:.1f} | {summary['wall_s']:.0f} s |"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=["grf-3v1-keeper", "grf-counterattack-easy"])
    parser.add_argument("--episodes", type=int, default=500, help="episodes per task")
    parser.add_argument("--games", type=int, default=10, help="games played side by side")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--env-kwargs", type=json.loads, default={}, help="JSON dict, e.g. '{\"N\": 4}'")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.games < 1:
        parser.error(f"--episodes and --games must be at least 1, got {args.episodes} and {args.games}")
    lines = ["| task | metric | episodes | rate [95% CI] | episode reward | episode length | wall |", "|---" * 7 + "|"]
    sys.stdout.write("\n".join(lines) + "\n")
    for task in args.tasks:
        sys.stdout.write(markdown_row(task, random_scores(task, args.episodes, args.games, args.seed, args.env_kwargs)) + "\n")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
