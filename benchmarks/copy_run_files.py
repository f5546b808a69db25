"""Copy a benchmark run's small files into a study's folder of committed run files.

    python benchmarks/copy_run_files.py RUN TARGET [--bonus-window 250000 --bonus-name bonus_by_250k.md]

Copies from the run folder ``RUN`` into ``TARGET`` (made if missing) the files that a study page is rebuilt from,
those that exist: ``spec.json``, ``evaluations.csv``, ``segments.json``, ``resume.log``, ``done.json``
(``docs/guide/training.md``, "The run folder"). Never checkpoints, models, ``progress.csv`` or the games' monitor
file. A run still training is copied as far as it got. With ``--bonus-window``, a ``SAEIR_PPO`` run whose
``progress.csv`` has logged a rollout also gets its bonus files (``benchmarks/bonus_files.py``: ``bonus.md``,
``bonus.png`` and the windowed table ``--bonus-name``). Prints one line: what was copied where, and whether the run
had finished.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import bonus_files

from sb3_saeir.benchmark import read_rows
from sb3_saeir.run.files import DONE_FILE, EVALUATIONS_FILE, PROGRESS_FILE, RESUME_LOG, SEGMENTS_FILE, SPEC_FILE

COMMITTED_FILES = (SPEC_FILE, EVALUATIONS_FILE, SEGMENTS_FILE, RESUME_LOG, DONE_FILE)


def copy_run_files(run: Path, target: Path) -> list[str]:
    """Copy the committed files of ``run`` that exist into ``target``; returns their names.

    :param run: a benchmark run folder (it holds ``spec.json``)
    :param target: the study's folder for this run, made if missing
    """
    if not (run / SPEC_FILE).is_file():
        raise SystemExit(f"copy_run_files: {run} is not a run folder (no {SPEC_FILE}); give a folder the benchmark made.")
    target.mkdir(parents=True, exist_ok=True)
    copied = []
    for name in COMMITTED_FILES:
        if (run / name).is_file():
            shutil.copyfile(run / name, target / name)
            copied.append(name)
    return copied


def has_bonus_logs(run: Path) -> bool:
    """Whether the run's ``progress.csv`` logged the SAEIR bonus yet (a run that just started has no rollout in it)."""
    rows = read_rows(run / PROGRESS_FILE)
    return any(row.get("rollout/intrinsic_reward_mean") not in (None, "") for row in rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path, help="a benchmark run folder (with its spec.json)")
    parser.add_argument("target", type=Path, help="the study's folder for this run")
    parser.add_argument("--bonus-window", type=float, help="for a SAEIR_PPO run: env steps per row of the bonus table")
    parser.add_argument("--bonus-name", default="bonus_by_window.md", help="file name of the windowed bonus table")
    args = parser.parse_args(argv)
    copied = copy_run_files(args.run, args.target)
    algo = json.loads((args.run / SPEC_FILE).read_text()).get("algo")
    if args.bonus_window is not None and algo == "saeir_ppo" and (args.run / PROGRESS_FILE).is_file():
        if has_bonus_logs(args.run):
            bonus_argv = [str(args.run), str(args.target), "--window", str(args.bonus_window), "--name", args.bonus_name]
            bonus_files.main(bonus_argv)
            copied += ["bonus.md", "bonus.png", args.bonus_name]
        else:
            copied.append("no bonus files yet (no rollout logged)")
    state = "finished" if (args.run / DONE_FILE).is_file() else "still training"
    print(f"copied {args.run} -> {args.target} ({state}): {', '.join(copied)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
