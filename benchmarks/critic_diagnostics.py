"""What the hypergraph critic's Gumbel noise does to a trained critic, and how the scales meet in the advantage.

    python benchmarks/critic_diagnostics.py --model <out>/runs/mshg_only/cn-sparse-n3_s6/cn-sparse-n3.zip [...]

For each model (a benchmark run's ``<task>.zip`` or a ``<task>_<N>_steps.zip`` kept when the run was trained longer;
its run's ``spec.json`` gives the method, task and config), the script collects ``--rollouts`` rollouts with the
model's policy exactly as training collects them (``benchmarks/bonus_readings.py``; nothing is updated) and reads,
per critic scale:

- **the Gumbel noise against the states**: each scale re-runs over the rollout from its stored states ``--draws``
  times with fresh Gumbel draws (the noise comes after the GRU, so it never carries from one step to the next).
  ``noise sd`` is the root mean square over the rollout's states of the value's standard deviation across the draws
  at a fixed state; ``state sd`` is the standard deviation across the rollout's states of the value averaged over the
  draws; both in the scale's normalised value units. The noise is switched on for this reading even in a model trained
  without it (the column ``trained with noise`` says which), so both arms are read the same way. The team scale has
  one edge type: its Gumbel-softmax is 1 whatever the draw, and its ``noise sd`` is 0.
- **explained variance** of the GAE returns by the rollout's values in return space (what ``train/`` logs);
- **the advantage weight** ``W_K`` the update would use on this rollout (``docs/method.md``, "Advantage mixing"):
  the softmax over K of the log-sum-exps of the standardised advantages, i.e. ``W_K`` is proportional to
  ``exp(lme_K)`` with ``lme_K = log mean_j exp(A_j^K)`` (printed as ``log mean exp(A)``: at least 0 for standardised
  advantages, 0.5 for a normal distribution; a heavy right tail makes it large, up to about ``sqrt(n)`` for ``n``
  samples), with the range of ``train/advantage_weight_<scale>`` over the
  run's ``progress.csv`` up to the model's agent-steps when it lies next to the model;
- **the correlation of the scales' advantages** (Pearson, over the rollout's agent-steps).

Writes the two Markdown tables to stdout (and ``--out``).
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from bonus_readings import (
    add_run_model_arguments,
    check_run_model_arguments,
    emit,
    load_experiment,
    model_label,
    rollout_windows,
)
from stable_baselines3.common.utils import explained_variance

from sb3_saeir.mappo.losses import scale_advantage_weights


def gumbel_spread(policy: Any, window: dict[str, Any], k: int, n_draws: int) -> tuple[float, float]:
    """``(noise sd, state sd)`` of critic scale ``k`` over one rollout window (see the module docstring).

    :param policy: the model's :class:`~sb3_saeir.common.policies.MultiAgentActorCriticPolicy`
    :param window: one rollout of :func:`bonus_readings.rollout_windows`
    :param k: index of the scale
    :param n_draws: Gumbel draws per state
    """
    n_steps, n_envs = window["episode_starts"].shape
    n_agents = policy.n_agents
    n_games = n_envs // n_agents
    # (T, E, *obs_shape) -> (T, G, N, d)
    obs = th.as_tensor(window["observations"]).reshape(n_steps, n_games, n_agents, -1)
    starts = th.as_tensor(window["episode_starts"], dtype=th.float32).reshape(n_steps, n_games, n_agents)  # (T, G, N)
    states = th.as_tensor(window["critic_states"][k])  # (G, N, H)
    trained_with_noise = policy.critic_gumbel_noise
    policy.critic_gumbel_noise = True
    try:
        with th.no_grad():
            draws = th.stack([policy.evaluate_critic(k, obs, states, starts) for _ in range(n_draws)]).numpy()
    finally:
        policy.critic_gumbel_noise = trained_with_noise
    # draws: (D, T, G, N)
    noise_sd = float(np.sqrt(draws.var(axis=0).mean()))
    state_sd = float(draws.mean(axis=0).std())
    return noise_sd, state_sd


def advantage_weights(advantages: np.ndarray) -> np.ndarray:
    """``W_K`` of the update on standardised advantages ``(T, E, K)`` of one rollout (one minibatch), ``(K,)``."""
    flat = th.as_tensor(advantages.reshape(-1, advantages.shape[-1]))  # (T, E, K) -> (T * E, K)
    return scale_advantage_weights(flat).numpy()


def log_mean_exp(advantages: np.ndarray) -> np.ndarray:
    """``log mean_j exp(A_j^K)`` per scale of standardised advantages ``(T, E, K)``, ``(K,)`` (no overflow)."""
    flat = advantages.reshape(-1, advantages.shape[-1]).astype(np.float64)  # (T * E, K)
    top = flat.max(axis=0)
    return top + np.log(np.exp(flat - top).mean(axis=0))


def advantage_correlations(advantages: np.ndarray, scales: tuple[str, ...]) -> dict[str, float]:
    """Pearson correlation of every pair of scales' advantages ``(T, E, K)`` over the agent-steps."""
    flat = advantages.reshape(-1, advantages.shape[-1])  # (T, E, K) -> (T * E, K)
    matrix = np.corrcoef(flat, rowvar=False) if flat.shape[-1] > 1 else np.ones((1, 1))
    return {f"{scales[a]}-{scales[b]}": float(matrix[a, b]) for a in range(len(scales)) for b in range(a + 1, len(scales))}


def logged_weight_ranges(
    progress: Path, scales: tuple[str, ...], up_to: float = float("inf")
) -> dict[str, tuple[float, float]]:
    """Min and max of ``train/advantage_weight_<scale>`` over a run's ``progress.csv`` rows up to ``up_to`` agent-steps
    (``time/total_timesteps``; a model kept at 1M reads the first 1M of a run trained on to 3M); empty without one."""
    if not progress.is_file():
        return {}
    columns: dict[str, list[float]] = {scale: [] for scale in scales}
    with progress.open(newline="") as handle:
        for row in csv.DictReader(handle):
            steps = row.get("time/total_timesteps", "")
            if steps and float(steps) > up_to:
                break
            for scale in scales:
                cell = row.get(f"train/advantage_weight_{scale}", "")
                if cell:
                    columns[scale].append(float(cell))
    return {scale: (min(values), max(values)) for scale, values in columns.items() if values}


def model_diagnostics(model_path: Path, n_rollouts: int, n_draws: int, n_games: int | None, seed: int) -> dict[str, Any]:
    """Every reading of one model (see the module docstring), pooled over its rollouts."""
    experiment = load_experiment(model_path, None, None, n_games, seed)
    model = experiment.model
    assert model is not None
    trained_steps = int(model.num_timesteps)  # before the rollouts, which count from 0 again
    th.manual_seed(seed)
    windows = rollout_windows(experiment, n_rollouts)
    policy = model.policy
    scales = windows[0]["scales"]
    per_scale: dict[str, dict[str, float]] = {}
    for k, scale in enumerate(scales):
        spreads = [gumbel_spread(policy, window, k, n_draws) for window in windows]
        values = np.concatenate([w["denormalized_values"][..., k].ravel() for w in windows])
        returns = np.concatenate([w["returns"][..., k].ravel() for w in windows])
        per_scale[scale] = {
            "noise_sd": float(np.sqrt(np.mean([noise**2 for noise, _ in spreads]))),
            "state_sd": float(np.mean([state for _, state in spreads])),
            "explained_variance": float(explained_variance(values, returns)),
        }
    weights = np.mean([advantage_weights(w["advantages"]) for w in windows], axis=0)
    exps = np.mean([log_mean_exp(w["advantages"]) for w in windows], axis=0)
    correlations = advantage_correlations(np.concatenate([w["advantages"] for w in windows], axis=1), scales)
    logged = logged_weight_ranges(model_path.parent / "progress.csv", scales, up_to=trained_steps)
    for k, scale in enumerate(scales):
        per_scale[scale].update({"weight": float(weights[k]), "log_mean_exp": float(exps[k])})
    trained_with_noise = bool(getattr(policy, "critic_gumbel_noise", False))
    experiment.close()
    return {
        "scales": per_scale,
        "correlations": correlations,
        "logged_weights": logged,
        "trained_with_noise": trained_with_noise,
        "trained_steps": trained_steps,
    }


def markdown(results: dict[str, dict[str, Any]], n_draws: int) -> str:
    """The per-scale table and the correlation table."""
    lines = [
        f"| model | agent-steps | trained with noise | scale | noise sd ({n_draws} draws) | state sd | noise / state "
        "| explained variance | log mean exp(A) | W_K (rollout) | W_K logged over the run (min-max) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, result in results.items():
        for scale, row in result["scales"].items():
            ratio = row["noise_sd"] / row["state_sd"] if row["state_sd"] > 0 else math.nan
            logged = result["logged_weights"].get(scale)
            logged_text = "-" if logged is None else f"{logged[0]:.4f}-{logged[1]:.4f}"
            noise = "yes" if result["trained_with_noise"] else "no"
            lines.append(
                f"| {name} | {result['trained_steps']:,} | {noise} | {scale} | {row['noise_sd']:.4f} "
                f"| {row['state_sd']:.4f} | {ratio:.3f} | {row['explained_variance']:.3f} | {row['log_mean_exp']:.3f} "
                f"| {row['weight']:.4f} | {logged_text} |"
            )
    pairs = list(next(iter(results.values()))["correlations"])
    lines += ["", f"| model | {' | '.join(f'corr {pair}' for pair in pairs)} |", "|---" * (1 + len(pairs)) + "|"]
    for name, result in results.items():
        cells = " | ".join(f"{result['correlations'][pair]:.3f}" for pair in pairs)
        lines.append(f"| {name} | {cells} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_model_arguments(parser)
    parser.add_argument("--draws", type=int, default=32, help="Gumbel draws per state")
    args = parser.parse_args(argv)
    if args.draws < 2:
        parser.error(f"--draws must be at least 2, got {args.draws}")
    check_run_model_arguments(parser, args)
    th.set_num_threads(1)
    results = {
        model_label(path): model_diagnostics(path, args.rollouts, args.draws, args.n_games, args.seed) for path in args.model
    }
    emit(markdown(results, args.draws), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
