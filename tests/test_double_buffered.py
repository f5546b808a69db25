"""Double-buffered sampling (``double_buffered``): the data it collects, determinism, the option's checks, stopping."""

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecNormalize

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.vec_env import MultiAgentVecMonitor
from sb3_saeir.common.vec_env.workers import GameWorkerError
from tests.toy_envs import FailingMeetEnv, JitteryMeetEnv, SlowMeetEnv, ToyMeetEnv

BUFFER_FIELDS = ("observations", "actions", "rewards", "episode_starts", "values", "log_probs", "returns", "advantages")


def greedy_model(env, double_buffered):
    """MAPPO (its centralised critic: the hypergraph critic's top-k neighbours flip on the toy game's exact cosine ties
    when a group's smaller batch changes the last bits of a sum) and an actor whose logits are scaled by 1e8 (its
    initial logits are about 1e-3 apart): its actions are the argmax of its logits whatever the random stream, so the
    synchronous and the double-buffered loop must collect the same data."""
    model = MAPPO(
        "MAPPOPolicy",
        env,
        n_steps=10,
        n_epochs=1,
        seed=3,
        double_buffered=double_buffered,
        policy_kwargs=dict(hidden_size=8),
    )
    with th.no_grad():
        model.policy.action_net.weight.mul_(1e8)
        # distinct biases: an all-zero latent (a zero observation) would otherwise give three equal logits
        model.policy.action_net.bias.copy_(th.tensor([0.0, 1e-4, 2e-4]) * 1e8)
    return model


def test_collects_the_synchronous_loops_data():
    """4 toy games (episodes of 6 steps inside 10-step rollouts): in-process, synchronous vs two workers,
    double-buffered (jittery games, so the groups come back in changing orders)."""
    buffers = {}
    for name, env_class, num_cpus, double_buffered in (
        ("sync", ToyMeetEnv, 0, False),
        ("double_buffered", JitteryMeetEnv, 2, True),
    ):
        env = MultiAgentVecMonitor(make_multiagent_vec_env(env_class, n_games=4, seed=1, num_cpus=num_cpus))
        model = greedy_model(env, double_buffered)
        model.learn(2 * 10 * env.num_envs)  # two rollouts: the second starts from the states the first left
        buffer = model.rollout_buffer
        buffers[name] = {field: np.array(getattr(buffer, field)) for field in BUFFER_FIELDS}
        buffers[name]["actor_states"] = np.array(buffer.actor_states)
        buffers[name]["critic_states"] = np.array(buffer.critic_states)
        buffers[name]["episodes"] = [(e["r"], e["l"]) for e in env.episodes]
        env.close()
    sync, double = buffers["sync"], buffers["double_buffered"]
    assert len(np.unique(sync["actions"])) > 1  # the actions depend on the observations
    for field in ("observations", "actions", "rewards", "episode_starts"):
        np.testing.assert_array_equal(double[field], sync[field], err_msg=field)
    for field in ("values", "log_probs", "returns", "advantages", "actor_states", "critic_states"):
        np.testing.assert_allclose(double[field], sync[field], rtol=1e-5, atol=1e-6, err_msg=field)
    assert double["episodes"] == sync["episodes"]


def final_parameters(algo, seed):
    env = MultiAgentVecMonitor(make_multiagent_vec_env(JitteryMeetEnv, n_games=4, seed=seed, num_cpus=2))
    model = algo("MSHGPolicy", env, n_steps=10, n_epochs=2, seed=seed, double_buffered=True, policy_kwargs=dict(hidden_size=8))
    model.learn(3 * 10 * env.num_envs)
    env.close()
    return th.cat([p.detach().flatten() for p in model.policy.parameters()]), th.rand(3)


@pytest.mark.parametrize("algo", [MAPPO, SAEIR_PPO])
def test_same_seed_same_run_whatever_order_the_groups_come_back(algo):
    """Actions and Gumbel noise are drawn group by group from per-group streams: the same seed gives the same
    parameters (and the same global random stream afterwards) though the jittery games come back in other orders."""
    first, after_first = final_parameters(algo, seed=4)
    second, after_second = final_parameters(algo, seed=4)
    assert th.equal(first, second)
    assert th.equal(after_first, after_second)
    other, _ = final_parameters(algo, seed=5)
    assert not th.equal(first, other)


def test_option_checked():
    env = make_multiagent_vec_env(ToyMeetEnv, n_games=2, seed=0)
    with pytest.raises(ValueError, match="double_buffered must be True, False or 'auto'"):
        MAPPO("MAPPOPolicy", env, double_buffered="yes")
    with pytest.raises(ValueError, match="num_cpus=2"):  # when the model is built, not at its first rollout
        MAPPO("MAPPOPolicy", env, n_steps=6, double_buffered=True)
    MAPPO("MAPPOPolicy", env, n_steps=6).learn(36)  # "auto": the synchronous loop for games in this process
    env.close()


def test_wrapper_that_changes_steps_refused():
    env = VecNormalize(make_multiagent_vec_env(ToyMeetEnv, n_games=2, seed=0, num_cpus=2))
    env.n_agents = 3  # VecNormalize does not forward attributes the algorithms read directly
    with pytest.raises(ValueError, match="VecNormalize"):
        MAPPO("MAPPOPolicy", env, n_steps=6, double_buffered=True)
    env.close()


class StopAtStep(BaseCallback):
    def __init__(self, step):
        super().__init__()
        self.step = step

    def _on_step(self):
        return self.n_calls < self.step


def test_stop_in_a_rollout_drains_the_groups_and_resets_at_the_next_learn():
    env = make_multiagent_vec_env(JitteryMeetEnv, n_games=4, seed=0, num_cpus=2)
    model = MAPPO("MAPPOPolicy", env, n_steps=10, n_epochs=1, double_buffered=True, policy_kwargs=dict(hidden_size=8))
    model.learn(10 * env.num_envs, callback=StopAtStep(4))
    assert model.num_timesteps == 4 * env.num_envs
    assert model._last_obs is None and not env.pool.busy
    model.learn(10 * env.num_envs, reset_num_timesteps=False)
    assert model.num_timesteps == 14 * env.num_envs
    env.close()


def test_option_saved_and_models_saved_without_it_load_with_the_default(tmp_path, toy_env):
    MAPPO("MAPPOPolicy", toy_env, n_steps=6, double_buffered=False).save(tmp_path / "off")
    assert MAPPO.load(tmp_path / "off").double_buffered is False
    model = MAPPO("MAPPOPolicy", toy_env, n_steps=6, double_buffered=False)
    del model.double_buffered  # as saved by a version without the option
    model.save(tmp_path / "old")
    loaded = MAPPO.load(tmp_path / "old", env=toy_env)
    assert loaded.double_buffered == "auto"
    loaded.learn(36)


def test_worker_error_in_a_double_buffered_rollout_is_raised_and_ends_the_workers():
    env = make_multiagent_vec_env(FailingMeetEnv, n_games=4, seed=0, num_cpus=2)
    processes = list(env.pool.processes)
    model = MAPPO("MAPPOPolicy", env, n_steps=10, double_buffered=True, policy_kwargs=dict(hidden_size=8))
    with pytest.raises(GameWorkerError, match="ValueError: the toy game broke at step 3"):
        model.learn(10 * env.num_envs)
    assert not any(process.is_alive() for process in processes)
    env.close()


def test_ctrl_c_in_a_double_buffered_rollout_leaves_the_workers_to_close(ctrl_c):
    """SIGINT to the whole process group during a rollout: learn raises KeyboardInterrupt after waiting for the steps
    in flight; the workers (which ignore SIGINT) end cleanly when the env is closed."""
    env = make_multiagent_vec_env(SlowMeetEnv, n_games=4, seed=0, num_cpus=2)
    processes = list(env.pool.processes)
    model = MAPPO("MAPPOPolicy", env, n_steps=10, double_buffered=True, policy_kwargs=dict(hidden_size=8))
    ctrl_c(processes, 0.3)
    with pytest.raises(KeyboardInterrupt):
        model.learn(100 * env.num_envs)
    assert all(process.is_alive() for process in processes) and not env.pool.busy
    assert model._last_obs is None
    env.close()
    assert [process.exitcode for process in processes] == [0, 0]
