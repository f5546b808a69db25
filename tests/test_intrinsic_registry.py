"""The bonus-name registry: a bonus defined outside the package registers itself and is used by name."""

import numpy as np
import pytest
from stable_baselines3.common.callbacks import BaseCallback

from sb3_saeir import MAPPO, SAEIR_PPO
from sb3_saeir.common.registry import INTRINSIC_REWARDS
from sb3_saeir.intrinsic import (
    ElignCallback,
    IntrinsicRewardCallback,
    RNDCallback,
    SAEIRCallback,
    register_intrinsic_reward,
)


@pytest.fixture
def my_bonus():
    """A constant bonus registered as ``"my_bonus"`` in the test, removed from the registry afterwards."""

    @register_intrinsic_reward("my_bonus")
    class ConstantBonus(IntrinsicRewardCallback):
        def __init__(self, coef: float = 0.5, level: float = 1.0, verbose: int = 0) -> None:
            super().__init__(coef=coef, name="my_bonus", verbose=verbose)
            self.level = level

        def compute_bonus(self, buffer):
            return np.full((buffer.buffer_size, buffer.n_envs), self.level)  # (n_steps, n_envs), every scale

    yield ConstantBonus
    del INTRINSIC_REWARDS["my_bonus"]


def test_the_package_bonuses_register_themselves():
    assert INTRINSIC_REWARDS == {"saeir": SAEIRCallback, "rnd": RNDCallback, "elign": ElignCallback}


def test_a_registered_bonus_is_used_by_name(env, tiny_kwargs, my_bonus):
    model = MAPPO("MAPPOPolicy", env, intrinsic_reward="my_bonus", intrinsic_coef=0.25, **tiny_kwargs)
    model.learn(10 * env.num_envs)
    [bonus] = model._intrinsic_rewards
    assert type(bonus) is my_bonus and bonus.coef == 0.25
    np.testing.assert_array_equal(model.rollout_buffer.intrinsic_rewards, 0.25)  # coef * 1.0 at every step and scale


def test_a_registered_bonus_has_its_keywords_checked(env, tiny_kwargs, my_bonus):
    SAEIR_PPO("MSHGPolicy", env, intrinsic_reward="my_bonus", intrinsic_kwargs={"level": 2.0}, **tiny_kwargs)
    with pytest.raises(ValueError, match="unknown intrinsic_kwargs key 'levle' for intrinsic_reward='my_bonus'"):
        SAEIR_PPO("MSHGPolicy", env, intrinsic_reward="my_bonus", intrinsic_kwargs={"levle": 2.0}, **tiny_kwargs)


def test_unregistered_names_and_classes_are_refused(env, tiny_kwargs):
    with pytest.raises(ValueError, match=r"Unknown intrinsic_reward 'my_bonus'; choose one of \['elign', 'rnd', 'saeir'"):
        MAPPO("MAPPOPolicy", env, intrinsic_reward="my_bonus", **tiny_kwargs)
    with pytest.raises(TypeError, match=r"not a subclass of sb3_saeir\.intrinsic\.IntrinsicRewardCallback"):
        register_intrinsic_reward("plain")(BaseCallback)
    with pytest.raises(ValueError, match="non-empty string"):
        register_intrinsic_reward("")
    assert "plain" not in INTRINSIC_REWARDS
