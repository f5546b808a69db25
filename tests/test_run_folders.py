"""Run folders of ``python -m sb3_saeir.train``: a run moved to another place resumes by its folder's path
(``--resume FOLDER``; ``--resume`` and ``--resume N`` work as before, and their refusal of a moved run names the way),
and runs started together in one log folder get different run numbers (the folder is created exclusively)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sb3_saeir.experiment import Experiment
from sb3_saeir.train import main as train_main
from tests.run_folders import (
    TASK,
    argv,
    assert_same_parameters,
    monitor_rows,
    snapshot,
    unfinished_copy,
)


# ---------------------------------------------------------------------------------------------------- moved runs
@pytest.mark.parametrize("log_folder", ["the old one", "the new one", "the default"])
def test_a_moved_run_resumes_by_its_path(finished_tiny_run, tmp_path, monkeypatch, capsys, log_folder):
    """The run was started with ``-f <the finished run's log folder>`` and moved under ``tmp_path/moved``; its command
    with ``--resume FOLDER`` continues it there whatever ``-f`` says, and nothing is written elsewhere."""
    run = unfinished_copy(finished_tiny_run, tmp_path / "moved", moved=True)
    command = argv(finished_tiny_run.parent.parent, "--resume", str(run))
    if log_folder == "the new one":
        command[command.index("-f") + 1] = str(tmp_path / "moved")
    elif log_folder == "the default":
        del command[command.index("-f") : command.index("-f") + 2]
    before = snapshot(finished_tiny_run.parent.parent)
    monkeypatch.chdir(tmp_path)  # the default -f, logs/, is relative
    assert train_main(command) == 0, capsys.readouterr().err
    assert f"Resuming {run} from rl_model_840_steps.zip" in capsys.readouterr().out
    assert_same_parameters(run / f"{TASK}.zip", finished_tiny_run / f"{TASK}.zip")
    assert monitor_rows(run) == monitor_rows(finished_tiny_run)
    assert snapshot(finished_tiny_run.parent.parent) == before and not (tmp_path / "logs").exists()


def test_plain_resume_of_a_moved_run_names_the_way(finished_tiny_run, tmp_path, capsys):
    run = unfinished_copy(finished_tiny_run, tmp_path / "moved", moved=True)
    before = snapshot(run)
    assert train_main(argv(tmp_path / "moved", "--resume")) == 2
    err = capsys.readouterr().err
    assert f'-f "{finished_tiny_run.parent.parent}" -> "{tmp_path / "moved"}"' in err and len(err.strip().splitlines()) == 1
    assert f"If the run folder was moved, give its path instead: --resume {run}." in err
    assert snapshot(run) == before


def test_resume_by_run_number_works_as_before(finished_tiny_run, tmp_path, capsys):
    run = unfinished_copy(finished_tiny_run, tmp_path / "logs")
    assert train_main(argv(tmp_path / "logs", "--resume", "1")) == 0, capsys.readouterr().err
    assert_same_parameters(run / f"{TASK}.zip", finished_tiny_run / f"{TASK}.zip")


@pytest.mark.parametrize(
    ("target", "message"),
    [
        ("missing", "no such folder; give a run's number, or the path of a run folder"),
        ("other task", "holds a run of mappo on cn-sparse-n4: it is not a run of this command"),
        ("no run", f"has no spec.json nor {TASK}/args.yml: it is not a run of this command"),
    ],
)
def test_resume_by_a_wrong_path_is_refused_in_one_line(finished_tiny_run, tmp_path, capsys, target, message):
    folder = tmp_path / "missing"
    if target == "other task":
        folder = unfinished_copy(finished_tiny_run, tmp_path / "logs")
        spec = json.loads((folder / "spec.json").read_text())
        (folder / "spec.json").write_text(json.dumps({**spec, "task": "cn-sparse-n4"}))
    elif target == "no run":
        folder.mkdir()
        (folder / "notes.txt").write_text("not a run")
    before = snapshot(tmp_path)
    assert train_main(argv(tmp_path / "logs", "--resume", str(folder))) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err
    assert snapshot(tmp_path) == before


# ---------------------------------------------------------------------------------------------------- run numbers
SHORT = ["-n", "120", "--eval-freq", "0"]


def test_a_run_started_while_this_one_builds_takes_the_next_number(tmp_path, monkeypatch, capsys):
    """Another command starts while this one builds its model: it takes the next number, and this run's folder is
    still this run's."""
    parent = tmp_path / "logs" / "mappo"
    build = Experiment.build

    def build_while_another_run_starts(self, *args, **kwargs):
        taken = [int(path.name.rsplit("_", 1)[1]) for path in parent.glob(f"{TASK}_*")]
        (parent / f"{TASK}_{max(taken, default=0) + 1}").mkdir(parents=True)
        return build(self, *args, **kwargs)

    monkeypatch.setattr(Experiment, "build", build_while_another_run_starts)
    assert train_main(argv(tmp_path / "logs", *SHORT)) == 0, capsys.readouterr().err
    folders = {path.name: sorted(child.name for child in path.iterdir()) for path in parent.iterdir()}
    assert folders[f"{TASK}_2"] == [] and f"{TASK}.zip" in folders[f"{TASK}_1"]  # the other run's folder untouched


def test_a_run_that_claims_the_number_between_choice_and_creation_gets_the_next(tmp_path, monkeypatch, capsys):
    """Another command creates the run folder this one has just chosen, before this one creates it: this one takes the
    next number and leaves the other's folder alone (os.mkdir, not mkdir(exist_ok=True))."""
    import sb3_saeir.run.folder as folder_module

    parent = tmp_path / "logs" / "mappo"
    numbered_paths = folder_module.numbered_paths
    raced = []

    def numbered_paths_then_another_run_claims(folder, prefix, suffix=""):
        found = numbered_paths(folder, prefix, suffix)
        if not raced and Path(folder) == parent:  # the run's choice of number, once
            raced.append(max(found, default=0) + 1)
            (parent / f"{prefix}{raced[0]}").mkdir()
        return found

    monkeypatch.setattr(folder_module, "numbered_paths", numbered_paths_then_another_run_claims)
    assert train_main(argv(tmp_path / "logs", *SHORT)) == 0, capsys.readouterr().err
    assert raced == [1]
    folders = {path.name: sorted(child.name for child in path.iterdir()) for path in parent.iterdir()}
    assert folders[f"{TASK}_1"] == [] and f"{TASK}.zip" in folders[f"{TASK}_2"]


def test_a_file_with_a_run_folders_name_is_passed_over(tmp_path, capsys):
    parent = tmp_path / "logs" / "mappo"
    parent.mkdir(parents=True)
    (parent / f"{TASK}_1").write_text("a user's file")
    assert train_main(argv(tmp_path / "logs", *SHORT)) == 0, capsys.readouterr().err
    assert (parent / f"{TASK}_1").read_text() == "a user's file"
    assert (parent / f"{TASK}_2" / f"{TASK}.zip").is_file()


def test_two_runs_started_together_get_different_numbers(tmp_path):
    command = [sys.executable, "-m", "sb3_saeir.train", *argv(tmp_path / "logs", *SHORT)]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    processes = [subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE) for _ in range(2)]
    results = [process.communicate(timeout=180) for process in processes]
    assert [process.returncode for process in processes] == [0, 0], results
    parent = tmp_path / "logs" / "mappo"
    assert sorted(path.name for path in parent.iterdir()) == [f"{TASK}_1", f"{TASK}_2"]
    for folder in parent.iterdir():
        assert (folder / f"{TASK}.zip").is_file() and (folder / TASK / "args.yml").is_file()
    logged = sorted(next(line for line in out.decode().splitlines() if line.startswith("Log folder")) for out, _ in results)
    assert logged == [f"Log folder: {parent / f'{TASK}_1'}", f"Log folder: {parent / f'{TASK}_2'}"]


def test_a_refused_command_leaves_no_run_folder(tmp_path, capsys):
    assert train_main(argv(tmp_path / "logs", *SHORT, "-params", "batch_size:7")) == 2  # refused while building
    assert "batch_size=7" in capsys.readouterr().err
    assert not (tmp_path / "logs").exists()


def test_a_failed_command_leaves_a_folder_made_in_place_of_its_own(tmp_path):
    """The run folder deleted while it trained, and the user making a folder at its path: the failed command removed
    the user's folder (and the emptied parent) as if it were the one it had made."""
    from sb3_saeir.run import RunFolder

    with pytest.raises(RuntimeError), RunFolder.claim(tmp_path / "logs", "mappo", "cn-sparse-n3") as claimed:
        claimed.path.rmdir()
        claimed.path.mkdir()  # the user's
        (claimed.path / "notes.txt").write_text("the user's")
        raise RuntimeError("the run stopped")
    assert (claimed.path / "notes.txt").is_file()
    with pytest.raises(RuntimeError), RunFolder.claim(tmp_path / "other", "mappo", "cn-sparse-n3") as claimed:
        (claimed.path / "cn-sparse-n3").mkdir()  # what rl-zoo3 writes before its setup fails (config.yml, args.yml)
        (claimed.path / "cn-sparse-n3" / "config.yml").write_text("{}")
        raise RuntimeError("refused")  # its own folder, the run not recorded: removed with the parents it made
    assert not (tmp_path / "other").exists()


def test_a_claimed_folder_whose_run_recorded_itself_is_kept(tmp_path):
    """A command that fails after its run wrote ``spec.json`` (a stop, a full disk) keeps the run folder: --resume
    continues it."""
    from sb3_saeir.run import RunFolder

    with pytest.raises(KeyboardInterrupt), RunFolder.claim(tmp_path / "logs", "mappo", "cn-sparse-n3") as claimed:
        (claimed.path / "spec.json").write_text("{}")
        raise KeyboardInterrupt
    assert (claimed.path / "spec.json").is_file()
