"""benchmarks/bonus_files.py: a SAEIR run's bonus files for a study folder (the entropy-plot table, its figure, the
windowed table with the value-softmax entropy)."""

import pytest


@pytest.fixture(scope="module")
def bonus_files(load_benchmark_script):
    return load_benchmark_script("bonus_files")


def test_files_of_a_benchmark_run(bonus_files, tiny_saeir_benchmark_run, tmp_path):
    run = tiny_saeir_benchmark_run
    target = tmp_path / "study" / "run"
    assert bonus_files.main([str(run), str(target), "--window", "50", "--name", "bonus_by_50.md"]) == 0
    table = (target / "bonus.md").read_text().splitlines()
    assert table[0] == f"`python -m sb3_saeir.benchmark --entropy-plot {run}`"
    assert table[3].startswith("| scale | fire rate (all rollouts) |")
    assert [line.split(" | ")[0] for line in table[5:]] == ["| group", "| individual", "| team"]
    assert (target / "bonus.png").read_bytes() == (run / "system_entropy.png").read_bytes()
    windowed = (target / "bonus_by_50.md").read_text().splitlines()
    assert windowed[0].startswith("Per 0.05k env steps:")
    assert windowed[2].endswith("| value entropy individual | value entropy team | episode starts per step |")
    # 450 agent-steps = 150 env steps in rollouts of 50: three windows of 50 env steps, one rollout each
    assert [line.split(" | ")[0] for line in windowed[4:]] == ["| 0M-5e-05M", "| 5e-05M-0.0001M", "| 0.0001M-0.00015M"]


def test_shown_paths_hide_the_home_folder(bonus_files, tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    assert bonus_files.shown(tmp_path / "saeir-results" / "run") == "$HOME/saeir-results/run"
    assert bonus_files.shown(tmp_path.parent / "other") == str(tmp_path.parent / "other")


def test_a_run_without_progress_is_refused(bonus_files, tmp_path, capsys):
    with pytest.raises(SystemExit):
        bonus_files.main([str(tmp_path), str(tmp_path / "out"), "--window", "10"])
    assert f"no progress.csv in {tmp_path}" in capsys.readouterr().err
