import math

import pytest
import torch as th
from torch import nn

from sb3_saeir.common.hypergraph import build_incidence, edge_to_node, gumbel_softmax, node_to_edge
from sb3_saeir.common.torch_layers import ActorNetwork, FCBlock, GRULayer, HypergraphScaleCritic, MLPEncoder, ValueNorm

GRF_OBS_DIM = 115


def _n_params(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


def test_actor_parameter_count():
    # spec §1.12: 42,681 for the authors' actor, minus the unused `fc_h` block (4,288)
    actor = ActorNetwork(GRF_OBS_DIM, activation_fn=nn.ReLU)
    assert _n_params(actor) + _n_params(nn.Linear(64, 19)) == 42_681 - 4_288 == 38_393


@pytest.mark.parametrize(
    "scale, n_agents, expected",
    [
        ("team", 3, 63_024 - 4_288),
        ("team", 4, 63_024 - 4_288),
        ("group", 3, 71_734 - 4_288),
        ("group", 4, 71_734 - 4_288),
        ("individual", 3, 71_734 - 4_288),
        ("individual", 4, 76_089 - 4_288),
    ],
)
def test_critic_parameter_count(scale, n_agents, expected):
    critic = HypergraphScaleCritic(GRF_OBS_DIM, n_agents, scale, activation_fn=nn.ReLU)
    assert _n_params(critic) == expected
    assert {"team": 58_736, "group": 67_446, "individual": 67_446 if n_agents == 3 else 71_801}[scale] == expected


@pytest.mark.parametrize("activation_fn, gain", [(nn.ReLU, math.sqrt(2.0)), (nn.Tanh, 5.0 / 3.0)])
def test_mlp_encoder_structure_and_init(activation_fn, gain):
    encoder = MLPEncoder(10, hidden_size=8, activation_fn=activation_fn)
    linears = [m for m in encoder if isinstance(m, nn.Linear)]
    assert len(linears) == 2
    assert isinstance(encoder[0], nn.LayerNorm) and encoder[0].normalized_shape == (10,)
    for linear in linears:
        w = linear.weight.detach()  # (8, in): rows orthonormal times gain
        th.testing.assert_close(w @ w.T, gain**2 * th.eye(8), atol=1e-5, rtol=0)
        assert th.all(linear.bias == 0)
    assert sum(isinstance(m, activation_fn) for m in encoder) == 2


def _gru_cell_by_hand(gru: nn.GRU, x: th.Tensor, h: th.Tensor) -> th.Tensor:
    """h' = (1 - z) n + z h with PyTorch's gate order (r, z, n)."""
    w_ir, w_iz, w_in = gru.weight_ih_l0.chunk(3)
    w_hr, w_hz, w_hn = gru.weight_hh_l0.chunk(3)
    b_ir, b_iz, b_in = gru.bias_ih_l0.chunk(3)
    b_hr, b_hz, b_hn = gru.bias_hh_l0.chunk(3)
    r = th.sigmoid(x @ w_ir.T + b_ir + h @ w_hr.T + b_hr)
    z = th.sigmoid(x @ w_iz.T + b_iz + h @ w_hz.T + b_hz)
    n = th.tanh(x @ w_in.T + b_in + r * (h @ w_hn.T + b_hn))
    return (1 - z) * n + z * h


def test_gru_layer_init():
    layer = GRULayer(6, 5)
    assert all(th.all(p == 0) for name, p in layer.gru.named_parameters() if name.startswith("bias"))
    w = layer.gru.weight_hh_l0.detach()  # (15, 5): orthonormal columns
    th.testing.assert_close(w.T @ w, th.eye(5), atol=1e-5, rtol=0)


def test_gru_layer_segments_equal_step_loop():
    gen = th.Generator().manual_seed(0)
    layer = GRULayer(6, 5).double()
    with th.no_grad():
        for param in layer.gru.parameters():  # non-zero biases make the check stricter
            param.normal_(0.0, 0.5, generator=gen)
        layer.norm.weight.normal_(1.0, 0.2, generator=gen)
        layer.norm.bias.normal_(0.0, 0.2, generator=gen)
    n_steps, batch = 12, 4
    x = th.randn(n_steps, batch, 6, generator=gen, dtype=th.float64)
    hidden0 = th.randn(batch, 5, generator=gen, dtype=th.float64)
    starts = (th.rand(n_steps, batch, generator=gen) < 0.2).double()
    starts[0, 1] = 1.0
    starts[5, 2] = 1.0
    out, last = layer(x, hidden0, starts)

    h = hidden0
    expected = []
    for t in range(n_steps):
        h = _gru_cell_by_hand(layer.gru, x[t], h * (1.0 - starts[t]).unsqueeze(-1))
        expected.append(nn.functional.layer_norm(h, (5,), layer.norm.weight, layer.norm.bias))
    th.testing.assert_close(out, th.stack(expected), atol=1e-6, rtol=0)
    th.testing.assert_close(last, h, atol=1e-6, rtol=0)


def test_actor_network_shapes():
    actor = ActorNetwork(7, hidden_size=8)
    latent, hidden = actor(th.randn(5, 3, 7), None, th.zeros(5, 3))
    assert latent.shape == (5, 3, 8) and hidden.shape == (3, 8)
    latent_default, _ = actor(th.zeros(5, 3, 7))
    assert latent_default.shape == (5, 3, 8)
    feedforward = ActorNetwork(7, hidden_size=8, recurrent=False)
    obs = th.randn(2, 3, 7)
    latent, hidden = feedforward(obs, None, None)
    assert hidden is None
    th.testing.assert_close(latent, feedforward.mlp(obs))
    assert not any(isinstance(m, nn.GRU) for m in feedforward.modules())


def _critic_inputs(n_steps: int, n_games: int, n_agents: int, obs_dim: int = 9, seed: int = 0):
    gen = th.Generator().manual_seed(seed)
    obs = th.randn(n_steps, n_games, n_agents, obs_dim, generator=gen)
    hidden = th.randn(n_games, n_agents, 16, generator=gen)
    starts = (th.rand(n_steps, n_games, 1, generator=gen) < 0.2).float().expand(-1, -1, n_agents).clone()
    return obs, hidden, starts


def _small_critic(scale: str, n_agents: int = 3, **kwargs) -> HypergraphScaleCritic:
    return HypergraphScaleCritic(9, n_agents, scale, hidden_size=16, **kwargs)


@pytest.mark.parametrize("scale", ["team", "group", "individual"])
def test_hypergraph_scale_critic_deterministic_without_gumbel_noise(scale):
    critic = _small_critic(scale)
    obs, hidden, starts = _critic_inputs(4, 2, 3)
    values, new_hidden = critic(obs, hidden, starts, gumbel_noise=False)
    assert values.shape == (4, 2, 3) and new_hidden.shape == (2, 3, 16)
    values_again, _ = critic(obs, hidden, starts, gumbel_noise=False)
    assert th.equal(values, values_again)
    noisy_a, _ = critic(obs, hidden, starts)
    noisy_b, _ = critic(obs, hidden, starts)
    if scale == "team":  # one edge type: the Gumbel-softmax is identically 1 (spec §1.8b)
        assert th.equal(noisy_a, noisy_b)
    else:
        assert not th.allclose(noisy_a, noisy_b)


@pytest.mark.parametrize("scale", ["team", "group", "individual"])
def test_hypergraph_scale_critic_permutation_equivariant(scale):
    critic = _small_critic(scale, n_agents=4)
    obs, hidden, starts = _critic_inputs(3, 2, 4, seed=1)
    perm = th.tensor([2, 0, 3, 1])
    values, new_hidden = critic(obs, hidden, starts, gumbel_noise=False)
    values_p, new_hidden_p = critic(obs[:, :, perm], hidden[:, perm], starts[:, :, perm], gumbel_noise=False)
    th.testing.assert_close(values_p, values[:, :, perm], atol=1e-5, rtol=1e-5)
    th.testing.assert_close(new_hidden_p, new_hidden[:, perm], atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("scale", ["team", "group", "individual"])
def test_hypergraph_scale_critic_sequence_equals_step_by_step(scale):
    critic = _small_critic(scale)
    obs, hidden, starts = _critic_inputs(10, 2, 3, seed=2)
    starts[4, 1] = 1.0  # at least one reset inside the sequence
    values, last_hidden = critic(obs, hidden, starts, gumbel_noise=False)
    h = hidden
    step_values = []
    for t in range(10):
        v, h = critic(obs[t : t + 1], h, starts[t : t + 1], gumbel_noise=False)
        step_values.append(v)
    th.testing.assert_close(values, th.cat(step_values), atol=1e-5, rtol=1e-5)
    th.testing.assert_close(last_hidden, h, atol=1e-5, rtol=1e-5)


def test_hypergraph_scale_critic_group_size_at_least_n_agents():
    critic = _small_critic("group", n_agents=3, group_size=3, n_edge_types=3)
    assert critic.n_types == 3
    obs, hidden, starts = _critic_inputs(2, 2, 3)
    values, _ = critic(obs, hidden, starts, gumbel_noise=False)
    assert values.shape == (2, 2, 3) and th.all(th.isfinite(values))
    with pytest.raises(ValueError, match="Unknown hypergraph scale"):
        _small_critic("idv")


def test_single_output_fc_heads_are_constant():
    # spec §1.8a: LayerNorm over one output returns its bias, whatever the input
    block = FCBlock(128, 1)
    with th.no_grad():
        block[2].bias.fill_(0.37)
    x = th.randn(50, 128, requires_grad=True)
    out = block(x)
    th.testing.assert_close(out, th.full((50, 1), 0.37))
    # the shortcut equals the full Linear -> ReLU -> LayerNorm path, which passes exactly zero gradient to its input
    # and to the Linear layer, so skipping that path changes neither values nor parameter updates
    full = nn.Sequential.forward(block, x)
    th.testing.assert_close(full, out)
    full.sum().backward()
    assert th.all(x.grad == 0)
    assert th.all(block[0].weight.grad == 0) and th.all(block[0].bias.grad == 0)
    critic = _small_critic("team")
    for head in (critic.attention, critic.edge_factor, critic.edge_type):
        outputs = head(th.randn(20, head[0].in_features) * 5.0)
        assert th.all(outputs == outputs[0])
    multi = _small_critic("group").edge_type(th.randn(20, 16))
    assert not th.all(multi == multi[0])


@pytest.mark.parametrize("beta", [0.9, 0.99999])
def test_value_norm_debiased_ema(beta):
    norm = ValueNorm(beta=beta)
    batches = [[1.0, 2.0, 3.0, 4.0], [-1.0, 0.5], [10.0, 6.0, -2.0]]
    mean = mean_sq = debias = 0.0
    for batch in batches:
        norm.update(th.tensor(batch, dtype=th.float32).reshape(-1, 1))
        mean = beta * mean + (1 - beta) * (sum(batch) / len(batch))
        mean_sq = beta * mean_sq + (1 - beta) * (sum(b * b for b in batch) / len(batch))
        debias = beta * debias + (1 - beta) * 1.0
    expected_mean = mean / max(debias, 1e-5)
    expected_var = max(mean_sq / max(debias, 1e-5) - expected_mean**2, 1e-2)
    got_mean, got_var = norm.running_mean_var()
    assert got_mean.item() == pytest.approx(expected_mean, rel=1e-9, abs=1e-9)
    assert got_var.item() == pytest.approx(expected_var, rel=1e-7)
    x = th.tensor([[0.5], [3.0], [-7.0]])
    expected = [(v - expected_mean) / math.sqrt(expected_var) for v in (0.5, 3.0, -7.0)]
    th.testing.assert_close(norm.normalize(x).flatten(), th.tensor(expected))
    th.testing.assert_close(norm.denormalize(norm.normalize(x)), x)
    assert norm.normalize(x).dtype == th.float32


def test_value_norm_fresh_and_state_dict():
    norm = ValueNorm()
    mean, var = norm.running_mean_var()
    assert mean.item() == 0.0
    assert math.sqrt(var.item()) == pytest.approx(0.1)
    th.testing.assert_close(norm.normalize(th.tensor([0.3])), th.tensor([3.0]))
    assert set(norm.state_dict()) == {"running_mean", "running_mean_sq", "debiasing_term"}


def _reference_critic_values(critic: HypergraphScaleCritic, h: th.Tensor) -> th.Tensor:
    """Spec §1.3-§1.7 written with explicit loops over one hypergraph: h (N, H) GRU features -> values (N,)."""
    n_agents = h.shape[0]
    if critic.scale == "team" or (critic.scale == "group" and critic.group_size >= n_agents):
        incidence = [[1.0] * n_agents]
    elif critic.scale == "individual":
        incidence = [[float(i == j) for j in range(n_agents)] for i in range(n_agents)]
    else:  # top-k cosine neighbours, node i included
        incidence = []
        for i in range(n_agents):
            cos = [(th.dot(h[i], h[j]) / (h[i].norm() * h[j].norm())).item() for j in range(n_agents)]
            others = sorted((j for j in range(n_agents) if j != i), key=lambda j: -cos[j])[: critic.group_size - 1]
            incidence.append([float(j == i or j in others) for j in range(n_agents)])
    n_edges = len(incidence)
    x = [critic.node2edge_start(h[i]) for i in range(n_agents)]
    values = []
    messages = []
    for e in range(n_edges):
        u = sum(incidence[e][i] * x[i] for i in range(n_agents))
        logits = [critic.attention(th.cat([x[i], u])).item() * incidence[e][i] for i in range(n_agents)]
        alpha = [incidence[e][i] * math.exp(logits[i]) / sum(math.exp(a) for a in logits) for i in range(n_agents)]
        z = critic.init_fc(sum(alpha[i] * x[i] for i in range(n_agents)))
        type_probs = th.softmax(critic.edge_type(z) / critic.gumbel_tau, dim=-1)
        factor = th.sigmoid(critic.edge_factor(z))
        raw = sum(incidence[e][i] * h[i] for i in range(n_agents))  # unweighted sum of GRU features
        messages.append(sum(factor * type_probs[k] * critic.edge_aggregation[k](raw) for k in range(critic.n_types)))
    for i in range(n_agents):
        incoming = sum(incidence[e][i] * messages[e] for e in range(n_edges))
        node_input = th.cat([incoming, h[i]]) / n_agents
        values.append(critic.value_net(critic.node_end(node_input)).squeeze(-1))
    return th.stack(values)


@pytest.mark.parametrize(
    "scale, n_agents, group_size", [("team", 3, 2), ("group", 4, 2), ("group", 4, 3), ("group", 3, 3), ("individual", 3, 2)]
)
def test_hypergraph_scale_critic_matches_hand_written_reference(scale, n_agents, group_size):
    critic = _small_critic(scale, n_agents=n_agents, group_size=group_size).double()
    with th.no_grad():  # random LayerNorm affine parameters make every path visible
        for module in critic.modules():
            if isinstance(module, nn.LayerNorm):
                module.weight.normal_(1.0, 0.3)
                module.bias.normal_(0.0, 0.3)
    obs, hidden, starts = _critic_inputs(1, 2, n_agents, seed=3)
    obs, hidden = obs.double(), hidden.double()
    with th.no_grad():
        values, _ = critic(obs, hidden, starts, gumbel_noise=False)
        gru_features, _ = critic.gru(
            critic.mlp(obs).reshape(1, 2 * n_agents, 16), hidden.reshape(2 * n_agents, 16), starts.reshape(1, -1)
        )
        gru_features = gru_features.reshape(2, n_agents, 16)
        for game in range(2):
            th.testing.assert_close(values[0, game], _reference_critic_values(critic, gru_features[game]), atol=1e-10, rtol=0)


def _generic_message_passing(critic: HypergraphScaleCritic, nodes: th.Tensor, gumbel_noise: bool) -> th.Tensor:
    """The critic's message passing as first written, every module run on every hypergraph (no shortcut):
    node-to-edge attention for every scale, the incidence products for H = I, the edge types as a list of modules.

    :param critic: the critic whose modules to run
    :param nodes: GRU features ``(B, N, H)``
    :param gumbel_noise: draw Gumbel noise (from the global RNG, in the same order as the critic)
    :return: node representations ``(B, N, H)``
    """
    incidence = build_incidence(critic.scale, nodes, critic.group_size)  # (B, E, N)
    x = critic.node2edge_start(nodes)  # (B, N, H)
    edges_init = incidence @ x  # (B, E, H)
    n_edges, n_agents = incidence.shape[-2:]
    pairs = th.cat(
        [x.unsqueeze(-3).expand(-1, n_edges, -1, -1), edges_init.unsqueeze(-2).expand(-1, -1, n_agents, -1)], dim=-1
    )  # (B, E, N, 2H)
    logits = critic.attention(pairs).squeeze(-1)  # (B, E, N)
    edges = critic.init_fc(node_to_edge(x, incidence, logits))  # (B, E, H)
    type_probs = gumbel_softmax(critic.edge_type(edges), critic.gumbel_tau, noise=gumbel_noise)  # (B, E, T_K)
    edge_weights = th.sigmoid(critic.edge_factor(edges)) * type_probs  # (B, E, T_K)
    raw_edges = incidence @ nodes  # (B, E, H)
    typed = th.stack([fc(raw_edges) for fc in critic.edge_aggregation], dim=-2)  # (B, E, T_K, H)
    messages = (edge_weights.unsqueeze(-1) * typed).sum(dim=-2)  # (B, E, H)
    return critic.node_end(edge_to_node(messages, incidence, nodes))  # (B, N, H)


@pytest.mark.parametrize(
    "scale, n_agents, group_size, n_edge_types",
    [("team", 3, 2, 3), ("group", 3, 2, 3), ("group", 4, 3, 3), ("group", 3, 2, 1), ("individual", 3, 2, 3)],
)
@pytest.mark.parametrize("gumbel_noise", [True, False])
def test_hypergraph_scale_critic_shortcuts_match_generic_path(scale, n_agents, group_size, n_edge_types, gumbel_noise):
    # the shortcuts (team: no node-to-edge path; H = I: diagonal attention and messages; no unused u_e product) give
    # the values, the gradients of every parameter and the global RNG stream of the generic computation
    critic = _small_critic(scale, n_agents=n_agents, group_size=group_size, n_edge_types=n_edge_types)
    with th.no_grad():  # random LayerNorm affine parameters make every path visible
        for module in critic.modules():
            if isinstance(module, nn.LayerNorm):
                module.weight.normal_(1.0, 0.3)
                module.bias.normal_(0.0, 0.3)
    obs, hidden, starts = _critic_inputs(5, 4, n_agents, seed=5)
    weights = th.randn(5, 4, n_agents)

    def run(message_passing) -> tuple[th.Tensor, dict[str, th.Tensor | None], th.Tensor]:
        critic.zero_grad(set_to_none=True)
        th.manual_seed(11)
        features, _ = critic._encode(obs, hidden, starts)  # (T, G, N, H)
        nodes = features.reshape(-1, n_agents, 16)  # (T*G, N, H)
        values = critic.value_net(message_passing(nodes)).reshape(5, 4, n_agents)  # (T*G, N, 1) -> (T, G, N)
        (values * weights).sum().backward()
        grads = {name: None if p.grad is None else p.grad.clone() for name, p in critic.named_parameters()}
        return values.detach(), grads, th.rand(3)  # the next draw checks that the RNG stream is the same

    fast_values, fast_grads, fast_draw = run(lambda nodes: critic._message_passing(nodes, gumbel_noise))
    ref_values, ref_grads, ref_draw = run(lambda nodes: _generic_message_passing(critic, nodes, gumbel_noise))
    th.testing.assert_close(fast_values, ref_values, atol=1e-5, rtol=1e-5)
    assert th.equal(fast_draw, ref_draw)
    for name, ref_grad in ref_grads.items():
        fast_grad = fast_grads[name]
        if ref_grad is None or fast_grad is None:  # a skipped module must have had no gradient path at all
            assert ref_grad is None or th.all(ref_grad == 0), name
            assert fast_grad is None or th.all(fast_grad == 0), name
            continue
        th.testing.assert_close(fast_grad, ref_grad, atol=1e-5, rtol=1e-5, msg=name)


@pytest.mark.parametrize("n_steps", [1, 6])
def test_gru_layer_one_stretch_and_one_step_paths(n_steps):
    # T = 1 (rollout: no reset search) and a sequence without resets after t = 0 (no concatenation) equal a step loop
    layer = GRULayer(5, 7)
    x = th.randn(n_steps, 4, 5)
    hidden = th.randn(4, 7)
    starts = th.zeros(n_steps, 4)
    starts[0, 1] = 1.0
    out, last = layer(x, hidden, starts)
    h = hidden * (1.0 - starts[0]).unsqueeze(-1)
    steps = []
    for t in range(n_steps):
        step_out, h_n = layer.gru(x[t : t + 1], h.unsqueeze(0))
        h = h_n.squeeze(0)
        steps.append(step_out)
    th.testing.assert_close(out, layer.norm(th.cat(steps)), atol=1e-6, rtol=1e-5)
    th.testing.assert_close(last, h, atol=1e-6, rtol=1e-5)
