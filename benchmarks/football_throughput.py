"""Env steps per second on the football tasks: random actions (1 and 2 games) and SAEIR_PPO training.

    python benchmarks/football_throughput.py                                   # everything below, ~3 min
    python benchmarks/football_throughput.py --tasks grf-3v1-keeper --n-games 1 2 4 --seconds 30 --num-cpus 0 2
    python benchmarks/football_throughput.py --no-random --train-iterations 2  # training only
    python benchmarks/football_throughput.py --tasks grf-3v1-keeper --n-games 1 --train-algos saeir_ppo mappo \\
        --train-games 4 8 --train-num-cpus 0 2                                 # with the cost model

"Env steps" are game steps (one step of one game, all its agents together), the unit of the paper's 25e6 budget;
agent-steps are env steps x N. Random stepping goes through ``make_multiagent_vec_env``: ``--num-cpus 0`` runs every game
in this process, one after the other (so more games do not mean more steps/s), ``--num-cpus k`` spreads them over k
worker processes. Training uses the method's packaged config (the paper's hyperparameters: 200-step buffer, 15 epochs,
2 minibatches) with fewer games and ``--train-iterations`` iterations. CPU-seconds count this process and its workers.
Each line also gives the share of the machine it kept busy (CPU-seconds of the process tree over ``CPUs x wall``).

**Cost model** (printed last when both random stepping in-process and training ran): ``e``, the engine's CPU-seconds
per env step (random stepping, one game in this process), and ``l``, the learner's (training's CPU per env step minus
``e``: inference, buffer, bonus and update), give the projected wall time of the paper's 25M env steps on ``C`` cores:

- the synchronous loop (``double_buffered=False``): the games step in parallel over ``min(C, games)`` workers, then
  the learner runs on one core: ``25e6 x (e / min(C, games) + l)``;
- with the engine overlapped with the learner (double-buffered sampling, the default with workers; the update still
  runs while the workers wait, so this is a bound): bounded by the learner's serial part and by
  the total work over the cores: ``25e6 x max(l, (e + l) / C)``.

Seeds are independent runs: ``--ray-address`` of the benchmark fans them out over machines, so S seeds on S machines
take the wall time of one. Timings on shared machines are noisy: they are lower bounds.
"""

from __future__ import annotations

import argparse
import os
import resource
import threading
import time

import numpy as np
import torch as th
from gymnasium import spaces

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.config import load_hyperparams
from sb3_saeir.experiment import Experiment


def cpu_seconds() -> float:
    """CPU time (user + system) of this process and its running child processes (SuperSuit workers), in seconds."""
    import psutil  # installed with the football extra

    process = psutil.Process()
    return sum(sum(proc.cpu_times()[:2]) for proc in [process, *process.children(recursive=True)])


class TreeMemory:
    """Peak resident memory of this process and its children (the env workers) together, sampled every ``interval``
    seconds in a thread while the ``with`` block runs (``peak_mb``, in MiB)."""

    def __init__(self, interval: float = 0.5) -> None:
        self.interval = interval
        self.peak_mb = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self) -> None:
        import psutil  # installed with the football extra

        process = psutil.Process()
        while not self._stop.is_set():
            total = 0
            for proc in [process, *process.children(recursive=True)]:
                try:
                    total += proc.memory_info().rss
                except psutil.Error:  # a child that ended between the listing and the reading
                    continue
            self.peak_mb = max(self.peak_mb, total / 2**20)
            self._stop.wait(self.interval)

    def __enter__(self) -> TreeMemory:
        self._thread.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stop.set()
        self._thread.join()


def busy_share(cpu: float, elapsed: float) -> float:
    """The share of the machine's CPUs kept busy: CPU-seconds over ``CPUs x wall``."""
    return cpu / max(elapsed * (os.cpu_count() or 1), 1e-9)


# The paper's football budget, env steps per run.
PAPER_ENV_STEPS = 25_000_000
# Core counts of the cost model's projection.
PROJECTED_CORES = (2, 8, 16, 64)


def projected_hours(engine_s: float, learner_s: float, cores: int, n_games: int) -> tuple[float, float]:
    """Projected wall hours of :data:`PAPER_ENV_STEPS` on ``cores`` cores: the synchronous loop, and with the engine
    overlapped with the learner (see the module docstring).

    :param engine_s: the engine's CPU-seconds per env step
    :param learner_s: the learner's CPU-seconds per env step
    :param cores: cores of the machine
    :param n_games: games of the run (the synchronous loop steps at most this many at once)
    """
    synchronous = PAPER_ENV_STEPS * (engine_s / min(cores, n_games) + learner_s)
    overlapped = PAPER_ENV_STEPS * max(learner_s, (engine_s + learner_s) / cores)
    return synchronous / 3600, overlapped / 3600


def cost_model_lines(engine_s: float, training_s: float, n_games: int) -> list[str]:
    """The cost model's lines: ``e``, ``l`` and the projection per core count.

    :param engine_s: the engine's CPU-seconds per env step (random stepping, one game in-process)
    :param training_s: training's CPU-seconds per env step
    :param n_games: games of the training run projected
    """
    learner_s = max(training_s - engine_s, 0.0)
    lines = [
        f"cost model: engine e = {engine_s * 1e3:.2f} ms, learner l = {learner_s * 1e3:.2f} ms of CPU per env step; "
        f"{PAPER_ENV_STEPS / 1e6:.0f}M env steps, wall hours "
        "(synchronous loop / engine overlapped with the learner, the bound of double-buffered sampling):"
    ]
    for cores in PROJECTED_CORES:
        synchronous, overlapped = projected_hours(engine_s, learner_s, cores, max(n_games, cores))
        lines.append(f"  {cores:>2} cores ({max(n_games, cores)} games): {synchronous:6.1f} h / {overlapped:6.1f} h")
    lines.append("  seeds fan out over machines with the benchmark's --ray-address: S seeds on S machines in the time of one")
    return lines


def random_stepping(
    task: str, n_games: int, seconds: float, num_cpus: int, seed: int, groups: bool = False
) -> dict[str, float]:
    """Env steps/s (and per CPU-second) of uniformly random actions for about ``seconds`` seconds.

    With ``groups``, each worker's games step on their own (as double-buffered sampling steps them: new actions go to
    whichever worker answers first) instead of all games in lockstep.
    """
    env = make_multiagent_vec_env(task, n_games=n_games, seed=seed, num_cpus=num_cpus)
    rng = np.random.default_rng(seed)
    env.reset()
    vec_steps = 0
    assert isinstance(env.action_space, spaces.Discrete)  # football's 19 actions
    n_actions = int(env.action_space.n)
    cpu_start, start = cpu_seconds(), time.perf_counter()
    if groups:
        slot_groups = env.sampling_groups
        for group, slots in enumerate(slot_groups):
            env.step_group_async(group, rng.integers(0, n_actions, size=len(slots)))
        while time.perf_counter() - start < seconds:
            group, _, _ = env.step_any_group_wait()
            env.step_group_async(group, rng.integers(0, n_actions, size=len(slot_groups[group])))
            while env.n_staged_steps:
                env.step_wait()
                vec_steps += 1
        env.drain_groups()
    else:
        while time.perf_counter() - start < seconds:
            env.step(rng.integers(0, n_actions, size=env.num_envs))
            vec_steps += 1
    elapsed, cpu = time.perf_counter() - start, cpu_seconds() - cpu_start
    episodes = env.episode_count
    env.close()
    env_steps = vec_steps * n_games
    return {
        "env_steps_per_s": env_steps / elapsed,
        "env_steps_per_cpu_s": env_steps / max(cpu, 1e-9),
        "episodes": episodes,
        "busy": busy_share(cpu, elapsed),
    }


def training(
    algo: str, task: str, n_games: int, iterations: int, seed: int, num_cpus: int = 0, double_buffered: str | None = None
) -> dict[str, float]:
    """Env steps/s of ``learn`` (rollouts + updates) with the packaged config, ``iterations`` iterations.

    :param double_buffered: ``"on"``, ``"off"`` or ``"auto"``: the algorithm's ``double_buffered``; ``None``: the
        config's (and versions of the package without the option)
    """
    config = {**load_hyperparams(algo, task), "num_cpus": num_cpus}
    if double_buffered is not None:
        config["double_buffered"] = {"on": True, "off": False, "auto": "auto"}[double_buffered]
    with TreeMemory() as memory:
        experiment = Experiment(algo, task, config, seed=seed, n_games=n_games)
        model = experiment.build()
        env, callbacks = experiment.env, experiment.config_callbacks
        assert env is not None
        n_agents = env.num_envs // n_games
        agent_steps = iterations * model.n_steps * env.num_envs
        cpu_start, start = cpu_seconds(), time.perf_counter()
        model.learn(agent_steps, callback=callbacks)
        elapsed, cpu = time.perf_counter() - start, cpu_seconds() - cpu_start
        env.close()
    env_steps = model.num_timesteps / n_agents
    return {
        "env_steps_per_s": env_steps / elapsed,
        "env_steps_per_cpu_s": env_steps / max(cpu, 1e-9),
        "seconds": elapsed,
        "busy": busy_share(cpu, elapsed),
        "peak_mb": memory.peak_mb,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=["grf-3v1-keeper", "grf-counterattack-easy"])
    parser.add_argument("--n-games", nargs="+", type=int, default=[1, 2], help="game counts for random stepping")
    parser.add_argument("--num-cpus", nargs="+", type=int, default=[0], help="env worker processes (0: in-process)")
    parser.add_argument(
        "--random-groups",
        action="store_true",
        help="random stepping with workers: each worker's games step on their own (double-buffered) instead of in lockstep",
    )
    parser.add_argument("--seconds", type=float, default=20.0, help="duration of each random-stepping measurement")
    parser.add_argument("--no-random", action="store_true", help="skip random stepping")
    parser.add_argument("--train-algos", nargs="*", default=["saeir_ppo"], help="methods trained (none given: skip)")
    parser.add_argument("--train-task", default="grf-3v1-keeper")
    parser.add_argument("--train-games", nargs="+", type=int, default=[2], help="game counts of the training runs")
    parser.add_argument("--train-num-cpus", nargs="+", type=int, default=[0], help="env worker processes of training")
    parser.add_argument(
        "--train-double-buffered",
        nargs="+",
        choices=["on", "off", "auto"],
        default=[None],
        help="the algorithms' double_buffered (default: the config's; leave out for versions without the option)",
    )
    parser.add_argument("--train-iterations", type=int, default=2, help="PPO iterations (each n_steps x games env steps)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (the update; inference is tiny)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    th.set_num_threads(args.threads)

    engine_s: float | None = None  # CPU-seconds per env step of one game in this process (the cost model's e)
    if not args.no_random:
        for task in args.tasks:
            for num_cpus in args.num_cpus:
                for n_games in args.n_games:
                    groups = args.random_groups and num_cpus >= 2
                    result = random_stepping(task, n_games, args.seconds, num_cpus, args.seed, groups)
                    if task == args.train_task and num_cpus == 0 and n_games == 1:
                        engine_s = 1.0 / result["env_steps_per_cpu_s"]
                    mode = " groups" if groups else ""
                    print(
                        f"random {task:>22} games={n_games} num_cpus={num_cpus}{mode}: "
                        f"{result['env_steps_per_s']:7.1f} env steps/s "
                        f"({result['env_steps_per_cpu_s']:6.1f} per CPU-s, {result['episodes']:.0f} episodes, "
                        f"{result['busy']:.0%} of the CPUs busy)",
                        flush=True,
                    )
    runs = [
        (algo, num_cpus, n_games, double_buffered)
        for algo in args.train_algos
        for num_cpus in args.train_num_cpus
        for n_games in args.train_games
        for double_buffered in args.train_double_buffered
    ]
    for algo, num_cpus, n_games, double_buffered in runs:
        result = training(algo, args.train_task, n_games, args.train_iterations, args.seed, num_cpus, double_buffered)
        mode = f" double_buffered={double_buffered}" if double_buffered is not None else ""
        print(
            f"train  {algo} {args.train_task} games={n_games} num_cpus={num_cpus}{mode} threads={args.threads} "
            f"iterations={args.train_iterations}: "
            f"{result['env_steps_per_s']:7.1f} env steps/s ({result['env_steps_per_cpu_s']:6.1f} per CPU-s, "
            f"{result['seconds']:.0f} s, {result['busy']:.0%} of the CPUs busy; 25M env steps at this rate: "
            f"{PAPER_ENV_STEPS / result['env_steps_per_s'] / 3600:.1f} h; peak RSS with the workers "
            f"{result['peak_mb']:.0f} MB)",
            flush=True,
        )
        if engine_s is not None:
            print("\n".join(cost_model_lines(engine_s, 1.0 / result["env_steps_per_cpu_s"], n_games)), flush=True)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {peak_mb:.0f} MB; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
