"""``python -m sb3_saeir.train --resume`` on a damaged run folder: a checkpoint that does not load is skipped (one line
names it and keeps it aside) and the run goes on from the newest one that loads, ending as the run uninterrupted; a
damaged ``spec.json`` (or, for a run of an older version, ``args.yml`` or ``config.yml``) is refused in one line naming
the file and the fix, nothing written; rows of ``games.monitor.csv``
that are cut, deleted or damaged are written again from the checkpoint, and rows of ``progress.csv`` that cannot be
restored are counted in a note naming the file (the damaged file is kept), never dropped without a word."""

import json
import os
import re
import shutil
import zipfile

import pytest

from sb3_saeir.train import main as train_main
from tests.run_folders import (
    LAST_CHECKPOINT,
    LEGACY_RUN,
    LEGACY_SETTINGS,
    TASK,
    argv,
    assert_same_parameters,
    checkpoint,
    monitor_rows,
    read_rows,
    snapshot,
    unfinished_copy,
)


@pytest.fixture
def run(finished_tiny_run, tmp_path):
    """A copy of the run stopped after its last checkpoint (840 agent-steps)."""
    return unfinished_copy(finished_tiny_run, tmp_path / "logs")


def resume(run, capsys):
    """``--resume`` the run; returns the exit status, stdout and stderr."""
    status = train_main(argv(run.parent.parent, "--resume"))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


# ---------------------------------------------------------------------------------------------------- checkpoints
def cut(path, fraction=0.5):
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * fraction)])


def flip_a_byte(path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF  # inside policy.pth or the optimizer's state: the CRC check fails
    path.write_bytes(bytes(data))


def not_a_zip(path):
    path.write_text("not a zip file\n")


def stopped_save(path):
    """The zip as SB3's save leaves it when Ctrl-C stops it: closed, without the entries written last."""
    with zipfile.ZipFile(path) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in entries.items():
            if name not in ("_stable_baselines3_version", "system_info.txt"):
                archive.writestr(name, data)


DAMAGED_CHECKPOINTS = {
    "cut at 50%": (cut, [840]),
    "cut to 0 bytes": (lambda path: cut(path, 0.0), [840]),
    "a byte flipped": (flip_a_byte, [840]),
    "not a zip": (not_a_zip, [840]),
    "save stopped by Ctrl-C": (stopped_save, [840]),
    "the two newest cut": (cut, [840, 720]),
}


@pytest.mark.parametrize("damage", list(DAMAGED_CHECKPOINTS))
def test_resume_falls_back_to_the_newest_checkpoint_that_loads(finished_tiny_run, run, capsys, damage):
    damage_file, steps = DAMAGED_CHECKPOINTS[damage]
    for step in steps:
        damage_file(checkpoint(run, step))
    status, out, err = resume(run, capsys)
    assert status == 0, err
    notes = [line for line in out.splitlines() if line.startswith("Note: skipped")]
    assert len(notes) == 1, out
    assert all(checkpoint(run, step).name in notes[0] for step in steps), notes
    resumed_from = checkpoint(run, min(steps) - 120)
    assert f"Resuming {run} from {resumed_from.name}" in out
    assert_same_parameters(run / f"{TASK}.zip", finished_tiny_run / f"{TASK}.zip")  # the run ends as uninterrupted
    assert monitor_rows(run) == monitor_rows(finished_tiny_run)


def test_no_checkpoint_that_loads_is_refused_in_one_line(run, capsys):
    for path in run.glob("rl_model_*_steps.zip"):
        cut(path, 0.3)
    before = snapshot(run)
    status, _, err = resume(run, capsys)
    assert status == 2 and len(err.strip().splitlines()) == 1, err
    assert f"no checkpoint of {run} loads" in err and "rl_model_120_steps.zip: BadZipFile" in err
    assert snapshot(run) == before


# ---------------------------------------------------------------------------------------------------- spec.json, args.yml
DAMAGED_SPEC_FILES = [
    (b"{not json", "not valid JSON"),
    (b"[1, 2]", "not a JSON object"),
    (b"\xff\xfe\x00\x01 binary", "not valid JSON"),
]


@pytest.mark.parametrize(("content", "problem"), DAMAGED_SPEC_FILES)
def test_a_damaged_spec_file_is_named_and_nothing_written(run, capsys, content, problem):
    path = run / "spec.json"
    path.write_bytes(content)
    before = snapshot(run)
    status, _, err = resume(run, capsys)
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert f"{path} is damaged ({problem}" in err and "restore it from a copy" in err, err
    assert snapshot(run) == before


DAMAGED_RUN_FILES = [
    ("args.yml", b"seed: [1, 2\n", "not valid YAML"),
    ("args.yml", b"- mappo\n- 3\n", "not a mapping of args, but list"),
    ("args.yml", b"", "not a mapping of args, but NoneType"),
    ("args.yml", b"algo: mappo\ntask: cn-sparse-n3\n", "no integer seed"),
    ("args.yml", b"\xff\xfe\x00\x01 binary", "not valid YAML"),
    ("config.yml", b"n_steps: 10\n  gamma: [0.99\n", "not valid YAML"),
    ("config.yml", b"just a string\n", "not a mapping of config, but str"),
]


@pytest.mark.parametrize(("name", "content", "problem"), DAMAGED_RUN_FILES)
def test_a_damaged_run_file_of_an_older_run_is_named_and_nothing_written(tmp_path, capsys, name, content, problem):
    """A run of an older version keeps its settings in ``<task>/args.yml`` and ``<task>/config.yml``."""
    run = tmp_path / "run"
    shutil.copytree(LEGACY_RUN, run)
    path = run / TASK / name
    path.write_bytes(content)
    before = snapshot(run)
    status = train_main(["--algo", "mappo", *LEGACY_SETTINGS, "-f", str(tmp_path / "logs"), "--resume", str(run)])
    err = capsys.readouterr().err
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert f"{path} is damaged ({problem}" in err and "restore it from a copy" in err, err
    assert snapshot(run) == before


MISSING = object()  # a record without a seed
DAMAGED_SEEDS = {"a string": "zero", "a fraction": 1.5, "missing": MISSING, "a bool": True, "negative": -1}


def with_seed(path, seed):
    """Write ``seed`` into the ``spec.json`` at ``path`` (:data:`MISSING`: no seed)."""
    record = json.loads(path.read_text())
    if seed is MISSING:
        del record["seed"]
    else:
        record["seed"] = seed
    path.write_text(json.dumps(record))


def damaged_seed_message(path, seed):
    shown = "missing" if seed is MISSING else repr(seed)
    return f"--resume: {path} is damaged (its seed is {shown}, not a seed 0 .. 2**32 - 1); restore it from a copy."


@pytest.mark.parametrize("damage", list(DAMAGED_SEEDS))
def test_a_damaged_seed_in_the_spec_file_is_named_and_nothing_written(run, capsys, damage):
    """``"zero"`` and a missing seed crashed (``ValueError``, ``KeyError``); 1.5 was taken as 1 and refused as made with
    other settings (``seed 1.5 -> 1``) though no ``--seed`` was given; ``True`` and -1 were taken."""
    seed = DAMAGED_SEEDS[damage]
    path = run / "spec.json"
    with_seed(path, seed)
    before = snapshot(run)
    command = argv(run.parent.parent, "--resume")
    del command[command.index("--seed") : command.index("--seed") + 2]  # no --seed: the run's own
    status = train_main(command)
    err = capsys.readouterr().err
    assert status == 2, err
    (line,) = err.strip().splitlines()
    assert line == f"sb3_saeir.train: error: {damaged_seed_message(path, seed)}"
    assert snapshot(run) == before


def test_a_damaged_seed_of_a_zoo_run_is_named_and_nothing_written(tmp_path, capsys):
    pytest.importorskip("rl_zoo3")
    from sb3_saeir.zoo.launcher import main as zoo_main

    folder = tmp_path / "mappo" / f"{TASK}_1"
    folder.mkdir(parents=True)
    (folder / "spec.json").write_text(json.dumps({"algo": "mappo", "task": TASK, "seed": "zero", "n_timesteps": 600}))
    before = snapshot(folder)
    assert zoo_main(["train", "--algo", "mappo", "--env", TASK, "-f", str(tmp_path), "--resume"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line == f"sb3_saeir.zoo: error: {damaged_seed_message(folder / 'spec.json', 'zero')}"
    assert snapshot(folder) == before


# ---------------------------------------------------------------------------------------------------- not writable
def refuse_writes_in(monkeypatch, folder):
    """``os.access`` says ``folder`` (or a file in it) cannot be written, as it says to a user without the
    permission (root may write anywhere: the tests run as root on some machines)."""
    real_access = os.access

    def access(path, mode, *args, **kwargs):
        if mode & os.W_OK and (os.fspath(path) == os.fspath(folder) or os.path.dirname(os.fspath(path)) == os.fspath(folder)):
            return False
        return real_access(path, mode, *args, **kwargs)

    monkeypatch.setattr(os, "access", access)


def test_unwritable_run_folder_names_the_folder_or_the_file(tmp_path, monkeypatch):
    """:func:`~sb3_saeir.run.folder.check_run_folder_writable` (the one check of ``train``, ``zoo train`` and the
    benchmark), with the permission probe answering as for a user without the permission."""
    from sb3_saeir.config import ConfigError
    from sb3_saeir.run.folder import check_run_folder_writable, unwritable_run_folder

    (tmp_path / "resume.log").write_text("")
    assert unwritable_run_folder(tmp_path) == ""
    refuse_writes_in(monkeypatch, tmp_path)
    assert unwritable_run_folder(tmp_path) == f"{tmp_path} is not writable"
    with pytest.raises(ConfigError) as error:
        check_run_folder_writable(tmp_path)
    message = str(error.value)
    assert "\n" not in message and message.startswith(f"--resume: the run in {tmp_path} cannot go on there (")
    assert f"chmod -R u+w {tmp_path}" in message and "copy the run to a folder you can write and --resume the copy" in message
    monkeypatch.undo()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode: not str(path).endswith("resume.log") and real_access(path, mode))
    assert unwritable_run_folder(tmp_path) == f"{tmp_path / 'resume.log'} is not writable"


def test_a_resume_in_a_folder_that_cannot_be_written_is_refused_before_anything_is_printed(run, capsys, monkeypatch):
    """``Resuming ...`` was printed, then a ``PermissionError`` traceback on ``resume.log``."""
    before = snapshot(run)
    refuse_writes_in(monkeypatch, run)
    status, out, err = resume(run, capsys)
    assert status == 2, err
    (line,) = err.strip().splitlines()
    assert f"--resume: the run in {run} cannot go on there ({run} is not writable)" in line
    assert out == "" and snapshot(run) == before


def test_zoo_and_benchmark_runs_in_a_folder_that_cannot_be_written_are_refused(tmp_path, capsys, monkeypatch):
    pytest.importorskip("rl_zoo3")
    from sb3_saeir.benchmark import main as benchmark_main
    from sb3_saeir.zoo.launcher import main as zoo_main

    folder = tmp_path / "mappo" / f"{TASK}_1"
    folder.mkdir(parents=True)
    (folder / "spec.json").write_text(json.dumps({"algo": "mappo", "task": TASK, "seed": 0}))
    out = tmp_path / "bench"
    bench = ["--algos", "mappo", "--seeds", "1", "-n", "120", "--n-games", "2", "-params", "n_steps:10", "--out", str(out)]
    assert benchmark_main([*bench, "-n", "60"]) == 0
    run_folder = out / "runs" / "mappo" / f"{TASK}_s1"
    capsys.readouterr()
    before = snapshot(tmp_path)
    for refused in (folder, run_folder):
        refuse_writes_in(monkeypatch, refused)
    assert zoo_main(["train", "--algo", "mappo", "--env", TASK, "-f", str(tmp_path), "--resume"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"sb3_saeir.zoo: error: --resume: the run in {folder} cannot go on there ({folder} is not writable)" in line
    assert benchmark_main(bench) == 2  # -n 120: the finished run goes on
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"mappo/{TASK}_s1: the run in {run_folder} cannot go on there ({run_folder} is not writable)" in line
    assert "give the copy's benchmark folder as --out" in line
    assert snapshot(tmp_path) == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write in a folder without write permission")
def test_a_resume_in_a_read_only_folder_is_refused(run, capsys):
    before = snapshot(run)
    os.chmod(run, 0o555)
    try:
        status, out, err = resume(run, capsys)
    finally:
        os.chmod(run, 0o755)
    assert status == 2 and out == "", err
    (line,) = err.strip().splitlines()
    assert f"--resume: the run in {run} cannot go on there" in line and "make the folder and its files writable" in line
    assert snapshot(run) == before


# ---------------------------------------------------------------------------------------------------- games.monitor.csv
def cut_mid_row(path, fraction):
    text = path.read_bytes()
    cut_at = int(len(text) * fraction)
    while text[cut_at - 1 : cut_at] in (b"\n", b"\r"):  # inside a row, not at its end
        cut_at -= 1
    path.write_bytes(text[:cut_at])


def replace_line(path, number, text):
    lines = path.read_bytes().split(b"\n")
    lines[number] = text
    path.write_bytes(b"\n".join(lines))


DAMAGED_MONITORS = {
    "cut mid-row at 40%": (lambda path: cut_mid_row(path, 0.4), "written again from the checkpoint"),
    "deleted": (lambda path: path.unlink(), "it was missing"),
    "a row garbled": (lambda path: replace_line(path, 4, b"0.5,oops"), "1 rows of the games"),
    "header garbled": (lambda path: replace_line(path, 0, b"garbage"), "the header written again"),
}


@pytest.mark.parametrize("damage", list(DAMAGED_MONITORS))
def test_monitor_rows_are_written_again_from_the_checkpoint(finished_tiny_run, run, capsys, damage):
    damage_file, said = DAMAGED_MONITORS[damage]
    path = run / "games.monitor.csv"
    damage_file(path)
    status, out, err = resume(run, capsys)
    assert status == 0, err
    notes = [line for line in out.splitlines() if line.startswith(f"Note: {path}")]
    assert len(notes) == 1 and said in notes[0], out
    assert monitor_rows(run) == monitor_rows(finished_tiny_run)  # every row, none lost
    kept = list(run.glob("games.monitor.csv.damaged-*"))
    assert len(kept) == (0 if damage == "deleted" else 1)


# ---------------------------------------------------------------------------------------------------- progress.csv
def checkpoint_rows(folder):
    """The rows of ``progress.csv`` dumped up to the last checkpoint."""
    return [row for row in read_rows(folder / "progress.csv") if int(row["time/total_timesteps"]) <= LAST_CHECKPOINT]


def later_rows(folder):
    return [row for row in read_rows(folder / "progress.csv") if int(row["time/total_timesteps"]) > LAST_CHECKPOINT]


def steps_column(rows):
    return [row["time/total_timesteps"] for row in rows]


def test_deleted_progress_csv_is_reported_with_its_rows(finished_tiny_run, run, capsys):
    (run / "progress.csv").unlink()
    status, out, err = resume(run, capsys)
    assert status == 0, err
    n_rows = len(checkpoint_rows(finished_tiny_run))
    assert f"Note: {run / 'progress.csv'} is missing: the {n_rows} rows written up to the checkpoint cannot be restored" in out
    assert steps_column(read_rows(run / "progress.csv")) == steps_column(later_rows(finished_tiny_run))


@pytest.mark.parametrize("fraction", [0.3, 0.7])
def test_progress_csv_cut_mid_row_is_reported_with_its_rows(finished_tiny_run, run, capsys, fraction):
    path = run / "progress.csv"
    cut_mid_row(path, fraction)
    whole_rows = len(path.read_bytes().split(b"\n")) - 2  # the header, and the row cut short
    status, out, err = resume(run, capsys)
    assert status == 0, err
    lost = len(checkpoint_rows(finished_tiny_run)) - whole_rows
    note = re.search(rf"Note: {re.escape(str(path))}: (\d+) rows written up to the checkpoint cannot be restored", out)
    assert note is not None and int(note[1]) == lost > 0, out
    assert f"{lost} missing at its end" in out and "the damaged file is kept as progress.csv.damaged-" in out
    expected = [*checkpoint_rows(finished_tiny_run)[:whole_rows], *later_rows(finished_tiny_run)]
    assert steps_column(read_rows(path)) == steps_column(expected)  # nothing else lost
    assert len(list(run.glob("progress.csv.damaged-*"))) == 1


def test_a_garbled_progress_row_is_reported_by_its_line(finished_tiny_run, run, capsys):
    path = run / "progress.csv"
    replace_line(path, 3, b"1,2,three")
    status, out, err = resume(run, capsys)
    assert status == 0, err
    assert f"Note: {path}: 1 rows written up to the checkpoint cannot be restored (1 damaged (lines 4))" in out
    expected = [row for index, row in enumerate(checkpoint_rows(finished_tiny_run)) if index != 2] + later_rows(
        finished_tiny_run
    )
    assert steps_column(read_rows(path)) == steps_column(expected)


def test_a_garbled_progress_header_is_reported(finished_tiny_run, run, capsys):
    path = run / "progress.csv"
    replace_line(path, 0, b"not,a,header")
    status, out, err = resume(run, capsys)
    assert status == 0, err
    assert f"Note: {path} has no readable header: the {len(checkpoint_rows(finished_tiny_run))} rows" in out
    assert steps_column(read_rows(path)) == steps_column(later_rows(finished_tiny_run))


# ---------------------------------------------------------------------------------------------------- the benchmark
def test_a_benchmark_run_whose_checkpoint_does_not_load_starts_over(tmp_path, capsys):
    """The benchmark keeps one checkpoint per run: when it does not load, it is kept aside and the run starts over
    (saying so), ending with the rows of a run never interrupted."""
    from sb3_saeir.benchmark import RunSpec, execute_run

    spec = RunSpec("mappo", TASK, 1, 900, n_games=2, eval_freq=250, eval_episodes=2, params={"n_steps": 10, "n_epochs": 2})
    reference = execute_run(spec, str(tmp_path / "reference"))
    folder = tmp_path / "damaged"
    execute_run(RunSpec(**{**spec.__dict__, "n_timesteps": 120}), str(folder))  # the spec file, and a start
    (folder / "done.json").unlink()
    (folder / f"{TASK}.zip").unlink()  # an unfinished run: no final model
    (folder / "spec.json").write_text((tmp_path / "reference" / "spec.json").read_text())
    (folder / "checkpoint.zip").write_bytes(b"PK\x03\x04 cut short")
    capsys.readouterr()
    result = execute_run(spec, str(folder))
    out = capsys.readouterr().out
    assert "checkpoint.zip does not load (BadZipFile" in out and "the run starts over from the beginning" in out
    assert result["status"] == "done" and result["rows"] == reference["rows"]
    assert len(list(folder.glob("checkpoint.zip.damaged-*"))) == 1


@pytest.mark.parametrize(("content", "problem"), DAMAGED_SPEC_FILES)
@pytest.mark.parametrize("report_only", [False, True], ids=["run", "report-only"])
def test_a_damaged_benchmark_spec_file_is_named_and_nothing_written(tmp_path, capsys, content, problem, report_only):
    """A benchmark run whose ``spec.json`` is damaged is refused like a run of other settings, naming the file and
    the damage (a binary file or a JSON list ended in a traceback), before anything is written."""
    from sb3_saeir.benchmark import main as benchmark_main

    out = tmp_path / "bench"
    path = out / "runs" / "mappo" / f"{TASK}_s1" / "spec.json"
    path.parent.mkdir(parents=True)
    path.write_bytes(content)
    before = snapshot(out)
    argv = ["--algos", "mappo", "--tasks", TASK, "--seeds", "1", "-n", "900", "--n-games", "2", "--out", str(out)]
    status = benchmark_main(argv + (["--report-only"] if report_only else []))
    err = capsys.readouterr().err
    assert status == 2 and "Traceback" not in err, err
    assert f"{path} is damaged ({problem}" in err and "its settings are unknown" in err, err
    assert snapshot(out) == before


# ---------------------------------------------------------------------------------------------------- round 6 (issue 67)
def edit_spec(folder, **fields):
    spec = json.loads((folder / "spec.json").read_text())
    spec.update(fields)
    (folder / "spec.json").write_text(json.dumps(spec))


@pytest.mark.parametrize(
    "fields, named",
    [
        ({"n_timesteps": "900"}, 'n_timesteps is "900", not a whole number of agent-steps >= 1'),
        ({"n_timesteps": -5}, "n_timesteps is -5, not a whole number of agent-steps >= 1"),
        ({"options": [1]}, "options is [1], not an object"),
        ({"config": "x"}, 'config is "x", not an object'),
        ({"extensions": 5}, "extensions is 5, not a list of objects"),
        ({"extensions": {"a": 1}}, 'extensions is {"a": 1}, not a list of objects'),
    ],
)
def test_a_damaged_field_of_spec_json_is_named(run, capsys, fields, named):
    """A budget as a string sent the user round between two refusals; -5 was trained longer from; the others were
    raw TypeErrors or silently rewritten."""
    edit_spec(run, **fields)
    before = snapshot(run)
    status, _, err = resume(run, capsys)
    assert status == 2
    (line,) = err.strip().splitlines()
    assert f"{run / 'spec.json'} is damaged ({named}); restore it from a copy" in line
    assert snapshot(run) == before


@pytest.mark.parametrize(
    "text",
    [
        "garb{",
        "[1, 2]",
        "",
        '{"wall_s": -5, "segments": 0, "timesteps": -600}',
        '{"wall_s": NaN, "segments": 1, "timesteps": 9}',
    ],
)
def test_a_damaged_done_json_is_refused_before_training_longer(finished_tiny_run, tmp_path, capsys, text):
    """A raw JSONDecodeError (after the shorter run's model was copied), or ``[1, 2]`` recorded as the shorter run."""
    folder = unfinished_copy(finished_tiny_run, tmp_path / "logs")
    shutil.copy2(finished_tiny_run / f"{TASK}.zip", folder / f"{TASK}.zip")
    (folder / "done.json").write_text(text)
    before = snapshot(folder)
    longer = [arg if arg != "900" else "1200" for arg in argv(tmp_path / "logs", "--resume")]
    assert train_main(longer) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"{folder / 'done.json'} is damaged" in line and "delete it" in line
    assert snapshot(folder) == before


@pytest.mark.parametrize("text", ["xx[", '[{"wall_s": NaN}]', '[{"wall_s": Infinity}]', '[{"wall_s": -100}]', '{"a": 1}'])
def test_a_damaged_segments_json_is_kept_aside_and_the_run_goes_on(run, finished_tiny_run, capsys, text):
    """A raw JSONDecodeError (NaN: a ValueError, Infinity: an OverflowError), after resume.log had said the run
    resumed; -100 s went into done.json."""
    (run / "segments.json").write_text(text)
    status, _, err = resume(run, capsys)
    assert status == 0, err
    assert [path.name for path in run.glob("segments.json.damaged-*")] and json.loads((run / "segments.json").read_text())
    assert "segments.json is damaged: kept as segments.json.damaged-" in (run / "resume.log").read_text()
    assert_same_parameters(run / f"{TASK}.zip", finished_tiny_run / f"{TASK}.zip")


@pytest.mark.parametrize("damage", ["garbage", "cut"])
def test_unreadable_evaluation_rows_are_left_out_and_the_run_goes_on(run, capsys, damage):
    """A raw KeyError or TypeError at every resume."""
    path = run / "evaluations.csv"
    if damage == "garbage":
        path.write_text("a,b\n1,2\n")
    else:
        lines = path.read_text().splitlines()
        path.write_text("\n".join([*lines[:-1], lines[-1][: len(lines[-1]) // 3]]) + "\n")
    status, _, err = resume(run, capsys)
    assert status == 0, err
    assert [p.name for p in run.glob("evaluations.csv.damaged-*")]
    assert "row(s) of evaluations.csv cannot be read" in (run / "resume.log").read_text()
    assert all(row["timesteps"].isdigit() for row in read_rows(path))


def test_a_spec_json_without_its_budget_is_damaged(run, capsys):
    """It was "made with other settings: -n (unset) -> 900 ... resume with the command that started it"."""
    spec = json.loads((run / "spec.json").read_text())
    del spec["n_timesteps"]
    (run / "spec.json").write_text(json.dumps(spec))
    status, _, err = resume(run, capsys)
    assert status == 2 and f"{run / 'spec.json'} is damaged (no n_timesteps); restore it from a copy" in err


def test_a_folder_in_place_of_a_run_file_is_refused_before_the_resume(run, capsys):
    """evaluations.csv made a folder: the run trained to its next evaluation, then a raw IsADirectoryError."""
    (run / "evaluations.csv").unlink()
    (run / "evaluations.csv").mkdir()
    status, _, err = resume(run, capsys)
    assert status == 2
    (line,) = err.strip().splitlines()
    assert f"{run / 'evaluations.csv'} is a folder, where the run writes a file" in line


def test_the_temporary_files_of_a_killed_process_are_removed_at_the_resume(run, capsys):
    """A benchmark job terminated with its driver left .evaluations.npz.<pid>-<hex>.tmp.npz behind, for good."""
    import subprocess
    import sys

    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead_pid = int(gone.stdout)
    stale = run / f".evaluations.npz.{dead_pid}-0123abcd.tmp.npz"
    alive = run / f".best_model.zip.{os.getpid()}-0123abcd.tmp.zip"  # a live process's: kept
    stale.write_bytes(b"half")
    alive.write_bytes(b"half")
    status, _, err = resume(run, capsys)
    assert status == 0, err
    assert not stale.exists() and alive.exists()
    assert f"removed {stale.name}, a file a killed process was writing" in (run / "resume.log").read_text()


def test_an_option_recorded_as_another_type_is_named_as_damage(run, capsys):
    """``"--save-freq": "60"`` for 60 read as another setting, with the fix "resume with the command that started it"
    (which the user had given)."""
    spec = json.loads((run / "spec.json").read_text())
    spec["options"]["--save-freq"] = str(spec["options"]["--save-freq"])
    (run / "spec.json").write_text(json.dumps(spec))
    status, _, err = resume(run, capsys)
    assert status == 2 and "(the same value as another type: spec.json is damaged; restore it from a copy)" in err
