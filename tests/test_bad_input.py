"""Bad input is stopped early with one clear line, and nothing a user saved is changed.

Each case is one bad input a user could give: an algorithm argument, a policy argument, an env or task option, a
config or command-line value. The API cases assert the exception type and the key words of its one-line message; the
command-line cases assert exit status 2, one ``error:`` line on stderr, and that the log folder is exactly as before.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import ActorCriticPolicy

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.vec_env import NonFiniteValueError
from sb3_saeir.enjoy import main as enjoy_main
from sb3_saeir.envs import make_task
from sb3_saeir.train import main as train_main
from tests.toy_envs import MixedSpacesEnv, ToyMeetEnv

# ------------------------------------------------------------------------------------------------ algorithm arguments
BAD_ALGO_ARGUMENTS = [
    ({"gamma": 1.5}, "gamma=1.5 is out of range"),
    ({"gamma": -0.1}, "gamma=-0.1 is out of range"),
    ({"gae_lambda": -1}, "gae_lambda=-1 is out of range"),
    ({"ent_coef": -0.01}, "ent_coef=-0.01 is out of range"),
    ({"vf_coef": -1.0}, "vf_coef=-1.0 is out of range"),
    ({"max_grad_norm": -1.0}, "max_grad_norm=-1.0 is out of range"),
    ({"clip_range": -0.2}, "clip_range=-0.2 is out of range"),
    ({"intrinsic_coef": -0.1}, "intrinsic_coef=-0.1 is out of range"),
    ({"learning_rate": 0.0}, "learning_rate=0.0 is out of range"),
    ({"n_epochs": 0}, "n_epochs=0 is out of range"),
    ({"n_steps": 2.5}, "n_steps must be an integer"),
    ({"n_steps": 0}, "n_steps=0 is out of range"),
    ({"data_chunk_length": 0}, "data_chunk_length=0 is out of range"),
    ({"huber_delta": 0.0}, "huber_delta=0.0 is out of range"),
    ({"target_kl": -0.01}, "target_kl=-0.01 is out of range"),
    ({"gamma": float("nan")}, "gamma must be a finite number"),
    ({"batch_size": 7}, "batch_size=7 cannot be formed from whole"),
    ({"n_minibatches": 99}, "n_minibatches=99 must be between 1 and"),
    ({"intrinsic_reward": "curiosity"}, "Unknown intrinsic_reward 'curiosity'"),
    ({"value_loss": "l1"}, "value_loss must be 'huber' or 'mse'"),
]


@pytest.mark.parametrize("kwargs, message", BAD_ALGO_ARGUMENTS, ids=[m for _, m in BAD_ALGO_ARGUMENTS])
def test_bad_algorithm_argument(env, kwargs, message):
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", env, **kwargs)
    assert message in str(error.value) and "\n" not in str(error.value)


BAD_POLICY_ARGUMENTS = [
    (
        {"net_arch": [256]},
        "net_arch=[256] is not supported: the networks follow the paper's layout; set their width with hidden_size",
    ),
    ({"ortho_init": False}, "ortho_init=False is not supported"),
    ({"share_features_extractor": False}, "share_features_extractor=False is not supported"),
    ({"use_sde": True}, "use_sde=True is not supported"),
    ({"hiden_size": 32}, "unknown policy argument 'hiden_size'"),
    ({"scales": ("team", "team")}, "each at most once"),
    ({"scales": ("team", "global")}, "scales must be a non-empty subset"),
    ({"group_size": 3}, "group_size=3 must be smaller than the number of agents (3)"),
    ({"n_edge_types": 0}, "group_size and n_edge_types must be >= 1"),
]


@pytest.mark.parametrize("policy_kwargs, message", BAD_POLICY_ARGUMENTS, ids=[m[:40] for _, m in BAD_POLICY_ARGUMENTS])
def test_bad_policy_argument(env, policy_kwargs, message):
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", env, policy_kwargs=policy_kwargs)
    assert message in str(error.value) and "\n" not in str(error.value)


def test_sb3_policy_class_is_refused_before_it_is_built(env):
    with pytest.raises(ValueError, match="needs a MultiAgentActorCriticPolicy"):
        MAPPO(ActorCriticPolicy, env)


def test_task_id_string_instead_of_env():
    with pytest.raises(ValueError, match=r"task id 'cn-sparse-n3'; build it with sb3_saeir\.make_multiagent_vec_env"):
        SAEIR_PPO("MSHGPolicy", "cn-sparse-n3")


def test_raw_pettingzoo_env_instead_of_vec_env():
    with pytest.raises(ValueError, match=r"got the PettingZoo env .*make_multiagent_vec_env"):
        MAPPO("MAPPOPolicy", make_task("cn-sparse-n3"))


def test_single_agent_vec_env_is_refused():
    from stable_baselines3.common.env_util import make_vec_env

    with pytest.raises(ValueError, match="does not say how many agents a game has"):
        MAPPO("MAPPOPolicy", make_vec_env("CartPole-v1", n_envs=2))


def test_image_observations_show_the_env_shape_and_the_flatten_wrapper():
    class ImageToy(ToyMeetEnv):
        def observation_space(self, agent):
            return spaces.Box(0, 255, (8, 6, 3), np.uint8)

        def _observations(self):
            return {agent: np.zeros((8, 6, 3), np.uint8) for agent in self.possible_agents}

    env = make_multiagent_vec_env(ImageToy, n_games=1, seed=0)
    with pytest.raises(ValueError, match=r"shape \(8, 6, 3\).*supersuit\.flatten_v0"):
        SAEIR_PPO("MSHGPolicy", env)
    env.close()


# ------------------------------------------------------------------------------------------------ envs and tasks
@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"n_games": 0}, ValueError, "n_games must be a positive integer"),
        ({"n_games": 2, "backend": "gpu"}, ValueError, "backend must be one of"),
        ({"n_games": 2, "world": "mpe3"}, ValueError, "world"),
        ({"n_games": 2, "reward": "dense"}, ValueError, "reward"),
        ({"n_games": 2, "cover_radius": -0.1}, ValueError, "cover_radius"),
        ({"n_games": 2, "collision_penalty": -1.0}, ValueError, "collision_penalty"),
        ({"n_games": 2, "N": 0}, ValueError, "N must be"),
    ],
)
def test_bad_navigation_options(kwargs, error, message):
    with pytest.raises(error, match=message):
        make_multiagent_vec_env("cn-sparse-n3", seed=0, **kwargs)


def test_unknown_task_id_lists_the_tasks():
    with pytest.raises(KeyError, match="Registered tasks: cn-sparse-n3"):
        make_multiagent_vec_env("cn-sparse-n5", n_games=2)


def test_agents_with_different_spaces_name_every_wrapper_at_once():
    class BothDiffer(MixedSpacesEnv):
        def action_space(self, agent):
            return spaces.Discrete(3) if agent == "agent_1" else spaces.Discrete(2)

    with pytest.raises(ValueError) as error:
        make_multiagent_vec_env(lambda: BothDiffer("observation"), n_games=1)
    assert "pad_observations_v0 and supersuit.pad_action_space_v0" in str(error.value)


@pytest.mark.parametrize("where", ["reward", "observation"])
def test_non_finite_values_name_the_game_agent_and_step(where):
    class Broken(ToyMeetEnv):
        def step(self, actions):
            observations, rewards, terminations, truncations, infos = super().step(actions)
            if self._t == 3:
                if where == "reward":
                    rewards = {**rewards, "agent_2": float("inf")}
                else:
                    observations = {**observations, "agent_1": np.array([np.nan, 0.0], np.float32)}
            return observations, rewards, terminations, truncations, infos

    env = make_multiagent_vec_env(Broken, n_games=2, seed=0)
    model = MAPPO("MAPPOPolicy", env, n_steps=6, n_epochs=1, policy_kwargs=dict(hidden_size=8))
    parameters = [p.detach().clone() for p in model.policy.parameters()]
    agent = "agent 2 (agent_2): reward inf" if where == "reward" else "agent 1 (agent_1): observation has nan at entry 0"
    with pytest.raises(NonFiniteValueError, match=re.escape(f"toy_meet_v0: game 0, {agent} at step 3 of its episode")):
        model.learn(2 * 6 * env.num_envs)
    assert all(p.isfinite().all() for p in model.policy.parameters())
    assert all((a == b).all() for a, b in zip(parameters, model.policy.parameters()))  # no update on bad data
    env.close()


@pytest.mark.parametrize("dtype", [np.float64, np.int64, np.uint8])
def test_observations_of_any_numeric_dtype_train(dtype):
    class Typed(ToyMeetEnv):
        def observation_space(self, agent):
            return spaces.Box(0, 4, (2,), dtype)

        def _observations(self):
            return {a: np.array([self._cells[i], self._goal], dtype) for i, a in enumerate(self.possible_agents)}

    env = make_multiagent_vec_env(Typed, n_games=2, seed=0)
    for algo in (SAEIR_PPO, MAPPO):
        model = algo("MSHGPolicy", env, n_steps=6, n_epochs=1, policy_kwargs=dict(hidden_size=8))
        before = [p.detach().clone() for p in model.policy.parameters()]
        model.learn(2 * 6 * env.num_envs)
        assert model.num_timesteps == 2 * 6 * env.num_envs
        after = list(model.policy.parameters())
        assert all(th.isfinite(p).all() for p in after)
        assert any(not th.equal(b, a) for b, a in zip(before, after))  # the updates read the observations as floats
        assert model.rollout_buffer.observations.dtype == np.float32
    env.close()


# ------------------------------------------------------------------------------------------------ command line
def snapshot(folder: Path) -> dict[str, tuple[int, float]]:
    """Every file under ``folder`` with its size and modification time."""
    return {
        str(path.relative_to(folder)): (path.stat().st_size, path.stat().st_mtime)
        for path in folder.rglob("*")
        if path.is_file()
    }


@pytest.fixture
def log_folder(tmp_path):
    """A log folder that already holds a user's run, which bad commands must leave untouched."""
    run = tmp_path / "logs" / "saeir_ppo" / "cn-sparse-n3_1"
    run.mkdir(parents=True)
    (run / "cn-sparse-n3.zip").write_bytes(b"a model the user saved")
    return tmp_path / "logs"


BASE = ["--algo", "saeir_ppo", "--n-games", "2", "-n", "100", "--eval-freq", "0", "--verbose", "0"]
BAD_COMMAND_LINES = [
    (["-params", "n_steps:2.5"], "n_steps must be an integer"),
    (["-params", "batch_size:7"], "batch_size=7 cannot be formed"),
    (["-params", "gamma:1.5"], "gamma=1.5 is out of range"),
    (["-params", "n_epochs:0"], "n_epochs=0 is out of range"),
    (["-params", "policy_kwargs:{hiden_size: 8}"], "unknown policy argument 'hiden_size'"),
    (["-params", "policy_kwargs:dict(net_arch=[64])"], "net_arch=[64] is not supported"),
    (["-params", "env_kwargs:{N: 3, radius: 0.2}"], "'radius' is not an argument of the task's constructor"),
    (["-params", "env_kwargs:{N: 3, world: mpe3}"], "world"),
    (["-params", "no_such_key:1"], "unknown config key 'no_such_key'"),
    (["-params", "policy_kwargs:dict(hidden_size=)"], "cannot evaluate 'dict(hidden_size=)': SyntaxError"),
    (["-params", "env_kwargs:dict(N=3, world='mpe3')"], "world"),
    (["-params", "learning_rate:fast"], "learning_rate='fast' has type str"),
    (["-params", "n_steps"], "is not key:value"),
    (["-params", "num_cpus:-1"], "num_cpus (env worker processes) must be an integer >= 0"),
    (["-n", "-5"], "n_timesteps (-n, agent-steps) must be a positive number"),
    (["--n-games", "0"], "n_envs (number of games) must be a positive integer"),
    (["--task", "cn-sparse-n5"], "unknown task 'cn-sparse-n5'"),
    (["-i", "missing.zip"], "--trained-agent missing.zip is not a file"),
    (["-conf", "missing.yml"], "config file missing.yml does not exist"),
]


@pytest.mark.parametrize("extra, message", BAD_COMMAND_LINES, ids=[m[:40] for _, m in BAD_COMMAND_LINES])
def test_bad_command_line(log_folder, capsys, extra, message):
    before = snapshot(log_folder)
    assert train_main([*BASE, "-f", str(log_folder), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sb3_saeir.train: error: ") and "\n" not in err, err
    assert message in err, err
    assert snapshot(log_folder) == before  # no new run folder, nothing changed


def test_env_kwargs_as_a_dict_string_work(tmp_path):
    argv = [*BASE, "-f", str(tmp_path), "-params", "n_steps:10", "env_kwargs:dict(N=3, reward='reach', world='mpe2')"]
    assert train_main(argv) == 0
    config = (tmp_path / "saeir_ppo" / "cn-sparse-n3_1" / "cn-sparse-n3" / "config.yml").read_text()
    assert "reach" in config and "mpe2" in config


def test_unknown_algorithm(log_folder, capsys):
    assert train_main(["--algo", "sae_ppo", "-f", str(log_folder)]) == 2
    assert "unknown algorithm 'sae_ppo'; valid choices: elign, ippo" in capsys.readouterr().err


def test_broken_yaml_config(log_folder, tmp_path, capsys):
    broken = tmp_path / "broken.yml"
    broken.write_text("cn-sparse-n3:\n  n_envs: [1\n")
    before = snapshot(log_folder)
    assert train_main([*BASE, "-f", str(log_folder), "-conf", str(broken)]) == 2
    err = capsys.readouterr().err.strip()
    assert "is not valid YAML (line 3)" in err and "\n" not in err
    assert snapshot(log_folder) == before


def test_not_a_zip_as_trained_agent(log_folder, tmp_path, capsys):
    not_a_model = tmp_path / "notes.zip"
    not_a_model.write_text("not a model")
    before = snapshot(log_folder)
    assert train_main([*BASE, "-f", str(log_folder), "-i", str(not_a_model)]) == 2
    assert "wasn't a zip-file" in capsys.readouterr().err
    assert snapshot(log_folder) == before and not_a_model.read_text() == "not a model"


def test_help_shows_defaults(capsys):
    with pytest.raises(SystemExit):
        train_main(["--help"])
    assert "(default: 25000)" in capsys.readouterr().out  # --eval-freq


def test_enjoy_without_runs_and_with_a_model_of_another_task(tmp_path, capsys):
    assert enjoy_main(["--algo", "saeir_ppo", "-f", str(tmp_path / "none")]) == 2
    assert "no run of saeir_ppo on cn-sparse-n3" in capsys.readouterr().err
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=1, seed=0)
    SAEIR_PPO("MSHGPolicy", env, n_steps=10, policy_kwargs=dict(hidden_size=8)).save(tmp_path / "n3.zip")
    assert enjoy_main(["--algo", "saeir_ppo", "--task", "cn-sparse-n4", "--model", str(tmp_path / "n3.zip")]) == 2
    assert "was trained with 3 agents per game, the task has 4" in capsys.readouterr().err


def test_enjoy_picks_the_latest_run_that_has_a_model(tmp_path):
    from sb3_saeir.run.folder import find_model

    for run, has_model in ((1, True), (2, False)):
        folder = tmp_path / "saeir_ppo" / f"cn-sparse-n3_{run}"
        folder.mkdir(parents=True)
        if has_model:
            (folder / "cn-sparse-n3.zip").write_bytes(b"model")
    assert find_model(tmp_path, "saeir_ppo", "cn-sparse-n3") == tmp_path / "saeir_ppo" / "cn-sparse-n3_1" / "cn-sparse-n3.zip"


def test_missing_extra_names_the_extra(monkeypatch):
    import builtins

    from sb3_saeir.common.extras import MissingExtraError, require_extra

    real_import = builtins.__import__

    def no_imageio(name, *args, **kwargs):
        if name.startswith("imageio"):
            raise ModuleNotFoundError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_imageio)
    with pytest.raises(MissingExtraError, match=r"writing a GIF needs imageio .*pip install 'sb3-saeir\[plots\]'"):
        require_extra("imageio.v2", "plots", "writing a GIF")


def test_package_namespace_has_no_leaked_names():
    import sb3_saeir

    assert not {"os", "file_handler"} & set(vars(sb3_saeir))
    assert os.path.isfile(Path(sb3_saeir.__file__).parent.parent / "LICENSE")
