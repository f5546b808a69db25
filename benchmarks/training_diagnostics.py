"""What the learners did during a benchmark's runs: SB3's ``train/*`` statistics per method, over thirds of training.

    python benchmarks/training_diagnostics.py $HOME/saeir-results/stage2/default

Reads ``runs/<algo>/<task>_s<seed>/progress.csv`` of every run under the benchmark folder (finished or not) and
prints one Markdown table per task: for each method and each ``train/`` key (per-scale keys such as
``train/explained_variance_team`` included), the mean over the run's updates in the first, middle and last third of
its training, averaged over seeds. It tells, for example, whether the methods' policies moved alike (``entropy_loss``,
``approx_kl``, ``clip_fraction``) and how much of the return each critic explains (``explained_variance_*``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from sb3_saeir.benchmark import numeric_series, read_rows

DEFAULT_KEYS = ("explained_variance", "value_loss", "entropy_loss", "approx_kl", "clip_fraction")


def thirds(values: list[float]) -> list[float]:
    """Means of the first, middle and last third of ``values`` (``np.array_split``: the first thirds take the extra)."""
    return [float(np.mean(part)) for part in np.array_split(np.asarray(values), 3)]


def run_thirds(progress: Path, prefixes: tuple[str, ...]) -> dict[str, list[float]]:
    """``{key: thirds}`` for the ``train/<prefix>...`` keys of one run's ``progress.csv`` that hold at least 3 values."""
    rows = read_rows(progress)
    keys = [key for key in rows[0] if any(key.startswith(f"train/{prefix}") for prefix in prefixes)] if rows else []
    result = {}
    for key in keys:
        _, values = numeric_series(rows, key)
        if len(values) >= 3:
            result[key] = thirds(values)
    return result


def diagnostics(out: Path, prefixes: tuple[str, ...] = DEFAULT_KEYS) -> dict[str, dict[str, dict[str, np.ndarray]]]:
    """``{task: {algo: {key: (n_seeds, 3) array}}}`` over the runs under ``out/runs``."""
    found: dict[str, dict[str, dict[str, list[list[float]]]]] = {}
    for progress in sorted(out.glob("runs/*/*_s*/progress.csv")):
        algo, task = progress.parent.parent.name, progress.parent.name.rsplit("_s", 1)[0]
        for key, values in run_thirds(progress, prefixes).items():
            found.setdefault(task, {}).setdefault(algo, {}).setdefault(key, []).append(values)
    return {
        task: {algo: {key: np.array(seeds) for key, seeds in keys.items()} for algo, keys in algos.items()}
        for task, algos in found.items()
    }


def markdown(table: dict[str, dict[str, np.ndarray]], task: str) -> str:
    """One task's table: a row per (method, key), the seed-mean of each third."""
    lines = [
        f"### {task}",
        "",
        "| method | key | first third | middle third | last third | seeds |",
        "|---|---|---|---|---|---|",
    ]
    for algo in sorted(table):
        for key, seeds in sorted(table[algo].items()):
            means = seeds.mean(axis=0)  # (3,) mean over seeds of each third
            lines.append(f"| {algo} | {key} | {means[0]:.4f} | {means[1]:.4f} | {means[2]:.4f} | {len(seeds)} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out", type=Path, help="a benchmark's --out folder")
    parser.add_argument("--keys", nargs="+", default=list(DEFAULT_KEYS), help="train/ key prefixes to show")
    args = parser.parse_args()
    if not (args.out / "runs").is_dir():
        parser.error(f"{args.out} has no runs/ folder: pass a benchmark's --out folder")
    for task, table in sorted(diagnostics(args.out, tuple(args.keys)).items()):
        print(markdown(table, task))


if __name__ == "__main__":
    main()
