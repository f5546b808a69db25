"""Slow learning checks (``make test-slow``): trained policies beat a random policy.

- Sparse Cooperative Navigation on the paper's world (``world="mpe"``, the task's default) without the collision
  penalty: MAPPO with its packaged config (the benchmark's run, seed 1, 128 games) for PAPER_BUDGET agent-steps.
  The claim, as measured by the learning-evidence runs (docs/results.md, stage 1: 26.7% and 21.7% final-step
  coverage at 1M agent-steps on seeds 1 and 2, random 1.5%): greedy coverage at least five times a random policy's
  and 0.10 above it, on the benchmark's evaluation episodes (measured on 0.2.0a0: 27.3% vs random 1.7%, 174 s with
  two benchmark jobs sharing the machine's two cores).

- Sparse Cooperative Navigation (the issue's learning check): BUDGET agent-steps with 128 games (the paper's
  rollout threads; with 16 games the paper's learning rate and epochs collapse the policy entropy early), the
  package defaults, seed 0; about 15 minutes on one core. The paper trains 20M env steps (60M agent-steps).
  The claim, as measured (docs/results.md): on mpe2's world without the collision penalty
  (``world="mpe2", collision_penalty=0``; the variant the earlier runs learned in), SAEIR_PPO's final-step coverage is
  at least three times a random policy's and 0.05 above it (measured on 0.2.0a0: 16.2% vs 1.8%, seed 0, 745 s on
  one core; 17.5% on 0.1.0a0).
  The task as defined (penalty 1) did not rise above random at this budget, so it is not claimed here; where it is
  learnable is the subject of the learning-evidence runs (docs/results.md).
- Dense mpe2 ``simple_spread`` (a sanity check that the learner itself works): DENSE_BUDGET agent-steps, 16 games,
  same defaults, about 7 minutes on one core (396 s measured on 0.2.0a0).
"""

import pytest
from mpe2 import simple_spread_v3

from sb3_saeir import SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.config import load_hyperparams
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy
from sb3_saeir.experiment import Experiment

BUDGET = 1_000_000
N_GAMES = 128
DENSE_BUDGET = 300_000
EVAL_EPISODES = 200
PAPER_BUDGET = 1_000_000


def eval_env(**task_kwargs):
    return make_multiagent_vec_env("cn-sparse-n3", n_games=10, seed=12_345, **task_kwargs)


# the variant of the claim: mpe2's world (the task's world until 0.2.0) without the collision penalty
VARIANT = {"world": "mpe2", "collision_penalty": 0.0}


@pytest.mark.slow
def test_saeir_ppo_beats_random_coverage_without_collision_penalty():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=N_GAMES, seed=0, **VARIANT)
    model = SAEIR_PPO("MSHGPolicy", env, seed=0).learn(BUDGET)
    trained = evaluate_multiagent_policy(model, eval_env(**VARIANT), n_episodes=EVAL_EPISODES, deterministic=False)
    random = evaluate_multiagent_policy(
        RandomMultiAgentPolicy(env.action_space), eval_env(**VARIANT), n_episodes=EVAL_EPISODES
    )
    print(
        f"{VARIANT}: coverage rate (final step): SAEIR_PPO "
        f"{trained['coverage_rate_mean']:.3f}, random {random['coverage_rate_mean']:.3f}; coverage over steps: "
        f"SAEIR_PPO {trained['coverage_over_steps_mean']:.3f}, random {random['coverage_over_steps_mean']:.3f}"
    )
    # "clearly above": at least three times the random rate and 0.05 (absolute) higher
    assert trained["coverage_rate_mean"] >= max(3 * random["coverage_rate_mean"], random["coverage_rate_mean"] + 0.05)


@pytest.mark.slow
def test_mappo_beats_random_coverage_on_paper_world_without_collision_penalty():
    # the packaged MAPPO config on the paper's world (world="mpe", reward="occupancy") with collision_penalty=0
    config = {**load_hyperparams("mappo", "cn-sparse-n3"), "env_kwargs": {"N": 3, "collision_penalty": 0.0}}
    experiment = Experiment("mappo", "cn-sparse-n3", config, seed=1, n_games=N_GAMES)
    model = experiment.build()
    experiment.learn(PAPER_BUDGET)
    eval_env = experiment.make_eval_env(100)  # the benchmark's evaluation episodes (10 games, seed 10_001)
    trained = evaluate_multiagent_policy(model, eval_env, n_episodes=100, deterministic=True)
    eval_env.seed(10_001)
    random = evaluate_multiagent_policy(RandomMultiAgentPolicy(eval_env.action_space), eval_env, n_episodes=100)
    experiment.close()
    print(
        f"paper's world, no collision penalty: coverage rate (final step): MAPPO {trained['coverage_rate_mean']:.3f}, "
        f"random {random['coverage_rate_mean']:.3f}"
    )
    assert trained["coverage_rate_mean"] >= max(5 * random["coverage_rate_mean"], random["coverage_rate_mean"] + 0.10)


def dense_spread():
    return simple_spread_v3.parallel_env(N=3, max_cycles=25, continuous_actions=False)


def dense_eval_env():
    return make_multiagent_vec_env(dense_spread, n_games=10, seed=999)


@pytest.mark.slow
def test_saeir_ppo_learns_dense_spread():
    env = make_multiagent_vec_env(dense_spread, n_games=16, seed=0)
    model = SAEIR_PPO("MSHGPolicy", env, seed=0).learn(DENSE_BUDGET)
    trained = evaluate_multiagent_policy(model, dense_eval_env(), n_episodes=100)
    random = evaluate_multiagent_policy(RandomMultiAgentPolicy(env.action_space), dense_eval_env(), n_episodes=100)
    print(f"dense simple_spread return: SAEIR_PPO {trained['ep_rew_mean']:.2f}, random {random['ep_rew_mean']:.2f}")
    # measured at this budget on 0.2.0a0: SAEIR_PPO -19.59, random -25.47 (100 episodes; 0.1.0a0: -19.98); require a
    # 3-point margin
    assert trained["ep_rew_mean"] >= random["ep_rew_mean"] + 3.0
