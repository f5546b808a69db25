"""Batched NumPy engine of sparse Cooperative Navigation: ``G`` games x ``N`` agents x ``N`` landmarks at once, with
no Python loop over games or agents in a step (resets loop over the games being reset, one generator each). The
physics is MPE ``simple_spread`` written from its equations: the action force, the soft contact force between agents,
damping 0.25, ``dt = 0.1``, 25 steps; ``world="mpe"`` (the paper's: the new velocity moves the agents, landmarks in
``0.8 * U(-1, 1)^2``) or ``world="mpe2"`` (mpe2 1.1.1's order and starts, seed for seed). The rewards
(``"occupancy"``, ``"reach"``) and the collision rule: ``docs/tasks.md``, which gives every constant.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from sb3_saeir.common.utils import check_bool

WORLDS = ("mpe", "mpe2")
REWARDS = ("occupancy", "reach")

AGENT_SIZE = 0.15
LANDMARK_SIZE = 0.05
DT = 0.1
DAMPING = 0.25
CONTACT_FORCE = 100.0
CONTACT_MARGIN = 1e-3
SENSITIVITY = 5.0
COVER_RADIUS = 0.1
N_ACTIONS = 5  # no-op, -x, +x, -y, +y (mpe2's discrete actions)
# Unit direction of each discrete action, (5, 2).
ACTION_DIRECTIONS = np.array([[0.0, 0.0], [-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
# Landmarks start in LANDMARK_RANGE[world] * U(-1, 1)^2.
LANDMARK_RANGE = {"mpe": 0.8, "mpe2": 1.0}
# Metadata of both faces (the ParallelEnv and the vec env).
METADATA: dict[str, Any] = {
    "render_modes": ["rgb_array"],
    "name": "cn_sparse_v0",
    "is_parallelizable": True,
    "render_fps": 10,
}


def observation_dim(n_agents: int) -> int:
    """Length of one agent's observation: velocity, position, landmarks, other agents, their (silent) messages."""
    return 4 + 2 * n_agents + 4 * (n_agents - 1)


def navigation_spaces(N: int, continuous_actions: bool) -> tuple[spaces.Box, spaces.Space]:
    """Observation and action space of one agent (mpe2's): ``Box(-inf, inf, (obs_dim,), float32)`` and ``Discrete(5)``
    or ``Box(0, 1, (5,), float32)``.

    :param N: agents per game
    :param continuous_actions: continuous actions
    """
    shape = (observation_dim(N),)
    observation_space = spaces.Box(low=-np.float32(np.inf), high=+np.float32(np.inf), shape=shape, dtype=np.float32)
    action_space: spaces.Space = spaces.Discrete(N_ACTIONS)
    if continuous_actions:
        action_space = spaces.Box(low=0.0, high=1.0, shape=(N_ACTIONS,), dtype=np.float32)
    return observation_space, action_space


# Bytes of float64 working arrays one step allocates per agent-observation entry and per agent pair (observations,
# their float32 copy, the pairwise offsets and distances of agents and landmarks, with temporaries): an upper estimate.
_BYTES_PER_OBS_ENTRY = 8 * 4
_BYTES_PER_PAIR = 8 * 12


def check_positive_int(name: str, value: Any) -> None:
    """Refuse anything but an integer >= 1 (bools, floats such as ``2.5`` or ``25.0``, strings), naming ``name``.

    :param name: the option, for the message
    :param value: its value
    :raises ValueError: with one line naming the option
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}; pass a whole number such as {name}=3.")


def check_finite_option(name: str, value: Any) -> None:
    """Refuse non-numbers and NaN / infinite values of a float option, naming ``name``.

    :param name: the option, for the message
    :param value: its value
    :raises ValueError: with one line naming the option
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a finite number, got {value!r} ({type(value).__name__}).")
    if not np.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}; a NaN or infinite value makes NaN rewards.")


def memory_estimate(n_games: int, N: int) -> int:
    """Upper estimate of the bytes the engine's step of ``n_games`` games of ``N`` agents works with.

    :param n_games: games
    :param N: agents per game
    :return: bytes
    """
    return n_games * N * (observation_dim(N) * _BYTES_PER_OBS_ENTRY + 2 * N * _BYTES_PER_PAIR)


def _available_memory() -> int:
    """Physical memory of this machine in bytes (16 GiB where the OS does not tell)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return 16 * 2**30


def check_memory(n_games: int, N: int) -> None:
    """Refuse a size whose step cannot fit in half of this machine's memory, with the estimate.

    :param n_games: games
    :param N: agents per game
    :raises MemoryError: with one line giving the estimate and the fix
    """
    needed, limit = memory_estimate(n_games, N), _available_memory() // 2
    if needed > limit:
        raise MemoryError(
            f"n_games={n_games} games of N={N} agents need about {needed / 2**30:.1f} GiB per step (observations grow "
            f"as n_games * N**2), more than half of this machine's {2 * limit / 2**30:.1f} GiB: lower N or n_games."
        )


@dataclass
class StepResult:
    """What :meth:`NavigationCore.step` returns, per game.

    :param observations: ``(G, N, obs_dim)`` float32
    :param rewards: team reward of the step, ``(G,)`` float64
    :param covered: landmarks whose nearest agent is within the cover radius, ``(G,)`` int64
    :param reached: landmarks reached at this step and not at the previous one, ``(G,)`` int64
    :param collided: any two agents overlap, ``(G,)`` bool
    :param truncated: the game reached ``max_cycles``, ``(G,)`` bool
    """

    observations: np.ndarray
    rewards: np.ndarray
    covered: np.ndarray
    reached: np.ndarray
    collided: np.ndarray
    truncated: np.ndarray


def _check_choice(name: str, value: str, choices: Sequence[str]) -> str:
    if value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(repr(c) for c in choices)}; got {value!r}.")
    return value


# Arrays of the core that a resume state holds (per-game parameters, physical state, episode bookkeeping).
_RESUME_ARRAYS = (
    "max_cycles",
    "cover_radius",
    "collision_penalty",
    "positions",
    "velocities",
    "landmarks",
    "steps",
    "reached",
    "covered_sum",
    "collision_steps",
    "reach_events",
    "last_covered",
)


class NavigationCore:
    """The state and dynamics of ``n_games`` Cooperative Navigation games, stepped together.

    :param n_games: number of games G
    :param N: agents per game (= landmarks)
    :param max_cycles: episode length in steps (a game is truncated after this many steps)
    :param continuous_actions: actions ``(G, N, 5)`` in ``[0, 1]`` (force ``(a2 - a1, a4 - a3)``) instead of integer
        actions ``(G, N)`` in ``0..4``
    :param world: ``"mpe"`` (the original MPE, the paper's world) or ``"mpe2"`` (mpe2 1.1.1)
    :param reward: ``"occupancy"`` or ``"reach"`` (see the module docstring)
    :param cover_radius: a landmark is reached when its nearest agent is closer than this
    :param collision_penalty: subtracted once per step when any two agents of a game collide
    """

    def __init__(
        self,
        n_games: int,
        N: int = 3,
        max_cycles: int = 25,
        continuous_actions: bool = False,
        world: str = "mpe",
        reward: str = "occupancy",
        cover_radius: float = COVER_RADIUS,
        collision_penalty: float = 1.0,
    ) -> None:
        check_positive_int("n_games", n_games)
        check_positive_int("N", N)
        check_positive_int("max_cycles", max_cycles)
        check_bool(type(self).__name__, continuous_actions=continuous_actions)
        check_finite_option("cover_radius", cover_radius)
        check_finite_option("collision_penalty", collision_penalty)
        if not cover_radius > 0:
            raise ValueError(f"cover_radius must be positive, got {cover_radius}.")
        if not collision_penalty >= 0:
            raise ValueError(f"collision_penalty must be >= 0 (it is subtracted), got {collision_penalty}.")
        check_memory(int(n_games), int(N))
        self.world = _check_choice("world", world, WORLDS)
        self.reward = _check_choice("reward", reward, REWARDS)
        self.n_games = int(n_games)
        self.N = int(N)
        self.continuous_actions = bool(continuous_actions)
        self.obs_dim = observation_dim(self.N)
        G, N_ = self.n_games, self.N
        # Per-game parameters (settable per game through the vec env's set_attr).
        self.max_cycles = np.full(G, int(max_cycles), dtype=np.int64)
        self.cover_radius = np.full(G, float(cover_radius), dtype=np.float64)
        self.collision_penalty = np.full(G, float(collision_penalty), dtype=np.float64)
        # Physical state.
        self.positions = np.zeros((G, N_, 2))
        self.velocities = np.zeros((G, N_, 2))
        self.landmarks = np.zeros((G, N_, 2))
        # Episode bookkeeping.
        self.steps = np.zeros(G, dtype=np.int64)
        self.reached = np.zeros((G, N_), dtype=bool)  # landmarks reached at the last step (or at the start)
        self.covered_sum = np.zeros(G)  # sum over steps of the covered fraction
        self.collision_steps = np.zeros(G, dtype=np.int64)
        self.reach_events = np.zeros(G, dtype=np.int64)
        self.last_covered = np.zeros(G, dtype=np.int64)
        # others[i] = the agents other than i in index order, (N, N-1)
        self._others = np.array([[j for j in range(N_) if j != i] for i in range(N_)], dtype=np.int64).reshape(N_, N_ - 1)
        self._eye = np.eye(N_)
        self._off_diagonal = ~np.eye(N_, dtype=bool)
        self.rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(G)]

    # ------------------------------------------------------------------ seeding and resets
    def seed(self, seeds: Sequence[int | None], games: Sequence[int] | np.ndarray | None = None) -> None:
        """Give games fresh generators (gymnasium's ``np_random(seed)``, as mpe2's ``reset(seed=...)`` does).

        :param seeds: one seed per game in ``games``; ``None`` keeps that game's generator
        :param games: game indices (default: all games)
        """
        indices = range(self.n_games) if games is None else [int(g) for g in games]
        for game, seed in zip(indices, seeds, strict=True):
            if seed is not None:
                self.rngs[game] = seeding.np_random(int(seed))[0]

    def reset_games(self, games: Sequence[int] | np.ndarray | None = None) -> None:
        """Start new episodes in ``games`` (default: all): draw agents then landmarks from each game's generator.

        :param games: game indices
        """
        indices = np.arange(self.n_games) if games is None else np.asarray(games, dtype=np.int64).reshape(-1)
        scale = LANDMARK_RANGE[self.world]
        for game in indices:
            rng = self.rngs[game]
            self.positions[game] = rng.uniform(-1.0, 1.0, (self.N, 2))
            landmarks = rng.uniform(-1.0, 1.0, (self.N, 2))
            self.landmarks[game] = landmarks * scale if scale != 1.0 else landmarks
        self.velocities[indices] = 0.0
        self.steps[indices] = 0
        self.covered_sum[indices] = 0.0
        self.collision_steps[indices] = 0
        self.reach_events[indices] = 0
        reached = self._reached_landmarks()
        self.reached[indices] = reached[indices]
        self.last_covered[indices] = reached[indices].sum(axis=1)

    def place(
        self,
        game: int,
        agent_positions: Any,
        landmark_positions: Any | None = None,
        velocities: Any | None = None,
    ) -> None:
        """Put the entities of one game at given positions (for tests and scripted set-ups).

        The "reached at the previous step" record of the reach reading is left as it was.

        :param game: game index
        :param agent_positions: ``(N, 2)``
        :param landmark_positions: ``(N, 2)``; ``None`` keeps them
        :param velocities: ``(N, 2)``; ``None`` sets them to zero
        """
        self.positions[game] = np.asarray(agent_positions, dtype=np.float64).reshape(self.N, 2)
        if landmark_positions is not None:
            self.landmarks[game] = np.asarray(landmark_positions, dtype=np.float64).reshape(self.N, 2)
        self.velocities[game] = 0.0 if velocities is None else np.asarray(velocities, dtype=np.float64).reshape(self.N, 2)

    # ------------------------------------------------------------------ resume state
    def get_resume_state(self) -> dict[str, Any]:
        """Everything that determines the games' future: per-game parameters, physical state, episode bookkeeping and
        each game's generator state (``bit_generator.state``); copies, safe to pickle.

        :return: a dict for :meth:`set_resume_state`
        """
        state: dict[str, Any] = {
            "layout": self._layout(),
            "rngs": [rng.bit_generator.state for rng in self.rngs],
        }
        state.update({name: getattr(self, name).copy() for name in _RESUME_ARRAYS})
        return state

    def set_resume_state(self, state: dict[str, Any]) -> None:
        """Put the games back in the state returned by :meth:`get_resume_state` (same number of games, agents,
        world, reward reading and action type).

        :param state: a dict from :meth:`get_resume_state`
        :raises ValueError: when the state was taken from a core of another layout
        """
        if state["layout"] != self._layout():
            raise ValueError(f"resume state of a core {state['layout']} cannot be put into a core {self._layout()}.")
        for name in _RESUME_ARRAYS:
            setattr(self, name, np.array(state[name], dtype=getattr(self, name).dtype, copy=True))
        rngs = []
        for rng_state in state["rngs"]:
            rng = np.random.Generator(getattr(np.random, rng_state["bit_generator"])())
            rng.bit_generator.state = rng_state
            rngs.append(rng)
        self.rngs = rngs

    def _layout(self) -> dict[str, Any]:
        """What a resume state must agree on: games, agents, world, reward reading, action type."""
        return {
            "n_games": self.n_games,
            "N": self.N,
            "world": self.world,
            "reward": self.reward,
            "continuous_actions": self.continuous_actions,
        }

    # ------------------------------------------------------------------ dynamics
    def action_forces(self, actions: np.ndarray) -> np.ndarray:
        """Action force of every agent, ``(G, N, 2)``.

        :param actions: ``(G, N)`` integers in ``0..4``, or ``(G, N, 5)`` in ``[0, 1]`` for continuous actions
        """
        actions = np.asarray(actions)
        if self.continuous_actions:
            # (G, N, 5) -> (G, N, 2): (a2 - a1, a4 - a3) in the actions' own precision, then scaled in float64
            direction = np.stack([actions[..., 2] - actions[..., 1], actions[..., 4] - actions[..., 3]], axis=-1)
            return direction.astype(np.float64) * SENSITIVITY
        return ACTION_DIRECTIONS[actions.astype(np.int64) % N_ACTIONS] * SENSITIVITY

    def contact_forces(self, positions: np.ndarray) -> np.ndarray:
        """Contact force on agent a from agent b, ``(G, N, N, 2)`` (zero for b = a).

        :param positions: ``(G, N, 2)``
        """
        # delta[g, a, b] = p_a - p_b, (G, N, N, 2)
        delta = positions[:, :, None, :] - positions[:, None, :, :]
        squares = np.square(delta)
        dist = np.sqrt(squares[..., 0] + squares[..., 1]) + self._eye  # (G, N, N); 1 on the diagonal avoids 0 / 0
        penetration = np.logaddexp(0.0, -(dist - 2 * AGENT_SIZE) / CONTACT_MARGIN) * CONTACT_MARGIN
        return CONTACT_FORCE * delta / dist[..., None] * penetration[..., None]

    def forces(self, actions: np.ndarray) -> np.ndarray:
        """Total force on every agent, ``(G, N, 2)``: the action force, then each contact force in agent order."""
        contact = self.contact_forces(self.positions)
        # (G, N, 1 + N, 2) summed strictly left to right: u + f_a0 + f_a1 + ... (the order the MPE loops add them)
        terms = np.concatenate([self.action_forces(actions)[:, :, None, :], contact], axis=2)
        return np.add.accumulate(terms, axis=2)[:, :, -1, :]

    def integrate(self, force: np.ndarray) -> None:
        """Advance positions and velocities by one ``dt`` in this core's world order.

        :param force: ``(G, N, 2)`` (mass 1)
        """
        if self.world == "mpe2":
            self.positions += self.velocities * DT
            self.velocities = self.velocities * (1 - DAMPING)
            self.velocities += force * DT
        else:
            self.velocities = self.velocities * (1 - DAMPING)
            self.velocities += force * DT
            self.positions += self.velocities * DT

    # ------------------------------------------------------------------ task quantities
    def landmark_distances(self) -> np.ndarray:
        """Distance from each landmark to each agent, ``(G, L, N)``."""
        # (G, L, 1, 2) - (G, 1, N, 2) -> (G, L, N, 2)
        delta = self.landmarks[:, :, None, :] - self.positions[:, None, :, :]
        squares = np.square(delta)
        return np.sqrt(squares[..., 0] + squares[..., 1])

    def _reached_landmarks(self) -> np.ndarray:
        """Landmarks whose nearest agent is closer than the game's cover radius, ``(G, L)`` bool."""
        return self.landmark_distances().min(axis=2) < self.cover_radius[:, None]

    def collisions(self) -> np.ndarray:
        """Games in which two distinct agents are closer than the sum of their sizes, ``(G,)`` bool."""
        delta = self.positions[:, :, None, :] - self.positions[:, None, :, :]  # (G, N, N, 2)
        squares = np.square(delta)
        dist = np.sqrt(squares[..., 0] + squares[..., 1])
        return ((dist < 2 * AGENT_SIZE) & self._off_diagonal).any(axis=(1, 2))

    def observations(self) -> np.ndarray:
        """Every agent's observation, ``(G, N, obs_dim)`` float32.

        Layout per agent: own velocity (2), own position (2), each landmark relative to the agent (2N), each other
        agent relative to it in index order (2(N-1)), their communication (2(N-1), always 0).
        """
        G, N = self.n_games, self.N
        obs = np.zeros((G, N, self.obs_dim), dtype=np.float32)
        obs[:, :, 0:2] = self.velocities
        obs[:, :, 2:4] = self.positions
        # (G, 1, L, 2) - (G, N, 1, 2) -> (G, N, L, 2) -> (G, N, 2L)
        obs[:, :, 4 : 4 + 2 * N] = (self.landmarks[:, None, :, :] - self.positions[:, :, None, :]).reshape(G, N, 2 * N)
        if N > 1:
            # relative[g, i, j] = p_j - p_i, (G, N, N, 2); keep j != i -> (G, N, N-1, 2) -> (G, N, 2(N-1))
            relative = self.positions[:, None, :, :] - self.positions[:, :, None, :]
            others = relative[:, np.arange(N)[:, None], self._others]
            obs[:, :, 4 + 2 * N : 4 + 2 * N + 2 * (N - 1)] = others.reshape(G, N, 2 * (N - 1))
        return obs

    def step(self, actions: np.ndarray) -> StepResult:
        """One step of every game (no automatic reset: call :meth:`reset_games` for truncated games).

        :param actions: ``(G, N)`` integers, or ``(G, N, 5)`` for continuous actions
        :return: observations, team rewards, per-step counts and truncation flags
        """
        self.integrate(self.forces(actions))
        self.steps += 1
        reached_now = self._reached_landmarks()  # (G, L)
        covered = reached_now.sum(axis=1)
        new_reaches = (reached_now & ~self.reached).sum(axis=1)
        collided = self.collisions()
        gain = covered if self.reward == "occupancy" else new_reaches
        rewards = gain - self.collision_penalty * collided
        self.reached = reached_now
        self.last_covered = covered
        self.covered_sum += covered / self.N
        self.collision_steps += collided
        self.reach_events += new_reaches
        return StepResult(
            observations=self.observations(),
            rewards=rewards,
            covered=covered,
            reached=new_reaches,
            collided=collided,
            truncated=self.steps >= self.max_cycles,
        )

    def episode_metrics(self, game: int) -> dict[str, float]:
        """Metrics of a game's episode so far (call at its last step, before resetting it).

        ``coverage_rate``: covered landmarks at the last step / N; ``coverage_over_steps``: covered fraction averaged
        over the steps; ``collision_steps``: steps with a collision; ``success``: every landmark covered at the last
        step; ``reach_events``: landmarks that became reached, summed over the steps.
        """
        steps = max(int(self.steps[game]), 1)
        covered = int(self.last_covered[game])
        return {
            "coverage_rate": covered / self.N,
            "coverage_over_steps": float(self.covered_sum[game]) / steps,
            "collision_steps": float(self.collision_steps[game]),
            "success": float(covered == self.N),
            "reach_events": float(self.reach_events[game]),
        }

    # ------------------------------------------------------------------ rendering
    def render(self, game: int = 0, size: int = 400) -> np.ndarray:
        """An RGB picture of one game, ``(size, size, 3)`` uint8: cover discs (light green when reached), landmarks
        (dark grey), agents (blue; red while colliding).

        :param game: game index
        :param size: image side in pixels
        """
        frame = np.full((size, size, 3), 255, dtype=np.uint8)
        agents, landmarks = self.positions[game], self.landmarks[game]
        cam = 1.1 * max(1.0, float(np.abs(np.concatenate([agents, landmarks])).max()))
        scale = size / (2 * cam)
        rows, cols = np.mgrid[0:size, 0:size]
        x, y = cols + 0.5, rows + 0.5

        def disc(center: np.ndarray, radius: float, colour: tuple[int, int, int]) -> None:
            cx, cy = size / 2 + center[0] * scale, size / 2 - center[1] * scale
            frame[(x - cx) ** 2 + (y - cy) ** 2 <= (radius * scale) ** 2] = colour

        reached = self.landmark_distances()[game].min(axis=1) < self.cover_radius[game]
        for landmark, hit in zip(landmarks, reached):
            disc(landmark, float(self.cover_radius[game]), (170, 230, 170) if hit else (225, 225, 225))
        delta = agents[:, None, :] - agents[None, :, :]
        colliding = ((np.linalg.norm(delta, axis=-1) < 2 * AGENT_SIZE) & self._off_diagonal).any(axis=1)
        for agent, hit in zip(agents, colliding):
            disc(agent, AGENT_SIZE, (220, 60, 60) if hit else (89, 89, 217))
        for landmark in landmarks:
            disc(landmark, LANDMARK_SIZE, (64, 64, 64))
        return frame
