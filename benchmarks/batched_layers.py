"""Would batched products or a fused GRU speed up the SAEIR update? Forward + backward times of its layers, as the
update runs them and as batched products, at the update's shapes.

    OMP_NUM_THREADS=1 python benchmarks/batched_layers.py
    OMP_NUM_THREADS=1 python benchmarks/batched_layers.py --compile   # adds torch.compile of the message passing

At the navigation defaults (128 games, 25-step rollouts, 10-step chunks, hidden size 64) the update runs each network
on a 10-step group of 256 blocks (7,680 agent rows) and a 5-step group of 128 blocks; the default ``--rows`` is the
first. Four comparisons, each forward + backward of a sum, median of ``--repeats`` timings of ``--iterations`` calls:

- **across critics**: the three critics' identical ``FCBlock`` (Linear -> ReLU -> LayerNorm; ``node_end`` 2H -> H,
  ``node2edge_start`` H -> H) each on its own input,
  as three calls (the update), against one ``baddbmm`` over the stacked weights, one ReLU, one LayerNorm without
  affine and one broadcast affine (the batched product; the stacking of the weights is left out of its time, as a
  parameter layout could hold them stacked);
- **edge types**: the group and individual critics' three edge-aggregation blocks on the same input, three calls and
  a ``stack`` (the update), against one wide product over the concatenated weights (same exclusion);
- **GRU**: ``nn.GRU`` over the 10-step sequences against its matrix products alone (the floor a fused kernel could
  approach: input projection, recurrent products, and their gradients);
- **compiled message passing** (``--compile``): ``HypergraphScaleCritic._message_passing`` eager against ``torch.compile``.

Each batched variant's outputs are compared with the update's (max abs difference printed). Results and what they
mean for the update: ``docs/guide/performance.md``, "Batched products and fused kernels".
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import torch as th
import torch.nn.functional as F
from torch import nn

from sb3_saeir.common.torch_layers import FCBlock, HypergraphScaleCritic


def time_ms(step: Callable[[], None], iterations: int, repeats: int) -> float:
    """Median over ``repeats`` of the mean time of ``iterations`` calls of ``step``, in ms (two warm-up calls)."""
    step()
    step()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(iterations):
            step()
        times.append((time.perf_counter() - start) / iterations * 1e3)
    return statistics.median(times)


def stacked_block_parameters(blocks: list[FCBlock]) -> tuple[th.Tensor, th.Tensor, th.Tensor, th.Tensor]:
    """The blocks' Linear weights ``(K, in, out)`` and biases ``(K, 1, out)``, LayerNorm weights and biases
    ``(K, 1, out)``, as leaves that collect gradients (the layout a batched implementation would hold)."""
    weight = th.stack([block.linear.weight.t() for block in blocks]).detach().requires_grad_()  # (K, in, out)
    bias = th.stack([block.linear.bias for block in blocks]).unsqueeze(1).detach().requires_grad_()  # (K, 1, out)
    gain = th.stack([block.norm.weight for block in blocks]).unsqueeze(1).detach().requires_grad_()  # (K, 1, out)
    shift = th.stack([block.norm.bias for block in blocks]).unsqueeze(1).detach().requires_grad_()  # (K, 1, out)
    return weight, bias, gain, shift


def batched_blocks(inputs: th.Tensor, weight: th.Tensor, bias: th.Tensor, gain: th.Tensor, shift: th.Tensor) -> th.Tensor:
    """K FCBlocks on K inputs as one batched product: ``(K, rows, in) -> (K, rows, out)``."""
    hidden = F.relu(th.baddbmm(bias, inputs, weight))  # (K, rows, out)
    return th.addcmul(shift, F.layer_norm(hidden, hidden.shape[-1:]), gain)  # (K, rows, out)


def wide_blocks(inputs: th.Tensor, weight: th.Tensor, bias: th.Tensor, gain: th.Tensor, shift: th.Tensor) -> th.Tensor:
    """K FCBlocks on one input as one wide product: ``(..., in) -> (..., K, out)``.

    :param weight: the concatenated Linear weights ``(K * out, in)``; ``bias`` ``(K * out,)``
    :param gain: the LayerNorm weights ``(K, out)``; ``shift`` their biases ``(K, out)``
    """
    n_blocks, out_dim = gain.shape
    hidden = F.relu(F.linear(inputs, weight, bias)).unflatten(-1, (n_blocks, out_dim))  # (..., K * out) -> (..., K, out)
    return th.addcmul(shift, F.layer_norm(hidden, (out_dim,)), gain)  # (..., K, out)


def compare_across_critics(rows: int, in_dim: int, hidden: int, iterations: int, repeats: int) -> None:
    blocks = [FCBlock(in_dim, hidden) for _ in range(3)]
    inputs = th.randn(3, rows, in_dim, requires_grad=True)  # (K, rows, in): one input per critic
    weight, bias, gain, shift = stacked_block_parameters(blocks)

    def separate() -> None:
        sum(block(inputs[k]).sum() for k, block in enumerate(blocks)).backward()

    def batched() -> None:
        batched_blocks(inputs, weight, bias, gain, shift).sum().backward()

    with th.no_grad():
        reference = th.stack([block(inputs[k]) for k, block in enumerate(blocks)])
        difference = (batched_blocks(inputs, weight, bias, gain, shift) - reference).abs().max().item()
    print(
        f"across critics, 3 x FCBlock({in_dim}->{hidden}) on {rows} rows: three calls "
        f"{time_ms(separate, iterations, repeats):6.2f} ms, one baddbmm {time_ms(batched, iterations, repeats):6.2f} ms"
        f"  (max diff {difference:.1e})"
    )


def compare_edge_types(rows: int, hidden: int, iterations: int, repeats: int) -> None:
    blocks = [FCBlock(hidden, hidden) for _ in range(3)]
    raw_edges = th.randn(rows // 3, 3, hidden, requires_grad=True)  # (B, E, H): one input for every type
    weight = th.cat([block.linear.weight for block in blocks]).detach().requires_grad_()  # (T_K * H, H)
    bias = th.cat([block.linear.bias for block in blocks]).detach().requires_grad_()  # (T_K * H,)
    gain = th.stack([block.norm.weight for block in blocks]).detach().requires_grad_()  # (T_K, H)
    shift = th.stack([block.norm.bias for block in blocks]).detach().requires_grad_()  # (T_K, H)

    def wide(x: th.Tensor) -> th.Tensor:
        return wide_blocks(x, weight, bias, gain, shift)

    def separate() -> None:
        th.stack([block(raw_edges) for block in blocks], dim=-2).sum().backward()  # (B, E, T_K, H)

    def batched() -> None:
        wide(raw_edges).sum().backward()

    with th.no_grad():
        difference = (wide(raw_edges) - th.stack([block(raw_edges) for block in blocks], dim=-2)).abs().max().item()
    print(
        f"edge types, 3 x FCBlock({hidden}->{hidden}) on the same {rows} rows: three calls + stack "
        f"{time_ms(separate, iterations, repeats):6.2f} ms, one wide product {time_ms(batched, iterations, repeats):6.2f} ms"
        f"  (max diff {difference:.1e})"
    )


def compare_gru(rows: int, hidden: int, n_steps: int, iterations: int, repeats: int) -> None:
    gru = nn.GRU(hidden, hidden)
    batch = rows // n_steps
    inputs = th.randn(n_steps, batch, hidden, requires_grad=True)  # (T, B, H)
    state = th.zeros(1, batch, hidden)  # (1, B, H)

    def native() -> None:
        gru(inputs, state)[0].sum().backward()

    flat = th.randn(n_steps * batch, hidden)  # (T * B, H)
    step_rows = th.randn(batch, hidden)  # (B, H)
    weight = th.randn(hidden, 3 * hidden)  # (H, 3H)
    gates = th.randn(n_steps * batch, 3 * hidden)  # (T * B, 3H)
    step_gates = th.randn(batch, 3 * hidden)  # (B, 3H)

    def products_only() -> None:
        flat @ weight  # input projection, all steps
        gates @ weight.t()  # its input gradient
        gates.t() @ flat  # its weight gradient
        gates.t() @ flat  # the recurrent weight gradient (all steps at once)
        for _ in range(n_steps):
            step_rows @ weight  # recurrent product
            step_gates @ weight.t()  # its gradient to the previous state

    print(
        f"GRU({hidden}), {n_steps} steps x {batch} sequences: nn.GRU {time_ms(native, iterations, repeats):6.2f} ms, "
        f"its matrix products alone {time_ms(products_only, iterations, repeats):6.2f} ms"
    )


def compare_compiled_message_passing(scale: str, rows: int, hidden: int, iterations: int, repeats: int) -> None:
    critic = HypergraphScaleCritic(18, 3, scale, hidden_size=hidden)
    nodes = th.randn(rows // 3, 3, hidden, requires_grad=True)  # (B, N, H)
    uniform = th.rand(rows // 3, *critic.gumbel_shape)  # (B, E, T_K)
    compiled = th.compile(critic._message_passing)

    def eager() -> None:
        critic._message_passing(nodes, True, uniform).sum().backward()

    def fused() -> None:
        compiled(nodes, True, uniform).sum().backward()

    start = time.perf_counter()
    fused()
    compile_s = time.perf_counter() - start
    with th.no_grad():
        difference = (compiled(nodes, True, uniform) - critic._message_passing(nodes, True, uniform)).abs().max().item()
    print(
        f"{scale} message passing on {rows} rows: eager {time_ms(eager, iterations, repeats):6.2f} ms, "
        f"torch.compile {time_ms(fused, iterations, repeats):6.2f} ms (compiled in {compile_s:.1f} s, "
        f"max diff {difference:.1e})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rows", type=int, default=7_680, help="agent rows of one network call (10 steps x 768)")
    parser.add_argument("--hidden", type=int, default=64)
    parser.add_argument("--iterations", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--compile", action="store_true", help="also time torch.compile of the message passing")
    args = parser.parse_args()
    th.set_num_threads(args.threads)
    th.manual_seed(0)
    compare_across_critics(args.rows, args.hidden, args.hidden, args.iterations, args.repeats)
    compare_across_critics(args.rows, 2 * args.hidden, args.hidden, args.iterations, args.repeats)
    compare_edge_types(args.rows, args.hidden, args.iterations, args.repeats)
    compare_gru(args.rows, args.hidden, 10, args.iterations, args.repeats)
    if args.compile:
        for scale in ("group", "individual"):
            compare_compiled_message_passing(scale, args.rows, args.hidden, args.iterations, args.repeats)


if __name__ == "__main__":
    main()
