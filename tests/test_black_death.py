"""sb3_saeir.common.vec_env.black_death: agents that finish early stay with zero observations and rewards, and the
game ends at the step where its last agent finishes, by termination or by truncation."""

import numpy as np
import pytest
from gymnasium import spaces
from pettingzoo import ParallelEnv

from sb3_saeir.common.vec_env import BlackDeathWrapper, black_death, make_multiagent_vec_env


class FinishingAgentsEnv(ParallelEnv):
    """3 agents; ``agent_2`` terminates at step 2, the others finish at step 5 (terminated, or truncated with
    ``truncate``). Agent ``i`` observes ``(t, i + 1)`` and gets reward ``i + 1`` while it plays; ``steps`` counts the
    calls of ``step``."""

    metadata = {"name": "finishing_agents_v0"}  # noqa: RUF012

    def __init__(self, truncate=False):
        self.possible_agents = ["agent_0", "agent_1", "agent_2"]
        self.agents = []
        self.truncate = truncate
        self.steps = 0
        self._t = 0

    def observation_space(self, agent):
        return spaces.Box(-10.0, 10.0, (2,), np.float32)

    def action_space(self, agent):
        return spaces.Discrete(2)

    def _observation(self, agent):
        return np.array([self._t, self.possible_agents.index(agent) + 1], np.float32)

    def reset(self, seed=None, options=None):
        self.agents = list(self.possible_agents)
        self._t = 0
        return {a: self._observation(a) for a in self.agents}, {a: {} for a in self.agents}

    def step(self, actions):
        assert set(actions) == set(self.agents), "stepped with the actions of agents that are not playing"
        self.steps += 1
        self._t += 1
        last = self._t >= 5
        terminations = {a: (a == "agent_2" and self._t == 2) or (last and not self.truncate) for a in self.agents}
        truncations = {a: last and self.truncate for a in self.agents}
        observations = {a: self._observation(a) for a in self.agents}
        rewards = {a: float(self.possible_agents.index(a) + 1) for a in self.agents}
        infos = {a: {"t": self._t} for a in self.agents}
        self.agents = [a for a in self.agents if not (terminations[a] or truncations[a])]
        return observations, rewards, terminations, truncations, infos


@pytest.mark.parametrize("truncate", [False, True])
def test_finished_agent_stays_until_the_last_finishes(truncate):
    game = FinishingAgentsEnv(truncate)
    env = black_death(game)
    observations, _ = env.reset(seed=0)
    assert env.agents == game.possible_agents and sorted(observations) == game.possible_agents
    for t in range(1, 6):
        observations, rewards, terminations, truncations, infos = env.step(dict.fromkeys(game.possible_agents, 0))
        assert sorted(observations) == sorted(rewards) == sorted(terminations) == game.possible_agents
        if t <= 2:  # agent_2 still plays (it finishes at step 2)
            assert observations["agent_2"].tolist() == [t, 3] and rewards["agent_2"] == 3.0 and infos["agent_2"] == {"t": t}
        else:
            assert observations["agent_2"].tolist() == [0.0, 0.0] and rewards["agent_2"] == 0.0 and infos["agent_2"] == {}
        assert observations["agent_0"].tolist() == [t, 1] and rewards["agent_1"] == 2.0
        if t < 5:
            assert not any(terminations.values()) and not any(truncations.values()), t
            assert env.agents == game.possible_agents
    # the game ends at step 5: the survivors with their own flag, agent_2 (finished before) terminated
    assert terminations == {"agent_0": not truncate, "agent_1": not truncate, "agent_2": True}
    assert truncations == {"agent_0": truncate, "agent_1": truncate, "agent_2": False}
    assert env.agents == [] and game.steps == 5  # the game is never stepped with no agent left


@pytest.mark.parametrize("num_cpus", [0, 2])
def test_episodes_through_the_vec_env_end_with_the_game(num_cpus):
    env = make_multiagent_vec_env(
        lambda: black_death(FinishingAgentsEnv(truncate=True)), n_games=2, seed=0, mark_truncation=True, num_cpus=num_cpus
    )
    env.reset()
    for t in range(1, 11):
        _, rewards, dones, infos = env.step(np.zeros(env.num_envs, dtype=int))
        assert dones.all() == (t % 5 == 0) and (dones.any() == dones.all()), t
        if t % 5 == 0:
            assert [info["episode"]["l"] for info in infos if "episode" in info] == [5, 5]
            assert [bool(info.get("TimeLimit.truncated")) for info in infos] == [True, True, False] * 2
            # team return: steps 1-2 mean (1 + 2 + 3) / 3 = 2, steps 3-5 mean (1 + 2 + 0) / 3 = 1: 2 * 2 + 3 * 1
            assert [info["episode"]["r"] for info in infos if "episode" in info] == [pytest.approx(7.0)] * 2
        else:
            assert rewards.tolist() == ([1.0, 2.0, 3.0 if t % 5 <= 2 else 0.0] * 2)
    env.close()


def test_an_observation_space_that_is_not_a_box_is_refused():
    class Discrete(FinishingAgentsEnv):
        def observation_space(self, agent):
            return spaces.Discrete(4)

    with pytest.raises(TypeError, match="agent 'agent_0' observes a Discrete, not a Box"):
        black_death(Discrete())
    assert isinstance(black_death(FinishingAgentsEnv()), BlackDeathWrapper)


def test_supersuit_black_death_is_warned_about():
    import warnings

    import supersuit as ss

    with pytest.warns(
        UserWarning, match=r"black_death_v3.*ends a step late. Wrap it with sb3_saeir.common.vec_env.black_death"
    ):
        env = make_multiagent_vec_env(lambda: ss.black_death_v3(FinishingAgentsEnv()), n_games=1, seed=0)
    env.close()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make_multiagent_vec_env(lambda: black_death(FinishingAgentsEnv()), n_games=1, seed=0).close()
