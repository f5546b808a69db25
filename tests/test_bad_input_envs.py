"""Bad inputs of the envs and the multi-agent vec env (issue 24, part C): each is refused with one line naming the
argument, or warned about once."""

import warnings

import numpy as np
import pytest
from gymnasium import spaces
from pettingzoo.utils.env import ParallelEnv

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.common.vec_env import NonFiniteValueError
from sb3_saeir.envs.navigation import SparseCooperativeNavigation
from sb3_saeir.envs.navigation_vec_env import NavigationVecEnv


class FaultyEnv(ParallelEnv):
    """2 agents, 4 steps; ``fault`` picks what goes wrong at step 2 (or at the second reset)."""

    metadata = {"name": "faulty_v0"}  # noqa: RUF012

    def __init__(self, fault="none", action_space=None):
        self.possible_agents = ["agent_0", "agent_1"]
        self.agents = []
        self.fault = fault
        self._action_space = action_space or spaces.Discrete(2)
        self._t = 0
        self._resets = 0

    def observation_space(self, agent):
        return spaces.Box(-1.0, 1.0, (2,), np.float32)

    def action_space(self, agent):
        return self._action_space

    def _obs(self):
        obs = {a: np.zeros(2, np.float32) for a in self.possible_agents}
        if self._t == 2 and self.fault == "shape_changes":
            obs["agent_1"] = np.zeros(3, np.float32)
        if self._t == 2 and self.fault == "missing_obs":
            del obs["agent_1"]
        return obs

    def reset(self, seed=None, options=None):
        self._resets += 1
        self._t = 0
        if self.fault == "renamed" and self._resets > 1:
            self.possible_agents = ["player_0", "player_1"]
        if self.fault == "declared_shape":
            self.agents = list(self.possible_agents)
            return {a: np.zeros(5, np.float32) for a in self.agents}, {a: {} for a in self.agents}
        self.agents = list(self.possible_agents)
        return self._obs(), {a: {} for a in self.agents}

    def step(self, actions):
        self._t += 1
        reward = 1e30 if self.fault == "huge_reward" else 0.0
        rewards = dict.fromkeys(self.agents, reward)
        truncations = dict.fromkeys(self.agents, self._t >= 4)
        terminations = dict.fromkeys(self.agents, False)
        if self.fault == "one_terminated" and self._t == 2:
            terminations["agent_0"] = True
        infos = {a: {} for a in self.agents}
        obs = self._obs()
        if self._t >= 4:
            self.agents = []
        return obs, rewards, terminations, truncations, infos


def _one_line(excinfo, name):
    message = str(excinfo.value)
    assert "\n" not in message
    assert name in message
    return message


def _run(vec_env, steps=8):
    vec_env.reset()
    for _ in range(steps):
        vec_env.step(np.zeros(vec_env.num_envs, dtype=np.int64))


# ----------------------------------------------------------------------------- serious: non-finite navigation options
@pytest.mark.parametrize("builder", ["parallel", "native"])
@pytest.mark.parametrize(
    "name,value",
    [
        ("collision_penalty", float("inf")),
        ("cover_radius", float("inf")),
        ("collision_penalty", "1.0"),
    ],
)
def test_navigation_refuses_non_finite_options(builder, name, value):
    with pytest.raises(ValueError) as excinfo:
        if builder == "parallel":
            SparseCooperativeNavigation(**{name: value})
        else:
            make_multiagent_vec_env("cn-sparse-n3", n_games=2, **{name: value})
    _one_line(excinfo, name)


@pytest.mark.parametrize("name,value", [("collision_penalty", float("inf")), ("cover_radius", float("nan"))])
def test_navigation_refuses_non_finite_set_attr(name, value):
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2)
    with pytest.raises(ValueError) as excinfo:
        env.set_attr(name, value)
    _one_line(excinfo, name)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_native_env_checks_its_outputs():
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=2, seed=0)
    env.reset()
    env.core.positions[1, 0, 0] = np.nan  # a fault of the engine: it must not reach the learner
    with pytest.raises(NonFiniteValueError) as excinfo:
        env.step(np.zeros(env.num_envs, dtype=np.int64))
    message = _one_line(excinfo, "game 1")
    assert "agent_" in message and "step 1" in message


# ----------------------------------------------------------------------------- serious: string bools
@pytest.mark.parametrize(
    "build,name",
    [
        (lambda: SparseCooperativeNavigation(continuous_actions="no"), "continuous_actions"),
        (lambda: make_multiagent_vec_env("cn-sparse-n3", n_games=2, continuous_actions="no"), "continuous_actions"),
        (lambda: make_multiagent_vec_env("cn-sparse-n3", n_games=2, continuous_actions=0), "continuous_actions"),
        (lambda: make_multiagent_vec_env("cn-sparse-n3", n_games=2, mark_truncation="no"), "mark_truncation"),
        (lambda: make_multiagent_vec_env("cn-sparse-n3", n_games=2, check_finite="no"), "check_finite"),
        (lambda: NavigationVecEnv(2, mark_truncation="yes"), "mark_truncation"),
        (lambda: make_multiagent_vec_env(FaultyEnv, n_games=2, mark_truncation="no"), "mark_truncation"),
    ],
)
def test_string_bools_are_refused(build, name):
    with pytest.raises(TypeError) as excinfo:
        build()
    _one_line(excinfo, name)


# ----------------------------------------------------------------------------- silent acceptance: sizes and integers
@pytest.mark.parametrize(
    "kwargs,name",
    [
        ({"n_games": 2, "max_cycles": 2.5}, "max_cycles"),
        ({"n_games": 2, "max_cycles": "25"}, "max_cycles"),
        ({"n_games": 2, "max_cycles": 25.0}, "max_cycles"),
        ({"n_games": 2, "num_cpus": -1}, "num_cpus"),
        ({"n_games": 2, "num_cpus": 1.5}, "num_cpus"),
    ],
)
def test_bad_sizes_are_refused(kwargs, name):
    with pytest.raises(ValueError) as excinfo:
        make_multiagent_vec_env("cn-sparse-n3", **kwargs)
    _one_line(excinfo, name)


@pytest.mark.parametrize(
    "kwargs,name", [({"n_games": 2, "num_cpus": 0.5}, "num_cpus"), ({"n_games": 2, "num_cpus": "2"}, "num_cpus")]
)
def test_bad_sizes_are_refused_supersuit(kwargs, name):
    with pytest.raises(ValueError) as excinfo:
        make_multiagent_vec_env(FaultyEnv, **kwargs)
    _one_line(excinfo, name)


def test_max_cycles_set_attr_fractional():
    env = SparseCooperativeNavigation()
    with pytest.raises(ValueError) as excinfo:
        env.max_cycles = 2.5
    _one_line(excinfo, "max_cycles")


# ----------------------------------------------------------------------------- unbounded sizes
@pytest.mark.parametrize("kwargs", [{"N": 10**5, "n_games": 1}, {"N": 1000, "n_games": 10**6}])
def test_unbounded_sizes_are_refused(kwargs):
    with pytest.raises(MemoryError) as excinfo:
        make_multiagent_vec_env("cn-sparse-n3", **kwargs)
    message = _one_line(excinfo, "GiB")
    assert "N=" in message and "n_games=" in message


def test_large_size_that_fits_is_accepted():
    """A positive control (passes before the change too): N=50 is not refused."""
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=1, N=50, seed=0)
    obs = env.reset()
    assert obs.shape[0] == 50


# ----------------------------------------------------------------------------- raw library errors (SuperSuit path)
@pytest.mark.parametrize(
    "fault,words",
    [
        ("shape_changes", ["agent_1", "(3,)", "(2,)", "faulty_v0"]),
        ("declared_shape", ["agent_0", "(5,)", "(2,)", "faulty_v0"]),
        ("missing_obs", ["agent_1", "faulty_v0"]),
        ("renamed", ["player_0", "faulty_v0"]),
    ],
)
def test_raw_library_errors_name_the_agent(fault, words):
    with pytest.raises(ValueError) as excinfo:
        env = make_multiagent_vec_env(lambda: FaultyEnv(fault), n_games=2)
        _run(env)
    message = _one_line(excinfo, words[0])
    for word in words[1:]:
        assert word in message


# ----------------------------------------------------------------------------- env faults worth a warning / refusal
@pytest.mark.parametrize("fault,words", [("huge_reward", ["agent_0", "1e+30"]), ("one_terminated", ["agent_0"])])
def test_env_faults_warn_once(fault, words):
    env = make_multiagent_vec_env(lambda: FaultyEnv(fault), n_games=1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _run(env, steps=12)  # three episodes: one warning only
    ours = [w for w in caught if "faulty_v0" in str(w.message)]
    assert len(ours) == 1
    message = str(ours[0].message)
    assert "\n" not in message
    for word in words:
        assert word in message


def test_discrete_start_is_refused():
    with pytest.raises(ValueError) as excinfo:
        make_multiagent_vec_env(lambda: FaultyEnv(action_space=spaces.Discrete(3, start=1)), n_games=2)
    message = _one_line(excinfo, "Discrete(3")
    assert "start" in message
