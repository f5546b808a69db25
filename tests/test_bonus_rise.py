"""benchmarks/bonus_rise.py: the rise of a value above the window's log-mean-exp and the rise that fires the code
bonus, against a brute-force scan of ``saeir_bonus`` and worked examples; the script on a benchmark model."""

import numpy as np
import pytest

from sb3_saeir.benchmark import main as benchmark_main
from sb3_saeir.intrinsic import saeir_bonus


@pytest.fixture(scope="module")
def bonus_rise(load_benchmark_script):
    return load_benchmark_script("bonus_rise")


def test_rise_worked_example(bonus_rise):
    values = np.array([[0.0], [0.0], [2.0], [np.log(3.0)]])
    rise = bonus_rise.rises(values)[:, 0]
    assert np.isnan(rise[0])
    assert rise[1] == pytest.approx(0.0)
    assert rise[2] == pytest.approx(2.0)  # log-mean-exp of (0, 0) is 0
    assert rise[3] == pytest.approx(np.log(3.0) - np.log((2.0 + np.exp(2.0)) / 3.0))
    entropies = bonus_rise.window_entropies(values)[:, 0]
    assert entropies[:2] == pytest.approx([0.0, 0.0])
    assert entropies[2] == pytest.approx(np.log(2.0))
    p = np.array([1.0, 1.0, np.exp(2.0)]) / (2.0 + np.exp(2.0))
    assert entropies[3] == pytest.approx(-(p * np.log(p)).sum())


@pytest.mark.parametrize("earlier", [[0.0, 0.0], [0.3, -0.5, 1.2], [0.0] * 20, [1.0, -2.0, 0.5, 0.0, 3.0, -1.0]])
def test_threshold_is_the_smallest_rise_that_fires(bonus_rise, earlier):
    earlier = np.array(earlier)
    t = len(earlier)
    mean = np.log(np.mean(np.exp(earlier)))
    threshold = bonus_rise.thresholds(bonus_rise.window_entropies(np.append(earlier, 0.0)[:, None]))[t, 0]
    # brute force: append v_t = mean + d on a fine grid of d and ask the package's bonus whether step t fires
    grid = np.linspace(-1.0, 6.0, 7001)
    fires = np.array([saeir_bonus(np.append(earlier, mean + d))[t] > 0 for d in grid])
    assert fires.any() and not fires.all()
    first = grid[np.argmax(fires)]
    assert not fires[grid < first].any() and fires[grid >= first].all()  # one crossing
    assert threshold == pytest.approx(first, abs=2e-3)


def test_flat_earlier_values_need_a_rise_of_about_one(bonus_rise):
    thresholds = bonus_rise.thresholds(bonus_rise.window_entropies(np.zeros((400, 1))))[:, 0]
    assert np.isinf(thresholds[:2]).all()  # H_0 = H_1 = 0: steps 0 and 1 never fire
    assert thresholds[4] == pytest.approx(np.log(4.0), abs=1e-9)  # h(1/2)/(1/2) = 2 log 2 = H_4: q* = 1/2, d* = log 4
    assert np.all(np.diff(thresholds[2:]) < 0) and 1.0 < thresholds[-1] < 1.01


def test_fire_rate_equals_the_code_bonus(bonus_rise):
    rng = np.random.default_rng(4)
    for spread in (0.2, 1.0, 5.0):
        values = spread * rng.normal(size=(25, 300))
        readings = bonus_rise.scale_readings(values, 3.0 * values, np.zeros((25, 300)), np.zeros((25, 300)))
        expected = np.count_nonzero(saeir_bonus(values)[2:]) / values[2:].size
        assert readings["fire_rate"] == pytest.approx(expected)
        assert readings["fire_rate_by_rise"] == pytest.approx(expected)
    # step 6 rises 1.57 above the whole window's earlier values (not enough: only step 2 fires) but 3 above its own
    # episode's (steps 4-5), where it fires; of steps 2-7, one fires in the rollout's window and two in episode windows
    values = np.tile(np.array([0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 3.0, 0.0])[:, None], (1, 2))
    starts = np.zeros((8, 2))
    starts[4] = 1
    rewards = np.zeros((8, 2))
    rewards[3, 0] = 1.0  # the first episode of game 0 ends with a reward
    readings = bonus_rise.scale_readings(values, values, starts, rewards)
    assert readings["fire_rate"] == pytest.approx(1 / 6) and readings["fire_rate_episode_windows"] == pytest.approx(2 / 6)
    # the rises of steps 2-7 by hand: 3 above log-mean-exp(0, 0) = 0, then v_t - log((k + m e^3) / t) with k zeros and
    # m threes before step t
    rises = [3.0, -np.log((2 + np.e**3) / 3), -np.log((3 + np.e**3) / 4), -np.log((4 + np.e**3) / 5)]
    rises += [3.0 - np.log((5 + np.e**3) / 6), -np.log((5 + 2 * np.e**3) / 7)]
    assert readings["n"] == 12 and readings["max"] == pytest.approx(3.0)
    assert readings["above_one"] == pytest.approx(2 / 6)  # steps 2 and 6 (1.57)
    assert readings["quantiles"][0] == pytest.approx(np.median(rises))
    assert readings["profile"] == pytest.approx([0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 3.0, 0.0])
    # steps 2-3 of game 0 are in the run-up to its reward at step 3 (2 of 12 steps from 2 on), and so is the one step
    # that fires in the rollout's window (step 2 of each game: game 0's of 2 firing steps)
    assert readings["run_up_rate"] == pytest.approx(2 / 12) and readings["run_up_share"] == pytest.approx(1 / 2)
    # values x 4 (and the same in return space): step 2 still fires; step 6's second 12 raises the entropy of a window
    # that the first 12 dominates, so it does not; appending a low value to such a window raises it too
    readings = bonus_rise.scale_readings(values, 2.0 * values, starts, rewards)
    assert readings["fire_rate_temperature"] == pytest.approx(1 / 6)
    assert readings["fire_rate_return_space"] == pytest.approx(1 / 6)


def test_main_on_benchmark_models(bonus_rise, tmp_path, capsys):
    argv = ["--algos", "mshg_only", "mappo", "--tasks", "cn-sparse-n3", "--seeds", "1", "-n", "300", "--n-games", "2"]
    argv += ["--eval-freq", "300", "--eval-episodes", "1", "-params", "n_steps:25", "n_epochs:1", "--out", str(tmp_path)]
    assert benchmark_main(argv) == 0
    models = [str(tmp_path / "runs" / algo / "cn-sparse-n3_s1" / "cn-sparse-n3.zip") for algo in ("mshg_only", "mappo")]
    out = tmp_path / "rise.md"
    capsys.readouterr()
    assert bonus_rise.main(["--model", *models, "--n-games", "2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert text == out.read_text()
    rows = [line for line in text.splitlines() if line.startswith(f"| {tmp_path.name}/")]
    assert [row.split(" | ")[1] for row in rows[:4]] == ["team", "group", "individual", "critic"]
    assert rows[0].startswith(f"| {tmp_path.name}/mshg_only/cn-sparse-n3_s1/cn-sparse-n3 | team |")  # folder/algo/run/file
    assert all(row.split(" | ")[2] == str(23 * 6) for row in rows[:4])  # steps 2-24 of 2 games x 3 agents
    assert "| mean value at step 0 | mean value at step 5 |" in text and "| mean value at step 24 |" in text
    assert len(rows) == 16 and rows[4].count(" | ") == 7  # the profile table: model, scale, positions 0-20 and 24
    # the episode-start table: navigation's windows are whole episodes, so no step from 2 on starts one
    assert "| firing steps that are an episode's first step | mean value at episode step 0 |" in text
    assert all(row.split(" | ")[3] == "0.0000" for row in rows[8:12])
    assert all(row.split(" | ")[5] != "-" for row in rows[8:12])  # every window's step 0 is an episode's first
    # the run-up table: a share of steps for every scale, and its firing share a share or "-" (nothing fired)
    assert "| steps in the 10 steps up to a positive reward | firing steps in the 10 steps up to a positive reward |" in text
    assert all(0.0 <= float(row.split(" | ")[3]) <= 1.0 for row in rows[12:])


def test_profile_positions(bonus_rise):
    assert bonus_rise.profile_positions(25) == [0, 5, 10, 15, 20, 24]  # navigation's window
    assert bonus_rise.profile_positions(200) == [*range(0, 200, 20), 199]  # football's: eleven columns, not 41
    assert bonus_rise.profile_positions(3) == [0, 2]


def test_models_without_spec_are_refused(bonus_rise, tmp_path, capsys):
    (tmp_path / "model.zip").write_bytes(b"")
    with pytest.raises(SystemExit):
        bonus_rise.main(["--model", str(tmp_path / "model.zip")])
    assert "no spec.json next to" in capsys.readouterr().err


def test_episode_positions_worked_example(bonus_rise):
    starts = np.array([[0, 1], [0, 0], [1, 0], [0, 0], [0, 1], [1, 0]], dtype=bool)  # (T=6, S=2)
    positions = bonus_rise.episode_positions(starts)
    assert positions[:, 0].tolist() == [-1, -1, 0, 1, 2, 0]  # the window began inside an earlier episode
    assert positions[:, 1].tolist() == [0, 1, 2, 3, 0, 1]


def test_first_step_share_and_episode_profile_worked_example(bonus_rise):
    starts = np.array([[1, 0], [0, 1], [0, 0], [1, 0]], dtype=bool)  # (T=4, S=2)
    fired = np.array([[1, 0], [0, 1], [1, 0], [0, 0]], dtype=bool)
    assert bonus_rise.first_step_share(fired, starts) == pytest.approx(2 / 3)  # 2 of 3 firing steps open an episode
    assert np.isnan(bonus_rise.first_step_share(np.zeros_like(fired), starts))
    values = np.array([[1.0, 9.0], [2.0, 4.0], [3.0, 6.0], [5.0, 7.0]])
    positions = bonus_rise.episode_positions(starts)  # column 0: 0 1 2 0; column 1: -1 0 1 2
    profile = bonus_rise.episode_profile(values, positions, [0, 1, 2, 3])
    np.testing.assert_allclose(profile[:3], [(1.0 + 5.0 + 4.0) / 3, (2.0 + 6.0) / 2, (3.0 + 7.0) / 2])
    assert np.isnan(profile[3])  # 9.0 (position unknown) is left out; no step is at position 3


def test_before_positive_reward_worked_example(bonus_rise):
    # column 0: two episodes, rewarded at steps 3 and 7; column 1: the reward at step 4 is in the episode from step 3
    rewards = np.array([[0, 0], [0, 0], [0, 0], [1, 0], [0, 1], [0, 0], [0, 0], [1, 0]], dtype=float)  # (T=8, S=2)
    starts = np.array([[1, 0], [0, 0], [0, 0], [0, 1], [1, 0], [0, 0], [0, 0], [0, 0]], dtype=bool)
    marked = bonus_rise.before_positive_reward(rewards, starts, run_up=3)
    assert marked[:, 0].tolist() == [False, True, True, True, False, True, True, True]
    # steps 2 and 3 of column 1 are within 3 steps of its reward, but step 2 ends the previous episode
    assert marked[:, 1].tolist() == [False, False, False, True, True, False, False, False]
    fired = np.array([[0, 0], [1, 0], [0, 1], [0, 0], [1, 0], [0, 0], [0, 0], [0, 0]], dtype=bool)
    assert bonus_rise.marked_share(fired, marked) == pytest.approx(1 / 3)  # of steps (1, 0), (2, 1), (4, 0): (1, 0)
    assert np.isnan(bonus_rise.marked_share(np.zeros_like(fired), marked))


def test_before_positive_reward_against_a_slow_loop(bonus_rise):
    rng = np.random.default_rng(3)
    rewards = (rng.random((40, 6)) < 0.1) * rng.choice([-1.0, 1.0], size=(40, 6))  # some negative rewards too
    starts = rng.random((40, 6)) < 0.15
    marked = bonus_rise.before_positive_reward(rewards, starts, run_up=4)
    for s in range(6):
        for t in range(40):
            expected = False
            for u in range(t, min(t + 4, 40)):
                if u > t and starts[u, s]:
                    break  # a new episode begins: its rewards are not this step's
                if rewards[u, s] > 0:
                    expected = True
                    break
            assert marked[t, s] == expected, (t, s)
