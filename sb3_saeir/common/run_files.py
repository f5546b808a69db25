"""The names of a run folder's files, one constant each: what each holds is ``docs/guide/training.md``, "The run
folder" (the one description of the layout)."""

SPEC_FILE = "spec.json"
CONFIG_FILE = "config.yml"  # in <task>/, as rl-zoo3 writes it
ARGS_FILE = "args.yml"  # in <task>/, as rl-zoo3 writes it
CHECKPOINT_NAME = "rl_model_{steps}_steps.zip"
LEGACY_CHECKPOINT = "checkpoint.zip"  # the benchmark's one checkpoint before this layout: read, never written
EVALUATIONS_FILE = "evaluations.csv"
BEST_MODEL_FILE = "best_model.zip"
PROGRESS_FILE = "progress.csv"
MONITOR_PREFIX = "games"  # -> games.monitor.csv
SEGMENTS_FILE = "segments.json"
RESUME_LOG = "resume.log"
FINAL_MODEL = "{task}.zip"
SHORTER_RUN_MODEL = "{task}_{steps}_steps.zip"  # the final model of a run later trained longer
DONE_FILE = "done.json"
