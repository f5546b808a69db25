"""Continuing a saved model with ``-i`` (``train`` and ``zoo train``): the config's and ``-params``' hyperparameters
apply to the loaded model, the record says what trained and compares like with like, so that such a run resumes and
trains longer with its own command; ``done.json`` counts the run's agent-steps against the budget of ``spec.json``."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sb3_saeir import MAPPO
from sb3_saeir.config import loaded_network
from sb3_saeir.experiment import Experiment
from sb3_saeir.train import main as train_main

REPO = Path(__file__).parent.parent
TASK = "cn-sparse-n3"
TINY = ["--algo", "mappo", "--task", TASK, "--n-games", "2", "--eval-freq", "0", "--verbose", "0", "--num-threads", "1"]
FF_KWARGS = "policy_kwargs:dict(activation_fn=nn.Tanh, hidden_size=64, critic_input='joint', recurrent=False)"


def train(log_folder, *extra):
    try:
        return train_main([*TINY, "-f", str(log_folder), *extra])
    except SystemExit as exit_:
        return int(exit_.code or 0)


def run_folder(log_folder, number):
    return log_folder / "mappo" / f"{TASK}_{number}"


@pytest.fixture(scope="module")
def saved_models(tmp_path_factory):
    """A recurrent model (the config's own kind) and a feed-forward one, 60 agent-steps each."""
    log_folder = tmp_path_factory.mktemp("saved")
    assert train(log_folder, "-n", "60", "-params", "n_steps:10", "n_epochs:2") == 0
    assert train(log_folder, "-n", "60", "-params", "n_steps:10", "n_epochs:2", FF_KWARGS) == 0
    return {kind: run_folder(log_folder, number) / f"{TASK}.zip" for kind, number in (("recurrent", 1), ("ff", 2))}


def test_train_i_applies_the_configs_and_params_hyperparameters(saved_models, tmp_path):
    """``-params learning_rate:0.005 n_steps:50 n_epochs:3`` train the loaded model (as ``zoo train -i`` does), and
    the record says so."""
    params = ["-params", "learning_rate:0.005", "n_steps:50", "n_epochs:3"]
    assert train(tmp_path, "-n", "300", *params, "-i", str(saved_models["recurrent"])) == 0
    folder = run_folder(tmp_path, 1)
    model = MAPPO.load(folder / f"{TASK}.zip")
    assert model.learning_rate == 0.005 and model.n_steps == 50 and model.n_epochs == 3
    assert model.lr_schedule(1.0) == 0.005
    config = json.loads((folder / "spec.json").read_text())["config"]
    assert (config["learning_rate"], config["n_steps"], config["n_epochs"]) == (0.005, 50, 3)
    assert model.num_timesteps == 60 + 300


def test_done_json_counts_the_runs_agent_steps_against_its_budget(saved_models, tmp_path):
    assert train(tmp_path, "-n", "120", "-params", "n_steps:10", "n_epochs:2", "-i", str(saved_models["recurrent"])) == 0
    folder = run_folder(tmp_path, 1)
    done, spec = (json.loads((folder / name).read_text()) for name in ("done.json", "spec.json"))
    assert spec["n_timesteps"] == 120
    assert done["timesteps"] == 120 and done["model_start"] == 60  # the model's count goes on: 60 + 120
    assert MAPPO.load(folder / f"{TASK}.zip").num_timesteps == 180


def test_a_new_run_has_no_model_start_in_done_json(tmp_path):
    assert train(tmp_path, "-n", "60", "-params", "n_steps:10") == 0
    assert json.loads((run_folder(tmp_path, 1) / "done.json").read_text())["timesteps"] == 60
    assert "model_start" not in json.loads((run_folder(tmp_path, 1) / "done.json").read_text())


@pytest.mark.parametrize("kind", ["recurrent", "ff"])
def test_an_i_run_trains_longer_with_its_own_command(saved_models, tmp_path, kind, capsys):
    """The record of a model of the config's own kind keeps the config's policy_kwargs (not the ``n_agents`` and
    ``normalize_values`` the algorithm adds); a model of another network is recorded as it, on resume too."""
    own = ["-params", "n_steps:10", "n_epochs:2", "-i", str(saved_models[kind])]
    assert train(tmp_path, "-n", "60", *own) == 0
    folder = run_folder(tmp_path, 1)
    recorded = json.loads((folder / "spec.json").read_text())["config"].get("policy_kwargs", "")
    assert "n_agents" not in recorded and "normalize_values" not in recorded
    assert ("recurrent=False" in recorded) == (kind == "ff")
    capsys.readouterr()
    assert train(tmp_path, "-n", "120", *own, "--resume") == 0, capsys.readouterr().err
    assert MAPPO.load(folder / f"{TASK}.zip").num_timesteps == 60 + 120
    assert json.loads((folder / "spec.json").read_text())["n_timesteps"] == 120
    assert json.loads((folder / "done.json").read_text())["timesteps"] == 120


def test_an_interrupted_i_run_resumes_with_its_own_command(saved_models, tmp_path, capsys):
    """A stop at a checkpoint (as Ctrl-C leaves one) of an ``-i`` run: ``--resume`` with its command goes on."""
    own = ["-n", "120", "-params", "n_steps:10", "n_epochs:2", "--save-freq", "60", "-i", str(saved_models["ff"])]
    assert train(tmp_path, *own) == 0
    folder = run_folder(tmp_path, 1)
    (folder / "done.json").unlink()
    (folder / f"{TASK}.zip").unlink()  # as if stopped after the checkpoint at 60 + 60 agent-steps
    checkpoints = sorted(folder.glob("rl_model_*_steps.zip"))
    assert [path.name for path in checkpoints][:1] == ["rl_model_120_steps.zip"]
    for later in checkpoints[1:]:
        later.unlink()
    capsys.readouterr()
    assert train(tmp_path, *own, "--resume") == 0, capsys.readouterr().err
    assert MAPPO.load(folder / f"{TASK}.zip").num_timesteps == 180


def test_experiment_load_applies_the_config(saved_models):
    experiment = Experiment("mappo", TASK, {"n_envs": 2, "n_steps": 20, "learning_rate": 0.002}, seed=5)
    try:
        model = experiment.load(saved_models["recurrent"])
        assert model.n_steps == 20 and model.learning_rate == 0.002 and model.lr_schedule(0.5) == 0.002
        assert model.seed == 5 and experiment.resolved_hyperparams["n_steps"] == 20
    finally:
        experiment.close()


def test_loaded_network_leaves_out_what_the_algorithm_sets(saved_models):
    model = MAPPO.load(saved_models["recurrent"])
    assert {"n_agents", "normalize_values"} <= set(model.policy_kwargs)
    configured = "dict(activation_fn=nn.Tanh, hidden_size=64, critic_input='joint')"
    assert loaded_network(model, saved_models["recurrent"], None, configured) is None
    feed_forward = MAPPO.load(saved_models["ff"])
    recorded = loaded_network(feed_forward, saved_models["ff"], None, configured)
    assert recorded is not None and "recurrent=False" in recorded and "n_agents" not in recorded


def test_zoo_i_run_trains_longer_with_its_own_command(saved_models, tmp_path):
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    common = ["train", "--algo", "mappo", "--env", TASK, "--num-threads", "1", "--device", "cpu", "--seed", "0",
              "--eval-freq", "0", "-f", str(tmp_path), "-params", "n_envs:2", "n_steps:10", "learning_rate:0.003",
              "-i", str(saved_models["ff"])]  # fmt: skip

    def zoo(*extra):
        return subprocess.run(
            [sys.executable, "-m", "sb3_saeir.zoo", *common, *extra],
            cwd=REPO, env=env, capture_output=True, text=True, timeout=300,
        )  # fmt: skip

    first = zoo("-n", "60")
    assert first.returncode == 0, first.stderr[-2000:]
    longer = zoo("-n", "120", "--resume")
    assert longer.returncode == 0, longer.stderr[-2000:]
    folder = run_folder(tmp_path, 1)
    model = MAPPO.load(folder / f"{TASK}.zip")
    assert model.num_timesteps == 60 + 120 and model.lr_schedule(1.0) == 0.003
    assert json.loads((folder / "done.json").read_text()) | {"wall_s": 0} == {
        "wall_s": 0,
        "segments": 2,
        "timesteps": 120,
        "model_start": 60,
    }
