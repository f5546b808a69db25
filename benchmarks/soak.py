"""Soak run: train SAEIR_PPO with its packaged config for a long budget and report, every ``--every`` agent-steps,
the number of NaN/inf values in the parameters, the optimizer state and the last rollout, and the process's memory.

    python benchmarks/soak.py                         # 1M agent-steps on cn-sparse-n3, 128 games (the config's)
    python benchmarks/soak.py -n 200000 --n-games 16 --algo mappo

Not a test: it prints a table (and writes it as CSV with ``--csv``). A healthy run has zero non-finite values on every
line and a resident memory that stops growing after the first rows.
"""

from __future__ import annotations

import argparse
import csv
import resource
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

from sb3_saeir.experiment import Experiment


def rss_mib() -> float:
    """Current resident set size of this process in MiB (Linux ``/proc/self/status``)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def peak_rss_mib() -> float:
    """Peak resident set size of this process so far, in MiB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def count_non_finite(arrays: list[Any]) -> int:
    """Number of NaN or infinite entries over tensors and arrays."""
    total = 0
    for array in arrays:
        if isinstance(array, th.Tensor):
            total += int((~th.isfinite(array)).sum())
        else:
            total += int((~np.isfinite(np.asarray(array, dtype=np.float64))).sum())
    return total


class SoakReport(BaseCallback):
    """Every ``every`` agent-steps (at a rollout's start, after the update): non-finite counts and memory.

    :param every: agent-steps between two rows
    """

    def __init__(self, every: int) -> None:
        super().__init__()
        self.every = every
        self.next_report = every
        self.rows: list[dict[str, float]] = []
        self.start = time.time()

    def _on_step(self) -> bool:
        return True

    def _on_rollout_start(self) -> None:
        if self.model.num_timesteps >= self.next_report:
            self.next_report += self.every
            self.report()

    def report(self) -> None:
        policy = self.model.policy
        optimizer_state = [value for state in policy.optimizer.state_dict()["state"].values() for value in state.values()]
        assert isinstance(self.model, OnPolicyAlgorithm)  # every method of the package
        buffer = self.model.rollout_buffer
        buffer_arrays = [buffer.observations, buffer.rewards, buffer.values, buffer.returns, buffer.advantages]
        buffer_arrays += [getattr(buffer, "intrinsic_rewards", np.zeros(1))]
        row = {
            "agent_steps": self.model.num_timesteps,
            "wall_s": round(time.time() - self.start, 1),
            "non_finite_parameters": count_non_finite(list(policy.parameters())),
            "non_finite_optimizer": count_non_finite([v for v in optimizer_state if isinstance(v, th.Tensor)]),
            "non_finite_rollout": count_non_finite(buffer_arrays),
            "rss_mib": round(rss_mib(), 1),
            "peak_rss_mib": round(peak_rss_mib(), 1),
        }
        self.rows.append(row)
        print("  ".join(f"{key}={value}" for key, value in row.items()), flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--algo", default="saeir_ppo")
    parser.add_argument("--task", default="cn-sparse-n3")
    parser.add_argument("-n", "--n-timesteps", type=int, default=1_000_000, help="agent-steps")
    parser.add_argument("--n-games", type=int, default=None, help="override the config's n_envs (games)")
    parser.add_argument("--every", type=int, default=50_000, help="agent-steps between two rows")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--csv", default=None, help="also write the rows to this CSV file")
    args = parser.parse_args(argv)
    th.set_num_threads(args.threads)
    experiment = Experiment(args.algo, args.task, seed=args.seed, n_games=args.n_games)
    experiment.build(verbose=0)
    report = SoakReport(args.every)
    print(f"soak: {args.algo} on {args.task}, {experiment.n_games} games, {args.n_timesteps:,} agent-steps", flush=True)
    experiment.learn(args.n_timesteps, callbacks=[report])
    report.report()  # the end of the run
    experiment.close()
    if args.csv:
        with open(args.csv, "w", newline="") as file:
            writer = csv.DictWriter(file, fieldnames=list(report.rows[0]))
            writer.writeheader()
            writer.writerows(report.rows)
    bad = sum(row["non_finite_parameters"] + row["non_finite_optimizer"] + row["non_finite_rollout"] for row in report.rows)
    growth = report.rows[-1]["rss_mib"] - report.rows[min(1, len(report.rows) - 1)]["rss_mib"]
    print(
        f"soak done: {bad} non-finite values over {len(report.rows)} rows; RSS growth after the first rows {growth:+.1f} MiB"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
