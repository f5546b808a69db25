"""Profile the rollout inference and the PPO update of a method with the torch profiler, by operator and by module.

    OMP_NUM_THREADS=1 python benchmarks/profile_step.py --algo saeir_ppo --n-games 128
    OMP_NUM_THREADS=1 python benchmarks/profile_step.py --algo mappo --n-games 128 --rows 15

The model is built from the method's packaged config (``zoo_configs/<algo>.yml``: 25-step rollouts, 10 epochs, one
minibatch, hidden size 64) with ``n_games`` games. One rollout and one update run first (warm-up; they also fill the
buffer), then the profiler records ``--inference-steps`` rollout forward passes (``policy.forward`` on the stored
observations, no environment) and one full update (``model.train()``: every epoch and minibatch).

Two tables per phase:

- **by operator**: ``torch.profiler`` self CPU time per aten operator (forward and backward operators appear separately);
- **by module**: CPU time of every network module's forward (a ``record_function`` around each forward call, inclusive of
  its children) plus the autograd backward as one row and the rest of the update (optimizer, losses, buffer) as another.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator

import torch as th
from torch import nn
from torch.profiler import ProfilerActivity, profile, record_function

from sb3_saeir.common.policies import MultiAgentActorCriticPolicy
from sb3_saeir.experiment import Experiment

# modules timed one level below the policy's actor and critics (HypergraphScaleCritic's message-passing parts included)
_MODULE_DEPTH = 4


@contextlib.contextmanager
def module_labels(policy: nn.Module, max_depth: int = _MODULE_DEPTH) -> Iterator[None]:
    """Wrap the forward of every named module of ``policy`` up to ``max_depth`` dots in a ``record_function``
    labelled ``module::<name>``.

    :param policy: the policy whose modules to label
    :param max_depth: deepest module name (number of dots + 1) to label
    """
    handles = []
    for name, module in policy.named_modules():
        if not name or name.count(".") >= max_depth or name.startswith(("value_norms", "optimizer")):
            continue
        label = f"module::{name}"

        def pre_hook(mod: nn.Module, args: object, label: str = label) -> None:
            ctx = record_function(label)
            ctx.__enter__()
            mod.__dict__.setdefault("_profile_ctx", []).append(ctx)

        def post_hook(mod: nn.Module, args: object, output: object) -> None:
            mod.__dict__["_profile_ctx"].pop().__exit__(None, None, None)

        handles.append(module.register_forward_pre_hook(pre_hook))
        handles.append(module.register_forward_hook(post_hook))
    try:
        yield
    finally:
        for handle in handles:
            handle.remove()


def module_table(prof: profile, total_label: str, rows: int) -> str:
    """Inclusive CPU time of every ``module::`` label and of the backward pass, as a share of ``total_label``.

    :param prof: a finished profiler
    :param total_label: the ``record_function`` label spanning the whole phase
    :param rows: how many rows to print
    """
    averages = prof.key_averages()
    total = next(event.cpu_time_total for event in averages if event.key == total_label)
    entries = [(e.key.removeprefix("module::"), e.cpu_time_total, e.count) for e in averages if e.key.startswith("module::")]
    # the autograd engine's evaluate_function events do not nest: their inclusive times add up to the backward pass
    backward = sum(e.cpu_time_total for e in averages if e.key.startswith("autograd::engine::evaluate_function"))
    entries.append(("(autograd backward, all modules)", backward, 0))
    entries.sort(key=lambda entry: -entry[1])
    lines = [f"{'module (inclusive forward time; children nested in parents)':<60} {'ms':>9} {'%':>6} {'calls':>6}"]
    for name, micros, count in entries[:rows]:
        lines.append(f"{name:<60} {micros / 1e3:9.1f} {100 * micros / total:6.1f} {count:6d}")
    lines.append(f"{'total ' + total_label:<60} {total / 1e3:9.1f} {100.0:6.1f}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", default="saeir_ppo")
    parser.add_argument("--task", default="cn-sparse-n3")
    parser.add_argument("--n-games", type=int, default=128)
    parser.add_argument("--inference-steps", type=int, default=25, help="rollout forward passes to profile")
    parser.add_argument("--rows", type=int, default=20, help="rows per table")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--device", default="cpu", help="torch device (cuda: add the CUDA activity to the profile)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    th.set_num_threads(args.threads)

    experiment = Experiment(args.algo, args.task, seed=args.seed, n_games=args.n_games)
    model = experiment.build(device=args.device)
    env, callbacks = experiment.env, experiment.config_callbacks
    assert env is not None
    policy = model.policy
    if not isinstance(policy, MultiAgentActorCriticPolicy):
        raise SystemExit(f"--algo {args.algo}: this script profiles the multi-agent policies (not {type(policy).__name__})")
    model.learn(model.n_steps * env.num_envs, callback=callbacks)  # warm-up: one rollout and one update
    buffer = model.rollout_buffer
    device = policy.device
    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if device.type == "cuda" else [])
    observations = th.as_tensor(buffer.observations, device=device)  # (T, G * N, d)
    starts = th.as_tensor(buffer.episode_starts, dtype=th.float32, device=device)  # (T, G * N)
    n_games = env.num_envs // policy.n_agents

    policy.set_training_mode(False)
    with module_labels(policy), profile(activities=activities) as prof_inference:
        with record_function("phase::inference"), th.no_grad():
            states = policy.initial_states(n_games)
            for step in range(args.inference_steps):
                _, _, _, states = policy(observations[step % len(observations)], states, starts[step % len(starts)])
    with module_labels(policy), profile(activities=activities) as prof_update:
        with record_function("phase::update"):
            model.train()
    env.close()

    for phase, prof in (("inference", prof_inference), ("update", prof_update)):
        print(f"\n=== {args.algo} {phase} ({args.n_games} games, {args.threads} thread(s)) -- by operator (self CPU) ===")
        print(prof.key_averages().table(sort_by="self_cpu_time_total", row_limit=args.rows, max_name_column_width=40))
        print(f"=== {args.algo} {phase} -- by module ===")
        print(module_table(prof, f"phase::{phase}", args.rows))


if __name__ == "__main__":
    main()
