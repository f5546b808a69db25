"""Plain SB3 algorithms on MultiAgentVecEnv (parameter sharing): seeding, logging, wrappers."""

import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import VecNormalize

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.common.callbacks import EpisodeMetricsCallback


class RecordingLogger:
    """Collects every key recorded through SB3's logger."""

    def __init__(self, logger):
        self.logger = logger
        self.records: list[dict] = []
        self._orig_dump = logger.dump

        def dump(step=0):
            self.records.append(dict(logger.name_to_value))
            self._orig_dump(step)

        logger.dump = dump


def test_plain_ppo_trains_and_logs_task_metrics(tmp_path):
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    model = PPO("MlpPolicy", env, n_steps=25, batch_size=50, n_epochs=1, seed=0, policy_kwargs=dict(net_arch=[16]))
    logger = configure(str(tmp_path), ["csv"])
    model.set_logger(logger)
    recorder = RecordingLogger(logger)
    model.learn(total_timesteps=2 * 25 * env.num_envs, callback=EpisodeMetricsCallback())
    assert len(recorder.records) == 2
    last = recorder.records[-1]
    assert "rollout/ep_rew_mean" in last and "rollout/ep_len_mean" in last
    assert last["rollout/ep_len_mean"] == 25  # one episode per game, 25 steps
    assert 0.0 <= last["rollout/coverage_rate"] <= 1.0
    assert "rollout/success_rate" in last  # SB3's own is_success path, one per game
    assert len(model.ep_info_buffer) == 2 * 2  # 2 rollouts x 2 games (VecMonitor would count x 3 agents)
    env.close()


def test_ppo_seed_reproducible():
    def run():
        env = make_multiagent_vec_env("cn-sparse-n3", n_games=2)
        model = PPO("MlpPolicy", env, n_steps=25, batch_size=50, n_epochs=1, seed=7, policy_kwargs=dict(net_arch=[8]))
        model.learn(50 * 3)
        params = np.concatenate([p.detach().numpy().ravel() for p in model.policy.parameters()])
        env.close()
        return params

    np.testing.assert_array_equal(run(), run())


def test_vec_normalize_wraps():
    env = VecNormalize(make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0))
    assert env.n_agents == 3  # forwarded through the wrapper
    PPO("MlpPolicy", env, n_steps=25, batch_size=50, n_epochs=1, policy_kwargs=dict(net_arch=[8])).learn(150)
    env.close()


@pytest.mark.parametrize("num_cpus", [2])
def test_ppo_with_subprocess_games(num_cpus):
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0, num_cpus=num_cpus)
    model = PPO("MlpPolicy", env, n_steps=25, batch_size=50, n_epochs=1, seed=0, policy_kwargs=dict(net_arch=[8]))
    model.learn(150)
    assert model.num_timesteps == 150  # one rollout of 25 steps x 6 agent slots, stepped in 2 worker processes
    assert model.logger.name_to_value["train/n_updates"] == 1
    env.close()


def test_callbacks_see_the_step_locals_sb3_gives_them(env, tiny_kwargs):
    """A callback reading ``self.locals["actions"]`` (and ``clipped_actions``, ``values``, ``log_probs``), as SB3's
    examples do, gets one row per agent slot; the actions are those the env stepped with."""
    from stable_baselines3.common.callbacks import BaseCallback

    from sb3_saeir import SAEIR_PPO

    class StepLocals(BaseCallback):
        def __init__(self):
            super().__init__()
            self.seen = []

        def _on_step(self):
            seen = {key: self.locals[key] for key in ("actions", "clipped_actions", "values", "log_probs")}
            self.seen.append({key: value.numpy() if hasattr(value, "numpy") else value.copy() for key, value in seen.items()})
            return True

    callback = StepLocals()
    SAEIR_PPO("MSHGPolicy", env, **tiny_kwargs).learn(2 * env.num_envs, callback=callback)
    first = callback.seen[0]
    assert first["actions"].shape == (env.num_envs,) and np.array_equal(first["actions"], first["clipped_actions"])
    assert set(first["actions"].tolist()) <= set(range(5))
    assert first["values"].shape == (env.num_envs, 3) and first["log_probs"].shape == (env.num_envs,)
    assert (first["log_probs"] <= 0).all()
