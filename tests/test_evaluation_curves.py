"""benchmarks/evaluation_curves.py: final and best values per run, wall time from segments.json, the random floor,
the figure and the one-line errors."""

import csv
import json
import math

import numpy as np
import pytest

TASK = "cn-sparse-n3"
FIELDS = ["algo", "task", "seed", "timesteps", "env_steps", "n_episodes", "coverage_rate_mean", "success_mean"]
# (env steps, coverage rate, success) per evaluation
MAPPO = [(0, 0.1, 0.0), (1_000_000, 0.4, 0.1), (2_000_000, 0.4, 0.05), (3_000_000, 0.3, 0.2)]
SAEIR = [(0, 0.2, 0.0), (1_000_000, 0.5, 0.0), (2_000_000, 0.6, 0.0)]


@pytest.fixture(scope="module")
def curves(load_benchmark_script):
    return load_benchmark_script("evaluation_curves")


def write_runs(path, runs):
    """A benchmark runs.csv: ``runs`` maps (algo, seed) to its evaluations (env steps, coverage rate, success)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=FIELDS)
        writer.writeheader()
        for (algo, seed), points in runs.items():
            for env_steps, coverage, success in points:
                writer.writerow(
                    dict(algo=algo, task=TASK, seed=seed, timesteps=3 * env_steps, env_steps=env_steps, n_episodes=20,
                         coverage_rate_mean=coverage, success_mean=success)
                )  # fmt: skip
    return path


@pytest.fixture
def benchmark(tmp_path):
    """Two runs of cn-sparse-n3; mappo's folder holds a segments.json of two segments (the run was resumed once)."""
    runs_csv = write_runs(tmp_path / "bench" / "runs.csv", {("mappo", 1): MAPPO, ("saeir_ppo", 1): SAEIR})
    folder = tmp_path / "bench" / "runs" / "mappo" / f"{TASK}_s1"
    folder.mkdir(parents=True)
    segments = [
        {"started": "20261203T175040Z", "resumed_at": 0, "reached": 5_400_000, "wall_s": 2700.0},
        {"started": "20261203T191802Z", "resumed_at": 5_400_000, "reached": 9_000_000, "wall_s": 900.0},
    ]
    (folder / "segments.json").write_text(json.dumps(segments))
    return runs_csv


def test_table_final_best_and_wall_time(curves, benchmark, tmp_path, capsys):
    out = tmp_path / "out"
    references = ["--reference", f"{TASK}:mappo=64.43", f"{TASK}:saeir_ppo=65.48"]
    assert curves.main([str(benchmark), "--out", str(out), "--random-episodes", "0", *references]) == 0
    text = (out / "evaluation_curves.md").read_text()
    assert (out / "curves_full.png").stat().st_size > 0
    assert text in capsys.readouterr().out
    # coverage: last 30%, best 40% first at 1M (2M ties); success: last and best 20% at 3M; 9M agent-steps in 3600 s
    assert "| mappo s1 | 30.00 | 40.00 (1M) | 20.00 | 20.00 (3M) | 3M | 2,500 | 1.0 |" in text
    # no run folder: no wall time; the best of a curve that never rises is its first evaluation
    assert "| saeir_ppo s1 | 60.00 | 60.00 (2M) | 0.00 | 0.00 (0) | 2M | n/a | n/a |" in text
    assert "| mappo, paper 20M | 64.43 | - | - | - | - | - | - |" in text  # on the main metric only
    assert "| saeir_ppo, paper 20M | 65.48 |" in text
    assert "random policy" not in text
    assert "Evaluations per run: mappo s1 4, saeir_ppo s1 3, of 20 game episodes each (n_episodes)." in text


def test_metrics_with_or_without_the_mean_suffix(curves, benchmark, tmp_path):
    out = tmp_path / "out"
    assert curves.main([str(benchmark), "--out", str(out), "--random-episodes", "0", "--metrics", "success_mean"]) == 0
    text = (out / "evaluation_curves.md").read_text()
    assert "| run | Success % final | Success % best (first at) | last evaluation |" in text
    assert "| mappo s1 | 20.00 | 20.00 (3M) | 3M | 2,500 | 1.0 |" in text


def one_line_error(capsys):
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "error: " in err
    return err


def test_same_run_in_two_files_is_refused(curves, benchmark, tmp_path, capsys):
    other = write_runs(tmp_path / "other" / "runs.csv", {("mappo", 1): MAPPO})
    assert curves.main([str(benchmark), str(other), "--out", str(tmp_path / "out"), "--random-episodes", "0"]) == 2
    assert "('mappo', 'cn-sparse-n3', 1) is in both" in one_line_error(capsys)


def test_unknown_metric_lists_the_available_ones(curves, benchmark, tmp_path, capsys):
    args = [str(benchmark), "--out", str(tmp_path / "out"), "--random-episodes", "0", "--metrics", "goal_diff"]
    assert curves.main(args) == 2
    assert "no metric 'goal_diff' in the rows of cn-sparse-n3; they have: coverage_rate, success." in one_line_error(capsys)
    assert not (tmp_path / "out").exists()


def test_missing_and_empty_files_are_named(curves, tmp_path, capsys):
    missing = tmp_path / "nowhere" / "runs.csv"
    assert curves.main([str(missing), "--out", str(tmp_path / "out")]) == 2
    assert f"{missing} does not exist." in one_line_error(capsys)
    empty = tmp_path / "runs.csv"
    empty.write_text(",".join(FIELDS) + "\n")
    assert curves.main([str(empty), "--out", str(tmp_path / "out")]) == 2
    assert f"{empty} has no evaluation rows" in one_line_error(capsys)


def test_bad_reference_is_one_line(curves, benchmark, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        curves.main([str(benchmark), "--out", str(tmp_path / "out"), "--reference", "mappo=64"])
    assert stop.value.code == 2
    assert "is not TASK:ALGO=VALUE" in one_line_error(capsys)
    args = [str(benchmark), "--out", str(tmp_path / "out"), "--random-episodes", "0", "--reference", "cn-sparse-n4:mappo=1"]
    assert curves.main(args) == 2
    assert "no runs of cn-sparse-n4" in one_line_error(capsys)


def test_random_floor(curves, benchmark, tmp_path):
    out = tmp_path / "out"
    args = [str(benchmark), "--out", str(out), "--random-episodes", "20", "--random-games", "2"]
    assert curves.main(args) == 0
    text = (out / "evaluation_curves.md").read_text()
    row = next(line for line in text.splitlines() if line.startswith("| random policy (20 episodes) |"))
    coverage, success = float(row.split("|")[2]), float(row.split("|")[4])
    for value in (coverage / 100, success / 100):
        assert math.isfinite(value) and 0.0 <= value <= 1.0
    assert row.endswith("| - | - | - | - |")


def test_paths_under_home_are_shown_from_home(curves, tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    assert curves.shown_path(tmp_path / "results" / "runs.csv") == "$HOME/results/runs.csv"
    assert curves.shown_path(tmp_path.parent / "elsewhere.csv") == str(tmp_path.parent / "elsewhere.csv")


@pytest.mark.parametrize(
    "values, tolerance, expected",
    [
        # level = mean of the last 3 = 64; from 2M on every value is within 2 of it (1M: 60 is 4 below)
        ([10.0, 60.0, 63.0, 65.0, 64.0, 63.0], 2.0, (2_000_000, 64.0)),
        ([10.0, 60.0, 63.0, 65.0, 64.0, 63.0], 5.0, (1_000_000, 64.0)),
        # a late dip leaves the plateau after it: 66 -> level 64, the dip at 4M (50) is outside
        ([10.0, 64.0, 64.0, 64.0, 50.0, 71.0, 64.0, 57.0], 2.0, (math.nan, 64.0)),
        ([10.0, 64.0, 64.0, 64.0, 50.0, 64.0, 64.0, 64.0], 2.0, (5_000_000, 64.0)),
        ([30.0], 1.0, (0, 30.0)),  # one evaluation: its own level
    ],
)
def test_plateau_start_against_worked_examples(curves, values, tolerance, expected):
    steps = [1_000_000 * index for index in range(len(values))]
    start, level = curves.plateau_start((np.array(steps, dtype=float), np.array(values)), tolerance)
    assert level == pytest.approx(expected[1])
    assert (math.isnan(start) and math.isnan(expected[0])) or start == expected[0]


def test_plateau_column(curves, benchmark, tmp_path, capsys):
    out = tmp_path / "out"
    assert curves.main([str(benchmark), "--out", str(out), "--random-episodes", "0", "--plateau", "7"]) == 0
    text = (out / "evaluation_curves.md").read_text()
    assert "| Coverage % plateau from (level, within 7) |" in text
    # mappo: level (40 + 40 + 30) / 3 = 36.67; 1M-3M within 7 of it (30 is 6.67 below), 0 (10) is not
    assert "| mappo s1 | 30.00 | 40.00 (1M) | 20.00 | 20.00 (3M) | 1M (36.67) | 3M | 2,500 | 1.0 |" in text
    # saeir_ppo: level (20 + 50 + 60) / 3 = 43.33; 60 is 16.67 above: no plateau
    assert "| saeir_ppo s1 | 60.00 | 60.00 (2M) | 0.00 | 0.00 (0) | - | 2M | n/a | n/a |" in text
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:
        curves.main([str(benchmark), "--out", str(out), "--plateau", "0"])
    assert stop.value.code == 2
    assert "--plateau must be a positive number, got 0.0" in one_line_error(capsys)
