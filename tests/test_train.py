"""python -m sb3_saeir.train / enjoy: rl-zoo folder layout, continued training, replay with GIF, bad input."""

from pathlib import Path

import numpy as np
import pytest
import torch as th
import yaml
from stable_baselines3.common.monitor import load_results

from sb3_saeir import MAPPO, SAEIR_PPO
from sb3_saeir.enjoy import main as enjoy_main
from sb3_saeir.train import main as train_main

TINY_ARGV = ["--task", "cn-sparse-n3", "--n-games", "2", "-params", "n_steps:10", "n_epochs:1", "--verbose", "0"]


def run_train(log_folder, *extra):
    return train_main(["--algo", "saeir_ppo", *TINY_ARGV, "-f", str(log_folder), *extra])


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    log_folder = tmp_path_factory.mktemp("logs")
    args = ["-n", "300", "--eval-freq", "120", "--eval-episodes", "2", "--save-freq", "120"]
    assert run_train(log_folder, *args) == 0
    return log_folder, log_folder / "saeir_ppo" / "cn-sparse-n3_1"


def test_rl_zoo_folder_layout(trained):
    _, run = trained
    for name in ("cn-sparse-n3.zip", "best_model.zip", "evaluations.npz", "games.monitor.csv", "spec.json"):
        assert (run / name).is_file(), name
    for name in ("evaluations.csv", "progress.csv", "segments.json", "done.json"):  # the benchmark's run files too
        assert (run / name).is_file(), name
    assert sorted(p.name for p in run.glob("rl_model_*_steps.zip")) == ["rl_model_120_steps.zip", "rl_model_240_steps.zip"]
    config = yaml.safe_load((run / "cn-sparse-n3" / "config.yml").read_text())
    assert config["n_envs"] == 2 and config["n_steps"] == 10 and config["n_epochs"] == 1
    assert config["learning_rate"] == 7e-4 and config["intrinsic_reward"] == "saeir"  # from zoo_configs/saeir_ppo.yml
    args = yaml.safe_load((run / "cn-sparse-n3" / "args.yml").read_text())
    assert args["algo"] == "saeir_ppo" and args["seed"] == 0
    evaluations = np.load(run / "evaluations.npz")
    assert evaluations["results"].shape == (4, 2)  # 4 evaluations x 2 game episodes: at the start, 120, 240, the end
    assert evaluations["coverage_rate"].shape == (4, 2) and list(evaluations["timesteps"]) == [0, 120, 240, 300]
    monitor = load_results(str(run))
    assert (monitor["l"] == 25).all() and "coverage_rate" in monitor  # one row per game episode


def test_continue_training_restores_value_norm_and_optimizer(trained):
    log_folder, run = trained
    saved = SAEIR_PPO.load(run / "cn-sparse-n3.zip")
    assert run_train(log_folder, "-n", "60", "--eval-freq", "0", "-i", str(run / "cn-sparse-n3.zip")) == 0
    continued = log_folder / "saeir_ppo" / "cn-sparse-n3_2"
    assert (run / "cn-sparse-n3.zip").is_file()  # the first run is untouched
    model = SAEIR_PPO.load(continued / "cn-sparse-n3.zip")
    assert model.num_timesteps == saved.num_timesteps + 60
    # training went on from the saved statistics: the ValueNorm debiasing term kept growing from its saved value
    for scale in saved.policy.scales:
        before = saved.policy.value_norms[scale].debiasing_term
        after = model.policy.value_norms[scale].debiasing_term
        assert after > before > 0
    # and the Adam state was restored (its step counter continued from the saved one)
    step_before = next(iter(saved.policy.optimizer.state.values()))["step"]
    step_after = next(iter(model.policy.optimizer.state.values()))["step"]
    assert th.as_tensor(step_after) > th.as_tensor(step_before) > 0


def test_enjoy_prints_metrics_and_writes_gif(trained, capsys, tmp_path):
    log_folder, _ = trained
    gif = tmp_path / "replay.gif"
    assert (
        enjoy_main(
            ["--algo", "saeir_ppo", "-f", str(log_folder), "--exp-id", "1", "-n", "4", "--n-games", "2", "--gif", str(gif)]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "coverage_rate" in out and "4 episodes" in out
    assert gif.stat().st_size > 1000
    assert enjoy_main(["--algo", "saeir_ppo", "-f", str(log_folder), "--load-best", "--exp-id", "1", "-n", "2"]) == 0


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--algo", "qmix"], "unknown algorithm 'qmix'; valid choices: elign, ippo, mappo"),
        (["--algo", "mappo", "--task", "cn-dense"], "unknown task 'cn-dense'; valid choices: cn-sparse-n3"),
        (["--algo", "mappo", "-params", "learning_rte:0.1"], "unknown config key 'learning_rte' for mappo; valid keys:"),
        (["--algo", "mappo", "-params", "n_epochs:ten"], "hyperparameter n_epochs='ten' has type str, expected int"),
        (["--algo", "mappo", "-params", "intrinsic_coef:[1]"], "hyperparameter intrinsic_coef=[1] has type list"),
        (["--algo", "mappo", "--n-games", "0"], "n_envs (number of games) must be a positive integer"),
    ],
)
def test_bad_input_one_line_error_and_nothing_written(trained, capsys, argv, message):
    log_folder, _ = trained
    before = sorted(p for p in Path(log_folder).rglob("*"))
    assert train_main([*argv, "-f", str(log_folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert sorted(p for p in Path(log_folder).rglob("*")) == before


def test_missing_config_entry(tmp_path, capsys):
    conf = tmp_path / "only_n4.yml"
    conf.write_text("cn-sparse-n4:\n  policy: MAPPOPolicy\n")
    assert train_main(["--algo", "mappo", "-conf", str(conf), "-f", str(tmp_path / "logs")]) == 2
    assert "has no entry for task 'cn-sparse-n3'. Entries: cn-sparse-n4" in capsys.readouterr().err
    assert not (tmp_path / "logs").exists()


def test_the_configs_tensorboard_log_is_used_without_tb(tmp_path):
    """A ``tensorboard_log`` in the config (here through -params) writes events when -tb is not given."""
    tensorboard = tmp_path / "tb"
    argv = ["--algo", "mappo", *TINY_ARGV, "-f", str(tmp_path / "logs"), "-n", "60", "--eval-freq", "0"]
    argv += ["-params", "n_steps:10", "n_epochs:1", f"tensorboard_log:'{tensorboard}'"]
    assert train_main(argv) == 0
    assert list(tensorboard.glob("MAPPO_1/events.out.tfevents.*"))
    assert (tmp_path / "logs" / "mappo" / "cn-sparse-n3_1" / "progress.csv").is_file()


@pytest.mark.parametrize("flag, expected", [("off", False), ("on", True), ("auto", "auto")])
def test_double_buffered_flag_reaches_the_model_and_args(tmp_path, flag, expected):
    """``--double-buffered`` overrides the config's ``double_buffered`` (here with the games in 2 env workers) and is
    saved with the run's settings."""
    argv = ["--algo", "mappo", *TINY_ARGV, "-f", str(tmp_path / "logs"), "-n", "60", "--eval-freq", "0"]
    argv += ["--num-cpus", "2", "--double-buffered", flag]
    assert train_main(argv) == 0
    run = tmp_path / "logs" / "mappo" / "cn-sparse-n3_1"
    assert MAPPO.load(run / "cn-sparse-n3.zip").double_buffered == expected
    assert yaml.safe_load((run / "cn-sparse-n3" / "config.yml").read_text())["double_buffered"] == expected
