"""Bad input to the Python API (issue 24, part A): refused early with one line naming the argument.

Kinds: serious ones (load onto games of another size, the 2-agent MSHG default, string booleans), silent acceptance,
late errors made early, raw library errors replaced by one line.
"""

from __future__ import annotations

import warnings
import zipfile
from functools import partial

import numpy as np
import pytest
import torch as th
from gymnasium import spaces

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.utils import keywords_taken
from sb3_saeir.intrinsic import ElignCallback, RNDCallback
from sb3_saeir.intrinsic.saeir import SAEIRCallback
from tests.toy_envs import ToyMeetEnv


def one_line(error: pytest.ExceptionInfo, *words: str) -> None:
    message = str(error.value)
    assert "\n" not in message, message
    for word in words:
        assert word in message, message


# ------------------------------------------------------------------------------------------------ serious ones
@pytest.mark.parametrize("algo", [SAEIR_PPO, MAPPO])
def test_load_onto_games_of_another_size(tiny_kwargs, tmp_path, algo):
    """Same observation space, 6 agents per game: before, the model trained as if each game were two 3-agent games."""
    path = tmp_path / "model.zip"
    three = make_multiagent_vec_env(partial(ToyMeetEnv, n_agents=3), n_games=4, seed=0)
    algo("MlpPolicy", three, **tiny_kwargs).save(path)
    six = make_multiagent_vec_env(partial(ToyMeetEnv, n_agents=6), n_games=2, seed=0)
    assert six.observation_space == three.observation_space and six.num_envs == three.num_envs
    with pytest.raises(ValueError) as error:
        algo.load(path, env=six)
    three.close()
    six.close()
    one_line(error, "3 agents per game", "6")


def test_mshg_default_trains_on_two_agents(tiny_kwargs):
    two = make_multiagent_vec_env("cn-sparse-n3", n_games=2, N=2, seed=0)
    with pytest.warns(UserWarning, match="group scale is left out"):
        model = SAEIR_PPO("MSHGPolicy", two, **tiny_kwargs)
    assert model.policy.scales == ("team", "individual")
    model.learn(40)
    two.close()


def test_mshg_explicit_group_scale_on_two_agents_still_errors(tiny_kwargs):
    two = make_multiagent_vec_env("cn-sparse-n3", n_games=2, N=2, seed=0)
    kwargs = {**tiny_kwargs, "policy_kwargs": {"hidden_size": 8, "scales": ("team", "group", "individual")}}
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", two, **kwargs)
    two.close()
    one_line(error, "group_size=2 must be smaller")


STRING_BOOLEANS = [
    ("algo", "normalize_advantage"),
    ("algo", "normalize_values"),
    ("policy", "recurrent_actor"),
    ("policy", "normalize_values"),
    ("policy", "critic_gumbel_noise"),
    ("policy", "ortho_init"),
    ("intrinsic", "reset_at_episode_start"),
]


@pytest.mark.parametrize("where, name", STRING_BOOLEANS, ids=[f"{w}-{n}" for w, n in STRING_BOOLEANS])
@pytest.mark.parametrize("value", ["no", "False"])
def test_string_boolean_refused(env, tiny_kwargs, where, name, value):
    kwargs = dict(tiny_kwargs)
    if where == "algo":
        kwargs[name] = value
    elif where == "policy":
        kwargs["policy_kwargs"] = {"hidden_size": 8, name: value}
    else:
        kwargs["intrinsic_kwargs"] = {name: value}
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", env, **kwargs)
    one_line(error, name, "must be True or False")


BAD_OPTIMIZER_ARGUMENTS = {
    "class-by-name": ({"optimizer_class": "adam"}, ["optimizer_class='adam' is not a PyTorch optimizer class", "the class"]),
    "class-not-optimizer": ({"optimizer_class": th.nn.Linear}, ["is not a PyTorch optimizer class", "torch.optim.Adam"]),
    "kwargs-not-dict": ({"optimizer_kwargs": [("eps", 1e-5)]}, ["is not a dict of keyword arguments"]),
    "kwargs-lr": ({"optimizer_kwargs": {"lr": 0.1}}, ["optimizer_kwargs sets 'lr'", "pass learning_rate="]),
    "kwargs-params": ({"optimizer_kwargs": {"params": []}}, ["optimizer_kwargs sets 'params'", "remove it"]),
    "kwargs-unknown": ({"optimizer_kwargs": {"epsilon": 1e-5}}, ["'epsilon', which Adam does not take", "eps"]),
    "kwargs-of-another-class": (
        {"optimizer_class": th.optim.SGD, "optimizer_kwargs": {"betas": (0.9, 0.99)}},
        ["'betas', which SGD does not take", "momentum"],
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_OPTIMIZER_ARGUMENTS))
def test_optimizer_arguments_are_checked(env, tiny_kwargs, case):
    """PyTorch's messages named neither argument ("'str' object is not callable", "got multiple values for keyword
    argument 'lr'", "unexpected keyword argument"); each is now one line naming the argument and the fix."""
    policy_kwargs, words = BAD_OPTIMIZER_ARGUMENTS[case]
    with pytest.raises(ValueError) as error:
        MAPPO("MAPPOPolicy", env, **{**tiny_kwargs, "policy_kwargs": {"hidden_size": 8, **policy_kwargs}})
    one_line(error, "MAPPOPolicy: optimizer_", *words)


def test_optimizer_arguments_that_fit_pass(env, tiny_kwargs):
    """The positive control: an optimizer class's own keywords pass, on Adam and on SGD."""
    for fitting in (
        {"optimizer_kwargs": {"eps": 1e-6}},
        {"optimizer_class": th.optim.SGD, "optimizer_kwargs": {"momentum": 0.9}},
    ):
        model = MAPPO("MAPPOPolicy", env, **{**tiny_kwargs, "policy_kwargs": {"hidden_size": 8, **fitting}})
        assert all(model.policy.optimizer.defaults[key] == value for key, value in fitting["optimizer_kwargs"].items())


class _AnyKeywordAdam(th.optim.Adam):
    """An optimizer whose signature cannot tell its keywords (``**kwargs``)."""

    def __init__(self, params, **kwargs):
        super().__init__(params, **kwargs)


def test_an_optimizer_that_takes_any_keyword_checks_its_own(env, tiny_kwargs):
    """``**kwargs``: no keyword is refused or added by the policy; the class's own check still names a wrong one."""
    policy_kwargs = {"hidden_size": 8, "optimizer_class": _AnyKeywordAdam}
    model = MAPPO("MAPPOPolicy", env, **{**tiny_kwargs, "policy_kwargs": policy_kwargs})
    assert model.policy.optimizer.defaults["eps"] == th.optim.Adam([th.zeros(1)]).defaults["eps"]  # PyTorch's own
    with pytest.raises(TypeError, match="epsilon"):
        MAPPO("MAPPOPolicy", env, **{**tiny_kwargs, "policy_kwargs": {**policy_kwargs, "optimizer_kwargs": {"epsilon": 1}}})


def _positional_and_keywords(a, /, b, *args, c=1, **kwargs):
    pass


def _keywords(a, /, b, *args, c=1):
    pass


class _KeywordOptimizer:
    def __init__(self, params, lr=0.1, *, eps=1e-8):
        pass


@pytest.mark.parametrize(
    "function, expected",
    [
        (_keywords, ("b", "c")),  # positional-only and *args are not keywords
        (_positional_and_keywords, None),  # **kwargs: any keyword
        (_KeywordOptimizer, ("params", "lr", "eps")),
        (ToyMeetEnv, ("n_agents", "max_cycles")),  # a class: its constructor's, without self
        (len, ()),  # a builtin with a signature: positional-only
        (min, None),  # a builtin without one
    ],
    ids=["keywords", "var-keyword", "optimizer-class", "env-class", "builtin", "no-signature"],
)
def test_keywords_taken(function, expected):
    """The keyword names the argument checks accept, or None where the signature cannot tell them."""
    assert keywords_taken(function) == expected


BAD_BONUS_SETTINGS = [
    ("RNDCallback", {"learning_rate": "fast"}, "learning_rate must be a finite number > 0, got 'fast'"),
    ("RNDCallback", {"learning_rate": -1e-4}, "learning_rate must be a finite number > 0"),
    ("RNDCallback", {"gamma_int": 1.5}, "gamma_int must be a finite number in [0, 1]"),
    ("RNDCallback", {"n_epochs": 2.5}, "n_epochs must be an integer >= 1"),
    ("RNDCallback", {"embedding_dim": 0}, "embedding_dim must be an integer >= 1"),
    ("RNDCallback", {"obs_clip": 0.0}, "obs_clip must be a finite number > 0"),
    ("ElignCallback", {"obs_radius": -0.5}, "obs_radius must be a finite number > 0 (or None: every teammate)"),
    ("ElignCallback", {"obs_radius": "0.5"}, "obs_radius must be a finite number > 0"),
    ("ElignCallback", {"learning_rate": 0.0}, "learning_rate must be a finite number > 0"),
    ("ElignCallback", {"n_epochs": 0}, "n_epochs must be an integer >= 1"),
    ("SAEIRCallback", {"coef": -0.1}, "coef must be a finite number >= 0"),
    ("SAEIRCallback", {"coef": float("nan")}, "coef must be a finite number >= 0"),
]


@pytest.mark.parametrize(
    "name, kwargs, words", BAD_BONUS_SETTINGS, ids=[f"{n}-{next(iter(k))}" for n, k, _ in BAD_BONUS_SETTINGS]
)
def test_bonus_settings_out_of_range_are_refused(name, kwargs, words):
    """Accepted without a word before: a negative learning rate, gamma_int 1.5 (intrinsic returns that grow without
    bound), zero epochs (a bonus model never trained), a string radius (a TypeError at the first rollout)."""
    callback_class = {"RNDCallback": RNDCallback, "ElignCallback": ElignCallback, "SAEIRCallback": SAEIRCallback}[name]
    with pytest.raises(ValueError) as error:
        callback_class(**kwargs)
    one_line(error, f"{name}: {words}")


def test_bonus_settings_reach_the_check_through_the_algorithm(env, tiny_kwargs):
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", env, intrinsic_reward="rnd", intrinsic_kwargs={"gamma_int": 1.5}, **tiny_kwargs)
    one_line(error, "RNDCallback: gamma_int must be a finite number in [0, 1], got 1.5")
    SAEIR_PPO("MSHGPolicy", env, intrinsic_reward="elign", intrinsic_kwargs={"obs_radius": None}, **tiny_kwargs)


def test_string_boolean_refused_by_callback():
    with pytest.raises(ValueError) as error:
        SAEIRCallback(reset_at_episode_start="no")
    one_line(error, "reset_at_episode_start", "must be True or False")


# ------------------------------------------------------------------------------------------------ silent acceptance
BAD_CONSTRUCTOR = [
    ({"use_sde": True}, "use_sde=True is not supported"),
    ({"clip_range_vf": -0.5}, "clip_range_vf=-0.5 is out of range"),
    ({"clip_range_vf": 0.0}, "clip_range_vf=0.0 is out of range"),
    ({"normalize_advantage": 1}, "normalize_advantage must be True or False"),
    ({"normalize_advantage": None}, "normalize_advantage must be True or False"),
    ({"stats_window_size": 0}, "stats_window_size=0 is out of range"),
    ({"stats_window_size": -3}, "stats_window_size=-3 is out of range"),
    ({"intrinsic_reward": None, "intrinsic_kwargs": {"variant": "paper"}}, "would be ignored"),
]


@pytest.mark.parametrize("kwargs, message", BAD_CONSTRUCTOR, ids=[m for _, m in BAD_CONSTRUCTOR])
def test_silent_constructor_argument_refused(env, tiny_kwargs, kwargs, message):
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", env, **{**tiny_kwargs, **kwargs})
    one_line(error, message)


def test_value_clipping_off_value_accepted(env, tiny_kwargs, monkeypatch):
    """``clip_range_vf=-1`` trains, and the value loss gets -1, which it reads as no clipping (tests/test_mappo.py)."""
    import sb3_saeir.mappo.losses as losses

    given = []
    value_loss = losses.clipped_value_loss

    def recording_value_loss(values, old_values, returns, clip_range_vf, *args):
        given.append(clip_range_vf)
        return value_loss(values, old_values, returns, clip_range_vf, *args)

    monkeypatch.setattr(losses, "clipped_value_loss", recording_value_loss)
    SAEIR_PPO("MSHGPolicy", env, clip_range_vf=-1, **tiny_kwargs).learn(20)
    assert given and set(given) == {-1}


@pytest.mark.parametrize("total_timesteps", [0, -5, 2.5, "100"])
def test_learn_needs_positive_integer(env, tiny_kwargs, tmp_path, total_timesteps):
    model = SAEIR_PPO("MSHGPolicy", env, tensorboard_log=str(tmp_path / "tb"), **tiny_kwargs)
    with pytest.raises(ValueError) as error:
        model.learn(total_timesteps)
    one_line(error, "total_timesteps")
    assert not (tmp_path / "tb").exists()
    assert model.num_timesteps == 0


def test_ppo_hyperparameters_that_turn_gsde_off_apply(env, tiny_kwargs):
    model = SAEIR_PPO("MSHGPolicy", env, use_sde=False, sde_sample_freq=-1, **tiny_kwargs)
    assert model.use_sde is False and model.sde_sample_freq == -1


def test_learn_takes_a_whole_float_as_sb3_does(env, tiny_kwargs):
    model = SAEIR_PPO("MSHGPolicy", env, **tiny_kwargs).learn(6e1)  # one rollout: 10 steps x 6 slots
    assert model.num_timesteps == 60 and model._total_timesteps == 60 and isinstance(model._total_timesteps, int)


LOAD_OVERRIDES = [
    ("kwargs", {"gamma": 1.5}, "gamma=1.5 is out of range"),
    ("kwargs", {"n_epochs": 0}, "n_epochs=0 is out of range"),
    ("kwargs", {"normalize_advantage": "no"}, "normalize_advantage must be True or False"),
    ("custom_objects", {"learning_rate": -1.0}, "learning_rate=-1.0 is out of range"),
    ("custom_objects", {"clip_range_vf": -0.3}, "clip_range_vf=-0.3 is out of range"),
]


@pytest.mark.parametrize("how, overrides, message", LOAD_OVERRIDES, ids=[m for _, _, m in LOAD_OVERRIDES])
def test_load_overrides_are_range_checked(env, tiny_kwargs, tmp_path, how, overrides, message):
    path = tmp_path / "model.zip"
    SAEIR_PPO("MSHGPolicy", env, **tiny_kwargs).save(path)
    with pytest.raises(ValueError) as error:
        if how == "kwargs":
            SAEIR_PPO.load(path, env=env, **overrides)
        else:
            SAEIR_PPO.load(path, env=env, custom_objects=overrides)
    one_line(error, message)


def test_load_for_inference_with_learning_rate_zero(env, tiny_kwargs, tmp_path):
    """rl-zoo3's enjoy loads with custom_objects={"learning_rate": 0.0, ...} (no training): that stays allowed."""
    path = tmp_path / "model.zip"
    SAEIR_PPO("MSHGPolicy", env, **tiny_kwargs).save(path)
    custom_objects = {"learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0}
    assert SAEIR_PPO.load(path, env=env, custom_objects=custom_objects).learning_rate == 0.0
    with pytest.raises(ValueError, match=r"learning_rate=0\.0 is out of range"):
        SAEIR_PPO.load(path, env=env, learning_rate=0.0)  # a training override keeps the constructor's check


@pytest.mark.parametrize("space", [spaces.Discrete(5, start=1), spaces.MultiDiscrete([3, 3], start=[0, -1])])
def test_action_space_with_nonzero_start_refused(env, tiny_kwargs, space):
    env.action_space = space
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", env, **tiny_kwargs)
    one_line(error, "start", "actions")


# ------------------------------------------------------------------------------------------------ late errors made early
LATE = [
    ({"intrinsic_kwargs": {"variant": "papper"}}, "Unknown SAEIR variant 'papper'"),
    ({"intrinsic_kwargs": {"varaint": "paper"}}, "unknown intrinsic_kwargs key 'varaint'"),
    ({"intrinsic_reward": "rnd", "intrinsic_kwargs": {"input": "pixels"}}, "Unknown RND input 'pixels'"),
    ({"intrinsic_reward": "elign", "intrinsic_kwargs": {"coef": 2.0}}, "unknown intrinsic_kwargs key 'coef'"),
]


@pytest.mark.parametrize("kwargs, message", LATE, ids=[m for _, m in LATE])
def test_intrinsic_reward_checked_at_construction(env, tiny_kwargs, kwargs, message):
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", env, **{**tiny_kwargs, **kwargs})
    one_line(error, message)


def test_tensorboard_log_that_is_a_file(env, tiny_kwargs, tmp_path):
    log_file = tmp_path / "tb"
    log_file.write_text("not a folder")
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", env, tensorboard_log=str(log_file), **tiny_kwargs)
    one_line(error, "tensorboard_log", "is an existing file")
    assert log_file.read_text() == "not a folder" and sorted(tmp_path.iterdir()) == [log_file]


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"tensorboard_log": 3}, ["tensorboard_log=3 is not a folder path", "or None"]),
        ({"verbose": "1"}, ["verbose='1' is not a verbosity level", "pass 0 (silent), 1 (info) or 2 (debug)"]),
        ({"verbose": -1}, ["verbose=-1 is not a verbosity level"]),
    ],
    ids=["tensorboard_log-int", "verbose-str", "verbose-negative"],
)
def test_tensorboard_log_and_verbose_of_the_wrong_type(env, tiny_kwargs, tmp_path, kwargs, words):
    """Each ended in a TypeError naming no argument (``expected str, bytes or os.PathLike object``, ``'>=' not
    supported``), the first at construction, the second at ``learn``; at ``load`` too they are refused."""
    with pytest.raises(ValueError) as error:
        MAPPO("MAPPOPolicy", env, **{**tiny_kwargs, **kwargs})
    one_line(error, "MAPPO: ", *words)
    path = tmp_path / "model.zip"
    MAPPO("MAPPOPolicy", env, **tiny_kwargs).save(path)
    with pytest.raises(ValueError) as error:
        MAPPO.load(path, env=env, **kwargs)
    one_line(error, "MAPPO: ", *words)
    assert MAPPO("MAPPOPolicy", env, **{**tiny_kwargs, "verbose": True}).verbose is True  # as 1 in SB3


# ------------------------------------------------------------------------------------------------ raw library errors
BAD_PREDICT = [
    ({"observation": np.zeros((6, 5))}, "observation of shape (6, 5)"),
    ({"observation": np.zeros(7)}, "observation of shape (7,)"),
    ({"observation": [[0.0] * 18, [0.0]]}, "observation must be an array"),
    ({"observation": np.full((6, 18), np.nan)}, "observation holds NaN"),
    ({"observation": np.full(18, np.inf)}, "observation holds NaN"),
    ({"observation": np.zeros((6, 18)), "state": np.zeros((6, 5))}, "state of shape (6, 5)"),
    ({"observation": np.zeros((6, 18)), "state": np.zeros((4, 8))}, "state of shape (4, 8)"),
    ({"observation": np.zeros((6, 18)), "episode_start": np.zeros(4)}, "episode_start of shape (4,)"),
    # NumPy cast these to float32: numeric strings without a word, complex numbers with its ComplexWarning only
    ({"observation": np.full((6, 18), "0.5")}, "the observation must be an array of numbers, got dtype <U3"),
    ({"observation": np.zeros((6, 18), np.complex64)}, "the observation must be an array of numbers, got dtype complex64"),
]


@pytest.mark.parametrize("kwargs, message", BAD_PREDICT, ids=[m for _, m in BAD_PREDICT])
def test_predict_bad_arrays(model, kwargs, message):
    assert model.observation_space.shape == (18,)
    with pytest.raises(ValueError) as error:
        model.predict(**kwargs)
    one_line(error, "predict", message)


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _edit_data(path):
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    members["data"] = members["data"][:-40]
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)


def _drop_policy(path):
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist() if name != "policy.pth"}
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)


def _garble_policy(path):
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    members["policy.pth"] = members["policy.pth"][: len(members["policy.pth"]) // 2]
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)


@pytest.mark.parametrize("damage", [_truncate, _edit_data, _drop_policy, _garble_policy])
def test_load_damaged_zip(env, tiny_kwargs, tmp_path, damage):
    path = tmp_path / "model.zip"
    SAEIR_PPO("MSHGPolicy", env, **tiny_kwargs).save(path)
    damage(path)
    with pytest.raises(ValueError) as error:
        SAEIR_PPO.load(path, env=env)
    one_line(error, str(path), "not a complete sb3-saeir model")


@pytest.mark.parametrize("device", ["gpu2", "cuda:x", "tpu"])
def test_unknown_device(env, tiny_kwargs, device):
    with pytest.raises(ValueError) as error:
        SAEIR_PPO("MSHGPolicy", env, device=device, **tiny_kwargs)
    one_line(error, f"device={device!r}")


def test_cuda_without_cuda_warns(env, tiny_kwargs, monkeypatch):
    import torch

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        SAEIR_PPO("MSHGPolicy", env, device="cuda", **tiny_kwargs)
    messages = [str(w.message) for w in caught if "CUDA is not available" in str(w.message)]
    assert len(messages) == 1 and "\n" not in messages[0] and "device='cuda'" in messages[0]


# ------------------------------------------------------------------------------------------------ issue 35
BAD_HIDDEN_SIZES = [0, -4, 2.5, "8", None, True]


@pytest.mark.parametrize("policy", ["MSHGPolicy", "MAPPOPolicy"])
@pytest.mark.parametrize("hidden_size", BAD_HIDDEN_SIZES, ids=[repr(value) for value in BAD_HIDDEN_SIZES])
def test_bad_hidden_size(env, policy, hidden_size):
    """Torch's own messages (``input_size must be greater than zero``, a tensor size) named no argument."""
    with pytest.raises(ValueError) as error:
        MAPPO(policy, env, n_steps=10, policy_kwargs={"hidden_size": hidden_size})
    one_line(error, f"{policy}: hidden_size must be a positive integer", f"got {hidden_size!r}")


def test_numpy_integer_hidden_size_is_accepted(env):
    model = MAPPO("MAPPOPolicy", env, n_steps=10, policy_kwargs={"hidden_size": np.int64(8)})
    assert model.policy.hidden_size == 8 and type(model.policy.hidden_size) is int


BAD_SEEDS = ["abc", 2.5, -1, 2**32, True]


@pytest.mark.parametrize("where", ["constructor", "set_random_seed", "load"])
@pytest.mark.parametrize("seed", BAD_SEEDS, ids=[repr(seed) for seed in BAD_SEEDS])
def test_bad_seed(env, tiny_kwargs, tmp_path, where, seed):
    """NumPy's and Python's messages (a dtype cast, ``Seed must be between 0 and 2**32 - 1``) did not name ``seed``;
    ``True`` was taken as 1."""
    model = None if where == "constructor" else MAPPO("MAPPOPolicy", env, **tiny_kwargs)
    if where == "load":
        model.save(tmp_path / "model.zip")
    with pytest.raises(ValueError) as error:
        if where == "constructor":
            MAPPO("MAPPOPolicy", env, seed=seed, **tiny_kwargs)
        elif where == "set_random_seed":
            model.set_random_seed(seed)
        else:
            MAPPO.load(tmp_path / "model.zip", env=env, seed=seed)
    one_line(error, f"MAPPO: seed={seed!r} is not a seed")


@pytest.mark.parametrize("seed", [np.int64(3), np.int32(3), np.uint32(3)], ids=["int64", "int32", "uint32"])
def test_numpy_integer_seed_is_accepted(tiny_kwargs, tmp_path, seed):
    """Python's ``random.seed`` refused NumPy integers (``The only supported seed types are...``)."""

    def first_actions(model):
        model.env.seed(0)
        return model.predict(model.env.reset(), deterministic=False)[0]

    runs = []
    for value in (3, seed):
        env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
        runs.append(first_actions(MAPPO("MAPPOPolicy", env, seed=value, **tiny_kwargs)))
    np.testing.assert_array_equal(runs[1], runs[0])
    model = MAPPO("MAPPOPolicy", make_multiagent_vec_env("cn-sparse-n3", n_games=2), **tiny_kwargs)
    model.set_random_seed(seed)
    model.save(tmp_path / "model.zip")
    assert MAPPO.load(tmp_path / "model.zip", env=model.env, seed=seed).seed == 3


BAD_DETERMINISTIC = ["no", "False", 1, None]


@pytest.mark.parametrize("caller", ["model", "policy"])
@pytest.mark.parametrize("deterministic", BAD_DETERMINISTIC, ids=[repr(value) for value in BAD_DETERMINISTIC])
def test_predict_deterministic_must_be_a_bool(model, caller, deterministic):
    """``"no"`` is truthy: it was accepted and acted greedily."""
    predictor = model if caller == "model" else model.policy
    with pytest.raises(ValueError) as error:
        predictor.predict(np.zeros((6, 18)), deterministic=deterministic)
    one_line(error, "predict: deterministic must be True or False")


LOAD_SKIPPED_CHECKS = [
    ({"batch_size": 7}, "batch_size=7 cannot be formed from whole"),
    ({"batch_size": 2.5}, "batch_size=2.5 cannot be formed from whole"),
    ({"n_minibatches": 99}, "n_minibatches=99 must be between 1 and"),
    ({"n_steps": 7, "batch_size": 60}, "batch_size=60 cannot be formed from whole"),
    ({"value_loss": "l1"}, "value_loss must be 'huber' or 'mse'"),
    ({"double_buffered": "yes"}, "double_buffered must be True, False or 'auto'"),
    ({"intrinsic_reward": "curiosity"}, "Unknown intrinsic_reward 'curiosity'"),
    ({"intrinsic_kwargs": {"varaint": "paper"}}, "unknown intrinsic_kwargs key 'varaint'"),
]


@pytest.mark.parametrize("overrides, message", LOAD_SKIPPED_CHECKS, ids=[m[:40] for _, m in LOAD_SKIPPED_CHECKS])
def test_load_overrides_get_the_constructor_checks(env, tiny_kwargs, tmp_path, overrides, message):
    """These overrides were set on the loaded model without a check (``batch_size`` was even ignored)."""
    path = tmp_path / "model.zip"
    SAEIR_PPO("MSHGPolicy", env, **tiny_kwargs).save(path)
    before = path.read_bytes()
    with pytest.raises(ValueError) as error:
        SAEIR_PPO.load(path, env=env, **overrides)
    one_line(error, message)
    assert path.read_bytes() == before


def test_load_batch_size_override_is_applied(env, tiny_kwargs, tmp_path):
    """A positive control: a valid batch_size override now sets the minibatch count (before: ignored)."""
    path = tmp_path / "model.zip"
    SAEIR_PPO("MSHGPolicy", env, **tiny_kwargs).save(path)
    assert SAEIR_PPO.load(path, env=env, batch_size=30).n_minibatches == 2


def _unwritable_paths(tmp_path):
    (tmp_path / "a_file").write_text("not a folder")
    return {
        "/proc": ("/proc/model.zip", "no file can be created in /proc"),
        "/proc/sub": ("/proc/sub/model.zip", "no file can be created in /proc"),
        "under a file": (str(tmp_path / "a_file" / "model.zip"), "a_file is a file, not a folder"),
        "empty": ("", "'' is not a file name"),
    }


@pytest.mark.parametrize("case", ["/proc", "/proc/sub", "under a file", "empty"])
def test_save_to_a_path_that_cannot_be_written(model, tmp_path, case):
    """``/proc/model.zip`` ended in a RecursionError in SB3's ``open_path``; the others in the OS's message."""
    path, message = _unwritable_paths(tmp_path)[case]
    before = {p.name: p.is_dir() or p.read_text() for p in tmp_path.iterdir()}
    with pytest.raises(ValueError) as error:
        model.save(path)
    one_line(error, "SAEIR_PPO.save", message)
    assert {p.name: p.is_dir() or p.read_text() for p in tmp_path.iterdir()} == before


@pytest.mark.parametrize("scales", [None, ("team", "group")], ids=["default", "explicit"])
def test_one_agent_warns_that_the_group_scale_is_degenerate(tiny_kwargs, scales):
    one = make_multiagent_vec_env("cn-sparse-n3", n_games=2, N=1, seed=0)
    policy_kwargs = {"hidden_size": 8, **({} if scales is None else {"scales": scales})}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        SAEIR_PPO("MSHGPolicy", one, **{**tiny_kwargs, "policy_kwargs": policy_kwargs})
    ours = [str(w.message) for w in caught if "group scale" in str(w.message)]
    assert len(ours) == 1 and "\n" not in ours[0] and "degenerate with 1 agent per game" in ours[0], ours
    assert "scales=('team',)" in ours[0]
    one.close()


# ------------------------------------------------------------------------------------------------ round 6 (issue 67)
@pytest.mark.parametrize(
    "learn_kwargs, words",
    [
        ({"reset_num_timesteps": "no"}, ("MAPPO.learn", "reset_num_timesteps", "'no'")),
        ({"progress_bar": "yes"}, ("MAPPO.learn", "progress_bar", "'yes'")),
        ({"tb_log_name": None}, ("MAPPO.learn: tb_log_name=None must be a folder name",)),
        ({"tb_log_name": "../../escape"}, ("MAPPO.learn: tb_log_name='../../escape' must be a folder name", "no path")),
    ],
)
def test_learn_options_that_sb3_misreads_are_refused(env, tiny_kwargs, learn_kwargs, words):
    """``"no"`` was read as True; ``None`` failed in ``os.path``; a path wrote outside ``tensorboard_log``."""
    model = MAPPO("MAPPOPolicy", env, **tiny_kwargs)
    model.learn(60)
    with pytest.raises(ValueError) as error:
        model.learn(60, **learn_kwargs)
    one_line(error, *words)
    assert model.num_timesteps == 60


def test_learn_of_a_model_loaded_without_env_names_the_fix(env, tiny_kwargs, tmp_path):
    MAPPO("MAPPOPolicy", env, **tiny_kwargs).save(tmp_path / "model.zip")
    with pytest.raises(ValueError) as error:
        MAPPO.load(tmp_path / "model.zip").learn(60)  # SB3: an AssertionError without a message
    one_line(error, "MAPPO.learn: the model has no env", "pass env= to load, or call model.set_env(env)")


@pytest.mark.parametrize(
    "call, error_type, words",
    [
        (lambda model, path: model.save(123), TypeError, ("MAPPO.save: path=123; pass a file path",)),
        (lambda model, path: MAPPO.load(path, custom_objects=[("gamma", 0.9)]), TypeError, ("custom_objects=", "a dict")),
        (lambda model, path: model.set_env(None), ValueError, ("MAPPO.set_env: env=None",)),
        (lambda model, path: model.set_env(ToyMeetEnv()), ValueError, ("MAPPO.set_env needs a multi-agent vec env",)),
        (lambda model, path: model.set_parameters(path.parent / "none.zip"), FileNotFoundError,
         ("MAPPO.set_parameters: no such file", "none.zip'")),
        (lambda model, path: model.set_parameters(path, exact_match="no"), ValueError, ("exact_match", "'no'")),
    ],
)  # fmt: skip
def test_model_method_arguments_are_refused_in_one_line(env, tiny_kwargs, tmp_path, call, error_type, words):
    """Raw errors before: SB3's type list, ``'list' object is not a mapping``, gym's patch message, ``none.zip.zip``;
    ``exact_match="no"`` was read as True."""
    model = MAPPO("MAPPOPolicy", env, **tiny_kwargs)
    path = tmp_path / "model.zip"
    model.save(path)
    with pytest.raises(error_type) as error:
        call(model, path)
    one_line(error, *words)


def test_policy_kwargs_and_an_unused_intrinsic_coef_are_refused(env, tiny_kwargs):
    with pytest.raises(TypeError) as error:
        MAPPO("MAPPOPolicy", env, **{**tiny_kwargs, "policy_kwargs": [("hidden_size", 8)]})  # 'list' is not a mapping
    one_line(error, "MAPPO: policy_kwargs must be a dict")
    with pytest.raises(ValueError) as error:
        MAPPO("MAPPOPolicy", env, intrinsic_coef=0.5, **tiny_kwargs)  # was accepted, and ignored
    one_line(error, "intrinsic_coef=0.5 given with intrinsic_reward=None would be ignored")


@pytest.mark.parametrize(
    "call, error_type, words",
    [
        (lambda register: register(None, "my_package:Game"), TypeError, ("task_id=None must be a non-empty string",)),
        (lambda register: register("t", ToyMeetEnv), ValueError, ("entry_point=", "'module:callable'")),
        (lambda register: register("t", "my_package.Game"), ValueError, ("entry_point='my_package.Game'",)),
        (lambda register: register("t", "m:G", main_metric=5), TypeError, ("main_metric=5",)),
        (lambda register: register("t", "m:G", kwargs=[("n", 2)]), TypeError, ("kwargs must be a dict",)),
    ],
)
def test_register_task_refuses_what_would_break_later(call, error_type, words):
    """``None`` broke ``list_tasks()`` and every later unknown-task message; the others failed when the task was made."""
    from sb3_saeir.common import registry

    before = registry.list_tasks()
    with pytest.raises(error_type) as error:
        call(registry.register_task)
    one_line(error, *words)
    assert registry.list_tasks() == before


def test_an_entry_point_that_does_not_import_is_named():
    from sb3_saeir.common.registry import load_entry_point

    with pytest.raises(ModuleNotFoundError) as error:
        load_entry_point("no_such_module_here:Game")
    one_line(error, "entry point 'no_such_module_here:Game': no module 'no_such_module_here'")
    with pytest.raises(AttributeError) as error:
        load_entry_point("sb3_saeir.envs:NoSuchGame")
    one_line(error, "module 'sb3_saeir.envs' has no 'NoSuchGame'")


def test_callback_helpers_check_their_arguments(env, tiny_kwargs):
    from stable_baselines3.common.callbacks import CheckpointCallback

    from sb3_saeir.common.callbacks import BudgetEstimate, EveryAgentSteps

    with pytest.raises(TypeError) as error:
        EveryAgentSteps(None, 10)  # failed at learn: 'NoneType' object has no attribute 'init_callback'
    one_line(error, "EveryAgentSteps: callback=None must be an SB3 BaseCallback")
    with pytest.raises(ValueError) as error:
        BudgetEstimate("x")  # failed after the first rollout: Cannot specify ',' with 's'
    one_line(error, "BudgetEstimate: total_timesteps='x'")
    every = EveryAgentSteps(CheckpointCallback(1, "unused"), np.int64(10))  # NumPy ints, as elsewhere
    assert every.frequency == 10 and type(every.frequency) is int
