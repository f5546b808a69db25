"""Sparse Cooperative Navigation (the ParallelEnv face): API compliance and the reward / coverage formulas on hand-placed
entities."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from sb3_saeir.common.vec_env import EPISODE_METRICS_KEY
from sb3_saeir.envs import list_tasks, make_task
from sb3_saeir.envs.navigation import SparseCooperativeNavigation, any_collision, count_covered_landmarks


@pytest.mark.parametrize("n_agents", [3, 4])
@pytest.mark.parametrize("world", ["mpe", "mpe2"])
def test_parallel_api(n_agents, world):
    parallel_api_test(SparseCooperativeNavigation(N=n_agents, world=world), num_cycles=60)


def test_registered_tasks():
    assert {"cn-sparse-n3", "cn-sparse-n4"} <= set(list_tasks())
    assert len(make_task("cn-sparse-n4").possible_agents) == 4
    assert make_task("cn-sparse-n3").observation_space("agent_0").shape == (18,)


def place(env, agents, landmarks):
    """Put agents and landmarks at given positions (velocities zero)."""
    env.place(agents, landmarks)


# The hand-placed tests below use mpe2's world: a step moves positions with the old (zero) velocity, so placed agents
# stay where they were put (in the original MPE world a contact force pushes overlapping agents apart within the step;
# tests/test_navigation_engine.py covers both worlds).
MPE2 = {"world": "mpe2"}


NO_OP = 0


def step_noop(env):
    return env.step({agent: NO_OP for agent in env.agents})


def test_cover_and_collision_helpers():
    agents = np.array([[0.0, 0.0], [0.5, 0.0], [2.0, 2.0]])
    landmarks = np.array([[0.05, 0.0], [0.5, 0.099], [-1.0, -1.0]])
    assert count_covered_landmarks(agents, landmarks) == 2
    assert count_covered_landmarks(agents, np.array([[0.0, 0.1]])) == 0  # exactly 0.1 is not "within"
    sizes = np.full(3, 0.15)
    assert not any_collision(agents, sizes)  # 0.5 apart > 0.3
    assert any_collision(np.array([[0.0, 0.0], [0.29, 0.0], [2.0, 2.0]]), sizes)
    assert not any_collision(np.array([[0.0, 0.0], [0.31, 0.0], [2.0, 2.0]]), sizes)


@pytest.mark.parametrize(
    "agents, landmarks, expected",
    [
        # two landmarks covered, nobody collides -> 2
        ([[0.0, 0.0], [0.6, 0.0], [-0.6, 0.5]], [[0.0, 0.02], [0.6, -0.05], [0.9, 0.9]], 2.0),
        # every landmark covered -> 3
        ([[0.0, 0.0], [0.6, 0.0], [-0.6, 0.5]], [[0.0, 0.0], [0.6, 0.0], [-0.6, 0.5]], 3.0),
        # one landmark covered and agents 0/1 collide (0.2 < 0.3) -> 1 - 1 = 0
        ([[0.0, 0.0], [0.2, 0.0], [-0.6, 0.5]], [[0.0, 0.0], [0.9, 0.9], [-0.9, 0.9]], 0.0),
        # nothing covered, two collisions in the same step -> penalty only once: -1
        ([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0]], [[0.9, 0.9], [-0.9, 0.9], [0.9, -0.9]], -1.0),
    ],
)
def test_sparse_reward_hand_placed(agents, landmarks, expected):
    env = SparseCooperativeNavigation(N=3, **MPE2)
    env.reset(seed=0)
    # Entities are placed before a no-op step; during it only contact forces move agents (by millimetres), so the
    # expected rewards hold for the post-step state, which is what the env rewards.
    place(env, agents, landmarks)
    _, rewards, _, _, infos = step_noop(env)
    agent_pos, landmark_pos, sizes = env.positions()
    covered = count_covered_landmarks(agent_pos, landmark_pos)
    collided = any_collision(agent_pos, sizes)
    assert rewards["agent_0"] == covered - int(collided)
    assert rewards["agent_0"] == pytest.approx(expected)
    assert len(set(rewards.values())) == 1  # team reward: the same for every agent
    assert infos["agent_1"]["covered_landmarks"] == covered


def test_episode_metrics():
    env = SparseCooperativeNavigation(N=3, max_cycles=4, **MPE2)
    env.reset(seed=1)
    landmark_positions = [[0.0, 0.0], [0.6, 0.0], [-0.6, 0.5]]
    covered_by_step = []
    collisions = 0
    for step in range(4):
        if step in (1, 3):  # cover everything at steps 1 and 3 (incl. the final step)
            place(env, landmark_positions, landmark_positions)
        else:  # cover one landmark with agents 0 and 1 colliding
            place(env, [[0.0, 0.0], [0.2, 0.0], [2.0, 2.0]], landmark_positions)
        _, _rewards, _terminations, truncations, infos = step_noop(env)
        covered_by_step.append(infos["agent_0"]["covered_landmarks"])
        collisions += int(infos["agent_0"]["collision"])
        if step < 3:
            assert EPISODE_METRICS_KEY not in infos["agent_0"]
    assert all(truncations.values())
    metrics = infos["agent_2"][EPISODE_METRICS_KEY]
    assert covered_by_step == [1, 3, 1, 3]
    assert metrics["coverage_rate"] == pytest.approx(1.0)
    assert metrics["coverage_over_steps"] == pytest.approx(np.mean(covered_by_step) / 3)
    assert metrics["collision_steps"] == collisions == 2
    assert metrics["success"] == 1.0


def test_continuous_actions_option():
    env = SparseCooperativeNavigation(N=3, continuous_actions=True)
    assert env.action_space("agent_0").shape == (5,)


def test_cover_radius_and_collision_penalty_options():
    # agents 0/1 collide (0.2 apart); landmark 0 is 0.15 from agent 0: covered only with a radius above 0.15
    agents = [[0.0, 0.0], [0.2, 0.0], [-0.6, 0.5]]
    landmarks = [[0.0, 0.15], [0.9, 0.9], [-0.9, 0.9]]
    rewards = {}
    for kwargs in ({}, {"cover_radius": 0.2}, {"cover_radius": 0.2, "collision_penalty": 0.5}):
        env = SparseCooperativeNavigation(N=3, **kwargs, **MPE2)
        env.reset(seed=0)
        place(env, agents, landmarks)
        _, step_rewards, _, _, infos = step_noop(env)
        agent_pos, landmark_pos, sizes = env.positions()
        radius = kwargs.get("cover_radius", 0.1)
        covered = count_covered_landmarks(agent_pos, landmark_pos, radius=radius)
        assert infos["agent_0"]["covered_landmarks"] == covered
        assert step_rewards["agent_0"] == covered - kwargs.get("collision_penalty", 1.0) * int(any_collision(agent_pos, sizes))
        rewards[tuple(kwargs.items())] = step_rewards["agent_0"]
    assert list(rewards.values()) == pytest.approx([-1.0, 0.0, 0.5])
    # the options travel through the task registry and the vec env factory
    assert make_task("cn-sparse-n3", cover_radius=0.3).cover_radius == 0.3


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"cover_radius": 0.0}, "cover_radius"),
        ({"collision_penalty": -1}, "collision_penalty"),
        ({"world": "mpe3"}, "world"),
        ({"reward": "dense"}, "reward"),
    ],
)
def test_reward_options_are_checked(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SparseCooperativeNavigation(N=3, **kwargs)
