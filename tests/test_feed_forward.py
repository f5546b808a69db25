"""The feed-forward networks (``policy_kwargs=dict(recurrent=False)``): no GRU in the actor or any critic, no state in
the rollout or the buffer, the update on the valid rows without chunks; saved and loaded like the recurrent ones, whose
saved-state keys do not change. The learning check is a slow test (tests/test_learning.py)."""

import numpy as np
import pytest
import torch as th

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.buffers import split_by_valid_length, valid_rows
from sb3_saeir.common.utils import NotABoolError
from sb3_saeir.config import load_hyperparams
from sb3_saeir.experiment import Experiment
from tests.test_save_load import deterministic_actions, observation_sequence

FEED_FORWARD = dict(hidden_size=8, recurrent=False)
METHODS = [(SAEIR_PPO, "MSHGPolicy"), (MAPPO, "MAPPOPolicy"), (MAPPO, "SNMAPPOPolicy")]


@pytest.mark.parametrize("algo, policy", METHODS)
def test_no_gru_no_state_and_the_update_shapes(algo, policy, env):
    model = algo(policy, env, n_steps=25, n_epochs=1, seed=0, policy_kwargs=dict(FEED_FORWARD))
    assert not [name for name in model.policy.state_dict() if ".gru." in name]
    assert model.policy.feed_forward and model.policy.actor_state_size == 0 and model.policy.critic_state_size == 0
    states = model.policy.initial_states(2)
    assert states.actor.shape == (6, 0) and states.critic.shape == (model.policy.n_scales, 2, 3, 0)
    model.learn(25 * env.num_envs)
    buffer = model.rollout_buffer
    assert buffer.actor_states.shape[-1] == 0 and buffer.critic_states.shape[-1] == 0
    samples = next(buffer.get(1))
    (group,) = [valid_rows(samples)]
    n_rows = int(samples.mask.sum())
    assert n_rows == 2 * 25  # every valid (step, game) row once, the padding of the last chunk left out
    assert group.samples.observations.shape == (1, n_rows, 3, 18)
    log_prob, entropy = model.policy.evaluate_actor(
        group.samples.observations, group.samples.actions, group.samples.actor_states, group.samples.episode_starts
    )
    assert log_prob.shape == entropy.shape == (1, n_rows, 3)
    part = group.samples
    values = model.policy.evaluate_critic(0, part.observations, part.critic_states[0], part.episode_starts)
    assert values.shape == (1, n_rows, 3)
    actions, state = model.predict(env.reset(), deterministic=True)
    assert actions.shape == (6,) and state is None


def test_valid_rows_are_the_padded_pass_rows(env):
    """Run on the valid rows at once, a feed-forward network gives the padded pass's outputs on those rows."""
    model = SAEIR_PPO("MSHGPolicy", env, n_steps=25, n_epochs=1, seed=0, policy_kwargs=dict(FEED_FORWARD))
    model.learn(25 * env.num_envs)
    samples = next(model.rollout_buffer.get(1))
    policy = model.policy
    th.manual_seed(5)
    values, log_prob, _ = policy.evaluate_actions(
        samples.observations, samples.actions, samples.actor_states, samples.critic_states, samples.episode_starts
    )
    group = valid_rows(samples)
    part = group.samples
    part_log_prob, _ = policy.evaluate_actor(part.observations, part.actions, part.actor_states, part.episode_starts)
    np.testing.assert_allclose(part_log_prob[0].detach(), log_prob[samples.mask].detach(), rtol=1e-5, atol=1e-6)
    th.manual_seed(5)
    for k in range(policy.n_scales):
        uniform = policy.draw_gumbel_uniform(k, *samples.mask.shape)
        part_uniform = None if uniform is None else group.take(uniform)
        part_values = policy.evaluate_critic(k, part.observations, part.critic_states[k], part.episode_starts, part_uniform)
        np.testing.assert_allclose(part_values[0].detach(), values[..., k][samples.mask].detach(), rtol=1e-5, atol=1e-6)


def test_recurrent_actor_with_feed_forward_critics(env):
    model = MAPPO("MAPPOPolicy", env, n_steps=25, n_epochs=1, seed=0, policy_kwargs=dict(FEED_FORWARD, recurrent_actor=True))
    assert not model.policy.feed_forward
    assert model.policy.actor_state_size == 8 and model.policy.critic_state_size == 0
    assert {name.split(".gru.")[0] for name in model.policy.state_dict() if ".gru." in name} == {"actor"}
    model.learn(25 * env.num_envs)
    assert model.rollout_buffer.actor_states.shape[-1] == 8 and model.rollout_buffer.critic_states.shape[-1] == 0
    assert [group.length for group in split_by_valid_length(next(model.rollout_buffer.get(1)))] == [10, 5]


@pytest.mark.parametrize("algo, policy", METHODS)
def test_save_load_predict(algo, policy, env, tmp_path):
    model = algo(policy, env, n_steps=10, n_epochs=1, seed=0, policy_kwargs=dict(FEED_FORWARD)).learn(2 * 10 * env.num_envs)
    observations = observation_sequence(env)
    expected = deterministic_actions(model, observations)
    model.save(tmp_path / "model.zip")
    loaded = algo.load(tmp_path / "model.zip", env=env, device="cpu")
    assert loaded.policy.recurrent is False and loaded.policy.feed_forward
    assert loaded.policy.state_dict().keys() == model.policy.state_dict().keys()
    for name, tensor in model.policy.state_dict().items():
        assert th.equal(tensor, loaded.policy.state_dict()[name]), name
    np.testing.assert_array_equal(deterministic_actions(loaded, observations), expected)
    loaded.learn(10 * env.num_envs, reset_num_timesteps=False)  # and trains on


@pytest.mark.parametrize("algo, policy", [(SAEIR_PPO, "MSHGPolicy"), (MAPPO, "MAPPOPolicy")])
def test_recurrent_models_keep_their_saved_state_keys(algo, policy, env, tmp_path):
    """Today's recurrent models: the same state-dict keys as before the option (the golden zips, saved by 0.1.0a0,
    load and are recurrent), and a recurrent model round-trips as recurrent."""
    from tests.test_golden import DATA

    golden = algo.load(DATA / f"golden_{algo.__name__.lower()}.zip", device="cpu")
    fresh = algo(policy, env, seed=0, policy_kwargs=dict(hidden_size=16))
    assert golden.policy.recurrent and golden.policy.recurrent_actor
    assert list(golden.policy.state_dict()) == list(fresh.policy.state_dict())
    fresh.save(tmp_path / "model.zip")
    loaded = algo.load(tmp_path / "model.zip", device="cpu")
    assert loaded.policy.recurrent and list(loaded.policy.state_dict()) == list(fresh.policy.state_dict())


def test_bad_value_is_one_line(env):
    with pytest.raises(NotABoolError, match=r"recurrent must be True or False, got 'no'"):
        MAPPO("MAPPOPolicy", env, policy_kwargs=dict(recurrent="no"))


def test_config_and_params_spelling():
    """From a config or ``-params policy_kwargs:"dict(recurrent=False)"``: the config's policy_kwargs string."""
    config = load_hyperparams("mappo", "cn-sparse-n3")
    config["policy_kwargs"] = config["policy_kwargs"].replace(")", ", recurrent=False)")
    experiment = Experiment("mappo", "cn-sparse-n3", config, n_games=2)
    model, env = experiment.build(), experiment.env
    assert model.policy.feed_forward and not [name for name in model.policy.state_dict() if ".gru." in name]
    env.close()


def test_feed_forward_smoke_training_on_navigation():
    """A fast check in the default run that the feed-forward MAPPO trains on cn-sparse-n3 (the packaged config, 16
    games, 4 iterations): finite losses, the policy sharpens (entropy falls) and the critic's value loss falls."""
    config = load_hyperparams("mappo", "cn-sparse-n3")
    config["policy_kwargs"] = config["policy_kwargs"].replace(")", ", recurrent=False)")
    experiment = Experiment("mappo", "cn-sparse-n3", config, n_games=16)
    model, env = experiment.build(), experiment.env
    logs = []

    def record(model):
        values = model.logger.name_to_value
        logs.append({key: float(values[key]) for key in ("train/entropy_loss", "train/value_loss")})

    original_train = model.train

    def train_and_record():
        original_train()
        record(model)

    model.train = train_and_record
    model.learn(4 * 25 * env.num_envs)
    env.close()
    assert len(logs) == 4 and all(np.isfinite(list(log.values())).all() for log in logs)
    assert logs[-1]["train/entropy_loss"] > logs[0]["train/entropy_loss"]  # entropy_loss = -entropy
    assert logs[-1]["train/value_loss"] < logs[0]["train/value_loss"]


@pytest.fixture
def env():
    vec_env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    yield vec_env
    vec_env.close()
