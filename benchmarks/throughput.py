"""Training throughput of each method at the paper's settings: agent-steps/s, where the time goes, update GFLOP/s, RSS.

    OMP_NUM_THREADS=1 python benchmarks/throughput.py --task cn-sparse-n3 --n-games 128 --algos saeir_ppo mappo
    python benchmarks/throughput.py --algos saeir_ppo --threads 2          # the update with 2 torch threads
    python benchmarks/throughput.py --algos saeir_ppo --device cuda        # on a GPU machine (not run on CPU-only CI)
    OMP_NUM_THREADS=1 python benchmarks/throughput.py --algos mappo --policy-kwargs "dict(recurrent=False)"  # feed-forward

Each method trains with its packaged config (``zoo_configs/<algo>.yml``: 25-step rollouts, 10 epochs, one minibatch,
hidden size 64) except the number of games, in a fresh process of its own (so that its peak RSS is its own). After
``--warmup`` untimed iterations, ``--iterations`` more are timed, and the wall time is split into:

- **env**: ``VecEnv.step`` (the environment, with its wrappers);
- **inference**: the policy's rollout forward passes (``policy.forward`` and ``policy.predict_values``);
- **update**: ``model.train()`` (every epoch and minibatch of the PPO update);
- **bonus**: the intrinsic-reward callbacks (``IntrinsicRewardCallback.add_to``, or their ``on_rollout_end`` in versions
  that computed the bonus there);
- **other**: the rest (buffer writes, GAE, logging).

``busy%`` is the share of the machine's CPUs kept busy over the timed iterations (CPU-seconds of this process and its
env workers over ``CPUs x wall``; needs psutil). ``--num-cpus`` spreads the games over env worker processes.

The floating-point work of one update is counted once with ``torch.utils.flop_counter.FlopCounterMode`` (matrix
products, which dominate these networks; elementwise operations are not counted), then divided by the mean timed
update to give the update's GFLOP/s, which is compared with a 64-wide matrix product ``(rows, 64) @ (64, 64)``
measured in the same process with the same threads and device. ``random`` steps the env with random actions.

Timings on shared machines are noisy: compare figures from one sitting, interleaving the versions compared. The
script only uses the public API (``sb3_saeir.experiment.Experiment``), so it also runs against older versions of the
package (run it with that version's interpreter).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import resource
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.vec_env import VecEnv

PHASES = ("env", "inference", "update", "bonus")


def matmul_gflops(device: th.device, rows: int = 11_520, width: int = 64, seconds: float = 0.5) -> float:
    """GFLOP/s of ``(rows, width) @ (width, width)`` float32 products (best of 5 timed batches).

    :param device: torch device
    :param rows: rows of the left operand (the update's node count at 128 games)
    :param width: inner and output width
    :param seconds: rough duration of each timed batch
    """
    a = th.randn(rows, width, device=device)
    b = th.randn(width, width, device=device)
    out = th.empty(rows, width, device=device)

    def sync() -> None:
        if device.type == "cuda":
            th.cuda.synchronize(device)

    th.mm(a, b, out=out)
    sync()
    start = time.perf_counter()
    reps = 0
    while time.perf_counter() - start < 0.05:
        th.mm(a, b, out=out)
        reps += 1
    sync()
    per_call = (time.perf_counter() - start) / reps
    n_calls = max(1, int(seconds / per_call))
    best = float("inf")
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(n_calls):
            th.mm(a, b, out=out)
        sync()
        best = min(best, (time.perf_counter() - start) / n_calls)
    return 2.0 * rows * width * width / best / 1e9


class PhaseTimer:
    """Accumulates wall time of wrapped callables per phase (outermost call only, so nested calls count once)."""

    def __init__(self, device: th.device) -> None:
        self.totals = dict.fromkeys(PHASES, 0.0)
        self.counts = dict.fromkeys(PHASES, 0)
        self.device = device
        self._depth = 0

    def wrap(self, phase: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """Return ``fn`` timed under ``phase``.

        :param phase: one of :data:`PHASES`
        :param fn: the callable to time
        """

        def timed(*args: Any, **kwargs: Any) -> Any:
            if self._depth:
                return fn(*args, **kwargs)
            self._depth += 1
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                if self.device.type == "cuda":
                    th.cuda.synchronize(self.device)
                self.totals[phase] += time.perf_counter() - start
                self.counts[phase] += 1
                self._depth -= 1

        return timed

    def reset(self) -> None:
        self.totals = dict.fromkeys(PHASES, 0.0)
        self.counts = dict.fromkeys(PHASES, 0)


def _patch_bonus(timer: PhaseTimer) -> None:
    """Time the intrinsic-reward callbacks (class-level patch; ``add_to`` in this version, ``on_rollout_end`` before)."""
    try:
        from sb3_saeir.intrinsic.base import IntrinsicRewardCallback
    except ImportError:  # a version without intrinsic rewards
        return
    if hasattr(IntrinsicRewardCallback, "add_to"):
        IntrinsicRewardCallback.add_to = timer.wrap("bonus", IntrinsicRewardCallback.add_to)  # type: ignore[method-assign]
    else:
        IntrinsicRewardCallback.on_rollout_end = timer.wrap("bonus", IntrinsicRewardCallback.on_rollout_end)  # type: ignore[method-assign]


def measure_method(
    algo: str,
    task: str,
    n_games: int,
    warmup: int,
    iterations: int,
    seed: int,
    device: str,
    threads: int,
    backend: str | None = None,
    num_cpus: int | None = None,
    policy_kwargs: str | None = None,
) -> dict:
    """Train ``algo`` in this process and return its figures (run in a fresh process per method).

    :param policy_kwargs: policy arguments merged into the config's (a ``"dict(...)"`` string, e.g.
        ``"dict(recurrent=False)"``); ``None``: the config's alone

    :return: agent-steps/s, seconds per phase, update GFLOP and GFLOP/s, the matmul GFLOP/s, peak RSS (MiB)
    """
    th.set_num_threads(threads)
    from sb3_saeir.experiment import Experiment

    torch_device = th.device(device)
    if algo == "random":
        return _random_stepping(task, n_games, iterations, seed, backend)
    timer = PhaseTimer(torch_device)
    _patch_bonus(timer)
    env: VecEnv | None = None  # None: the experiment makes the config's
    if backend is not None or num_cpus is not None:  # the env backend (native or SuperSuit) or worker processes asked for
        from sb3_saeir import make_multiagent_vec_env
        from sb3_saeir.config import load_hyperparams

        env_kwargs = dict(load_hyperparams(algo, task).get("env_kwargs") or {})
        if backend is not None:
            env_kwargs["backend"] = backend
        if num_cpus is not None:
            env_kwargs["num_cpus"] = num_cpus
        env = make_multiagent_vec_env(task, n_games=n_games, seed=seed, **env_kwargs)
    hyperparams = None
    if policy_kwargs is not None:
        from sb3_saeir.config import load_hyperparams, parse_policy_kwargs

        hyperparams = load_hyperparams(algo, task)
        merged = {**parse_policy_kwargs(hyperparams.get("policy_kwargs")), **parse_policy_kwargs(policy_kwargs)}
        hyperparams["policy_kwargs"] = merged
    experiment = Experiment(algo, task, hyperparams, seed=seed, n_games=n_games)
    model = experiment.build(env=env, device=device)
    env, callbacks = experiment.env, experiment.config_callbacks
    assert env is not None
    policy = model.policy
    policy.forward = timer.wrap("inference", policy.forward)  # type: ignore[method-assign]
    policy.predict_values = timer.wrap("inference", policy.predict_values)  # type: ignore[method-assign]
    model.env.step = timer.wrap("env", model.env.step)  # type: ignore[method-assign, union-attr]
    model.train = timer.wrap("update", model.train)  # type: ignore[method-assign]
    rollout = model.n_steps * env.num_envs
    model.learn(warmup * rollout, callback=callbacks)
    timer.reset()
    start_steps = model.num_timesteps
    cpu_start, start = process_tree_cpu_seconds(), time.perf_counter()
    model.learn(iterations * rollout, callback=callbacks, reset_num_timesteps=False)
    wall = time.perf_counter() - start
    cpu = process_tree_cpu_seconds() - cpu_start
    steps = model.num_timesteps - start_steps
    phases, n_updates = dict(timer.totals), timer.counts["update"]
    peak_rss_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # before the FLOP count's extra update

    from torch.utils.flop_counter import FlopCounterMode

    with FlopCounterMode(display=False) as counter:
        model.train()  # untimed: counts the work of one update on the last rollout
    env.close()
    update_gflop = counter.get_total_flops() / 1e9
    update_seconds = phases["update"] / max(n_updates, 1)
    return {
        "agent_steps_per_s": steps / wall,
        "wall": wall,
        "phases": phases,
        "update_gflop": update_gflop,
        "update_gflops": update_gflop / update_seconds if update_seconds > 0 else float("nan"),
        "matmul_gflops": matmul_gflops(torch_device),
        "peak_rss_mib": peak_rss_mib,
        "busy": cpu / (wall * (os.cpu_count() or 1)),
    }


def _measure_into(queue: Any, arguments: tuple) -> None:
    queue.put(measure_method(*arguments))


def in_fresh_process(context: Any, arguments: tuple) -> dict:
    """:func:`measure_method` in a fresh (non-daemonic) process, so that its peak RSS is its own and it may start env
    worker processes of its own."""
    queue = context.Queue()
    process = context.Process(target=_measure_into, args=(queue, arguments))
    process.start()
    result = queue.get()
    process.join()
    return result


def process_tree_cpu_seconds() -> float:
    """CPU seconds (user + system) of this process and its children (env workers); NaN without psutil."""
    try:
        import psutil
    except ImportError:
        return float("nan")
    process = psutil.Process()
    return sum(sum(proc.cpu_times()[:2]) for proc in [process, *process.children(recursive=True)])


def _random_stepping(task: str, n_games: int, iterations: int, seed: int, backend: str | None) -> dict:
    from sb3_saeir import make_multiagent_vec_env

    env = make_multiagent_vec_env(task, n_games=n_games, seed=seed, backend=backend)
    rng = np.random.default_rng(seed)
    env.reset()
    n_vec_steps = 25 * iterations
    start = time.perf_counter()
    for _ in range(n_vec_steps):
        env.step(rng.integers(0, env.action_space.n, size=env.num_envs))  # type: ignore[attr-defined]
    wall = time.perf_counter() - start
    env.close()
    return {
        "agent_steps_per_s": n_vec_steps * env.num_envs / wall,
        "wall": wall,
        "phases": {"env": wall},
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="cn-sparse-n3")
    parser.add_argument("--n-games", type=int, default=128)
    parser.add_argument("--algos", nargs="+", default=["saeir_ppo", "mappo"], help="random or methods of sb3_saeir.config")
    parser.add_argument("--warmup", type=int, default=1, help="untimed iterations (rollout + update) first")
    parser.add_argument("--iterations", type=int, default=3, help="timed iterations (rollout + update)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (the update's figure in the issue: 1)")
    parser.add_argument("--device", default="cpu", help="torch device of the policy: cpu or cuda (needs a GPU build)")
    parser.add_argument(
        "--backend",
        default=None,
        help="env backend of make_multiagent_vec_env (native or supersuit; default: the version's default, native "
        "where the task has one). Versions before the native engine have no such argument: leave it out",
    )
    parser.add_argument(
        "--num-cpus",
        type=int,
        default=None,
        help="env worker processes (default: the config's; 0: every game in this process). Training methods only",
    )
    parser.add_argument(
        "--policy-kwargs",
        default=None,
        help='policy arguments merged into each config\'s, e.g. "dict(recurrent=False)" (the feed-forward networks)',
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.warmup < 1:
        parser.error("--warmup must be >= 1: the first iteration also fills the buffer that the FLOP count reads")

    context = multiprocessing.get_context("spawn")
    print(
        f"task {args.task}, {args.n_games} games, {args.iterations} timed iterations after {args.warmup}, "
        f"{args.threads} thread(s), device {args.device}, env backend {args.backend or 'default'}, "
        f"env workers {'config' if args.num_cpus is None else args.num_cpus}, torch {th.__version__}"
        + (f", policy kwargs {args.policy_kwargs}" if args.policy_kwargs else "")
    )
    header = (
        f"{'method':>10} {'agent-steps/s':>13} {'env%':>5} {'inf%':>5} {'upd%':>5} {'bonus%':>6} {'other%':>6} "
        f"{'upd s':>6} {'upd GFLOP':>9} {'GFLOP/s':>7} {'matmul':>6} {'ratio':>5} {'peak RSS MiB':>12} {'busy%':>5}"
    )
    print(header, flush=True)
    for algo in args.algos:
        result = in_fresh_process(
            context,
            (
                algo,
                args.task,
                args.n_games,
                args.warmup,
                args.iterations,
                args.seed,
                args.device,
                args.threads,
                args.backend,
                args.num_cpus,
                args.policy_kwargs,
            ),
        )
        wall, phases = result["wall"], result["phases"]
        shares = {phase: 100.0 * phases.get(phase, 0.0) / wall for phase in PHASES}
        other = 100.0 - sum(shares.values())
        update_seconds = phases.get("update", 0.0) / max(args.iterations, 1)
        if "update_gflop" in result:
            flops = (
                f"{update_seconds:6.2f} {result['update_gflop']:9.1f} {result['update_gflops']:7.1f} "
                f"{result['matmul_gflops']:6.1f} {result['update_gflops'] / result['matmul_gflops']:5.2f}"
            )
        else:
            flops = f"{'-':>6} {'-':>9} {'-':>7} {'-':>6} {'-':>5}"
        print(
            f"{algo:>10} {result['agent_steps_per_s']:13.0f} {shares['env']:5.1f} {shares['inference']:5.1f} "
            f"{shares['update']:5.1f} {shares['bonus']:6.1f} {other:6.1f} {flops} {result['peak_rss_mib']:12.0f} "
            f"{100 * result.get('busy', float('nan')):5.0f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
