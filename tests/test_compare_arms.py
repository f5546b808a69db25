"""benchmarks/compare_arms.py: arms from several runs.csv files renamed and reported with the benchmark's functions."""

import csv

import pytest


@pytest.fixture(scope="module")
def compare_arms(load_benchmark_script):
    return load_benchmark_script("compare_arms")


def write_runs(path, algo, finals):
    """A runs.csv with an evaluation at 0 and a final one per seed."""
    fields = ["algo", "task", "seed", "timesteps", "env_steps", "coverage_rate_mean", "ep_rew_mean"]
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=fields)
        writer.writeheader()
        for seed, final in enumerate(finals, start=1):
            for steps, coverage in ((0, 0.0), (300, final)):
                writer.writerow(
                    dict(
                        algo=algo,
                        task="cn-sparse-n3",
                        seed=seed,
                        timesteps=steps,
                        env_steps=steps // 3,
                        coverage_rate_mean=coverage,
                        ep_rew_mean=10 * coverage,
                    )
                )


def test_two_folders_side_by_side(compare_arms, tmp_path, capsys):
    write_runs(tmp_path / "a.csv", "mappo", [0.1, 0.2, 0.3])
    write_runs(tmp_path / "b.csv", "saeir_ppo", [0.5, 0.6, 0.7])
    out = tmp_path / "report"
    assert compare_arms.main([f"base={tmp_path / 'a.csv'}:mappo", f"new arm={tmp_path / 'b.csv'}", "--out", str(out)]) == 0
    text = (out / "comparison.md").read_text()
    assert text == capsys.readouterr().out and (out / "curves.png").stat().st_size > 0
    assert "| base | 20.00 ± 8.16 (n=3) |" in text and "| new arm | **60.00 ± 8.16 (n=3)** |" in text
    assert "| cn-sparse-n3 | base (n=3) | new arm (n=3) | -40.00 Coverage % | 0% | 0.100 |" in text


@pytest.mark.parametrize(
    "argument, message",
    [("no-equals", "is not ARM=RUNS_CSV"), ("x=missing.csv", "no rows in"), ("x={a}:rnd", "no rows of 'rnd'")],
)
def test_bad_arm_is_refused(compare_arms, tmp_path, argument, message):
    write_runs(tmp_path / "a.csv", "mappo", [0.1])
    with pytest.raises(SystemExit, match=message):
        compare_arms.main([argument.format(a=tmp_path / "a.csv"), "--out", str(tmp_path / "r")])
