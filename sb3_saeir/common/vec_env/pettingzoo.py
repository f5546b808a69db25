"""PettingZoo games in this process, stepped through SuperSuit: :class:`MultiAgentDummyVecEnv`.

SuperSuit vectorizes one game with one slot per agent (``pettingzoo_env_to_vec_env_v1``) and concatenates the copies
(``concat_vec_envs_v1``); this env is the SB3 ``VecEnv`` on top (SuperSuit's own SB3 wrapper is broken with SB3 2.9,
``docs/guide/custom_env.md``). The games in worker processes: :mod:`sb3_saeir.common.vec_env.workers`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sb3_saeir.common.vec_env.base import MultiAgentVecEnv, RawStep
from sb3_saeir.common.vec_env.game_checks import ParallelEnvFactory, checked_game, probe_game


class MultiAgentDummyVecEnv(MultiAgentVecEnv):
    """SB3 ``VecEnv`` over ``n_games`` copies of a PettingZoo parallel game stepped in this process, one slot per agent
    (a :class:`~sb3_saeir.common.vec_env.base.MultiAgentVecEnv`: one sampling group of all slots), as SB3's
    ``DummyVecEnv`` steps its envs in this process.

    Use :func:`~sb3_saeir.common.vec_env.factory.make_multiagent_vec_env` to build one (``num_cpus`` 0 or 1).

    :param env_fn: callable returning one PettingZoo ``ParallelEnv`` (one game)
    :param n_games: number of game copies G; the vec env has ``G * n_agents`` slots
    :param mark_truncation: set ``infos[i]["TimeLimit.truncated"]`` when a game is truncated (not terminated), so
        that SB3 bootstraps the value of the final observation. Off by default: time limits are treated as terminal,
        as MAPPO does on MPE, since the observation carries no time feature.
    :param check_finite: raise :class:`~sb3_saeir.common.vec_env.game_checks.NonFiniteValueError` (naming the game,
        agent and step) as soon as an observation or reward is NaN or infinite; ``False`` skips the check (it costs
        well under 1% of a training step)
    """

    def __init__(
        self,
        env_fn: ParallelEnvFactory,
        n_games: int,
        mark_truncation: bool = False,
        check_finite: bool = True,
    ) -> None:
        import supersuit as ss

        probe_env = probe_game(env_fn)
        self._probe_env = probe_env
        possible_agents = list(probe_env.possible_agents)
        markov_env = ss.pettingzoo_env_to_vec_env_v1(checked_game(probe_env))
        #: SuperSuit's concatenated ``MarkovVectorEnv`` copies of the game (a gymnasium-style vector env)
        self.venv: Any = ss.concat_vec_envs_v1(markov_env, int(n_games), num_cpus=0, base_class="gymnasium")
        for game, vec in enumerate(self.venv.vec_envs):  # copies of markov_env: number their checks' messages
            vec.par_env.game_index = game
        super().__init__(
            n_games,
            possible_agents,
            probe_env.observation_space(possible_agents[0]),
            probe_env.action_space(possible_agents[0]),
            mark_truncation=mark_truncation,
            check_finite=check_finite,
            render_mode=getattr(probe_env, "render_mode", None),
            metadata=getattr(probe_env, "metadata", {}) or {},
            game_name=type(probe_env).__name__,
        )

    # ------------------------------------------------------------------ the games (MultiAgentVecEnv)
    def _game_objects(self) -> list[Any]:
        return [vec.par_env.env for vec in self.venv.vec_envs]  # MarkovVectorEnv -> CheckedParallelEnv -> game

    def _reset_games(self, seed: int | None, options: dict | None) -> tuple[np.ndarray, list[dict[str, Any]]]:
        obs, infos = self.venv.reset(seed=seed, options=options)
        return obs, [dict(info) for info in infos]

    def _step_games_async(self, actions: np.ndarray, group: int | None) -> None:
        self.venv.step_async(actions)  # one group of all slots: a group's step is a step of every game

    def _step_games_wait(self, group: int | None, episode_steps: np.ndarray) -> RawStep:
        obs, rewards, terminations, truncations, infos = self.venv.step_wait()
        return self._raw_step(group, episode_steps, obs, rewards, terminations, truncations, infos)

    def _abandon_steps(self, groups: list[int]) -> None:
        self.venv.step_wait()

    def _render_game_zero(self) -> Any:
        return self.venv.render()  # SuperSuit renders the first game only

    def _close_games(self) -> None:
        self.venv.close()
        if hasattr(self._probe_env, "close"):
            self._probe_env.close()
