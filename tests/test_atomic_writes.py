"""Atomic writes: a save interrupted (SIGINT, SIGKILL) at any point of the write, or failing mid-way (standing in for
a full disk), leaves the file it replaces whole: the old file or the new one, never a part of the new one; and no
temporary file is left behind but after a SIGKILL."""

import contextlib
import errno
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import zipfile

import numpy as np
import pytest
import yaml

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.common.run_state import progress_logger, save_checkpoint
from sb3_saeir.common.vec_env import MultiAgentVecMonitor
from sb3_saeir.evaluation import MultiAgentEvalCallback

resource = pytest.importorskip("resource")  # RLIMIT_FSIZE: a write that fails mid-way, as on a full disk

TIMEOUT = 120

# The child: writes a good file with `writer`, keeps a copy as <path>.expected, changes the model, then writes it
# again with every zip entry's bytes going through in small chunks, and sends itself `signal` once `fraction` of the
# zip's bytes are written (the same hook on any code: zipfile's entry writer, which SB3's save and np.savez use).
CHILD = textwrap.dedent(
    """
    import io, os, shutil, signal, sys, time, zipfile
    from pathlib import Path
    import torch as th
    from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
    from sb3_saeir.experiment import Experiment

    writer, signal_name, fraction, path = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
    # Ctrl-C as in a terminal: a parent may ignore SIGINT (pytest-xdist's workers do), and children inherit that
    signal.signal(signal.SIGINT, signal.default_int_handler)
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=1, seed=0)
    if writer == "ippo":  # the final model of `python -m sb3_saeir.train --algo ippo` (plain SB3 PPO)
        experiment = Experiment("ippo", "cn-sparse-n3", n_games=1, seed=0)
        model = experiment.build(env=env)
        save = experiment.save
    else:
        algo = SAEIR_PPO if writer == "saeir_ppo" else MAPPO
        model = algo("MlpPolicy", env, n_steps=10, n_epochs=1, policy_kwargs=dict(hidden_size=256), seed=0)
        save = model.save
        if writer == "checkpoint":
            from sb3_saeir.common.run_state import save_checkpoint

            model.learn(30)  # a checkpoint holds the state of a model in learn
            save = lambda target: save_checkpoint(model, Path(target))  # noqa: E731
    save(path)
    shutil.copy(path, path + ".expected")
    with th.no_grad():
        for parameter in model.policy.parameters():
            parameter.add_(1.0)
    buffer = io.BytesIO()
    model.save(buffer)
    total, written = len(buffer.getvalue()), 0
    chunk_size = max(1024, total // 64)
    original_write = zipfile._ZipWriteFile.write

    def write(self, data):
        global written
        view = memoryview(data).cast("B")
        for start in range(0, len(view), chunk_size):
            original_write(self, view[start : start + chunk_size])
            written += len(view[start : start + chunk_size])
            if written >= fraction * total:
                os.kill(os.getpid(), getattr(signal, signal_name))
                time.sleep(30)
        return len(view)

    zipfile._ZipWriteFile.write = write
    save(path)
    print("the save was not interrupted")
    """
)


def interrupted_save(tmp_path, writer, signal_name, fraction):
    """Run the child; return its result and the path it saved to."""
    path = tmp_path / "model.zip"
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    result = subprocess.run(
        [sys.executable, str(script), writer, signal_name, str(fraction), str(path)],
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
    )
    return result, path


INTERRUPTS = [
    *[("mappo", name, fraction) for name in ("SIGINT", "SIGKILL") for fraction in (0.1, 0.5, 0.9)],
    *[(writer, name, 0.5) for writer in ("saeir_ppo", "checkpoint", "ippo") for name in ("SIGINT", "SIGKILL")],
]


@pytest.mark.parametrize(("writer", "signal_name", "fraction"), INTERRUPTS)
def test_an_interrupted_save_leaves_the_old_file(tmp_path, writer, signal_name, fraction):
    result, path = interrupted_save(tmp_path, writer, signal_name, fraction)
    assert "the save was not interrupted" not in result.stdout, "the hook did not fire"
    expected_status = -signal.SIGKILL if signal_name == "SIGKILL" else 1
    assert result.returncode == expected_status, result.stderr
    if signal_name == "SIGINT":
        assert "KeyboardInterrupt" in result.stderr
    assert path.read_bytes() == (tmp_path / "model.zip.expected").read_bytes()  # the old file, whole
    if writer == "ippo":
        from stable_baselines3 import PPO

        PPO.load(path)
    else:
        (SAEIR_PPO if writer == "saeir_ppo" else MAPPO).load(path)
    left = sorted(name.name for name in tmp_path.iterdir())
    temporary = [name for name in left if name not in ("child.py", "model.zip", "model.zip.expected")]
    if signal_name == "SIGINT":
        assert temporary == []  # cleaned up; a SIGKILL cannot clean up (a hidden .model.zip.<pid>-<hex>.tmp.zip)
    else:
        assert all(name.startswith(".model.zip.") for name in temporary), left


# ---------------------------------------------------------------------------------------------------- failed writes
@contextlib.contextmanager
def file_size_limit(n_bytes):
    """Writes beyond ``n_bytes`` of a file fail with EFBIG, as writes on a full disk fail with ENOSPC."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    previous = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (n_bytes, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, previous)


def small_and_big_models(env):
    small = MAPPO("MlpPolicy", env, n_steps=10, policy_kwargs=dict(hidden_size=8), seed=0)
    big = MAPPO("MlpPolicy", env, n_steps=10, policy_kwargs=dict(hidden_size=128), seed=0)
    return small, big


def write_model(tmp_path, env):
    path = tmp_path / "model.zip"
    small, big = small_and_big_models(env)
    small.save(path)
    return path, lambda: big.save(path), 200_000


def write_checkpoint(tmp_path, env):
    path = tmp_path / "rl_model_30_steps.zip"
    small, big = small_and_big_models(env)
    small.learn(30)
    big.learn(30)
    save_checkpoint(small, path)
    return path, lambda: save_checkpoint(big, path), 200_000


def write_final_model(tmp_path, env):
    from sb3_saeir.config import load_hyperparams
    from sb3_saeir.experiment import Experiment

    path = tmp_path / "cn-sparse-n3.zip"
    experiment = Experiment("ippo", "cn-sparse-n3", n_games=1, seed=0)
    experiment.build(env=env)
    experiment.save(path)
    config = {**load_hyperparams("ippo", "cn-sparse-n3"), "policy_kwargs": "dict(net_arch=[256, 256])"}
    bigger = Experiment("ippo", "cn-sparse-n3", config, n_games=1, seed=0)
    bigger.build(env=env)
    return path, lambda: bigger.save(path), path.stat().st_size + 10_000


def write_evaluations(tmp_path, env):
    callback = MultiAgentEvalCallback(env, n_eval_episodes=1, log_path=str(tmp_path))
    callback.timesteps, callback.history = [1], {"r": [[1.0]]}
    callback._save_evaluations()
    path = tmp_path / "evaluations.npz"
    callback.timesteps = list(range(5_000))
    callback.history = {"r": [[float(step)] for step in range(5_000)]}
    return path, callback._save_evaluations, 20_000


def write_args(tmp_path, env):
    from sb3_saeir.run.record import save_run_config

    save_run_config(tmp_path, {"n_steps": 10}, {"seed": 1, "params": None})
    path = tmp_path / "args.yml"
    long_params = [f"key_{index}:{index}" for index in range(400)]
    return path, lambda: save_run_config(tmp_path, {"n_steps": 10}, {"seed": 1, "params": long_params}), 2_000


def write_monitor(tmp_path, env):
    monitor = MultiAgentVecMonitor(env, str(tmp_path / "games"))
    monitor.reset()
    while monitor.n_finished_games < 40:
        monitor.step(np.zeros(monitor.num_envs, dtype=int))
    state = monitor.get_resume_state()
    while monitor.n_finished_games < 60:
        monitor.step(np.zeros(monitor.num_envs, dtype=int))
    monitor.results_writer.close()
    path = tmp_path / "games.monitor.csv"
    return path, lambda: monitor.set_resume_state(state), 1_000  # cut back to 40 rows, which take more than 1 kB


def write_progress(tmp_path, env):
    logger = progress_logger(tmp_path / "progress.csv", None, 0)
    for step in range(50):
        logger.record("time/total_timesteps", step)
        logger.record("a/value", step)
        logger.dump(step)
    logger.close()
    path = tmp_path / "progress.csv"
    logger = progress_logger(tmp_path / "progress.csv", 49, 0)  # resumed at step 49: every row kept

    def widen():
        logger.record("b/new_key", 1)
        logger.dump(50)

    return path, widen, path.stat().st_size + 10  # the rewrite with a wider header is longer


FAILED_WRITES = {
    "model.save": write_model,
    "checkpoint": write_checkpoint,
    "final model (ippo)": write_final_model,
    "evaluations.npz": write_evaluations,
    "args.yml": write_args,
    "monitor csv rewrite": write_monitor,
    "progress.csv header": write_progress,
}


@pytest.mark.parametrize("writer", list(FAILED_WRITES))
def test_a_failed_write_leaves_the_old_file(tmp_path, writer):
    env = make_multiagent_vec_env("cn-sparse-n3", n_games=1, seed=0)
    path, write_again, limit = FAILED_WRITES[writer](tmp_path, env)
    old = path.read_bytes()
    with file_size_limit(limit), pytest.raises(OSError) as error:
        write_again()
    assert error.value.errno == errno.EFBIG
    assert path.read_bytes() == old
    assert [name.name for name in tmp_path.iterdir() if name.name.startswith(".")] == []  # no temporary file left
    env.close()


# ---------------------------------------------------------------------------------------------------- the helper
def test_atomic_helpers_replace_whole_files(tmp_path):
    from sb3_saeir.common.atomic import atomic_file, atomic_path, atomic_write_text

    path = tmp_path / "a.txt"
    atomic_write_text(path, "one")
    os.chmod(path, 0o640)
    atomic_write_text(path, "two")
    assert path.read_text() == "two" and (path.stat().st_mode & 0o777) == 0o640  # the old file's permissions kept
    with pytest.raises(RuntimeError), atomic_file(path, "w") as file:
        file.write("three")
        raise RuntimeError("stopped mid-way")
    assert path.read_text() == "two"
    with atomic_path(tmp_path / "b.npz") as temp:
        assert temp.suffix == ".npz" and temp.parent == tmp_path
        np.savez(temp, x=np.arange(3))
    assert np.load(tmp_path / "b.npz")["x"].tolist() == [0, 1, 2]
    with pytest.raises(ValueError, match="mode must be one of"), atomic_file(path, "a"):
        pass
    with pytest.raises(FileNotFoundError, match=str(tmp_path / "missing" / "c.txt")):
        atomic_write_text(tmp_path / "missing" / "c.txt", "x")
    assert sorted(name.name for name in tmp_path.iterdir()) == ["a.txt", "b.npz"]


def test_model_save_keeps_sb3s_path_rules(tmp_path, env):
    from sb3_saeir.common.atomic import save_model
    from sb3_saeir.common.run_state import checkpoint_problem

    model = MAPPO("MlpPolicy", env, n_steps=10, policy_kwargs=dict(hidden_size=8))
    model.save(tmp_path / "plain")  # .zip added
    model.save(str(tmp_path / "named.zip"))
    with pytest.warns(UserWarning, match="does not exist. Will create it"):
        model.save(tmp_path / "new_folder" / "model")
    (tmp_path / "folder.zip").mkdir()
    with pytest.raises(ValueError, match="is a folder; save to a file path"):  # SB3 saved to <path>_2, load(path) failed
        model.save(tmp_path / "folder.zip")
    with pytest.warns(UserWarning, match="is a folder"):
        save_model(model, tmp_path / "folder.zip")  # the helper for any SB3 model keeps SB3's rule: <path>_2
    with open(tmp_path / "object.zip", "wb") as file:  # a file object is written to directly
        model.save(file)
    assert save_model(model, tmp_path / "helper") == tmp_path / "helper.zip"
    for name in ("plain.zip", "named.zip", "new_folder/model.zip", "folder.zip_2", "object.zip", "helper.zip"):
        assert checkpoint_problem(tmp_path / name) == "", name
        MAPPO.load(tmp_path / name)
    with zipfile.ZipFile(tmp_path / "plain.zip") as archive:
        assert "policy.pth" in archive.namelist()
    assert not [path for path in tmp_path.rglob(".*")]


def test_a_save_through_a_symbolic_link_writes_the_file_it_points_to(tmp_path, env):
    """As ``open(link, "wb")`` (SB3's save) does: the link stays a link, and the file it points to gets the model."""
    from sb3_saeir.common.atomic import atomic_write_text

    (tmp_path / "models").mkdir()
    target = tmp_path / "models" / "latest.zip"
    target.write_bytes(b"")
    link = tmp_path / "current.zip"
    link.symlink_to(target)
    MAPPO("MlpPolicy", env, n_steps=10, policy_kwargs=dict(hidden_size=8)).save(link)
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert zipfile.is_zipfile(target) and sorted(path.name for path in (tmp_path / "models").iterdir()) == ["latest.zip"]
    dangling = tmp_path / "notes.txt"
    dangling.symlink_to(tmp_path / "models" / "notes.txt")
    atomic_write_text(dangling, "written through")
    assert dangling.is_symlink() and (tmp_path / "models" / "notes.txt").read_text() == "written through"


def test_args_file_is_still_plain_yaml(tmp_path):
    from sb3_saeir.run.record import save_run_config

    save_run_config(tmp_path, {"n_steps": 10}, {"seed": 3, "algo": "mappo"})
    assert yaml.safe_load((tmp_path / "args.yml").read_text()) == {"algo": "mappo", "seed": 3}
    assert yaml.safe_load((tmp_path / "config.yml").read_text()) == {"n_steps": 10}
    shutil.rmtree(tmp_path)


def test_ctrl_c_right_after_the_temporary_file_is_made_leaves_nothing_behind(tmp_path, monkeypatch):
    """A SIGINT between the temporary file's creation and the write used to leave a 0-byte hidden file beside the
    target: the signal arrives here just as the file is made."""
    from sb3_saeir.common import atomic

    create_temp = atomic._create_temp

    def create_then_interrupted(path):
        temp = create_temp(path)
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C at the worst moment
        return temp

    monkeypatch.setattr(atomic, "_create_temp", create_then_interrupted)
    previous_handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            atomic.atomic_write_text(tmp_path / "record.json", "{}")
    finally:
        signal.signal(signal.SIGINT, previous_handler)
    assert list(tmp_path.iterdir()) == []
