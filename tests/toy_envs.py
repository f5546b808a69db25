"""Tiny PettingZoo parallel envs for bad-input, worker and sampling tests."""

import os
import random
import time

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
