"""rl-zoo3 interop (sb3_saeir.zoo): rl-zoo3's own train and enjoy run the package's methods on its tasks."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.monitor import load_results

from sb3_saeir import MultiAgentVecEnv, make_multiagent_vec_env
from sb3_saeir.config import ALGOS
from sb3_saeir.zoo import GameMonitor, games_to_agents, register_algorithms
from sb3_saeir.zoo.launcher import prepare_enjoy_args, prepare_train_args

REPO = Path(__file__).parent.parent
TASK = "cn-sparse-n3"


def run_launcher(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    result = subprocess.run(
        [sys.executable, "-m", "sb3_saeir.zoo", *args], cwd=REPO, env=env, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, f"{args[0]} failed:\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result


@pytest.mark.parametrize("algo", ["saeir_ppo", "mappo"])
def test_train_and_enjoy(tmp_path, algo):
    folder = tmp_path / "logs"
    # 300 agent-steps = 50 vec steps of 2 games x 3 agents = 2 episodes per game; eval every 60 // 2 = 30 vec steps
    run_launcher(
        "train", "--algo", algo, "--env", TASK, "--conf-file", f"zoo_configs/{algo}.yml", "-f", str(folder),
        "--num-threads", "1", "--device", "cpu", "--seed", "0", "-n", "300", "-params", "n_envs:2", "n_steps:10",
        "--eval-freq", "60", "--eval-episodes", "3",
    )  # fmt: skip
    run = folder / algo / f"{TASK}_1"
    for name in (f"{TASK}.zip", "best_model.zip", "evaluations.npz", f"{TASK}/config.yml", f"{TASK}/args.yml"):
        assert (run / name).is_file(), name
    config = yaml.load((run / TASK / "config.yml").read_text(), Loader=yaml.UnsafeLoader)
    assert config["vec_env_wrapper"] == "sb3_saeir.zoo.games_to_agents"  # added by the launcher
    assert config["n_envs"] == 2 and config["policy"] == ("MSHGPolicy" if algo == "saeir_ppo" else "MAPPOPolicy")

    model = ALGOS[algo].load(run / f"{TASK}.zip", device="cpu")
    assert model.n_agents == 3 and model.n_envs == 6  # n_envs = 2 games -> 6 agent slots
    assert model.num_timesteps == 300  # agent-steps
    # a Run's evaluations: at the start, every 30 vec steps x 6 slots (rl-zoo3's period), at the end
    assert np.load(run / "evaluations.npz")["timesteps"].tolist() == [0, 180, 300]
    assert (run / "spec.json").is_file() and (run / "done.json").is_file() and (run / "evaluations.csv").is_file()

    # per-game monitor: rl-zoo3's empty per-game files are replaced by one row per finished game
    assert not list(run.glob("[0-9]*.monitor.csv"))
    games = load_results(str(run))
    assert len(games) == 4 and (games["l"] == 25).all() and "coverage_rate" in games

    result = run_launcher(
        "enjoy", "--algo", algo, "--env", TASK, "-f", str(folder), "--no-render", "-n", "50", "--num-threads", "1",
        "--device", "cpu", "--reward-log", str(tmp_path / "replay"),
    )  # fmt: skip
    assert f"Loading {run / TASK}.zip" in result.stdout
    assert "4 finished games (2 in parallel)" in result.stdout  # --n-envs 1 became 2 games; 50 steps = 2 episodes
    assert len(load_results(str(tmp_path / "replay"))) == 4


# 900 agent-steps of 2 games x 3 agents; checkpoints every 40 // 2 = 20 vec steps (120 agent-steps), evaluations every
# 60 // 2 = 30 vec steps (180 agent-steps)
RESUMED = [
    "train", "--algo", "mappo", "--env", TASK, "--conf-file", "zoo_configs/mappo.yml", "--num-threads", "1", "--device",
    "cpu", "--seed", "0", "-n", "900", "-params", "n_envs:2", "n_steps:10", "--eval-freq", "60", "--eval-episodes", "2",
    "--save-freq", "40",
]  # fmt: skip


def with_seed(arguments, seed):
    """``arguments`` with ``--seed`` set to ``seed`` (``None``: left out)."""
    arguments = list(arguments)
    index = arguments.index("--seed")
    del arguments[index : index + 2]
    return arguments if seed is None else [*arguments, "--seed", seed]


def test_zoo_train_killed_and_resumed_ends_as_uninterrupted(tmp_path):
    """``python -m sb3_saeir.zoo train --resume`` (a package task: the run is a ``Run`` in rl-zoo3's folder) after a
    SIGKILL mid-run ends with the uninterrupted run's parameters, training rows, evaluations and monitor rows."""
    from tests.run_folders import assert_same_parameters, monitor_rows, read_rows

    run_launcher(*RESUMED, "-f", str(tmp_path / "reference"))
    reference = tmp_path / "reference" / "mappo" / f"{TASK}_1"
    folder = tmp_path / "killed" / "mappo" / f"{TASK}_1"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    command = [sys.executable, "-m", "sb3_saeir.zoo", *RESUMED, "-f", str(tmp_path / "killed")]
    process = subprocess.Popen(command, cwd=REPO, env=env, start_new_session=True, stdout=subprocess.DEVNULL)
    deadline = time.time() + 300
    while len(list(folder.glob("rl_model_*_steps.zip"))) < 3:
        assert process.poll() is None, "the run ended before it could be killed"
        assert time.time() < deadline
        time.sleep(0.005)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    assert not (folder / "done.json").exists()
    # a seed other than the run's is refused before anything is written; no --seed (rl-zoo3's -1) takes the run's
    from tests.run_folders import snapshot

    before = snapshot(folder)
    other_seed = subprocess.run(
        [sys.executable, "-m", "sb3_saeir.zoo", *with_seed(RESUMED, "5"), "-f", str(tmp_path / "killed"), "--resume"],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert other_seed.returncode == 2
    assert f"{folder} was made with --seed 0, not --seed 5" in other_seed.stderr
    assert snapshot(folder) == before
    resumed = run_launcher(*with_seed(RESUMED, None), "-f", str(tmp_path / "killed"), "--resume")
    assert f"Resuming {folder}" in resumed.stdout and "Seed: 0" in resumed.stdout
    assert_same_parameters(folder / f"{TASK}.zip", reference / f"{TASK}.zip")
    rows, expected_rows = read_rows(folder / "progress.csv"), read_rows(reference / "progress.csv")
    keys = [key for key in expected_rows[0] if not key.startswith("time/") or key == "time/total_timesteps"]
    assert [[row.get(key) for key in keys] for row in rows] == [[row[key] for key in keys] for row in expected_rows]
    for name in ("timesteps", "results"):
        np.testing.assert_array_equal(np.load(folder / "evaluations.npz")[name], np.load(reference / "evaluations.npz")[name])
    assert monitor_rows(folder) == monitor_rows(reference) and len(monitor_rows(reference)) > 0


def zoo_game_venv(n_games, seed, monitor_dir=None):
    """The game vec env rl-zoo3 builds (ExperimentManager.create_envs)."""
    spec = gym.spec(TASK)
    return make_vec_env(
        lambda **kwargs: spec.make(**kwargs), n_envs=n_games, seed=seed, env_kwargs={"N": 3}, monitor_dir=monitor_dir
    )


def test_games_to_agents_layout_seeding_and_monitor(tmp_path):
    env = games_to_agents(zoo_game_venv(2, seed=7, monitor_dir=str(tmp_path)))
    assert isinstance(env, GameMonitor) and isinstance(env.venv, MultiAgentVecEnv)
    assert env.n_games == 2 and env.n_agents == 3 and env.num_envs == 6  # slot = game * n_agents + agent
    assert not list(tmp_path.glob("[0-9]*.monitor.csv"))  # rl-zoo3's never-stepped game monitors are removed

    obs = env.reset()
    # rl-zoo3's seed reaches the games: game g is reset with seed + g, as make_multiagent_vec_env(seed=7) does
    reference = make_multiagent_vec_env(TASK, n_games=2, seed=7, N=3)
    np.testing.assert_array_equal(obs, reference.reset())
    np.testing.assert_array_equal(obs, games_to_agents(zoo_game_venv(2, seed=7)).reset())
    assert not np.array_equal(obs, games_to_agents(zoo_game_venv(2, seed=8)).reset())
    assert not np.array_equal(obs[:3], obs[3:])  # the two games differ

    rng = np.random.default_rng(0)
    for _ in range(25):
        actions = rng.integers(0, 5, size=6)
        _, rewards, dones, infos = env.step(actions)
        np.testing.assert_array_equal(rewards, reference.step(actions)[1])
    assert dones.all() and [i for i, info in enumerate(infos) if "episode" in info] == [0, 3]
    env.close()
    games = load_results(str(tmp_path))  # games.monitor.csv: one row per game, not per agent
    assert len(games) == 2 and (games["l"] == 25).all()
    assert games["r"].tolist() == [infos[0]["episode"]["r"], infos[3]["episode"]["r"]]


def test_game_env_is_one_game():
    env = gym.make(TASK, N=3)
    assert env.observation_space.shape == (3, 18) and env.action_space.nvec.tolist() == [5, 5, 5]
    assert env.unwrapped.saeir_task == TASK and env.unwrapped.saeir_task_kwargs == {"N": 3}
    env.reset(seed=0)
    ends = []
    for _ in range(25):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert isinstance(reward, float)
        ends.append(terminated or truncated)
    assert ends == [False] * 24 + [True] and truncated and "coverage_rate" in info["episode_metrics"]
    env.close()


def test_games_to_agents_rejects_other_envs():
    venv = make_vec_env("CartPole-v1", n_envs=1)
    with pytest.raises(TypeError, match="package task"):
        games_to_agents(venv)


def test_register_algorithms():
    from rl_zoo3.utils import ALGOS as ZOO_ALGOS

    assert set(register_algorithms()) == set(ALGOS)
    assert all(ZOO_ALGOS[name] is algo_class for name, algo_class in ALGOS.items())


def test_launcher_arguments():
    args = prepare_train_args(["--algo", "saeir_ppo", "--env", TASK, "-params", "n_envs:2", "-f", "x", "-params", "a:1"])
    assert args[args.index("--conf-file") + 1].endswith("zoo_configs/saeir_ppo.yml")  # packaged config by default
    assert args[args.index("-params") + 1 :] == ["n_envs:2", "a:1", "vec_env_wrapper:'sb3_saeir.zoo.games_to_agents'"]
    assert args[args.index("-f") + 1] == "x"
    own = prepare_train_args(["--algo", "mappo", "--env", TASK, "-params", "vec_env_wrapper:'my.wrapper'"])
    assert own[own.index("-params") + 1 :] == ["vec_env_wrapper:'my.wrapper'"]
    other = ["--algo", "ppo", "--env", "CartPole-v1", "-params", "n_envs:2"]
    assert prepare_train_args(other) == other  # other envs: untouched
    assert prepare_enjoy_args(["--env", TASK, "-f", "x"])[-2:] == ["--n-envs", "2"]
    assert prepare_enjoy_args(["--env", TASK, "--n-envs", "4"])[-2:] == ["--n-envs", "4"]


def test_zoo_i_records_the_loaded_network_and_refuses_another(tmp_path):
    """``zoo train -i FF.zip``: the record says feed-forward (rl-zoo3 drops the config's policy_kwargs when it loads);
    a ``-params policy_kwargs`` the loaded model cannot take is refused in one line, nothing left behind."""
    import json

    common = ["train", "--algo", "mappo", "--env", TASK, "--num-threads", "1", "--device", "cpu", "--seed", "0", "-n", "60",
              "--eval-freq", "0", "-f", str(tmp_path)]  # fmt: skip
    feed_forward = "policy_kwargs:dict(activation_fn=nn.Tanh, hidden_size=64, critic_input='joint', recurrent=False)"
    run_launcher(*common, "-params", "n_envs:2", "n_steps:10", feed_forward)
    model = tmp_path / "mappo" / f"{TASK}_1" / f"{TASK}.zip"
    run_launcher(*common, "-params", "n_envs:2", "n_steps:10", "-i", str(model))
    record = json.loads((tmp_path / "mappo" / f"{TASK}_2" / "spec.json").read_text())
    assert "recurrent=False" in record["config"]["policy_kwargs"]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    refused = subprocess.run(
        [sys.executable, "-m", "sb3_saeir.zoo", *common, "-params", "n_envs:2", "n_steps:10",
         "policy_kwargs:dict(recurrent=True)", "-i", str(model)],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert refused.returncode == 2
    assert "-params policy_kwargs recurrent=True cannot apply to the loaded model" in refused.stderr
    assert sorted(path.name for path in (tmp_path / "mappo").iterdir()) == [f"{TASK}_1", f"{TASK}_2"]


def test_zoo_train_longer_ends_as_the_longer_run(tmp_path):
    """``zoo train --resume`` with a larger ``-n`` trains a finished run longer, as an uninterrupted run of that budget."""
    import json

    from tests.run_folders import assert_same_parameters

    common = ["train", "--algo", "mappo", "--env", TASK, "--conf-file", "zoo_configs/mappo.yml", "--num-threads", "1",
              "--device", "cpu", "--seed", "0", "-params", "n_envs:2", "n_steps:10", "--eval-freq", "60",
              "--eval-episodes", "2"]  # fmt: skip
    run_launcher(*common, "-n", "300", "-f", str(tmp_path / "extended"))
    run_launcher(*common, "-n", "600", "-f", str(tmp_path / "extended"), "--resume")
    run_launcher(*common, "-n", "600", "-f", str(tmp_path / "uninterrupted"))
    extended, uninterrupted = (tmp_path / name / "mappo" / f"{TASK}_1" for name in ("extended", "uninterrupted"))
    assert_same_parameters(extended / f"{TASK}.zip", uninterrupted / f"{TASK}.zip")
    (extension,) = json.loads((extended / "spec.json").read_text())["extensions"]
    assert (extension["from"], extension["to"]) == (300, 600)


@pytest.mark.parametrize(("stop_signal", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_zoo_train_stopped_by_a_signal_says_so_and_exits_with_its_status(tmp_path, stop_signal, status):
    """Ctrl-C or SIGTERM during ``zoo train``: a checkpoint, one line naming it, 128 + the signal (Ctrl-C exited 0
    with no line, SIGTERM ended the process with no checkpoint)."""
    folder = tmp_path / "mappo" / f"{TASK}_1"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    command = [sys.executable, "-m", "sb3_saeir.zoo", *RESUMED, "-f", str(tmp_path)]
    # a terminal's Ctrl-C: the child must not inherit an ignored SIGINT (pytest-xdist workers ignore it)
    process = subprocess.Popen(
        command, cwd=REPO, env=env, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    deadline = time.time() + 300
    while not list(folder.glob("rl_model_*_steps.zip")):
        assert process.poll() is None, f"the run ended before it could be stopped: {process.communicate()}"
        assert time.time() < deadline
        time.sleep(0.005)
    os.kill(process.pid, stop_signal)
    stdout, stderr = process.communicate(timeout=300)
    assert process.returncode == status, stderr.decode()[-2000:]
    stopped_line = [line for line in stdout.decode().splitlines() if line.startswith("Stopped at the checkpoint")]
    assert len(stopped_line) == 1 and "--resume continues it" in stopped_line[0]
    assert not (folder / "done.json").exists()
    resumed = run_launcher(*RESUMED, "-f", str(tmp_path), "--resume")
    assert f"Resuming {folder}" in resumed.stdout and (folder / "done.json").is_file()


def test_zoo_reads_a_conf_file_with_the_package_yaml_loader(tmp_path):
    """``learning_rate: 5e-4`` without ``!!float`` is a number (``yaml.safe_load``, rl-zoo3's loader, reads a
    string): rl-zoo3's ``read_hyperparameters`` runs with the package's loader."""
    entry = yaml.safe_load((REPO / "zoo_configs" / "mappo.yml").read_text())[TASK]
    text = yaml.safe_dump({TASK: {**entry, "learning_rate": "LR"}}).replace("'LR'", "5e-4").replace("LR", "5e-4")
    (tmp_path / "conf.yml").write_text(text)
    run_launcher(
        "train", "--algo", "mappo", "--env", TASK, "--conf-file", str(tmp_path / "conf.yml"), "-f", str(tmp_path),
        "--num-threads", "1", "--device", "cpu", "--seed", "0", "-n", "60", "-params", "n_envs:2", "n_steps:10",
        "--eval-freq", "0",
    )  # fmt: skip
    model = ALGOS["mappo"].load(tmp_path / "mappo" / f"{TASK}_1" / f"{TASK}.zip", device="cpu")
    assert model.lr_schedule(1.0) == 5e-4
