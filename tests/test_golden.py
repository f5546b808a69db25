"""Golden tests: seeded two-iteration runs of every machinery path, against arrays saved by an earlier version.

A change of what the algorithms compute (rollout, intrinsic rewards, GAE, the update) moves the buffer's advantages and
returns or the parameters after two updates beyond the stated tolerance and fails here; reordering float sums does not,
so the code sums its terms the plain way. ``tests/data/golden_*`` (arrays and model zips) were written by
``python -m tests.test_golden --write`` on version 0.1.0a0 (commit 54974f9), ``golden_saeir_ppo_no_group.npz`` on
0.2.0a0 (the commit after d2d8a4f). Do not regenerate them to make a test pass: a difference is a behaviour change to explain.
"""

from __future__ import annotations

import pathlib
import sys
from typing import Any

import numpy as np
import pytest
import torch as th

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.intrinsic import ElignCallback, RNDCallback
from tests.run_folders import SAVED_ARRAYS_ATOL, SAVED_ARRAYS_RTOL

DATA = pathlib.Path(__file__).parent / "data"
N_GAMES = 2
N_STEPS = 25  # the paper's rollout length (a padded last chunk of 5 steps with data_chunk_length 10)
ITERATIONS = 2
SEED = 3
TINY_POLICY = {"hidden_size": 16}
# SAEIR_PPO's group critic rebuilds its hyperedges by a top-k of cosine similarities at every step, so a last-bit change
# of a parameter can swap two nearly tied agents of an edge and move the second iteration's arrays by orders more
# than the change itself. Since 0.2.0a0 the update skips the padded rows of the last chunk and sums the rest in
# another order: its gradients stay within 5e-7 of the padded update (tests/test_update_equivalence.py), and the
# two-iteration arrays here move by up to 1.1e-4 (relative 5e-4). The tolerance for it is 1e-3: a change of what is
# computed (a formula, a missing term, another noise draw) moves them by far more.
METHOD_TOLERANCES = {"saeir_ppo": (1e-3, 1e-3), "saeir_ppo_no_group": (1e-5, 1e-5)}
# The same near-ties make the group critic's part depend on the CPU's rounding: on one machine of this workplace (an
# Intel Xeon whose kernels round differently from the machine the data was written on), three of the 450 group-scale
# values/advantages moved by up to 1.1e-2 and the group critic's parameter checksums by up to 5e-3, with the same
# code that matched within 1.1e-4 elsewhere; the team and individual scales and the actor stayed within 1e-4. So
# SAEIR_PPO's group critic (its parameters and scale 1 of the per-scale arrays) is compared at 2e-2: another noise
# draw or a wrong formula moves every part by far more, and the other parts keep 1e-3.
GROUP_CRITIC_TOLERANCE = (2e-2, 2e-2)
GROUP_SCALE = 1  # ("team", "group", "individual")
PER_SCALE_ARRAYS = ("values", "advantages", "returns")
# At 2e-2 most of the group critic's checksums would also match its untrained parameters (two updates move them by
# less), so its update is checked as a whole as well: the vector of its checksums' changes from the initial parameters
# (norm 0.52) points where the stored one does (cosine above 0.95) and is as long (within 10%). The CPU's rounding
# moves it by at most 5e-3 per checksum, 0.07 in norm over its 162 numbers: cosine at least 0.99.
GROUP_UPDATE_MIN_COSINE = 0.95
GROUP_UPDATE_NORM_RATIO = (0.9, 1.1)
# Those tolerances let through a change of SAEIR's own maths that moves the arrays by less than 1e-3 (the bonus's value
# where it fires, a scaled term of its log-sum-exp, the W_K weights' temperature: measured 1e-4 to 1e-3).
# "saeir_ppo_no_group" runs SAEIR_PPO with the team and individual critics and without Gumbel noise: no top-k, no
# near-ties. One torch thread against two moves its arrays by up to 2.6e-6 (MAPPO's by 9.5e-7; with the noise, whose
# sharp softmax over the individual scale's N edge types amplifies, by 1.2e-5), so it is compared at 1e-5 (relative
# 1e-5), where those changes of SAEIR's maths fail by a factor of 30 or more.


def assert_matches_golden(method: str, arrays: dict[str, np.ndarray], expected: Any) -> None:
    """Compare a golden run's arrays with the stored ones at the method's tolerance (and SAEIR_PPO's group critic at
    :data:`GROUP_CRITIC_TOLERANCE`)."""
    atol, rtol = METHOD_TOLERANCES.get(method, (SAVED_ARRAYS_ATOL, SAVED_ARRAYS_RTOL))
    for key in expected.files:
        got, stored = arrays[key], expected[key]
        if method != "saeir_ppo":
            np.testing.assert_allclose(got, stored, atol=atol, rtol=rtol, err_msg=f"{method}: {key}")
        elif "critics.group." in key:
            np.testing.assert_allclose(got, stored, *GROUP_CRITIC_TOLERANCE, err_msg=f"{method}: {key}")
        elif key in PER_SCALE_ARRAYS:
            other = [k for k in range(got.shape[-1]) if k != GROUP_SCALE]
            np.testing.assert_allclose(got[..., other], stored[..., other], atol=atol, rtol=rtol, err_msg=f"{method}: {key}")
            np.testing.assert_allclose(
                got[..., GROUP_SCALE], stored[..., GROUP_SCALE], *GROUP_CRITIC_TOLERANCE, err_msg=f"{method}: {key}"
            )
        else:
            np.testing.assert_allclose(got, stored, atol=atol, rtol=rtol, err_msg=f"{method}: {key}")


def assert_group_critic_update_matches(arrays: dict[str, np.ndarray], expected: Any, initial: dict[str, np.ndarray]) -> None:
    """SAEIR_PPO's group critic moved from its initial parameters as the stored run's did (see
    :data:`GROUP_UPDATE_MIN_COSINE`)."""
    keys = [key for key in expected.files if "critics.group." in key]
    got = np.concatenate([arrays[key] - initial[key] for key in keys])
    stored = np.concatenate([expected[key] - initial[key] for key in keys])
    cosine = got @ stored / (np.linalg.norm(got) * np.linalg.norm(stored))
    ratio = np.linalg.norm(got) / np.linalg.norm(stored)
    assert cosine > GROUP_UPDATE_MIN_COSINE, f"the group critic's update points elsewhere (cosine {cosine:.4f})"
    low, high = GROUP_UPDATE_NORM_RATIO
    assert low < ratio < high, f"the group critic's update is {ratio:.3f} times the stored one"


METHODS: dict[str, dict[str, Any]] = {
    "saeir_ppo": {"algo": SAEIR_PPO, "policy": "MSHGPolicy", "kwargs": {}, "callback": None},
    "saeir_ppo_no_group": {
        "algo": SAEIR_PPO,
        "policy": "MSHGPolicy",
        "kwargs": {},
        "policy_kwargs": {"scales": ("team", "individual"), "critic_gumbel_noise": False},
        "callback": None,
    },
    "mappo": {"algo": MAPPO, "policy": "MAPPOPolicy", "kwargs": {}, "callback": None},
    "rnd": {"algo": MAPPO, "policy": "MAPPOPolicy", "kwargs": {}, "callback": RNDCallback},
    "elign": {"algo": MAPPO, "policy": "MAPPOPolicy", "kwargs": {}, "callback": ElignCallback},
}


def golden_env() -> Any:
    """The navigation task the golden arrays were produced on (mpe2's world, then through SuperSuit, 2 games).

    The native engine's ``world="mpe2"`` gives mpe2's streams bit for bit (tests/test_navigation_engine.py).
    """
    return make_multiagent_vec_env("cn-sparse-n3", n_games=N_GAMES, seed=SEED, world="mpe2")


def parameter_checksums(model: Any) -> dict[str, np.ndarray]:
    """Per parameter tensor: sum, sum of squares and a dot product with fixed pseudo-random weights."""
    sums = {}
    for name, param in model.policy.state_dict().items():
        values = param.detach().cpu().double().numpy().reshape(-1)
        weights = np.random.default_rng(len(values)).normal(size=len(values))
        sums[name] = np.array([values.sum(), (values**2).sum(), values @ weights])
    return sums


def golden_model(method: str) -> Any:
    """The untrained model of ``method`` that :func:`golden_run` trains, on :func:`golden_env`."""
    th.manual_seed(SEED)
    spec = METHODS[method]
    env = golden_env()
    policy_kwargs = {**TINY_POLICY, **spec.get("policy_kwargs", {})}
    return spec["algo"](spec["policy"], env, n_steps=N_STEPS, seed=SEED, policy_kwargs=policy_kwargs, **spec["kwargs"])


def golden_run(method: str) -> tuple[Any, dict[str, np.ndarray]]:
    """Train ``method`` for two iterations from a fixed seed; return the model and the arrays to compare."""
    spec = METHODS[method]
    model = golden_model(method)
    env = model.env
    callback = spec["callback"]() if spec["callback"] is not None else None
    model.learn(ITERATIONS * N_STEPS * env.num_envs, callback=callback)
    buffer = model.rollout_buffer
    arrays = {
        "advantages": np.array(buffer.advantages),
        "returns": np.array(buffer.returns),
        "values": np.array(buffer.values),
        # (T, E) env rewards; since 0.2.0 the buffer holds them per critic scale, (T, E, K), equal across scales here
        "rewards": np.array(buffer.rewards if buffer.rewards.ndim == 2 else buffer.rewards[..., 0]),
    }
    arrays.update({f"param/{name}": value for name, value in parameter_checksums(model).items()})
    return model, arrays


def evaluation_observations() -> np.ndarray:
    """25 steps of observations from a fresh seeded env (random actions), ``(25, n_envs, obs_dim)``."""
    env = golden_env()
    rng = np.random.default_rng(SEED)
    observations = [env.reset()]
    for _ in range(N_STEPS - 1):
        obs, _, _, _ = env.step(rng.integers(0, 5, size=env.num_envs))
        observations.append(obs)
    env.close()
    return np.stack(observations)


def deterministic_actions(model: Any, observations: np.ndarray) -> np.ndarray:
    """Deterministic actions of ``model`` on a sequence of observations, GRU states carried through."""
    states, actions = None, []
    starts = np.ones(observations.shape[1], dtype=bool)
    for obs in observations:
        action, states = model.predict(obs, state=states, episode_start=starts, deterministic=True)
        starts = np.zeros_like(starts)
        actions.append(action)
    return np.stack(actions)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_two_iterations_match_golden_arrays(method):
    path = DATA / f"golden_{method}.npz"
    expected = np.load(path)
    model, arrays = golden_run(method)
    model.env.close()
    assert sorted(arrays) == sorted(expected.files), "the set of parameters changed (renamed or new tensors)"
    assert_matches_golden(method, arrays, expected)
    if method == "saeir_ppo":
        untrained = golden_model(method)
        untrained.env.close()
        initial = {f"param/{name}": value for name, value in parameter_checksums(untrained).items()}
        assert_group_critic_update_matches(arrays, expected, initial)


@pytest.mark.parametrize("method, algo", [("saeir_ppo", SAEIR_PPO), ("mappo", MAPPO)])
def test_old_model_zip_loads_with_identical_actions(method, algo):
    model = algo.load(DATA / f"golden_{method}.zip", device="cpu")
    expected = np.load(DATA / f"golden_{method}_actions.npz")
    actions = deterministic_actions(model, expected["observations"])
    np.testing.assert_array_equal(actions, expected["actions"])


def write_golden_data(methods: list[str]) -> None:
    """Write the golden arrays (and model zips) of ``methods`` (run once, on the version the data documents)."""
    th.set_num_threads(1)
    DATA.mkdir(exist_ok=True)
    observations = evaluation_observations()
    for method in methods:
        model, arrays = golden_run(method)
        np.savez_compressed(DATA / f"golden_{method}.npz", **arrays)
        if method in ("saeir_ppo", "mappo"):
            model.save(DATA / f"golden_{method}.zip")
            np.savez_compressed(
                DATA / f"golden_{method}_actions.npz",
                observations=observations,
                actions=deterministic_actions(model, observations),
            )
        model.env.close()
        print(f"wrote golden data for {method}")


if __name__ == "__main__":
    if "--write" not in sys.argv:
        sys.exit(
            "Usage: python -m tests.test_golden --write [METHOD ...]   (overwrites tests/data/golden_* of every method, "
            "or of the methods named; see the module docstring)"
        )
    names = [arg for arg in sys.argv[1:] if arg != "--write"]
    unknown = sorted(set(names) - set(METHODS))
    if unknown:
        sys.exit(f"Unknown methods {unknown}; choose from {sorted(METHODS)}.")
    write_golden_data(names or sorted(METHODS))
