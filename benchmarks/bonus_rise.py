"""How far a trained critic's values stay from firing the SAEIR bonus: the rise of each step's value above the
log-mean-exp of the window's earlier values, against the rise that would fire.

    python benchmarks/bonus_rise.py --model <out>/runs/mappo/cn-sparse-n3_s1/cn-sparse-n3.zip [...]

The released code's bonus (``docs/method.md``, "The intrinsic reward"; ``saeir_bonus(..., variant="code")``) rewards
step ``t`` of a window when appending its value ``v_t`` lowers the entropy ``H_t`` of the value-softmax over the
window's earlier steps. With ``m_t`` the log-mean-exp of ``v_0 .. v_{t-1}``, the step's **rise** is ``d_t = v_t - m_t``;
its share of the softmax is ``q_t = sigmoid(d_t - log t)``, and the step fires exactly when ``h(q_t) / q_t < H_t``
(``h`` the binary entropy), i.e. when ``d_t`` exceeds the **threshold** ``d*_t = logit(q*_t) + log t`` with
``h(q*) / q* = H_t``: about +1 when the earlier values are flat. Steps 0 and 1 never fire (``H_0 = H_1 = 0``) and are
left out of every figure.

For each model (a benchmark run's model with its ``spec.json``: any method, the bonus is read on its critic's own
values, every scale of a hypergraph critic), the script collects ``--rollouts`` rollouts exactly as training does
(``benchmarks/bonus_readings.py``, nothing updated) and prints per scale: quantiles of the rise, the share of steps
with a rise above +1, the median threshold and the median margin ``d - d*`` (the step fires when it is above 0), the
fire rate (equal to the code bonus's), and the fire rate under three changes of setting that leave the authors'
defaults as they are: the values in return space (what ``normalize_values=False`` would feed the bonus: the
normalised values times the scale's ``ValueNorm`` standard deviation ``sigma``, printed), the values times 4 (a
softmax temperature of 1/4; no such setting exists), and the window restarted at every episode start. A second table
gives the mean normalised value at every fifth position of the window (about ten positions of a window longer than
50 steps) and at its last, the shape the rises come from. A third asks whether the bonus marks episode starts: per
scale, the fire rate beside the rate at which steps are an episode's first (steps 2 on of each window, as the fire
rate), the share of firing steps that are an episode's first step, and the mean value by position in the episode
(steps before the window's first episode start, whose position is unknown, left out). A fourth asks whether it marks
the run-up to a reward: per scale, the share of steps that lie in the ``RUN_UP`` = 10 steps up to and including a step
with a positive env reward of the same episode and window (on football, a goal), beside the share of firing steps that
do; a goal after the window's end is not seen, so both shares count only the run-ups inside the window.
"""

from __future__ import annotations

import argparse
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

from sb3_saeir.intrinsic import saeir_bonus

QUANTILES = (0.5, 0.9, 0.99)
TEMPERATURE_FACTOR = 4.0
RUN_UP = 10


def window_entropies(values: np.ndarray) -> np.ndarray:
    """``H_t`` of every step of windows ``(T, S)``: the entropy of the softmax over ``v_0 .. v_{t-1}`` (``H_0 = 0``),
    computed directly over each prefix, ``(T, S)``."""
    n_steps = values.shape[0]
    entropies = np.zeros(values.shape, dtype=np.float64)
    for t in range(1, n_steps):
        prefix = values[:t].astype(np.float64)  # (t, S)
        logits = prefix - prefix.max(axis=0)
        log_p = logits - np.log(np.exp(logits).sum(axis=0))
        entropies[t] = -(np.exp(log_p) * log_p).sum(axis=0)
    return entropies


def rises(values: np.ndarray) -> np.ndarray:
    """``d_t = v_t - logmeanexp(v_0 .. v_{t-1})`` of windows ``(T, S)``, ``(T, S)`` (``nan`` at step 0)."""
    values = values.astype(np.float64)
    out = np.full(values.shape, np.nan)
    for t in range(1, values.shape[0]):
        prefix = values[:t]
        top = prefix.max(axis=0)
        out[t] = values[t] - (top + np.log(np.exp(prefix - top).mean(axis=0)))
    return out


def thresholds(entropies: np.ndarray) -> np.ndarray:
    """The rise ``d*_t`` above which step ``t`` fires, from the entropies ``H_t`` ``(T, S)`` of the earlier steps:
    ``logit(q*) + log t`` with ``h(q*) / q* = H_t``, found by bisection on ``x = logit(q)`` (``h(q) / q`` falls from
    +inf to 0 as ``x`` grows: ``softplus(-x) + exp(-x) softplus(x)``); ``inf`` where ``H_t = 0``."""
    low = np.full(entropies.shape, -60.0)
    high = np.full(entropies.shape, 60.0)
    for _ in range(100):
        middle = 0.5 * (low + high)
        ratio = np.logaddexp(0.0, -middle) + np.exp(-middle) * np.logaddexp(0.0, middle)  # h(q) / q at q = sigmoid(x)
        above = ratio > entropies  # too little share to fire: the root lies higher
        low = np.where(above, middle, low)
        high = np.where(above, high, middle)
    steps = np.arange(entropies.shape[0], dtype=np.float64).reshape(-1, *([1] * (entropies.ndim - 1)))
    with np.errstate(divide="ignore"):
        log_steps = np.log(steps)
    return np.where(entropies > 0, 0.5 * (low + high) + log_steps, np.inf)


def episode_positions(episode_starts: np.ndarray) -> np.ndarray:
    """Each step's position in its episode, 0 on an episode's first step, of windows ``(T, S)``; ``-1`` before the
    window's first episode start (that episode began in an earlier rollout, at an unknown position), ``(T, S)``."""
    starts = episode_starts.astype(bool)
    positions = np.full(starts.shape, -1, dtype=np.int64)
    positions[0] = np.where(starts[0], 0, -1)
    for t in range(1, starts.shape[0]):
        positions[t] = np.where(starts[t], 0, np.where(positions[t - 1] >= 0, positions[t - 1] + 1, -1))
    return positions


def marked_share(fired: np.ndarray, marked: np.ndarray) -> float:
    """The share of firing steps that are marked (``nan`` when no step fires), both ``(T, S)``."""
    n_fired = int(fired.sum())
    return float((fired & marked).sum() / n_fired) if n_fired else float("nan")


def first_step_share(fired: np.ndarray, episode_starts: np.ndarray) -> float:
    """The share of firing steps that are an episode's first step (``nan`` when no step fires).

    :param fired: which steps fired, ``(T, S)``
    :param episode_starts: which steps are an episode's first, ``(T, S)``
    """
    return marked_share(fired, episode_starts.astype(bool))


def before_positive_reward(rewards: np.ndarray, episode_starts: np.ndarray, run_up: int) -> np.ndarray:
    """Which steps lie in the ``run_up`` steps up to and including a step with a positive reward of the same episode,
    of windows ``(T, S)``: step ``t`` is marked when a step ``u`` with ``t <= u < t + run_up`` has a reward above 0 and
    no episode starts in ``(t, u]``.

    :param rewards: the env reward of each step (received after its action), ``(T, S)``
    :param episode_starts: which steps are an episode's first, ``(T, S)``
    :param run_up: how many steps, the rewarded one included, are marked before each positive reward
    :return: the marked steps, ``(T, S)``
    """
    starts = episode_starts.astype(bool)
    marked = np.zeros(rewards.shape, dtype=bool)
    steps_to_reward = np.full(rewards.shape[1], np.inf)  # (S,) steps from t to the episode's next positive reward
    for t in range(rewards.shape[0] - 1, -1, -1):
        steps_to_reward = np.where(rewards[t] > 0, 0.0, steps_to_reward + 1.0)
        marked[t] = steps_to_reward < run_up
        steps_to_reward = np.where(starts[t], np.inf, steps_to_reward)  # the steps before t belong to another episode
    return marked


def episode_profile(values: np.ndarray, positions: np.ndarray, at: list[int]) -> np.ndarray:
    """The mean value at each position ``at`` in the episode (``nan`` where no step has that position), ``(len(at),)``.

    :param values: the values of windows ``(T, S)``
    :param positions: :func:`episode_positions` of the windows, ``(T, S)``
    :param at: the positions
    """
    return np.array([values[positions == position].mean() if (positions == position).any() else np.nan for position in at])


def scale_readings(
    values: np.ndarray, values_return_space: np.ndarray, episode_starts: np.ndarray, rewards: np.ndarray
) -> dict[str, Any]:
    """Every figure of one scale over windows ``(T, S)`` (see the module docstring); ``rewards`` are the env rewards."""
    rise = rises(values)[2:]  # steps 0 and 1 never fire
    threshold = thresholds(window_entropies(values))[2:]
    fired = saeir_bonus(values)[2:] > 0
    positions = episode_positions(episode_starts)
    run_up = before_positive_reward(rewards, episode_starts, RUN_UP)[2:]
    finite = np.isfinite(threshold)
    return {
        "n": rise.size,
        "quantiles": np.quantile(rise, QUANTILES),
        "max": float(rise.max()),
        "above_one": float((rise > 1.0).mean()),
        "threshold_median": float(np.median(threshold[finite])) if finite.any() else float("inf"),
        "margin_median": float(np.median(rise - threshold)),
        "fire_rate": float(fired.mean()),
        "fire_rate_by_rise": float((rise > threshold).mean()),
        "fire_rate_return_space": float((saeir_bonus(values_return_space)[2:] > 0).mean()),
        "fire_rate_temperature": float((saeir_bonus(TEMPERATURE_FACTOR * values)[2:] > 0).mean()),
        "fire_rate_episode_windows": float((saeir_bonus(values, episode_starts=episode_starts)[2:] > 0).mean()),
        "profile": values.mean(axis=1),  # (T,) mean value at each position of the window
        "first_step_share": first_step_share(fired, episode_starts[2:]),
        "episode_start_rate": float(episode_starts[2:].astype(bool).mean()),
        "episode_profile": episode_profile(values, positions, profile_positions(values.shape[0])),
        "run_up_rate": float(run_up.mean()),
        "run_up_share": marked_share(fired, run_up),
    }


def model_readings(model_path: Path, n_rollouts: int, n_games: int | None, seed: int) -> dict[str, dict[str, Any]]:
    """``{scale: readings}`` of one model, pooled over its rollouts' windows (games x agents)."""
    experiment = load_experiment(model_path, None, None, n_games, seed)
    windows = rollout_windows(experiment, n_rollouts)
    experiment.close()
    readings = {}
    for k, scale in enumerate(windows[0]["scales"]):
        values = np.concatenate([w["values"][..., k] for w in windows], axis=1)  # (T, E * rollouts)
        returns_space = np.concatenate([w["denormalized_values"][..., k] for w in windows], axis=1)
        starts = np.concatenate([w["episode_starts"] for w in windows], axis=1)
        rewards = np.concatenate([w["rewards"][..., k] for w in windows], axis=1)  # (T, E * rollouts)
        readings[scale] = scale_readings(values, returns_space, starts, rewards)
        spread = values.std()
        readings[scale]["sigma"] = float(returns_space.std() / spread) if spread > 0 else float("nan")
    return readings


def markdown(results: dict[str, dict[str, dict[str, Any]]]) -> str:
    quantile_names = " | ".join(f"rise p{round(100 * q)}" for q in QUANTILES)
    lines = [
        f"| model | scale | steps | {quantile_names} | rise max | rise > 1 | threshold (median) | margin (median) "
        f"| fire rate | return space: sigma, fire rate | values x{TEMPERATURE_FACTOR:g}: fire rate "
        "| episode windows: fire rate |",
        "|---" * 14 + "|",
    ]
    for name, scales in results.items():
        for scale, row in scales.items():
            quantiles = " | ".join(f"{value:+.3f}" for value in row["quantiles"])
            lines.append(
                f"| {name} | {scale} | {row['n']} | {quantiles} | {row['max']:+.3f} | {row['above_one']:.4f} "
                f"| {row['threshold_median']:+.3f} | {row['margin_median']:+.3f} | {row['fire_rate']:.4f} "
                f"| {row['sigma']:.2f}, {row['fire_rate_return_space']:.4f} | {row['fire_rate_temperature']:.4f} "
                f"| {row['fire_rate_episode_windows']:.4f} |"
            )
    n_steps = len(next(iter(next(iter(results.values())).values()))["profile"])
    positions = profile_positions(n_steps)
    lines += ["", f"| model | scale | {' | '.join(f'mean value at step {t}' for t in positions)} |"]
    lines.append("|---" * (2 + len(positions)) + "|")
    for name, scales in results.items():
        for scale, row in scales.items():
            profile = row["profile"]
            cells = " | ".join(f"{profile[t]:+.3f}" if t < len(profile) else "-" for t in positions)
            lines.append(f"| {name} | {scale} | {cells} |")
    lines += [
        "",
        "| model | scale | fire rate | episode-start rate | firing steps that are an episode's first step "
        f"| {' | '.join(f'mean value at episode step {t}' for t in positions)} |",
    ]
    lines.append("|---" * (5 + len(positions)) + "|")
    for name, scales in results.items():
        for scale, row in scales.items():
            cells = " | ".join("-" if np.isnan(value) else f"{value:+.3f}" for value in row["episode_profile"])
            share = "-" if np.isnan(row["first_step_share"]) else f"{row['first_step_share']:.3f}"
            lines.append(
                f"| {name} | {scale} | {row['fire_rate']:.4f} | {row['episode_start_rate']:.4f} | {share} | {cells} |"
            )
    lines += [
        "",
        f"| model | scale | fire rate | steps in the {RUN_UP} steps up to a positive reward "
        f"| firing steps in the {RUN_UP} steps up to a positive reward |",
        "|---|---|---|---|---|",
    ]
    for name, scales in results.items():
        for scale, row in scales.items():
            share = "-" if np.isnan(row["run_up_share"]) else f"{row['run_up_share']:.3f}"
            lines.append(f"| {name} | {scale} | {row['fire_rate']:.4f} | {row['run_up_rate']:.3f} | {share} |")
    return "\n".join(lines) + "\n"


def profile_positions(n_steps: int) -> list[int]:
    """The window positions of the value profile: every fifth step of a window of up to 50 (navigation's 25), about
    ten evenly spaced ones of a longer window (football's 200: every 20th), and always the last."""
    stride = 5 if n_steps <= 50 else 5 * round(n_steps / 50)
    return sorted({*range(0, n_steps, stride), n_steps - 1})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_model_arguments(parser)
    args = parser.parse_args(argv)
    check_run_model_arguments(parser, args)
    th.set_num_threads(1)
    results = {model_label(path): model_readings(path, args.rollouts, args.n_games, args.seed) for path in args.model}
    emit(markdown(results), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
