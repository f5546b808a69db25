r"""
Network modules of SAEIR (IJCAI-24): the recurrent actor trunk, one scale of the multi-scale hypergraph (MSHG)
critic, and the running value normaliser.

Reference: ``docs/method.md`` ("The critic"; the "§" numbers below are the sections of the specification it
summarises). Paper: He et al., "SAEIR: Sequentially
Accumulated Entropy Intrinsic Reward for Cooperative Multi-Agent Reinforcement Learning with Sparse Reward",
IJCAI-24.
"""

import itertools
import typing
from typing import Literal

import numpy as np
import torch as th
from torch import nn
from torch.nn import functional as F

from sb3_saeir.common.hypergraph import SCALES, build_incidence, edge_to_node, gumbel_softmax, node_to_edge

_GainName = Literal["relu", "tanh", "leaky_relu", "sigmoid", "selu", "linear"]
_GAIN_NAMES: dict[type[nn.Module], _GainName] = {
    nn.ReLU: "relu",
    nn.Tanh: "tanh",
    nn.LeakyReLU: "leaky_relu",
    nn.Sigmoid: "sigmoid",
    nn.SELU: "selu",
}


def activation_gain(activation_fn: type[nn.Module]) -> float:
    r"""
    Orthogonal-init gain recommended for an activation (``nn.init.calculate_gain``): √2 for ReLU, 5/3 for Tanh.

    :param activation_fn: Activation class.
    :return: The gain (1 for activations without a recommendation).
    """
    return nn.init.calculate_gain(_GAIN_NAMES.get(activation_fn, "linear"))


def check_hidden_size(owner: str, hidden_size: object) -> int:
    r"""
    The width of the hidden layers and GRUs as a Python ``int``, or a one-line ``ValueError`` naming ``hidden_size``
    (torch would fail later, naming ``input_size`` or a tensor size). NumPy integers are accepted.

    :param owner: Class name for the message.
    :param hidden_size: The ``hidden_size`` argument.
    :return: ``int(hidden_size)``.
    """
    if isinstance(hidden_size, bool) or not isinstance(hidden_size, (int, np.integer)) or hidden_size < 1:
        raise ValueError(
            f"{owner}: hidden_size must be a positive integer (the width of every hidden layer and GRU, 64 in the "
            f"paper's code), got {hidden_size!r}; e.g. policy_kwargs=dict(hidden_size=64)."
        )
    return int(hidden_size)


class FCBlock(nn.Sequential):
    r"""
    The authors' ``FC`` block: Linear → ReLU → LayerNorm(out), with PyTorch's default Linear init.

    With ``out_dim == 1`` the LayerNorm returns its bias whatever the input (x - mean = 0): the block is a
    learnable constant and passes no gradient to its input. This is how the released critic behaves (spec §1.8a)
    and it is reproduced on purpose.

    :param in_dim: Input size.
    :param out_dim: Output size.
    """

    def __init__(self, in_dim: int, out_dim: int) -> None:
        super().__init__(nn.Linear(in_dim, out_dim), nn.ReLU(), nn.LayerNorm(out_dim))
        self.out_dim = out_dim

    @property
    def linear(self) -> nn.Linear:
        """The block's Linear layer (its first)."""
        linear = self[0]
        assert isinstance(linear, nn.Linear)
        return linear

    @property
    def norm(self) -> nn.LayerNorm:
        """The block's LayerNorm (its last)."""
        norm = self[2]
        assert isinstance(norm, nn.LayerNorm)
        return norm

    def constant_output(self, *batch_shape: int) -> th.Tensor:
        """The output of a 1-output block for inputs of batch shape ``batch_shape``: the LayerNorm bias, broadcast."""
        assert self.norm.bias is not None
        return self.norm.bias.expand(*batch_shape, 1)

    @property
    def is_constant(self) -> bool:
        """True for a 1-output block: its output is the LayerNorm bias whatever the input."""
        return self.out_dim == 1

    def forward(self, x: th.Tensor) -> th.Tensor:
        if self.is_constant:
            # LayerNorm over one feature maps every input to its bias, so Linear and ReLU cannot change the output and
            # receive exactly zero gradient: skipping them gives the same values and the same parameter updates.
            return self.constant_output(*x.shape[:-1])
        return super().forward(x)


class MLPEncoder(nn.Sequential):
    r"""
    MAPPO's feature encoder (spec §1.2 steps 1-3): LayerNorm(in) → [Linear → act → LayerNorm(hidden)] x n_layers.

    Linear layers: orthogonal init with the gain of ``activation_fn`` (√2 ReLU, 5/3 Tanh), bias 0.
    The authors' unused template block ``fc_h`` is not created.

    :param in_dim: Input size.
    :param hidden_size: Width of every layer.
    :param activation_fn: Activation class (ReLU for GRF, Tanh for Cooperative Navigation).
    :param n_layers: Number of Linear layers (2 = ``layer_N`` 1 in the authors' code).
    """

    def __init__(
        self, in_dim: int, hidden_size: int = 64, activation_fn: type[nn.Module] = nn.Tanh, n_layers: int = 2
    ) -> None:
        layers: list[nn.Module] = [nn.LayerNorm(in_dim)]
        for layer_in in [in_dim] + [hidden_size] * (n_layers - 1):
            linear = nn.Linear(layer_in, hidden_size)
            nn.init.orthogonal_(linear.weight, gain=activation_gain(activation_fn))
            nn.init.zeros_(linear.bias)
            layers += [linear, activation_fn(), nn.LayerNorm(hidden_size)]
        super().__init__(*layers)


class GRULayer(nn.Module):
    r"""
    One-layer GRU with episode resets and an output LayerNorm (MAPPO's ``RNNLayer``, spec §1.2 step 4).

    Before step t the hidden state is multiplied by ``1 - episode_starts[t]``. The GRU runs in one call over each
    stretch of steps without any reset, which gives the same result as a step-by-step loop. Inside ``torch.compile``
    (the algorithms' ``compile`` switch) it runs as that step loop, written out (:meth:`step_loop`) so that the
    compiler fuses each step's gate arithmetic; the same maths up to float rounding.
    GRU weights: orthogonal; biases: 0.

    :param in_dim: Input size.
    :param hidden_size: Hidden size.
    """

    def __init__(self, in_dim: int = 64, hidden_size: int = 64) -> None:
        super().__init__()
        self.gru = nn.GRU(in_dim, hidden_size, num_layers=1)
        for name, param in self.gru.named_parameters():
            if name.startswith("weight"):
                nn.init.orthogonal_(param)
            else:
                nn.init.zeros_(param)
        self.norm = nn.LayerNorm(hidden_size)

    def forward(self, x: th.Tensor, hidden: th.Tensor, episode_starts: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        r"""
        :param x: Input sequence ``(T, B, in_dim)``.
        :param hidden: Hidden state before step 0, ``(B, H)``.
        :param episode_starts: 1 where sequence b starts a new episode at step t, ``(T, B)``.
        :return: LayerNorm'ed outputs ``(T, B, H)`` and the raw last hidden state ``(B, H)``.
        """
        keep = 1.0 - episode_starts.to(x.dtype)  # (T, B)
        if th.compiler.is_compiling():
            return self.step_loop(x, hidden, keep)
        if x.shape[0] == 1:
            # one step (the rollout): no split to find, so no device-to-host sync of the reset steps
            boundaries = [0, 1]
        else:
            # Split the sequence where any sequence restarts (always at t = 0)
            reset_steps = (keep[1:] < 1.0).any(dim=-1).nonzero().squeeze(-1) + 1
            boundaries = [0, *reset_steps.tolist(), x.shape[0]]
        outputs = []
        for start, end in itertools.pairwise(boundaries):
            hidden = hidden * keep[start].unsqueeze(-1)  # (B, H)
            out, hidden_n = self.gru(x[start:end], hidden.unsqueeze(0).contiguous())  # (L, B, H), (1, B, H)
            hidden = hidden_n.squeeze(0)  # (B, H)
            outputs.append(out)
        # one stretch (no reset after t = 0, the usual case): no concatenation copy
        return self.norm(outputs[0] if len(outputs) == 1 else th.cat(outputs)), hidden

    def step_loop(self, x: th.Tensor, hidden: th.Tensor, keep: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        r"""
        The GRU as a loop over steps with ``nn.GRU``'s parameters and formulas (PyTorch's gate order r, z, n), the
        state reset by multiplying it with ``keep[t]`` at every step: no data-dependent split, so ``torch.compile``
        traces it into one graph.

        :param x: Input sequence ``(T, B, in_dim)``.
        :param hidden: Hidden state before step 0, ``(B, H)``.
        :param keep: ``1 - episode_starts``, ``(T, B)``.
        :return: LayerNorm'ed outputs ``(T, B, H)`` and the raw last hidden state ``(B, H)``.
        """
        gru = self.gru
        weight_ih, bias_ih = typing.cast(th.Tensor, gru.weight_ih_l0), typing.cast(th.Tensor, gru.bias_ih_l0)
        weight_hh, bias_hh = typing.cast(th.Tensor, gru.weight_hh_l0), typing.cast(th.Tensor, gru.bias_hh_l0)
        input_gates = F.linear(x, weight_ih, bias_ih)  # (T, B, 3H), every step at once
        outputs = []
        for step in range(x.shape[0]):
            hidden = hidden * keep[step].unsqueeze(-1)  # (B, H)
            hidden_gates = F.linear(hidden, weight_hh, bias_hh)  # (B, 3H)
            input_r, input_z, input_n = input_gates[step].chunk(3, dim=-1)  # 3 x (B, H)
            hidden_r, hidden_z, hidden_n = hidden_gates.chunk(3, dim=-1)  # 3 x (B, H)
            reset = th.sigmoid(input_r + hidden_r)
            update = th.sigmoid(input_z + hidden_z)
            candidate = th.tanh(input_n + reset * hidden_n)
            hidden = candidate + update * (hidden - candidate)  # (1 - z) * n + z * h
            outputs.append(hidden)
        return self.norm(th.stack(outputs)), hidden  # (T, B, H), (B, H)


class ActorNetwork(nn.Module):
    r"""
    Parameter-shared actor trunk (spec §3): MLPEncoder → GRULayer (if ``recurrent``).

    The action head (SB3's ``action_net``) is not part of it.

    :param obs_dim: Size of one agent's observation.
    :param hidden_size: Width of the MLP and of the GRU.
    :param activation_fn: MLP activation class.
    :param recurrent: Whether to add the GRU (the authors' rMAPPO: True).
    """

    def __init__(
        self, obs_dim: int, hidden_size: int = 64, activation_fn: type[nn.Module] = nn.Tanh, recurrent: bool = True
    ) -> None:
        super().__init__()
        self.latent_dim = hidden_size
        self.hidden_size = hidden_size
        self.recurrent = recurrent
        self.mlp = MLPEncoder(obs_dim, hidden_size, activation_fn)
        self.gru = GRULayer(hidden_size, hidden_size) if recurrent else None

    def forward(
        self, obs: th.Tensor, hidden: th.Tensor | None = None, episode_starts: th.Tensor | None = None
    ) -> tuple[th.Tensor, th.Tensor | None]:
        r"""
        :param obs: Observations ``(T, B, obs_dim)``.
        :param hidden: GRU state before step 0, ``(B, H)``; None = zeros. Ignored if not recurrent.
        :param episode_starts: ``(T, B)``, 1 where a new episode starts; None = no reset.
        :return: Latent ``(T, B, H)`` and the new hidden state ``(B, H)`` (None if not recurrent).
        """
        latent = self.mlp(obs)  # (T, B, H)
        if self.gru is None:
            return latent, None
        n_steps, batch_size = obs.shape[:2]
        if hidden is None:
            hidden = latent.new_zeros(batch_size, self.hidden_size)
        if episode_starts is None:
            episode_starts = latent.new_zeros(n_steps, batch_size)
        return self.gru(latent, hidden, episode_starts)


class HypergraphScaleCritic(nn.Module):
    r"""
    One scale of the multi-scale hypergraph (MSHG) critic, as released by the authors (spec §1.2-§1.7).

    Per agent: MLPEncoder → GRULayer gives :math:`h_i`. Per (step, game), over its N agents, with incidence
    :math:`H` of the scale (:func:`~sb3_saeir.common.hypergraph.build_incidence`) and ``FC`` = :class:`FCBlock`:

    .. math::

        x_i = \mathrm{FC}(h_i), \quad u_e = \sum_i H_{e,i} x_i, \quad a_{e,i} = \mathrm{FC}([x_i ; u_e]),
        \quad g_e = \sum_i H_{e,i} \operatorname{softmax}_i(a_{e,\cdot} \odot H_{e,\cdot}) \, x_i,

        z_e = \mathrm{FC}(g_e), \quad w_e = \sigma(\mathrm{FC}(z_e)) \cdot
        \operatorname{GumbelSoftmax}_\tau(\mathrm{FC}(z_e)) \in \mathbb{R}^{T_K},

        m_e = \sum_k w_{e,k} \, \mathrm{FC}^{(k)}\Big(\sum_i H_{e,i} h_i\Big), \quad
        \bar s_i = \mathrm{FC}\Big(\tfrac{1}{N} \Big[\sum_e H_{e,i} m_e ; h_i\Big]\Big), \quad
        v_i = W \bar s_i + b .

    :math:`T_K` = 1 (team), ``n_edge_types`` (group) or N (individual). The 1-output heads (attention, factor,
    team type logit) are constants, as in the released code (spec §1.8a). Values live in the normalised return
    space of this scale's :class:`ValueNorm`. The Gumbel noise is drawn from the global torch RNG.

    :param obs_dim: Size of one agent's critic input.
    :param n_agents: Number of agents N of a game (nodes of every hypergraph).
    :param scale: ``"team"``, ``"group"`` or ``"individual"``.
    :param group_size: Hyperedge size k of the group scale (``num_in_group``); ``>= n_agents`` gives the team
        incidence (with still ``n_edge_types`` types), as in the authors' code.
    :param n_edge_types: Number of edge types of the group scale (``num_group``).
    :param hidden_size: Width of every layer (64 in the authors' code).
    :param activation_fn: Activation class of the MLP encoder.
    :param gumbel_tau: Gumbel-softmax temperature.
    :param recurrent: Whether the encoder has its GRU (the paper's critic: True). ``False``: the feed-forward variant,
        :math:`h_i` is the MLP's output and the critic keeps no state (its states have width 0;
        ``docs/guide/algorithms.md``, "Feed-forward networks").
    """

    def __init__(
        self,
        obs_dim: int,
        n_agents: int,
        scale: str,
        group_size: int = 2,
        n_edge_types: int = 3,
        hidden_size: int = 64,
        activation_fn: type[nn.Module] = nn.Tanh,
        gumbel_tau: float = 0.5,
        recurrent: bool = True,
    ) -> None:
        super().__init__()
        if scale not in SCALES:
            raise ValueError(f"Unknown hypergraph scale {scale!r}, expected one of {SCALES}")
        self.n_agents = n_agents
        self.scale = scale
        self.group_size = group_size
        self.hidden_size = hidden_size
        self.gumbel_tau = gumbel_tau
        self.n_types = {"team": 1, "group": n_edge_types, "individual": n_agents}[scale]
        self.recurrent = recurrent

        self.mlp = MLPEncoder(obs_dim, hidden_size, activation_fn)
        self.gru = GRULayer(hidden_size, hidden_size) if recurrent else None
        self.node2edge_start = FCBlock(hidden_size, hidden_size)
        self.attention = FCBlock(2 * hidden_size, 1)
        self.init_fc = FCBlock(hidden_size, hidden_size)
        self.edge_type = FCBlock(hidden_size, self.n_types)
        self.edge_factor = FCBlock(hidden_size, 1)
        self.edge_aggregation = nn.ModuleList([FCBlock(hidden_size, hidden_size) for _ in range(self.n_types)])
        self.node_end = FCBlock(2 * hidden_size, hidden_size)
        self.value_net = nn.Linear(hidden_size, 1)
        nn.init.orthogonal_(self.value_net.weight, gain=1.0)
        nn.init.zeros_(self.value_net.bias)

    def forward(
        self,
        obs: th.Tensor,
        hidden: th.Tensor,
        episode_starts: th.Tensor,
        gumbel_noise: bool = True,
        gumbel_uniform: th.Tensor | None = None,
    ) -> tuple[th.Tensor, th.Tensor]:
        r"""
        :param obs: Critic inputs ``(T, G, N, obs_dim)`` (G games, N agents).
        :param hidden: GRU states before step 0, ``(G, N, H)`` (``(G, N, 0)`` without the GRU).
        :param episode_starts: ``(T, G, N)``, 1 where a new episode starts.
        :param gumbel_noise: Draw Gumbel noise for the edge types (authors: always); False = plain softmax.
        :param gumbel_uniform: The noise's uniform draws, ``(T * G, *self.gumbel_shape)`` (drawn here when ``None``).
        :return: Values ``(T, G, N)`` and the new GRU states ``(G, N, H)``.
        """
        latent, new_hidden = self.forward_latent(obs, hidden, episode_starts, gumbel_noise, gumbel_uniform)
        return self.value_net(latent).squeeze(-1), new_hidden  # (T, G, N)

    @property
    def gumbel_shape(self) -> tuple[int, int]:
        """``(E, T_K)``: hyperedges and edge types of one hypergraph, the shape of its Gumbel draws."""
        group_as_team = self.scale == "group" and self.group_size >= self.n_agents
        n_edges = 1 if self.scale == "team" or group_as_team else self.n_agents
        return n_edges, self.n_types

    def forward_latent(
        self,
        obs: th.Tensor,
        hidden: th.Tensor,
        episode_starts: th.Tensor,
        gumbel_noise: bool = True,
        gumbel_uniform: th.Tensor | None = None,
    ) -> tuple[th.Tensor, th.Tensor]:
        r"""
        Node representations :math:`\bar s_i` before the value head.

        :param obs: Critic inputs ``(T, G, N, obs_dim)``.
        :param hidden: GRU states ``(G, N, H)``.
        :param episode_starts: ``(T, G, N)``.
        :param gumbel_noise: Whether to draw Gumbel noise.
        :param gumbel_uniform: The noise's uniform draws, ``(T * G, E, T_K)`` (drawn here when ``None``).
        :return: Latent ``(T, G, N, H)`` and the new GRU states ``(G, N, H)``.
        """
        n_steps, n_games, n_agents = obs.shape[:3]
        features, new_hidden = self._encode(obs, hidden, episode_starts)  # (T, G, N, H), (G, N, H)
        nodes = features.reshape(n_steps * n_games, n_agents, self.hidden_size)  # (T*G, N, H)
        latent = self._message_passing(nodes, gumbel_noise, gumbel_uniform)  # (T*G, N, H)
        return latent.reshape(n_steps, n_games, n_agents, self.hidden_size), new_hidden

    def _encode(self, obs: th.Tensor, hidden: th.Tensor, episode_starts: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        r"""
        Per-agent MLP + GRU over the G·N agent sequences (the MLP alone without the GRU).

        :param obs: ``(T, G, N, obs_dim)``.
        :param hidden: ``(G, N, H)`` (``(G, N, 0)`` without the GRU: returned as it is).
        :param episode_starts: ``(T, G, N)``.
        :return: GRU features h ``(T, G, N, H)`` and new states ``(G, N, H)``.
        """
        n_steps, n_games, n_agents = obs.shape[:3]
        if self.gru is None:
            return self.mlp(obs), hidden  # (T, G, N, H), no state
        x = self.mlp(obs).reshape(n_steps, n_games * n_agents, self.hidden_size)  # (T, G*N, H)
        out, last = self.gru(
            x,
            hidden.reshape(n_games * n_agents, self.hidden_size),  # (G*N, H)
            episode_starts.reshape(n_steps, n_games * n_agents),  # (T, G*N)
        )
        features = out.reshape(n_steps, n_games, n_agents, self.hidden_size)  # (T, G, N, H)
        return features, last.reshape(n_games, n_agents, self.hidden_size)  # (G, N, H)

    def _message_passing(self, nodes: th.Tensor, gumbel_noise: bool, gumbel_uniform: th.Tensor | None = None) -> th.Tensor:
        r"""
        One round of hypergraph message passing (spec §1.3-§1.6).

        :param nodes: GRU features h of the N agents of each hypergraph, ``(B, N, H)``.
        :param gumbel_noise: Whether to draw Gumbel noise.
        :param gumbel_uniform: The noise's uniform draws, ``(B, E, T_K)`` (drawn here when ``None``).
        :return: Node representations ``(B, N, H)``.
        """
        incidence = build_incidence(self.scale, nodes, self.group_size)  # (B, E, N)
        edge_weights = self._edge_type_weights(nodes, incidence, gumbel_noise, gumbel_uniform)  # (B, E, T_K)
        # Kept as a product even for H = I: it fixes the order in which autograd sums the gradients reaching h, and
        # the golden runs (Adam on near-zero gradients) are sensitive to the last bit of that sum.
        raw_edges = incidence @ nodes  # (B, E, H), unweighted member sums of h
        if len(self.edge_aggregation) == 1:  # one edge type (team): no stack, no sum over types
            messages = edge_weights * self.edge_aggregation[0](raw_edges)  # (B, E, 1) * (B, E, H)
        else:
            typed = th.stack([fc(raw_edges) for fc in self.edge_aggregation], dim=-2)  # (B, E, T_K, H)
            messages = (edge_weights.unsqueeze(-1) * typed).sum(dim=-2)  # (B, E, H)
        if self.scale == "individual":  # H^T m = m (exactly)
            n_agents = nodes.shape[-2]
            return self.node_end(th.cat([messages, nodes], dim=-1) / n_agents)  # (B, N, 2H) -> (B, N, H)
        return self.node_end(edge_to_node(messages, incidence, nodes))  # (B, N, 2H) -> (B, N, H)

    def _edge_type_weights(
        self, nodes: th.Tensor, incidence: th.Tensor, gumbel_noise: bool, gumbel_uniform: th.Tensor | None = None
    ) -> th.Tensor:
        r"""
        Attention node→edge embedding, then the scaled Gumbel-softmax edge-type weights (spec §1.4-§1.5).

        :param nodes: ``(B, N, H)``.
        :param incidence: ``(B, E, N)``.
        :param gumbel_noise: Whether to draw Gumbel noise.
        :param gumbel_uniform: The noise's uniform draws, ``(B, E, T_K)`` (drawn here when ``None``).
        :return: Edge-type weights :math:`w_e = \sigma_e \pi_e`, ``(B, E, T_K)``.
        """
        n_batch = nodes.shape[0]
        n_edges, n_agents = incidence.shape[-2:]
        if self.edge_type.is_constant and self.edge_factor.is_constant:
            # One edge type (the team scale): both heads are 1-output blocks, i.e. constants (their LayerNorm biases),
            # so the node-to-edge embedding below changes neither the weights nor any gradient; skip it. The Gumbel
            # noise is still drawn (same shape), which keeps the global RNG stream of the full computation.
            type_logits = self.edge_type.constant_output(n_batch, n_edges)  # (B, E, 1)
            type_probs = gumbel_softmax(type_logits, self.gumbel_tau, noise=gumbel_noise, uniform=gumbel_uniform)  # all 1
            return th.sigmoid(self.edge_factor.constant_output(n_batch, n_edges)) * type_probs  # (B, E, 1)
        x = self.node2edge_start(nodes)  # (B, N, H)
        if self.attention.is_constant:  # the released 1-output head (spec §1.8a): same logit for every pair
            logits = self.attention.constant_output(n_batch, n_edges, n_agents).squeeze(-1)  # (B, E, N)
        else:
            edges_init = incidence @ x  # (B, E, H)
            pairs = th.cat(
                [
                    x.unsqueeze(-3).expand(-1, n_edges, -1, -1),  # (B, E, N, H): x_i
                    edges_init.unsqueeze(-2).expand(-1, -1, n_agents, -1),  # (B, E, N, H): u_e
                ],
                dim=-1,
            )  # (B, E, N, 2H)
            logits = self.attention(pairs).squeeze(-1)  # (B, E, N)
        if self.scale == "individual":
            # H = I: the softmax weights are diagonal, so the weighted member sum is the diagonal weight times x_e
            weights = th.softmax(logits * incidence, dim=-1) * incidence  # (B, N, N)
            edges = self.init_fc(weights.diagonal(dim1=-2, dim2=-1).unsqueeze(-1) * x)  # (B, N, 1) * (B, N, H)
        else:
            edges = self.init_fc(node_to_edge(x, incidence, logits))  # (B, E, H)
        type_logits = self.edge_type(edges)  # (B, E, T_K)
        type_probs = gumbel_softmax(type_logits, self.gumbel_tau, noise=gumbel_noise, uniform=gumbel_uniform)
        return th.sigmoid(self.edge_factor(edges)) * type_probs  # (B, E, 1) * (B, E, T_K)


class ValueNorm(nn.Module):
    r"""
    Running normaliser of the return targets of one scale (MAPPO's ``ValueNorm``, spec §1.9).

    Exponential moving averages with weight :math:`\beta` of the batch mean, of the batch mean of squares and of
    the debiasing term (EMA of 1), all over every element of the batch:

    .. math::

        \mu = \frac{m}{\max(d, \epsilon)}, \quad
        \sigma^2 = \max\Big(\frac{s}{\max(d, \epsilon)} - \mu^2, 10^{-2}\Big), \quad
        \operatorname{normalize}(x) = \frac{x - \mu}{\sigma} .

    A fresh normaliser has :math:`\mu = 0`, :math:`\sigma = 0.1`. The paper says "PopArt"; the released code
    uses this (the output layer is not rescaled).

    :param beta: EMA weight.
    :param epsilon: Lower clamp of the debiasing term.
    :param min_var: Variance floor.
    """

    running_mean: th.Tensor
    running_mean_sq: th.Tensor
    debiasing_term: th.Tensor

    def __init__(self, beta: float = 0.99999, epsilon: float = 1e-5, min_var: float = 1e-2) -> None:
        super().__init__()
        self.beta = beta
        self.epsilon = epsilon
        self.min_var = min_var
        self.register_buffer("running_mean", th.zeros((), dtype=th.float64))
        self.register_buffer("running_mean_sq", th.zeros((), dtype=th.float64))
        self.register_buffer("debiasing_term", th.zeros((), dtype=th.float64))

    @th.no_grad()
    def update(self, x: th.Tensor) -> None:
        r"""
        :param x: A batch of return targets (any shape; all elements are pooled).
        """
        x = x.detach().to(self.running_mean.dtype)
        self.running_mean.mul_(self.beta).add_((1.0 - self.beta) * x.mean())
        self.running_mean_sq.mul_(self.beta).add_((1.0 - self.beta) * (x**2).mean())
        self.debiasing_term.mul_(self.beta).add_(1.0 - self.beta)

    def running_mean_var(self) -> tuple[th.Tensor, th.Tensor]:
        r"""
        :return: Debiased running mean and variance (0-d float64 tensors).
        """
        debias = self.debiasing_term.clamp(min=self.epsilon)
        mean = self.running_mean / debias
        var = (self.running_mean_sq / debias - mean**2).clamp(min=self.min_var)
        return mean, var

    def normalize(self, x: th.Tensor) -> th.Tensor:
        r"""
        :param x: Values in return space.
        :return: :math:`(x - \mu) / \sigma`, same dtype as ``x``.
        """
        mean, var = self.running_mean_var()
        return (x - mean.to(x.dtype)) / th.sqrt(var).to(x.dtype)

    def denormalize(self, x: th.Tensor) -> th.Tensor:
        r"""
        :param x: Values in normalised space.
        :return: :math:`x \sigma + \mu`, same dtype as ``x``.
        """
        mean, var = self.running_mean_var()
        return x * th.sqrt(var).to(x.dtype) + mean.to(x.dtype)


class RecurrentValueCritic(nn.Module):
    r"""
    MAPPO's recurrent critic (one scale): MLPEncoder → GRULayer → Linear(H→1) value head, on either the joint
    observation of a game or each agent's own observation.

    - ``critic_input="joint"`` (MAPPO on MPE): every agent's node gets the concatenation of all N agents'
      observations of its game, so the value is the same for every agent; it is computed once per game.
    - ``critic_input="own"`` (MAPPO on football, where the 115-d observation is already global): each agent's own
      observation.

    Spectral normalisation (SN-MAPPO, Mehta et al. 2023) wraps the chosen Linear layers with
    ``torch.nn.utils.parametrizations.spectral_norm``: ``"output"`` (the value head, the paper's ``critic_spectral="nny"``)
    and/or ``"hidden"`` (the encoder's Linear layers).

    :param obs_dim: one agent's observation size d
    :param n_agents: agents per game N
    :param critic_input: ``"joint"`` or ``"own"``
    :param hidden_size: width of the encoder and the GRU
    :param activation_fn: encoder activation
    :param spectral_norm: layers to normalise, any of ``("output", "hidden")``
    :param recurrent: whether the encoder has its GRU (MAPPO's recurrent critic: True); ``False``: MLP → value head,
        no state (width 0; ``docs/guide/algorithms.md``, "Feed-forward networks")
    """

    def __init__(
        self,
        obs_dim: int,
        n_agents: int,
        critic_input: str = "joint",
        hidden_size: int = 64,
        activation_fn: type[nn.Module] = nn.Tanh,
        spectral_norm: tuple[str, ...] = (),
        recurrent: bool = True,
    ) -> None:
        super().__init__()
        if critic_input not in ("joint", "own"):
            raise ValueError(f"critic_input must be 'joint' or 'own', got {critic_input!r}.")
        unknown = [name for name in spectral_norm if name not in ("output", "hidden")]
        if unknown:
            raise ValueError(f"spectral_norm entries must be 'output' or 'hidden', got {unknown}.")
        self.n_agents = n_agents
        self.critic_input = critic_input
        self.hidden_size = hidden_size
        self.recurrent = recurrent
        in_dim = obs_dim * n_agents if critic_input == "joint" else obs_dim
        self.mlp = MLPEncoder(in_dim, hidden_size, activation_fn)
        self.gru = GRULayer(hidden_size, hidden_size) if recurrent else None
        self.value_net = nn.Linear(hidden_size, 1)
        nn.init.orthogonal_(self.value_net.weight, gain=1.0)
        nn.init.zeros_(self.value_net.bias)
        if "hidden" in spectral_norm:
            for module in self.mlp:
                if isinstance(module, nn.Linear):
                    nn.utils.parametrizations.spectral_norm(module)
        if "output" in spectral_norm:
            nn.utils.parametrizations.spectral_norm(self.value_net)

    def forward(
        self,
        obs: th.Tensor,
        hidden: th.Tensor,
        episode_starts: th.Tensor,
        gumbel_noise: bool = True,
        gumbel_uniform: th.Tensor | None = None,
    ) -> tuple[th.Tensor, th.Tensor]:
        r"""
        :param obs: ``(T, G, N, d)``
        :param hidden: ``(G, N, H)`` GRU states (identical over agents for the joint input); ``(G, N, 0)`` without the
            GRU (returned as it is)
        :param episode_starts: ``(T, G, N)``
        :param gumbel_noise: unused (same signature as :class:`HypergraphScaleCritic`)
        :param gumbel_uniform: unused (same signature as :class:`HypergraphScaleCritic`)
        :return: values ``(T, G, N)`` and new states ``(G, N, H)``
        """
        n_steps, n_games, n_agents, _ = obs.shape
        if self.gru is None:
            return self._feed_forward_values(obs), hidden
        if self.critic_input == "joint":
            joint = obs.reshape(n_steps, n_games, -1)  # (T, G, N * d)
            latent, new_hidden = self.gru(self.mlp(joint), hidden[:, 0], episode_starts[..., 0])  # (T, G, H), (G, H)
            values = self.value_net(latent).expand(n_steps, n_games, n_agents)  # (T, G, 1) -> (T, G, N)
            return values, new_hidden.unsqueeze(1).expand(n_games, n_agents, self.hidden_size).contiguous()
        flat = obs.reshape(n_steps, n_games * n_agents, -1)  # (T, G * N, d)
        flat_hidden = hidden.reshape(n_games * n_agents, -1)  # (G * N, H)
        flat_starts = episode_starts.reshape(n_steps, n_games * n_agents)  # (T, G * N)
        latent, new_hidden = self.gru(self.mlp(flat), flat_hidden, flat_starts)
        values = self.value_net(latent).reshape(n_steps, n_games, n_agents)  # (T, G * N, 1) -> (T, G, N)
        return values, new_hidden.reshape(n_games, n_agents, -1)

    def _feed_forward_values(self, obs: th.Tensor) -> th.Tensor:
        r"""
        Values without the GRU: the encoder and the value head, once per game for the joint input.

        :param obs: ``(T, G, N, d)``
        :return: values ``(T, G, N)``
        """
        n_steps, n_games, n_agents, _ = obs.shape
        if self.critic_input == "joint":
            joint = obs.reshape(n_steps, n_games, -1)  # (T, G, N * d)
            return self.value_net(self.mlp(joint)).expand(n_steps, n_games, n_agents)  # (T, G, 1) -> (T, G, N)
        return self.value_net(self.mlp(obs)).squeeze(-1)  # (T, G, N, 1) -> (T, G, N)
