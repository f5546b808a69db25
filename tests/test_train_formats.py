"""``python -m sb3_saeir.train`` run folders outlive changes of the code: a run interrupted by an earlier version
(commit 2ff651c, ``tests/data/make_interrupted_train.py``, before one ``Run`` owned a run) resumes with
``--resume FOLDER`` and trains as that version's uninterrupted run did (parameters, the training rows of
``progress.csv``); its evaluations up to the checkpoint are kept, and the later ones follow today's schedule (on the
grid, each on the same episodes, one at the end)."""

import shutil
from pathlib import Path

import numpy as np

from sb3_saeir.train import main as train_main
from tests.run_folders import LEGACY_RUN, LEGACY_SETTINGS, SAVED_ARRAYS_ATOL, SAVED_ARRAYS_RTOL, parameters, read_rows

DATA = Path(__file__).parent / "data" / "interrupted_train"


def test_a_run_interrupted_by_an_earlier_version_resumes(tmp_path, capsys):
    folder = tmp_path / "cn-sparse-n3_1"
    shutil.copytree(LEGACY_RUN, folder)
    expected = DATA / "expected" / "mappo"
    assert train_main(["--algo", "mappo", *LEGACY_SETTINGS, "-f", str(tmp_path / "logs"), "--resume", str(folder)]) == 0
    assert "Resuming" in capsys.readouterr().out
    final = {name: tensor.numpy() for name, tensor in parameters(folder / "cn-sparse-n3.zip").items()}
    reference = np.load(expected / "parameters.npz")
    assert sorted(final) == sorted(name.split(".", 1)[1] for name in reference.files)
    for name in reference.files:
        # the reference was made on another CPU; a resume that trained on other data or other random draws moves the
        # parameters by orders of magnitude more than the tolerance
        got = final[name.split(".", 1)[1]]
        np.testing.assert_allclose(got, reference[name], atol=SAVED_ARRAYS_ATOL, rtol=SAVED_ARRAYS_RTOL, err_msg=name)
    rows, expected_rows = read_rows(folder / "progress.csv"), read_rows(expected / "progress.csv")
    # the rows of every rollout (an evaluation's row, and the update's values dumped with it, come with the schedule)
    keys = [key for key in expected_rows[0] if key.startswith("rollout/")] + ["time/iterations", "time/total_timesteps"]
    assert [[row[key] for key in keys] for row in rows if row["time/iterations"]] == [
        [row[key] for key in keys] for row in expected_rows if row["time/iterations"]
    ]
    evaluations, expected_evaluations = np.load(folder / "evaluations.npz"), np.load(expected / "evaluations.npz")
    assert list(expected_evaluations["timesteps"]) == [252, 504, 756]
    assert list(evaluations["timesteps"]) == [252, 504, 750, 900]  # the grid (first count >= k * 250), the end
    np.testing.assert_array_equal(evaluations["results"][0], expected_evaluations["results"][0])  # kept
    assert [row["timesteps"] for row in read_rows(folder / "evaluations.csv")] == ["504", "750", "900"]
