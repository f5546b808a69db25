"""The batched navigation engine, step by step: against mpe2's own simple_spread_v3 (world="mpe2"), against a slow
reference of the original MPE written here from its equations (world="mpe"), native vec env against the ParallelEnv
through SuperSuit, and each reward reading on hand-placed agents and landmarks."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from gymnasium.utils import seeding
from pettingzoo.utils.env import ParallelEnv

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.common.vec_env import MultiAgentDummyVecEnv, MultiAgentVecEnv
from sb3_saeir.envs import get_native_vec_env_factory, make_task
from sb3_saeir.envs.navigation import SparseCooperativeNavigation
from sb3_saeir.envs.navigation_core import NavigationCore
from sb3_saeir.envs.navigation_vec_env import NavigationVecEnv

N_GAMES = 8
EPISODES = 5
STEPS = 25


def random_actions(rng: np.random.Generator, n_slots: int, continuous: bool) -> np.ndarray:
    if continuous:
        return rng.uniform(0.0, 1.0, size=(n_slots, 5)).astype(np.float32)
    return rng.integers(0, 5, size=n_slots)


def sparse_reward(agents: np.ndarray, landmarks: np.ndarray, previous: np.ndarray, reading: str) -> tuple[float, np.ndarray]:
    """Team reward from positions with plain loops; returns it and the landmarks reached now."""
    reached = np.array([min(math.dist(a, lm) for a in agents) < 0.1 for lm in landmarks])
    collided = any(math.dist(agents[a], agents[b]) < 0.3 for a in range(len(agents)) for b in range(a + 1, len(agents)))
    gain = reached.sum() if reading == "occupancy" else (reached & ~previous).sum()
    return float(gain) - float(collided), reached


# ------------------------------------------------------------------------------------ world="mpe2" against mpe2
class Mpe2Sparse(ParallelEnv):
    """mpe2's simple_spread_v3 with the sparse reward computed from its world: the path the package took before."""

    metadata = {"name": "mpe2_sparse", "render_modes": [], "is_parallelizable": True}  # noqa: RUF012

    def __init__(self, N: int, continuous_actions: bool, reward: str = "occupancy") -> None:
        from mpe2 import simple_spread_v3

        self._env = simple_spread_v3.parallel_env(
            N=N, local_ratio=0.0, max_cycles=STEPS, continuous_actions=continuous_actions
        )
        self.possible_agents = list(self._env.possible_agents)
        self.reading = reward
        self.render_mode = None
        self.collisions = 0

    def observation_space(self, agent: str) -> Any:
        return self._env.observation_space(agent)

    def action_space(self, agent: str) -> Any:
        return self._env.action_space(agent)

    def _positions(self) -> tuple[np.ndarray, np.ndarray]:
        world = self._env.unwrapped.world
        return np.array([a.state.p_pos for a in world.agents]), np.array([lm.state.p_pos for lm in world.landmarks])

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        observations, infos = self._env.reset(seed=seed, options=options)
        self.agents = list(self._env.agents)
        agents, landmarks = self._positions()
        _, self._reached = sparse_reward(agents, landmarks, np.zeros(len(landmarks), dtype=bool), "occupancy")
        return observations, infos

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        observations, _, terminations, truncations, infos = self._env.step(actions)
        agents, landmarks = self._positions()
        reward, self._reached = sparse_reward(agents, landmarks, self._reached, self.reading)
        self.collisions += int(any(math.dist(a, b) < 0.3 for i, a in enumerate(agents) for b in agents[i + 1 :]))
        self.agents = list(self._env.agents)
        return observations, dict.fromkeys(self.possible_agents, reward), terminations, truncations, infos


def run_stream(env: Any, seed: int, continuous: bool, steps: int = EPISODES * STEPS) -> dict[str, np.ndarray]:
    """Observations, rewards, dones and per-game episode records of ``steps`` random steps."""
    rng = np.random.default_rng(seed + 1000)
    observations, rewards, dones, episodes = [env.reset()], [], [], []
    for _ in range(steps):
        obs, reward, done, infos = env.step(random_actions(rng, env.num_envs, continuous))
        observations.append(obs)
        rewards.append(reward)
        dones.append(done)
        episodes += [{k: v for k, v in info["episode"].items() if k != "t"} for info in infos if "episode" in info]
    return {
        "observations": np.stack(observations),
        "rewards": np.stack(rewards),
        "dones": np.stack(dones),
        "episodes": np.array([[episode[k] for k in sorted(episode)] for episode in episodes]),
    }


@pytest.mark.parametrize("continuous", [False, True], ids=["discrete", "continuous"])
@pytest.mark.parametrize("N", [3, 4, 5])
def test_mpe2_world_matches_mpe2(N, continuous):
    expected = run_stream(make_multiagent_vec_env(lambda: Mpe2Sparse(N, continuous), n_games=N_GAMES, seed=N), N, continuous)
    native_env = make_multiagent_vec_env(
        "cn-sparse-n3", n_games=N_GAMES, seed=N, N=N, continuous_actions=continuous, world="mpe2"
    )
    assert isinstance(native_env, NavigationVecEnv)
    native = run_stream(native_env, N, continuous)
    np.testing.assert_allclose(native["observations"], expected["observations"], atol=1e-6, rtol=0)
    np.testing.assert_array_equal(native["rewards"], expected["rewards"])
    np.testing.assert_array_equal(native["dones"], expected["dones"])
    assert native["dones"].sum() == EPISODES * N_GAMES * N
    # collisions happen: negative occupancy rewards in mpe2's stream, collision steps in the native episode records
    assert (expected["rewards"] < 0).sum() > 0
    episode_keys = [*native_env.core.episode_metrics(0), "l", "r"]
    assert native["episodes"][:, sorted(episode_keys).index("collision_steps")].sum() > 0


def test_mpe2_world_reach_reading_matches_mpe2():
    expected = run_stream(make_multiagent_vec_env(lambda: Mpe2Sparse(3, False, "reach"), n_games=N_GAMES, seed=7), 7, False)
    native = run_stream(
        make_multiagent_vec_env("cn-sparse-n3", n_games=N_GAMES, seed=7, world="mpe2", reward="reach"), 7, False
    )
    np.testing.assert_array_equal(native["observations"], expected["observations"])
    np.testing.assert_array_equal(native["rewards"], expected["rewards"])
    assert (native["rewards"] > 0).any() and (native["rewards"] < 0).any()


# ------------------------------------------------------------------------ world="mpe" against a slow reference
class SlowOriginalMPE:
    """One game of the original MPE simple_spread, from the equations: plain Python over entities and pairs.

    Agents (size 0.15, mass 1) start in U(-1, 1)^2, landmarks in 0.8 * U(-1, 1)^2 (agents drawn first, from the
    game's generator). Per step: force = 5 * action direction + for every pair a < b the contact force
    100 * margin * log(1 + exp(-(dist - 0.3) / margin)) * (p_a - p_b) / dist (+ on a, - on b); then
    v <- v * (1 - 0.25) + force * 0.1 and p <- p + v * 0.1.
    """

    def __init__(self, N: int, seed: int, continuous: bool, reading: str) -> None:
        self.N, self.continuous, self.reading = N, continuous, reading
        self.rng = seeding.np_random(seed)[0]
        self.reset()

    def reset(self) -> list[list[float]]:
        self.pos = [list(self.rng.uniform(-1, 1, 2)) for _ in range(self.N)]
        self.landmarks = [list(0.8 * self.rng.uniform(-1, 1, 2)) for _ in range(self.N)]
        self.vel = [[0.0, 0.0] for _ in range(self.N)]
        self.t = 0
        _, self.reached = sparse_reward(
            np.array(self.pos), np.array(self.landmarks), np.zeros(self.N, dtype=bool), "occupancy"
        )
        return self.observations()

    def observations(self) -> list[list[float]]:
        result = []
        for i in range(self.N):
            obs = [*self.vel[i], *self.pos[i]]
            for lm in self.landmarks:
                obs += [lm[0] - self.pos[i][0], lm[1] - self.pos[i][1]]
            for j in range(self.N):
                if j != i:
                    obs += [self.pos[j][0] - self.pos[i][0], self.pos[j][1] - self.pos[i][1]]
            obs += [0.0] * (2 * (self.N - 1))
            result.append(obs)
        return result

    def step(self, actions: np.ndarray) -> tuple[list[list[float]], float, bool]:
        force = []
        for i in range(self.N):
            if self.continuous:
                a = [float(x) for x in actions[i]]
                force.append([5.0 * (a[2] - a[1]), 5.0 * (a[4] - a[3])])
            else:
                direction = {0: (0, 0), 1: (-1, 0), 2: (1, 0), 3: (0, -1), 4: (0, 1)}[int(actions[i])]
                force.append([5.0 * direction[0], 5.0 * direction[1]])
        for a in range(self.N):
            for b in range(a + 1, self.N):
                delta = [self.pos[a][0] - self.pos[b][0], self.pos[a][1] - self.pos[b][1]]
                dist = math.hypot(*delta)
                penetration = 1e-3 * np.logaddexp(0.0, -(dist - 0.3) / 1e-3)
                for k in range(2):
                    f = 100.0 * delta[k] / dist * penetration
                    force[a][k] += f
                    force[b][k] -= f
        for i in range(self.N):
            for k in range(2):
                self.vel[i][k] = self.vel[i][k] * 0.75 + force[i][k] * 0.1
                self.pos[i][k] += self.vel[i][k] * 0.1
        self.t += 1
        reward, self.reached = sparse_reward(np.array(self.pos), np.array(self.landmarks), self.reached, self.reading)
        return self.observations(), reward, self.t >= STEPS


@pytest.mark.parametrize(
    "N, continuous, reading", [(3, False, "occupancy"), (3, True, "reach"), (4, False, "reach"), (5, True, "occupancy")]
)
def test_mpe_world_matches_slow_reference(N, continuous, reading):
    seed = 20 + N
    env = make_multiagent_vec_env(
        "cn-sparse-n3", n_games=N_GAMES, seed=seed, N=N, continuous_actions=continuous, reward=reading
    )  # world="mpe" is the default
    games = [SlowOriginalMPE(N, seed + g, continuous, reading) for g in range(N_GAMES)]
    obs = env.reset()
    np.testing.assert_allclose(obs, np.concatenate([game.observations() for game in games]), atol=1e-6, rtol=0)
    rng = np.random.default_rng(seed)
    collisions = 0
    for _ in range(EPISODES * STEPS):
        actions = random_actions(rng, env.num_envs, continuous)
        obs, rewards, dones, infos = env.step(actions)
        expected_obs, expected_rewards, expected_dones = [], [], []
        for g, game in enumerate(games):
            game_obs, reward, done = game.step(actions[g * N : (g + 1) * N])
            if done:
                np.testing.assert_allclose(infos[g * N]["terminal_observation"], game_obs[0], atol=1e-6, rtol=0)
                collisions += int(infos[g * N]["episode"]["collision_steps"])
                game_obs = game.reset()
            expected_obs += game_obs
            expected_rewards += [reward] * N
            expected_dones += [done] * N
        np.testing.assert_allclose(obs, np.array(expected_obs), atol=1e-6, rtol=0)
        np.testing.assert_array_equal(rewards, np.array(expected_rewards, dtype=np.float32))
        np.testing.assert_array_equal(dones, expected_dones)
    assert collisions > 0


# ---------------------------------------------------------- native vec env against the ParallelEnv through SuperSuit
@pytest.mark.parametrize("num_cpus", [0, 2])
@pytest.mark.parametrize(
    "kwargs",
    [{}, {"world": "mpe2", "reward": "reach"}, {"N": 4, "continuous_actions": True, "cover_radius": 0.2}],
    ids=["mpe-occupancy", "mpe2-reach", "n4-continuous"],
)
def test_native_matches_supersuit(kwargs, num_cpus):
    continuous = kwargs.get("continuous_actions", False)
    supersuit_env = make_multiagent_vec_env(
        "cn-sparse-n3", n_games=4, seed=5, num_cpus=num_cpus, backend="supersuit", **kwargs
    )
    assert not isinstance(supersuit_env, NavigationVecEnv)
    expected = run_stream(supersuit_env, 5, continuous, steps=2 * STEPS + 3)
    supersuit_env.close()
    native = run_stream(
        make_multiagent_vec_env("cn-sparse-n3", n_games=4, seed=5, **kwargs), 5, continuous, steps=2 * STEPS + 3
    )
    for key in ("observations", "rewards", "dones", "episodes"):
        np.testing.assert_array_equal(native[key], expected[key], err_msg=key)
    assert len(native["episodes"]) == 2 * 4


def test_unseeded_games_differ_and_reset_seed_reproduces():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=3)
    first = env.reset().reshape(3, 3, -1)
    assert not np.allclose(first[0], first[1])
    np.testing.assert_array_equal(env.reset(seed=4), make_multiagent_vec_env("cn-sparse-n3", n_games=3, seed=4).reset())


# --------------------------------------------------------------------------------- reward readings, hand-placed
AWAY = [[-0.9, 0.9], [0.9, 0.9], [0.9, -0.9]]  # agents far from each other and from every landmark
LANDMARKS = [[-0.5, -0.5], [0.5, -0.2], [0.0, 0.5]]


def head_on(landmark_0_covered: bool) -> tuple[list, list]:
    """Agents 1 and 2 0.6 apart, closing at 2.5 each: they overlap after the step in both worlds."""
    agent_0 = LANDMARKS[0] if landmark_0_covered else AWAY[0]
    return [agent_0, [-0.3, -0.8], [0.3, -0.8]], [[0.0, 0.0], [2.5, 0.0], [-2.5, 0.0]]


@pytest.mark.parametrize("world", ["mpe", "mpe2"])
@pytest.mark.parametrize(
    "reading, expected",
    [
        # cover, stay, leave, re-enter with a collision in the same step, stay with the collision, away and colliding
        ("occupancy", [1.0, 1.0, 0.0, 0.0, 0.0, -1.0]),
        ("reach", [1.0, 0.0, 0.0, 0.0, -1.0, -1.0]),
    ],
)
def test_reward_readings_hand_placed(world, reading, expected):
    env = SparseCooperativeNavigation(N=3, world=world, reward=reading, max_cycles=6)
    env.reset(seed=0)
    env.place(AWAY, LANDMARKS)  # the start state (before the first step) has no landmark reached
    env.core.reached[:] = False
    plan = [
        ([LANDMARKS[0], *AWAY[1:]], None),
        ([LANDMARKS[0], *AWAY[1:]], None),
        (AWAY, None),
        head_on(True),
        head_on(True),
        head_on(False),
    ]
    rewards, collisions, reach_events = [], [], []
    for agents, velocities in plan:
        env.place(agents, velocities=velocities)
        _, step_rewards, _, truncations, infos = env.step(dict.fromkeys(env.agents, 0))
        assert len(set(step_rewards.values())) == 1
        rewards.append(step_rewards["agent_0"])
        collisions.append(infos["agent_0"]["collision"])
        reach_events.append(infos["agent_0"]["reached_landmarks"])
    assert rewards == expected
    assert collisions == [False, False, False, True, True, True]
    assert all(truncations.values())
    metrics = infos["agent_0"]["episode_metrics"]
    assert metrics["reach_events"] == sum(reach_events) == 2
    assert metrics["collision_steps"] == 3
    assert metrics["coverage_rate"] == 0.0 and metrics["success"] == 0.0
    assert metrics["coverage_over_steps"] == pytest.approx(4 / 6 / 3)


def test_collision_penalty_once_per_step_and_scaled():
    core = NavigationCore(2, N=3, world="mpe2", collision_penalty=0.5)
    core.reset_games()
    for game in range(2):  # three agents in a row, 0.1 apart: three overlapping pairs, far from the landmarks
        core.place(game, [[0.0, 0.0], [0.1, 0.0], [0.2, 0.0]], [[0.9, 0.9], [-0.9, 0.9], [0.9, -0.9]])
    result = core.step(np.zeros((2, 3), dtype=int))
    np.testing.assert_array_equal(result.rewards, [-0.5, -0.5])


# ----------------------------------------------------------------------------------- the native vec env's API
def test_native_vec_env_api():
    env = make_multiagent_vec_env(
        "cn-sparse-n3", n_games=2, seed=0, render_mode="rgb_array", mark_truncation=True, max_cycles=4
    )
    assert isinstance(env, MultiAgentVecEnv) and isinstance(env, NavigationVecEnv)
    assert not isinstance(env, MultiAgentDummyVecEnv)
    assert (env.n_agents, env.n_games, env.possible_agents) == (3, 2, ["agent_0", "agent_1", "agent_2"])
    assert env.game_of(4) == 1
    obs = env.reset()
    np.testing.assert_array_equal(env.get_state(), obs.reshape(2, -1))
    assert env.get_attr("world") == ["mpe"] * 6 and env.get_attr("reward", indices=[0]) == ["occupancy"]
    env.set_attr("cover_radius", 0.5, indices=[3])
    assert env.get_attr("cover_radius") == [0.1] * 3 + [0.5] * 3
    agents, _, _ = env.env_method("positions", indices=[3])[0]
    np.testing.assert_allclose(obs[3, 2:4], agents[0], atol=1e-6)
    frame = env.render()
    assert frame.shape == (400, 400, 3) and frame.dtype == np.uint8 and (frame != 255).any()
    assert env.env_method("render", indices=[0])[0].shape == frame.shape
    for _ in range(4):
        _, _, dones, infos = env.step(np.zeros(env.num_envs, dtype=int))
    assert dones.all() and dones.dtype == bool
    assert all(info["TimeLimit.truncated"] for info in infos)
    assert [slot for slot, info in enumerate(infos) if "episode" in info] == [0, 3]
    assert {"coverage_rate", "coverage_over_steps", "collision_steps", "success", "reach_events"} <= set(infos[0]["episode"])
    env.close()


@pytest.mark.parametrize("backend", ["native", "supersuit"])
def test_both_backends_are_multiagent_vec_envs_stepping_by_group(backend):
    """The native env and the SuperSuit-backed one implement MultiAgentVecEnv (the native one without subclassing
    MultiAgentDummyVecEnv); stepped as their one sampling group, they give the lockstep steps."""
    envs = [make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0, max_cycles=3, backend=backend) for _ in range(2)]
    assert all(isinstance(env, MultiAgentVecEnv) for env in envs)
    assert MultiAgentDummyVecEnv not in type(envs[0]).__mro__[1:]
    lockstep, grouped = envs
    np.testing.assert_array_equal(lockstep.reset(), grouped.reset())
    assert grouped.sampling_groups == [range(6)]
    actions = np.random.default_rng(0).integers(0, 5, size=(4, 6))
    for t in range(4):
        obs, rewards, dones, infos = lockstep.step(actions[t])
        grouped.step_group_async(0, actions[t])
        group, group_obs, group_dones = grouped.step_any_group_wait()
        assert group == 0 and grouped.n_staged_steps == 1
        np.testing.assert_array_equal(group_obs, obs)
        np.testing.assert_array_equal(group_dones, dones)
        got = grouped.step_wait()
        np.testing.assert_array_equal(got[1], rewards)
        assert [set(info) for info in got[3]] == [set(info) for info in infos]
    for env in envs:
        env.close()


def test_native_vec_env_trains_with_ppo():
    from stable_baselines3 import PPO

    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0, N=3, continuous_actions=True)
    model = PPO("MlpPolicy", env, n_steps=25, batch_size=50, n_epochs=1, seed=0, device="cpu").learn(150)
    assert model.num_timesteps == 150  # one rollout of 25 steps x 6 agent slots
    assert model.logger.name_to_value["train/n_updates"] == 1
    actions, _ = model.predict(env.reset(), deterministic=True)
    assert actions.shape == (env.num_envs, *env.action_space.shape)
    env.close()


# ------------------------------------------------------------------------------------------------ backend choice
def test_backend_choice():
    assert isinstance(make_multiagent_vec_env("cn-sparse-n4", n_games=1), NavigationVecEnv)
    assert isinstance(make_multiagent_vec_env(SparseCooperativeNavigation, n_games=1, N=2), NavigationVecEnv)
    supersuit = make_multiagent_vec_env("cn-sparse-n3", n_games=1, backend="supersuit", world="mpe2")
    assert type(supersuit) is MultiAgentDummyVecEnv
    assert supersuit.get_attr("world") == ["mpe2"] * 3
    # a callable without a native vec env, and worker processes, go through SuperSuit
    assert type(make_multiagent_vec_env(lambda: SparseCooperativeNavigation(N=2), n_games=1)) is MultiAgentDummyVecEnv
    assert get_native_vec_env_factory("grf-3v1-keeper") is None
    # the backend may travel with the task kwargs (configs' env_kwargs, the rl-zoo3 bridge): the game ignores it
    assert make_task("cn-sparse-n3", backend="supersuit", world="mpe2").world == "mpe2"


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"backend": "gpu"}, "backend must be one of"),
        ({"backend": "native", "num_cpus": 2}, "num_cpus"),
        ({"world": "mpe3"}, "world"),
        ({"reward": "dense"}, "reward"),
    ],
)
def test_bad_backend_and_options(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_multiagent_vec_env("cn-sparse-n3", n_games=2, **kwargs)


def test_native_backend_needs_a_native_task():
    with pytest.raises(ValueError, match="no native vec env"):
        make_multiagent_vec_env(lambda: SparseCooperativeNavigation(N=2), n_games=2, backend="native")
