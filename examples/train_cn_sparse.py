"""Train on sparse Cooperative Navigation, compare with a random policy, and write a learning curve and a GIF.

    python examples/train_cn_sparse.py                        # the quickstart (bash scripts/quickstart.sh)
    python examples/train_cn_sparse.py --timesteps 2000000 --seed 1
    python examples/train_cn_sparse.py --algo ppo             # plain SB3 PPO with parameter sharing (IPPO)

The console shows a progress bar with an ETA and one line per evaluation; the full logs go to ``progress.csv`` and
tensorboard in the run folder (``--out``, default ``runs/quickstart``). At the end the trained policy and a random
policy play the same evaluation episodes (same seeds) and the script prints both side by side, how often the SAEIR
bonus fired, and what that means at this budget. Files written into the run folder: ``model.zip``, ``progress.csv``,
tensorboard events, ``eval.json``, ``learning_curve.png`` and ``replay.gif``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import time
from typing import Any

import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import configure
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

from sb3_saeir import SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.callbacks import EpisodeMetricsCallback, episode_metric_means
from sb3_saeir.common.utils import set_num_threads
from sb3_saeir.enjoy import record_gif
from sb3_saeir.evaluation import MultiAgentEvalCallback, RandomMultiAgentPolicy, evaluate_multiagent_policy

# Measured on the 2-core reference machine: 576,000 agent-steps (60 updates of 128 games x 3 agents x 25 steps)
# train in about 4 minutes with the native navigation engine, leaving time for evaluation, the plot and the GIF.
DEFAULT_TIMESTEPS = 576_000
EVAL_SEED = 10_000  # evaluation games never replay training seeds


class CompactEvalCallback(MultiAgentEvalCallback):
    """:class:`~sb3_saeir.evaluation.MultiAgentEvalCallback` that prints one line per evaluation (the full numbers
    still go to the logger: ``progress.csv`` and tensorboard)."""

    def evaluate(self) -> bool:
        keep_going = super().evaluate()
        summary, n = self.last_summary, self.last_summary["n_episodes"]
        train = episode_metric_means(list(self.model.ep_info_buffer or []))
        line = (
            f"{self.num_timesteps:>10,} agent-steps | eval coverage {summary['coverage_rate_mean']:.3f}"
            f" ± {summary['coverage_rate_std'] / math.sqrt(n):.3f}"
            f" | success {summary.get('success_mean', 0.0):.2f} | team return {summary['ep_rew_mean']:6.2f}"
        )
        if "coverage_rate" in train:
            line += f" | train coverage {train['coverage_rate']:.3f}"
        print(line, flush=True)
        return keep_going


class FireRateRecorder(BaseCallback):
    """Remember, after each rollout, the fraction of agent-steps where each intrinsic reward scale fired
    (``rollout/intrinsic_fire_rate_<scale>``, logged by :class:`~sb3_saeir.intrinsic.SAEIRCallback`)."""

    prefix = "rollout/intrinsic_fire_rate_"

    def __init__(self) -> None:
        super().__init__()
        self.history: list[dict[str, float]] = []

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        logged = self.logger.name_to_value.items()
        rates = {key[len(self.prefix) :]: value for key, value in logged if key.startswith(self.prefix)}
        if rates:
            self.history.append(rates)


def evaluate_pair(model: Any, task: str, n_episodes: int, seed: int) -> tuple[dict[str, float], dict[str, float]]:
    """The trained policy and a random policy on the same evaluation episodes (same game seeds)."""
    results = []
    for policy in (model, None):
        env = make_multiagent_vec_env(task, n_games=min(10, n_episodes), seed=seed)
        policy = policy if policy is not None else RandomMultiAgentPolicy(env.action_space, seed=seed)
        results.append(evaluate_multiagent_policy(policy, env, n_episodes=n_episodes, deterministic=True))
        env.close()
    return results[0], results[1]


def standard_error(summary: dict[str, float], key: str) -> float:
    return summary[f"{key}_std"] / math.sqrt(summary["n_episodes"])


def verdict(trained: dict[str, float], random: dict[str, float], fire_rate: float | None, timesteps: int) -> str:
    """One plain sentence on what the numbers mean, from the numbers (no hard-coded outcome)."""
    diff = trained["coverage_rate_mean"] - random["coverage_rate_mean"]
    noise = 2.0 * math.hypot(standard_error(trained, "coverage_rate"), standard_error(random, "coverage_rate"))
    if diff > noise:
        learned = f"the policy's coverage rate is {diff:.3f} above random's, more than the evaluation noise (±{noise:.3f})"
        advice = "it has started to learn, train longer (--timesteps) for more"
    elif diff < -noise:
        learned = f"the policy's coverage rate is {-diff:.3f} below random's, more than the evaluation noise (±{noise:.3f})"
        advice = "it has not learned to navigate yet (the paper trains 60M agent-steps; see docs/results.md)"
    else:
        learned = f"the policy is within the evaluation noise (±{noise:.3f}) of random"
        advice = "it has not learned to navigate yet (the paper trains 60M agent-steps; see docs/results.md)"
    if fire_rate is None:
        bonus = "no intrinsic reward was used"
    elif fire_rate < 0.01:
        bonus = "the SAEIR bonus almost never fired, so the extrinsic reward alone drove training"
    else:
        bonus = f"the SAEIR bonus fired on {100 * fire_rate:.1f}% of agent-steps"
    return f"After {timesteps:,} agent-steps {learned}: {advice}; {bonus}."


def training_coverage(progress_csv: str) -> tuple[list[int], list[float]]:
    """``rollout/coverage_rate`` over agent-steps from the run's ``progress.csv``."""
    steps, values = [], []
    with open(progress_csv) as file:
        for row in csv.DictReader(file):
            if row.get("rollout/coverage_rate") and row.get("time/total_timesteps"):
                steps.append(int(float(row["time/total_timesteps"])))
                values.append(float(row["rollout/coverage_rate"]))
    return steps, values


def plot_curve(
    path: str,
    evaluator: MultiAgentEvalCallback,
    progress_csv: str,
    final: tuple[int, dict[str, float]],
    random: dict[str, float],
    title: str,
) -> None:
    """Coverage over agent-steps (training games, evaluations, the final evaluation) with the random policy's level."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, ax = plt.subplots(figsize=(7, 4), dpi=120)
    train_steps, train_values = training_coverage(progress_csv)
    if train_steps:
        ax.plot(train_steps, train_values, color="tab:blue", alpha=0.4, lw=1, label="training games (stochastic)")
    if evaluator.timesteps:
        per_eval = np.array(evaluator.history["coverage_rate"])  # (n_evaluations, n_episodes)
        mean, se = per_eval.mean(axis=1), per_eval.std(axis=1) / math.sqrt(per_eval.shape[1])
        ax.plot(evaluator.timesteps, mean, "o-", color="tab:blue", label="evaluation (greedy) ± 1 s.e.")
        ax.fill_between(evaluator.timesteps, mean - se, mean + se, color="tab:blue", alpha=0.2)
    steps, trained = final  # after the last update (the last evaluation above ran just before it)
    ax.errorbar(
        [steps],
        [trained["coverage_rate_mean"]],
        yerr=[standard_error(trained, "coverage_rate")],
        fmt="D",
        color="black",
        capsize=3,
        label=f"final evaluation, {int(trained['n_episodes'])} episodes ({trained['coverage_rate_mean']:.3f})",
    )
    level, se_random = random["coverage_rate_mean"], standard_error(random, "coverage_rate")
    ax.axhline(level, color="tab:red", ls="--", label=f"random policy, same final episodes ({level:.3f})")
    ax.axhspan(level - se_random, level + se_random, color="tab:red", alpha=0.1)
    ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda x, _: f"{x / 1000:.0f}k"))
    ax.set_xlabel("agent-steps")
    ax.set_ylabel("coverage rate (final step)")
    ax.set_ylim(bottom=0)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", choices=["saeir_ppo", "ppo"], default="saeir_ppo", help="ppo: plain SB3 PPO (IPPO)")
    parser.add_argument(
        "--task",
        default="cn-sparse-no-penalty-n3",
        help="cn-sparse-no-penalty-n3 / -n4 (no collision penalty: the reading that reaches Table 1) or cn-sparse-n3 / "
        "-n4 (the paper's words, collision penalty 1)",
    )
    parser.add_argument("--n-games", type=int, default=128, help="games per rollout (128: the paper's rollout threads)")
    parser.add_argument("--timesteps", type=int, default=DEFAULT_TIMESTEPS, help="agent-steps")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-freq", type=int, default=None, help="agent-steps between evaluations (default: 10 per run)")
    parser.add_argument("--eval-episodes", type=int, default=100, help="game episodes per evaluation during training")
    parser.add_argument("--final-episodes", type=int, default=500, help="game episodes of the final comparison")
    parser.add_argument("--gif-episodes", type=int, default=3, help="episodes in replay.gif (0: no GIF)")
    parser.add_argument("--out", default="runs/quickstart", help="run folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar (e.g. in logs)")
    args = parser.parse_args()
    set_num_threads(None)  # the free cores, at most 2 (OMP_NUM_THREADS wins): more threads than free cores slow SB3 down
    os.makedirs(args.out, exist_ok=True)
    start = time.time()

    env = make_multiagent_vec_env(args.task, n_games=args.n_games, seed=args.seed)  # native engine for cn-sparse-*
    callbacks: list[BaseCallback] = []
    model: OnPolicyAlgorithm
    if args.algo == "saeir_ppo":  # the paper's Cooperative Navigation settings are SAEIR_PPO's defaults
        model = SAEIR_PPO("MSHGPolicy", env, seed=args.seed)
        name = "SAEIR_PPO"
    else:
        model = PPO("MlpPolicy", env, n_steps=125, batch_size=500, n_epochs=10, seed=args.seed)
        callbacks.append(EpisodeMetricsCallback())
        name = "PPO (IPPO)"
    model.set_logger(configure(args.out, ["csv", "tensorboard"]))  # full logs to files, none on the console
    eval_freq = args.eval_freq or max(1, args.timesteps // 10)
    eval_env = make_multiagent_vec_env(args.task, n_games=min(10, args.eval_episodes), seed=EVAL_SEED + args.seed)
    evaluator = CompactEvalCallback(
        eval_env, n_eval_episodes=args.eval_episodes, eval_freq=eval_freq, main_metric="coverage_rate", verbose=0
    )
    fire_rates = FireRateRecorder()
    callbacks += [evaluator, fire_rates]
    print(
        f"Training {name} on {args.task}: {args.n_games} games x {env.n_agents} agents, {args.timesteps:,} agent-steps, "
        f"seed {args.seed}. Logs: {args.out}/progress.csv and tensorboard (tensorboard --logdir {args.out})."
    )
    model.learn(args.timesteps, callback=callbacks, progress_bar=not args.no_progress)
    train_seconds = time.time() - start
    model_path = os.path.join(args.out, "model.zip")
    model.save(model_path)
    eval_env.close()
    env.close()

    trained, random = evaluate_pair(model, args.task, args.final_episodes, seed=EVAL_SEED + 1_000_000 + args.seed)
    scales = sorted({scale for rates in fire_rates.history for scale in rates})
    fired = {scale: float(np.mean([rates.get(scale, 0.0) for rates in fire_rates.history])) for scale in scales}
    fired_last = fire_rates.history[-1] if fire_rates.history else {}
    mean_fired = float(np.mean(list(fired.values()))) if fired else None
    sentence = verdict(trained, random, mean_fired, int(model.num_timesteps))

    n = int(trained["n_episodes"])
    print(f"\nFinal evaluation on the same {n} episodes (same seeds, greedy actions), mean ± standard error:")
    print(f"{'':14}{name:>18}{'random policy':>18}")
    for label, key in (("coverage rate", "coverage_rate"), ("success rate", "success"), ("team return", "ep_rew")):
        cells = [f"{s[f'{key}_mean']:.3f} ± {standard_error(s, key):.3f}" for s in (trained, random)]
        print(f"{label:14}{cells[0]:>18}{cells[1]:>18}")
    if fired:
        rates = ", ".join(f"{scale} {100 * rate:.2f}%" for scale, rate in fired.items())
        last = ", ".join(f"{scale} {100 * fired_last.get(scale, 0.0):.2f}%" for scale in scales)
        print(f"SAEIR bonus fired on (share of agent-steps, mean over the run): {rates}; last rollout: {last}")
    print(sentence)

    curve_path = os.path.join(args.out, "learning_curve.png")
    progress = os.path.join(args.out, "progress.csv")
    plot_curve(curve_path, evaluator, progress, (int(model.num_timesteps), trained), random, f"{name} on {args.task}")
    gif_path = os.path.join(args.out, "replay.gif")
    if args.gif_episodes > 0:
        record_gif(model, args.task, gif_path, n_episodes=args.gif_episodes, seed=EVAL_SEED + 1_000_000 + args.seed)
    with open(os.path.join(args.out, "eval.json"), "w") as file:
        json.dump(
            {
                "algo": args.algo,
                "task": args.task,
                "agent_steps": int(model.num_timesteps),
                "train_seconds": round(train_seconds, 1),
                "trained": trained,
                "random": random,
                "intrinsic_fire_rate": fired,
                "intrinsic_fire_rate_last_rollout": fired_last,
                "verdict": sentence,
                "evaluations": {
                    "timesteps": evaluator.timesteps,
                    "coverage_rate_mean": [float(np.mean(v)) for v in evaluator.history.get("coverage_rate", [])],
                },
            },
            file,
            indent=2,
        )
    print(f"\nWritten in {args.out}/ after {time.time() - start:.0f} s (training {train_seconds:.0f} s):")
    print(f"  model.zip           the trained model ({type(model).__name__}.load('{model_path}'))")
    print("  progress.csv        every logged value; tensorboard events: tensorboard --logdir " + args.out)
    print("  eval.json           the comparison above")
    print("  learning_curve.png  coverage over agent-steps, random policy marked")
    if args.gif_episodes > 0:
        print(f"  replay.gif          the trained agents on {args.gif_episodes} evaluation episode(s)")


if __name__ == "__main__":
    main()
