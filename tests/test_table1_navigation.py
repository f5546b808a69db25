"""benchmarks/table1_navigation.py: the arithmetic of the Table 1 navigation page on small made-up run folders (the
difference of a seed, its interval and verdict, the reward ratio in the authors' unit, the bonus table), and runs that
are running, differ from the protocol or have no files yet shown as such, never as finals."""

import csv
import json
import math

import numpy as np
import pytest

from sb3_saeir.benchmark import read_rows, table_markdown

N3, N4 = "cn-sparse-no-penalty-n3", "cn-sparse-no-penalty-n4"
BUDGET = 20_000_000
FIELDS = ["algo", "task", "seed", "timesteps", "env_steps", "n_episodes", "coverage_rate_mean", "coverage_rate_std"]
BONUS_TABLE = """Per 1M env steps: the bonus's fire rate (made up):

| env steps | fire rate group | fire rate individual | fire rate team | bonus mean group |
|---|---|---|---|---|
| 0M-1M | 4.00e-05 | 1.00e-05 | 0.00e+00 | 1.00e-04 |
| 1M-2M | 0.00e+00 | - | 0.00e+00 | 0.00e+00 |
| 2M-3M | 2.00e-06 | 3.00e-07 | 0.00e+00 | 5.00e-06 |
"""


@pytest.fixture(scope="module")
def table1(load_benchmark_script):
    return load_benchmark_script("table1_navigation")


def evaluation(env_steps, coverage, std=0.3, reward=0.0, n_episodes=200):
    """One evaluation row (``evaluations.csv``'s columns that the page reads)."""
    return dict(env_steps=env_steps, n_episodes=n_episodes, coverage_rate_mean=coverage, coverage_rate_std=std,
                ep_rew_mean=reward)  # fmt: skip


def write_run(folder, spec, rows, done):
    """A run folder: ``spec.json``, ``evaluations.csv`` (``rows``) and, when ``done``, ``done.json``."""
    folder.mkdir(parents=True)
    (folder / "spec.json").write_text(json.dumps(spec))
    with open(folder / "evaluations.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=[*FIELDS, "ep_rew_mean"])
        writer.writeheader()
        for row in rows:
            n = spec["game_kwargs"]["N"] if "game_kwargs" in spec else spec["config"]["env_kwargs"]["N"]
            writer.writerow(
                dict(algo=spec["algo"], task=spec["task"], seed=spec["seed"], timesteps=n * row["env_steps"], **row)
            )
    if done:
        (folder / "done.json").write_text("{}")


def spec(algo, seed, n, n_games=128):
    """The ``spec.json`` of this study's protocol on ``cn-sparse-no-penalty-n<n>``."""
    return dict(algo=algo, seed=seed, task=f"cn-sparse-no-penalty-n{n}", game_kwargs={"N": n, "collision_penalty": 0.0},
                n_games=n_games, eval_episodes=200, eval_freq=1_000_000 * n, n_timesteps=BUDGET * n)  # fmt: skip


def old_spec(algo):
    """N=3 seed 1's ``spec.json``: made as task ``cn-sparse-n3`` with the penalty off in ``env_kwargs``, no ``game_kwargs``."""
    return dict(algo=algo, seed=1, task="cn-sparse-n3", config={"env_kwargs": {"N": 3, "collision_penalty": 0.0}},
                n_games=128, eval_episodes=200, eval_freq=3_000_000, n_timesteps=3 * BUDGET)  # fmt: skip


@pytest.fixture
def results(tmp_path):
    """N=3 seed 1 of both methods final (in the calibrated study's folders), MAPPO N=4 final, SAEIR_PPO N=4 running at
    7M env steps with a bonus table, MAPPO N=3 seed 2 finished on 16 games (not the protocol); the rest not started."""
    root = tmp_path / "results"
    calibrated = root / "navigation-calibrated" / "runs"
    write_run(calibrated / "mappo-no-penalty" / "cn-sparse-n3_s1", old_spec("mappo"),
              [evaluation(0, 0.0), evaluation(BUDGET, 0.6, 0.3, 37.5)], done=True)  # fmt: skip
    write_run(calibrated / "saeir_ppo-no-penalty" / "cn-sparse-n3_s1", old_spec("saeir_ppo"),
              [evaluation(0, 0.0), evaluation(BUDGET, 0.7, 0.4, 40.0)], done=True)  # fmt: skip
    study = root / "table1-navigation" / "runs"
    write_run(
        study / "mappo" / f"{N4}_s1", spec("mappo", 1, 4), [evaluation(0, 0.0), evaluation(BUDGET, 0.45, 0.2, 32.0)], True
    )
    write_run(
        study / "saeir_ppo" / f"{N4}_s1", spec("saeir_ppo", 1, 4), [evaluation(0, 0.0), evaluation(7_000_064, 0.3)], False
    )
    (study / "saeir_ppo" / f"{N4}_s1" / "bonus_by_1m.md").write_text(BONUS_TABLE)
    write_run(study / "mappo" / f"{N3}_s2", spec("mappo", 2, 3, n_games=16), [evaluation(BUDGET, 0.9)], True)
    return root


def test_the_difference_of_a_seed_its_interval_and_verdict(table1):
    mappo, saeir = evaluation(BUDGET, 0.6, 0.3), evaluation(BUDGET, 0.7, 0.4)
    # 10 points; standard errors 30 / sqrt(199) and 40 / sqrt(199), so the half width is 1.95996 x 50 / sqrt(199)
    value, low, high = table1.difference(mappo, saeir)
    assert value == pytest.approx(10.0)
    assert (low, high) == pytest.approx((3.0530918, 16.9469082))
    assert table1.verdict(low, high) == "ahead"
    assert table1.verdict(-16.9469082, -3.0530918) == "behind"
    assert table1.verdict(-1.0, 2.0) == table1.verdict(0.0, 2.0) == "level"  # an interval that holds 0
    same = table1.difference(mappo, mappo)
    assert same[0] == 0.0 and table1.verdict(*same[1:]) == "level"


def test_the_reward_ratio_in_the_authors_unit(table1):
    # docs/tasks.md: Table 1's MAPPO at N=3, 3.38 = 1.75 x 3 x 0.6443
    assert table1.reward_ratio(3.38, 64.43, 3) == pytest.approx(1.7486678)
    assert table1.reward_ratio(37.84, 66.333333, 3) == pytest.approx(19.015075, rel=1e-6)


def test_table1_rows_of_the_new_ids_are_the_paper_tasks(table1):
    pages = table1  # the builder reads Table 1 through results_pages
    for algo in ("mappo", "saeir_ppo"):
        assert pages.PAPER[(N3, algo)] == pages.PAPER[("cn-sparse-n3", algo)]
        assert pages.PAPER_REWARD[(N4, algo)] == pages.PAPER_REWARD[("cn-sparse-n4", algo)]
    assert pages.PAPER_ENV_STEPS[N3] == pages.PAPER_ENV_STEPS[N4] == BUDGET


def test_the_states_of_the_runs(table1, results):
    states = {(s.run.task, s.run.algo, s.run.seed): s for s in (table1.read_run(run, results) for run in table1.RUNS)}
    assert states[(N3, "mappo", 1)].state() == "final at 20M env steps"  # cn-sparse-n3 with the penalty off: the same game
    assert states[(N4, "saeir_ppo", 1)].state() == "running, at 7M env steps"
    assert states[(N4, "saeir_ppo", 1)].final is None
    assert states[(N3, "mappo", 2)].state() == "differs from the protocol: games 16 (expected 128)"
    assert states[(N3, "mappo", 2)].final is None
    assert states[(N3, "saeir_ppo", 3)].state() == "no run files yet"


def test_the_page_tables_show_finals_and_mark_the_rest(table1, results):
    assert table1.main(["--results", str(results)]) == 0
    out = results / "table1-navigation"
    assert {path.name for path in out.iterdir()} >= {"finals.md", "differences.md", "reward.md", "curves.png", "fire_rate.png"}
    finals = (out / "finals.md").read_text()
    assert "| N=3 | MAPPO | 64.43\u00a0±\u00a01.56 | 1 | s1 60.00 | 60.00 | - |" in finals  # seed 2 differs: not a final
    assert "s2 differs from the protocol" in finals
    assert "| N=4 | SAEIR_PPO | 66.80\u00a0±\u00a01.54 | 0 | - | - | - | s1 running, at 7M env steps |" in finals
    differences = (out / "differences.md").read_text()
    assert "| N=3 | 1 | 60.00 | 70.00 | +10.00 | [+3.05,\u00a0+16.95] | ahead |" in differences
    assert "| N=4 | 1 | 45.00 | running, at 7M env steps | - | - | waits for both finals |" in differences
    assert "| N=3 | 1 of 3 | 1 | 0 | 0 | +10.00 |" in differences
    # ours: 37.5 per agent at 60% coverage, N=3: 37.5 / (3 x 0.6) = 20.83, 37.5 / 3.38 = 11.1 times Table 1's reward
    reward = (out / "reward.md").read_text()
    assert "| N=3 | MAPPO | 64.43 | 3.38\u00a0±\u00a00.06 | 1.75 | 1 | 60.00 | 37.50 | 20.83 | 11.1 |" in reward
    assert "| N=4 | SAEIR_PPO | 66.80 | 4.79\u00a0±\u00a00.02 | 1.79 | 0 | - | - | - | - |" in reward


def test_the_bonus_table_and_its_fire_rates(table1, results):
    found = table1.read_bonus_table(results / "table1-navigation" / "runs" / "saeir_ppo" / f"{N4}_s1" / "bonus_by_1m.md")
    np.testing.assert_array_equal(found.starts, [0.0, 1e6, 2e6])
    np.testing.assert_array_equal(found.ends, [1e6, 2e6, 3e6])
    assert set(found.fire_rates) == {"group", "individual", "team"}
    np.testing.assert_array_equal(found.fire_rates["group"], [4e-5, 0.0, 2e-6])
    assert math.isnan(found.fire_rates["individual"][1])  # "-": a window without that scale's logs
    table1.main(["--results", str(results)])
    lines = (results / "table1-navigation" / "fire_rate.md").read_text().splitlines()
    running = "| N=4 | 1 | running, at 7M env steps | `bonus_by_1m.md` (1M windows) |"
    assert f"{running} team | 0.00e+00 | 0 (none fired) | 0.00e+00 | 0 of 3 |" in lines
    assert f"{running} group | 4.00e-05 | 2.00e-06 (2M-3M) | 1.40e-05 | 2 of 3 |" in lines
    assert f"{running} individual | 1.00e-05 | 3.00e-07 (2M-3M) | 5.15e-06 | 2 of 3 |" in lines
    assert any(line.startswith("| N=3 | 2 | no run files yet | no bonus table yet") for line in lines)


def test_the_final_runs_file_holds_finals_only_under_their_readings_id(table1, results):
    table1.main(["--results", str(results)])
    out = results / "table1-navigation"
    rows = read_rows(out / "runs.csv")
    # N=3 seed 1 of both methods (made as cn-sparse-n3 with the penalty off) and MAPPO N=4; not the running SAEIR_PPO
    # N=4 nor MAPPO N=3 seed 2 (16 games)
    assert sorted({(row["task"], row["algo"], row["seed"]) for row in rows}) == [
        (N3, "mappo", 1), (N3, "saeir_ppo", 1), (N4, "mappo", 1)
    ]  # fmt: skip
    assert len(rows) == 6
    table = (out / "table.md").read_text()
    assert table == table_markdown(rows)
    assert "| mappo | 60.00 ± 0.00 (n=1) |" in table and "| **45.00 ± 0.00 (n=1)** |" in table


def test_no_run_files_at_all_is_a_page_of_states(table1, tmp_path):
    out = tmp_path / "table1-navigation"
    out.mkdir()
    (out / "runs.csv").write_text("stale\n")  # from an earlier build: no run is final now, so it goes
    (out / "table.md").write_text("stale\n")
    assert table1.main(["--results", str(tmp_path)]) == 0
    runs = (out / "runs.md").read_text().splitlines()
    assert len(runs) == 2 + len(table1.RUNS) and all(line.endswith("| no run files yet |") for line in runs[2:])
    assert (out / "fire_rate.png").is_file()
    assert not (out / "runs.csv").exists() and not (out / "table.md").exists()
