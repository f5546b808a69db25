"""Replay a trained model: print its evaluation metrics and optionally write a GIF of one game.

    python -m sb3_saeir.enjoy --algo saeir_ppo --task cn-sparse-n3 -f logs -n 100 --gif replay.gif

By default it loads the final model of the latest run that has one in ``<log-folder>/<algo>/<task>_<run>/``;
``--exp-id`` picks a run, ``--load-best`` its best model, ``--model`` any saved zip. The task's keyword arguments come
from the run's ``<task>/config.yml`` (``env_kwargs``) unless ``--env-kwargs`` gives them.
"""

from __future__ import annotations

import argparse
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from sb3_saeir.command_line import OneLineParser, check_output_file, check_range, check_seed_option, count
from sb3_saeir.common.atomic import atomic_path
from sb3_saeir.common.extras import MissingExtraError, require_extra
from sb3_saeir.common.utils import set_num_threads
from sb3_saeir.common.vec_env import make_multiagent_vec_env
from sb3_saeir.config import ALGOS, ConfigError, check_algo, load_hyperparams, load_yaml, model_method_mismatch, parse_params
from sb3_saeir.envs import list_tasks, make_task
from sb3_saeir.evaluation import evaluate_multiagent_policy
from sb3_saeir.run.files import CONFIG_FILE
from sb3_saeir.run.folder import find_model

__all__ = ["find_model", "main", "record_gif"]


def record_gif(
    model: Any,
    task: str,
    path: str,
    n_episodes: int = 1,
    seed: int = 0,
    deterministic: bool = True,
    fps: float = 10.0,
    env_kwargs: dict[str, Any] | None = None,
) -> int:
    """Write a looping GIF of one game playing ``n_episodes`` episodes (needs a task that renders ``rgb_array``).

    The game runs as its own PettingZoo env (no automatic reset), so each episode's frames go from its first state to
    its last one.

    :param model: anything with SB3's ``predict(obs, state, episode_start, deterministic)``
    :param task: task id
    :param path: GIF path
    :param n_episodes: episodes to record, one after the other
    :param seed: seed of the first episode (episode ``i`` uses ``seed + i``)
    :param deterministic: greedy actions
    :param fps: frames per second (each frame lasts ``1000 / fps`` ms)
    :param env_kwargs: the task's keyword arguments (e.g. the config's ``env_kwargs``)
    :return: number of frames written
    """
    imageio = require_extra("imageio.v2", "plots", "writing a GIF")
    game = make_task(task, render_mode="rgb_array", **(env_kwargs or {}))
    frames = []
    for episode in range(n_episodes):
        observations, _ = game.reset(seed=seed + episode)
        agents = list(game.possible_agents)
        states, starts = None, np.ones(len(agents), dtype=bool)
        frames.append(game.render())
        while game.agents:
            obs = np.stack([observations[agent] for agent in agents])  # (N, d) in agent order
            actions, states = model.predict(obs, state=states, episode_start=starts, deterministic=deterministic)
            starts = np.zeros(len(agents), dtype=bool)
            observations, _, _, _, _ = game.step({agent: action for agent, action in zip(agents, actions)})
            frames.append(game.render())
    game.close()
    frames = [frame for frame in frames if frame is not None]
    if not frames:
        raise ValueError(f"Task {task!r} rendered no rgb_array frames: it cannot be recorded as a GIF.")
    # imageio >= 2.28 reads duration in milliseconds per frame; loop=0 loops forever
    with atomic_path(path) as temp:  # an interrupted write leaves the GIF that was there
        imageio.mimsave(temp, frames, duration=1000.0 / fps, loop=0)
    return len(frames)


def model_env_mismatch(model: Any, env: Any) -> str:
    """Why ``model`` cannot play ``env`` (different observation or action space, or number of agents), or ``""``."""
    model_agents, env_agents = getattr(model, "n_agents", None), getattr(env, "n_agents", None)
    if model_agents is not None and env_agents is not None and model_agents != env_agents:
        return f"the model was trained with {model_agents} agents per game, the task has {env_agents}."
    if model.observation_space != env.observation_space:
        return f"observation space {model.observation_space} (model) vs {env.observation_space} (task)."
    if model.action_space != env.action_space:
        return f"action space {model.action_space} (model) vs {env.action_space} (task)."
    return ""


def run_env_kwargs(model_path: Path, task: str) -> dict[str, Any]:
    """The ``env_kwargs`` of the run a model was saved in (``<run>/<task>/config.yml``), or ``{}``."""
    config = model_path.parent / task / CONFIG_FILE
    if not config.is_file():
        return {}
    return dict((load_yaml(config.read_text()) or {}).get("env_kwargs") or {})


def check_enjoy_arguments(args: argparse.Namespace) -> tuple[Path, dict[str, Any]]:
    """Everything ``enjoy`` can check before loading the model: the method, sizes, the GIF path and its extra, the
    model file and its method; returns the model's path and the task's keyword arguments.

    :raises ~sb3_saeir.config.ConfigError: naming the first bad option
    :raises FileNotFoundError: when there is no model to load
    """
    set_num_threads(args.num_threads)
    check_algo(args.algo)
    if args.task not in list_tasks():
        raise ConfigError(f"unknown task {args.task!r}; valid choices: {', '.join(list_tasks())}.")
    check_range("-n/--n-episodes", args.n_episodes, 1)
    check_range("--n-games", args.n_games, 1)
    check_range("--gif-episodes", args.gif_episodes, 1)
    check_seed_option(args.seed)
    check_output_file("--gif", args.gif)
    if args.gif is not None:
        require_extra("imageio.v2", "plots", "--gif")
    path = Path(args.model) if args.model else find_model(args.log_folder, args.algo, args.task, args.exp_id, args.load_best)
    if not path.is_file():
        raise FileNotFoundError(f"--model {path} is not a file.")
    try:
        config = load_hyperparams(args.algo, args.task)
    except KeyError:
        config = None  # no packaged entry for this task: nothing to compare with
    mismatch = model_method_mismatch(path, args.algo, args.task, config) if config is not None else ""
    if mismatch:
        raise ConfigError(f"--algo {args.algo}: {mismatch}")
    env_kwargs = parse_params(args.env_kwargs) if args.env_kwargs else run_env_kwargs(path, args.task)
    return path, env_kwargs


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m sb3_saeir.enjoy", description=__doc__.split("\n")[0])
    parser.add_argument("--algo", required=True, help=f"method: {', '.join(sorted(ALGOS))}")
    parser.add_argument("--task", "--env", dest="task", default="cn-sparse-n3", help=f"task id: {', '.join(list_tasks())}")
    parser.add_argument("-f", "--log-folder", default="logs")
    parser.add_argument("--exp-id", type=int, default=0, help="run number (0: latest)")
    parser.add_argument("--load-best", action="store_true", help="load best_model.zip instead of the final model")
    parser.add_argument("--model", default=None, help="path of a saved model (overrides -f/--exp-id)")
    parser.add_argument("-n", "--n-episodes", type=count, default=100, help="game episodes to evaluate")
    parser.add_argument("--n-games", type=count, default=10, help="games played in parallel")
    parser.add_argument("--stochastic", action="store_true", help="sample actions instead of the greedy ones")
    parser.add_argument("--seed", type=count, default=0)
    parser.add_argument("--gif", default=None, help="write a GIF of one game to this path")
    parser.add_argument("--gif-episodes", type=count, default=1)
    parser.add_argument("--num-threads", type=int, default=0, help="torch threads (0: the free cores, at most 2)")
    parser.add_argument(
        "--env-kwargs", nargs="+", default=None, help="task keyword arguments key:value (default: the run's env_kwargs)"
    )
    args = parser.parse_args(argv)
    try:
        path, env_kwargs = check_enjoy_arguments(args)
        model = ALGOS[args.algo].load(path, device="cpu")
        env = make_multiagent_vec_env(args.task, n_games=args.n_games, seed=args.seed, **env_kwargs)
    except (FileNotFoundError, ConfigError, MissingExtraError) as error:
        print(f"sb3_saeir.enjoy: error: {error}", file=sys.stderr)
        return 2
    except MemoryError as error:  # the env's estimate for a size that cannot fit
        print(f"sb3_saeir.enjoy: error: --n-games {args.n_games}: {error}", file=sys.stderr)
        return 2
    except (ValueError, TypeError, KeyError, zipfile.BadZipFile) as error:
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(
            f"sb3_saeir.enjoy: error: cannot load {args.algo} from {args.model or 'the run'} on {args.task}: {message}",
            file=sys.stderr,
        )
        return 2
    mismatch = model_env_mismatch(model, env)
    if mismatch:
        env.close()
        print(f"sb3_saeir.enjoy: error: {path} does not fit {args.task}: {mismatch}", file=sys.stderr)
        return 2
    summary = evaluate_multiagent_policy(model, env, args.n_episodes, deterministic=not args.stochastic)
    env.close()
    print(f"{path}: {int(summary['n_episodes'])} episodes")
    for key in sorted(summary):
        if key.endswith("_mean"):
            print(f"  {key[:-5]:<22} {summary[key]:9.4f} +/- {summary[key[:-5] + '_std']:.4f}")
    if args.gif:
        n_frames = record_gif(
            model, args.task, args.gif, args.gif_episodes, args.seed, not args.stochastic, env_kwargs=env_kwargs
        )
        print(f"GIF: {args.gif} ({n_frames} frames)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
