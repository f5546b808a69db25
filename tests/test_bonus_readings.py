"""benchmarks/bonus_readings.py: rollouts collected as training does, without any update; the readings' statistics
against a direct count; a benchmark run's model.zip found with its spec.json."""

import numpy as np
import pytest

from sb3_saeir.benchmark import main as benchmark_main
from sb3_saeir.intrinsic import saeir_bonus


@pytest.fixture(scope="module")
def bonus_readings(load_benchmark_script):
    return load_benchmark_script("bonus_readings")


def test_rollouts_do_not_train_and_statistics_count_the_bonus(bonus_readings):
    experiment = bonus_readings.load_experiment(None, "saeir_ppo", "cn-sparse-n3", n_games=4, seed=3)
    before = {key: value.clone() for key, value in experiment.model.policy.state_dict().items()}
    windows = bonus_readings.rollout_windows(experiment, n_rollouts=2)
    after = experiment.model.policy.state_dict()
    assert all(np.array_equal(before[key].numpy(), after[key].numpy()) for key in before)
    experiment.close()
    assert len(windows) == 2 and windows[0]["values"].shape == (25, 12, 3)  # (T, games * agents, scales)
    assert windows[0]["scales"] == ("team", "group", "individual")
    assert not np.array_equal(windows[0]["values"], windows[1]["values"])  # the second rollout continues the games

    stats = bonus_readings.reading_statistics(windows, coef=0.1, reset_at_episode_start=False)
    for reading in bonus_readings.READINGS:
        bonus = [
            0.1 * saeir_bonus(w["values"], reading, last_values=w["last_values"], last_dones=w["last_dones"]) for w in windows
        ]
        team = np.concatenate([b[..., 0] for b in bonus], axis=1)  # (T, 2 * 12)
        assert stats[reading]["team"]["fire_rate"] == pytest.approx(np.count_nonzero(team) / team.size)
        assert stats[reading]["team"]["fire_rate_by_step"].shape == (25,)
        if np.count_nonzero(team):
            assert stats[reading]["team"]["fired_mean"] == pytest.approx(team[team > 0].mean())
    assert 0.35 < stats["supplement"]["all"]["fire_rate"] < 0.6  # near-flat untrained values: about half
    assert stats["supplement"]["all"]["fire_rate_by_step"][-1] == 0.0  # every rollout ends its episodes here


def test_statistics_pool_windows_per_scale_by_hand(bonus_readings, monkeypatch):
    """With the bonus stubbed to the values themselves: two windows of 2 steps, one series, scales team and group."""
    monkeypatch.setattr(bonus_readings, "saeir_bonus", lambda values, variant, **kwargs: values)
    first = np.array([[[0.5, 0.0]], [[0.0, 0.0]]])  # (T, E, K)
    second = np.array([[[0.0, 0.0]], [[0.3, 0.2]]])
    windows = [
        {"values": values, "episode_starts": None, "last_values": None, "last_dones": None, "scales": ("team", "group")}
        for values in (first, second)
    ]
    stats = bonus_readings.reading_statistics(windows, coef=2.0, reset_at_episode_start=False)
    for reading in bonus_readings.READINGS:
        team, group, every = stats[reading]["team"], stats[reading]["group"], stats[reading]["all"]
        # team: step 0 fires 1.0 in the first window, step 1 fires 0.6 in the second
        assert team["fire_rate"] == pytest.approx(0.5) and team["fired_mean"] == pytest.approx(0.8)
        np.testing.assert_allclose(team["fire_rate_by_step"], [0.5, 0.5])
        np.testing.assert_allclose(team["fired_mean_by_step"], [1.0, 0.6])
        # group: only step 1 of the second window, 0.4
        assert group["fire_rate"] == pytest.approx(0.25) and group["fired_mean"] == pytest.approx(0.4)
        np.testing.assert_allclose(group["fired_mean_by_step"], [np.nan, 0.4])
        # every scale of every window: 3 of 8, mean of 1.0, 0.6, 0.4
        assert every["fire_rate"] == pytest.approx(3 / 8) and every["fired_mean"] == pytest.approx(2.0 / 3)


def test_main_on_a_benchmark_model(bonus_readings, tmp_path, capsys):
    argv = ["--algos", "sae_only", "--tasks", "cn-sparse-n3", "--seeds", "1", "-n", "300", "--n-games", "2"]
    argv += ["--eval-freq", "300", "--eval-episodes", "1", "-params", "n_steps:25", "n_epochs:1", "--out", str(tmp_path)]
    assert benchmark_main(argv) == 0
    model = tmp_path / "runs" / "sae_only" / "cn-sparse-n3_s1" / "cn-sparse-n3.zip"
    out = tmp_path / "readings.md"
    capsys.readouterr()
    assert bonus_readings.main(["--model", str(model), "--n-games", "2", "--positions", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert text == out.read_text()
    assert "| supplement | critic |" in text and "| Fig. 3 (supplement) |" in text
    assert text.count("\n| 24 |") == 1  # one row per position of the 25-step window


def test_missing_model_is_refused(bonus_readings, tmp_path, capsys):
    with pytest.raises(SystemExit):
        bonus_readings.main(["--model", str(tmp_path / "nothing.zip")])
    assert "no model file at" in capsys.readouterr().err
