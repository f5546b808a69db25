"""Bad inputs of the envs and the multi-agent vec env (issue 24, part C): each is refused with one line naming the
argument, or warned about once."""

import warnings

import numpy as np
import pytest
from gymnasium import spaces

from sb3_saeir import make_multiagent_vec_env
from sb3_saeir.common.vec_env import NonFiniteValueError
from sb3_saeir.envs.navigation import SparseCooperativeNavigation
from sb3_saeir.envs.navigation_vec_env import NavigationVecEnv
from tests.toy_envs import FaultyEnv, ReorderedMeetEnv, ToyMeetEnv


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


# ----------------------------------------------------------------------------- env faults named alike on both paths
ENV_FAULTS = [
    ("missing_reward", "no reward"),
    ("none_reward", "the reward is NoneType None, not a number"),
    ("string_reward", "the reward is str '1.0', not a number"),
    ("string_obs", "the observation is ndarray array(['0.5', '0.25']"),
    ("object_obs", "the observation is list [Decimal('0.5'), Decimal('0.25')]"),
    ("missing_obs", "no observation"),
    ("shape_changes", "an observation of shape (3,)"),
]


def _fault_message(fault, num_cpus):
    """The error of a :class:`FaultyEnv` fault in game 1 (of 2), with the games in this process or in 2 workers."""
    env = make_multiagent_vec_env(lambda: FaultyEnv(fault, faulty_seeds={1}), n_games=2, seed=0, num_cpus=num_cpus)
    try:
        with pytest.raises(ValueError) as excinfo:
            _run(env)
    finally:
        env.close()
    return str(excinfo.value)


@pytest.mark.parametrize("fault, words", ENV_FAULTS, ids=[fault for fault, _ in ENV_FAULTS])
def test_env_fault_named_alike_in_process_and_in_workers(fault, words):
    """A reward or observation the vec env cannot use is one line naming the env, the game, the agent and the step,
    the same text with the games in this process and in worker processes (issue 35)."""
    in_process = _fault_message(fault, num_cpus=0)
    assert "\n" not in in_process, in_process
    for word in ("faulty_v0: game 1, agent 1 (agent_1), step 2 of its episode", words):
        assert word in in_process, in_process
    assert _fault_message(fault, num_cpus=2) == in_process


def _every_game_faulty_message(fault, num_cpus, grouped):
    """The error of a :class:`FaultyEnv` fault in every game (of 2), with the games in this process or in 2 workers,
    stepped all at once or group by group as double-buffered sampling steps them (one group in this process, one per
    worker)."""
    env = make_multiagent_vec_env(lambda: FaultyEnv(fault), n_games=2, seed=0, num_cpus=num_cpus)
    try:
        env.reset()
        with pytest.raises(ValueError) as excinfo:
            for _ in range(8):
                if not grouped:
                    env.step(np.zeros(env.num_envs, dtype=np.int64))
                    continue
                for group, slots in enumerate(env.sampling_groups):  # one group in flight at a time: game 0 first
                    env.step_group_async(group, np.zeros(len(slots), dtype=np.int64))
                    env.step_any_group_wait()
                env.step_wait()
    finally:
        env.close()
    return str(excinfo.value)


@pytest.mark.parametrize("grouped", [False, True], ids=["lockstep", "grouped"])
def test_non_finite_observations_of_every_game_are_counted_alike_in_process_and_in_workers(grouped):
    """A NaN observation in every game: the count was of the games checked together, 2 in this process and 1 in each
    worker's group (issue 55); it is the named game's on every backend."""
    in_process = _every_game_faulty_message("nan_obs", num_cpus=0, grouped=grouped)
    assert "\n" not in in_process, in_process
    assert "faulty_v0: game 0, agent 1 (agent_1): observation has nan at entry 0 at step 2" in in_process, in_process
    assert "(1 observations and 0 rewards of this game's step are not finite)" in in_process, in_process
    assert _every_game_faulty_message("nan_obs", num_cpus=2, grouped=grouped) == in_process


class DtypeEnv(FaultyEnv):
    """:class:`FaultyEnv` whose observation space declares ``declared`` observations; at step 2 of the games reset
    with a seed in ``faulty_seeds``, agent_1's observation is of dtype ``returned`` (0.5 for floats, else 1)."""

    def __init__(self, declared, returned, faulty_seeds=None):
        super().__init__("dtype", faulty_seeds=faulty_seeds)
        self.declared, self.returned = np.dtype(declared), np.dtype(returned)

    def observation_space(self, agent):
        return spaces.Box(-1, 1, (2,), self.declared)

    def _obs(self):
        obs = {a: np.zeros(2, self.declared) for a in self.possible_agents}
        if self._now("dtype"):
            obs["agent_1"] = np.full(2, 0.5 if self.returned.kind == "f" else 1, self.returned)
        return obs


def _dtype_run(declared, returned, num_cpus):
    """The observations of 3 steps of 2 :class:`DtypeEnv` games (game 1 faulty), or the error they end in."""
    env = make_multiagent_vec_env(lambda: DtypeEnv(declared, returned, faulty_seeds={1}), n_games=2, seed=0, num_cpus=num_cpus)
    try:
        env.reset()
        return [env.step(np.zeros(env.num_envs, dtype=np.int64))[0] for _ in range(3)]
    except Exception as error:  # compared across the two paths
        return error
    finally:
        env.close()


@pytest.mark.parametrize("declared, returned", [("int64", "float64"), ("int64", "float32"), ("int32", "float16")])
def test_observation_dtype_that_does_not_cast_is_named_alike_on_both_paths(declared, returned):
    """Floats for an integer observation space: in this process gymnasium's ``concatenate`` raised NumPy's raw cast
    error (a ``TypeError``), in workers the floats were truncated to 0 without a word (issue 55)."""
    in_process, in_workers = _dtype_run(declared, returned, 0), _dtype_run(declared, returned, 2)
    assert isinstance(in_process, ValueError), in_process
    message = str(in_process)
    assert "\n" not in message, message
    for words in (
        "faulty_v0: game 1, agent 1 (agent_1), step 2 of its episode",
        f"an observation of dtype {returned}, its observation space declares {declared}",
        f"declare dtype={returned}",
    ):
        assert words in message, message
    assert isinstance(in_workers, ValueError) and str(in_workers) == message


@pytest.mark.parametrize(
    "declared, returned", [("float32", "float64"), ("float32", "int64"), ("int64", "int32"), ("float32", "bool")]
)
def test_observation_dtype_that_casts_is_accepted_alike(declared, returned):
    """A positive control: what NumPy casts by its same_kind rule (float64 for float32, integers for floats) passes on
    both paths, with the same values."""
    in_process, in_workers = _dtype_run(declared, returned, 0), _dtype_run(declared, returned, 2)
    assert not isinstance(in_process, Exception), in_process
    np.testing.assert_array_equal(np.stack(in_workers), np.stack(in_process))
    assert np.stack(in_process)[1, 3].tolist() == ([0.5, 0.5] if returned.startswith("float") else [1, 1])


@pytest.mark.parametrize("num_cpus", [0, 2])
def test_agents_listed_in_another_order_take_the_order_of_possible_agents(num_cpus):
    """A game listing its agents in reverse order steps as the same game listing them in possible_agents order."""
    reordered = make_multiagent_vec_env(ReorderedMeetEnv, n_games=2, seed=0, num_cpus=num_cpus)
    reference = make_multiagent_vec_env(ToyMeetEnv, n_games=2, seed=0)
    np.testing.assert_array_equal(reordered.reset(), reference.reset())
    for actions in np.random.default_rng(0).integers(0, 3, size=(14, reference.num_envs)):  # past two episode ends
        for got, expected in zip(reordered.step(actions)[:3], reference.step(actions)[:3]):
            np.testing.assert_array_equal(got, expected)
    reordered.close()
    reference.close()


# ----------------------------------------------------------------------------- a closed env
CLOSED_ENVS = {"navigation": ("cn-sparse-n3", 0), "in-process": (ToyMeetEnv, 0), "workers": (ToyMeetEnv, 2)}


@pytest.mark.parametrize("backend", sorted(CLOSED_ENVS))
def test_a_closed_env_refuses_to_reset_step_and_train(backend, tiny_kwargs):
    """In this process a closed env went on stepping its games (``learn`` trained on it without a word); the worker
    backend refused. Every backend refuses alike now."""
    from sb3_saeir import MAPPO

    task, num_cpus = CLOSED_ENVS[backend]
    env = make_multiagent_vec_env(task, n_games=2, seed=0, num_cpus=num_cpus)
    model = MAPPO("MAPPOPolicy", env, **tiny_kwargs)
    env.close()
    calls = [env.reset, lambda: env.step(np.zeros(env.num_envs, dtype=np.int64)), lambda: model.learn(60)]
    for call in calls:
        with pytest.raises(RuntimeError) as excinfo:
            call()
        message = _one_line(excinfo, "The games are closed (by close()): create a new env to go on.")
        assert message == "The games are closed (by close()): create a new env to go on."


# ----------------------------------------------------------------------------- seeds of the vec env
SEED_TASKS = {"native": "cn-sparse-n3", "supersuit": ToyMeetEnv}
BAD_SEEDS = ["abc", -1, 2.5, 2**32, True]


@pytest.mark.parametrize("task", sorted(SEED_TASKS))
@pytest.mark.parametrize("seed", BAD_SEEDS, ids=[repr(seed) for seed in BAD_SEEDS])
def test_bad_seed_of_make_multiagent_vec_env(task, seed):
    with pytest.raises(ValueError) as excinfo:
        make_multiagent_vec_env(SEED_TASKS[task], n_games=2, seed=seed).reset()
    _one_line(excinfo, f"make_multiagent_vec_env: seed={seed!r} is not a seed")


@pytest.mark.parametrize("task", sorted(SEED_TASKS))
@pytest.mark.parametrize("call", ["seed", "reset"])
def test_bad_seed_of_a_built_env_leaves_it_usable(task, call):
    env = make_multiagent_vec_env(SEED_TASKS[task], n_games=2, seed=0)
    first = env.reset()
    with pytest.raises(ValueError) as excinfo:
        env.seed(-3) if call == "seed" else env.reset(seed=-3)
    _one_line(excinfo, "seed=-3 is not a seed")
    np.testing.assert_array_equal(env.reset(seed=0), first)
    env.close()


@pytest.mark.parametrize("task", sorted(SEED_TASKS))
def test_numpy_integer_seed_of_the_vec_env(task):
    """A positive control: NumPy integer seeds give the run of the same Python integer."""
    expected = make_multiagent_vec_env(SEED_TASKS[task], n_games=2, seed=5).reset()
    np.testing.assert_array_equal(make_multiagent_vec_env(SEED_TASKS[task], n_games=2, seed=np.int64(5)).reset(), expected)
    np.testing.assert_array_equal(make_multiagent_vec_env(SEED_TASKS[task], n_games=2).reset(seed=np.uint32(5)), expected)


# ----------------------------------------------------------------------------- worker processes
@pytest.mark.parametrize("cores, num_cpus, n_games", [(1, 2, 2), (2, 4, 3)])
def test_more_workers_than_cores_warns(monkeypatch, cores, num_cpus, n_games):
    import sb3_saeir.common.vec_env.factory as vec_env_module

    monkeypatch.setattr(vec_env_module, "usable_cores", lambda: cores)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = make_multiagent_vec_env(ToyMeetEnv, n_games=n_games, num_cpus=num_cpus)
    env.close()
    ours = [str(w.message) for w in caught if "num_cpus=" in str(w.message)]
    assert len(ours) == 1 and "\n" not in ours[0], ours
    assert f"num_cpus={num_cpus} starts {min(num_cpus, n_games)} env worker processes" in ours[0]
    assert f"{cores} core(s)" in ours[0]


UNGUARDED_SCRIPTS = {
    "forkserver": (
        "from sb3_saeir import make_multiagent_vec_env\n"
        "from tests.toy_envs import ToyMeetEnv\n"
        "env = make_multiagent_vec_env(ToyMeetEnv, n_games=2, num_cpus=2)\n"
    ),
    "spawn": (
        "from gymnasium import spaces\n"
        "import numpy as np\n"
        "from sb3_saeir.common.vec_env.workers import GameWorkerPool\n"
        "from tests.toy_envs import ToyMeetEnv\n"
        "box = spaces.Box(0.0, 1.0, (2,), np.float32)\n"
        "pool = GameWorkerPool(ToyMeetEnv, 2, 2, 3, box, spaces.Discrete(3), start_method='spawn')\n"
    ),
}


@pytest.mark.parametrize("start_method", sorted(UNGUARDED_SCRIPTS))
def test_script_without_main_guard_is_told_first_in_one_line(tmp_path, start_method):
    """Workers import the main script again: without the guard, one line says so (before: one multiprocessing
    traceback per worker, then the advice)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    script = tmp_path / "unguarded.py"
    script.write_text(UNGUARDED_SCRIPTS[start_method])
    root = str(Path(__file__).resolve().parent.parent)
    environment = {**os.environ, "PYTHONPATH": root, "OMP_NUM_THREADS": "1"}
    result = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, env=environment, cwd=tmp_path, timeout=300
    )
    assert result.returncode != 0
    assert result.stderr.count("Traceback") == 1 and "bootstrapping phase" not in result.stderr, result.stderr[-3000:]
    last = result.stderr.strip().splitlines()[-1]
    assert str(script) in last and 'if __name__ == "__main__":' in last and start_method in last, last


# ----------------------------------------------------------------------------- football options
FOOTBALL_REWARDS = ["checkpoint", "scoring,goals", "", "checkpoints", 1]


@pytest.mark.parametrize("build", ["class", "task"])
@pytest.mark.parametrize("rewards", FOOTBALL_REWARDS, ids=[repr(r) for r in FOOTBALL_REWARDS])
def test_football_rewards_checked_before_gfootball(monkeypatch, build, rewards):
    """gfootball's own check is an AssertionError without a message; the value is checked first (no gfootball
    needed: the import is replaced by a failure)."""
    import sb3_saeir.envs.football as football

    monkeypatch.setattr(football, "import_gfootball", lambda: pytest.fail("gfootball imported before the check"))
    with pytest.raises(ValueError) as excinfo:
        if build == "class":
            football.FootballEnv(rewards=rewards)
        else:
            make_multiagent_vec_env("grf-3v1-keeper", n_games=1, rewards=rewards)
    message = _one_line(excinfo, f"rewards={rewards!r}")
    assert "'scoring,checkpoints'" in message


@pytest.mark.parametrize(
    "task, kwargs, constructor, takes",
    [
        ("cn-sparse-n3", {"radius": 0.2}, "SparseCooperativeNavigation", "N, max_cycles"),  # the native vec env's path
        ("cn-sparse-n3", {"radius": 0.2, "backend": "supersuit"}, "SparseCooperativeNavigation", "cover_radius"),
        ("cn-sparse-n3", {"radius": 0.2, "num_cpus": 2}, "SparseCooperativeNavigation", "world, reward"),  # workers
        (ToyMeetEnv, {"n_agent": 2}, "ToyMeetEnv", "n_agents, max_cycles"),  # a user's constructor
    ],
    ids=["native", "supersuit", "workers", "callable"],
)
def test_a_task_argument_the_constructor_does_not_take_is_named_with_those_it_takes(task, kwargs, constructor, takes):
    """The constructor's TypeError named the keyword but not the ones it takes, and in env workers it came from
    another process; it is now one line, before any game is built."""
    with pytest.raises(ValueError) as excinfo:
        make_multiagent_vec_env(task, n_games=2, **kwargs)
    unknown = next(key for key in kwargs if key not in ("backend", "num_cpus"))
    message = _one_line(excinfo, f"{unknown!r} is not an argument of the task's constructor {constructor}; it takes: ")
    assert takes in message


def test_a_constructor_that_takes_any_keyword_gets_them_unchecked():
    """A constructor with ``**kwargs`` checks its own keywords: they pass through as before."""
    seen = {}

    def build(**kwargs):
        seen.update(kwargs)
        return ToyMeetEnv(n_agents=kwargs.get("n_agents", 3))

    env = make_multiagent_vec_env(build, n_games=2, n_agents=2, anything=1)
    assert env.n_agents == 2 and seen == {"n_agents": 2, "anything": 1}
    env.close()


# ------------------------------------------------------------- what reset and step return, against PettingZoo's API
class OffApiMeetEnv(ToyMeetEnv):
    """:class:`ToyMeetEnv` whose reset or step returns something PettingZoo's parallel API does not: ``fault`` is
    ``obs_only_reset`` (the API before 1.22), ``none_infos_reset``, ``empty_infos_step`` or ``array_reward``."""

    def __init__(self, fault, n_agents=3):
        super().__init__(n_agents=n_agents)
        self.fault = fault

    def reset(self, seed=None, options=None):
        observations, infos = super().reset(seed=seed, options=options)
        if self.fault == "obs_only_reset":
            return observations
        if self.fault == "none_infos_reset":
            return observations, None
        return observations, infos

    def step(self, actions):
        observations, rewards, terminations, truncations, infos = super().step(actions)
        if self.fault == "empty_infos_step":
            infos = {}
        if self.fault == "termination_missing":
            del terminations["agent_1"]
        if self.fault == "truncation_missing":
            del truncations["agent_2"]
        if self.fault == "termination_none":
            terminations["agent_0"] = None
        if self.fault == "truncation_text":
            truncations["agent_0"] = "False"
        if self.fault == "info_none":
            infos["agent_0"] = None
        if self.fault == "array_reward":
            rewards = {agent: np.array([0.25]) for agent in rewards}  # one value whatever the unseeded game does
        return observations, rewards, terminations, truncations, infos


@pytest.mark.parametrize("n_agents", [1, 2, 3])
@pytest.mark.parametrize("num_cpus", [0, 2])
def test_a_reset_without_infos_is_named_for_every_agent_count(n_agents, num_cpus):
    """The API before PettingZoo 1.22 (observations alone) gave three raw errors, by the number of agents."""
    with pytest.raises(ValueError) as excinfo:
        _run(make_multiagent_vec_env(lambda: OffApiMeetEnv("obs_only_reset", n_agents), n_games=2, num_cpus=num_cpus))
    message = _one_line(excinfo, "toy_meet_v0: game 0, reset")
    assert "reset returned a dict (observations alone" in message and "(observations, infos)" in message


@pytest.mark.parametrize(
    "fault, expected",
    [
        ("none_infos_reset", "reset returned infos = NoneType None; PettingZoo's parallel API returns (observations, infos)"),
        ("empty_infos_step", "agent 0 (agent_0), step 1 of its episode: no info; step must return an info dict"),
        ("array_reward", "agent 0 (agent_0), step 1 of its episode: the reward is ndarray array([0.25]), not a number"),
    ],
)
def test_off_api_returns_are_named_in_one_line(fault, expected):
    with pytest.raises(ValueError) as excinfo:
        _run(make_multiagent_vec_env(lambda: OffApiMeetEnv(fault), n_games=2))
    assert expected in _one_line(excinfo, "toy_meet_v0: game 0")


# ------------------------------------------------------------- round 6: the flags and infos of a step, the agents' names
@pytest.mark.parametrize("num_cpus", [0, 2])
@pytest.mark.parametrize(
    "fault, expected",
    [
        ("termination_missing", "agent 1 (agent_1), step 1 of its episode: no entry in terminations"),
        ("truncation_missing", "agent 2 (agent_2), step 1 of its episode: no entry in truncations"),
        ("termination_none", "agent 0 (agent_0), step 1 of its episode: terminations holds NoneType None; a flag is"),
        ("truncation_text", "agent 0 (agent_0), step 1 of its episode: truncations holds str 'False'; a flag is"),
        ("info_none", "agent 0 (agent_0), step 1 of its episode: the info is NoneType None; step must return an info"),
    ],
)
def test_step_flags_and_infos_are_checked_alike_in_process_and_in_workers(fault, expected, num_cpus):
    """A missing flag raised SuperSuit's broadcast error in this process and trained silently in worker processes;
    ``None`` or ``"False"`` raised ``int()``'s error; a ``None`` info, two other raw errors."""
    env = make_multiagent_vec_env(lambda: OffApiMeetEnv(fault), n_games=2, num_cpus=num_cpus)
    try:
        with pytest.raises(ValueError) as excinfo:
            _run(env)
        assert expected in _one_line(excinfo, "toy_meet_v0: game 0")
    finally:
        env.close()


class TupleAgentsMeetEnv(ToyMeetEnv):
    def __init__(self):
        super().__init__()
        self.possible_agents = tuple(self.possible_agents)


class TwinNamesMeetEnv(ToyMeetEnv):
    def __init__(self):
        super().__init__()
        self.possible_agents = ["agent_0", "agent_0", "agent_2"]


class NoSeedMeetEnv(ToyMeetEnv):
    def reset(self):
        return super().reset()


@pytest.mark.parametrize(
    "env_fn, expected",
    [
        (TupleAgentsMeetEnv, "TupleAgentsMeetEnv.possible_agents is tuple ('agent_0', 'agent_1', 'agent_2'); PettingZoo's"),
        (TwinNamesMeetEnv, "TwinNamesMeetEnv.possible_agents names ['agent_0'] more than once"),
        (NoSeedMeetEnv, "NoSeedMeetEnv.reset takes no seed or options; PettingZoo's parallel API is reset(self, seed=None"),
    ],
)
def test_agents_names_and_reset_keywords_are_checked_when_the_env_is_made(env_fn, expected):
    """A tuple gave SuperSuit's message on agents that die; twin names trained two slots on one agent's data; a reset
    without seed gave Python's TypeError."""
    with pytest.raises((TypeError, ValueError)) as excinfo:
        make_multiagent_vec_env(env_fn, n_games=2)
    assert expected in _one_line(excinfo, "possible_agents" if env_fn is not NoSeedMeetEnv else "reset")


@pytest.mark.parametrize("task", ["cn-sparse-n3", ToyMeetEnv])
@pytest.mark.parametrize(
    "actions, expected",
    [
        (np.zeros(5, dtype=np.int64), "step: actions for 5 slots; the env has 6 slots (2 games x 3 agents)"),
        (np.array([0, 0, 0, 0, 0, -1]), "step: slot 5 (game 1, agent 2) got the action np.int64(-1), outside"),
        (np.array([0, 0, 7, 0, 0, 0]), "step: slot 2 (game 0, agent 2) got the action np.int64(7), outside"),
        (np.array([0, 1.7, 0, 0, 0, 0]), "step: slot 1 (game 0, agent 1) got the action np.float64(1.7), outside"),
    ],
)
def test_step_actions_are_one_per_slot_and_in_the_action_space(task, actions, expected):
    """A wrong count was a raw reshape or SuperSuit error; -1, 7 and 1.7 reached the games (-1 moved the native
    navigation's agents)."""
    env = make_multiagent_vec_env(task, n_games=2, seed=0)
    env.reset()
    with pytest.raises(ValueError) as excinfo:
        env.step(actions)
    assert expected in _one_line(excinfo, "step")
    env.step(np.zeros(6))  # whole numbers as floats: taken (SuperSuit's cast refused them)
    env.close()
