"""benchmarks/critic_diagnostics.py: the Gumbel noise's spread against the states', the advantage weights, their
mean exponentials and the scales' correlations against hand-written loops; the script on benchmark models."""

import csv

import numpy as np
import pytest
import torch as th

from sb3_saeir.benchmark import main as benchmark_main


@pytest.fixture(scope="module")
def critic_diagnostics(load_benchmark_script):
    return load_benchmark_script("critic_diagnostics")


@pytest.fixture(scope="module")
def bonus_readings(load_benchmark_script):
    return load_benchmark_script("bonus_readings")


@pytest.mark.parametrize("noise", [True, False])
def test_gumbel_spread_against_a_loop(critic_diagnostics, bonus_readings, noise):
    experiment = bonus_readings.load_experiment(None, "mshg_only", "cn-sparse-n3", n_games=3, seed=2)
    policy = experiment.model.policy
    policy.critic_gumbel_noise = noise  # as a model built with critic_gumbel_noise=noise has it
    window = bonus_readings.rollout_windows(experiment, 1)[0]
    experiment.close()
    n_draws = 6
    for k, scale in enumerate(policy.scales):
        th.manual_seed(11)
        noise_sd, state_sd = critic_diagnostics.gumbel_spread(policy, window, k, n_draws)
        assert policy.critic_gumbel_noise is noise  # put back as it was
        th.manual_seed(11)
        obs = th.as_tensor(window["observations"]).reshape(25, 3, 3, -1)  # (T, G, N, d)
        starts = th.as_tensor(window["episode_starts"], dtype=th.float32).reshape(25, 3, 3)
        policy.critic_gumbel_noise = True
        with th.no_grad():
            draws = [
                policy.evaluate_critic(k, obs, th.as_tensor(window["critic_states"][k]), starts).numpy()
                for _ in range(n_draws)
            ]
        policy.critic_gumbel_noise = noise
        states = [(t, g, i) for t in range(25) for g in range(3) for i in range(3)]
        per_state_var = []
        for t, g, i in states:
            draw_values = [draw[t, g, i] for draw in draws]
            centre = sum(draw_values) / n_draws
            per_state_var.append(sum((value - centre) ** 2 for value in draw_values) / n_draws)
        means = [sum(draw[t, g, i] for draw in draws) / n_draws for t, g, i in states]
        centre = sum(means) / len(means)
        assert noise_sd == pytest.approx((sum(per_state_var) / len(states)) ** 0.5, rel=1e-5, abs=1e-9)
        assert state_sd == pytest.approx((sum((m - centre) ** 2 for m in means) / len(means)) ** 0.5, rel=1e-5)
        if scale == "team":
            assert noise_sd < 1e-6  # one edge type: the Gumbel-softmax is 1 whatever the draw
        else:
            assert noise_sd > 1e-4
        assert state_sd > 0


def test_advantage_weights_and_correlations_against_loops(critic_diagnostics):
    rng = np.random.default_rng(0)
    advantages = rng.normal(size=(5, 4, 3))
    advantages[..., 2] = rng.exponential(size=(5, 4)) - 1.0  # a right tail: the heavier weight
    flat = [[advantages[t, e, k] for k in range(3)] for t in range(5) for e in range(4)]
    sums = [sum(np.exp(row[k]) for row in flat) for k in range(3)]
    weights = critic_diagnostics.advantage_weights(advantages)
    assert weights == pytest.approx([s / sum(sums) for s in sums], rel=1e-5)
    assert critic_diagnostics.log_mean_exp(advantages) == pytest.approx([np.log(s / len(flat)) for s in sums])
    correlations = critic_diagnostics.advantage_correlations(advantages, ("team", "group", "individual"))
    assert list(correlations) == ["team-group", "team-individual", "group-individual"]
    for name, (a, b) in {"team-group": (0, 1), "team-individual": (0, 2), "group-individual": (1, 2)}.items():
        x, y = [row[a] for row in flat], [row[b] for row in flat]
        mx, my = sum(x) / len(x), sum(y) / len(y)
        cov = sum((u - mx) * (v - my) for u, v in zip(x, y))
        expected = cov / (sum((u - mx) ** 2 for u in x) * sum((v - my) ** 2 for v in y)) ** 0.5
        assert correlations[name] == pytest.approx(expected)
    huge = np.zeros((1, 2, 2))
    huge[0, 0] = [800.0, 0.0]  # exp(800) overflows float64: the log-space mean does not
    assert critic_diagnostics.log_mean_exp(huge) == pytest.approx([800.0 - np.log(2.0), 0.0])


def test_logged_weight_ranges(critic_diagnostics, tmp_path):
    progress = tmp_path / "progress.csv"
    with progress.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["time/total_timesteps", "train/advantage_weight_team", "train/advantage_weight_group"])
        writer.writerows([[100, "", ""], [200, 0.30, 0.36], [300, 0.35, 0.31]])
    ranges = critic_diagnostics.logged_weight_ranges(progress, ("team", "group", "individual"))
    assert ranges == {"team": (0.30, 0.35), "group": (0.31, 0.36)}
    assert critic_diagnostics.logged_weight_ranges(progress, ("team",), up_to=250) == {"team": (0.30, 0.30)}
    assert critic_diagnostics.logged_weight_ranges(tmp_path / "none.csv", ("team",)) == {}


def test_main_on_benchmark_models(critic_diagnostics, tmp_path, capsys):
    argv = ["--algos", "mshg_only", "--tasks", "cn-sparse-n3", "--seeds", "1", "-n", "600", "--n-games", "2"]
    argv += ["--eval-freq", "600", "--eval-episodes", "1", "-params", "n_steps:25", "n_epochs:1", "--out", str(tmp_path)]
    assert benchmark_main(argv) == 0
    model = tmp_path / "runs" / "mshg_only" / "cn-sparse-n3_s1" / "cn-sparse-n3.zip"
    out = tmp_path / "diagnostics.md"
    capsys.readouterr()
    assert critic_diagnostics.main(["--model", str(model), "--draws", "4", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert text == out.read_text()
    rows = [line.split(" | ") for line in text.splitlines() if line.startswith(f"| {tmp_path.name}/mshg_only/")]
    assert [row[3] for row in rows[:3]] == ["team", "group", "individual"] and rows[0][1:3] == ["600", "yes"]
    assert sum(float(row[9]) for row in rows[:3]) == pytest.approx(1.0, abs=1e-3)  # W_K sum to 1
    assert all(row[10].count("-") == 1 for row in rows[:3])  # the logged range of its two updates (up to 600)
    assert rows[3][1:] and "corr team-group" in text


def test_bad_arguments_are_refused(critic_diagnostics, tmp_path, capsys):
    with pytest.raises(SystemExit):
        critic_diagnostics.main(["--model", str(tmp_path / "nothing.zip")])
    assert "no model file at" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        critic_diagnostics.main(["--model", str(tmp_path / "nothing.zip"), "--draws", "1"])
    assert "--draws must be at least 2, got 1" in capsys.readouterr().err
