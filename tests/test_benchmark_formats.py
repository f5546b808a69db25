"""The benchmark's formats outlive changes of its code: a folder of runs interrupted by an earlier version (the one
module ``sb3_saeir/benchmark.py``, commit cf63ac6) resumes and ends with that version's uninterrupted rows, and
every committed result folder under ``docs/results/`` re-reports to the same ``table.md`` and ``aggregate.md``."""

import csv
import shutil
from pathlib import Path

import pytest

from sb3_saeir.benchmark import main, pairwise_markdown, read_rows, rliable_markdown, table_markdown

DATA = Path(__file__).parent / "data"
RESULTS = Path(__file__).parent.parent / "docs" / "results"
# the command that made tests/data/interrupted_benchmark (tests/data/make_interrupted_benchmark.py)
ARGV = [
    "--algos", "mappo", "saeir_ppo", "--tasks", "cn-sparse-n3", "--seeds", "1", "-n", "900", "--n-games", "2",
    "--eval-freq", "250", "--eval-episodes", "2", "-params", "n_steps:10", "n_epochs:2",
]  # fmt: skip
RESULT_FOLDERS = sorted(folder for folder in RESULTS.iterdir() if (folder / "runs.csv").is_file())


def read_csv(path):
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def test_runs_interrupted_by_an_earlier_version_resume(tmp_path):
    out = tmp_path / "benchmark"
    shutil.copytree(DATA / "interrupted_benchmark", out)
    assert main([*ARGV, "--out", str(out)]) == 0
    for algo in ("mappo", "saeir_ppo"):
        log = (out / "runs" / algo / "cn-sparse-n3_s1" / "resume.log").read_text()
        assert "resumed from the checkpoint at 480 agent-steps" in log
        assert "approximately" not in log and "different from" not in log
    assert read_csv(out / "runs.csv") == read_csv(DATA / "expected_runs.csv")


def test_there_are_result_folders_to_re_report():
    assert len(RESULT_FOLDERS) >= 10


@pytest.mark.parametrize("folder", RESULT_FOLDERS, ids=lambda folder: folder.name)
def test_committed_results_re_report_byte_for_byte(folder):
    rows = read_rows(folder / "runs.csv")
    assert table_markdown(rows) == (folder / "table.md").read_text()
    if (folder / "aggregate.md").is_file():
        assert rliable_markdown(rows) + "\n" + pairwise_markdown(rows) == (folder / "aggregate.md").read_text()
