"""Time of ``saeir_bonus`` (O(T)) against the authors' O(T^2) prefix loop, on the paper's football buffer shape.

python benchmarks/saeir_bonus_timing.py --steps 200 --games 50 --agents 3 --scales 3
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

from sb3_saeir.intrinsic import saeir_bonus


def quadratic_prefix_loop(values: np.ndarray) -> np.ndarray:
    """The released code's computation (``docs/method.md``, "The intrinsic reward"): for every t, the entropy of the
    softmax over the first t and t + 1 values, each prefix recomputed from scratch (vectorised over games, agents and
    scales)."""
    n_steps = values.shape[0]

    def prefix_entropy(n: int) -> np.ndarray:
        if n == 0:
            return np.zeros(values.shape[1:])
        exp = np.exp(values[:n])
        p = exp / np.maximum(exp.sum(axis=0), 1e-8)
        return -(p * np.log(np.maximum(p, 1e-8))).sum(axis=0)

    bonus = np.zeros_like(values)
    for t in range(n_steps):
        before, after = prefix_entropy(t), prefix_entropy(t + 1)
        bonus[t] = np.where(before > after, before, 0.0)
    return bonus


def best_time(function: Callable[[np.ndarray], object], values: np.ndarray, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function(values)
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--games", type=int, default=50)
    parser.add_argument("--agents", type=int, default=3)
    parser.add_argument("--scales", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    values = rng.normal(0.0, 1.5, size=(args.steps, args.games, args.agents, args.scales))
    fast = best_time(saeir_bonus, values, args.repeats)
    slow = best_time(quadratic_prefix_loop, values, args.repeats)
    max_diff = np.abs(saeir_bonus(values) - quadratic_prefix_loop(values)).max()
    print(
        f"values shape {values.shape}: saeir_bonus {fast * 1e3:.2f} ms, O(T^2) loop {slow * 1e3:.2f} ms, "
        f"speed-up {slow / fast:.1f}x, max |diff| {max_diff:.2e}"
    )


if __name__ == "__main__":
    main()
