"""Bad input to a run's folder and record on the command lines (round 4, issue 59): a loaded model's network, files in
the place of folders, checkpoints that are folders or dangling links, budgets that are not whole rollouts or beyond
2**53, seeds at the range's ends, a benchmark run resumed by train.
"""

from __future__ import annotations

import pytest

from sb3_saeir import MAPPO, make_multiagent_vec_env
from sb3_saeir.benchmark import main as benchmark_main
from sb3_saeir.train import main as train_main
from sb3_saeir.zoo.launcher import main as zoo_main
from tests.test_bad_input_cli import TASK, run, snapshot

# ---------------------------------------------------------------------------------------------------- round 4 (issue 55)
FF_KWARGS = "policy_kwargs:dict(activation_fn=nn.Tanh, hidden_size=64, critic_input='joint', recurrent=False)"
TINY = ["--algo", "mappo", "--n-games", "2", "-n", "60", "--eval-freq", "0", "--verbose", "0", "--num-threads", "1"]


def test_a_loaded_model_is_recorded_as_the_network_that_trains(tmp_path, capsys):
    """``-i FF.zip`` with the packaged (recurrent) config trains the feed-forward model: spec.json says so; a
    ``-params policy_kwargs`` that the loaded model cannot take is refused in one line, nothing left behind."""
    import json

    assert run(train_main, [*TINY, "-f", str(tmp_path), "-params", "n_steps:10", FF_KWARGS]) == 0
    feed_forward = tmp_path / "mappo" / f"{TASK}_1" / f"{TASK}.zip"
    assert run(train_main, [*TINY, "-f", str(tmp_path), "-params", "n_steps:10", "-i", str(feed_forward)]) == 0
    recorded = json.loads((tmp_path / "mappo" / f"{TASK}_2" / "spec.json").read_text())["config"]["policy_kwargs"]
    assert "recurrent=False" in recorded
    capsys.readouterr()
    before = snapshot(tmp_path)
    overridden = [*TINY, "-f", str(tmp_path), "-params", "n_steps:10", "policy_kwargs:dict(recurrent=True)"]
    assert run(train_main, [*overridden, "-i", str(feed_forward)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "-params policy_kwargs recurrent=True cannot apply to the loaded model" in line
    assert "whose network has recurrent=False" in line
    assert snapshot(tmp_path) == before


def test_a_file_in_the_place_of_the_methods_folder_is_named(tmp_path, capsys):
    (tmp_path / "mappo").write_text("not a folder")
    before = snapshot(tmp_path)
    assert run(train_main, [*TINY, "-f", str(tmp_path), "-params", "n_steps:10"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"{tmp_path / 'mappo'} is a file, where a folder of the runs" in line
    assert snapshot(tmp_path) == before


def test_resume_of_a_file_says_it_is_a_file(tmp_path, capsys):
    path = tmp_path / "run.zip"
    path.write_bytes(b"PK")
    assert run(train_main, [*TINY, "-f", str(tmp_path), "--resume", str(path)]) == 2
    assert f"--resume {path}: a file, not a run folder" in capsys.readouterr().err


def test_a_checkpoint_that_is_a_folder_is_skipped_and_kept_aside(finished_tiny_run, tmp_path, capsys):
    from tests.run_folders import argv, unfinished_copy

    folder = unfinished_copy(finished_tiny_run, tmp_path / "logs")
    (folder / "rl_model_870_steps.zip").mkdir()
    assert run(train_main, argv(tmp_path / "logs", "--resume")) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "rl_model_870_steps.zip does not load (it is a folder, not a zip file)" in out
    assert "Resuming" in out and "from rl_model_840_steps.zip" in out
    assert [path.name.split(".damaged-")[0] for path in folder.glob("*.damaged-*")] == ["rl_model_870_steps.zip"]


def test_a_checkpoint_that_is_a_link_to_nothing_is_skipped_and_kept_aside(finished_tiny_run, tmp_path, capsys):
    """``shutil.copy2`` of the damaged checkpoint failed with ``FileNotFoundError``: ``--resume`` crashed."""
    from tests.run_folders import argv, unfinished_copy

    folder = unfinished_copy(finished_tiny_run, tmp_path / "logs")
    (folder / "rl_model_870_steps.zip").symlink_to("missing")
    assert run(train_main, argv(tmp_path / "logs", "--resume")) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "rl_model_870_steps.zip does not load (it is a link to missing, which does not exist)" in out
    assert "Resuming" in out and "from rl_model_840_steps.zip" in out
    (kept,) = folder.glob("*.damaged-*")
    assert kept.name.startswith("rl_model_870_steps.zip.damaged-") and kept.is_symlink()  # the link itself, moved aside


def test_a_benchmark_checkpoint_that_is_a_link_to_nothing_is_skipped_and_kept_aside(tmp_path, capsys):
    """The benchmark failed the run (``FileNotFoundError`` in ``failures.txt``)."""
    tiny = ["--algos", "mappo", "--seeds", "1", "--n-games", "2", "--eval-freq", "60", "-params", "n_steps:10", "n_epochs:1"]
    assert run(benchmark_main, [*tiny, "-n", "60", "--out", str(tmp_path)]) == 0
    folder = tmp_path / "runs" / "mappo" / f"{TASK}_s1"
    (folder / "rl_model_90_steps.zip").symlink_to("missing")
    capsys.readouterr()
    assert run(benchmark_main, [*tiny, "-n", "120", "--out", str(tmp_path)]) == 0, (tmp_path / "failures.txt").read_text()
    log = (folder / "resume.log").read_text()
    assert "rl_model_90_steps.zip does not load (it is a link to missing, which does not exist)" in log
    assert "resuming from cn-sparse-n3.zip" in log
    (kept,) = folder.glob("*.damaged-*")
    assert kept.name.startswith("rl_model_90_steps.zip.damaged-") and kept.is_symlink()
    assert (folder / "done.json").is_file()


@pytest.mark.parametrize("budget, note", [("90", True), ("120", False)])
def test_a_budget_that_is_not_a_whole_number_of_rollouts_gets_a_note(tmp_path, capsys, budget, note):
    """``-n 90`` with rollouts of 60 agent-steps printed "90 agent-steps" and trained 120 without a word."""
    command = [*TINY, "-f", str(tmp_path), "-params", "n_steps:10", "n_epochs:1"]
    command[command.index("-n") + 1] = budget
    assert run(train_main, command) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    expected = (
        "Note: the budget is not a whole number of rollouts (a rollout: 10 steps x 2 games x 3 agents = 60 agent-steps): "
        "the run stops at the end of the rollout that reaches it, after 120 agent-steps."
    )
    assert (expected in out) == note, out
    assert ("whole number of rollouts" in out) == note
    assert f"{int(budget):,} agent-steps, seed 0" in out


def test_compile_may_change_at_resume_in_params_too(finished_tiny_run, tmp_path, capsys):
    from tests.run_folders import argv, unfinished_copy

    unfinished_copy(finished_tiny_run, tmp_path / "logs")
    command = argv(tmp_path / "logs", "--resume")
    command.insert(command.index("n_epochs:2") + 1, "compile:False")
    assert run(train_main, command) == 0, capsys.readouterr().err


def test_a_budget_beyond_2_53_is_refused_before_anything_is_written(tmp_path, capsys):
    """``-n 1e20`` crashed in ``learn`` with numpy's TypeError after the run's spec.json was written (and, at
    ``--resume``, recorded as an extension); ``MAPPO.learn(10**20)`` likewise."""
    assert run(train_main, [*TINY, "-n", "1e20", "-f", str(tmp_path)]) == 2
    assert "'1e20' agent-steps is more than 2**53" in capsys.readouterr().err
    assert run(benchmark_main, ["--algos", "mappo", "-n", "1e20", "--out", str(tmp_path / "b")]) == 2
    assert "more than 2**53" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    model = MAPPO("MAPPOPolicy", make_multiagent_vec_env(TASK, n_games=2), n_steps=10)
    with pytest.raises(
        ValueError, match=r"total_timesteps=100000000000000000000 is out of range; it must be >= 1 and at most 2\*\*53"
    ):
        model.learn(10**20)


def test_a_benchmark_run_with_nothing_to_resume_from_says_it_starts_over(tmp_path, capsys):
    tiny = ["--algos", "mappo", "--seeds", "1", "--n-games", "2", "--eval-freq", "60", "-params", "n_steps:10", "n_epochs:1"]
    assert run(benchmark_main, [*tiny, "-n", "60", "--out", str(tmp_path)]) == 0
    folder = tmp_path / "runs" / "mappo" / f"{TASK}_s1"
    (folder / f"{TASK}.zip").unlink()  # the finished run's resume point deleted
    assert run(benchmark_main, [*tiny, "-n", "120", "--out", str(tmp_path)]) == 0
    assert (
        "nothing to resume from (no checkpoint, no final model with a resume state): the run starts over"
        in (folder / "resume.log").read_text()
    )


def test_zoo_params_value_that_is_not_python_names_the_fix(tmp_path, capsys):
    """rl-zoo3 evaluates each ``-params`` value: ``compile:bogus`` was its ``NameError`` traceback."""
    argv = ["train", "--algo", "mappo", "--env", TASK, "-n", "60", "-f", str(tmp_path), "-params", "compile:bogus"]
    assert run(zoo_main, argv) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "-params compile:bogus: rl-zoo3 reads each value as a Python expression and 'bogus' is not one" in line
    assert "NameError" in line and "-params \"compile:'bogus'\"" in line
    assert list(tmp_path.iterdir()) == []


def test_the_evaluation_seed_wraps_into_the_seed_range():
    from sb3_saeir.experiment import evaluation_seed

    assert evaluation_seed(0) == 10_000 and evaluation_seed(7) == 10_007  # every seed used so far keeps its games
    assert evaluation_seed(2**32 - 1) == 9_999
    assert evaluation_seed(2**32 - 10_001) == 2**32 - 1


@pytest.mark.parametrize("seed", [2**32 - 1, 2**32 - 10_000])
def test_every_accepted_seed_trains_and_evaluates(tmp_path, capsys, seed):
    """The top of the documented range (evaluation games used to get 10_000 + seed, outside it)."""
    argv = ["--algo", "mappo", "--task", "cn-sparse-n3", "--n-games", "2", "-n", "60", "-params", "n_steps:10"]
    argv += ["n_epochs:1", "--eval-freq", "60", "--eval-episodes", "2", "--verbose", "0", "--seed", str(seed)]
    assert train_main([*argv, "-f", str(tmp_path / "train")]) == 0
    assert f"seed {seed}" in capsys.readouterr().out
    assert (tmp_path / "train" / "mappo" / "cn-sparse-n3_1" / "done.json").is_file()
    argv = ["--algos", "mappo", "--tasks", "cn-sparse-n3", "--seeds", str(seed), "-n", "60", "--n-games", "2"]
    argv += ["--eval-freq", "60", "--eval-episodes", "2", "-params", "n_steps:10", "--out", str(tmp_path / "bench")]
    assert benchmark_main(argv) == 0
    assert (tmp_path / "bench" / "runs" / "mappo" / f"cn-sparse-n3_s{seed}" / "done.json").is_file()


def test_zoo_train_refuses_a_seed_out_of_range_before_anything_is_written(tmp_path, capsys):
    argv = ["train", "--algo", "mappo", "--env", "cn-sparse-n3", "--seed", str(2**64), "-n", "60"]
    assert zoo_main([*argv, "-params", "n_envs:2", "-f", str(tmp_path / "logs")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"--seed={2**64} is not a seed; pass an integer from 0 to 2**32 - 1 (or -1 to draw one)" in line
    assert not (tmp_path / "logs").exists()


def test_seed_takes_the_number_forms_that_n_takes(tmp_path, capsys):
    """``--seed 1e3`` was refused ("invalid int value") where ``-n 1e3`` was taken."""
    argv = ["--algo", "mappo", "--task", "cn-sparse-n3", "--n-games", "2", "-n", "6e1", "-params", "n_steps:10"]
    argv += ["n_epochs:1", "--eval-freq", "0", "--verbose", "0", "--seed", "1e3", "-f", str(tmp_path)]
    assert train_main(argv) == 0
    assert "seed 1000" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        train_main([*argv[:-4], "--seed", "1.5e0", "-f", str(tmp_path)])
    assert "'1.5e0' is not a whole number" in capsys.readouterr().err


def test_train_resume_of_a_benchmark_run_names_the_benchmark_command(tmp_path, capsys):
    """``train --resume <benchmark run folder>`` listed train's defaults as "other settings"."""
    argv = ["--algos", "mappo", "--tasks", "cn-sparse-n3", "--seeds", "2", "-n", "60", "--n-games", "2"]
    argv += ["--eval-freq", "60", "--eval-episodes", "2", "-params", "n_steps:10", "--out", str(tmp_path / "bench")]
    assert benchmark_main(argv) == 0
    folder = tmp_path / "bench" / "runs" / "mappo" / "cn-sparse-n3_s2"
    before = snapshot(folder)
    capsys.readouterr()
    assert train_main(["--algo", "mappo", "--task", "cn-sparse-n3", "--resume", str(folder)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"{folder} is a run of the benchmark, not of train" in line
    assert "python -m sb3_saeir.benchmark --algos mappo --tasks cn-sparse-n3 --seeds 2 -n 60 --n-games 2" in line
    assert f"'n_steps:10' --out {tmp_path / 'bench'}" in line and "--eval-freq" in line
    assert snapshot(folder) == before
