"""A warning about what the user passed names the user's line (the call into the package), as SB3's do, whatever
the depth of the package's calls behind it (``SAEIR_PPO`` runs one level deeper than ``MAPPO``)."""

from __future__ import annotations

import warnings
from collections.abc import Callable

import pytest

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from tests.toy_envs import ToyMeetEnv


def _the_warning(call: Callable[[], object], match: str) -> warnings.WarningMessage:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    found = [warning for warning in caught if match in str(warning.message)]
    assert found, f"no warning with {match!r}: {[str(warning.message) for warning in caught]}"
    return found[0]


@pytest.fixture
def two_agent_env():
    env = make_multiagent_vec_env(ToyMeetEnv, n_games=2, n_agents=2, seed=0)
    yield env
    env.close()


@pytest.mark.parametrize("algo", [MAPPO, SAEIR_PPO])
def test_a_chunk_longer_than_the_rollout(env, algo):
    warning = _the_warning(lambda: algo("MSHGPolicy", env, n_steps=4, data_chunk_length=8), "data_chunk_length=8")
    assert warning.filename == __file__


@pytest.mark.parametrize("algo", [MAPPO, SAEIR_PPO])
def test_the_group_scale_left_out(two_agent_env, algo):
    warning = _the_warning(lambda: algo("MSHGPolicy", two_agent_env, n_steps=4), "the group scale is left out")
    assert warning.filename == __file__


@pytest.mark.parametrize("algo", [MAPPO, SAEIR_PPO])
def test_cuda_without_a_gpu(env, algo, monkeypatch):
    import torch as th

    monkeypatch.setattr(th.cuda, "is_available", lambda: False)
    warning = _the_warning(lambda: algo("MAPPOPolicy", env, n_steps=4, device="cuda"), "CUDA is not available")
    assert warning.filename == __file__


def test_save_into_a_missing_folder(env, tmp_path):
    model = MAPPO("MAPPOPolicy", env, n_steps=4)
    warning = _the_warning(lambda: model.save(tmp_path / "new" / "model"), "does not exist. Will create it")
    assert warning.filename == __file__
