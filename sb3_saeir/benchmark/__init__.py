"""Benchmark runner: methods x tasks x seeds -> ``runs.csv``, the paper's Table 1 layout and learning curves.

    python -m sb3_saeir.benchmark --algos saeir_ppo mappo --tasks cn-sparse-n3 --seeds 1-3 \
        --n-timesteps 1000000 --n-games 16 --eval-freq 50000 --eval-episodes 50 --jobs 2 --out results/cn3

Each run trains with the packaged config of its method (``zoo_configs/<algo>.yml``; ``--n-games`` and ``-params``
override it) and evaluates at 0 agent-steps, at the first agent-step count >= k * ``--eval-freq`` (k = 1, 2, ...)
and at the end, on game episodes. Every evaluation reseeds the evaluation env with the same seed (``10_000 + seed``)
before it starts, so every evaluation of a run plays the same ``--eval-episodes`` episodes. Output folder:

- ``runs/<algo>/<task>_s<seed>/``: a :class:`~sb3_saeir.run.Run`'s folder, as a ``train`` run's (:mod:`sb3_saeir.run`
  lists the files): ``spec.json`` (the run's settings: algo, task, seed, n_timesteps, n_games, eval_freq,
  eval_episodes, params, the config entry it trains with, the package version), ``evaluations.csv`` (one row per
  evaluation), ``evaluations.npz`` and ``best_model.zip``, ``progress.csv`` (SB3 logger, continued over resumes),
  ``games.monitor.csv``, ``rl_model_<steps>_steps.zip`` (the newest two checkpoints, for resuming),
  ``segments.json`` (wall time of each process that worked on the run), ``resume.log`` (what each resume did),
  ``done.json`` and ``<task>.zip`` (when finished: total wall time over the segments, agent-steps; the final model,
  for ``enjoy`` or ``benchmarks/bonus_readings.py``);
- ``runs.csv``: every evaluation row of the command's runs (algo, task, seed, agent-steps, env steps, metrics);
- ``table.md``: mean ± std over seeds at the final evaluation, best method in bold (the paper's Table 1 layout);
- ``curves.png``: one panel per task, mean line and std band per method, x axis in env steps (game steps);
- ``aggregate.md`` with ``--rliable``: IQM and 95% stratified-bootstrap confidence intervals of the final main metric
  (the bootstrap is seeded: reporting the same runs again writes the same intervals; below 4 seeds the IQM trims none
  and equals the mean, which a line under the table says), then every pair of methods: the
  difference of the means, how often one ends above the other over the pairs of seeds, and the two-sided Mann-Whitney
  U test's p-value, to tell which differences are larger than the seed spread.

**Settings are never mixed.** Before any training the command compares every planned run with the ``spec.json`` of
its folder; when one differs (another ``-n``, ``-params``, ``--n-games``, ``--eval-freq``, ``--eval-episodes``, or
an edited config), it refuses with one line per run naming what differs, and exit status 2: use another ``--out``,
or ``--rerun-changed`` to move those folders aside (``<folder>.replaced-<UTC time>``, nothing is deleted) and train
them again. A larger ``-n`` is a different run too, not an extension: learning-rate and clip schedules depend on the
total budget, the shorter run's final (off-grid) evaluation would sit in the curve, and a finished run keeps no
checkpoint. ``runs.csv``, ``table.md`` and ``curves.png`` hold only runs whose spec matches the command, and only
the command's runs: when the folder holds others (an earlier command's methods or seeds), the command names them;
``--report-only`` with all their methods, tasks and seeds reports them together.

**Resuming loses nothing.** Re-running the same command skips finished runs and resumes interrupted ones from their
checkpoint, taken at the start of every rollout after the first. A checkpoint is the SB3 model zip with one more
entry, ``resume_state.pkl``: the torch, NumPy and ``random`` generator states, the model's last observations,
episode starts and GRU states, its episode-info buffers, the training env's state (the native navigation env's
``get_resume_state``: arrays and per-game generators), the intrinsic-reward callbacks (RND, Elign: networks,
optimisers, running statistics) and the logger's values not yet written. It is written to a temporary file and moved
into place with ``os.replace``, so a kill during a save leaves the previous checkpoint whole. A run killed at any
moment (even SIGKILL) and re-run ends with the same ``runs.csv`` rows as an uninterrupted run of the same seed.
Envs without ``get_resume_state`` (the games stepped through ``MultiAgentVecEnv``: football, mpe2's world) resume
approximately: the training env restarts from a reset, and ``resume.log`` says so. On resume ``progress.csv`` keeps
its rows up to the checkpoint and goes on; evaluations made after the checkpoint are re-done (``resume.log`` says
whether each came out identical); ``wall_s`` in ``done.json`` sums the segments (each counted up to its last
checkpoint or evaluation). Ctrl-C stops every job and prints "interrupted: re-run the same command to resume"
(exit status 130).

A failing run is reported in ``failures.txt`` and does not stop the others. ``--ray-address`` runs them on a Ray
cluster instead of local processes (results gathered into the same folder; resuming from checkpoints needs a shared
filesystem). ``--entropy-plot RUN_FOLDER`` draws the SAEIR bonus, its fire rate and the value-softmax entropy over training for
one run (``system_entropy.png`` in the run's folder) and prints the fire rate and entropy per scale.

The package's modules, one concern each: :mod:`~sb3_saeir.benchmark.runs` (run folders, the comparison of
``spec.json`` with the command), :mod:`~sb3_saeir.benchmark.execution` (one run as a :class:`~sb3_saeir.run.Run`;
local processes and Ray), :mod:`~sb3_saeir.benchmark.reports` (the
tables and figures), :mod:`~sb3_saeir.benchmark.statistics` (final scores, IQM, Mann-Whitney) and
:mod:`~sb3_saeir.benchmark.cli` (the command line). The run itself is :mod:`sb3_saeir.run`,
shared with ``python -m sb3_saeir.train``; its checkpoints and continued logger are :mod:`sb3_saeir.common.run_state`.
"""

from sb3_saeir.benchmark.cli import INTERRUPTED, check_runs_build, main, plan_runs, prepare_folders, refusal
from sb3_saeir.benchmark.execution import BenchmarkEvalCallback, execute_run, run_all
from sb3_saeir.benchmark.reports import (
    collect,
    format_steps,
    numeric_series,
    plot_curves,
    plot_system_entropy,
    report,
    system_entropy_summary,
    table_markdown,
    unfinished_runs,
)
from sb3_saeir.benchmark.runs import (
    CHECKPOINT_NAME,
    SPEC_FILE,
    SPEC_SETTINGS,
    RunLog,
    RunSpec,
    ensure_spec_file,
    move_aside,
    parse_seeds,
    read_rows,
    run_folder,
    spec_differences,
    spec_record,
    stored_spec_differences,
    write_rows,
)
from sb3_saeir.benchmark.statistics import (
    METRIC_COLUMNS,
    final_rows,
    final_scores,
    main_metric,
    mann_whitney,
    pairwise_markdown,
    rliable_markdown,
    table_columns,
)

__all__ = [
    "CHECKPOINT_NAME",
    "INTERRUPTED",
    "METRIC_COLUMNS",
    "SPEC_FILE",
    "SPEC_SETTINGS",
    "BenchmarkEvalCallback",
    "RunLog",
    "RunSpec",
    "check_runs_build",
    "collect",
    "ensure_spec_file",
    "execute_run",
    "final_rows",
    "final_scores",
    "format_steps",
    "main",
    "main_metric",
    "mann_whitney",
    "move_aside",
    "numeric_series",
    "pairwise_markdown",
    "parse_seeds",
    "plan_runs",
    "plot_curves",
    "plot_system_entropy",
    "prepare_folders",
    "read_rows",
    "refusal",
    "report",
    "rliable_markdown",
    "run_all",
    "run_folder",
    "spec_differences",
    "spec_record",
    "stored_spec_differences",
    "system_entropy_summary",
    "table_columns",
    "table_markdown",
    "unfinished_runs",
    "write_rows",
]
