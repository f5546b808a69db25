"""``python -m sb3_saeir.train`` run folders outlive changes of the code: a run interrupted by an earlier version
(commit 2ff651c, ``tests/data/make_interrupted_train.py``) resumes with ``--resume FOLDER`` and ends as that
version's uninterrupted run ended (parameters, ``progress.csv`` but its ``time/`` columns, ``evaluations.npz``)."""

import shutil
from pathlib import Path

import numpy as np

from sb3_saeir.train import main as train_main
from tests.run_folders import parameters, read_rows

DATA = Path(__file__).parent / "data" / "interrupted_train"
# the command that made tests/data/interrupted_train (tests/data/make_interrupted_train.py)
SETTINGS = [
    "--task", "cn-sparse-n3", "--seed", "1", "-n", "900", "--n-games", "2", "--eval-freq", "250", "--eval-episodes", "2",
    "--save-freq", "240", "--num-threads", "1", "-params", "n_steps:10", "n_epochs:2",
]  # fmt: skip


def test_a_run_interrupted_by_an_earlier_version_resumes(tmp_path, capsys):
    folder = tmp_path / "cn-sparse-n3_1"
    shutil.copytree(DATA / "logs" / "mappo" / "cn-sparse-n3_1", folder)
    expected = DATA / "expected" / "mappo"
    assert train_main(["--algo", "mappo", *SETTINGS, "-f", str(tmp_path / "logs"), "--resume", str(folder)]) == 0
    assert "Resuming" in capsys.readouterr().out
    final = {name: tensor.numpy() for name, tensor in parameters(folder / "cn-sparse-n3.zip").items()}
    reference = np.load(expected / "parameters.npz")
    assert sorted(final) == sorted(name.split(".", 1)[1] for name in reference.files)
    for name in reference.files:
        np.testing.assert_array_equal(final[name.split(".", 1)[1]], reference[name], err_msg=name)
    rows, expected_rows = read_rows(folder / "progress.csv"), read_rows(expected / "progress.csv")
    counters = ("time/iterations", "time/total_timesteps")
    keys = [key for key in expected_rows[0] if not key.startswith("time/") or key in counters]
    assert [[row.get(key) for key in keys] for row in rows] == [[row[key] for key in keys] for row in expected_rows]
    evaluations, expected_evaluations = np.load(folder / "evaluations.npz"), np.load(expected / "evaluations.npz")
    assert sorted(evaluations.files) == sorted(expected_evaluations.files)
    for name in expected_evaluations.files:
        np.testing.assert_array_equal(evaluations[name], expected_evaluations[name])
