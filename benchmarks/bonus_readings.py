"""The three readings of the SAEIR bonus on a model's own rollouts, beside the supplement's Fig. 3.

    python benchmarks/bonus_readings.py --model <out>/runs/saeir_ppo/cn-sparse-n3_s*/cn-sparse-n3.zip
    python benchmarks/bonus_readings.py --algo saeir_ppo --task cn-sparse-n3      # an untrained model

For each model (a benchmark run's final ``<task>.zip``, ``model.zip`` for runs finished before 0.2.0a0: its
``spec.json`` next to it gives the method, task and config; or ``--algo``/``--task`` for a model saved elsewhere, or
for an untrained one when ``--model`` is left out), the script
plays ``--rollouts`` rollouts of ``--n-games`` games on the model's task with the model's policy, exactly as training
collects them (same buffer, stored normalised critic values, bootstrap values), without updating anything. On every
rollout window it computes ``coef * saeir_bonus(values, variant)`` for each reading (``"code"``, ``"paper"``,
``"supplement"``; ``docs/method.md``, "The intrinsic reward") and prints, per reading and critic scale, the fire rate
(share of agent-steps where the bonus is above 0), the mean bonus when fired, and the same per position in the window,
next to what the supplement's Fig. 3 shows for the authors' navigation bonus in the last training episode: the bonus
on 13 of the 26 steps at about 0.012-0.015, about 0 on the other steps, step 0 among them.

The window is the whole rollout (the authors' behaviour) unless ``--reset-at-episode-start``. Statistics are pooled
over the models given (e.g. the five seeds of an arm), their rollouts, games, agents and scales as printed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import torch as th

from sb3_saeir.experiment import Experiment
from sb3_saeir.intrinsic import saeir_bonus
from sb3_saeir.intrinsic.saeir import SAEIR_VARIANTS

READINGS = SAEIR_VARIANTS
FIG3 = {"fire_rate": 13 / 26, "fired_mean": "0.012-0.015", "step0": "about 0"}


def load_experiment(model: Path | None, algo: str | None, task: str | None, n_games: int | None, seed: int) -> Experiment:
    """The experiment of a saved model (its run's ``spec.json`` when there is one) or of an untrained model.

    :param model: the model zip, or ``None`` for an untrained model of ``algo`` on ``task``
    :param algo: the method (needed without ``spec.json``)
    :param task: the task (needed without ``spec.json``)
    :param n_games: games per rollout (default: the run's or the config's)
    :param seed: seed of the rollout games (and of the untrained model)
    """
    hyperparams = None
    spec_path = None if model is None else model.parent / "spec.json"
    if spec_path is not None and spec_path.is_file():
        spec = json.loads(spec_path.read_text())
        algo, task = algo or spec["algo"], task or spec["task"]
        hyperparams = spec.get("config")
        n_games = n_games or spec.get("n_games")
    if algo is None or task is None:
        raise SystemExit(f"bonus_readings: give --algo and --task (no spec.json next to {model}).")
    experiment = Experiment(algo, task, hyperparams=hyperparams, seed=seed, n_games=n_games)
    if model is None:
        experiment.build()
    else:
        experiment.load(model)
    return experiment


def rollout_windows(experiment: Experiment, n_rollouts: int) -> list[dict[str, Any]]:
    """Collect ``n_rollouts`` rollouts with the model's policy, as ``learn`` does, without any update.

    :return: per rollout the stored normalised values ``(T, E, K)``, episode starts ``(T, E)``, bootstrap values
        ``(E, K)``, last dones ``(E,)`` and the scale names; for the critic diagnostics also the observations
        ``(T, E, *obs_shape)``, the critics' states before the rollout's first step ``(K, G, N, H)``, the values in
        return space, the GAE returns and the env rewards ``(T, E, K)``, and the advantages standardised per scale as
        the update uses them ``(T, E, K)``
    """
    model = experiment.model
    assert model is not None and model.env is not None
    n_steps = int(model.n_steps)  # type: ignore[attr-defined]
    total = n_rollouts * n_steps * model.env.num_envs
    _, callback = model._setup_learn(total, callback=None, reset_num_timesteps=True)
    callback.on_training_start(locals(), globals())
    windows = []
    for _ in range(n_rollouts):
        buffer = model.rollout_buffer  # type: ignore[attr-defined]
        model.collect_rollouts(model.env, callback, buffer, n_rollout_steps=n_steps)  # type: ignore[attr-defined]
        windows.append(
            {
                "values": buffer.values.copy(),
                "episode_starts": buffer.episode_starts.copy(),
                "last_values": buffer.last_values.copy(),
                "last_dones": buffer.last_dones.copy(),
                "scales": tuple(model.policy.scales),  # type: ignore[attr-defined, arg-type]
                "observations": buffer.observations.copy(),
                "critic_states": buffer.critic_states[0].copy(),
                "denormalized_values": buffer.denormalized_values.copy(),
                "returns": buffer.returns.copy(),
                "rewards": buffer.rewards.copy(),
                "advantages": buffer.standardized_advantages(),
            }
        )
    callback.on_training_end()
    return windows


def reading_statistics(
    windows: list[dict[str, Any]], coef: float, reset_at_episode_start: bool
) -> dict[str, dict[str, dict[str, Any]]]:
    """``{reading: {scale: {fire_rate, fired_mean, fire_rate_by_step (T,), fired_mean_by_step (T,)}}}``."""
    result: dict[str, dict[str, dict[str, Any]]] = {}
    for reading in READINGS:
        bonuses = []  # per window (T, E, K)
        for window in windows:
            bonus = coef * saeir_bonus(
                window["values"],
                variant=reading,
                episode_starts=window["episode_starts"] if reset_at_episode_start else None,
                last_values=window["last_values"],
                last_dones=window["last_dones"],
            )
            bonuses.append(bonus)
        scales = windows[0]["scales"]
        per_scale = {}
        for k, scale in enumerate(scales):
            # (T, E) per window -> (T, E * n_windows)
            pooled = np.concatenate([bonus[..., k] for bonus in bonuses], axis=1)
            per_scale[scale] = _summary(pooled)
        per_scale["all"] = _summary(np.concatenate([bonus.reshape(bonus.shape[0], -1) for bonus in bonuses], axis=1))
        result[reading] = per_scale
    return result


def _summary(bonus: np.ndarray) -> dict[str, Any]:
    """Fire rate and mean when fired, overall and per position, of a ``(T, n_series)`` bonus array."""
    fired = bonus > 0
    fired_sum_by_step = np.where(fired, bonus, 0.0).sum(axis=1)
    count_by_step = fired.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        fired_mean_by_step = np.where(count_by_step > 0, fired_sum_by_step / np.maximum(count_by_step, 1), np.nan)
    return {
        "fire_rate": float(fired.mean()),
        "fired_mean": float(bonus[fired].mean()) if fired.any() else float("nan"),
        "fire_rate_by_step": fired.mean(axis=1),
        "fired_mean_by_step": fired_mean_by_step,
    }


def markdown(stats: dict[str, dict[str, dict[str, Any]]], title: str, positions: bool) -> str:
    """The summary table (reading x scale, beside Fig. 3) and, with ``positions``, the table by window position."""
    lines = [
        f"### {title}",
        "",
        "| reading | scale | fire rate | mean bonus when fired | fire rate at step 0 |",
        "|---|---|---|---|---|",
    ]
    for reading, scales in stats.items():
        for scale, summary in scales.items():
            lines.append(
                f"| {reading} | {scale} | {summary['fire_rate']:.4f} | {_fmt(summary['fired_mean'])} "
                f"| {summary['fire_rate_by_step'][0]:.3f} |"
            )
    lines.append(
        f"| Fig. 3 (supplement) | - | {FIG3['fire_rate']:.2f} (13 of 26 steps) | {FIG3['fired_mean']} | {FIG3['step0']} |"
    )
    if positions:
        header = " | ".join(f"{reading} rate | {reading} size" for reading in stats)
        separator = "|---" * (1 + 2 * len(stats)) + "|"
        lines += ["", "All scales, by position in the window:", "", f"| step | {header} |", separator]
        n_positions = len(next(iter(stats.values()))["all"]["fire_rate_by_step"])
        for t in range(n_positions):
            cells = " | ".join(
                f"{scales['all']['fire_rate_by_step'][t]:.3f} | {_fmt(scales['all']['fired_mean_by_step'][t])}"
                for scales in stats.values()
            )
            lines.append(f"| {t} | {cells} |")
    return "\n".join(lines) + "\n"


def model_label(model_path: Path) -> str:
    """``<benchmark folder>/<algo>/<run>/<file stem>`` of a benchmark model path
    (``<benchmark folder>/runs/<algo>/<task>_s<seed>/<file>.zip``; without the first part for other paths)."""
    parts = model_path.parts
    if len(parts) >= 5 and parts[-4] == "runs":
        return "/".join((parts[-5], *parts[-3:-1], model_path.stem))
    return "/".join((*parts[-3:-1], model_path.stem)) if len(parts) >= 3 else model_path.stem


def add_run_model_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments of the scripts that read benchmark run models on their own rollouts (``bonus_rise.py``,
    ``critic_diagnostics.py``): ``--model``, ``--rollouts``, ``--n-games``, ``--seed``, ``--out``."""
    parser.add_argument("--model", nargs="+", type=Path, required=True, help="model zip(s), each with its spec.json")
    parser.add_argument("--rollouts", type=int, default=1, help="rollouts per model")
    parser.add_argument("--n-games", type=int, default=None, help="games per rollout (default: the run's)")
    parser.add_argument("--seed", type=int, default=20_000, help="seed of the rollout games (and of any random draw)")
    parser.add_argument("--out", type=Path, default=None, help="also write the Markdown to this file")


def check_run_model_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse (``parser.error``) fewer than one rollout, and model paths that are not files or have no ``spec.json``
    of a benchmark run beside them."""
    if args.rollouts < 1:
        parser.error(f"--rollouts must be at least 1, got {args.rollouts}")
    missing = [str(path) for path in args.model if not path.is_file()]
    if missing:
        parser.error(f"no model file at {', '.join(missing)}")
    no_spec = [str(path) for path in args.model if not (path.parent / "spec.json").is_file()]
    if no_spec:
        parser.error(f"no spec.json next to {', '.join(no_spec)} (give models of benchmark runs)")


def emit(text: str, out: Path | None) -> None:
    """Print the Markdown, and write it to ``out`` too when given."""
    sys.stdout.write(text)
    if out is not None:
        out.write_text(text)


def _fmt(value: float) -> str:
    return "-" if not np.isfinite(value) else f"{value:.4f}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", nargs="+", type=Path, default=None, help="model zip(s); pooled (e.g. an arm's seeds)")
    parser.add_argument("--algo", default=None, help="method, when no spec.json lies next to the model (or untrained)")
    parser.add_argument("--task", default=None, help="task, when no spec.json lies next to the model (or untrained)")
    parser.add_argument("--n-games", type=int, default=None, help="games per rollout (default: the run's or config's)")
    parser.add_argument("--rollouts", type=int, default=1, help="rollouts per model")
    parser.add_argument("--seed", type=int, default=20_000, help="seed of the rollout games (apart from training's)")
    parser.add_argument("--coef", type=float, default=0.1, help="beta, the bonus coefficient (0.1 in the paper)")
    parser.add_argument("--reset-at-episode-start", action="store_true", help="restart the window at episode starts")
    parser.add_argument("--positions", action="store_true", help="also print the table by position in the window")
    parser.add_argument("--title", default=None, help="heading of the table (default: the models' folder)")
    parser.add_argument("--out", type=Path, default=None, help="also write the Markdown to this file")
    args = parser.parse_args(argv)
    if args.rollouts < 1:
        parser.error(f"--rollouts must be at least 1, got {args.rollouts}")
    if args.model is None and (args.algo is None or args.task is None):
        parser.error("give --model, or --algo and --task for an untrained model")
    missing = [str(path) for path in args.model or [] if not path.is_file()]
    if missing:
        parser.error(f"no model file at {', '.join(missing)}")
    th.set_num_threads(1)
    windows = []
    for model_path in args.model or [None]:
        experiment = load_experiment(model_path, args.algo, args.task, args.n_games, args.seed)
        windows += rollout_windows(experiment, args.rollouts)
        experiment.close()
    stats = reading_statistics(windows, args.coef, args.reset_at_episode_start)
    title = args.title or (f"{len(args.model)} model(s) in {args.model[0].parent.parent}" if args.model else "untrained")
    emit(markdown(stats, title, args.positions), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
