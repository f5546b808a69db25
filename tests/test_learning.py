"""Slow learning checks (``make test-slow``): trained policies beat a random policy.

- Sparse Cooperative Navigation on the paper's world (``world="mpe"``, the task's default) without the collision
  penalty, MAPPO and SAEIR_PPO, each with its packaged config (the benchmark's run: seed 1, 128 games) for
  PAPER_BUDGET agent-steps (1M, 1.7% of the paper's 60M). The claim, as measured by the learning-evidence runs
  (docs/results/navigation-variants.md, MAPPO 26.7% and 21.7% final-step coverage at 1M agent-steps on seeds 1 and 2;
  docs/results/navigation-5pct.md,
  SAEIR_PPO 28.3% and 29.0% at 1M on seeds 1 and 2; random 1.5%): greedy coverage at least five times a random
  policy's and 0.10 above it, on the benchmark's evaluation episodes. Measured on 0.2.0a0: MAPPO 27.3% vs random
  1.7% (174 s with two benchmark jobs sharing the machine's two cores); SAEIR_PPO 30.3% vs random 1.7% (482 s, one
  torch thread, beside two benchmark jobs on the two cores).
  The task as the supplement words it (penalty 1) learns more slowly (stage 2: 6-15% at 3M agent-steps), so it is
  not claimed at a test's budget. The feed-forward MAPPO (``policy_kwargs=dict(recurrent=False)``, not the paper's
  setting) is held to the same claim (measured in the docstring of its test).
- Dense mpe2 ``simple_spread`` (a sanity check that the learner itself works): DENSE_BUDGET agent-steps, 16 games,
  the package defaults, seed 0, about 7 minutes on one core (396 s measured on 0.2.0a0).
"""

import pytest
from mpe2 import simple_spread_v3

from sb3_saeir import SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.config import load_hyperparams, parse_policy_kwargs
from sb3_saeir.evaluation import RandomMultiAgentPolicy, evaluate_multiagent_policy
from sb3_saeir.experiment import Experiment

N_GAMES = 128
DENSE_BUDGET = 300_000
PAPER_BUDGET = 1_000_000


def paper_world_coverage(algo: str, policy_kwargs: dict | None = None) -> tuple[float, float]:
    """Greedy final-step coverage of ``algo`` (its packaged config, seed 1, 128 games, PAPER_BUDGET agent-steps) and of a
    random policy, on the paper's world (world="mpe", reward="occupancy") with collision_penalty=0, on the benchmark's
    evaluation episodes (100 episodes, 10 games, seed 10_001).

    :param policy_kwargs: policy arguments merged into the config's (e.g. ``dict(recurrent=False)``)
    """
    config = {**load_hyperparams(algo, "cn-sparse-n3"), "env_kwargs": {"N": 3, "collision_penalty": 0.0}}
    if policy_kwargs:
        config["policy_kwargs"] = {**parse_policy_kwargs(config.get("policy_kwargs")), **policy_kwargs}
    experiment = Experiment(algo, "cn-sparse-n3", config, seed=1, n_games=N_GAMES)
    model = experiment.build()
    experiment.learn(PAPER_BUDGET)
    eval_env = experiment.make_eval_env(100)
    trained = evaluate_multiagent_policy(model, eval_env, n_episodes=100, deterministic=True)
    eval_env.seed(10_001)
    random = evaluate_multiagent_policy(RandomMultiAgentPolicy(eval_env.action_space), eval_env, n_episodes=100)
    experiment.close()
    print(
        f"paper's world, no collision penalty: coverage rate (final step): {algo} {trained['coverage_rate_mean']:.3f}, "
        f"random {random['coverage_rate_mean']:.3f}"
    )
    return trained["coverage_rate_mean"], random["coverage_rate_mean"]


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["mappo", "saeir_ppo"])
def test_beats_random_coverage_on_paper_world_without_collision_penalty(algo):
    trained, random = paper_world_coverage(algo)
    # "clearly above": at least five times the random rate and 0.10 (absolute) higher
    assert trained >= max(5 * random, random + 0.10)


@pytest.mark.slow
def test_feed_forward_mappo_beats_random_coverage_on_paper_world_without_collision_penalty():
    """MAPPO without GRUs (``recurrent=False``) under the same claim as the recurrent methods; measured: see
    docs/guide/algorithms.md ("Feed-forward networks")."""
    trained, random = paper_world_coverage("mappo", dict(recurrent=False))
    assert trained >= max(5 * random, random + 0.10)


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
