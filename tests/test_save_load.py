"""Save and load across methods and policies (SB3's tests/test_save_load.py for the package's algorithms)."""

import numpy as np
import pytest
import torch as th

from sb3_saeir import MAPPO, SAEIR_PPO

ALGOS = [SAEIR_PPO, MAPPO]
POLICIES = ["MSHGPolicy", "MAPPOPolicy", "SNMAPPOPolicy"]


def deterministic_actions(model, observations):
    """Greedy actions over a sequence of observations ``(T, n_slots, d)``, GRU states carried through."""
    states, starts, actions = None, np.ones(observations.shape[1], dtype=bool), []
    for obs in observations:
        action, states = model.predict(obs, state=states, episode_start=starts, deterministic=True)
        starts = np.zeros_like(starts)
        actions.append(action)
    return np.stack(actions)


def observation_sequence(env, n_steps=8):
    rng = np.random.default_rng(0)
    observations = [env.reset()]
    for _ in range(n_steps - 1):
        observations.append(env.step(rng.integers(0, env.action_space.n, size=env.num_envs))[0])
    return np.stack(observations)


@pytest.mark.parametrize("algo", ALGOS)
@pytest.mark.parametrize("policy", POLICIES)
def test_save_load_same_parameters_actions_and_settings(algo, policy, env, tiny_kwargs, tmp_path):
    bonus = {"intrinsic_coef": 0.3} if algo is SAEIR_PPO else {}  # MAPPO has no intrinsic reward: refused there
    model = algo(policy, env, seed=0, **bonus, **tiny_kwargs).learn(2 * 10 * env.num_envs)
    observations = observation_sequence(env)
    expected_actions = deterministic_actions(model, observations)
    model.save(tmp_path / "model.zip")

    loaded = algo.load(tmp_path / "model.zip", device="cpu")
    assert type(loaded) is algo and type(loaded.policy) is type(model.policy)
    for name, tensor in model.policy.state_dict().items():
        assert th.equal(tensor, loaded.policy.state_dict()[name]), name
    np.testing.assert_array_equal(deterministic_actions(loaded, observations), expected_actions)
    for attribute in (
        "n_agents",
        "n_steps",
        "n_epochs",
        "n_minibatches",
        "intrinsic_reward",
        "intrinsic_coef",
        "num_timesteps",
    ):
        assert getattr(loaded, attribute) == getattr(model, attribute), attribute
    assert loaded.policy.scales == model.policy.scales
    # the ValueNorm statistics are part of the state dict: the de-normalised values agree
    values = np.random.default_rng(1).normal(size=(4, len(model.policy.scales))).astype(np.float32)
    np.testing.assert_array_equal(
        loaded.policy.denormalize_values_numpy(values), model.policy.denormalize_values_numpy(values)
    )


@pytest.mark.parametrize("algo", ALGOS)
def test_loaded_model_continues_training_on_a_new_env(algo, env, tiny_kwargs, tmp_path):
    model = algo("MSHGPolicy", env, seed=0, **tiny_kwargs).learn(10 * env.num_envs)
    model.save(tmp_path / "model.zip")
    loaded = algo.load(tmp_path / "model.zip", env=env, device="cpu")

    def adam_steps(m):
        return sorted(float(state["step"]) for state in m.policy.optimizer.state_dict()["state"].values())

    assert adam_steps(loaded) == adam_steps(model) and adam_steps(model)[0] > 0  # the optimizer state was restored
    loaded.learn(10 * env.num_envs, reset_num_timesteps=False)
    assert loaded.num_timesteps == 2 * 10 * env.num_envs


def test_batch_size_keeps_its_meaning_on_another_number_of_games(tiny_kwargs, tmp_path):
    """A 10-step rollout of 3 agents is split in blocks of 30 agent-samples: batch_size=30 is one block per minibatch
    on 2 games (2 minibatches), on 4 games (4) and on 1 game (1); a saved n_minibatches=2 that 1 game cannot hold is
    refused at load, in one line, not after a rollout."""
    from sb3_saeir import make_multiagent_vec_env

    two, four, one = (make_multiagent_vec_env("cn-sparse-n3", n_games=n, seed=0) for n in (2, 4, 1))
    model = SAEIR_PPO("MSHGPolicy", two, seed=0, batch_size=30, **tiny_kwargs)
    assert model.n_minibatches == 2
    model.save(tmp_path / "batch.zip")
    assert SAEIR_PPO.load(tmp_path / "batch.zip", env=four, device="cpu").n_minibatches == 4
    loaded = SAEIR_PPO.load(tmp_path / "batch.zip", env=one, device="cpu")
    assert loaded.n_minibatches == 1 and loaded.batch_size == 30
    loaded.learn(10 * one.num_envs)
    SAEIR_PPO("MSHGPolicy", two, seed=0, n_minibatches=2, **tiny_kwargs).save(tmp_path / "split.zip")
    with pytest.raises(ValueError, match=r"n_minibatches=2 must be between 1 and the number of \(game, chunk\) blocks 1"):
        SAEIR_PPO.load(tmp_path / "split.zip", env=one, device="cpu")
    for env in (two, four, one):
        env.close()


def test_loading_onto_an_env_with_another_number_of_agents_is_refused(env, tiny_kwargs, tmp_path):
    from sb3_saeir import make_multiagent_vec_env

    SAEIR_PPO("MSHGPolicy", env, seed=0, **tiny_kwargs).save(tmp_path / "model.zip")
    four_agents = make_multiagent_vec_env("cn-sparse-n4", n_games=2, seed=0)
    with pytest.raises(ValueError, match=r"agents|Observation spaces do not match"):
        SAEIR_PPO.load(tmp_path / "model.zip", env=four_agents, device="cpu")
    four_agents.close()


@pytest.mark.parametrize("algo", ALGOS)
def test_save_load_on_a_user_parallel_env(algo, toy_env, tiny_kwargs, tmp_path):
    """Any PettingZoo parallel env through SuperSuit: train, save, load, same greedy actions."""
    model = algo("MSHGPolicy", toy_env, seed=0, n_steps=6, n_epochs=1, policy_kwargs=dict(hidden_size=8))
    model.learn(2 * 6 * toy_env.num_envs)
    observations = observation_sequence(toy_env, n_steps=6)
    model.save(tmp_path / "toy.zip")
    loaded = algo.load(tmp_path / "toy.zip", device="cpu")
    np.testing.assert_array_equal(deterministic_actions(loaded, observations), deterministic_actions(model, observations))


def test_a_zip_records_the_package_version_and_another_version_is_named_on_load(tmp_path, recwarn):
    """``save`` records the sb3-saeir version in the zip's data; ``load`` of a zip from another version loads with one
    warning naming both (an older zip without the record, or the same version, loads without a word)."""
    import json
    import zipfile

    from sb3_saeir import __version__, make_multiagent_vec_env

    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    MAPPO("MAPPOPolicy", env, n_steps=10, n_epochs=1, seed=0).save(tmp_path / "model.zip")
    with zipfile.ZipFile(tmp_path / "model.zip") as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    assert json.loads(entries["data"])["sb3_saeir_version"] == __version__
    MAPPO.load(tmp_path / "model.zip")
    assert not [w for w in recwarn if "sb3-saeir" in str(w.message)]
    data = json.loads(entries["data"])
    for name, version in (("old.zip", "0.1.0"), ("unrecorded.zip", None)):
        if version is None:
            del data["sb3_saeir_version"]
        else:
            data["sb3_saeir_version"] = version
        with zipfile.ZipFile(tmp_path / name, "w") as archive:
            for entry, content in entries.items():
                archive.writestr(entry, json.dumps(data) if entry == "data" else content)
    with pytest.warns(UserWarning, match=rf"saved by sb3-saeir 0\.1\.0; this is {__version__}") as caught:
        MAPPO.load(tmp_path / "old.zip")
    assert len([w for w in caught if "sb3-saeir" in str(w.message)]) == 1 and "\n" not in str(caught[0].message)
    recwarn.clear()
    MAPPO.load(tmp_path / "unrecorded.zip")
    assert not [w for w in recwarn if "sb3-saeir" in str(w.message)]
    env.close()
