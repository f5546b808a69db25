"""Every entry of every packaged zoo config builds its model; every method trains two iterations from its config."""

import inspect

import pytest
import yaml
from stable_baselines3 import PPO

from sb3_saeir import MAPPO, SAEIR_PPO
from sb3_saeir.config import ALGOS, config_dir, load_hyperparams, parse_policy_kwargs
from sb3_saeir.experiment import Experiment

CONFIG_ENTRIES = [
    pytest.param(path.stem, task, marks=[pytest.mark.football] if task.startswith("grf-") else [])
    for path in sorted(config_dir().glob("*.yml"))
    for task in yaml.safe_load(path.read_text())
]


def test_every_method_has_a_config():
    assert {entry.values[0] for entry in CONFIG_ENTRIES} == set(ALGOS)
    assert {entry.values[1] for entry in CONFIG_ENTRIES} >= {"cn-sparse-n3", "cn-sparse-n4"}


@pytest.mark.parametrize("algo, task", CONFIG_ENTRIES)
def test_config_entry_builds(algo, task):
    experiment = Experiment(algo, task, n_games=2)
    model, env, resolved = experiment.build(), experiment.env, experiment.resolved_hyperparams
    params = load_hyperparams(algo, task)
    assert env.n_agents == params["env_kwargs"]["N"]
    assert model.learning_rate == params["learning_rate"]
    assert model.n_epochs == params["n_epochs"] and model.n_steps == params["n_steps"]
    assert resolved["n_envs"] == 2
    if isinstance(model, MAPPO):
        assert model.intrinsic_reward == params.get("intrinsic_reward")
    env.close()


@pytest.mark.parametrize("algo", sorted(ALGOS))
def test_every_method_trains_two_iterations_from_its_config(algo):
    experiment = Experiment(algo, "cn-sparse-n3", n_games=2)
    model, env, callbacks = experiment.build(), experiment.env, experiment.config_callbacks
    if isinstance(model, PPO):  # IPPO: the whole-rollout batch follows the game count
        assert model.batch_size == model.n_steps * env.num_envs
    model.learn(2 * model.n_steps * env.num_envs, callback=callbacks)
    assert model.num_timesteps == 2 * model.n_steps * env.num_envs
    env.close()


def test_paper_hyperparameters_identical_across_methods():
    shared = ("learning_rate", "n_steps", "n_epochs", "gamma", "gae_lambda", "clip_range", "ent_coef", "n_envs")
    for task in ("cn-sparse-n3", "cn-sparse-n4"):
        reference = load_hyperparams("saeir_ppo", task)
        for algo in ALGOS:
            params = load_hyperparams(algo, task)
            assert {key: params[key] for key in shared} == {key: reference[key] for key in shared}, algo
            assert parse_policy_kwargs(params["policy_kwargs"])["activation_fn"].__name__ == "Tanh"


# The authors' settings (docs/method.md; the paper's supplement Table 1 and the released scripts), written out by hand
AUTHORS = {
    "navigation": dict(learning_rate=7e-4, n_steps=25, n_epochs=10, n_minibatches=1, n_envs=128),
    "football": dict(learning_rate=5e-4, n_steps=200, n_epochs=15, n_minibatches=2, n_envs=50),
    "both": dict(
        data_chunk_length=10, gamma=0.99, gae_lambda=0.95, clip_range=0.2, ent_coef=0.01, vf_coef=1.0,
        max_grad_norm=10.0, value_loss="huber", huber_delta=10.0,
    ),
}  # fmt: skip


@pytest.mark.parametrize("task", ["cn-sparse-n3", "cn-sparse-n4", "grf-3v1-keeper", "grf-counterattack-easy"])
def test_packaged_configs_hold_the_authors_settings(task):
    family = "football" if task.startswith("grf") else "navigation"
    expected = {**AUTHORS[family], **AUTHORS["both"]}
    checked = 0
    for algo in ALGOS:
        try:
            params = load_hyperparams(algo, task)
        except KeyError:
            continue  # no entry of this method for this task
        if algo == "ippo":  # MAPPO's machinery without its chunked recurrent update
            expected_here = {key: value for key, value in expected.items() if key in params}
        else:
            expected_here = expected
        assert {key: params.get(key) for key in expected_here} == expected_here, algo
        checked += 1
    assert checked >= 2  # at least MAPPO and SAEIR_PPO


def test_class_defaults_are_the_authors_shared_settings():
    for algo_class in (MAPPO, SAEIR_PPO):
        defaults = inspect.signature(algo_class.__init__).parameters
        for key, value in AUTHORS["both"].items():
            assert defaults[key].default == value, (algo_class.__name__, key)


def test_missing_entry_and_unknown_algo():
    with pytest.raises(KeyError, match="cn-sparse-n3"):
        load_hyperparams("mappo", "grf-5v5")
    with pytest.raises(KeyError, match="saeir_ppo"):
        load_hyperparams("qmix", "cn-sparse-n3")


@pytest.mark.parametrize(
    "value, variant",
    [
        ("dict(variant='paper')", "paper"),
        ({"variant": "paper"}, "paper"),
        ("dict(variant='supplement')", "supplement"),
        ({"variant": "supplement"}, "supplement"),
    ],
)
def test_intrinsic_kwargs_string_or_dict(value, variant):
    """``-params "intrinsic_kwargs:dict(variant='paper')"`` is evaluated like rl-zoo's ``policy_kwargs`` strings."""
    params = {**load_hyperparams("saeir_ppo", "cn-sparse-n3"), "intrinsic_kwargs": value}
    experiment = Experiment("saeir_ppo", "cn-sparse-n3", params, n_games=2)
    model, env = experiment.build(), experiment.env
    assert model.intrinsic_kwargs == {"variant": variant}
    env.close()


@pytest.mark.parametrize("task", ["grf-3v1-keeper", "grf-counterattack-easy"])
def test_football_ablations_change_only_their_half_of_saeir(task):
    """MSHG-only is SAEIR_PPO without the bonus, SAE-only is MAPPO with it (the paper's Fig. 5 ablation)."""
    saeir, mappo = load_hyperparams("saeir_ppo", task), load_hyperparams("mappo", task)
    without_bonus = {key: value for key, value in saeir.items() if key != "intrinsic_coef"}
    assert load_hyperparams("mshg_only", task) == {**without_bonus, "intrinsic_reward": None}
    assert load_hyperparams("sae_only", task) == {**mappo, "intrinsic_reward": "saeir", "intrinsic_coef": 0.1}
    assert saeir["intrinsic_coef"] == 0.1


def test_experiment_of_an_unknown_task_is_refused_when_made():
    from sb3_saeir.experiment import Experiment

    with pytest.raises(KeyError) as error:
        Experiment("mappo", "nope-task")  # accepted; the KeyError came at build()
    assert "Unknown task 'nope-task'. Registered tasks:" in str(error.value)


@pytest.mark.parametrize(
    "games, cpus, message",
    [
        (2.5, None, "Experiment: n_games must be an integer >= 1, got 2.5."),
        (0, None, "Experiment: n_games must be an integer >= 1, got 0."),
        (True, None, "Experiment: n_games must be an integer >= 1, got True."),
        (2, -1, "Experiment: num_cpus must be an integer >= 0, got -1."),
        (2, "2", "Experiment: num_cpus must be an integer >= 0, got '2'."),
    ],
)
def test_experiment_refuses_game_and_worker_counts_that_are_not_counts(games, cpus, message):
    from sb3_saeir.experiment import Experiment

    with pytest.raises(ValueError) as error:
        Experiment("mappo", "cn-sparse-n3", n_games=games, num_cpus=cpus)
    assert str(error.value) == message


def test_experiment_takes_a_whole_float_count():
    from sb3_saeir.experiment import Experiment

    assert Experiment("mappo", "cn-sparse-n3", n_games=2.0, num_cpus=0.0).n_games == 2
