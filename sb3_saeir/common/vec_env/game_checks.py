"""What one game may return, and the one-line errors for what it may not.

:class:`CheckedParallelEnv` wraps every game the PettingZoo backends step (in this process and in the workers alike);
the functions check a game before it is vectorized, the options of
:func:`~sb3_saeir.common.vec_env.make_multiagent_vec_env`, and the NaN/inf of a step. Every error names the env, the
game, the agent and the step of its episode (``docs/guide/custom_env.md``).
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo.utils.env import AECEnv, ParallelEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper

from sb3_saeir.common.utils import check_bool

ParallelEnvFactory = Callable[..., ParallelEnv]

# dtype kinds of the numbers a game may return as observations and rewards: bool, signed, unsigned, float
NUMBER_KINDS = "biuf"

# Rewards of this magnitude or more get a warning: the value loss squares value errors of this size in float32, whose
# largest value is 3.4e38, so a reward of 1e19 already gives inf losses; 1e18 leaves one order of margin.
HUGE_REWARD = 1e18


# The parts of what a parallel env's reset and step return (PettingZoo 1.22 and later).
RESET_PARTS = ("observations", "infos")
STEP_PARTS = ("observations", "rewards", "terminations", "truncations", "infos")


class GameFaultError(ValueError):
    """A game returned something the vec env cannot use (a missing reward, an observation that is not numbers, ...).

    The message names the env, the game, the agent and the step of its episode. Raised by :class:`CheckedParallelEnv`
    around each game, and re-raised as it is when the game runs in a worker process, so both backends give the same
    error.
    """


class AgentDeathError(GameFaultError, RuntimeError):
    """Raised when agents of a game leave it before the game ends (wrap the game with
    :func:`~sb3_saeir.common.vec_env.black_death`)."""


class CheckedParallelEnv(BaseParallelWrapper):
    """Parallel-env wrapper that checks what one game returns, the same way in this process and in the env workers.

    Every agent must be there in every step (SuperSuit's ``MarkovVectorEnv`` needs it; an env whose agents can die is
    wrapped with :func:`~sb3_saeir.common.vec_env.black_death` first, else :class:`AgentDeathError`). A missing or
    non-numeric observation or reward, or an observation of another shape or dtype than declared, is refused with a
    :class:`GameFaultError` naming the env, the game, the agent and the step of its episode; a huge reward and agents
    done while others continue are warned about once. ``agents`` are given in ``possible_agents`` order whatever order
    the game lists them in.

    :param env: the wrapped parallel env
    :param game_index: the game's index in its vec env (for the messages)
    """

    def __getattr__(self, name: str) -> Any:
        if name == "env":  # not yet set (e.g. while unpickling): avoid infinite recursion
            raise AttributeError(name)
        return super().__getattr__(name)

    def __init__(self, env: ParallelEnv, game_index: int = 0) -> None:
        super().__init__(env)
        self._agent_names = list(env.possible_agents)  # as vectorized: SuperSuit keeps the first names
        self._agent_set = set(self._agent_names)
        self._warned: set[str] = set()
        self._declared: dict[Any, spaces.Space] = {}  # each agent's observation space, asked once
        self.game_index = game_index
        self.episode_step = 0  # steps since the last reset

    @property
    def agents(self) -> list:
        """The game's live agents in ``possible_agents`` order (the slot order), whatever order the game uses."""
        live = self.env.agents
        if live == self._agent_names:
            return live
        present = set(live)
        return [agent for agent in self._agent_names if agent in present]

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        self.episode_step = 0
        observations, infos = self._check_returned(self.env.reset(seed=seed, options=options), RESET_PARTS)
        self._check_observations(observations)
        return observations, infos

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        self.episode_step += 1
        returned = self._check_returned(self.env.step(actions), STEP_PARTS)
        observations, rewards, terminations, truncations, infos = returned
        remaining = set(self.env.agents)
        if remaining and remaining != set(self.env.possible_agents):
            missing = sorted(set(self.env.possible_agents) - remaining)
            raise AgentDeathError(
                f"{self._where()}: agents {missing} left the game before it ended. make_multiagent_vec_env needs every "
                "agent in every step: wrap the parallel env with sb3_saeir.common.vec_env.black_death(env) so that "
                "finished agents receive zero observations and rewards until the game ends."
            )
        self._check_observations(observations)
        values = self._check_rewards(rewards)
        self._warn_faults(values, terminations, truncations)
        return observations, rewards, terminations, truncations, infos

    def _check_returned(self, returned: Any, parts: tuple[str, ...]) -> tuple:
        """What ``reset`` or ``step`` returned, as PettingZoo's parallel API has it (a tuple of ``parts``, each a
        dict), or one line naming the env, the game, the call and what it must return: the API before PettingZoo 1.22
        returned ``reset``'s observations alone, which unpacked into other raw errors for each number of agents.

        :param returned: the call's result
        :param parts: the names of the tuple's parts (:data:`RESET_PARTS`, :data:`STEP_PARTS`)
        """
        call = "reset" if parts is RESET_PARTS else "step"
        shape = f"({', '.join(parts)}), each a dict keyed by agent"
        if not isinstance(returned, tuple) or len(returned) != len(parts):
            got = (
                "a dict (observations alone: the PettingZoo API before 1.22?)"
                if isinstance(returned, dict)
                else _describe(returned)
            )
            raise GameFaultError(f"{self._where()}: {call} returned {got}; PettingZoo's parallel API returns {shape}.")
        for name, part in zip(parts, returned):
            if not isinstance(part, dict):
                raise GameFaultError(
                    f"{self._where()}: {call} returned {name} = {_describe(part)}; PettingZoo's parallel API returns {shape}."
                )
        if call == "step":
            self._check_step_flags(returned[2], returned[3], returned[4])
        return returned

    def _check_step_flags(self, terminations: dict, truncations: dict, infos: dict) -> None:
        """Every agent of ``possible_agents`` has its termination and truncation flag (a bool, or 0 / 1) and its info
        dict after a step: SuperSuit reads them all (a raw ``KeyError``, ``int()`` or broadcast error in this
        process, while the worker processes went on)."""
        for name, flags in (("terminations", terminations), ("truncations", truncations)):
            for agent in self._agent_names:
                if agent not in flags:
                    raise GameFaultError(
                        f"{self._where(agent)}: no entry in {name}; step must return a flag for every agent of "
                        "possible_agents (False while the agent plays on)."
                    )
                flag = flags[agent]
                if not isinstance(flag, (bool, np.bool_, int, np.integer)) or flag not in (0, 1):
                    raise GameFaultError(f"{self._where(agent)}: {name} holds {_describe(flag)}; a flag is True or False.")
        for agent in self._agent_names:
            if not isinstance(infos.get(agent), dict):
                got = "no info" if agent not in infos else f"the info is {_describe(infos[agent])}"
                raise GameFaultError(
                    f"{self._where(agent)}: {got}; step must return an info dict for every agent of possible_agents "
                    "({} when there is nothing to say)."
                )

    def _game_name(self) -> str:
        return str((getattr(self.env, "metadata", None) or {}).get("name") or type(self.env.unwrapped).__name__)

    def _where(self, agent: str | None = None) -> str:
        """``"<env>: game <g>, agent <i> (<name>), step <t> of its episode"`` (``reset`` for a reset)."""
        when = f"step {self.episode_step} of its episode" if self.episode_step else "reset"
        if agent is None:
            return f"{self._game_name()}: game {self.game_index}, {when}"
        index = self._agent_names.index(agent) if agent in self._agent_names else "?"
        return f"{self._game_name()}: game {self.game_index}, agent {index} ({agent}), {when}"

    def _declared_space(self, agent: Any) -> spaces.Space:
        """The agent's observation space, asked of the game once: PettingZoo's API has it fixed per agent, and an env
        that builds a new space at every call would pay for it at every step of every agent."""
        declared = self._declared.get(agent)
        if declared is None:
            declared = self._declared[agent] = self.env.observation_space(agent)
        return declared

    def _check_observations(self, observations: dict) -> None:
        """Raise one line naming the env, game, agent and step when an observation is missing, unknown, not made of
        numbers (a string, ``None``, an object), of another shape than the declared observation space, or of a dtype
        that does not cast to the declared one by NumPy's ``same_kind`` rule (floats for an integer space). That rule
        is the one of gymnasium's ``concatenate`` on the in-process path (which raised NumPy's raw cast error), so the
        check refuses nothing that path took; in the workers the shared array's assignment truncated such floats
        without a word, and the same check refuses them there too."""
        possible = self._agent_names
        if observations.keys() != self._agent_set:
            unknown = sorted(set(observations) - self._agent_set, key=str)
            if unknown:
                raise GameFaultError(
                    f"{self._where()}: observations of agents {unknown} not in the game's first possible_agents "
                    f"{possible} (agents renamed?); keep the agent names in every reset and step."
                )
            agent = next(agent for agent in possible if agent not in observations)
            raise GameFaultError(
                f"{self._where(agent)}: no observation; every agent of possible_agents needs one in every reset and "
                "step (sb3_saeir.common.vec_env.black_death for finished agents)."
            )
        for agent in possible:
            observation = np.asarray(observations[agent])
            if observation.dtype.kind not in NUMBER_KINDS:
                raise GameFaultError(
                    f"{self._where(agent)}: the observation is {_describe(observations[agent])}, not numbers; return "
                    f"a numeric array as the observation space declares ({self._declared_space(agent)})."
                )
            declared = self._declared_space(agent)
            expected = declared.shape
            if expected is not None and observation.shape != tuple(expected):
                raise GameFaultError(
                    f"{self._where(agent)}: an observation of shape {observation.shape}, its observation space "
                    f"declares {tuple(expected)}; return observations of the declared shape."
                )
            dtype = declared.dtype
            if dtype is not None and observation.dtype != dtype and not np.can_cast(observation.dtype, dtype, "same_kind"):
                raise GameFaultError(
                    f"{self._where(agent)}: an observation of dtype {observation.dtype}, its observation space declares "
                    f"{dtype}, which {observation.dtype} does not cast to (NumPy's same_kind rule); return observations "
                    f"of the declared dtype, or declare dtype={observation.dtype} in the observation space."
                )

    def _check_rewards(self, rewards: dict) -> np.ndarray:
        """The agents' rewards in ``possible_agents`` order as an array, or one line naming the env, game, agent and
        step of a reward that is missing or not a number (``None``, a string)."""
        possible = self._agent_names
        try:
            values = np.asarray([rewards[agent] for agent in possible])
        except KeyError as error:
            raise GameFaultError(
                f"{self._where(error.args[0])}: no reward; every agent of possible_agents needs one in every step "
                "(0.0 when it earned nothing; sb3_saeir.common.vec_env.black_death for finished agents)."
            ) from None
        if values.dtype.kind not in NUMBER_KINDS or values.shape != (len(possible),):
            for agent in possible:
                value = np.asarray(rewards[agent])
                if value.dtype.kind not in NUMBER_KINDS or value.shape != ():
                    raise GameFaultError(
                        f"{self._where(agent)}: the reward is {_describe(rewards[agent])}, not a number; return a "
                        "float (0.0 when the agent earned nothing)."
                    )
        return values

    def _warn_faults(self, rewards: np.ndarray, terminations: dict, truncations: dict) -> None:
        """Warn once per game instance about rewards of huge magnitude and agents terminated while others continue.

        :param rewards: the agents' rewards in ``possible_agents`` order (checked: numbers)
        """
        warned = self._warned
        if "reward" not in warned:
            values = rewards.astype(np.float64).reshape(-1)
            huge = np.isfinite(values) & (np.abs(values) >= HUGE_REWARD)
            if huge.any():
                warned.add("reward")
                agent = self._agent_names[int(np.flatnonzero(huge)[0])]
                warnings.warn(
                    f"{self._game_name()}: agent {agent!r} received a reward of {values[huge][0]:.3g} (|r| >= "
                    f"{HUGE_REWARD:.0e}); returns and advantages overflow float32: scale the rewards down.",
                    stacklevel=2,
                )
        if "termination" not in warned:
            done = {agent for agent in terminations if terminations[agent] or truncations.get(agent, False)}
            if done and done != set(terminations):
                warned.add("termination")
                warnings.warn(
                    f"{self._game_name()}: agents {sorted(done, key=str)} are done while others continue; "
                    "the game's slots are reset together only when every agent is done, so a done agent's slot "
                    "keeps stepping: end all agents of a game together (or wrap the game with "
                    "sb3_saeir.common.vec_env.black_death).",
                    stacklevel=2,
                )


def _describe(value: Any) -> str:
    """A short description of a value a game returned, for the messages: its type and a clipped ``repr``."""
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 40 else text[:37] + '...'}"


def checked_game(game: ParallelEnv) -> CheckedParallelEnv:
    """One game as the vec envs step it: with a ``render_mode`` (optional in PettingZoo, required by SuperSuit) and
    wrapped in :class:`CheckedParallelEnv`."""
    if not hasattr(game.unwrapped, "render_mode"):
        game.unwrapped.render_mode = None
    return CheckedParallelEnv(game)


class CheckedGameFactory:
    """Picklable factory of one game as the vec envs step it, ``checked_game(env_fn())`` (for the worker processes).

    :param env_fn: callable returning one PettingZoo ``ParallelEnv``
    """

    def __init__(self, env_fn: ParallelEnvFactory) -> None:
        self.env_fn = env_fn

    def __call__(self) -> ParallelEnv:
        return checked_game(self.env_fn())


def check_parallel_env(par_env: Any) -> None:
    """Check that ``par_env`` can be vectorized with one slot per agent and parameter sharing.

    :param par_env: an instance returned by the task factory
    :raises TypeError: for an AEC env or anything that is not a PettingZoo ``ParallelEnv``
    :raises ValueError: when agents have different observation or action spaces
    """
    if isinstance(par_env, AECEnv):
        raise TypeError(
            f"Got a PettingZoo AEC env ({type(par_env).__name__}); make_multiagent_vec_env needs a ParallelEnv. "
            "Convert it with `from pettingzoo.utils.conversions import aec_to_parallel; env = aec_to_parallel(env)` "
            "or use the module's `parallel_env()` constructor."
        )
    if not isinstance(par_env, ParallelEnv) and not (hasattr(par_env, "possible_agents") and hasattr(par_env, "step")):
        raise TypeError(
            f"Expected a PettingZoo ParallelEnv, got {type(par_env).__name__}. For a single-agent gymnasium env use "
            "stable_baselines3.common.env_util.make_vec_env instead."
        )
    if not isinstance(par_env.possible_agents, list):
        raise TypeError(
            f"{type(par_env).__name__}.possible_agents is {_describe(par_env.possible_agents)}; PettingZoo's API (and "
            "SuperSuit's vector env) needs a list: possible_agents = list(...)."
        )
    agents = list(par_env.possible_agents)
    if len(agents) == 0:
        raise ValueError("The parallel env has no agents (`possible_agents` is empty).")
    repeated = sorted({str(agent) for agent in agents if agents.count(agent) > 1})
    if repeated:
        raise ValueError(
            f"{type(par_env).__name__}.possible_agents names {repeated} more than once; each agent needs a name of its "
            "own (its slot, observation and reward are looked up by it)."
        )
    obs_space = par_env.observation_space(agents[0])
    act_space = par_env.action_space(agents[0])
    odd_obs = [a for a in agents if par_env.observation_space(a) != obs_space]
    odd_act = [a for a in agents if par_env.action_space(a) != act_space]
    problems, wrappers = [], []
    if odd_obs:
        problems.append(f"agents {odd_obs} have an observation space different from {agents[0]}'s ({obs_space})")
        wrappers.append("supersuit.pad_observations_v0")
    if odd_act:
        problems.append(f"agents {odd_act} have an action space different from {agents[0]}'s ({act_space})")
        wrappers.append("supersuit.pad_action_space_v0")
    if problems:
        raise ValueError(
            f"{'; '.join(problems)}. Parameter sharing needs identical spaces: wrap the env with "
            f"{' and '.join(wrappers)} (and, to tell the agents apart, supersuit.agent_indicator_v0)."
        )


def check_action_space(owner: str, action_space: spaces.Space) -> None:
    """Reject ``Discrete`` / ``MultiDiscrete`` action spaces whose ``start`` is not 0: the policies sample actions
    ``0 .. n - 1`` (as SB3 does), so every action the env received would be off by ``start``.

    :param owner: who checks, for the message (``"MAPPO"``, ``"make_multiagent_vec_env"``)
    :param action_space: one agent's action space, as the env declares it
    """
    if not isinstance(action_space, (spaces.Discrete, spaces.MultiDiscrete)):
        return
    start = np.asarray(action_space.start)
    if not np.any(start != 0):
        return
    if isinstance(action_space, spaces.Discrete):
        declared, offset = f"Discrete({int(action_space.n)})", str(int(start))
    else:
        declared, offset = f"MultiDiscrete({action_space.nvec.tolist()})", str(start.tolist())
    raise ValueError(
        f"{owner}: the action space {action_space} starts at {offset}, but the policies sample actions 0 .. n - 1, so "
        f"the env would get every action shifted; declare {declared} and add {offset} to the action inside the env."
    )


def probe_game(env_fn: ParallelEnvFactory) -> ParallelEnv:
    """Build one game and check that it can be vectorized (:func:`check_parallel_env`, :func:`check_action_space`).

    :param env_fn: callable returning one PettingZoo ``ParallelEnv``
    :return: the game (its first agent's spaces are the vec env's)
    """
    game = env_fn()
    check_parallel_env(game)
    check_reset_signature(game)
    check_action_space("make_multiagent_vec_env", game.action_space(game.possible_agents[0]))
    warn_late_black_death(game)
    return game


def check_reset_signature(game: Any) -> None:
    """Refuse a game whose ``reset`` does not take PettingZoo's ``seed`` and ``options`` keywords (the vec envs seed
    every game through them; Python's ``TypeError`` named neither the API nor the fix).

    :param game: one game
    """
    try:
        parameters = inspect.signature(game.reset).parameters
    except (TypeError, ValueError):  # a builtin or C method: left to the call
        return
    if any(parameter.kind is inspect.Parameter.VAR_KEYWORD for parameter in parameters.values()):
        return
    missing = [name for name in ("seed", "options") if name not in parameters]
    if missing:
        raise TypeError(
            f"{type(game).__name__}.reset takes no {' or '.join(missing)}; PettingZoo's parallel API is "
            "reset(self, seed=None, options=None), and the vec envs seed each game through it: add the keywords (seed "
            "the game's random generator with seed when it is not None)."
        )


# SuperSuit releases whose black_death_v3 ends a game only when its agents are terminated *and* truncated at once
LATE_BLACK_DEATH_UP_TO = (3, 11, 0)


def warn_late_black_death(game: Any) -> None:
    """Warn when ``game`` is wrapped with the ``black_death_v3`` of SuperSuit 3.11.0 or older, which ends a game a step
    late (``docs/guide/custom_env.md``, "Agents that finish early"); :func:`~sb3_saeir.common.vec_env.black_death`
    ends it on time.

    :param game: a game as the task factory returns it
    """
    layer, seen = game, set()
    while layer is not None and id(layer) not in seen:
        seen.add(id(layer))
        if type(layer).__name__ == "black_death_par" and type(layer).__module__.startswith("supersuit."):
            from importlib.metadata import version

            installed = version("supersuit")
            if tuple(int(part) for part in installed.split(".")[:3] if part.isdigit()) <= LATE_BLACK_DEATH_UP_TO:
                warnings.warn(
                    f"The game is wrapped with SuperSuit {installed}'s black_death_v3, which ends a game only "
                    "when its agents are terminated and truncated at once: a game whose agents terminate or are "
                    "truncated is stepped once more with no agent left and ends a step late. Wrap it with "
                    "sb3_saeir.common.vec_env.black_death instead.",
                    stacklevel=3,
                )
            return
        layer = vars(layer).get("env")  # the wrapped env of a wrapper (no attribute lookup through __getattr__)


def check_vec_env_options(n_games: Any, num_cpus: Any, mark_truncation: Any, check_finite: Any) -> None:
    """Refuse bad sizes and non-bool flags of :func:`make_multiagent_vec_env` with one line naming the argument.

    :param n_games: an integer >= 1
    :param num_cpus: an integer >= 0
    :param mark_truncation: a bool
    :param check_finite: a bool
    :raises ValueError: for a bad size
    :raises ~sb3_saeir.common.utils.NotABoolError: for a non-bool flag (a ``TypeError`` and a ``ValueError``)
    """
    if isinstance(n_games, bool) or not isinstance(n_games, (int, np.integer)) or n_games < 1:
        raise ValueError(f"n_games must be a positive integer (number of game copies), got {n_games!r}.")
    if isinstance(num_cpus, bool) or not isinstance(num_cpus, (int, np.integer)) or num_cpus < 0:
        raise ValueError(f"num_cpus must be an integer >= 0 (0: every game in this process), got {num_cpus!r}.")
    check_bool("make_multiagent_vec_env", mark_truncation=mark_truncation, check_finite=check_finite)


class NonFiniteValueError(ValueError):
    """An env returned a NaN or infinite observation or reward."""


def check_finite(
    env_name: str,
    observations: np.ndarray,
    rewards: np.ndarray | None,
    n_agents: int,
    agent_names: Sequence[str],
    episode_steps: np.ndarray,
    first_game: int = 0,
) -> None:
    """Raise :class:`NonFiniteValueError` naming the first slot whose observation or reward is NaN or infinite, and how
    many of its game's are (the games' workers check their games apart, so other games are not counted).

    :param env_name: the env, for the message
    :param observations: ``(n_games * n_agents, ...)``
    :param rewards: ``(n_games * n_agents,)``, or ``None`` after a reset
    :param n_agents: agents per game (slot = game * n_agents + agent)
    :param agent_names: the agents' names, in slot order within a game
    :param episode_steps: ``(n_games,)`` the step of each game's episode that produced these values
    :param first_game: index of the first game of these arrays in its vec env (for the message)
    """
    flat = np.asarray(observations).reshape(len(observations), -1)  # (G * N, ...) -> (G * N, d)
    if np.issubdtype(flat.dtype, np.integer) and rewards is None:
        return
    bad_obs = ~np.isfinite(flat).all(axis=1)
    bad_rewards = ~np.isfinite(rewards) if rewards is not None else np.zeros(len(flat), dtype=bool)
    if not (bad_obs.any() or bad_rewards.any()):
        return
    slot = int(np.flatnonzero(bad_obs | bad_rewards)[0])
    game, agent = divmod(slot, n_agents)
    if bad_rewards[slot]:
        what = f"reward {float(rewards[slot])}"  # type: ignore[index]
    else:
        bad_entries = np.flatnonzero(~np.isfinite(flat[slot]))
        what = f"observation has {flat[slot, bad_entries[0]]} at entry {int(bad_entries[0])}"
    step = int(episode_steps[game])
    rows = slice(game * n_agents, (game + 1) * n_agents)  # counted in the named game only: the same on every backend
    raise NonFiniteValueError(
        f"{env_name}: game {first_game + game}, agent {agent} ({agent_names[agent]}): {what} at step {step} of its episode "
        f"({int(bad_obs[rows].sum())} observations and {int(bad_rewards[rows].sum())} rewards of this game's step are "
        "not finite). "
        "Fix the env; SB3's VecCheckNan(env, raise_exception=True) also checks the actions that led there; "
        "make_multiagent_vec_env(..., check_finite=False) turns this check off."
    )
