"""Double-buffered sampling: the policy acts for one group of games while the other groups step.

With the games in worker processes (``make_multiagent_vec_env(..., num_cpus=k)``), each worker's games form a group
(:attr:`~sb3_saeir.common.vec_env.MultiAgentVecEnv.sampling_groups`). ``MAPPO(..., double_buffered=...)`` (and
``SAEIR_PPO``) keeps every group stepping: as soon as one group's step comes back, the policy computes that group's
next actions and sends them, while the other groups' engines run (Sample Factory's double-buffered sampling). The
policy is fixed during a rollout and every network computes per slot or per game, so the maths is that of the
synchronous loop: the buffer gets the same observations, actions, rewards, values, log-probs and states in the same
layout, up to the last bits of float sums over a group's smaller batch (tested with a policy whose actions do not
depend on random draws; ``docs/guide/performance.md``, "Football across cores").

**Random draws.** The actions (and the hypergraph critics' Gumbel noise) are drawn group by group, so the random
stream differs from the synchronous loop's. Each group draws from its own torch generator state, seeded from the global
generator at the start of the rollout, so the order in which the groups come back does not matter: the same seed gives
the same run twice (tested with workers whose steps take random wall time). After the rollout the global generator
continues from where the group seeds were drawn.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from sb3_saeir.common.type_aliases import MultiAgentStates


def base_multiagent_env(env: VecEnv) -> tuple[Any, list[VecEnvWrapper]]:
    """The innermost vec env and the wrappers around it (outermost first)."""
    wrappers = []
    while isinstance(env, VecEnvWrapper):
        wrappers.append(env)
        env = env.venv
    return env, wrappers


def games_in_workers(env: VecEnv | None) -> bool:
    """Whether the games of ``env`` (under its wrappers) run in two or more worker processes."""
    if env is None:
        return False
    base, _ = base_multiagent_env(env)
    return len(getattr(base, "sampling_groups", ())) >= 2


def double_buffering_obstacle(env: VecEnv | None) -> str | None:
    """Why ``env`` cannot be sampled double-buffered, or ``None`` when it can.

    It can when its games run in two or more worker processes and every wrapper around it passes observations,
    rewards and dones through unchanged (wrappers that do declare ``passes_steps_through = True``, as
    :class:`~sb3_saeir.common.vec_env.MultiAgentVecMonitor` does): the policy acts on a group's observations before the
    wrappers see the whole step.

    :param env: the training env
    :return: a sentence naming the obstacle and the fix, or ``None``
    """
    if env is None:
        return "there is no env"
    base, wrappers = base_multiagent_env(env)
    if not hasattr(base, "sampling_groups"):
        return f"{type(base).__name__} has no groups of games that step on their own (make_multiagent_vec_env does)"
    if len(base.sampling_groups) < 2:
        return "its games run in one process (make_multiagent_vec_env(..., num_cpus=2) or more runs them in workers)"
    changing = [type(wrapper).__name__ for wrapper in wrappers if not getattr(wrapper, "passes_steps_through", False)]
    if changing:
        return (
            f"the wrappers {changing} may change observations, rewards or dones, which the policy must see before the "
            "wrappers do (VecNormalize, frame stacks): remove them or use double_buffered=False"
        )
    return None


class GroupRandomStreams:
    """One torch generator state per group of games, seeded from the global generator (module docstring).

    :param n_groups: groups of games
    :param device: the policy's device (its default generator is swapped)
    """

    def __init__(self, n_groups: int, device: th.device) -> None:
        self.device = th.device(device)
        if self.device.type not in ("cpu", "cuda"):
            raise ValueError(f"Double-buffered sampling supports the cpu and cuda devices, not {self.device}.")
        seeds = th.randint(0, 2**62, (n_groups,), dtype=th.int64)  # from the global CPU generator
        self._after_seeds = self._get()
        self.states = []
        for seed in seeds.tolist():
            generator = th.Generator(device=self.device)
            generator.manual_seed(int(seed))
            self.states.append(generator.get_state())

    def _get(self) -> th.Tensor:
        return th.cuda.get_rng_state(self.device) if self.device.type == "cuda" else th.get_rng_state()

    def _set(self, state: th.Tensor) -> None:
        if self.device.type == "cuda":
            th.cuda.set_rng_state(state, self.device)
        else:
            th.set_rng_state(state)

    def run(self, group: int, draw: Callable[[], Any]) -> Any:
        """Call ``draw`` with group ``group``'s generator state as the device's default; keep its new state."""
        self._set(self.states[group])
        try:
            return draw()
        finally:
            self.states[group] = self._get()

    def finish(self) -> None:
        """Put the global generator back where the group seeds were drawn."""
        self._set(self._after_seeds)


@dataclass
class GroupStep:
    """What the policy computed for one group at one step (inputs and outputs), kept until the whole step is in."""

    obs: np.ndarray  # (rows, ...) the observations the policy acted on
    episode_starts: np.ndarray  # (rows,)
    states: MultiAgentStates  # the states before the step: actor (rows, H), critic (K, games, N, H)
    actions: np.ndarray  # (rows, ...) as sent to the env
    values: th.Tensor  # (rows, K) normalised
    log_probs: th.Tensor  # (rows,)
    new_states: MultiAgentStates  # the states after the step


def slice_states(states: MultiAgentStates, slots: range, n_agents: int) -> MultiAgentStates:
    """The states of a group's slots: actor rows ``slots``, critic games ``slots // n_agents``."""
    games = slice(slots.start // n_agents, slots.stop // n_agents)
    return MultiAgentStates(actor=states.actor[slots.start : slots.stop], critic=states.critic[:, games])


def join_states(parts: list[MultiAgentStates]) -> MultiAgentStates:
    """The states of all slots from the groups' states (groups in slot order)."""
    # actor (rows_g, H) -> (n_slots, H); critic (K, games_g, N, H) -> (K, n_games, N, H)
    return MultiAgentStates(
        actor=th.cat([part.actor for part in parts]), critic=th.cat([part.critic for part in parts], dim=1)
    )


def join_steps(parts: list[GroupStep]) -> GroupStep:
    """One step of all slots from the groups' steps (groups in slot order)."""
    return GroupStep(
        obs=np.concatenate([part.obs for part in parts]),
        episode_starts=np.concatenate([part.episode_starts for part in parts]),
        states=join_states([part.states for part in parts]),
        actions=np.concatenate([part.actions for part in parts]),
        values=th.cat([part.values for part in parts]),
        log_probs=th.cat([part.log_probs for part in parts]),
        new_states=join_states([part.new_states for part in parts]),
    )
