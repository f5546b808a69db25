"""Benchmark runner: CSV, table and curves from tiny runs; resume; failures; the Ray path; the entropy plot."""

import csv
import itertools
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import mannwhitneyu, rankdata

from sb3_saeir import benchmark
from sb3_saeir.benchmark import RunSpec, execute_run, execution, main, parse_seeds, run_folder

TINY_ARGV = ["-n", "200", "--n-games", "2", "--eval-freq", "100", "--eval-episodes", "2", "-params", "n_steps:10"]


def read_csv(path):
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    argv = ["--algos", "saeir_ppo", "mappo", "--tasks", "cn-sparse-n3", "--seeds", "1-2", *TINY_ARGV, "--jobs", "2"]
    assert main([*argv, "--out", str(out), "--rliable"]) == 0
    return out, argv


def test_parse_seeds():
    assert parse_seeds("1-5") == [1, 2, 3, 4, 5]
    assert parse_seeds("1,3,7") == [1, 3, 7]


def test_format_steps():
    assert [benchmark.format_steps(x) for x in (0, 500, 250_000, 1_000_000, 1_500_000)] == ["0", "500", "250k", "1M", "1.5M"]
    # an evaluation made at the end of the rollout that crossed 7M env steps reads 7M, not 7.00006M
    steps = (7_000_064, 12_250_000, 666_752, 1_001_600)
    assert [benchmark.format_steps(x) for x in steps] == ["7M", "12.25M", "666.8k", "1.002M"]


def test_csv_table_figure(finished):
    out, _ = finished
    rows = read_csv(out / "runs.csv")
    assert {(r["algo"], r["seed"]) for r in rows} == {("saeir_ppo", "1"), ("saeir_ppo", "2"), ("mappo", "1"), ("mappo", "2")}
    for algo in ("saeir_ppo", "mappo"):  # at 0, at the first vec step past each 100 agent-steps, at the end (4 rollouts)
        steps = [int(r["timesteps"]) for r in rows if r["algo"] == algo and r["seed"] == "1"]
        assert steps == [0, 102, 204, 240]
    assert {"coverage_rate_mean", "ep_rew_mean", "env_steps", "coverage_rate_std"} <= set(rows[0])
    assert all(int(r["env_steps"]) * 3 == int(r["timesteps"]) for r in rows)
    table = (out / "table.md").read_text()
    assert table.count("\n") == 4 and "| saeir_ppo |" in table and "(n=2)" in table and "**" in table
    assert "cn-sparse-n3 Coverage %" in table
    assert (out / "curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    aggregate = (out / "aggregate.md").read_text()
    assert "IQM" in aggregate and "| cn-sparse-n3 | mappo (n=2) | saeir_ppo (n=2) |" in aggregate


def test_run_folders_hold_their_spec(finished):
    out, _ = finished
    spec = json.loads((out / "runs" / "saeir_ppo" / "cn-sparse-n3_s1" / "spec.json").read_text())
    assert {key: spec[key] for key in ("algo", "task", "seed", "n_timesteps", "n_games", "eval_freq", "eval_episodes")} == {
        "algo": "saeir_ppo",
        "task": "cn-sparse-n3",
        "seed": 1,
        "n_timesteps": 200,
        "n_games": 2,
        "eval_freq": 100,
        "eval_episodes": 2,
    }
    assert spec["params"] == {"n_steps": 10} and spec["config"]["n_steps"] == 10 and spec["version"]
    done = json.loads((out / "runs" / "saeir_ppo" / "cn-sparse-n3_s1" / "done.json").read_text())
    assert done["segments"] == 1 and done["timesteps"] == 240 and done["wall_s"] > 0


def test_report_leaves_unfinished_runs_out_of_the_table(finished, tmp_path, capsys):
    """A run without done.json (running, stopped, failed) is in runs.csv and the curves, never a final value."""
    out, argv = finished
    copy = tmp_path / "bench"
    shutil.copytree(out, copy)
    (copy / "runs" / "mappo" / "cn-sparse-n3_s2" / "done.json").unlink()
    assert main([*argv, "--out", str(copy), "--rliable", "--report-only"]) == 0
    assert "not finished: mappo/cn-sparse-n3_s2 at 240 agent-steps" in capsys.readouterr().out
    assert {(r["algo"], r["seed"]) for r in read_csv(copy / "runs.csv")} >= {("mappo", "2")}
    table = (copy / "table.md").read_text()
    assert "| mappo |" in table and "(n=1)" in table and "| saeir_ppo |" in table and "(n=2)" in table
    assert "Not finished, left out of this table (curves only): mappo/cn-sparse-n3_s2 at 240 agent-steps." in table
    assert "mappo/cn-sparse-n3_s2" in (copy / "aggregate.md").read_text()
    for algo in ("mappo", "saeir_ppo"):  # nothing finished: no table at all
        for seed in (1, 2):
            (copy / "runs" / algo / f"cn-sparse-n3_s{seed}" / "done.json").unlink(missing_ok=True)
    assert main([*argv, "--out", str(copy), "--report-only"]) == 0
    assert not (copy / "table.md").exists() and (copy / "curves.png").is_file()


def test_report_only_of_a_larger_budget_gives_no_final_values(finished, tmp_path, capsys):
    """``--report-only -n 1000`` on runs finished at 200 agent-steps: they are not finished for that budget (their
    200-step values were reported as the finals of 1,000)."""
    out, argv = finished
    copy = tmp_path / "bench"
    shutil.copytree(out, copy)
    larger = [arg if arg != "200" else "1000" for arg in argv]
    assert main([*larger, "--out", str(copy), "--report-only"]) == 0
    assert "not finished: saeir_ppo/cn-sparse-n3_s1 at 240" in capsys.readouterr().out
    assert not (copy / "table.md").exists() and (copy / "curves.png").is_file()


def test_report_of_fewer_runs_names_the_folders_it_leaves_out(finished, tmp_path, capsys):
    """A command with one method or seed rewrites runs.csv with its runs only, and names the folder's other runs."""
    out, argv = finished
    copy = tmp_path / "bench"
    shutil.copytree(out, copy)
    replaced = copy / "runs" / "mappo" / "cn-sparse-n3_s1.replaced-20261204T000000Z"  # moved aside: no run to report
    shutil.copytree(copy / "runs" / "mappo" / "cn-sparse-n3_s1", replaced)
    one_method = ["--algos", "mappo", "--tasks", "cn-sparse-n3", "--seeds", "2", *TINY_ARGV]
    assert main([*one_method, "--out", str(copy), "--report-only"]) == 0
    printed = capsys.readouterr().out
    left_out = "mappo/cn-sparse-n3_s1, saeir_ppo/cn-sparse-n3_s1, saeir_ppo/cn-sparse-n3_s2"
    assert f"only this command's runs (1); also in {copy / 'runs'}: {left_out} (to report them together" in printed
    assert {(r["algo"], r["seed"]) for r in read_csv(copy / "runs.csv")} == {("mappo", "2")}
    assert main([*argv, "--out", str(copy), "--report-only"]) == 0  # all of them: nothing to name
    assert "also in" not in capsys.readouterr().out
    assert read_csv(copy / "runs.csv") == read_csv(out / "runs.csv")


def test_rerun_skips_finished_runs(finished, capsys):
    out, argv = finished
    before = (out / "runs.csv").read_text()
    assert main([*argv, "--out", str(out)]) == 0
    assert capsys.readouterr().out.count(": skipped") == 4
    assert (out / "runs.csv").read_text() == before


def test_interrupted_run_resumes_from_checkpoint(tmp_path, monkeypatch):
    spec = RunSpec("mappo", "cn-sparse-n3", 3, 300, 2, 100, 2, {"n_steps": 10})
    folder = run_folder(tmp_path, spec)
    from sb3_saeir.evaluation import MultiAgentEvalCallback

    original = MultiAgentEvalCallback.evaluate
    calls = []

    def crash_on_third(self):
        calls.append(self.num_timesteps)
        if len(calls) == 3:
            raise RuntimeError("machine went down")
        return original(self)

    monkeypatch.setattr(MultiAgentEvalCallback, "evaluate", crash_on_third)
    with pytest.raises(RuntimeError, match="machine went down"):
        execute_run(spec, str(folder))
    assert len(list(folder.glob("rl_model_*_steps.zip"))) == 2 and not (folder / "done.json").exists()  # the newest two
    monkeypatch.setattr(MultiAgentEvalCallback, "evaluate", original)
    result = execute_run(spec, str(folder))
    assert result["status"] == "done"
    steps = [int(r["timesteps"]) for r in read_csv(folder / "evaluations.csv")]
    assert calls[:2] == [0, 102] and steps[:2] == [0, 102]  # evaluations before the crash are kept
    assert steps == sorted(set(steps)) and steps[-1] == 300  # resumed at 102: nothing repeated, nothing lost
    assert (folder / "done.json").is_file() and not list(folder.glob("rl_model_*_steps.zip"))


def test_failing_run_does_not_stop_the_others(tmp_path, monkeypatch):
    real = execution.execute_run

    def flaky(spec, folder, num_threads=1):
        if spec.seed == 2:
            raise ValueError("boom")
        return real(spec, folder, num_threads)

    monkeypatch.setattr(execution, "execute_run", flaky)
    argv = ["--algos", "mappo", "--tasks", "cn-sparse-n3", "--seeds", "1-2", *TINY_ARGV, "--out", str(tmp_path)]
    assert main(argv) == 1
    assert "mappo/cn-sparse-n3_s2" in (tmp_path / "failures.txt").read_text()
    assert {r["seed"] for r in read_csv(tmp_path / "runs.csv")} == {"1"}


def test_unknown_method_or_task(tmp_path, capsys):
    assert main(["--algos", "qmix", "--out", str(tmp_path)]) == 2
    assert "unknown methods ['qmix']" in capsys.readouterr().err


def test_entropy_plot(finished, capsys):
    out, _ = finished
    run = out / "runs" / "saeir_ppo" / "cn-sparse-n3_s1"
    assert main(["--entropy-plot", str(run)]) == 0
    assert (run / "system_entropy.png").read_bytes()[:4] == b"\x89PNG"
    printed = capsys.readouterr().out
    assert all(f"| {scale} |" in printed for scale in ("team", "group", "individual"))
    with pytest.raises(ValueError, match="no SAEIR logs"):
        benchmark.plot_system_entropy(out / "runs" / "mappo" / "cn-sparse-n3_s1", out / "x.png")


@pytest.fixture
def custom_tasks(monkeypatch):
    """Two tasks registered for one test: one whose main metric is the return, one with a metric of its own."""
    from sb3_saeir.common import registry

    monkeypatch.setattr(registry, "_TASKS", dict(registry._TASKS))
    registry.register_task("my-return-task", "my_package:Game", main_metric="r")
    registry.register_task("my-score-task", "my_package:Game", main_metric="score")


def test_table_columns_follow_the_tasks_main_metric(custom_tasks):
    assert benchmark.table_columns("cn-sparse-n3") == [
        ("coverage_rate_mean", "Coverage %", 100.0),
        ("ep_rew_mean", "Ep. reward", 1.0),
    ]
    assert benchmark.main_metric("grf-counterattack-easy") == ("success_mean", "Success %", 100.0)
    assert benchmark.table_columns("my-return-task") == [("ep_rew_mean", "Ep. reward", 1.0)]
    assert benchmark.table_columns("my-score-task") == [("score_mean", "score", 1.0), ("ep_rew_mean", "Ep. reward", 1.0)]
    rows = [
        {"algo": "mappo", "task": "my-score-task", "seed": 1, "timesteps": 10, "score_mean": 2.5, "ep_rew_mean": 1.0},
        {"algo": "mappo", "task": "my-return-task", "seed": 1, "timesteps": 10, "ep_rew_mean": 3.0},
    ]
    header = benchmark.table_markdown(rows).splitlines()[0]
    assert header == "| Method | my-return-task Ep. reward | my-score-task score | my-score-task Ep. reward |"


def test_aggregate_intervals_repeat():
    """The bootstrap is seeded: reporting the same ten runs twice writes the same intervals; the IQM is the closed form
    (mean of the middle half: seeds 4-7 of the sorted 0.01..0.10 coverages, 5.5%)."""
    rows = [
        {"algo": "mappo", "task": "cn-sparse-n3", "seed": seed, "timesteps": 100, "coverage_rate_mean": seed / 100}
        for seed in range(1, 11)
    ]
    np.random.seed(123)
    first = benchmark.rliable_markdown(rows, reps=500)
    assert np.random.randint(10**9) == np.random.RandomState(123).randint(10**9)  # the caller's global state is kept
    assert first == benchmark.rliable_markdown(rows, reps=500)
    assert "| cn-sparse-n3 | mappo | 5.50 Coverage % |" in first


def test_aggregate_says_when_the_iqm_trims_no_seed():
    """The IQM trims a quarter of the seeds from each end, rounded down: with 3 seeds none (the mean, and a line under
    the table says so), with 4 seeds one from each end (hand-computed: the mean of the middle two)."""
    three = [
        {"algo": "mappo", "task": "cn-sparse-n3", "seed": seed, "timesteps": 100, "coverage_rate_mean": value}
        for seed, value in zip((1, 2, 3), (0.10, 0.20, 0.90))
    ]
    text = benchmark.rliable_markdown(three, reps=200)
    assert "| cn-sparse-n3 | mappo | 40.00 Coverage % |" in text  # (10 + 20 + 90) / 3: nothing trimmed
    note = (
        "With fewer than 4 seeds the IQM trims none of them (a quarter of the seeds, rounded down, from each end), so it "
        "equals the mean, and its interval is the bootstrap's over the seeds (one seed: its own value): cn-sparse-n3 "
        "mappo (n=3).\n"
    )
    assert text.endswith(note)
    four = [*three, {**three[0], "seed": 4, "coverage_rate_mean": 0.30}]
    text = benchmark.rliable_markdown(four, reps=200)
    assert "| cn-sparse-n3 | mappo | 25.00 Coverage % |" in text  # sorted 10, 20, 30, 90: mean of 20 and 30
    assert "trims none" not in text


def test_iqm_trims_none_below_four_seeds():
    """Against SciPy's trimmed mean at a quarter (rliable's IQM): on distinct, skewed values it equals the plain mean
    exactly when nothing is trimmed."""
    from scipy.stats import trim_mean

    for n_seeds in range(1, 10):
        values = np.arange(n_seeds, dtype=float) ** 3  # (n_seeds,) skewed, so any trim moves the mean
        untrimmed = bool(np.isclose(trim_mean(values, 0.25), values.mean()))
        assert benchmark.statistics.iqm_trims_none(n_seeds) == untrimmed, n_seeds


def test_pairwise_differences_worked_examples():
    """Five seeds each, every A seed above every B seed (a tie inside A): A above B in 100% of the seed pairs, exact
    two-sided p = 2 / C(10, 5) = 2 / 252. Interleaved 1, 3, 5 against 2, 4, 6: A above B in 3 of 9 pairs, and
    P(U <= 3) = 7 / 20 under the null (U's counts for 3 vs 3: 1, 1, 2, 3, 3, 3, 3, 2, 1, 1), so p = 0.7."""

    def rows(algo, values):
        return [
            {"algo": algo, "task": "cn-sparse-n3", "seed": seed, "timesteps": 100, "coverage_rate_mean": value}
            for seed, value in enumerate(values, 1)
        ]

    table = benchmark.pairwise_markdown(
        rows("mappo", [0.30, 0.12, 0.10, 0.09, 0.12]) + rows("saeir_ppo", [0.07, 0.04, 0.08, 0.03, 0.06])
    )
    assert f"| cn-sparse-n3 | mappo (n=5) | saeir_ppo (n=5) | +9.00 Coverage % | 100% | {2 / 252:.3f} |" in table
    table = benchmark.pairwise_markdown(rows("a", [0.01, 0.03, 0.05]) + rows("b", [0.02, 0.04, 0.06]))
    assert "| a (n=3) | b (n=3) | -1.00 Coverage % | 33% | 0.700 |" in table


def test_mann_whitney_with_ties_worked_example():
    """[1, 2] against [2, 3]: mid-ranks 1, 2.5 | 2.5, 4, U = 0.5 (the tie counts half); the six splits of the pooled
    ranks give U = 0.5, 0.5, 2, 2, 3.5, 3.5, four of them at least 1.5 from the mean 2: p = 4 / 6."""
    assert benchmark.mann_whitney([1, 2], [2, 3]) == pytest.approx((0.5, 4 / 6))
    assert benchmark.mann_whitney([1, 2, 3], [4, 5, 6])[1] == pytest.approx(2 / 20)


def enumerated_mann_whitney(first, second):
    """The exact two-sided p-value by listing every split of the pooled mid-ranks (the slow reference)."""
    ranks = rankdata(np.concatenate([first, second]))
    n_first, n_second = len(first), len(second)
    offset, mean = n_first * (n_first + 1) / 2, n_first * n_second / 2
    observed = ranks[:n_first].sum() - offset
    splits = [ranks[list(split)].sum() - offset for split in itertools.combinations(range(n_first + n_second), n_first)]
    return observed, sum(abs(u - mean) >= abs(observed - mean) - 1e-9 for u in splits) / len(splits)


@pytest.mark.parametrize("seed", range(6))
def test_mann_whitney_counts_equal_listing_every_split(seed):
    rng = np.random.default_rng(seed)
    n_first, n_second = rng.integers(1, 8, size=2)
    levels = 4 if seed % 2 else 1000  # few levels: many ties
    first, second = rng.integers(0, levels, n_first) / levels, rng.integers(0, levels, n_second) / levels
    assert benchmark.mann_whitney(list(first), list(second)) == pytest.approx(enumerated_mann_whitney(first, second))


def test_mann_whitney_fifteen_seeds_each_is_exact():
    """Without ties the exact p-value is SciPy's exact one; 15 against 15 all apart: 2 / C(30, 15)."""
    rng = np.random.default_rng(0)
    first, second = rng.normal(size=15), rng.normal(size=15) + 1.0
    expected = mannwhitneyu(first, second, alternative="two-sided", method="exact").pvalue
    assert benchmark.mann_whitney(list(first), list(second))[1] == pytest.approx(expected, rel=1e-9)
    assert benchmark.mann_whitney(list(range(15)), list(range(15, 30)))[1] == pytest.approx(2 / math.comb(30, 15))


def test_system_entropy_summary_worked_example():
    """Ten rollouts of one scale plus an evaluation row without the keys: mean fire rate 0.06, last tenth 0.5."""
    fire = [0.1, 0, 0, 0, 0, 0, 0, 0, 0, 0.5]
    entropy = [3.0, 3.1, 3.1, 3.1, 3.1, 3.1, 3.1, 3.1, 3.1, 3.2]
    rows: list[dict] = [
        {
            "time/total_timesteps": 100 * (i + 1),
            "rollout/intrinsic_reward_mean": 0.0,
            "rollout/intrinsic_fire_rate_team": f,
            "rollout/value_entropy_team": e,
        }
        for i, (f, e) in enumerate(zip(fire, entropy))
    ]
    rows.insert(
        5,
        {
            "time/total_timesteps": 550,
            "rollout/intrinsic_reward_mean": "",
            "rollout/intrinsic_fire_rate_team": "",
            "rollout/value_entropy_team": "",
        },
    )
    summary = benchmark.system_entropy_summary(rows)
    assert summary["team"] == pytest.approx(
        {"fire_rate": 0.06, "fire_rate_late": 0.5, "entropy_first": 3.0, "entropy_last": 3.2}
    )
    assert benchmark.system_entropy_summary(rows, last_fraction=0.2)["team"]["fire_rate_late"] == pytest.approx(0.25)
    with pytest.raises(ValueError, match="no SAEIR logs"):
        benchmark.system_entropy_summary([{"time/total_timesteps": 1}])


def test_numeric_series_skips_rows_without_the_key(finished):
    """SB3's CSV logger leaves keys empty in rows dumped without them (the evaluation rows): a series keeps numbers only."""
    out, _ = finished
    rows = benchmark.read_rows(out / "runs" / "saeir_ppo" / "cn-sparse-n3_s1" / "progress.csv")
    key = "rollout/value_entropy_team"
    assert any(row[key] == "" for row in rows)  # the evaluation rows
    steps, values = benchmark.numeric_series(rows, key)
    assert len(steps) == len(values) == sum(isinstance(row[key], (int, float)) for row in rows) > 0
    assert all(isinstance(v, float) for v in values)
    assert steps == sorted(steps)
    hand = [(1.0, 0.5), (2.0, "")]
    assert benchmark.numeric_series([{"time/total_timesteps": s, key: v} for s, v in hand], key) == ([1.0], [0.5])


def free_port():
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def stop_process_group(group: int, grace_s: float = 20.0) -> None:
    """SIGTERM to every process of ``group``, then SIGKILL to those still there after ``grace_s`` seconds."""
    for sig, wait_s in ((signal.SIGTERM, grace_s), (signal.SIGKILL, 10.0)):
        try:
            os.killpg(group, sig)
        except ProcessLookupError:
            return
        deadline = time.time() + wait_s
        while time.time() < deadline:
            try:
                os.killpg(group, 0)  # raises once no process of the group is left
            except ProcessLookupError:
                return
            time.sleep(0.2)


@pytest.fixture
def ray_head():
    """A one-node Ray cluster of its own: started in a new session, so that its processes (GCS, raylet, workers) form
    one process group, and stopped by stopping that group alone. ``ray stop`` would stop every Ray process on the
    machine, a user's cluster or a second test run's included."""
    ray_bin = Path(sys.executable).parent / "ray"
    port, client_port = free_port(), free_port()
    temp = Path(tempfile.mkdtemp(prefix="ray_"))  # short: Ray's unix socket paths must stay under 108 characters
    command = [
        str(ray_bin),
        "start",
        "--head",
        "--node-ip-address",
        "127.0.0.1",
        "--port",
        str(port),
        "--ray-client-server-port",
        str(client_port),
        "--num-cpus",
        "2",
        "--include-dashboard",
        "false",
        "--temp-dir",
        str(temp),
        "--disable-usage-stats",
    ]
    starter = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    try:
        _, stderr = starter.communicate(timeout=180)
        assert starter.returncode == 0, stderr.decode()
        yield f"127.0.0.1:{port}"
    finally:
        import ray

        ray.shutdown()
        stop_process_group(starter.pid)  # the head's daemons keep the group of `ray start`, whose pid names it
        shutil.rmtree(temp, ignore_errors=True)


def test_ray_cluster_runs(ray_head, tmp_path):
    argv = ["--algos", "mappo", "--tasks", "cn-sparse-n3", "--seeds", "1-2", *TINY_ARGV, "--out", str(tmp_path)]
    assert main([*argv, "--ray-address", ray_head]) == 0
    rows = read_csv(tmp_path / "runs.csv")
    assert {r["seed"] for r in rows} == {"1", "2"}
    assert all((run_folder(tmp_path, RunSpec("mappo", "cn-sparse-n3", s, 200)) / "done.json").is_file() for s in (1, 2))
    assert (tmp_path / "table.md").is_file() and (tmp_path / "curves.png").is_file()
