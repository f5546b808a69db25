"""Tiny PettingZoo parallel envs for bad-input tests."""

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
