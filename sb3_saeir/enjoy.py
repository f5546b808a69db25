"""Replay a trained model: print its evaluation metrics and optionally write a GIF of one game.

    python -m sb3_saeir.enjoy --algo saeir_ppo --task cn-sparse-n3 -f logs -n 100 --gif replay.gif

By default it loads the final model of the latest run in ``<log-folder>/<algo>/<task>_<run>/``; ``--exp-id`` picks a
run, ``--load-best`` its best model, ``--model`` any saved zip.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
import torch as th

from sb3_saeir.common.vec_env import make_multiagent_vec_env
from sb3_saeir.config import ALGOS
from sb3_saeir.envs import list_tasks
from sb3_saeir.evaluation import evaluate_multiagent_policy


def find_model(log_folder: str, algo: str, task: str, exp_id: int = 0, load_best: bool = False) -> Path:
    """Path of a run's final (or best) model; ``exp_id=0`` means the latest run."""
    algo_folder = Path(log_folder) / algo
    runs = sorted(
        (int(p.name.rsplit("_", 1)[1]), p) for p in algo_folder.glob(f"{task}_*") if p.name.rsplit("_", 1)[1].isdigit()
    )
    if not runs:
        raise FileNotFoundError(f"no run of {algo} on {task} in {algo_folder}.")
    folder = dict(runs)[exp_id] if exp_id else runs[-1][1]
    path = folder / ("best_model.zip" if load_best else f"{task}.zip")
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist.")
    return path


def record_gif(model: Any, task: str, path: str, n_episodes: int = 1, seed: int = 0, deterministic: bool = True) -> int:
    """Write a GIF of game 0 playing ``n_episodes`` episodes (needs a task that renders ``rgb_array``).

    :return: number of frames written
    """
    import imageio.v2 as imageio

    env = make_multiagent_vec_env(task, n_games=1, seed=seed, render_mode="rgb_array")
    observations = env.reset()
    frames = [env.render()]
    states, starts, finished = None, np.ones(env.num_envs, dtype=bool), 0
    while finished < n_episodes:
        actions, states = model.predict(observations, state=states, episode_start=starts, deterministic=deterministic)
        observations, _, starts, infos = env.step(actions)
        finished += int(any("episode" in info for info in infos))
        frames.append(env.render())
    env.close()
    imageio.mimsave(path, [frame for frame in frames if frame is not None], duration=0.1)
    return len(frames)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sb3_saeir.enjoy", description=__doc__.split("\n")[0])
    parser.add_argument("--algo", required=True, help=f"method: {', '.join(sorted(ALGOS))}")
    parser.add_argument("--task", "--env", dest="task", default="cn-sparse-n3", help=f"task id: {', '.join(list_tasks())}")
    parser.add_argument("-f", "--log-folder", default="logs")
    parser.add_argument("--exp-id", type=int, default=0, help="run number (0: latest)")
    parser.add_argument("--load-best", action="store_true", help="load best_model.zip instead of the final model")
    parser.add_argument("--model", default=None, help="path of a saved model (overrides -f/--exp-id)")
    parser.add_argument("-n", "--n-episodes", type=int, default=100, help="game episodes to evaluate")
    parser.add_argument("--n-games", type=int, default=10, help="games played in parallel")
    parser.add_argument("--stochastic", action="store_true", help="sample actions instead of the greedy ones")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--gif", default=None, help="write a GIF of one game to this path")
    parser.add_argument("--gif-episodes", type=int, default=1)
    parser.add_argument("--num-threads", type=int, default=1)
    args = parser.parse_args(argv)
    th.set_num_threads(args.num_threads)
    if args.algo not in ALGOS:
        print(f"sb3_saeir.enjoy: error: unknown algorithm {args.algo!r}; valid choices: {', '.join(sorted(ALGOS))}.")
        return 2
    try:
        path = (
            Path(args.model) if args.model else find_model(args.log_folder, args.algo, args.task, args.exp_id, args.load_best)
        )
    except FileNotFoundError as error:
        print(f"sb3_saeir.enjoy: error: {error}", file=sys.stderr)
        return 2
    model = ALGOS[args.algo].load(path, device="cpu")
    env = make_multiagent_vec_env(args.task, n_games=args.n_games, seed=args.seed)
    summary = evaluate_multiagent_policy(model, env, args.n_episodes, deterministic=not args.stochastic)
    env.close()
    print(f"{path}: {int(summary['n_episodes'])} episodes")
    for key in sorted(summary):
        if key.endswith("_mean"):
            print(f"  {key[:-5]:<22} {summary[key]:9.4f} +/- {summary[key[:-5] + '_std']:.4f}")
    if args.gif:
        n_frames = record_gif(model, args.task, args.gif, args.gif_episodes, args.seed, not args.stochastic)
        print(f"GIF: {args.gif} ({n_frames} frames)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
