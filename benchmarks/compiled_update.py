"""The update eager against ``compile=True`` (torch.compile of the networks), side by side in one process, and a
training run of ``--wall-iterations`` iterations each way with the compile time inside it.

    OMP_NUM_THREADS=1 python benchmarks/compiled_update.py --algo saeir_ppo --task cn-sparse-n3 --n-games 128
    OMP_NUM_THREADS=1 python benchmarks/compiled_update.py --algo saeir_ppo --task grf-3v1-keeper --n-games 8
    OMP_NUM_THREADS=1 python benchmarks/compiled_update.py --algo mappo --task cn-sparse-n3 --n-games 128
    OMP_NUM_THREADS=1 python benchmarks/compiled_update.py ... --wall-iterations 20   # adds the 20-iteration runs

**The update, side by side.** The model is built from the packaged config (``--policy-kwargs`` merges policy
arguments into it) and one iteration fills its buffer. Then ``model.train()`` runs on that buffer ``--rounds`` times
each way, eager and compiled in turn, from the same parameters, optimizer state and random state (restored before
every update). The first compiled update compiles the networks: its time minus a compiled update's is the compile
time. The work of one update is counted with ``FlopCounterMode`` (matrix products) and its rate compared with a
64-wide matrix product on the same thread (``benchmarks/throughput.py``'s ``matmul_gflops``). ``--synthetic-football``
fills the buffer from a random env with football's shapes (115-d observations, 19 actions, episodes of 50-400
steps) where gfootball is not installed.

**The run** (``--wall-iterations N``): a fresh process trains two models N iterations (rollout + update) from the
same seed, eager and compiled, one iteration of each in turn (a change of load falls on both); the compiled one's wall
time includes its compilation (from torch's on-disk cache as the machine has it, e.g. filled by the side-by-side
part; ``--fresh-cache`` for a cold compile). Printed: the wall times, each iteration's time, and the compilations so
far after each iteration (``torch._dynamo`` counters: frames compiled), which stop growing once every network has its
graphs (shapes that vary, such as the number of blocks per chunk length or the last minibatch, are dynamic and do not
recompile).

Results: ``docs/guide/performance.md``, "Compiled networks".
"""

from __future__ import annotations

import argparse
import copy
import multiprocessing
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch as th

sys.path.insert(0, str(Path(__file__).parent))
from throughput import matmul_gflops


def football_shaped_env(n_games: int, seed: int) -> Any:
    """A random env with grf-3v1-keeper's shapes: 3 agents, 115-d observations, 19 actions, episodes of 50-400 steps
    (so the GRUs meet episode ends inside the update's chunks, as on football), sparse rewards."""
    from gymnasium import spaces
    from pettingzoo.utils.env import ParallelEnv

    from sb3_saeir import make_multiagent_vec_env

    class FootballShaped(ParallelEnv):
        metadata = {"name": "football_shaped_v0"}  # noqa: RUF012

        def __init__(self) -> None:
            self.possible_agents = ["agent_0", "agent_1", "agent_2"]
            self.agents: list[str] = []
            self._rng = np.random.default_rng(0)
            self._t, self._length = 0, 0

        def observation_space(self, agent: str) -> spaces.Box:
            return spaces.Box(-1.0, 1.0, (115,), np.float32)

        def action_space(self, agent: str) -> spaces.Discrete:
            return spaces.Discrete(19)

        def _obs(self) -> dict[str, np.ndarray]:
            return {a: self._rng.uniform(-1, 1, 115).astype(np.float32) for a in self.agents}

        def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
            if seed is not None:
                self._rng = np.random.default_rng(seed)
            self.agents = list(self.possible_agents)
            self._t, self._length = 0, int(self._rng.integers(50, 401))
            return self._obs(), {a: {} for a in self.agents}

        def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
            self._t += 1
            done = self._t >= self._length
            reward = float(done and self._rng.random() < 0.3)
            obs = self._obs()
            result = (obs, dict.fromkeys(self.agents, reward), dict.fromkeys(self.agents, done))
            truncations = dict.fromkeys(self.agents, False)
            infos: dict[str, dict] = {agent: {} for agent in self.agents}
            if done:
                self.agents = []
            return (*result, truncations, infos)

    return make_multiagent_vec_env(FootballShaped, n_games=n_games, seed=seed)


def build(args: argparse.Namespace, compile_setting: bool) -> tuple[Any, Any, list]:
    """The model of the packaged config (``--policy-kwargs`` merged in) and its env."""
    from sb3_saeir.config import load_hyperparams, parse_policy_kwargs
    from sb3_saeir.experiment import Experiment

    hyperparams = load_hyperparams(args.algo, args.task)
    if args.policy_kwargs:
        merged = {**parse_policy_kwargs(hyperparams.get("policy_kwargs")), **parse_policy_kwargs(args.policy_kwargs)}
        hyperparams["policy_kwargs"] = merged
    hyperparams["num_cpus"] = 0
    hyperparams["compile"] = compile_setting
    experiment = Experiment(args.algo, args.task, hyperparams, seed=args.seed, n_games=args.n_games)
    model = experiment.build(env=football_shaped_env(args.n_games, args.seed) if args.synthetic_football else None)
    return model, experiment.env, experiment.config_callbacks


class Snapshot:
    """Parameters, optimizer state and random state, to run several updates from the same start."""

    def __init__(self, model: Any) -> None:
        self.model = model
        self.policy = copy.deepcopy(model.policy.state_dict())
        self.optimizer = copy.deepcopy(model.policy.optimizer.state_dict())
        self.torch_rng = th.get_rng_state()
        self.numpy_rng = np.random.get_state()

    def restore(self) -> None:
        self.model.policy.load_state_dict(self.policy)
        self.model.policy.optimizer.load_state_dict(self.optimizer)
        th.set_rng_state(self.torch_rng)
        np.random.set_state(self.numpy_rng)


def timed_update(model: Any, snapshot: Snapshot) -> float:
    snapshot.restore()
    start = time.perf_counter()
    model.train()
    return time.perf_counter() - start


def side_by_side(args: argparse.Namespace) -> None:
    """The update eager and compiled in turn, on one buffer, from the same state."""
    from torch.utils.flop_counter import FlopCounterMode

    from sb3_saeir.common.compilation import compile_counters, resolve_compile_backend

    model, env, callbacks = build(args, compile_setting=False)
    model.learn(model.n_steps * env.num_envs, callback=callbacks)  # one rollout and update (eager): a full buffer
    env.close()
    snapshot = Snapshot(model)
    policy = model.policy
    eager = [timed_update(model, snapshot)]
    backend = resolve_compile_backend("compiled_update", True, policy.device)
    if backend is None:
        sys.exit("no C++ compiler: nothing to compare")
    policy.set_compile(backend)
    first_compiled = timed_update(model, snapshot)
    compiled_networks = (policy._compiled_actor, policy._compiled_critics)
    compiled = []
    for _ in range(args.rounds):
        policy._compiled_actor, policy._compiled_critics = None, {}
        eager.append(timed_update(model, snapshot))
        policy._compiled_actor, policy._compiled_critics = compiled_networks
        compiled.append(timed_update(model, snapshot))
    counts = compile_counters()
    policy._compiled_actor, policy._compiled_critics = None, {}
    snapshot.restore()
    with FlopCounterMode(display=False) as counter:
        model.train()
    gflop = counter.get_total_flops() / 1e9
    matmul = matmul_gflops(th.device("cpu"))
    eager_s, compiled_s = statistics.median(eager), statistics.median(compiled)
    print(
        f"{args.algo} on {args.task}{' (synthetic football shapes)' if args.synthetic_football else ''}, "
        f"{args.n_games} games, {th.get_num_threads()} thread(s), torch {th.__version__}"
        + (f", policy kwargs {args.policy_kwargs}" if args.policy_kwargs else "")
    )
    print(f"update eager    s: {' '.join(f'{t:.3f}' for t in eager)}  (median {eager_s:.3f})")
    print(f"update compiled s: {' '.join(f'{t:.3f}' for t in compiled)}  (median {compiled_s:.3f})")
    print(
        f"speed-up (medians): {eager_s / compiled_s:.2f}x; per round: "
        + " ".join(f"{e / c:.2f}x" for e, c in zip(eager[1:], compiled))
    )
    print(f"compile time: {first_compiled - compiled_s:.1f} s (first compiled update {first_compiled:.1f} s); {counts}")
    print(
        f"update {gflop:.1f} GFLOP: eager {gflop / eager_s:.1f} GFLOP/s, compiled {gflop / compiled_s:.1f} GFLOP/s; "
        f"64-wide matmul {matmul:.1f} GFLOP/s: ratio eager {gflop / eager_s / matmul:.2f}, compiled "
        f"{gflop / compiled_s / matmul:.2f}",
        flush=True,
    )


def _interleaved_runs(queue: Any, args: argparse.Namespace) -> None:
    """Train an eager and a compiled model from the same seed, one iteration of each in turn (so that a change of the
    machine's load falls on both), and report each one's iteration times and build time."""
    th.set_num_threads(args.threads)
    if args.fresh_cache:
        import os
        import tempfile

        os.environ["TORCHINDUCTOR_CACHE_DIR"] = tempfile.mkdtemp(prefix="torchinductor_")  # a cold compile
    from sb3_saeir.common.compilation import compile_counters

    runs: dict[bool, dict[str, Any]] = {}
    for compile_setting in (False, True):
        start = time.perf_counter()
        model, env, callbacks = build(args, compile_setting)
        runs[compile_setting] = {"model": model, "env": env, "callbacks": callbacks, "times": [], "counts": []}
        runs[compile_setting]["build"] = time.perf_counter() - start
    for _ in range(args.wall_iterations):
        for compile_setting, run in runs.items():
            rollout = run["model"].n_steps * run["env"].num_envs
            start = time.perf_counter()
            run["model"].learn(rollout, callback=run["callbacks"], reset_num_timesteps=False)
            run["times"].append(time.perf_counter() - start)
            if compile_setting:
                run["counts"].append(compile_counters()["frames"])
    results = {}
    for compile_setting, run in runs.items():
        run["env"].close()
        results[compile_setting] = {"build": run["build"], "times": run["times"], "counts": run["counts"]}
    queue.put(results)


def training_runs(args: argparse.Namespace) -> None:
    """``--wall-iterations`` iterations eager and compiled, interleaved, in a fresh process (no compiled code in
    memory; torch's on-disk cache as this machine has it, or a fresh one with ``--fresh-cache``)."""
    context = multiprocessing.get_context("spawn")
    queue = context.Queue()
    process = context.Process(target=_interleaved_runs, args=(queue, args))
    process.start()
    results = queue.get()
    process.join()
    walls = {}
    for compile_setting, result in results.items():
        walls[compile_setting] = result["build"] + sum(result["times"])
        label = "compiled" if compile_setting else "eager   "
        print(
            f"{args.wall_iterations} iterations {label}: wall {walls[compile_setting]:.1f} s (build "
            f"{result['build']:.1f} s included); per iteration " + " ".join(f"{t:.2f}" for t in result["times"])
        )
    compiled_times, eager_times = results[True]["times"], results[False]["times"]
    steady = statistics.median(e / c for e, c in zip(eager_times[1:], compiled_times[1:]))
    print(f"compile time inside the run: about {compiled_times[0] - statistics.median(compiled_times[1:]):.1f} s")
    print("compilations (frames) after each compiled iteration: " + " ".join(str(c) for c in results[True]["counts"]))
    ratio = walls[False] / walls[True]
    print(
        f"{args.wall_iterations}-iteration wall time, eager / compiled (compile included): {ratio:.2f}x; "
        f"iterations after the first, median of the interleaved ratios: {steady:.2f}x"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", default="saeir_ppo")
    parser.add_argument("--task", default="cn-sparse-n3")
    parser.add_argument("--n-games", type=int, default=128)
    parser.add_argument("--rounds", type=int, default=3, help="updates each way, in turn, after the first (0: none)")
    parser.add_argument("--wall-iterations", type=int, default=0, help="also train this many iterations each way")
    parser.add_argument("--policy-kwargs", default=None, help='merged into the config\'s, e.g. "dict(recurrent=False)"')
    parser.add_argument("--fresh-cache", action="store_true", help="the run compiles without torch's on-disk cache")
    parser.add_argument("--synthetic-football", action="store_true", help="football's shapes from a random env")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    th.set_num_threads(args.threads)
    if args.rounds:
        side_by_side(args)
    if args.wall_iterations:
        training_runs(args)


if __name__ == "__main__":
    main()
