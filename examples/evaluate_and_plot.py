"""Evaluate a saved model against a random policy and plot the results (and the training curve if there is one).

    python examples/evaluate_and_plot.py runs/quickstart/model.zip
    python examples/evaluate_and_plot.py logs/mappo/cn-sparse-n3_1/cn-sparse-n3.zip --algo mappo --episodes 1000

Writes into ``--out`` (default: the model's folder): ``evaluation.png`` (the distribution of the per-episode coverage
rate, or of the team return for tasks without coverage, for the model and a random policy on the same episodes) and,
when the folder has an SB3 ``progress.csv``, ``training.png`` (training and evaluation metrics over agent-steps);
``--gif`` also writes ``replay.gif``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os

import numpy as np

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.common.utils import set_num_threads
from sb3_saeir.config import ALGOS
from sb3_saeir.enjoy import record_gif
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy


def read_progress(path: str) -> dict[str, tuple[list[float], list[float]]]:
    """Every ``rollout/`` and ``eval/`` column of an SB3 ``progress.csv`` as (agent-steps, values)."""
    columns: dict[str, tuple[list[float], list[float]]] = {}
    with open(path) as file:
        for row in csv.DictReader(file):
            step = row.get("time/total_timesteps")
            if not step:
                continue
            for key, value in row.items():
                if value and key.startswith(("rollout/", "eval/")):
                    steps, values = columns.setdefault(key, ([], []))
                    steps.append(float(step))
                    values.append(float(value))
    return columns


def quickstart_task(model_path: str) -> str:
    """The task of the quickstart's ``eval.json`` beside ``model_path``, else the quickstart's default task."""
    report = os.path.join(os.path.dirname(os.path.abspath(model_path)), "eval.json")
    if os.path.isfile(report):
        with open(report) as file:
            return str(json.load(file)["task"])
    return "cn-sparse-no-penalty-n3"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", help="a saved model zip")
    parser.add_argument("--algo", default="saeir_ppo", help=f"method that saved it: {', '.join(sorted(ALGOS))}")
    parser.add_argument(
        "--task", default=None, help="task id (default: the task in eval.json beside the model, as the quickstart writes)"
    )
    parser.add_argument("--episodes", type=int, default=500, help="game episodes per policy")
    parser.add_argument("--seed", type=int, default=20_000, help="seed of the evaluation games")
    parser.add_argument("--stochastic", action="store_true", help="sample actions instead of greedy ones")
    parser.add_argument("--gif", action="store_true", help="also write replay.gif (2 episodes)")
    parser.add_argument("--out", default=None, help="output folder (default: the model's folder)")
    args = parser.parse_args()
    set_num_threads(None)  # the free cores, at most 2 (OMP_NUM_THREADS wins); see docs/guide/faq.md
    out = args.out or os.path.dirname(os.path.abspath(args.model))
    os.makedirs(out, exist_ok=True)

    args.task = args.task or quickstart_task(args.model)
    model = ALGOS[args.algo].load(args.model, device="cpu")
    episodes = {}
    policies = {"model": model, "random": RandomMultiAgentPolicy(model.action_space, seed=args.seed)}
    for name, policy in policies.items():
        env = make_multiagent_vec_env(args.task, n_games=min(10, args.episodes), seed=args.seed)  # same games for both
        summary, episodes[name] = evaluate_multiagent_policy(policy, env, args.episodes, not args.stochastic, True)
        env.close()
        metrics = ", ".join(
            f"{key[:-5]} {summary[key]:.3f} ± {summary[key[:-5] + '_std'] / math.sqrt(summary['n_episodes']):.3f}"
            for key in sorted(summary)
            if key.endswith("_mean")
        )
        print(f"{name:7} ({int(summary['n_episodes'])} episodes): {metrics}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    key = "coverage_rate" if "coverage_rate" in episodes["model"][0] else "r"
    label = "coverage rate (final step)" if key == "coverage_rate" else "team return"
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=120)
    values = {name: np.array([episode[key] for episode in eps]) for name, eps in episodes.items()}
    bins = np.histogram_bin_edges(np.concatenate(list(values.values())), bins=12).tolist()  # shared by both histograms
    for name, color in (("model", "tab:blue"), ("random", "tab:red")):
        ax.hist(values[name], bins=bins, alpha=0.5, color=color, label=f"{name} (mean {values[name].mean():.3f})")
    ax.set_xlabel(label)
    ax.set_ylabel("episodes")
    ax.set_title(f"{args.task}: {os.path.basename(args.model)} vs random, same {len(values['model'])} episodes")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(out, "evaluation.png"))
    plt.close(fig)
    print(f"wrote {os.path.join(out, 'evaluation.png')}")

    progress = os.path.join(os.path.dirname(os.path.abspath(args.model)), "progress.csv")
    if os.path.exists(progress):
        columns = read_progress(progress)
        preferred: tuple[str, ...] = ("rollout/coverage_rate", "eval/coverage_rate", "rollout/ep_rew_mean")
        names = [name for name in preferred if name in columns]
        names += sorted(name for name in columns if name.startswith("rollout/intrinsic_fire_rate_"))
        fig, axes = plt.subplots(len(names), 1, figsize=(7, 2.2 * len(names)), dpi=120, sharex=True, squeeze=False)
        for ax, name in zip(axes[:, 0], names):
            ax.plot(*columns[name], lw=1)
            ax.set_ylabel(name.split("/", 1)[1], fontsize=8)
            ax.grid(alpha=0.3)
        axes[-1, 0].set_xlabel("agent-steps")
        fig.tight_layout()
        fig.savefig(os.path.join(out, "training.png"))
        plt.close(fig)
        print(f"wrote {os.path.join(out, 'training.png')}")
    if args.gif:
        frames = record_gif(model, args.task, os.path.join(out, "replay.gif"), n_episodes=2, seed=args.seed)
        print(f"wrote {os.path.join(out, 'replay.gif')} ({frames} frames)")


if __name__ == "__main__":
    main()
