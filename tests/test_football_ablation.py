"""benchmarks/football_ablation.py: the rule of the football ablation page on small made-up run folders (the cut at
1M env steps, each of its four cases, its p-values against hand-computed ones), the rule pending while a run it needs
is missing or not final, and the states of the runs."""

import csv
import json
import math
from pathlib import Path

import pytest

from sb3_saeir.benchmark import read_rows, table_markdown

TASK = "grf-3v1-keeper"
K = 250_000  # env steps between evaluations
FIELDS = ["algo", "task", "seed", "timesteps", "env_steps", "n_episodes", "success_mean", "success_std"]
NEVER = None  # a seed that does not reach 10% success by 1M env steps


@pytest.fixture(scope="module")
def ablation(load_benchmark_script):
    return load_benchmark_script("football_ablation")


def spec(algo, seed, budget, n_games=8):
    """A ``spec.json`` of the protocol: 8 games, 100 episodes every 250k env steps, ``budget`` env steps."""
    return dict(algo=algo, seed=seed, task=TASK, n_games=n_games, eval_episodes=100, eval_freq=3 * K,
                n_timesteps=3 * budget, config={"env_kwargs": {"N": 3}})  # fmt: skip


def write_run(folder, spec, successes, done=True, segments=None):
    """A run folder: ``spec.json``, ``evaluations.csv`` (``successes``: ``{env_steps: success fraction}``), and
    ``done.json`` when ``done``, ``segments.json`` when given."""
    folder.mkdir(parents=True)
    (folder / "spec.json").write_text(json.dumps(spec))
    write_evaluations(folder, spec, successes)
    if done:
        (folder / "done.json").write_text("{}")
    if segments is not None:
        (folder / "segments.json").write_text(json.dumps(segments))


def write_evaluations(folder, spec, successes):
    """``evaluations.csv``: one row per ``{env_steps: success fraction}``."""
    with open(folder / "evaluations.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=FIELDS)
        writer.writeheader()
        for steps, success in sorted(successes.items()):
            row = dict(env_steps=steps, timesteps=3 * steps, n_episodes=100, success_mean=success, success_std=0.0)
            writer.writerow(dict(algo=spec["algo"], task=TASK, seed=spec["seed"], **row))


def successes(reach, end):
    """Evaluations every 250k env steps to ``end``: 0% before ``reach``, 30% from it on (``NEVER``: 0% to 1M); every
    evaluation after 1M at 90%, which the cut at 1M must ignore."""
    return {steps: 0.9 if steps > 1_000_000 else (0.3 if reach is not None and steps >= reach else 0.0)
            for steps in range(0, end + 1, K)}  # fmt: skip


def make_results(ablation, root, reaches, skip=(), running=()):
    """Every planned run, each seed's first reach of 10% (and 20%) success from ``reaches[algo]`` (one per seed);
    ``MAPPO`` and ``SAEIR_PPO`` seeds 1-3 as 2M runs, the others as 1M runs. ``skip``: (algo, seed) left without
    files; ``running``: (algo, seed) without ``done.json``, at 500k env steps."""
    for run in ablation.RUNS:
        key = (run.algo, run.seed)
        if key in skip:
            continue
        end = 2_000_000 if run.algo in ("mappo", "saeir_ppo") and run.seed < 4 else 1_000_000
        reach = reaches[run.algo][run.seed - 1]
        if key in running:
            write_run(root / run.folder, spec(run.algo, run.seed, end), successes(reach, 2 * K), done=False)
        else:
            write_run(root / run.folder, spec(run.algo, run.seed, end), successes(reach, end))
    return root


def rule_of(ablation, root):
    """The rule's tests ``{(algo, threshold): (share, p, earlier)}`` and ``{threshold: case}`` of the runs under root."""
    states = [ablation.read_run(run, root) for run in ablation.RUNS]
    tests = ablation.rule_tests(states)
    found = {key: (test.share, test.p, test.earlier) for key, test in tests.items()}
    return found, {cells[0]: cells[-1] for cells in ablation.case_rows(states, tests)}


MAPPO_LATE = [3 * K, 3 * K, 3 * K, 3 * K]  # every MAPPO seed first at 750k env steps
SAEIR_EARLY = [K, K, K, K]


def test_the_smallest_p_values(ablation):
    assert ablation.smallest_p(3, 4) == pytest.approx(1 / 35)
    assert ablation.smallest_p(4, 4) == pytest.approx(1 / 70)
    # the test reaches them exactly when every seed of the arm is earlier than every MAPPO seed
    assert ablation.earlier_test([K] * 3, [3 * K] * 4) == (1.0, pytest.approx(1 / 35))
    assert ablation.earlier_test([K] * 4, [3 * K] * 4) == (1.0, pytest.approx(1 / 70))


def test_the_critic_takes_the_credit(ablation, tmp_path):
    reaches = {"mappo": MAPPO_LATE, "saeir_ppo": SAEIR_EARLY, "mshg_only": [K] * 3, "sae_only": [NEVER] * 3}
    tests, cases = rule_of(ablation, make_results(ablation, tmp_path, reaches))
    for threshold in (10.0, 20.0):
        assert tests[("mshg_only", threshold)] == (1.0, pytest.approx(1 / 35), True)
        assert tests[("sae_only", threshold)] == (0.0, 1.0, False)  # censored at 1M: after every MAPPO seed
        assert tests[("saeir_ppo", threshold)] == (1.0, pytest.approx(1 / 70), True)
    assert cases == {"10%": "the critic takes the credit", "20%": "the critic takes the credit"}


def test_the_bonus_takes_it(ablation, tmp_path):
    reaches = {"mappo": MAPPO_LATE, "saeir_ppo": MAPPO_LATE, "mshg_only": [4 * K] * 3, "sae_only": [K, 2 * K, K]}
    tests, cases = rule_of(ablation, make_results(ablation, tmp_path, reaches))
    assert tests[("sae_only", 10.0)] == (1.0, pytest.approx(1 / 35), True)
    assert tests[("mshg_only", 10.0)] == (0.0, 1.0, False)  # 1M against 750k: later on every pair
    assert tests[("saeir_ppo", 10.0)] == (0.5, 1.0, False)  # every seed tied with every MAPPO seed
    assert cases == {"10%": "the bonus takes it", "20%": "the bonus takes it"}


def test_both(ablation, tmp_path):
    reaches = {"mappo": MAPPO_LATE, "saeir_ppo": SAEIR_EARLY, "mshg_only": [K, 2 * K, 2 * K], "sae_only": [2 * K] * 3}
    tests, cases = rule_of(ablation, make_results(ablation, tmp_path, reaches))
    assert tests[("mshg_only", 20.0)] == (1.0, pytest.approx(1 / 35), True)
    assert tests[("sae_only", 20.0)] == (1.0, pytest.approx(1 / 35), True)
    assert cases == {"10%": "both", "20%": "both"}


def test_neither_with_a_hand_computed_p(ablation, tmp_path):
    # MSHG-only [250k, 250k, 750k] against MAPPO [500k] x 4: later on 4 of 12 pairs, earlier on 8 (67%). The pooled
    # mid-ranks are 1.5, 1.5 | 4.5 x 4 | 7; of the 35 ways to give 3 of them to MSHG-only, those with a rank sum at most
    # the observed 10 are both 1.5s with one 4.5 (4 ways) and both 1.5s with the 7 (1 way): p = 5/35 = 1/7.
    reaches = {"mappo": [2 * K] * 4, "saeir_ppo": [K, K, K, NEVER], "mshg_only": [K, K, 3 * K], "sae_only": [NEVER] * 3}
    tests, cases = rule_of(ablation, make_results(ablation, tmp_path, reaches))
    assert tests[("mshg_only", 10.0)] == (pytest.approx(8 / 12), pytest.approx(1 / 7), False)
    assert tests[("sae_only", 10.0)] == (0.0, 1.0, False)
    # SAEIR_PPO [250k x 3, censored] against [500k] x 4: earlier on 12 of 16 pairs; rank sum 6 + 8 = 14 of the
    # observed; splits at most 14: the three 2s with any of the five others (5), p = 5/70
    assert tests[("saeir_ppo", 10.0)] == (pytest.approx(12 / 16), pytest.approx(5 / 70), False)
    assert cases == {"10%": "neither", "20%": "neither"}


def test_a_censored_seed_ranks_after_one_that_reaches_at_1m(ablation, tmp_path):
    # every MAPPO seed censored at 1M (each 90% from 1.25M on, which the cut ignores); MSHG-only reaches at 1M itself
    reaches = {"mappo": [NEVER] * 4, "saeir_ppo": [NEVER] * 4, "mshg_only": [4 * K] * 3, "sae_only": [NEVER] * 3}
    tests, cases = rule_of(ablation, make_results(ablation, tmp_path, reaches))
    assert tests[("mshg_only", 10.0)] == (1.0, pytest.approx(1 / 35), True)
    assert tests[("sae_only", 10.0)] == (0.5, 1.0, False)  # censored against censored: every pair tied
    assert tests[("saeir_ppo", 10.0)] == (0.5, 1.0, False)
    assert cases == {"10%": "the critic takes the credit", "20%": "the critic takes the credit"}


def test_the_cut_at_1m(ablation, tmp_path):
    # MAPPO seed 1 (a 2M run) is at 8% at 1M env steps and 90% from 1.25M on: censored at 1M for 10%
    reaches = {"mappo": [NEVER, 3 * K, 3 * K, 3 * K], "saeir_ppo": SAEIR_EARLY, "mshg_only": [K] * 3, "sae_only": [K] * 3}
    root = make_results(ablation, tmp_path, reaches)
    evaluations = {0: 0.0, K: 0.0, 2 * K: 0.05, 3 * K: 0.05, 4 * K: 0.08, 5 * K: 0.5, 8 * K: 0.9}
    write_evaluations(root / ablation.run_folder("mappo", 1), spec("mappo", 1, 2_000_000), evaluations)
    state = ablation.read_run(ablation.RUNS[0], root)
    assert state.final and [row["env_steps"] for row in state.window_rows] == [0, K, 2 * K, 3 * K, 4 * K]
    assert ablation.first_reach(state.curve, 10.0) == (1_000_000.0, False)
    assert ablation.main(["--results", str(root)]) == 0
    out = root / "football-ablation"
    assert "| MAPPO | 1 | final at 1M env steps | 0 | 0 | 5 | 5 | 8 |" in (out / "success.md").read_text()
    assert "| MAPPO | 10% | s1 > 1M, s2 0.75M, s3 0.75M, s4 0.75M | 4 of 4 |" in (out / "reaches.md").read_text()
    runs = (out / "runs.md").read_text()
    line = "| MAPPO | 1 | `football-probe/runs/mappo` | 8 games, 100 episodes every 0.25M env steps | 2M | 5 of 7 |"
    assert f"{line} done.json | final at 1M env steps |" in runs
    # MSHG-only [250k] x 3 against MAPPO [censored, 750k x 3]: every pair earlier, p = 1/35
    rule = (out / "rule.md").read_text()
    assert "| MSHG-only | 10% | 3 vs 4 | 100% | 0.029 | yes |" in rule
    assert "| SAEIR_PPO | 10% | 4 vs 4 | 100% | 0.014 | yes |" in rule
    assert "| 10% | yes | yes | both |" in rule
    assert "Every run is final: the rule is applied." in rule
    # the final runs' file, cut at 1M: MAPPO seed 1's 1.25M and 2M evaluations are not in it
    rows = read_rows(out / "runs.csv")
    assert len(rows) == 14 * 5 and max(float(row["env_steps"]) for row in rows) == 1_000_000
    mappo_1 = [row["success_mean"] for row in rows if row["algo"] == "mappo" and row["seed"] == 1]
    assert mappo_1 == [0.0, 0.0, 0.05, 0.05, 0.08]
    assert (out / "table.md").read_text() == table_markdown(rows)


def test_a_legs_end_evaluation_off_the_grid_is_left_out(ablation, tmp_path):
    # SAEIR_PPO seed 4 trains in legs, each ending one rollout past the grid point with an evaluation there (251,200
    # env steps): at 90% it would be the seed's first reach of 10% and move its rank, if it were read
    reaches = {"mappo": MAPPO_LATE, "saeir_ppo": [K, K, K, 2 * K], "mshg_only": [K] * 3, "sae_only": [K] * 3}
    root = make_results(ablation, tmp_path, reaches)
    evaluations = {**successes(2 * K, 1_000_000), K + 1_200: 0.9, 2 * K + 800: 0.9}
    write_evaluations(root / ablation.run_folder("saeir_ppo", 4), spec("saeir_ppo", 4, 1_000_000), evaluations)
    state = ablation.read_run(ablation.RUNS[7], root)
    assert (state.run.algo, state.run.seed) == ("saeir_ppo", 4)
    assert [row["env_steps"] for row in state.window_rows] == [0, K, 2 * K, 3 * K, 4 * K]
    assert ablation.first_reach(state.curve, 10.0) == (2.0 * K, True)
    ablation.main(["--results", str(root)])
    out = root / "football-ablation"
    assert "| SAEIR_PPO | 10% | s1 0.25M, s2 0.25M, s3 0.25M, s4 0.5M | 4 of 4 |" in (out / "reaches.md").read_text()
    assert "| 5 of 7 | done.json | final at 1M env steps |" in (out / "runs.md").read_text()
    assert {row["env_steps"] for row in read_rows(out / "runs.csv")} == {0, K, 2 * K, 3 * K, 4 * K}


def test_pending_while_a_run_is_missing_or_not_final(ablation, tmp_path):
    reaches = {"mappo": MAPPO_LATE, "saeir_ppo": SAEIR_EARLY, "mshg_only": [K] * 3, "sae_only": [NEVER] * 3}
    root = make_results(ablation, tmp_path, reaches, skip={("sae_only", 3)}, running={("mshg_only", 2)})
    tests, cases = rule_of(ablation, root)
    assert tests[("mshg_only", 10.0)] == (None, None, None)
    assert tests[("sae_only", 10.0)] == (None, None, None)
    assert tests[("saeir_ppo", 10.0)] == (1.0, pytest.approx(1 / 70), True)  # its runs and MAPPO's are final
    waits = "pending: waits for MSHG-only s2, SAE-only s3"
    assert cases == {"10%": waits, "20%": waits}
    ablation.main(["--results", str(root)])
    rule = (root / "football-ablation" / "rule.md").read_text()
    assert "Pending: not final yet: MSHG-only s2, SAE-only s3." in rule
    # MSHG-only s2 (running) has reached 10% at 250k: all three at 250k, earlier than every MAPPO seed (1/35)
    still = "(smallest p still possible: 0.029)"
    assert f"| MSHG-only | 10% | 3 vs 4 | - | - | pending: waits for MSHG-only s2 {still} |" in rule
    assert "| 20% | - | - | pending: waits for MSHG-only s2, SAE-only s3 |" in rule
    case_lines = [line for line in rule.splitlines() if line.startswith(("| 10% |", "| 20% |"))]
    assert len(case_lines) == 2 and all(line.split(" | ")[-1].startswith("pending") for line in case_lines)
    reaches_md = (root / "football-ablation" / "reaches.md").read_text()
    assert "| MSHG-only | 10% | s1 0.25M, s2 0.25M (not final), s3 0.25M | 2 of 3 |" in reaches_md
    assert "| SAE-only | 10% | s1 > 1M, s2 > 1M, s3 - (no run files yet) | 2 of 3 |" in reaches_md


def test_the_reaches_a_run_not_final_can_still_end_with(ablation, tmp_path):
    reaches = {"mappo": MAPPO_LATE, "saeir_ppo": SAEIR_EARLY, "mshg_only": [K, K, K], "sae_only": [K, NEVER, 3 * K]}
    running = {("mshg_only", 2), ("sae_only", 2)}  # both at 500k env steps: MSHG-only s2 reached at 250k, SAE-only s2 not
    root = make_results(ablation, tmp_path, reaches, skip={("sae_only", 3)}, running=running)
    state = {(r.algo, r.seed): ablation.read_run(r, root) for r in ablation.RUNS}
    assert ablation.reaches_still_possible(state[("mshg_only", 2)], 10.0) == [K]
    assert ablation.reaches_still_possible(state[("sae_only", 2)], 10.0) == [3 * K, 4 * K, math.inf]
    assert ablation.reaches_still_possible(state[("sae_only", 3)], 10.0) == [0, K, 2 * K, 3 * K, 4 * K, math.inf]
    assert ablation.reaches_still_possible(state[("sae_only", 1)], 10.0) == [K]  # final: its own
    assert ablation.reaches_still_possible(state[("mappo", 1)], 50.0) == [math.inf]  # final, censored at 1M


def test_the_smallest_p_still_possible_with_a_hand_count(ablation, tmp_path):
    # MAPPO [750k x 3, 500k] (final); MSHG-only s1, s2 final at 500k, s3 without files. Its best is s3 before 500k
    # (0 or 250k): then MSHG-only holds the pooled earliest time and two of the three 500k times, the third MAPPO's.
    # Of the 35 ways to give 3 of the 7 times to MSHG-only, those at least as early are the earliest time with any two
    # of the three 500k times: 3, so p = 3/35 (s3 at 500k: the four 500k times hold all three, C(4,3) = 4, p = 4/35).
    reaches = {"mappo": [3 * K, 3 * K, 3 * K, 2 * K], "saeir_ppo": SAEIR_EARLY, "mshg_only": [2 * K, 2 * K, K],
               "sae_only": [2 * K, NEVER, K]}  # fmt: skip
    root = make_results(ablation, tmp_path, reaches, skip={("mshg_only", 3), ("sae_only", 3)}, running={("sae_only", 2)})
    states = [ablation.read_run(run, root) for run in ablation.RUNS]
    tests = ablation.rule_tests(states)
    assert tests[("mshg_only", 10.0)].p is None
    assert tests[("mshg_only", 10.0)].p_still == pytest.approx(3 / 35)
    # SAE-only s2 has not reached 10% by 500k: its best is 750k, s3's the first evaluation; no arrangement is better
    mappo = [3 * K, 3 * K, 3 * K, 2 * K]
    assert tests[("sae_only", 10.0)].p_still == pytest.approx(ablation.earlier_test([2 * K, 3 * K, 0], mappo)[1])
    assert tests[("sae_only", 10.0)].p_still > 0.05
    assert tests[("saeir_ppo", 10.0)].p_still is None  # applied: no bound
    # the bound leaves MAPPO's seeds as they are, and gives none while one of them is not final
    root = make_results(ablation, tmp_path / "b", reaches, skip={("mshg_only", 3)}, running={("mappo", 4)})
    assert ablation.rule_tests([ablation.read_run(run, root) for run in ablation.RUNS])[("mshg_only", 10.0)].p_still is None


def test_the_states_of_the_runs(ablation, tmp_path):
    root = tmp_path
    folder = ablation.run_folder
    write_run(root / folder("mappo", 1), spec("mappo", 1, 2_000_000), successes(NEVER, 2_000_000))
    # the probe's SAEIR_PPO seed 1: no done.json committed, its segments.json reached the budget
    write_run(root / folder("saeir_ppo", 1), spec("saeir_ppo", 1, 2_000_000), successes(K, 2_000_000), done=False,
              segments=[{"resumed_at": 0, "reached": 6_000_000}])  # fmt: skip
    write_run(root / folder("saeir_ppo", 2), spec("saeir_ppo", 2, 2_000_000), successes(K, 2 * K), done=False,
              segments=[{"resumed_at": 0, "reached": 1_600_000}])  # fmt: skip
    write_run(root / folder("mshg_only", 1), spec("mshg_only", 1, 1_000_000), successes(K, 2 * K), done=False)
    write_run(root / folder("mshg_only", 2), spec("mshg_only", 2, 1_000_000, n_games=16), successes(K, 1_000_000))
    write_run(root / folder("mshg_only", 3), spec("mshg_only", 3, 1_000_000), successes(K, 3 * K))  # done at 750k
    write_run(root / folder("saeir_ppo", 4), spec("saeir_ppo", 4, K), successes(K, K))  # its first leg, 250k
    states = {(s.run.algo, s.run.seed): s for s in (ablation.read_run(run, root) for run in ablation.RUNS)}
    assert len(states) == 14
    assert states[("mappo", 1)].state() == "final at 1M env steps"
    assert states[("saeir_ppo", 1)].state() == "final at 1M env steps"
    assert states[("saeir_ppo", 1)].finished_by == "segments.json (no done.json)"
    assert states[("saeir_ppo", 2)].state() == "running, at 0.5M env steps"
    assert states[("mshg_only", 1)].state() == "running, at 0.5M env steps"
    assert states[("mshg_only", 2)].state() == "differs from the protocol: games 16 (expected 8)"
    assert not states[("mshg_only", 2)].final
    assert states[("mshg_only", 3)].state() == "stopped before 1M env steps, at 0.75M env steps"
    assert states[("saeir_ppo", 4)].state() == "running, at 0.25M env steps (its leg to 0.25M env steps finished)"
    assert states[("sae_only", 1)].state() == "no run files yet"
    assert [s.final for s in states.values()].count(True) == 2
    ablation.main(["--results", str(root)])
    runs = (root / "football-ablation" / "runs.md").read_text().splitlines()
    assert len(runs) == 2 + 14
    assert "| SAEIR_PPO | 1 | `football-probe/runs/saeir_ppo` | 8 games, 100 episodes every 0.25M env steps | 2M | 5 of 9 " \
        "| segments.json (no done.json) | final at 1M env steps |" in runs  # fmt: skip
    assert "| SAE-only | 3 | `football-ablation/runs/sae_only/grf-3v1-keeper_s3` | - | - | - | - | no run files yet |" in runs
    rows = read_rows(root / "football-ablation" / "runs.csv")  # the two final runs only, cut at 1M
    assert sorted({(row["algo"], row["seed"]) for row in rows}) == [("mappo", 1), ("saeir_ppo", 1)] and len(rows) == 10


def test_no_run_files_at_all_and_the_bonus_file(ablation, tmp_path):
    assert ablation.main(["--results", str(tmp_path)]) == 0
    out = tmp_path / "football-ablation"
    runs = (out / "runs.md").read_text().splitlines()
    assert len(runs) == 2 + 14 and all(line.endswith("| no run files yet |") for line in runs[2:])
    assert (out / "curves.png").is_file()
    assert not (out / "runs.csv").exists() and not (out / "table.md").exists()  # no final run: no rows for the summary
    assert "| `kept-models/saeir_ppo_s4_1000k/grf-3v1-keeper.zip` | 1M | not read yet |" in (out / "bonus_rise.md").read_text()
    (out / "bonus_rise.md").write_text("made by report.sh bonus\n")
    ablation.main(["--results", str(tmp_path)])
    assert (out / "bonus_rise.md").read_text() == "made by report.sh bonus\n"  # left untouched


def test_the_rule_is_written_verbatim(ablation):
    def words(text):
        return " ".join(text.split())

    assert words(ablation.RULE) in words(ablation.__doc__)
    page = Path(__file__).parent.parent / "docs" / "results" / "football-ablation.md"
    assert words(ablation.RULE) in words(page.read_text())
