"""benchmarks/batched_layers.py: its batched variants compute what the update's separate blocks compute (values and
gradients), and the script prints its four comparisons."""

import subprocess
import sys
from pathlib import Path

import torch as th

from sb3_saeir.common.torch_layers import FCBlock

SCRIPT = Path(__file__).parent.parent / "benchmarks" / "batched_layers.py"


def test_batched_product_equals_the_separate_blocks(load_benchmark_script):
    batched_layers = load_benchmark_script("batched_layers")
    th.manual_seed(0)
    blocks = [FCBlock(5, 4) for _ in range(3)]
    inputs = th.randn(3, 7, 5, requires_grad=True)  # (K, rows, in)
    parameters = batched_layers.stacked_block_parameters(blocks)
    output = batched_layers.batched_blocks(inputs, *parameters)
    weights = th.randn(3, 7, 4)
    (output * weights).sum().backward()
    batched_input_grad, inputs.grad = inputs.grad.clone(), None
    reference = th.stack([block(inputs[k]) for k, block in enumerate(blocks)])
    (reference * weights).sum().backward()
    th.testing.assert_close(output, reference, rtol=1e-5, atol=1e-6)
    th.testing.assert_close(batched_input_grad, inputs.grad, rtol=1e-5, atol=1e-6)
    weight, bias, gain, shift = parameters
    th.testing.assert_close(weight.grad, th.stack([block[0].weight.grad.t() for block in blocks]), rtol=1e-5, atol=1e-6)
    th.testing.assert_close(bias.grad.squeeze(1), th.stack([block[0].bias.grad for block in blocks]), rtol=1e-5, atol=1e-6)
    th.testing.assert_close(gain.grad.squeeze(1), th.stack([block[2].weight.grad for block in blocks]), rtol=1e-5, atol=1e-6)
    th.testing.assert_close(shift.grad.squeeze(1), th.stack([block[2].bias.grad for block in blocks]), rtol=1e-5, atol=1e-6)


def test_wide_product_equals_the_stacked_blocks(load_benchmark_script):
    batched_layers = load_benchmark_script("batched_layers")
    th.manual_seed(1)
    blocks = [FCBlock(6, 6) for _ in range(3)]
    raw_edges = th.randn(4, 3, 6)  # (B, E, H)
    weight = th.cat([block[0].weight for block in blocks])  # (K * H, H)
    bias = th.cat([block[0].bias for block in blocks])
    gain = th.stack([block[2].weight for block in blocks])  # (K, H)
    shift = th.stack([block[2].bias for block in blocks])
    with th.no_grad():
        wide = batched_layers.wide_blocks(raw_edges, weight, bias, gain, shift)
        stacked = th.stack([block(raw_edges) for block in blocks], dim=-2)  # (B, E, K, H)
    th.testing.assert_close(wide, stacked, rtol=1e-5, atol=1e-6)


def test_prints_the_four_comparisons():
    result = subprocess.run(
        [sys.executable, str(SCRIPT), "--rows", "300", "--iterations", "1", "--repeats", "1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert sum(line.startswith("across critics") for line in lines) == 2
    assert sum(line.startswith("edge types") for line in lines) == 1
    assert sum(line.startswith("GRU(64)") for line in lines) == 1
    assert all("max diff" in line for line in lines if line.startswith(("across", "edge")))
