import math

import pytest
import torch as th

from sb3_saeir.common.hypergraph import (
    build_incidence,
    edge_to_node,
    group_incidence,
    gumbel_softmax,
    individual_incidence,
    node_to_edge,
    team_incidence,
)


def _angles_to_features(angles_deg: list[float], norms: list[float]) -> th.Tensor:
    """(1, N, 2) features with given directions and lengths (cosine similarity = cos of the angle difference)."""
    rows = [[r * math.cos(math.radians(a)), r * math.sin(math.radians(a))] for a, r in zip(angles_deg, norms)]
    return th.tensor([rows])


def test_team_and_individual_incidence():
    team = team_incidence(3, batch_shape=(2, 5))
    assert team.shape == (2, 5, 1, 3)
    assert th.equal(team, th.ones(2, 5, 1, 3))
    individual = individual_incidence(4, batch_shape=(2,), dtype=th.float64)
    assert individual.shape == (2, 4, 4) and individual.dtype == th.float64
    assert th.equal(individual[1], th.eye(4, dtype=th.float64))
    assert team_incidence(3).shape == (1, 3)


def test_group_incidence_hand_computed_top2():
    # directions 0°, 10°, 90°, 100°: nearest other node is unambiguous, lengths must not matter (cosine)
    features = _angles_to_features([0.0, 10.0, 90.0, 100.0], [1.0, 5.0, 0.2, 3.0])
    expected = th.tensor([[1, 1, 0, 0], [1, 1, 0, 0], [0, 0, 1, 1], [0, 0, 1, 1]], dtype=th.float32)
    incidence = group_incidence(features, group_size=2)
    assert incidence.shape == (1, 4, 4)
    assert th.equal(incidence[0], expected)


def test_group_incidence_hand_computed_top3():
    # 0°, 10°, 50°, 170°: row 3 -> {3, 2 (120°), 1 (160°)}, row 2 -> {2, 1 (40°), 0 (50°)}
    features = _angles_to_features([0.0, 10.0, 50.0, 170.0], [1.0, 1.0, 2.0, 0.5])
    expected = th.tensor([[1, 1, 1, 0], [1, 1, 1, 0], [1, 1, 1, 0], [0, 1, 1, 1]], dtype=th.float32)
    incidence = build_incidence("group", features, group_size=3)
    assert th.equal(incidence[0], expected)
    assert th.all(incidence.sum(-1) == 3)
    assert th.all(th.diagonal(incidence, dim1=-2, dim2=-1) == 1)


def test_group_incidence_random_rows_and_diagonal():
    features = th.randn(7, 5, 16, requires_grad=True)
    incidence = group_incidence(features, group_size=2)
    assert incidence.shape == (7, 5, 5)
    assert not incidence.requires_grad
    assert th.all(incidence.sum(-1) == 2)
    assert th.all(th.diagonal(incidence, dim1=-2, dim2=-1) == 1)
    assert set(incidence.unique().tolist()) == {0.0, 1.0}


def test_group_incidence_keeps_diagonal_on_ties():
    # nodes 0 and 1 point the same way: C_01 = C_00 = 1, node i must still be in its own edge
    features = th.tensor([[[1.0, 0.0], [2.0, 0.0], [2.0, 0.0], [0.0, 1.0]]])
    incidence = group_incidence(features, group_size=2)
    assert th.all(th.diagonal(incidence, dim1=-2, dim2=-1) == 1)
    assert th.all(incidence.sum(-1) == 2)


@pytest.mark.parametrize("group_size", [3, 4])
def test_group_incidence_falls_back_to_team(group_size):
    features = th.randn(4, 3, 8)
    incidence = build_incidence("group", features, group_size=group_size)
    assert incidence.shape == (4, 1, 3)
    assert th.equal(incidence, th.ones(4, 1, 3))


def test_build_incidence_dispatch_and_errors():
    features = th.randn(2, 6, 3, 8, dtype=th.float64)
    assert th.equal(build_incidence("team", features, 2), th.ones(2, 6, 1, 3, dtype=th.float64))
    assert th.equal(build_incidence("individual", features, 2), th.eye(3, dtype=th.float64).expand(2, 6, 3, 3))
    with pytest.raises(ValueError, match="Unknown hypergraph scale"):
        build_incidence("idv", features, 2)
    with pytest.raises(ValueError, match="group_size"):
        group_incidence(features, 0)


def test_node_to_edge_uniform_worked_example():
    # spec §1.4: uniform logits 0, k = 2, N = 3 -> each member weight 1/3, members sum to 2/3
    x = th.tensor([[[3.0, 0.0], [0.0, 6.0], [100.0, 100.0]]])  # (1, 3, 2)
    incidence = th.tensor([[[1.0, 1.0, 0.0]]])  # (1, 1, 3)
    edges = node_to_edge(x, incidence, th.zeros(1, 1, 3))
    assert edges.shape == (1, 1, 2)
    th.testing.assert_close(edges, th.tensor([[[1.0, 2.0]]]))  # (x0 + x1) / 3
    ones = node_to_edge(th.ones(1, 3, 1), incidence, th.zeros(1, 1, 3))
    th.testing.assert_close(ones, th.tensor([[[2.0 / 3.0]]]))


def test_node_to_edge_hand_loop():
    gen = th.Generator().manual_seed(0)
    x = th.randn(2, 4, 3, generator=gen, dtype=th.float64)
    incidence = (th.rand(2, 5, 4, generator=gen) < 0.5).double()
    logits = th.randn(2, 5, 4, generator=gen, dtype=th.float64)
    out = node_to_edge(x, incidence, logits)
    for b in range(2):
        for e in range(5):
            # non-members enter the softmax with logit 0 and are then zeroed
            exps = [math.exp(logits[b, e, i].item() if incidence[b, e, i] else 0.0) for i in range(4)]
            expected = sum(incidence[b, e, i].item() * exps[i] / sum(exps) * x[b, i] for i in range(4))
            th.testing.assert_close(out[b, e], th.as_tensor(expected, dtype=th.float64))


def test_edge_to_node_hand_loop():
    gen = th.Generator().manual_seed(1)
    messages = th.randn(2, 5, 3, generator=gen)
    incidence = (th.rand(2, 5, 4, generator=gen) < 0.5).float()
    nodes = th.randn(2, 4, 3, generator=gen)
    out = edge_to_node(messages, incidence, nodes)
    assert out.shape == (2, 4, 6)
    for b in range(2):
        for i in range(4):
            incoming = sum(incidence[b, e, i] * messages[b, e] for e in range(5))
            expected = th.cat([incoming, nodes[b, i]]) / 4.0
            th.testing.assert_close(out[b, i], expected)


def test_gumbel_softmax():
    logits = th.randn(6, 4, 3)
    soft = gumbel_softmax(logits, tau=0.5)
    th.testing.assert_close(soft.sum(-1), th.ones(6, 4))
    assert th.all(soft >= 0)
    th.testing.assert_close(gumbel_softmax(logits, tau=0.5, noise=False), th.softmax(logits / 0.5, dim=-1))
    assert not th.allclose(gumbel_softmax(logits, tau=0.5), gumbel_softmax(logits, tau=0.5))
    # the noise formula of spec §1.5, with the same uniforms
    noisy = gumbel_softmax(logits, tau=0.5, generator=th.Generator().manual_seed(3))
    uniform = th.rand(logits.shape, generator=th.Generator().manual_seed(3))
    gumbel = -th.log(1e-10 - th.log(uniform + 1e-10))
    th.testing.assert_close(noisy, th.softmax((logits + gumbel) / 0.5, dim=-1))
    # a single type always gets probability 1
    assert th.equal(gumbel_softmax(th.randn(5, 1), tau=0.5), th.ones(5, 1))
