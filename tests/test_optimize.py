"""--optimize: Optuna trials in a local SQLite study, and two worker processes sharing one PostgreSQL study."""

import glob
import os
import shutil
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import optuna
import pytest
import sqlalchemy.exc

from sb3_saeir.hyperparams_opt import create_or_load_study
from sb3_saeir.train import main as train_main

TINY_ARGV = [
    "--task",
    "cn-sparse-n3",
    "--n-games",
    "2",
    "-n",
    "120",
    "--eval-episodes",
    "2",
    "--n-evaluations",
    "1",
    "-params",
    "n_steps:10",
    "--verbose",
    "0",
]


def test_local_sqlite_study(tmp_path):
    argv = ["--algo", "saeir_ppo", *TINY_ARGV, "--optimize", "--n-trials", "2", "--sampler", "random", "-f", str(tmp_path)]
    assert train_main(argv) == 0
    database = tmp_path / "saeir_ppo" / "saeir_ppo_cn-sparse-n3.db"
    assert database.is_file()
    study = optuna.load_study(study_name="saeir_ppo_cn-sparse-n3", storage=f"sqlite:///{database}")
    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(complete) == 2
    assert {"learning_rate", "intrinsic_coef", "group_size", "n_epochs"} <= set(study.best_trial.params)
    assert 0.0 <= study.best_value <= 1.0  # coverage rate


def race_error():
    """What the losing worker of a schema-creation race gets (psycopg's UniqueViolation through SQLAlchemy)."""
    return sqlalchemy.exc.IntegrityError("CREATE TABLE alembic_version", {}, Exception("duplicate key value"))


def test_study_creation_retries_after_a_schema_race(monkeypatch, tmp_path):
    calls = []
    create_study = optuna.create_study

    def racing_create_study(**kwargs):
        calls.append(kwargs["study_name"])
        if len(calls) == 1:
            raise race_error()
        return create_study(**kwargs)

    monkeypatch.setattr(optuna, "create_study", racing_create_study)
    monkeypatch.setattr("sb3_saeir.hyperparams_opt.time.sleep", lambda seconds: None)
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    study = create_or_load_study("raced", storage, optuna.samplers.RandomSampler(0), optuna.pruners.NopPruner())
    assert calls == ["raced", "raced"]
    assert study.study_name == "raced"


def test_study_creation_gives_up_on_a_broken_storage(monkeypatch):
    def broken_create_study(**kwargs):
        raise race_error()

    monkeypatch.setattr(optuna, "create_study", broken_create_study)
    monkeypatch.setattr("sb3_saeir.hyperparams_opt.time.sleep", lambda seconds: None)
    with pytest.raises(sqlalchemy.exc.IntegrityError):
        create_or_load_study("broken", "sqlite://", optuna.samplers.RandomSampler(0), optuna.pruners.NopPruner(), 3)


def postgres_bin_dir():
    candidates = sorted(glob.glob("/usr/lib/postgresql/*/bin"))
    for folder in reversed(candidates):
        if os.path.exists(os.path.join(folder, "initdb")) and os.path.exists(os.path.join(folder, "pg_ctl")):
            return folder
    return None


def free_port():
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture(scope="module")
def postgres_url():
    """A throwaway PostgreSQL server on loopback (Debian's server binaries; scripts/install_postgres.sh installs them)."""
    bin_dir = postgres_bin_dir()
    if bin_dir is None:
        pytest.fail("PostgreSQL server binaries not found: run `sudo bash scripts/install_postgres.sh` (CI does).")
    # not under pytest's tmp folder: that one is private to the current user, and initdb cannot run as root
    root = Path(tempfile.mkdtemp(prefix="sb3_saeir_pg_"))
    data = root / "data"
    as_user = []
    if os.geteuid() == 0:
        as_user = ["runuser", "-u", "postgres", "--"]
        shutil.chown(root, "postgres")
    port = free_port()
    subprocess.run(
        [*as_user, f"{bin_dir}/initdb", "-D", str(data), "-A", "trust", "-U", "postgres"], check=True, capture_output=True
    )
    options = f"-p {port} -k {data.parent} -c listen_addresses=127.0.0.1"
    subprocess.run(
        [*as_user, f"{bin_dir}/pg_ctl", "-D", str(data), "-o", options, "-w", "-l", str(data.parent / "log"), "start"],
        check=True,
        capture_output=True,
    )
    try:
        subprocess.run([f"{bin_dir}/createdb", "-h", "127.0.0.1", "-p", str(port), "-U", "postgres", "optuna"], check=True)
        yield f"postgresql://postgres@127.0.0.1:{port}/optuna"
    finally:
        subprocess.run([*as_user, f"{bin_dir}/pg_ctl", "-D", str(data), "-m", "fast", "stop"], capture_output=True)
        shutil.rmtree(root, ignore_errors=True)


def test_two_workers_share_a_postgres_study(postgres_url, tmp_path):
    argv = [
        sys.executable,
        "-m",
        "sb3_saeir.train",
        "--algo",
        "saeir_ppo",
        *TINY_ARGV,
        "--optimize",
        "--n-trials",
        "2",
        "--storage",
        postgres_url,
        "--study-name",
        "shared",
        "--sampler",
        "random",
    ]
    workers = []
    for worker in range(2):
        log = open(tmp_path / f"worker{worker}.log", "w")
        workers.append(
            (
                subprocess.Popen(
                    [*argv, "--seed", str(worker), "-f", str(tmp_path / f"w{worker}")], stdout=log, stderr=subprocess.STDOUT
                ),
                log,
            )
        )
        # no pause: both workers create-or-load the study on a fresh database at once (create_or_load_study retries)
    for process, log in workers:
        assert process.wait(timeout=600) == 0, (tmp_path / f"worker{workers.index((process, log))}.log").read_text()
        log.close()
    study = optuna.load_study(study_name="shared", storage=postgres_url)
    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(complete) == 4
    workers_seen = {trial.user_attrs["worker"] for trial in complete}
    assert len(workers_seen) == 2, workers_seen  # both processes contributed trials
    assert study.best_trial.value == max(t.value for t in complete)
    assert not (tmp_path / "w0" / "saeir_ppo").exists() or not list((tmp_path / "w0" / "saeir_ppo").glob("*.db"))


def test_every_method_has_a_search_space_and_group_size_stays_below_n_agents():
    from sb3_saeir.config import ALGOS
    from sb3_saeir.hyperparams_opt import HYPERPARAMS_SAMPLER, sample_params

    assert set(HYPERPARAMS_SAMPLER) == set(ALGOS)
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    for _ in range(20):
        trial = study.ask()
        group_size = sample_params(trial, "saeir_ppo", n_agents=3)["policy_kwargs"]["group_size"]
        assert 2 <= group_size < 3  # k = N would make the group critic a copy of the team critic
        study.tell(trial, 0.0)


def test_trial_seeds_near_2_32_wrap(tmp_path):
    """``--seed 4294967295``: trial 1 got seed 2**32 and failed with a raw traceback."""
    argv = ["--algo", "mappo", *TINY_ARGV, "--optimize", "--n-trials", "2", "--sampler", "random", "-f", str(tmp_path)]
    assert train_main([*argv, "--seed", "4294967295"]) == 0
    study = optuna.load_study(
        study_name="mappo_cn-sparse-n3", storage=f"sqlite:///{tmp_path / 'mappo' / 'mappo_cn-sparse-n3.db'}"
    )
    assert sum(trial.state == optuna.trial.TrialState.COMPLETE for trial in study.trials) == 2
