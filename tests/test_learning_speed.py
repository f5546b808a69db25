"""benchmarks/learning_speed.py: success at fixed env steps, first reaches, areas, the earlier test, bonus windows."""

import csv
import itertools
import json
import math

import numpy as np
import pytest


@pytest.fixture(scope="module")
def speed(load_benchmark_script):
    return load_benchmark_script("learning_speed")


def write_runs(path, algo, curves, task="grf-3v1-keeper"):
    """A runs.csv with one evaluation row per (seed, env steps, success in [0, 1])."""
    fields = ["algo", "task", "seed", "timesteps", "env_steps", "success_mean", "ep_rew_mean"]
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=fields)
        writer.writeheader()
        for seed, points in curves.items():
            for env_steps, success in points:
                writer.writerow(
                    dict(algo=algo, task=task, seed=seed, timesteps=3 * env_steps, env_steps=env_steps,
                         success_mean=success, ep_rew_mean=success)
                )  # fmt: skip


def test_value_at_and_first_reach(speed):
    curve = (np.array([0.0, 250.0, 500.0, 750.0]), np.array([0.0, 5.0, 12.0, 30.0]))
    assert speed.value_at(curve, 500) == 12.0
    assert speed.value_at(curve, 600) == 30.0  # the first evaluation at or after
    assert speed.value_at(curve, 800) is None
    assert speed.first_reach(curve, 10.0) == (500.0, True)
    assert speed.first_reach(curve, 30.0) == (750.0, True)
    assert speed.first_reach(curve, 50.0) == (750.0, False)  # censored at the last evaluation


def test_area_is_the_mean_height_by_trapezoids(speed):
    curve = (np.array([0.0, 1.0, 3.0, 4.0]), np.array([0.0, 10.0, 10.0, 40.0]))
    # trapezoids up to 3: 0.5 * 10 + 2 * 10 = 25 over a span of 3
    assert speed.area_under_curve(curve, 3.0) == pytest.approx(25.0 / 3.0)
    # the whole curve: 25 + (10 + 40) / 2 = 50 over 4
    assert speed.area_under_curve(curve, 4.0) == pytest.approx(12.5)
    with pytest.raises(ValueError, match="two evaluations"):
        speed.area_under_curve(curve, 0.5)


def slow_earlier_p(first, second):
    """The one-sided p by brute force: every assignment of the pooled times to labels, counted with its multiplicity."""
    pooled = first + second
    observed = sum((x < y) + 0.5 * (x == y) for x in first for y in second)
    count = extreme = 0
    for labels in itertools.permutations(range(len(pooled))):
        a = [pooled[i] for i in labels[: len(first)]]
        b = [pooled[i] for i in labels[len(first) :]]
        count += 1
        extreme += sum((x < y) + 0.5 * (x == y) for x in a for y in b) >= observed - 1e-12
    return extreme / count


@pytest.mark.parametrize(
    "first, second, share",
    [
        ([1.0, 2.0, 3.0], [4.0, 5.0, 6.0], 1.0),  # all earlier: the smallest p with 3 and 3, 1/20
        ([4.0, 5.0, 6.0], [1.0, 2.0, 3.0], 0.0),
        ([1.0, 5.0, math.inf], [2.0, math.inf, math.inf], 6 / 9),  # censored seeds tie with each other
        ([2.0, 2.0], [2.0, 3.0], 0.75),
    ],
)
def test_earlier_test_against_brute_force(speed, first, second, share):
    observed, p_value = speed.earlier_test(first, second)
    assert observed == pytest.approx(share)
    assert p_value == pytest.approx(slow_earlier_p(first, second))
    if share == 1.0 and len(first) == 3:
        assert p_value == pytest.approx(1 / 20)


@pytest.mark.parametrize("seed", range(4))
def test_earlier_test_counts_equal_listing_every_split(speed, seed):
    rng = np.random.default_rng(seed)
    times = rng.choice([1.0, 2.0, 3.0, 5.0, math.inf], size=7)  # ties and censored seeds
    first, second = list(times[:3]), list(times[3:])
    _, p_value = speed.earlier_test(first, second)
    assert p_value == pytest.approx(slow_earlier_p(first, second))


def test_earlier_test_fifteen_seeds_each_is_exact(speed):
    from scipy.stats import mannwhitneyu

    rng = np.random.default_rng(0)
    first, second = list(rng.normal(0.0, 1.0, 15)), list(rng.normal(0.5, 1.0, 15))  # no ties: scipy's exact law holds
    observed, p_value = speed.earlier_test(first, second)
    expected = mannwhitneyu(first, second, alternative="less", method="exact")
    assert p_value == pytest.approx(expected.pvalue, rel=1e-9)
    assert observed == pytest.approx(1.0 - expected.statistic / 225)  # scipy's U counts the pairs where first is above


def test_a_run_with_only_its_first_evaluation_has_no_area_yet(speed, tmp_path):
    write_runs(tmp_path / "a.csv", "saeir_ppo", {1: [(0, 0.0)]})  # a run that has just started
    write_runs(tmp_path / "b.csv", "mappo", {1: [(0, 0.0), (500_000, 0.1)]})
    assert speed.main([str(tmp_path / "a.csv"), str(tmp_path / "b.csv"), "--out", str(tmp_path / "out")]) == 0
    text = (tmp_path / "out" / "learning_speed.md").read_text()
    assert text.count("Area under the curve: none yet (a run has one evaluation so far).") == 2
    assert "| area to" not in text


def test_report_end_to_end(speed, tmp_path, capsys):
    write_runs(
        tmp_path / "a.csv",
        "saeir_ppo",
        {s: [(0, 0.0), (500_000, 0.1 * s), (1_000_000, 0.3), (2_000_000, 0.4)] for s in (1, 2, 3)},
    )
    write_runs(tmp_path / "b.csv", "mappo", {s: [(0, 0.0), (500_000, 0.0), (1_000_000, 0.05 * s), (2_000_000, 0.15)]
                                             for s in (1, 2, 3)})  # fmt: skip
    assert speed.main([str(tmp_path / "a.csv"), str(tmp_path / "b.csv"), "--out", str(tmp_path / "out")]) == 0
    text = (tmp_path / "out" / "learning_speed.md").read_text()
    assert text.startswith(f"Runs: `{tmp_path / 'a.csv'}`, `{tmp_path / 'b.csv'}`\n")  # outside the home folder
    assert (tmp_path / "out" / "curves_seeds.png").stat().st_size > 0
    assert "| 0.5M | s1 10, s2 20, s3 30 | 20.0 | 20.0 [" in text  # per seed, the mean and the IQM (untrimmed)
    assert text.count("With 3 seeds the IQM trims none of them") == 2  # under each method's table
    assert "| 10 | s1 0.5M, s2 0.5M, s3 0.5M |" in text  # saeir_ppo's first reaches of 10%
    assert "| 20 | s1 > 2M, s2 > 2M, s3 > 2M |" in text  # mappo never reaches 20%: censored
    # saeir_ppo reaches 10% earlier on every seed pair: the smallest one-sided p with 3 against 3
    assert "| saeir_ppo (n=3) | mappo (n=3) | first reach of 10 | | 100% | 0.050 (one-sided) |" in text


def test_iqm_trims_a_quarter_from_four_seeds_and_none_from_three(speed):
    """The IQM against the hand-computed trimmed mean: 4 seeds drop their lowest and highest, 3 seeds drop none."""
    four = {s: (np.array([0.0, 1e6]), np.array([0.0, value])) for s, value in zip((1, 2, 3, 4), (0, 10, 20, 90))}
    table = "\n".join(speed.success_table(four, [1_000_000], "Success %"))
    assert "| 1M | s1 0, s2 10, s3 20, s4 90 | 30.0 | 15.0 [" in table  # (10 + 20) / 2 against the mean 30
    assert "trims none" not in table
    three = {s: four[s] for s in (2, 3, 4)}
    table = "\n".join(speed.success_table(three, [1_000_000], "Success %"))
    assert "| 1M | s2 10, s3 20, s4 90 | 40.0 | 40.0 [" in table
    assert "With 3 seeds the IQM trims none of them" in table


def test_runs_under_the_home_folder_are_shown_as_home(speed, tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    write_runs(tmp_path / "a.csv", "saeir_ppo", {1: [(0, 0.0), (500_000, 0.1)]})
    assert speed.main([str(tmp_path / "a.csv"), "--out", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "learning_speed.md").read_text().startswith("Runs: `$HOME/a.csv`\n")


def test_same_run_in_two_files_is_refused(speed, tmp_path):
    for name in ("a.csv", "b.csv"):
        write_runs(tmp_path / name, "mappo", {1: [(0, 0.0), (10, 0.1)]})
    with pytest.raises(SystemExit, match="in both"):
        speed.main([str(tmp_path / "a.csv"), str(tmp_path / "b.csv"), "--out", str(tmp_path / "out")])


def add_progress_column(run, name, values):
    """Append the column ``name`` with one value per rollout (``""``: not logged that rollout) to ``progress.csv``."""
    rows = list(csv.reader(open(run / "progress.csv")))
    with open(run / "progress.csv", "w", newline="") as file:
        csv.writer(file).writerows([[*rows[0], name], *[[*row, value] for row, value in zip(rows[1:], values)]])


def test_bonus_windows_average_per_window_in_env_steps(speed, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "spec.json").write_text(json.dumps({"config": {"env_kwargs": {"N": 4}}}))
    fields = ["time/total_timesteps", "rollout/intrinsic_fire_rate_team", "rollout/intrinsic_reward_mean_team"]
    with open(run / "progress.csv", "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(fields)
        # agent-steps 4, 8, 12, 16 are env steps 1, 2, 3, 4: windows of 2 env steps hold rollouts (1, 2) and (3, 4)
        for agent_steps, fire in ((4, 0.1), (8, 0.3), (12, 0.5), (16, 0.7)):
            writer.writerow([agent_steps, fire, 2 * fire])
    lines = speed.bonus_windows(run, window=2.0)
    assert lines[0] == "| env steps | fire rate team | bonus mean team |"
    assert lines[2] == "| 0M-2e-06M | 2.00e-01 | 4.00e-01 |"
    assert lines[3] == "| 2e-06M-4e-06M | 6.00e-01 | 1.20e+00 |"
    # with the value-softmax entropy logged, its mean per window comes after the bonus
    add_progress_column(run, "rollout/value_entropy_team", (3.0, 2.0, 1.5, 0.5))
    lines = speed.bonus_windows(run, window=2.0)
    assert lines[0] == "| env steps | fire rate team | bonus mean team | value entropy team |"
    assert lines[2] == "| 0M-2e-06M | 2.00e-01 | 4.00e-01 | 2.50e+00 |"
    assert lines[3] == "| 2e-06M-4e-06M | 6.00e-01 | 1.20e+00 | 1.00e+00 |"
    # with episode lengths logged, 1 / length per window: the first rollout ended no episode yet (empty cell), so
    # the first window averages its second rollout alone
    add_progress_column(run, "rollout/ep_len_mean", ("", 4.0, 10.0, 40.0))
    lines = speed.bonus_windows(run, window=2.0)
    assert lines[0] == "| env steps | fire rate team | bonus mean team | value entropy team | episode starts per step |"
    assert lines[2] == "| 0M-2e-06M | 2.00e-01 | 4.00e-01 | 2.50e+00 | 2.50e-01 |"
    assert lines[3] == "| 2e-06M-4e-06M | 6.00e-01 | 1.20e+00 | 1.00e+00 | 6.25e-02 |"  # (1/10 + 1/40) / 2
    # a window in which no rollout logged a length shows "-"
    rows = list(csv.reader(open(run / "progress.csv")))
    with open(run / "progress.csv", "w", newline="") as file:
        csv.writer(file).writerows([rows[0], *[[*row[:-1], ""] for row in rows[1:3]], *rows[3:]])
    assert speed.bonus_windows(run, window=2.0)[2].endswith(" | 2.50e+00 | - |")


def test_iqm_interval_is_the_aggregate_tables(speed):
    """One method's IQM and interval are the ones the benchmark's ``aggregate.md`` prints for the same seeds (same
    bootstrap, same seed), and the caller's NumPy global state is given back."""
    from sb3_saeir.benchmark import rliable_markdown

    values = [0.05, 0.45, 0.64, 0.62, 0.30]
    rows = [
        {"algo": "saeir_ppo", "task": "grf-3v1-keeper", "seed": seed, "timesteps": 10, "success_mean": value}
        for seed, value in enumerate(values, start=1)
    ]
    np.random.seed(7)
    estimate, low, high = speed.iqm_interval([100 * v for v in values], reps=300)
    assert np.random.randint(10**9) == np.random.RandomState(7).randint(10**9)
    assert f"| grf-3v1-keeper | saeir_ppo | {estimate:.2f} Success % | [{low:.2f}, {high:.2f}] |" in rliable_markdown(
        rows, reps=300
    )
    assert estimate == pytest.approx(np.mean(sorted(100 * v for v in values)[1:4]))  # 5 seeds: drops one from each end
