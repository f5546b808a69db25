"""benchmarks/copy_run_files.py: a run's small files for a study folder, never its models, checkpoints or progress."""

import json

import pytest


@pytest.fixture(scope="module")
def copy_run_files(load_benchmark_script):
    return load_benchmark_script("copy_run_files")


def fake_run(folder, algo, finished):
    folder.mkdir(parents=True)
    (folder / "spec.json").write_text(json.dumps({"algo": algo}))
    for name in ["evaluations.csv", "segments.json", "resume.log", "progress.csv", "games.monitor.csv"]:
        (folder / name).write_text(name)
    (folder / "rl_model_1200_steps.zip").write_bytes(b"checkpoint")
    (folder / "cn-sparse-n3.zip").write_bytes(b"model")
    if finished:
        (folder / "done.json").write_text("{}")
    return folder


@pytest.mark.parametrize("finished", [True, False])
def test_only_the_committed_files_are_copied(copy_run_files, tmp_path, capsys, finished):
    run = fake_run(tmp_path / "runs" / "mappo" / "cn-sparse-n3_s1", "mappo", finished)
    target = tmp_path / "study" / "runs" / "mappo" / "cn-sparse-n3_s1"
    # a MAPPO run gets no bonus files, even when the window is given
    assert copy_run_files.main([str(run), str(target), "--bonus-window", "50"]) == 0
    expected = {"spec.json", "evaluations.csv", "segments.json", "resume.log"} | ({"done.json"} if finished else set())
    assert {path.name for path in target.iterdir()} == expected
    assert all((target / name).read_bytes() == (run / name).read_bytes() for name in expected)
    state = "finished" if finished else "still training"
    assert capsys.readouterr().out.startswith(f"copied {run} -> {target} ({state}): spec.json, evaluations.csv")


def test_a_folder_that_is_not_a_run_is_refused(copy_run_files, tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SystemExit, match=r"is not a run folder \(no spec\.json\)"):
        copy_run_files.main([str(tmp_path / "empty"), str(tmp_path / "target")])
    assert not (tmp_path / "target").exists()


def test_a_saeir_run_gets_its_bonus_files(copy_run_files, tiny_saeir_benchmark_run, tmp_path):
    run = tiny_saeir_benchmark_run
    target = tmp_path / "study" / "run"
    assert copy_run_files.main([str(run), str(target)]) == 0  # no window: no bonus files
    assert not (target / "bonus.md").exists()
    assert copy_run_files.main([str(run), str(target), "--bonus-window", "50", "--bonus-name", "bonus_by_50.md"]) == 0
    names = {path.name for path in target.iterdir()}
    assert {"spec.json", "evaluations.csv", "done.json", "bonus.md", "bonus.png", "bonus_by_50.md"} <= names
    assert not any(name.endswith(".zip") or name == "progress.csv" for name in names)


def test_a_saeir_run_without_a_rollout_yet_gets_no_bonus_files(copy_run_files, tmp_path, capsys):
    run = fake_run(tmp_path / "runs" / "saeir_ppo" / "cn-sparse-n3_s1", "saeir_ppo", finished=False)
    (run / "progress.csv").write_text("time/total_timesteps,rollout/intrinsic_reward_mean\n")  # the header alone
    target = tmp_path / "study"
    assert copy_run_files.main([str(run), str(target), "--bonus-window", "50"]) == 0
    assert not (target / "bonus.md").exists()
    assert capsys.readouterr().out.rstrip().endswith("no bonus files yet (no rollout logged)")
