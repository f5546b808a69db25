"""Tiny PettingZoo parallel envs for bad-input, worker and sampling tests."""

import os
import random
import time
from decimal import Decimal

import numpy as np
from gymnasium import spaces
from pettingzoo.utils.env import ParallelEnv


class DyingAgentsEnv(ParallelEnv):
    """3 agents; agent_2 leaves the game after step 2, the others at step 5."""

    metadata = {"name": "dying_agents_v0"}  # noqa: RUF012

    def __init__(self):
        self.possible_agents = ["agent_0", "agent_1", "agent_2"]
        self.agents = []
        self._t = 0

    def observation_space(self, agent):
        return spaces.Box(-1.0, 1.0, (2,), np.float32)

    def action_space(self, agent):
        return spaces.Discrete(2)

    def reset(self, seed=None, options=None):
        self.agents = list(self.possible_agents)
        self._t = 0
        return {a: np.zeros(2, np.float32) for a in self.agents}, {a: {} for a in self.agents}

    def step(self, actions):
        self._t += 1
        done_now = {a: (a == "agent_2" and self._t == 2) or self._t >= 5 for a in self.agents}
        obs = {a: np.zeros(2, np.float32) for a in self.agents}
        rewards = {a: 0.0 for a in self.agents}
        truncations = {a: False for a in self.agents}
        infos = {a: {} for a in self.agents}
        self.agents = [a for a in self.agents if not done_now[a]]
        return obs, rewards, done_now, truncations, infos


class MixedSpacesEnv(DyingAgentsEnv):
    """agent_1 has a different observation or action space."""

    def __init__(self, which="observation"):
        super().__init__()
        self.which = which

    def observation_space(self, agent):
        if self.which == "observation" and agent == "agent_1":
            return spaces.Box(-1.0, 1.0, (3,), np.float32)
        return super().observation_space(agent)

    def action_space(self, agent):
        if self.which == "action" and agent == "agent_1":
            return spaces.Discrete(3)
        return super().action_space(agent)


class ToyMeetEnv(ParallelEnv):
    """A tiny deterministic cooperative game for fast positive tests: ``n_agents`` agents on a line of 5 cells must all
    stand on the goal cell. Observation: own cell and goal cell (scaled to [0, 1]); actions: 0 stay, 1 left, 2 right;
    reward 1 to every agent while all of them stand on the goal, 0 otherwise; 6 steps. The start cells and the goal come
    from the reset seed, so a seeded reset replays the same game.
    """

    metadata = {"name": "toy_meet_v0"}  # noqa: RUF012

    def __init__(self, n_agents=3, max_cycles=6):
        self.possible_agents = [f"agent_{i}" for i in range(n_agents)]
        self.agents = []
        self.max_cycles = max_cycles
        self._rng = np.random.default_rng()
        self._cells = np.zeros(n_agents, dtype=int)
        self._goal = 0
        self._t = 0

    def observation_space(self, agent):
        return spaces.Box(0.0, 1.0, (2,), np.float32)

    def action_space(self, agent):
        return spaces.Discrete(3)

    def _observations(self):
        return {a: np.array([self._cells[i] / 4.0, self._goal / 4.0], np.float32) for i, a in enumerate(self.possible_agents)}

    def reset(self, seed=None, options=None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agents = list(self.possible_agents)
        self._cells = self._rng.integers(0, 5, size=len(self.possible_agents))
        self._goal = int(self._rng.integers(0, 5))
        self._t = 0
        return self._observations(), {a: {} for a in self.agents}

    def step(self, actions):
        moves = np.array([(0, -1, 1)[int(actions[a])] for a in self.possible_agents])
        self._cells = np.clip(self._cells + moves, 0, 4)
        self._t += 1
        reward = float((self._cells == self._goal).all())
        truncated = self._t >= self.max_cycles
        self.agents = [] if truncated else list(self.possible_agents)
        return (
            self._observations(),
            {a: reward for a in self.possible_agents},
            {a: False for a in self.possible_agents},
            {a: truncated for a in self.possible_agents},
            {a: {} for a in self.possible_agents},
        )


class UnequalRewardsEnv(ToyMeetEnv):
    """:class:`ToyMeetEnv` whose agent ``i`` gets ``i + 1`` at every step: a step's team reward (the mean over the
    agents) is 2 with 3 agents, the sum would be 6, the first agent's 1."""

    def step(self, actions):
        observations, _, terminations, truncations, infos = super().step(actions)
        rewards = {agent: float(i + 1) for i, agent in enumerate(self.possible_agents)}
        return observations, rewards, terminations, truncations, infos


class JitteryMeetEnv(ToyMeetEnv):
    """:class:`ToyMeetEnv` whose steps take a random wall time (0-3 ms from the OS's entropy, not from any seed): games
    in worker processes then come back in an order that changes from run to run."""

    def step(self, actions):
        time.sleep(random.SystemRandom().random() * 0.003)
        return super().step(actions)


class FailingMeetEnv(ToyMeetEnv):
    """:class:`ToyMeetEnv` that raises ``ValueError`` at its third step after a reset."""

    def step(self, actions):
        if self._t == 2:
            raise ValueError("the toy game broke at step 3")
        return super().step(actions)


class DyingMeetEnv(ToyMeetEnv):
    """:class:`ToyMeetEnv` whose process exits (as in a crash of native code) at its second step after a reset."""

    def step(self, actions):
        if self._t == 1:
            os._exit(3)
        return super().step(actions)


class SlowMeetEnv(ToyMeetEnv):
    """:class:`ToyMeetEnv` whose steps take 50 ms (time to interrupt a rollout)."""

    def step(self, actions):
        time.sleep(0.05)
        return super().step(actions)


class FaultyEnv(ParallelEnv):
    """2 agents, 4 steps; ``fault`` picks what goes wrong at step 2 (or at the second reset) of the games reset with a
    seed in ``faulty_seeds`` (``None``: every game).

    Faults: ``shape_changes``, ``missing_obs``, ``string_obs`` (an array of numeric strings), ``object_obs`` (a list
    of ``Decimal``), ``nan_obs`` (a NaN in agent_1's observation), ``missing_reward``, ``none_reward``,
    ``string_reward``, ``renamed`` (new agent names at the second reset), ``declared_shape`` (every observation of
    another shape), ``huge_reward``, ``one_terminated``.
    """

    metadata = {"name": "faulty_v0"}  # noqa: RUF012

    def __init__(self, fault="none", action_space=None, faulty_seeds=None):
        self.possible_agents = ["agent_0", "agent_1"]
        self.agents = []
        self.fault = fault
        self.faulty_seeds = faulty_seeds
        self._faulty = faulty_seeds is None
        self._action_space = action_space or spaces.Discrete(2)
        self._t = 0
        self._resets = 0

    def observation_space(self, agent):
        return spaces.Box(-1.0, 1.0, (2,), np.float32)

    def action_space(self, agent):
        return self._action_space

    def _now(self, fault):
        return self.fault == fault and self._faulty and self._t == 2

    def _obs(self):
        obs = {a: np.zeros(2, np.float32) for a in self.possible_agents}
        if self._now("shape_changes"):
            obs["agent_1"] = np.zeros(3, np.float32)
        if self._now("missing_obs"):
            del obs["agent_1"]
        if self._now("string_obs"):
            obs["agent_1"] = np.array(["0.5", "0.25"])
        if self._now("object_obs"):
            obs["agent_1"] = [Decimal("0.5"), Decimal("0.25")]
        if self._now("nan_obs"):
            obs["agent_1"] = np.array([np.nan, 0.0], np.float32)
        return obs

    def reset(self, seed=None, options=None):
        self._resets += 1
        self._t = 0
        if seed is not None and self.faulty_seeds is not None:
            self._faulty = seed in self.faulty_seeds
        if self.fault == "renamed" and self._resets > 1:
            self.possible_agents = ["player_0", "player_1"]
        if self.fault == "declared_shape":
            self.agents = list(self.possible_agents)
            return {a: np.zeros(5, np.float32) for a in self.agents}, {a: {} for a in self.agents}
        self.agents = list(self.possible_agents)
        return self._obs(), {a: {} for a in self.agents}

    def step(self, actions):
        self._t += 1
        reward = 1e30 if self.fault == "huge_reward" else 0.0
        rewards = dict.fromkeys(self.agents, reward)
        if self._now("missing_reward"):
            del rewards["agent_1"]
        if self._now("none_reward"):
            rewards["agent_1"] = None
        if self._now("string_reward"):
            rewards["agent_1"] = "1.0"
        truncations = dict.fromkeys(self.agents, self._t >= 4)
        terminations = dict.fromkeys(self.agents, False)
        if self.fault == "one_terminated" and self._t == 2:
            terminations["agent_0"] = True
        infos = {a: {} for a in self.agents}
        obs = self._obs()
        if self._t >= 4:
            self.agents = []
        return obs, rewards, terminations, truncations, infos


def _reversed_dict(mapping):
    return dict(reversed(list(mapping.items())))


class ReorderedMeetEnv(ToyMeetEnv):
    """:class:`ToyMeetEnv` that lists its agents (``agents`` and every dict it returns) in the reverse order of
    ``possible_agents``."""

    def reset(self, seed=None, options=None):
        observations, infos = super().reset(seed=seed, options=options)
        self.agents = self.agents[::-1]
        return _reversed_dict(observations), _reversed_dict(infos)

    def step(self, actions):
        results = super().step(actions)
        self.agents = self.agents[::-1]
        return tuple(_reversed_dict(result) for result in results)


class FreshSpacesMeetEnv(ToyMeetEnv):
    """:class:`ToyMeetEnv` that builds a new observation space at every call (as some envs do) and counts the calls
    in :attr:`space_calls`, shared by every instance of the process."""

    space_calls = 0

    def observation_space(self, agent):
        type(self).space_calls += 1
        return spaces.Box(0.0, 1.0, (2,), np.float32)
