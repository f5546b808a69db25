"""benchmarks/football_throughput.py: the cost model's projection of the paper's 25M env steps (closed forms)."""

import pytest


@pytest.fixture(scope="module")
def football_throughput(load_benchmark_script):
    return load_benchmark_script("football_throughput")


def test_projection_of_the_synchronous_and_the_overlapped_loop(football_throughput):
    # e = 3 ms, l = 1 ms: synchronous on 2 cores 25e6 x (3/2 + 1) ms = 62,500 s; overlapped 25e6 x max(1, 4/2) ms
    synchronous, overlapped = football_throughput.projected_hours(3e-3, 1e-3, cores=2, n_games=2)
    assert synchronous == pytest.approx(62_500 / 3600)
    assert overlapped == pytest.approx(50_000 / 3600)
    # many cores: the learner's serial part bounds both; fewer games than cores step no faster than the games
    synchronous, overlapped = football_throughput.projected_hours(3e-3, 1e-3, cores=64, n_games=4)
    assert synchronous == pytest.approx(25e6 * (3e-3 / 4 + 1e-3) / 3600)
    assert overlapped == pytest.approx(25e6 * 1e-3 / 3600)


def test_cost_model_lines_name_every_core_count(football_throughput):
    lines = football_throughput.cost_model_lines(3e-3, 4e-3, n_games=8)
    assert lines[0].startswith("cost model: engine e = 3.00 ms, learner l = 1.00 ms")
    assert [line.split()[0] for line in lines[1:5]] == ["2", "8", "16", "64"]
    assert "--ray-address" in lines[-1]


def test_busy_share_is_cpu_over_cpus_times_wall(football_throughput, monkeypatch):
    monkeypatch.setattr(football_throughput.os, "cpu_count", lambda: 2)
    assert football_throughput.busy_share(3.0, 2.0) == pytest.approx(0.75)


def test_tree_memory_counts_the_children(football_throughput):
    pytest.importorskip("psutil")
    import subprocess
    import sys
    import time

    # a child holding about 200 MB: the tree's peak is above this process's own resident memory by about that much
    holder = (
        "import time; b = bytearray(200 * 2**20); b[::4096] = b'x' * len(b[::4096]); print('ready', flush=True); "
        "time.sleep(60)"
    )
    child = subprocess.Popen([sys.executable, "-c", holder], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None and child.stdout.readline() == "ready\n"  # its pages are touched: resident
        with football_throughput.TreeMemory(interval=0.05) as memory:
            time.sleep(1.0)
        import psutil

        own_mb = psutil.Process().memory_info().rss / 2**20
        assert memory.peak_mb > own_mb + 150
    finally:
        child.kill()
        child.wait()
