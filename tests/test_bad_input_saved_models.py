"""Bad input around saved models (issue 55 and later rounds): a network of the other kind or size, another library's
zip, a folder for a file, a missing file, ``set_parameters`` of another shape; refused in one line, nothing set.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch as th

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from tests.test_bad_input_api import one_line

# ------------------------------------------------------------------------------------------------ issue 55
RECURRENT, FEED_FORWARD = dict(hidden_size=8), dict(hidden_size=8, recurrent=False)
KINDS = {"recurrent": RECURRENT, "feed-forward": FEED_FORWARD}


def _saved(algo, env, tiny_kwargs, tmp_path, kind):
    """A model zip of ``algo`` with the ``kind`` network (``"recurrent"`` or ``"feed-forward"``), and its path."""
    path = tmp_path / f"{kind}.zip"
    algo("MlpPolicy", env, **{**tiny_kwargs, "policy_kwargs": dict(KINDS[kind])}).save(path)
    return path


@pytest.mark.parametrize("algo", [SAEIR_PPO, MAPPO])
@pytest.mark.parametrize(
    "saved, override, words",
    [
        ("recurrent", dict(FEED_FORWARD), ["policy_kwargs recurrent=False does not fit", "network is recurrent"]),
        ("feed-forward", dict(RECURRENT, recurrent=True), ["recurrent=True does not fit", "network is feed-forward"]),
        ("feed-forward", dict(RECURRENT), ["without recurrent (so recurrent=True, the default)", "feed-forward"]),
    ],
    ids=["recurrent-zip", "feed-forward-zip", "feed-forward-zip-key-left-out"],
)
def test_load_with_policy_kwargs_of_the_other_kind(env, tiny_kwargs, tmp_path, algo, saved, override, words):
    """The override that builds the other network was reported as a damaged zip ("is not a complete sb3-saeir model
    zip ... save the model again")."""
    path = _saved(algo, env, tiny_kwargs, tmp_path, saved)
    with pytest.raises(ValueError) as error:
        algo.load(path, env=env, custom_objects={"policy_kwargs": override})
    one_line(error, f"{algo.__name__}.load: custom_objects", str(path), "drop the policy_kwargs override", *words)
    assert "not a complete" not in str(error.value)
    fitting = algo.load(path, env=env, custom_objects={"policy_kwargs": dict(KINDS[saved])})  # a positive control
    assert fitting.policy.feed_forward == (saved == "feed-forward")


def test_load_with_policy_kwargs_of_other_sizes(env, tiny_kwargs, tmp_path):
    path = _saved(MAPPO, env, tiny_kwargs, tmp_path, "recurrent")
    with pytest.raises(ValueError) as error:
        MAPPO.load(path, env=env, custom_objects={"policy_kwargs": {"hidden_size": 16}})
    one_line(error, "custom_objects policy_kwargs {'hidden_size': 16} do not fit", "size mismatch", "repeat the saved")


@pytest.mark.parametrize("source", ["zip", "dict"])
@pytest.mark.parametrize("saved, model_kind", [("recurrent", "feed-forward"), ("feed-forward", "recurrent")])
def test_set_parameters_of_the_other_kind(env, tiny_kwargs, tmp_path, source, saved, model_kind):
    """torch's ``load_state_dict`` error listed every GRU key over several lines."""
    path = _saved(MAPPO, env, tiny_kwargs, tmp_path, saved)
    parameters = str(path) if source == "zip" else MAPPO.load(path).get_parameters()
    model = MAPPO("MAPPOPolicy", env, **{**tiny_kwargs, "policy_kwargs": dict(KINDS[model_kind])})
    before = {name: value.clone() for name, value in model.policy.state_dict().items()}
    with pytest.raises(ValueError) as error:
        model.set_parameters(parameters)
    one_line(error, f"MAPPO.set_parameters: the parameters are of a {saved} network", f"this model's network is {model_kind}")
    after = model.policy.state_dict()
    assert all(np.array_equal(after[name].numpy(), value.numpy()) for name, value in before.items())


@pytest.mark.parametrize(
    "policy_kwargs, setting",
    [(FEED_FORWARD, "recurrent=False"), ({**RECURRENT, "recurrent_actor": False}, "recurrent_actor=False")],
)
@pytest.mark.parametrize("state", [np.zeros((6, 64)), np.zeros((6, 8)), [0.0]], ids=["(6, 64)", "(6, 8)", "list"])
def test_predict_state_of_a_feed_forward_actor(env, tiny_kwargs, policy_kwargs, setting, state):
    """SB3's feed-forward ``predict`` ignores a state (and returns it); the feed-forward actor ignored it silently,
    while the recurrent one names a state of the wrong shape: both refuse now."""
    model = MAPPO("MAPPOPolicy", env, **{**tiny_kwargs, "policy_kwargs": dict(policy_kwargs)})
    with pytest.raises(ValueError) as error:
        model.predict(np.zeros((6, 18)), state=state)
    one_line(error, f"predict: the model's actor is feed-forward ({setting}) and has no state", "pass state=None")
    assert model.predict(np.zeros((6, 18)), state=None)[1] is None  # a positive control


@pytest.mark.parametrize("where", ["constructor", "load"])
@pytest.mark.parametrize("case", ["/proc", "under a file"])
def test_tensorboard_log_that_cannot_be_written(env, tiny_kwargs, tmp_path, where, case):
    """SB3 failed only at ``learn``, with its raw ``FileNotFoundError`` (``/proc``) or ``NotADirectoryError``."""
    (tmp_path / "a_file").write_text("not a folder")
    folder, problem = {
        "/proc": ("/proc/tb", "no file can be created in /proc"),
        "under a file": (str(tmp_path / "a_file" / "tb"), "a_file is a file, not a folder"),
    }[case]
    if where == "load":
        MAPPO("MAPPOPolicy", env, **tiny_kwargs).save(tmp_path / "model.zip")
    with pytest.raises(ValueError) as error:
        if where == "constructor":
            MAPPO("MAPPOPolicy", env, tensorboard_log=folder, **tiny_kwargs)
        else:
            MAPPO.load(tmp_path / "model.zip", env=env, tensorboard_log=folder)
    one_line(error, f"MAPPO: tensorboard_log={folder!r}: ", problem, "pass a folder you can write")
    assert (tmp_path / "a_file").read_text() == "not a folder"


def test_compile_refusal_lists_the_backends_a_user_picks(env, tiny_kwargs):
    """The list held torch's ``*_TESTING_ONLY`` and minifier backends (a 570-character line)."""
    with pytest.raises(ValueError) as error:
        MAPPO("MAPPOPolicy", env, compile="fast", **tiny_kwargs)
    one_line(error, "MAPPO: compile must be True, False or a torch.compile backend name (", "inductor", "aot_eager", "'fast'")
    message = str(error.value)
    assert "TESTING_ONLY" not in message and "minifier" not in message and len(message) < 200, message
    # a positive control: a backend left out of the list is still accepted, as torch.compile accepts it
    assert (
        MAPPO("MAPPOPolicy", env, compile="aot_eager_decomp_partition", **tiny_kwargs).compile == "aot_eager_decomp_partition"
    )


# ------------------------------------------------------------------------------------------------ issue 55: load, save
def test_load_of_a_model_of_another_library_names_it(env, tmp_path):
    """SB3's ``Observation spaces do not match`` (with an env) or ``MAPPO needs an env`` (without) for an SB3 PPO zip."""
    import gymnasium as gym
    from stable_baselines3 import PPO

    path = tmp_path / "ppo.zip"
    PPO("MlpPolicy", gym.make("CartPole-v1"), n_steps=16, batch_size=16).save(path)
    for kwargs in ({"env": env}, {}):
        with pytest.raises(ValueError) as error:
            MAPPO.load(path, **kwargs)
        one_line(
            error,
            f"MAPPO.load: {str(path)!r} is a model of another library",
            "stable_baselines3.common.policies.ActorCriticPolicy",
            "load it with that library's algorithm class",
        )


def test_load_onto_an_env_of_another_number_of_agents_names_the_agents(env, tiny_kwargs, tmp_path):
    """SB3 compared the observation spaces first: ``Observation spaces do not match: Box(..., (18,)) != (24,)``."""
    path = tmp_path / "n3.zip"
    MAPPO("MAPPOPolicy", env, **tiny_kwargs).save(path)
    four = make_multiagent_vec_env("cn-sparse-n4", n_games=2, seed=0)
    with pytest.raises(ValueError) as error:
        MAPPO.load(path, env=four)
    four.close()
    one_line(error, "MAPPO: the model was built for 3 agents per game, the env has 4")


@pytest.mark.parametrize("given", ["a.zip", "a"])
def test_save_to_a_folder_and_load_of_a_folder_are_refused(model, tmp_path, given):
    """SB3 warned and saved to ``a.zip_2``, which ``load("a.zip")`` did not read (``IsADirectoryError``)."""
    folder = tmp_path / "a.zip"
    folder.mkdir()
    with pytest.raises(ValueError) as error:
        model.save(tmp_path / given)
    one_line(error, f"SAEIR_PPO.save: {str(folder)!r} is a folder; save to a file path such as", "a.zip/model.zip")
    assert sorted(path.name for path in tmp_path.iterdir()) == ["a.zip"] and not any(folder.iterdir())
    with pytest.raises(IsADirectoryError) as error:
        SAEIR_PPO.load(folder)
    one_line(error, f"SAEIR_PPO.load: {str(folder)!r} is a folder, not a model zip", "a.zip/model.zip")


def test_load_of_no_file_names_the_path_once(tmp_path):
    """SB3 named the second path it tried: ``No such file or directory: '.../no_such.zip.zip'``."""
    path = tmp_path / "no_such.zip"
    with pytest.raises(FileNotFoundError) as error:
        MAPPO.load(path)
    assert str(error.value) == f"MAPPO.load: no such file {str(path)!r}."


def test_compile_in_custom_objects_is_refused(env, tiny_kwargs, tmp_path):
    """``compile`` is not saved, and SB3's custom_objects replace only what the zip holds: it was ignored."""
    path = tmp_path / "model.zip"
    MAPPO("MAPPOPolicy", env, **tiny_kwargs).save(path)
    with pytest.raises(ValueError) as error:
        MAPPO.load(path, env=env, custom_objects={"compile": "fast"})
    one_line(error, "MAPPO.load: custom_objects 'compile' is not used", "MAPPO.load(path, compile=...)")


def test_set_parameters_with_an_entry_missing_sets_nothing(env, tiny_kwargs):
    """torch's two-line ``Missing key(s) in state_dict`` came after it had set the tensors it found."""
    model = MAPPO("MAPPOPolicy", env, seed=0, **tiny_kwargs)
    other = MAPPO("MAPPOPolicy", env, seed=1, **tiny_kwargs).get_parameters()
    first = next(iter(other["policy"]))
    del other["policy"][first]
    before = {name: value.clone() for name, value in model.policy.state_dict().items()}
    with pytest.raises(ValueError) as error:
        model.set_parameters(other, exact_match=True)
    one_line(error, "MAPPO.set_parameters:", f"missing policy[{first!r}]", "nothing was set", "exact_match=False")
    after = model.policy.state_dict()
    assert all(np.array_equal(after[name].numpy(), value.numpy()) for name, value in before.items())
    model.set_parameters(other, exact_match=False)  # a positive control: the others are set
    assert not np.array_equal(model.policy.state_dict()["actor.mlp.1.weight"].numpy(), before["actor.mlp.1.weight"].numpy())


@pytest.fixture
def small_model():
    from sb3_saeir import MAPPO, make_multiagent_vec_env

    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    yield MAPPO("MAPPOPolicy", env, n_steps=10, n_epochs=1, policy_kwargs=dict(hidden_size=8), seed=0)
    env.close()


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"callback": 42}, TypeError, "MAPPO.learn: callback=42 is not a callback; pass an SB3 BaseCallback"),
        ({"callback": [None, "eval"]}, TypeError, "MAPPO.learn: callback list item 'eval' is not a callback"),
        ({"log_interval": 0}, ValueError, "MAPPO.learn: log_interval=0 must be a whole number >= 1"),
        ({"log_interval": 1.5}, ValueError, "MAPPO.learn: log_interval=1.5 must be a whole number >= 1"),
    ],
)
def test_learn_refuses_a_bad_callback_or_log_interval_before_training(small_model, kwargs, error, message):
    with pytest.raises(error) as excinfo:
        small_model.learn(60, **kwargs)
    assert message in str(excinfo.value) and "\n" not in str(excinfo.value)
    assert small_model.num_timesteps == 0


def test_save_none_is_refused_in_one_line(small_model):
    with pytest.raises(TypeError, match=r"MAPPO.save: path=None; pass a file path \(such as 'model.zip'\)"):
        small_model.save(None)


@pytest.mark.parametrize("exact_match", [True, False])
def test_set_parameters_of_another_shape_is_refused_and_nothing_is_set(small_model, exact_match):

    params = small_model.get_parameters()
    before = {key: value.clone() for key, value in small_model.policy.state_dict().items()}
    first, second = list(params["policy"])[:2]
    params["policy"][first] = th.ones(3, 3)
    params["policy"][second] = th.ones_like(params["policy"][second])  # a good one: must not be set either
    with pytest.raises(ValueError) as excinfo:
        small_model.set_parameters(params, exact_match=exact_match)
    message = str(excinfo.value)
    assert f"policy[{first!r}] (3, 3) for" in message and "nothing was set" in message and "\n" not in message
    after = small_model.policy.state_dict()
    assert all(th.equal(before[key], after[key]) for key in before)
