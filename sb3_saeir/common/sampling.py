"""Filling a rollout buffer: :class:`RolloutCollector` holds the synchronous loop (the policy acts for every slot,
every game steps) and the double-buffered one (with the games in worker processes, the policy acts for one group of
games while the other groups step, Sample Factory's double-buffered sampling), beside :func:`double_buffering_obstacle`
and the per-group random streams. The maths is the synchronous loop's; the random draws come group by group from
per-group generators, so a seed gives the same run whatever order the groups come back in
(``docs/guide/performance.md``, "Football across cores"). ``MAPPO.collect_rollouts`` makes one collector per rollout;
the env is stepped only through :class:`~sb3_saeir.common.vec_env.MultiAgentVecEnv`'s grouped stepping.
"""

from __future__ import annotations

import collections
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.utils import obs_as_tensor
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from sb3_saeir.common.buffers import GroupedRecurrentRolloutBuffer
from sb3_saeir.common.policies import MultiAgentActorCriticPolicy
from sb3_saeir.common.type_aliases import MultiAgentStates
from sb3_saeir.common.vec_env import MultiAgentVecEnv


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
    return isinstance(base, MultiAgentVecEnv) and len(base.sampling_groups) >= 2


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
    if not isinstance(base, MultiAgentVecEnv):
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
class PolicyStep:
    """The policy's step for some slots (one group of games, or all of them): its inputs and outputs, kept until the
    step of all slots is stored."""

    obs: np.ndarray  # (rows, ...) the observations the policy acted on
    episode_starts: np.ndarray  # (rows,)
    states: MultiAgentStates  # the states before the step: actor (rows, H), critic (K, games, N, H)
    actions: np.ndarray  # (rows, ...) the policy's
    env_actions: np.ndarray  # (rows, ...) as the env gets them: clipped to a Box action space (else ``actions``)
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


def join_steps(parts: list[PolicyStep]) -> PolicyStep:
    """One step of all slots from the groups' steps (groups in slot order)."""
    return PolicyStep(
        obs=np.concatenate([part.obs for part in parts]),
        episode_starts=np.concatenate([part.episode_starts for part in parts]),
        states=join_states([part.states for part in parts]),
        actions=np.concatenate([part.actions for part in parts]),
        env_actions=np.concatenate([part.env_actions for part in parts]),
        values=th.cat([part.values for part in parts]),
        log_probs=th.cat([part.log_probs for part in parts]),
        new_states=join_states([part.new_states for part in parts]),
    )


def use_double_buffering(algo_name: str, setting: bool | str, env: VecEnv) -> bool:
    """Whether a rollout of ``env`` is sampled double-buffered.

    :param algo_name: the algorithm, for the message
    :param setting: the algorithm's ``double_buffered``: ``True``, ``False`` or ``"auto"`` (when the env allows it)
    :param env: the training env
    :raises ValueError: with ``True``, when the env does not allow it (:func:`double_buffering_obstacle` says why)
    """
    if setting is False:
        return False
    obstacle = double_buffering_obstacle(env)
    if obstacle is not None and setting is True:
        raise ValueError(f"{algo_name}(double_buffered=True) cannot sample this env: {obstacle}.")
    return obstacle is None


class RolloutOwner(Protocol):
    """What :class:`RolloutCollector` reads and moves on the algorithm (SB3's ``OnPolicyAlgorithm`` attributes): the
    policy, fixed during the rollout, one agent's action space (``Box`` actions are clipped before the env gets them),
    the discount of the bootstrap added at time limits, the device, the agent-step counter, where the env was left
    (observations, episode starts, recurrent states) and the episode info buffer of the ``rollout/`` logs."""

    policy: MultiAgentActorCriticPolicy
    action_space: spaces.Space
    gamma: float
    device: th.device
    num_timesteps: int
    _last_obs: np.ndarray | dict[str, np.ndarray] | None
    _last_episode_starts: np.ndarray | None
    _last_states: MultiAgentStates | None

    def _update_info_buffer(self, infos: list[dict[str, Any]], dones: np.ndarray | None = None) -> None: ...


class RolloutCollector:
    """The steps of one rollout, synchronous or double-buffered (module docstring), stored in the rollout buffer: the
    body of SB3's ``collect_rollouts(env, callback, rollout_buffer, n_rollout_steps)`` with the algorithm as ``owner``.

    Each step of all slots is stored, and the callbacks' ``on_step`` called, as SB3's ``collect_rollouts`` does: the
    callbacks' ``locals`` hold ``self`` (the algorithm), ``env``, ``callback``, ``rollout_buffer``,
    ``n_rollout_steps``, ``n_steps``, ``step`` (the policy's :class:`PolicyStep`), ``actions`` (the policy's, one row
    per slot), ``clipped_actions`` (as the env got them), ``values`` (``(slots, K)``, normalised, one column per critic
    scale), ``log_probs``, ``new_obs``, ``rewards``, ``dones`` and ``infos``. The algorithm's ``num_timesteps``
    counts agent-steps before each ``on_step``; its ``_last_obs``, ``_last_episode_starts`` and ``_last_states``
    follow the stored steps (``_last_obs`` is ``None`` after a double-buffered rollout that was stopped or failed: the
    next ``learn`` resets the env).

    :param owner: the algorithm (its policy, fixed during the rollout, and its counters: :class:`RolloutOwner`)
    :param env: the training env
    :param callback: the callbacks (``on_step`` after each step of all slots)
    :param rollout_buffer: the buffer, reset
    :param n_rollout_steps: steps per game
    """

    def __init__(
        self,
        owner: RolloutOwner,
        env: VecEnv,
        callback: BaseCallback,
        rollout_buffer: GroupedRecurrentRolloutBuffer,
        n_rollout_steps: int,
    ) -> None:
        self.owner = owner
        self.env = env
        self.callback = callback
        self.rollout_buffer = rollout_buffer
        self.n_rollout_steps = n_rollout_steps
        self.policy = owner.policy
        self.action_space = owner.action_space
        self.gamma = owner.gamma
        self.device = owner.device

    def collect(self, double_buffered: bool) -> bool:
        """Store ``n_rollout_steps`` steps of every game in the buffer, from where the owner left the env.

        With the games in worker processes, the policy's small forward passes run on one torch thread: more threads
        would spin on the cores the engines need (the update, with the workers idle, keeps the process's threads).

        :param double_buffered: the double-buffered loop (:func:`use_double_buffering`), else the synchronous one
        :return: ``False`` when a callback stopped training
        """
        threads = th.get_num_threads()
        if games_in_workers(self.env):
            th.set_num_threads(1)
        try:
            if double_buffered:
                return self._collect_double_buffered()
            return self._collect_synchronous()
        finally:
            th.set_num_threads(threads)

    def _collect_synchronous(self) -> bool:
        """The synchronous loop: the policy acts for every slot, then every game steps."""
        owner = self.owner
        for n_steps in range(self.n_rollout_steps):
            step = self._act(owner._last_obs, owner._last_states, owner._last_episode_starts)  # type: ignore[arg-type]
            if not self._take_step(n_steps, step, *self.env.step(step.env_actions)):
                return False
        return True

    def _take_step(
        self, n_steps: int, step: PolicyStep, new_obs: Any, rewards: np.ndarray, dones: np.ndarray, infos: list[dict]
    ) -> bool:
        """A step of all slots made: count it, call the callbacks (``False``: one stopped training), then store it.

        :param n_steps: steps of every game stored before this one
        :param step: the policy's step for all slots
        :param new_obs: the env's observations after it
        :param rewards: its rewards
        :param dones: its dones
        :param infos: its infos
        """
        owner, callback = self.owner, self.callback
        owner.num_timesteps += self.env.num_envs
        # the callbacks' locals, with the names SB3's collect_rollouts gives them (self: the algorithm)
        step_locals = {"self": owner, "env": self.env, "callback": callback, "n_steps": n_steps, "step": step}
        step_locals.update(rollout_buffer=self.rollout_buffer, n_rollout_steps=self.n_rollout_steps)
        step_locals.update(actions=step.actions, clipped_actions=step.env_actions)
        step_locals.update(values=step.values, log_probs=step.log_probs)
        callback.update_locals({**step_locals, "new_obs": new_obs, "rewards": rewards, "dones": dones, "infos": infos})
        if not callback.on_step():
            return False
        owner._update_info_buffer(infos, dones)
        self._store_step(step, rewards, dones, infos, new_obs)
        return True

    def _collect_double_buffered(self) -> bool:
        """The double-buffered loop: each group of games steps on its own; a step of all slots is stored (and the
        callbacks called) once every group has made it."""
        owner, env, n_rollout_steps = self.owner, self.env, self.n_rollout_steps
        base, _ = base_multiagent_env(env)
        assert isinstance(base, MultiAgentVecEnv)
        groups = base.sampling_groups
        streams = GroupRandomStreams(len(groups), self.device)
        in_buffer: list[collections.deque[PolicyStep]] = [collections.deque() for _ in groups]  # sent, not yet stored
        sent = [0] * len(groups)

        def act_and_send(group: int, obs: np.ndarray, starts: np.ndarray, states: MultiAgentStates) -> None:
            step = streams.run(group, lambda: self._act(obs, states, starts))
            base.step_group_async(group, step.env_actions)  # the group's rows only
            in_buffer[group].append(step)
            sent[group] += 1

        assert owner._last_obs is not None and owner._last_states is not None
        assert owner._last_episode_starts is not None
        last_obs, last_starts = np.asarray(owner._last_obs), owner._last_episode_starts
        for group, slots in enumerate(groups):
            rows = slice(slots.start, slots.stop)
            act_and_send(
                group, last_obs[rows], last_starts[rows], slice_states(owner._last_states, slots, self.policy.n_agents)
            )
        n_steps = 0
        try:
            while n_steps < n_rollout_steps:
                if base.n_staged_steps == 0:
                    group, group_obs, group_dones = base.step_any_group_wait()
                    if sent[group] < n_rollout_steps:
                        act_and_send(group, group_obs, group_dones, in_buffer[group][-1].new_states)
                    continue
                step = join_steps([queue.popleft() for queue in in_buffer])
                if not self._take_step(n_steps, step, *env.step_wait()):  # the oldest step every group made
                    base.drain_groups()
                    owner._last_obs = None  # the groups are out of step: the next learn() resets the env
                    return False
                n_steps += 1
        except BaseException:
            base.drain_groups()
            owner._last_obs = None
            raise
        finally:
            streams.finish()
        return True

    def _act(self, obs: np.ndarray, states: MultiAgentStates, episode_starts: np.ndarray) -> PolicyStep:
        """The policy's step for the slots of ``obs`` (all slots, or one group of games)."""
        with th.no_grad():
            obs_tensor = obs_as_tensor(obs, self.device)  # type: ignore[arg-type]
            starts = th.as_tensor(episode_starts, dtype=th.float32, device=self.device)
            actions, values, log_probs, new_states = self.policy(obs_tensor, states, starts)
        actions_array = actions.cpu().numpy()
        return PolicyStep(
            obs, episode_starts, states, actions_array, self._env_actions(actions_array), values, log_probs, new_states
        )

    def _env_actions(self, actions: np.ndarray) -> np.ndarray:
        """The actions as sent to the env (clipped to a ``Box`` action space)."""
        if isinstance(self.action_space, spaces.Box):
            return np.clip(actions, self.action_space.low, self.action_space.high)
        return actions

    def _store_step(
        self, step: PolicyStep, rewards: np.ndarray, dones: np.ndarray, infos: list[dict], new_obs: np.ndarray
    ) -> None:
        """Add one step of all slots to the buffer and move the owner's ``_last_obs``, ``_last_episode_starts`` and
        ``_last_states``."""
        # (E,) -> (E, 1) for Discrete actions: the buffer's action layout
        actions = step.actions.reshape(-1, 1) if isinstance(self.action_space, spaces.Discrete) else step.actions
        # (E,) -> (E, K): each critic scale gets the env reward plus its own bootstrap where a game was truncated
        scale_rewards = np.repeat(np.asarray(rewards, dtype=np.float32)[:, None], self.policy.n_scales, axis=1)
        scale_rewards += self.truncation_bootstrap(infos, dones, step.new_states)
        self.rollout_buffer.add(
            step.obs,  # type: ignore[arg-type]
            actions,
            scale_rewards,
            step.episode_starts,
            step.values,
            step.log_probs,
            actor_states=step.states.actor,
            critic_states=step.states.critic,
        )
        self.owner._last_obs = new_obs
        self.owner._last_episode_starts = dones
        self.owner._last_states = step.new_states

    def truncation_bootstrap(self, infos: list[dict], dones: np.ndarray, states: MultiAgentStates) -> np.ndarray:
        """``gamma * V_K(final observation)`` per scale for the slots of games that hit a time limit
        (``TimeLimit.truncated``, only set when the env is asked to), zero elsewhere; ``(n_envs, K)``.

        The critics run on the games' final observations with their states after this step.

        :param infos: the step's infos (``terminal_observation`` of finished games)
        :param dones: ``(n_envs,)`` the step's dones
        :param states: the recurrent states after the step
        """
        bootstrap = np.zeros((len(infos), self.policy.n_scales), dtype=np.float32)
        truncated_slots = [i for i, info in enumerate(infos) if dones[i] and info.get("TimeLimit.truncated", False)]
        if not truncated_slots:
            return bootstrap
        n_agents = self.policy.n_agents
        games = sorted({slot // n_agents for slot in truncated_slots})
        slots = [g * n_agents + a for g in games for a in range(n_agents)]
        terminal_obs = np.stack([infos[slot]["terminal_observation"] for slot in slots])  # (len(games) * N, d)
        with th.no_grad():
            obs = th.as_tensor(terminal_obs, dtype=th.float32, device=self.device)
            game_states = MultiAgentStates(actor=states.actor[slots], critic=states.critic[:, games])  # critic (K, g, N, H)
            normalized = self.policy.predict_values(obs, game_states)  # (len(games) * N, K)
            values = self.policy.denormalize_values(normalized).cpu().numpy()
        bootstrap[slots] = self.gamma * values
        return bootstrap
