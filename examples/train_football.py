"""Train SAEIR_PPO on Google Research Football, academy 3 vs 1 with keeper, and report the success (win) rate.

    python examples/train_football.py                          # 2 games, 30k agent-steps: a few minutes on 2 cores
    python examples/train_football.py --n-games 8 --num-cpus 4 --timesteps 1000000

Needs gfootball, which has no wheels (its C++ engine is built from the sdist): ``bash scripts/install_football.sh``
(as root: apt build dependencies, then the build into .venv; 8-14 minutes the first time). Without it this script
prints how to install it and exits. The paper's settings (50 games, 200-step buffer, 15 epochs, 2 minibatches, lr 5e-4,
ReLU) are in ``zoo_configs/saeir_ppo.yml``; this example keeps them except the number of games and the budget.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys

from torch import nn

INSTALL_HINT = """gfootball is not installed, so the football tasks are not available.
Install it (as root; builds the engine into .venv, 8-14 minutes the first time, seconds from pip's cache):

    bash scripts/install_football.sh

or, for another virtual environment: bash scripts/install_football.sh --venv PATH
(the 'football' extra, pip install 'sb3-saeir[football]', brings gfootball's Python dependencies, not the engine)."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="grf-3v1-keeper", help="grf-3v1-keeper or grf-counterattack-easy")
    parser.add_argument("--n-games", type=int, default=2)
    parser.add_argument("--num-cpus", type=int, default=0, help="env worker processes (0: all games in this process)")
    parser.add_argument("--timesteps", type=int, default=30_000, help="agent-steps")
    parser.add_argument("--n-steps", type=int, default=200, help="buffer length per game (the paper's 200)")
    parser.add_argument("--n-epochs", type=int, default=15)
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if importlib.util.find_spec("gfootball") is None:
        print(INSTALL_HINT)
        sys.exit(0)
    from sb3_saeir import SAEIR_PPO, make_multiagent_vec_env
    from sb3_saeir.common.utils import set_num_threads

    set_num_threads(None)  # the free cores, at most 2 (OMP_NUM_THREADS wins); see docs/guide/faq.md
    from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy

    env = make_multiagent_vec_env(args.task, n_games=args.n_games, seed=args.seed, num_cpus=args.num_cpus)
    model = SAEIR_PPO(
        "MSHGPolicy",
        env,
        learning_rate=5e-4,
        n_steps=args.n_steps,
        n_epochs=args.n_epochs,
        n_minibatches=2 if args.n_steps >= 2 * 10 else 1,
        policy_kwargs=dict(activation_fn=nn.ReLU),
        seed=args.seed,
    )
    print(f"Training SAEIR_PPO on {args.task}: {env.n_games} games x {env.n_agents} agents, {args.timesteps:,} agent-steps")
    model.learn(args.timesteps, progress_bar=True)
    policies = {"trained": model, "random": RandomMultiAgentPolicy(env.action_space, seed=args.seed)}
    env.close()

    for name, policy in policies.items():
        eval_env = make_multiagent_vec_env(args.task, n_games=1, seed=10_000 + args.seed)  # same episodes for both
        summary = evaluate_multiagent_policy(policy, eval_env, n_episodes=args.eval_episodes, deterministic=False)
        eval_env.close()
        print(
            f"{name:8} success rate {summary['success_mean']:.2f}, goal difference {summary['goal_diff_mean']:.2f}, "
            f"episode length {summary['ep_len_mean']:.0f} ({int(summary['n_episodes'])} episodes)"
        )


if __name__ == "__main__":
    main()
