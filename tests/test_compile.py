"""The ``compile`` switch (torch.compile of the actor's and the critics' forward): the same maths as eager on the golden
tests' inputs, the same run twice from a seed, models saved and loaded across the switch with unchanged state-dict
keys, no recompilation when the number of blocks changes, and eager training with one warning line where no C++
compiler is found.

These tests compile with the inductor backend on small networks (they need g++, as CI has; without it they are
skipped, except the no-compiler test). Compilation is most of their time; the compiled code is cached on disk by
torch (``/tmp/torchinductor_<user>``), so later runs are faster.
"""

import warnings

import numpy as np
import pytest
import torch as th

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common import compilation
from sb3_saeir.common.buffers import split_by_valid_length
from sb3_saeir.config import check_hyperparams, load_hyperparams, parse_params
from sb3_saeir.mappo.losses import actor_losses, critic_loss, scale_advantage_weights
from tests.test_save_load import deterministic_actions, observation_sequence

needs_compiler = pytest.mark.skipif(compilation.find_cpp_compiler() is None, reason="no C++ compiler for inductor")
RELATIVE = 1e-4  # the bound, relative to each array's largest magnitude
# the golden inputs' shapes in every test (chunks of 10 and 5 steps, hidden size 16): one set of compiled graphs serves
# them all (the batch sizes are dynamic), and torch's on-disk cache serves the other test process
SMALL = dict(n_steps=25, n_epochs=1, policy_kwargs=dict(hidden_size=16))


def assert_close(computed, expected, name):
    computed, expected = np.asarray(computed, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    scale = max(np.abs(expected).max(), 1e-8)
    assert np.abs(computed - expected).max() <= RELATIVE * scale, name


def one_update(model, samples, seed=11):
    """Values, log-probs, losses and gradients of one update's first minibatch, as ``MAPPO.train`` computes them."""
    policy = model.policy
    th.manual_seed(seed)
    groups = split_by_valid_length(samples)
    n_valid = samples.mask.sum() * policy.n_agents
    weights = scale_advantage_weights(samples.advantages[samples.mask].reshape(-1, policy.n_scales))
    outputs = {}
    for i, group in enumerate(groups):
        part = group.samples
        log_prob, entropy = policy.evaluate_actor(part.observations, part.actions, part.actor_states, part.episode_starts)
        outputs[f"log_prob/{i}"], outputs[f"entropy/{i}"] = log_prob.detach(), entropy.detach()
        for k in range(policy.n_scales):
            values = policy.evaluate_critic(k, part.observations, part.critic_states[k], part.episode_starts)
            outputs[f"values/{k}/{i}"] = values.detach()
    policy.zero_grad()
    policy_loss, entropy_loss, _, _ = actor_losses(model.policy, groups, weights, n_valid, 0.2)
    (policy_loss + model.ent_coef * entropy_loss).backward()
    outputs["policy_loss"], outputs["entropy_loss"] = policy_loss.detach(), entropy_loss.detach()
    for k in range(policy.n_scales):
        scale_loss = critic_loss(
            model.policy, k, samples, groups, n_valid, None, model.normalize_values, model.value_loss, model.huber_delta
        )
        scale_loss.backward()
        outputs[f"value_loss/{k}"] = scale_loss.detach()
    outputs.update({f"grad/{name}": p.grad.clone() for name, p in policy.named_parameters() if p.grad is not None})
    return outputs


@needs_compiler
@pytest.mark.parametrize(
    "algo, policy_name, n_steps",
    [(MAPPO, "MAPPOPolicy", 25), (SAEIR_PPO, "MSHGPolicy", 10)],
    ids=["MAPPO", "SAEIR_PPO"],
)
def test_compiled_update_matches_eager_on_the_golden_inputs(algo, policy_name, n_steps):
    """The golden tests' setup (tests/test_update_equivalence.py: 2 games, seed 3, hidden size 16): MAPPO with its
    25-step rollouts (chunks of 10 and 5 steps) and the rollout's forward pass; SAEIR_PPO's four networks on 10-step
    rollouts (one chunk length: half the graphs to compile, about 3 minutes of CI time saved)."""
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=3)
    model = algo(policy_name, env, seed=3, **{**SMALL, "n_steps": n_steps})
    model.learn(n_steps * env.num_envs)
    samples = next(model.rollout_buffer.get(1))
    state = {name: value.clone() for name, value in model.policy.state_dict().items()}
    eager = one_update(model, samples)
    model.policy.load_state_dict(state)
    model.policy.set_compile("inductor")
    compiled = one_update(model, samples)
    assert compiled.keys() == eager.keys() and len([key for key in eager if key.startswith("grad/")]) > 10
    for name in eager:
        assert_close(compiled[name], eager[name], name)
    if algo is MAPPO:  # the rollout's forward pass: actions from the same draws, values and log-probs
        obs = th.as_tensor(model.rollout_buffer.observations[3])
        starts = th.as_tensor(model.rollout_buffer.episode_starts[3], dtype=th.float32)
        states = model.policy.initial_states(2)
        results = []
        for backend in ("inductor", None):
            model.policy.set_compile(backend)
            th.manual_seed(5)
            with th.no_grad():
                results.append(model.policy(obs, states, starts))
        (actions, values, log_prob, _), (eager_actions, eager_values, eager_log_prob, _) = results
        assert th.equal(actions, eager_actions)
        assert_close(values, eager_values, "rollout values")
        assert_close(log_prob, eager_log_prob, "rollout log-probs")
    env.close()


def train_small(seed, compile_setting, n_iterations=2, **kwargs):
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=seed)
    model = MAPPO("MAPPOPolicy", env, seed=seed, compile=compile_setting, **{**SMALL, **kwargs})
    model.learn(n_iterations * SMALL["n_steps"] * env.num_envs)
    return model, env


@needs_compiler
def test_same_seed_same_run_compiled():
    first, env = train_small(0, True)
    second, _ = train_small(0, True)
    assert first.policy.compile_backend == "inductor"
    for name, tensor in first.policy.state_dict().items():
        assert th.equal(tensor, second.policy.state_dict()[name]), name
    np.testing.assert_array_equal(first.rollout_buffer.advantages, second.rollout_buffer.advantages)
    env.close()


@needs_compiler
@pytest.mark.parametrize("train_compiled", [True, False])
def test_save_load_across_the_switch(train_compiled, tmp_path):
    """Trained one way, loaded the other way: the same state-dict keys (no ``_orig_mod.``), parameters and actions."""
    model, env = train_small(0, train_compiled)
    observations = observation_sequence(env)
    expected = deterministic_actions(model, observations)
    model.save(tmp_path / "model.zip")
    loaded = MAPPO.load(tmp_path / "model.zip", env=env, device="cpu", compile=not train_compiled)
    assert loaded.policy.compile_backend == (None if train_compiled else "inductor")
    assert list(loaded.policy.state_dict()) == list(model.policy.state_dict())
    assert not [name for name in loaded.policy.state_dict() if "_orig_mod" in name]
    for name, tensor in model.policy.state_dict().items():
        assert th.equal(tensor, loaded.policy.state_dict()[name]), name
    np.testing.assert_array_equal(deterministic_actions(loaded, observations), expected)
    assert MAPPO.load(tmp_path / "model.zip", device="cpu").policy.compile_backend is None  # the switch is not saved
    loaded.learn(SMALL["n_steps"] * env.num_envs, reset_num_timesteps=False)  # and trains on
    env.close()


@needs_compiler
def test_no_recompilation_when_the_number_of_blocks_changes():
    """5 games, 3 minibatches of 5 blocks each, split by valid length into groups of 1-5 blocks that vary from one
    minibatch to the next: the first iterations compile, later ones reuse the code.

    Dynamo's cache belongs to the networks' ``forward`` code, shared by every model in the process, so it is emptied
    first: after other compiled tests in the same worker the check passed whatever this model did, and alone it
    failed, because run alone the third iteration still compiles once (measured: 8 graphs after one or two
    iterations, 9 from the third to the eighth; a guard on the stride of an input view's base)."""
    th._dynamo.reset()
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=5, seed=0)
    model = MAPPO("MAPPOPolicy", env, seed=0, compile=True, **{**SMALL, "n_minibatches": 3})
    rollout = SMALL["n_steps"] * env.num_envs
    before = compilation.compile_counters()
    model.learn(3 * rollout)
    warmed = compilation.compile_counters()
    assert warmed["frames"] > before["frames"]  # the networks did compile (else the check below says nothing)
    model.learn(4 * rollout, reset_num_timesteps=False)
    assert compilation.compile_counters() == warmed
    env.close()


def test_no_compiler_warns_once_and_trains_eagerly(monkeypatch):
    monkeypatch.setenv("PATH", "")  # hides g++
    assert compilation.find_cpp_compiler() is None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model, env = train_small(0, True, n_iterations=1)
    messages = [str(w.message) for w in caught if "compile" in str(w.message)]
    assert messages == [
        "MAPPO: compile=True but no C++ compiler was found (the inductor backend needs g++ on PATH on the CPU); "
        "training goes on without compiling (eager)."
    ]
    assert model.policy.compile_backend is None and model.num_timesteps == SMALL["n_steps"] * env.num_envs
    env.close()


def test_bad_compile_value_is_one_line(env):
    with pytest.raises(ValueError, match=r"^MAPPO: compile must be True, False or a torch.compile backend name .*'fast'"):
        MAPPO("MAPPOPolicy", env, compile="fast")


def test_compile_from_configs_and_params():
    overrides = parse_params(["compile:True"])
    check_hyperparams("saeir_ppo", load_hyperparams("saeir_ppo", "cn-sparse-n3"), overrides)
    assert overrides == {"compile": True}


def test_gru_step_loop_is_the_gru_with_resets():
    """What compiled code runs for a GRU layer (GRULayer.step_loop) against its eager forward, with episode starts
    inside the sequence (football's case): the same outputs and last states up to float rounding."""
    from sb3_saeir.common.torch_layers import GRULayer

    th.manual_seed(0)
    layer = GRULayer(6, 5)
    x, hidden = th.randn(7, 4, 6), th.randn(4, 5)
    starts = th.zeros(7, 4)
    starts[0, 1] = starts[3, 0] = starts[5, 2] = 1.0
    expected_out, expected_last = layer(x, hidden, starts)
    out, last = layer.step_loop(x, hidden, 1.0 - starts)
    th.testing.assert_close(out, expected_out, rtol=1e-6, atol=1e-6)
    th.testing.assert_close(last, expected_last, rtol=1e-6, atol=1e-6)


def test_compile_flag_resume_and_loading_for_more_training(tmp_path):
    """``--compile on`` sets the config's ``compile``; it may differ at ``--resume``; the config's value reaches a
    model loaded to continue training (``-i``, ``--resume``), since it is not saved with the model."""
    from sb3_saeir.experiment import Experiment
    from sb3_saeir.run.record import config_record, spec_differences, spec_record
    from sb3_saeir.train import make_parser, resolve_hyperparams, run_spec

    command = ["--algo", "mappo", "--task", "cn-sparse-n3"]
    with_compile = make_parser().parse_args([*command, "--compile", "on"])
    first_part = make_parser().parse_args(command)
    assert resolve_hyperparams(with_compile)["compile"] is True and "compile" not in resolve_hyperparams(first_part)
    stored = spec_record(run_spec(first_part, {}, 0, 1000, 8, config_record(resolve_hyperparams(first_part))))
    planned = spec_record(run_spec(with_compile, {}, 0, 1000, 8, config_record(resolve_hyperparams(with_compile))))
    assert spec_differences(stored, planned) == []

    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    MAPPO("MAPPOPolicy", env, seed=0, **SMALL).save(tmp_path / "model.zip")
    config = {**load_hyperparams("mappo", "cn-sparse-n3"), "compile": "aot_eager"}
    experiment = Experiment("mappo", "cn-sparse-n3", config, seed=0, n_games=2)
    assert experiment.load(tmp_path / "model.zip").policy.compile_backend == "aot_eager"
    experiment.close()
    env.close()
