r"""
Stateless tensor functions of the multi-scale hypergraph (MSHG) critic of SAEIR (IJCAI-24).

Incidence matrices are **edge-major**, as in the authors' code: :math:`H \in \{0, 1\}^{E \times N}` with
:math:`H_{e,i} = 1` iff node (agent) :math:`i` belongs to hyperedge :math:`e` (the paper's :math:`H` is the
transpose). Batched tensors are ``(B, E, N)``; ``B`` is any number of leading batch axes.
Reference: ``docs/method.md`` ("The critic"; the "§" numbers below are the sections of the specification it
summarises).
"""

import torch as th
from torch.nn import functional as F

SCALES = ("team", "group", "individual")


def team_incidence(
    n_agents: int,
    batch_shape: tuple[int, ...] = (),
    device: th.device | str | None = None,
    dtype: th.dtype = th.float32,
) -> th.Tensor:
    r"""
    Team scale: a single hyperedge containing every agent, :math:`H = \mathbf{1}_{1 \times N}`.

    :param n_agents: Number of agents N.
    :param batch_shape: Leading batch shape.
    :param device: Device of the result.
    :param dtype: Dtype of the result.
    :return: All-ones incidence of shape ``(*batch_shape, 1, N)`` (a broadcast view: do not modify in place).
    """
    return th.ones(1, n_agents, device=device, dtype=dtype).expand(*batch_shape, 1, n_agents)


def individual_incidence(
    n_agents: int,
    batch_shape: tuple[int, ...] = (),
    device: th.device | str | None = None,
    dtype: th.dtype = th.float32,
) -> th.Tensor:
    r"""
    Individual scale: one hyperedge per agent containing only that agent, :math:`H = I_N`.

    :param n_agents: Number of agents N.
    :param batch_shape: Leading batch shape.
    :param device: Device of the result.
    :param dtype: Dtype of the result.
    :return: Identity incidence of shape ``(*batch_shape, N, N)`` (a broadcast view: do not modify in place).
    """
    return th.eye(n_agents, device=device, dtype=dtype).expand(*batch_shape, n_agents, n_agents)


@th.no_grad()
def group_incidence(node_features: th.Tensor, group_size: int) -> th.Tensor:
    r"""
    Group scale: one hyperedge centred on every agent, made of its ``group_size`` most similar agents.

    With the cosine affinity :math:`C_{ij} = \langle h_i, h_j \rangle / (\lVert h_i \rVert \lVert h_j \rVert)`,
    row :math:`i` of :math:`H` is the indicator of the top-:math:`k` entries of :math:`C_{i,\cdot}`
    (:math:`k` = ``group_size``), which always include :math:`i` itself: the diagonal is set to :math:`+\infty`
    before the top-k, so that ties with an identical teammate (:math:`C_{ij} = C_{ii} = 1`) cannot push
    :math:`i` out of its own edge (the authors' plain top-k would break such ties arbitrarily). Hyperedges may
    coincide. The incidence is rebuilt from the current features at every call; no gradient flows through it.

    If ``group_size >= N`` the authors' code silently uses the team incidence (one all-ones edge), and so does
    this function: the result then has shape ``(B, 1, N)`` (spec §1.3).

    :param node_features: Node features h of shape ``(B, N, F)``.
    :param group_size: Hyperedge size k (``num_in_group`` in the authors' code, default 2).
    :return: Incidence of shape ``(B, N, N)``, or ``(B, 1, N)`` if ``group_size >= N``.
    """
    n_agents = node_features.shape[-2]
    if group_size < 1:
        raise ValueError(f"`group_size` must be >= 1, got {group_size}")
    if group_size >= n_agents:
        return team_incidence(n_agents, tuple(node_features.shape[:-2]), node_features.device, node_features.dtype)
    unit = F.normalize(node_features, dim=-1)  # (B, N, F), rows of unit length
    affinity = unit @ unit.transpose(-1, -2)  # (B, N, N) cosine similarities
    affinity.diagonal(dim1=-2, dim2=-1).fill_(float("inf"))  # node i always belongs to its own edge
    members = affinity.topk(group_size, dim=-1).indices  # (B, N, k)
    return th.zeros_like(affinity).scatter_(-1, members, 1.0)  # (B, N, N)


def build_incidence(scale: str, node_features: th.Tensor, group_size: int = 2) -> th.Tensor:
    r"""
    Incidence matrix of one scale for a batch of hypergraphs.

    :param scale: ``"team"``, ``"group"`` or ``"individual"``.
    :param node_features: Node features of shape ``(B, N, F)`` (only used by the group scale; the other scales
        only read the batch shape, device and dtype).
    :param group_size: Hyperedge size of the group scale.
    :return: Incidence ``(B, E, N)``: E = 1 (team), N (individual), N (group, or 1 if ``group_size >= N``).
    """
    batch_shape, n_agents = tuple(node_features.shape[:-2]), node_features.shape[-2]
    if scale == "team":
        return team_incidence(n_agents, batch_shape, node_features.device, node_features.dtype)
    if scale == "individual":
        return individual_incidence(n_agents, batch_shape, node_features.device, node_features.dtype)
    if scale == "group":
        return group_incidence(node_features, group_size)
    raise ValueError(f"Unknown hypergraph scale {scale!r}, expected one of {SCALES}")


def node_to_edge(x: th.Tensor, incidence: th.Tensor, attention_logits: th.Tensor) -> th.Tensor:
    r"""
    Attention-weighted node-to-edge aggregation (spec §1.4 steps 4-5).

    The softmax runs over **all** N nodes, with non-members entering it with logit 0, and the non-members are
    zeroed afterwards, so the member weights do not sum to 1 (uniform logits 0, k = 2, N = 3: each member 1/3):

    .. math::

        \alpha_{e,\cdot} = H_{e,\cdot} \odot \operatorname{softmax}(a_{e,\cdot} \odot H_{e,\cdot}), \qquad
        g_e = \sum_i \alpha_{e,i} x_i .

    :param x: Node features ``(B, N, F)``.
    :param incidence: Incidence ``(B, E, N)``.
    :param attention_logits: Logits :math:`a_{e,i}` for every (edge, node) pair, ``(B, E, N)``.
    :return: Edge embeddings g of shape ``(B, E, F)``.
    """
    weights = th.softmax(attention_logits * incidence, dim=-1) * incidence  # (B, E, N)
    return weights @ x  # (B, E, F)


def gumbel_softmax(
    logits: th.Tensor,
    tau: float,
    noise: bool = True,
    generator: th.Generator | None = None,
    eps: float = 1e-10,
    uniform: th.Tensor | None = None,
) -> th.Tensor:
    r"""
    Soft Gumbel-softmax over the last axis (the edge-type axis, spec §1.5).

    .. math::

        \pi = \operatorname{softmax}\big((\ell + G) / \tau\big), \qquad
        G = -\log(\varepsilon - \log(U + \varepsilon)), \quad U \sim \mathcal{U}(0, 1).

    The authors draw fresh noise on every forward pass; ``noise=False`` gives the deterministic
    :math:`\operatorname{softmax}(\ell / \tau)`.

    :param logits: Logits :math:`\ell`, shape ``(..., n_types)``.
    :param tau: Temperature (0.5 in the authors' code).
    :param noise: Whether to add Gumbel noise.
    :param generator: Optional random generator for U (drawn on the generator's device, then moved).
    :param eps: The :math:`\varepsilon` of the noise formula.
    :param uniform: The draws U, of the shape of ``logits`` (drawn here when ``None``): the update draws them once for
        a padded minibatch and hands each part of it its rows, so that the noise is that of the padded batch.
    :return: Type probabilities of the same shape as ``logits``, summing to 1 over the last axis.
    """
    if noise:
        if uniform is None:
            draw_device = generator.device if generator is not None else logits.device
            uniform = th.rand(logits.shape, generator=generator, device=draw_device, dtype=logits.dtype).to(logits.device)
        logits = logits - th.log(eps - th.log(uniform + eps))
    return th.softmax(logits / tau, dim=-1)


def edge_to_node(edge_messages: th.Tensor, incidence: th.Tensor, node_features: th.Tensor) -> th.Tensor:
    r"""
    Edge-to-node aggregation (spec §1.6 step 3): the sum of the messages of the node's hyperedges,
    concatenated with the node's own features, the **whole** vector divided by the node count N:

    .. math::

        n_i = \frac{1}{N} \Big[ \sum_e H_{e,i} m_e \; ; \; h_i \Big].

    :param edge_messages: Edge messages m of shape ``(B, E, F)``.
    :param incidence: Incidence ``(B, E, N)``.
    :param node_features: Node features h of shape ``(B, N, F)``.
    :return: Node inputs of shape ``(B, N, 2F)``.
    """
    incoming = incidence.transpose(-1, -2) @ edge_messages  # (B, N, F)
    return th.cat([incoming, node_features], dim=-1) / incidence.shape[-1]  # (B, N, 2F)
