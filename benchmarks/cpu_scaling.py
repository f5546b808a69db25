"""How much work the machine's cores do side by side: the same CPU-bound job in 1, 2, ... processes at once.

    python benchmarks/cpu_scaling.py                     # 1 and 2 processes, each job about 5 s alone
    python benchmarks/cpu_scaling.py --processes 1 2 4 --seconds 10

Each process runs the same fixed amount of work of one kind (a pure-Python loop, the kind of work an env's Python
layer does; a 64-wide float32 matrix product, the learner's; or one football engine stepping random actions, with the
football extra), one torch/BLAS thread each. The speed-up of ``k`` processes is ``k x (time alone) / (wall time of k
together)``: about ``k`` where the cores are independent, less where they share a physical core (SMT siblings
presented as cores) or are otherwise contended. Run it on an idle machine: it measures the machine, not the package,
and it bounds what any number of worker processes can gain (``docs/guide/performance.md``).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import time
from collections.abc import Callable

KINDS = ("python", "matmul", "football")


def python_work(units: int) -> None:
    """``units`` x 100,000 iterations of an integer loop."""
    total = 0
    for unit in range(units):
        for i in range(100_000):
            total += (i * unit) & 7


def matmul_work(units: int) -> None:
    """``units`` x 20 products ``(4096, 64) @ (64, 64)`` in float32 on one thread."""
    import torch as th

    th.set_num_threads(1)
    a, b = th.randn(4096, 64), th.randn(64, 64)
    for _ in range(units * 20):
        a @ b


def football_work(units: int) -> None:
    """``units`` x 20 random steps of one ``grf-3v1-keeper`` game in this process."""
    import numpy as np
    from gymnasium import spaces

    from sb3_saeir import make_multiagent_vec_env

    env = make_multiagent_vec_env("grf-3v1-keeper", n_games=1, seed=0, num_cpus=0)
    assert isinstance(env.action_space, spaces.Discrete)  # football's 19 actions
    rng = np.random.default_rng(0)
    env.reset()
    for _ in range(units * 20):
        env.step(rng.integers(0, env.action_space.n, size=env.num_envs))
    env.close()


WORK: dict[str, Callable[[int], None]] = {"python": python_work, "matmul": matmul_work, "football": football_work}


def timed(kind: str, units: int, start_barrier: multiprocessing.synchronize.Barrier | None = None) -> float:
    """Wall seconds of ``units`` of ``kind`` (after the barrier, when given, so that processes start together)."""
    if start_barrier is not None:
        start_barrier.wait()
    start = time.perf_counter()
    WORK[kind](units)
    return time.perf_counter() - start


def _child(kind: str, units: int, barrier: multiprocessing.synchronize.Barrier, queue: multiprocessing.Queue) -> None:
    queue.put(timed(kind, units, barrier))


def side_by_side(kind: str, units: int, processes: int) -> float:
    """Wall seconds until ``processes`` processes, started together, have each done ``units`` of ``kind``."""
    context = multiprocessing.get_context("spawn")
    barrier, queue = context.Barrier(processes + 1), context.Queue()
    children = [context.Process(target=_child, args=(kind, units, barrier, queue)) for _ in range(processes)]
    for child in children:
        child.start()
    barrier.wait()
    start = time.perf_counter()
    times = [queue.get() for _ in children]
    for child in children:
        child.join()
    return max(max(times), time.perf_counter() - start)


def speed_up(processes: int, alone: float, wall: float) -> float:
    """``processes x alone / wall``: the work done side by side per second, over the work one process does alone.

    :param processes: how many processes ran the job together
    :param alone: wall seconds of one job alone
    :param wall: wall seconds until all ``processes`` jobs had finished
    """
    return processes * alone / wall


def calibrate(kind: str, seconds: float) -> int:
    """Units of ``kind`` that take about ``seconds`` alone."""
    one = max(timed(kind, 1), 1e-6)
    return max(1, round(seconds / one))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--kinds", nargs="+", default=["python", "matmul"], choices=KINDS)
    parser.add_argument("--processes", nargs="+", type=int, default=[1, 2])
    parser.add_argument("--seconds", type=float, default=5.0, help="length of one job alone")
    args = parser.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    print(f"{os.cpu_count()} CPUs reported; each job about {args.seconds:g} s alone")
    print(f"{'kind':>9} {'processes':>9} {'wall s':>7} {'speed-up':>8}")
    for kind in args.kinds:
        units = calibrate(kind, args.seconds)
        alone = side_by_side(kind, units, 1)
        for processes in args.processes:
            wall = alone if processes == 1 else side_by_side(kind, units, processes)
            print(f"{kind:>9} {processes:>9} {wall:7.2f} {speed_up(processes, alone, wall):8.2f}", flush=True)


if __name__ == "__main__":
    main()
