"""The small files of a SAEIR run's bonus, for a study's folder of committed run files.

    python benchmarks/bonus_files.py RUN TARGET --window 250000 --name bonus_by_250k.md

From a benchmark run folder ``RUN`` whose ``progress.csv`` logged the bonus (``rollout/intrinsic_fire_rate_<scale>``;
``progress.csv`` itself is not committed), writes into ``TARGET``:

- ``bonus.md``: the table of ``python -m sb3_saeir.benchmark --entropy-plot RUN`` (per scale the fire rate over all
  rollouts and over their last 10%, the first and last value-softmax entropy), under the command that made it;
- ``bonus.png``: the ``system_entropy.png`` that command writes into ``RUN``;
- ``--name`` (default ``bonus_by_window.md``): per ``--window`` env steps the fire rate and mean bonus per scale and
  each critic's value-softmax entropy, and the episode starts per env step (:func:`learning_speed.bonus_windows`).
"""

from __future__ import annotations

import argparse
import io
import shutil
from contextlib import redirect_stdout
from pathlib import Path

from learning_speed import bonus_windows

from sb3_saeir.benchmark import main as benchmark_main


def entropy_plot_table(run: Path) -> list[str]:
    """The table lines the benchmark's ``--entropy-plot`` prints for ``run`` (it also writes ``system_entropy.png``)."""
    printed = io.StringIO()
    with redirect_stdout(printed):
        status = benchmark_main(["--entropy-plot", str(run)])
    if status != 0:
        raise SystemExit(f"bonus_files: --entropy-plot {run} failed (exit status {status}).")
    return [line for line in printed.getvalue().splitlines() if line.startswith("|")]


def shown(path: Path) -> str:
    """``path`` with the home folder written ``$HOME`` (the committed files do not name the machine's user)."""
    home = str(Path.home())
    text = str(path)
    return "$HOME" + text[len(home) :] if text == home or text.startswith(home + "/") else text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path, help="a SAEIR run folder with its progress.csv and spec.json")
    parser.add_argument("target", type=Path, help="the folder that receives bonus.md, bonus.png and --name")
    parser.add_argument("--window", type=float, required=True, help="env steps per row of the windowed table")
    parser.add_argument("--name", default="bonus_by_window.md", help="file name of the windowed table")
    args = parser.parse_args(argv)
    if not (args.window > 0):
        parser.error(f"--window must be positive, got {args.window}")
    if not (args.run / "progress.csv").is_file():
        parser.error(f"no progress.csv in {args.run}")
    args.target.mkdir(parents=True, exist_ok=True)
    table = entropy_plot_table(args.run)
    command = f"`python -m sb3_saeir.benchmark --entropy-plot {shown(args.run)}`"
    intro = [command, "(`bonus.png` is the `system_entropy.png` it wrote into the run folder):", ""]
    (args.target / "bonus.md").write_text("\n".join([*intro, *table]) + "\n")
    shutil.copyfile(args.run / "system_entropy.png", args.target / "bonus.png")
    window = f"{args.window / 1e6:g}M" if args.window >= 1e6 else f"{args.window / 1e3:g}k"
    heading = (
        f"Per {window} env steps: the bonus's fire rate and mean before beta per scale, and each critic's value-softmax "
        f"entropy where the run logged it, and the episode starts per env step (1 / mean episode length), which bounds "
        f"a bonus that fires only at episode starts (`benchmarks/learning_speed.py ... --bonus {args.run.name}`):"
    )
    (args.target / args.name).write_text("\n".join([heading, "", *bonus_windows(args.run, args.window)]) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
