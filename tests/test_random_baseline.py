"""benchmarks/random_baseline.py: the random policy's rate with its interval, one Markdown row per task."""

import pytest


@pytest.fixture(scope="module")
def random_baseline(load_benchmark_script):
    return load_benchmark_script("random_baseline")


def test_row_interval_is_the_normal_approximation(random_baseline):
    summary = {"coverage_rate_mean": 0.1, "n_episodes": 100.0, "ep_rew_mean": 1.0, "ep_rew_std": 0.5}
    summary.update(ep_len_mean=25.0, ep_len_std=0.0, wall_s=3.0)
    # 1.96 * sqrt(0.1 * 0.9 / 100) = 0.0588
    assert random_baseline.markdown_row("cn-sparse-n3", summary) == (
        "| cn-sparse-n3 | coverage_rate | 100 | 10.00% [4.12, 15.88] | 1.000 ± 0.500 | 25.0 ± 0.0 | 3 s |"
    )


def test_main_plays_the_episodes(random_baseline, capsys):
    assert random_baseline.main(["--tasks", "cn-sparse-n3", "--episodes", "8", "--games", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3 and lines[2].startswith("| cn-sparse-n3 | coverage_rate | 8 | ")
    with pytest.raises(SystemExit) as exit_info:
        random_baseline.main(["--episodes", "0"])
    assert exit_info.value.code == 2
    assert "--episodes and --games must be at least 1, got 0 and" in capsys.readouterr().err
