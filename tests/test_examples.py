"""The examples stay runnable: the custom intrinsic reward of examples/ reaches training."""

import importlib.util
from pathlib import Path

import numpy as np

from sb3_saeir import MAPPO, make_multiagent_vec_env


def load_example(name):
    path = Path(__file__).parent.parent / "examples" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_custom_intrinsic_reward_example():
    example = load_example("custom_intrinsic_reward")
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    bonus = example.PositionCountBonus(coef=0.05)
    model = MAPPO("MAPPOPolicy", env, n_steps=10, n_epochs=1, seed=0).learn(10 * env.num_envs, callback=bonus)
    np.testing.assert_allclose(model.rollout_buffer.intrinsic_rewards[..., 0], 0.05 * bonus.last_bonus, atol=1e-7)
    assert (bonus.last_bonus > 0).all() and (bonus.last_bonus <= 1).all()
    env.close()
