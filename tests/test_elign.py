"""Elign (elign_team): hand-computed bonuses with a fixed forward model, neighbourhoods, visibility masking, model
training, SAEIR_PPO integration."""

import numpy as np
import pytest
import torch as th
from gymnasium import spaces

from sb3_saeir.envs.navigation import SparseCooperativeNavigation
from sb3_saeir.intrinsic.elign import ElignCallback, elign_team_bonus, navigation_visibility

OBS_DIM = 18  # mpe2 layout for N = L = 3: vel(2), pos(2), landmarks(6), other agents(4), comm(4)
AGENTS = np.array([[0.0, 0.0], [0.3, 0.0], [0.9, 0.9]])  # 0-1 at distance 0.3; agent 2 is > 1 away from both
LANDMARKS = np.array([[0.1, 0.0], [-0.45, 0.0], [0.9, 0.5]])


def navigation_obs(agent: int) -> np.ndarray:
    """Agent ``agent``'s observation written out in the mpe2 layout, with non-zero velocity and comm entries."""
    own = AGENTS[agent]
    others = [j for j in range(3) if j != agent]
    velocity = [0.1 * (agent + 1), -0.2]
    comm = [[10.0 + j, 20.0 + j] for j in others]
    return np.concatenate([velocity, own, *(LANDMARKS - own), *(AGENTS[others] - own), *comm]).astype(np.float32)


def identity_model_callback(**kwargs) -> ElignCallback:
    """An ElignCallback whose forward model is a single linear layer fixed to f(o, a) = o + action index."""
    callback = ElignCallback(net_arch=(), device="cpu", **kwargs)
    callback.setup_forward_model(spaces.Box(-np.inf, np.inf, (OBS_DIM,)), spaces.Discrete(5))
    layer = callback.forward_model.net[0]
    with th.no_grad():
        layer.weight.zero_()
        layer.weight[:, :OBS_DIM] = th.eye(OBS_DIM)  # copy the observation
        layer.weight[:, OBS_DIM:] = th.arange(5.0)  # one-hot action k adds k to every entry
        layer.bias.zero_()
    return callback


def test_hand_example_radius_masking_and_lonely_agent():
    observations = np.stack([navigation_obs(i) for i in range(3)])[None]  # (T=1, E=3, d)
    next_observations = observations + np.random.default_rng(0).normal(size=observations.shape).astype(np.float32)
    actions = np.zeros((1, 3, 1))  # action 0: the fixed model predicts f(o, a) = o
    callback = identity_model_callback(obs_radius=0.5)
    bonus = callback.bonus_from_transitions(observations, actions, next_observations, n_agents=3)

    # agent 0's only neighbour is agent 1 (at (0.3, 0)); what agent 1 cannot see within 0.5: landmarks 1 (0.75 away)
    # and 2 (0.78), agent 2 (1.08) -> its relative position and comm entries
    imagined_0 = observations[0, 0].copy()
    imagined_0[6:10] = 0.0
    imagined_0[12:14] = 0.0
    imagined_0[16:18] = 0.0
    # agent 1's only neighbour is agent 0 (at the origin): it cannot see landmark 2 (1.03) and agent 2 (1.27)
    imagined_1 = observations[0, 1].copy()
    imagined_1[8:10] = 0.0
    imagined_1[12:14] = 0.0
    imagined_1[16:18] = 0.0
    expected = [
        -np.linalg.norm(next_observations[0, 0] - imagined_0) / OBS_DIM,
        -np.linalg.norm(next_observations[0, 1] - imagined_1) / OBS_DIM,
        0.0,  # agent 2 has no neighbour within 0.5
    ]
    np.testing.assert_allclose(bonus[0], expected, rtol=1e-5)
    assert callback.last_neighbour_fraction == pytest.approx(2 / 3)


def test_all_teammates_without_radius_and_actions_reach_the_model():
    observations = np.stack([navigation_obs(i) for i in range(3)])[None]
    next_observations = observations + 0.5
    actions = np.array([[[0], [2], [4]]])  # predictions o + 0, o + 2, o + 4
    callback = identity_model_callback(obs_radius=None, visibility_fn=None)
    bonus = callback.bonus_from_transitions(observations, actions, next_observations, n_agents=3)
    # every teammate is a neighbour and sees everything: each error is ||0.5 - k|| over 18 entries
    expected = [-np.sqrt(OBS_DIM) * abs(0.5 - k) / OBS_DIM for k in (0, 2, 4)]
    np.testing.assert_allclose(bonus[0], expected, rtol=1e-5)


def test_bonus_averages_over_neighbours_and_ignores_those_outside_the_radius():
    rng = np.random.default_rng(1)
    positions = np.array([[[0.0, 0.0], [0.5, 0.0], [1.4, 0.0], [0.0, -0.8]]])  # (B=1, N=4, 2)
    observations = rng.normal(size=(1, 4, 5))
    observations[..., :2] = positions
    next_observations = rng.normal(size=(1, 4, 5))

    def scale_by_viewer_x(obs, viewer_positions, radius):
        return (1.0 + viewer_positions[..., :1]).expand_as(obs)  # imagined o_i = (1 + x_j) * o_i

    bonus = elign_team_bonus(
        lambda obs, act: obs,  # f(o, a) = o
        th.as_tensor(observations),
        th.zeros(1, 4, 1),
        th.as_tensor(next_observations),
        obs_radius=1.0,
        position_fn=lambda obs: obs[..., :2],
        visibility_fn=scale_by_viewer_x,
    )
    expected = np.zeros(4)
    for i in range(4):
        neighbours = [j for j in range(4) if j != i and np.linalg.norm(positions[0, i] - positions[0, j]) <= 1.0]
        errors = [np.linalg.norm(next_observations[0, i] - (1 + positions[0, j, 0]) * observations[0, i]) for j in neighbours]
        expected[i] = -np.mean(errors) / 5 if errors else 0.0
    # neighbours within 1.0: agent 0 -> {1, 3} (2 is 1.4 away), 1 -> {0, 2, 3}, 2 -> {1}, 3 -> {0, 1}
    assert np.count_nonzero(expected) == 4
    np.testing.assert_allclose(bonus.numpy()[0], expected, rtol=1e-6)


def test_navigation_visibility_zeroes_exactly_what_the_viewer_cannot_see():
    env = SparseCooperativeNavigation(N=3)
    observations, _ = env.reset(seed=3)
    agent_positions, landmark_positions, _ = env.positions()
    obs_0 = th.as_tensor(observations[env.possible_agents[0]])
    viewer = agent_positions[1]
    radius = 0.8
    mask = navigation_visibility(obs_0, th.as_tensor(viewer, dtype=obs_0.dtype), radius).numpy()

    def seen(point):
        return float(np.linalg.norm(point - viewer) <= radius)

    expected = np.concatenate(
        [
            [seen(agent_positions[0])] * 4,  # agent 0's own velocity and position
            *([seen(landmark)] * 2 for landmark in landmark_positions),
            [seen(agent_positions[1])] * 2,  # agent 0's view of agents 1 and 2
            [seen(agent_positions[2])] * 2,
            [seen(agent_positions[1])] * 2,  # their comm entries
            [seen(agent_positions[2])] * 2,
        ]
    )
    np.testing.assert_array_equal(mask, expected)
    assert 0 < expected.sum() < OBS_DIM  # this seed has visible and hidden entities
    env.close()


def test_forward_model_loss_decreases_on_a_fixed_batch():
    th.manual_seed(0)
    rng = np.random.default_rng(0)
    observations = rng.normal(size=(64, 6)).astype(np.float32)
    actions = rng.integers(0, 3, size=(64, 1))
    next_observations = 0.5 * observations + actions  # a known dynamics
    callback = ElignCallback(n_epochs=50, batch_size=32, device="cpu")
    callback.setup_forward_model(spaces.Box(-np.inf, np.inf, (6,)), spaces.Discrete(3))
    before = callback.model_loss(observations, actions, next_observations)
    callback.train_forward_model(observations, actions, next_observations)
    assert callback.model_loss(observations, actions, next_observations) < 0.2 * before


def test_radius_needs_positions():
    with pytest.raises(ValueError, match="position_fn is needed when obs_radius is set"):
        ElignCallback(obs_radius=0.5, position_fn=None)
    ElignCallback(obs_radius=None, position_fn=None)
