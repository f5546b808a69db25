"""Training a run longer (``--resume`` with a larger ``-n``, and the benchmark with a larger ``-n``): a run extended
from N to 2N ends as an uninterrupted 2N run (parameters, progress.csv, monitor rows; the evaluations on the same grid
plus the shorter run's final one), its record says so, the shorter run's final model is kept; a smaller budget is
refused in one line."""

import json
import shutil

import pytest

from sb3_saeir.benchmark import RunSpec, run_folder
from sb3_saeir.benchmark import main as benchmark_main
from sb3_saeir.config import ALGOS
from sb3_saeir.train import main as train_main
from tests.run_folders import TASK, argv, assert_same_parameters, monitor_rows, read_rows, snapshot

LONGER = 1800  # twice the tiny run's 900 agent-steps


def with_budget(command, n_timesteps):
    command = list(command)
    command[command.index("-n") + 1] = str(n_timesteps)
    return command


@pytest.fixture(scope="module")
def longer_run(tmp_path_factory):
    """The tiny run trained uninterrupted to 1,800 agent-steps."""
    log_folder = tmp_path_factory.mktemp("longer")
    assert train_main(with_budget(argv(log_folder), LONGER)) == 0
    return log_folder / "mappo" / f"{TASK}_1"


def progress(folder):
    """progress.csv without the wall-clock columns."""
    rows = read_rows(folder / "progress.csv")
    keys = [key for key in rows[0] if not key.startswith("time/") or key in ("time/iterations", "time/total_timesteps")]
    return [[row.get(key) for key in keys] for row in rows]


def evaluations(folder):
    return [
        (int(row["timesteps"]), row["coverage_rate_mean"], row["ep_rew_mean"]) for row in read_rows(folder / "evaluations.csv")
    ]


def test_a_finished_run_trained_longer_ends_as_the_longer_run(finished_tiny_run, longer_run, tmp_path, capsys):
    log_folder = tmp_path / "logs"
    folder = log_folder / "mappo" / f"{TASK}_1"
    shutil.copytree(finished_tiny_run, folder)
    spec = json.loads((folder / "spec.json").read_text())
    spec["options"]["-f"] = str(log_folder)
    (folder / "spec.json").write_text(json.dumps(spec))
    done_before = json.loads((folder / "done.json").read_text())

    assert train_main(with_budget(argv(log_folder, "--resume"), LONGER)) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "Training longer: budget 900 -> 1,800 agent-steps" in out and f"from {TASK}.zip" in out

    assert_same_parameters(folder / f"{TASK}.zip", longer_run / f"{TASK}.zip")
    assert progress(folder) == progress(longer_run)
    assert monitor_rows(folder) == monitor_rows(longer_run)
    # the same grid, and the shorter run's final evaluation (900 is not on the 250-grid) kept where it was made
    extended, uninterrupted = evaluations(folder), evaluations(longer_run)
    assert [row for row in extended if row[0] != 900] == uninterrupted
    assert [row[0] for row in extended].count(900) == 1
    # the record: the new budget, the extension with the shorter run's done.json; the shorter run's model kept
    record = json.loads((folder / "spec.json").read_text())
    assert record["n_timesteps"] == LONGER and len(record["extensions"]) == 1
    extension = record["extensions"][0]
    assert (extension["from"], extension["to"], extension["finished"]) == (900, LONGER, done_before)
    assert_same_parameters(folder / f"{TASK}_900_steps.zip", finished_tiny_run / f"{TASK}.zip")
    assert json.loads((folder / "done.json").read_text())["timesteps"] == LONGER
    assert "trained longer: budget 900 -> 1,800" in (folder / "resume.log").read_text()


def test_the_same_budget_again_is_refused_as_finished(finished_tiny_run, capsys):
    before = snapshot(finished_tiny_run)
    assert train_main(argv(finished_tiny_run.parent.parent, "--resume")) == 2
    err = capsys.readouterr().err
    assert "is finished" in err and "give a larger -n to train it longer" in err
    assert snapshot(finished_tiny_run) == before


def test_a_smaller_budget_is_refused_in_one_line(finished_tiny_run, capsys):
    before = snapshot(finished_tiny_run)
    assert train_main(with_budget(argv(finished_tiny_run.parent.parent, "--resume"), 600)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "-n 600 is smaller than the budget of the run" in err and "(900 agent-steps)" in err and "-n 900" in err
    assert snapshot(finished_tiny_run) == before


def test_a_run_whose_final_model_has_no_resume_state_names_the_way(finished_tiny_run, tmp_path, capsys):
    """A run finished by an older version (its final model without a resume state) and without checkpoints."""
    folder = tmp_path / "mappo" / f"{TASK}_1"
    shutil.copytree(finished_tiny_run, folder)
    for checkpoint in folder.glob("rl_model_*_steps.zip"):
        checkpoint.unlink()
    model = ALGOS["mappo"].load(folder / f"{TASK}.zip", device="cpu")
    model.save(folder / f"{TASK}.zip")  # a plain SB3 save: no resume state
    before = snapshot(folder)
    assert train_main(with_budget(argv(tmp_path, "--resume", str(folder)), LONGER)) == 2
    err = capsys.readouterr().err
    assert "holds no resume state" in err and f"-i {folder / f'{TASK}.zip'}" in err
    assert snapshot(folder) == before


# ---------------------------------------------------------------------------------------------------- benchmark
BENCHMARK = ["--algos", "mappo", "--tasks", TASK, "--seeds", "1", "--n-games", "2", "--eval-freq", "250",
             "--eval-episodes", "2", "-params", "n_steps:10", "n_epochs:2"]  # fmt: skip


def test_the_benchmark_trains_a_finished_run_longer(tmp_path, capsys):
    extended, uninterrupted = tmp_path / "extended", tmp_path / "uninterrupted"
    assert benchmark_main([*BENCHMARK, "-n", "900", "--out", str(extended)]) == 0
    assert benchmark_main([*BENCHMARK, "-n", str(LONGER), "--out", str(extended)]) == 0
    assert benchmark_main([*BENCHMARK, "-n", str(LONGER), "--out", str(uninterrupted)]) == 0
    capsys.readouterr()
    folders = [run_folder(out, RunSpec("mappo", TASK, 1, LONGER)) for out in (extended, uninterrupted)]
    assert_same_parameters(folders[0] / f"{TASK}.zip", folders[1] / f"{TASK}.zip")
    rows, expected = evaluations(folders[0]), evaluations(folders[1])
    assert [row for row in rows if row[0] != 900] == expected
    # the benchmark's report shows the extended budget (the last row of the run at 1,800 agent-steps)
    assert max(int(row["timesteps"]) for row in read_rows(extended / "runs.csv")) == LONGER
    assert json.loads((folders[0] / "spec.json").read_text())["extensions"][0]["to"] == LONGER
    # run again with the longer budget: finished, skipped
    before = snapshot(folders[0])
    assert benchmark_main([*BENCHMARK, "-n", str(LONGER), "--out", str(extended)]) == 0
    assert "mappo/cn-sparse-n3_s1: skipped" in capsys.readouterr().out
    assert snapshot(folders[0]) == before
    # a smaller budget: refused, nothing written
    assert benchmark_main([*BENCHMARK, "-n", "600", "--out", str(extended)]) == 2
    assert "-n 1800 -> 600 (a run is not trained shorter" in capsys.readouterr().err
    assert snapshot(folders[0]) == before


def test_extension_record_keeps_earlier_extensions():
    from sb3_saeir.run.record import extension_record

    stored = {"n_timesteps": 900, "config": {"n_timesteps": 900.0}, "extensions": [{"from": 450, "to": 900}]}
    record = extension_record(stored, 1800, {"timesteps": 900})
    assert record["n_timesteps"] == 1800 and record["config"]["n_timesteps"] == 1800
    assert [(e["from"], e["to"]) for e in record["extensions"]] == [(450, 900), (900, 1800)]
    assert record["extensions"][1]["finished"] == {"timesteps": 900}
    assert stored["n_timesteps"] == 900 and len(stored["extensions"]) == 1  # not changed in place


def test_a_run_recorded_by_another_version_is_named_where_it_goes_on(finished_tiny_run, tmp_path, capsys):
    """Training a run of another sb3-saeir version longer says so in one line; segments.json records the version of
    each segment (the record kept the old version without a word)."""
    from sb3_saeir import __version__

    log_folder = tmp_path / "logs"
    folder = log_folder / "mappo" / f"{TASK}_1"
    shutil.copytree(finished_tiny_run, folder)
    spec = json.loads((folder / "spec.json").read_text())
    spec["options"]["-f"] = str(log_folder)
    spec["version"] = "0.1.0"
    (folder / "spec.json").write_text(json.dumps(spec))
    assert train_main(with_budget(argv(log_folder, "--resume"), LONGER)) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if "sb3-saeir 0.1.0" in line]
    assert len(lines) == 1 and f"recorded by sb3-saeir 0.1.0 and goes on with {__version__}" in lines[0]
    segments = json.loads((folder / "segments.json").read_text())
    assert segments[-1]["version"] == __version__
