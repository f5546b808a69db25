"""Bad inputs of the command lines and configs (issue 24, part B): each refused before anything is built or written,
as one ``error:`` line naming the option, exit status 2, and the folders left byte for byte as they were.

Kinds: late errors (settings that failed only at the first evaluation, save or ``learn()``), raw library errors,
silent acceptance, and the serious ones (``5e-4`` read as a string, a model of another method, repeated seeds).
"""

import hashlib
import os
from pathlib import Path

import pytest
import yaml

from sb3_saeir import MAPPO, SAEIR_PPO, make_multiagent_vec_env
from sb3_saeir.benchmark import main as benchmark_main
from sb3_saeir.benchmark import parse_seeds
from sb3_saeir.common.utils import unwritable_folder
from sb3_saeir.config import ConfigError, load_hyperparams, parse_params
from sb3_saeir.enjoy import main as enjoy_main
from sb3_saeir.train import main as train_main
from sb3_saeir.zoo.launcher import main as zoo_main

TASK = "cn-sparse-n3"
TRAIN = ["--algo", "saeir_ppo", "--n-games", "2", "-n", "100", "--eval-freq", "0", "--verbose", "0"]


def snapshot(folder: Path) -> dict[str, str]:
    """Every file and folder under ``folder`` with a hash of its bytes (folders: ``"dir"``)."""
    return {
        str(path.relative_to(folder)): "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
        for path in sorted(folder.rglob("*"))
    }


def run(main, argv) -> int:
    """Exit status of a command line (argparse errors raise ``SystemExit``)."""
    try:
        return main(argv)
    except SystemExit as exit_:
        return int(exit_.code or 0)


def assert_refused(main, argv, message, capsys, root: Path) -> None:
    """``argv`` exits 2 with one ``error:`` line holding ``message`` and leaves ``root`` unchanged."""
    before = snapshot(root)
    status = run(main, argv)
    err = capsys.readouterr().err.strip()
    assert status == 2, err[-2000:]
    assert "\n" not in err and ": error: " in err, err[-2000:]
    assert message in err, err
    assert snapshot(root) == before


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """A tiny saved SAEIR_PPO and MAPPO model of cn-sparse-n3 (outside every log folder)."""
    folder = tmp_path_factory.mktemp("models")
    env = make_multiagent_vec_env(TASK, n_games=1, seed=0)
    SAEIR_PPO("MSHGPolicy", env, n_steps=10, policy_kwargs=dict(hidden_size=8)).save(folder / "saeir.zip")
    MAPPO("MAPPOPolicy", env, n_steps=10, policy_kwargs=dict(hidden_size=8)).save(folder / "mappo.zip")
    env.close()
    return folder


@pytest.fixture
def root(tmp_path, monkeypatch):
    """A working folder (the current directory) holding a user's run that bad commands must leave untouched."""
    run_folder = tmp_path / "logs" / "saeir_ppo" / f"{TASK}_1"
    run_folder.mkdir(parents=True)
    (run_folder / f"{TASK}.zip").write_bytes(b"a model the user saved")
    (tmp_path / "a_file").write_text("not a folder")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def conf_with(root: Path, algo: str = "saeir_ppo", text: str = "", **changes) -> str:
    """A user's config file: the packaged entry of ``TASK`` with ``changes``, or ``text`` as given."""
    path = root / "my_config.yml"
    if not text:
        text = yaml.safe_dump({TASK: {**load_hyperparams(algo, TASK), **changes}})
    path.write_text(text)
    return str(path)


# ------------------------------------------------------------------------------------------------ serious ones
RL_ZOO_NUMBERS = [("5e-4", 5e-4), ("1e6", 1e6), ("1.5E-3", 1.5e-3), ("-1e-2", -1e-2), ("3e7", 3e7), ("+2E+3", 2e3)]


@pytest.mark.parametrize("text, value", RL_ZOO_NUMBERS, ids=[t for t, _ in RL_ZOO_NUMBERS])
def test_numbers_as_rl_zoo_users_write_them_parse_everywhere(tmp_path, text, value):
    from sb3_saeir.config import load_yaml

    assert parse_params([f"learning_rate:{text}"]) == {"learning_rate": value}  # train and benchmark -params
    conf = tmp_path / "conf.yml"
    conf.write_text(f"{TASK}:\n  learning_rate: {text}\n  n_timesteps: {text}\n")
    entry = load_hyperparams("mappo", TASK, conf)  # user -conf files and the packaged configs
    assert entry == {"learning_rate": value, "n_timesteps": value} and isinstance(entry["learning_rate"], float)
    assert load_yaml("[1, 1.0, abc, 1e, e5]") == [1, 1.0, "abc", "1e", "e5"]  # the rest unchanged


def test_documented_learning_rate_override_is_accepted(root, capsys, monkeypatch):
    """``-params learning_rate:5e-4`` (docs/guide/training.md) gets past every config check: the command stops only
    at the missing ``-i`` file, checked after the config."""
    argv = [*TRAIN, "-f", "logs", "-params", "learning_rate:5e-4", "n_timesteps:1e2", "-i", "missing.zip"]
    assert_refused(train_main, argv, "--trained-agent missing.zip is not a file", capsys, root)


@pytest.mark.parametrize(
    "algo, model, message",
    [
        (
            "saeir_ppo",
            "mappo.zip",
            "is a model with MAPPOPolicy and intrinsic_reward=None (a model of mappo; use --algo mappo)",
        ),
        ("mappo", "saeir.zip", "is a model with MSHGPolicy and intrinsic_reward='saeir' (a model of saeir_ppo"),
        ("mshg_only", "saeir.zip", "not one of mshg_only (MSHGPolicy, intrinsic_reward=None)"),
    ],
)
def test_trained_agent_of_another_method_is_refused(root, models, capsys, algo, model, message):
    argv = [*TRAIN[2:], "--algo", algo, "-f", "logs", "-i", str(models / model)]
    assert_refused(train_main, argv, message, capsys, root)


@pytest.mark.parametrize("algo, model", [("saeir_ppo", "mappo.zip"), ("mappo", "saeir.zip")])
def test_enjoy_of_another_method_is_refused(root, models, capsys, algo, model):
    argv = ["--algo", algo, "--model", str(models / model), "-n", "1", "--n-games", "1"]
    assert_refused(enjoy_main, argv, f"--algo {algo}: {models / model} is a model with", capsys, root)


SEEDS = [
    ("1,1", "gives seed(s) [1] more than once"),
    ("1-3,2", "gives seed(s) [2] more than once"),
    ("3-1", "the range 3-1 is empty"),
    ("a", "'a' is not a seed or a range"),
    ("1-", "'1-' is not a seed or a range"),
    (",", "gives no seed"),
]


@pytest.mark.parametrize("seeds, message", SEEDS, ids=[s for s, _ in SEEDS])
def test_bad_benchmark_seeds(root, capsys, seeds, message):
    with pytest.raises(ConfigError, match="--seeds"):
        parse_seeds(seeds)
    argv = ["--algos", "mappo", "--seeds", seeds, "-n", "100", "--eval-freq", "50", "--out", "bench", "--report-only"]
    assert_refused(benchmark_main, argv, message, capsys, root)


def test_parse_seeds_still_reads_ranges_and_lists():
    assert parse_seeds("1-3") == [1, 2, 3] and parse_seeds("1,3,7") == [1, 3, 7] and parse_seeds("0-1,5,") == [0, 1, 5]
    with pytest.raises(ConfigError, match="-2 is not a seed"):  # a range of negative numbers still parses, as a range
        parse_seeds("-2--1,5")


# ------------------------------------------------------------------------------------------------ late errors
LATE_TRAIN = [
    (["--eval-freq", "50", "--eval-episodes", "0"], "--eval-episodes must be >= 1, got 0"),
    (["--eval-freq", "50", "--eval-episodes", "-3"], "--eval-episodes must be >= 1, got -3"),
    (["-conf", {"intrinsic_kwargs": "dict(variant='bogus')"}], "Unknown SAEIR variant 'bogus'"),
    (["-conf", {"callback": "my.missing.Callback"}], "callback 'my.missing.Callback' does not import"),
    (
        ["-conf", {"callback": [{"sb3_saeir.common.callbacks.EveryAgentSteps": {"x": 1}}]}],
        "callback 'sb3_saeir.common.callbacks.EveryAgentSteps': EveryAgentSteps.__init__() got an unexpected",
    ),
    (["-tb", "a_file"], "-tb/--tensorboard-log a_file is a file"),
    (["-params", "tensorboard_log:a_file"], "tensorboard_log a_file is a file"),
    (["-f", "a_file/logs"], "-f/--log-folder a_file/logs: a_file is a file"),
    (["-f", "a_file"], "-f/--log-folder a_file is a file"),
]


@pytest.mark.parametrize("extra, message", LATE_TRAIN, ids=[m[:40] for _, m in LATE_TRAIN])
def test_late_errors_of_the_train_command(root, capsys, extra, message):
    """Each of these used to fail at the first evaluation, save or learn(), after the run folder was made."""
    extra = [conf_with(root, **item) if isinstance(item, dict) else item for item in extra]
    argv = [*TRAIN, *extra] if "-f" in extra else [*TRAIN, "-f", "logs", *extra]
    assert_refused(train_main, argv, message, capsys, root)


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--gif", "."], "--gif '.' is not a file name"),
        (["--gif", "missing/replay.gif"], "--gif missing/replay.gif: the folder missing does not exist"),
        (["--gif", "a_file/replay.gif"], "the folder a_file does not exist"),
    ],
)
def test_enjoy_gif_path_is_checked_before_the_evaluation(root, models, capsys, extra, message):
    argv = ["--algo", "saeir_ppo", "--model", str(models / "saeir.zip"), "-n", "1", "--n-games", "1", *extra]
    assert_refused(enjoy_main, argv, message, capsys, root)


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--out", "a_file"], "--out a_file is a file"),
        (["-params", "gamma:1.5"], "cannot build mappo on cn-sparse-n3 with these settings"),
        (["-params", "intrinsic_reward:saeir", "intrinsic_kwargs:dict(variant='bogus')"], "Unknown SAEIR variant"),
    ],
)
def test_benchmark_refuses_before_any_run_folder(root, capsys, extra, message):
    argv = ["--algos", "mappo", "--seeds", "1", "-n", "100", "--eval-freq", "50", "--n-games", "2", "--out", "bench"]
    assert_refused(benchmark_main, [*argv, *extra], message, capsys, root)


# ------------------------------------------------------------------------------------------------ raw library errors
RAW_TRAIN = [
    (["-n", "2.5"], "argument -n/--n-timesteps: '2.5' is not a whole number"),
    (["--n-games", "x"], "argument --n-games: invalid integer 'x'"),
    (["--eval-freq", "ten"], "argument --eval-freq: invalid integer 'ten'"),
    (["--device", "gpu2"], "--device 'gpu2' is not a torch device"),
    (["--num-threads", "-2"], "--num-threads must be >= 0"),
    (["--optimize", "--n-trials", "1", "--storage", "foo://x"], "--storage 'foo://x' is not a database URL"),
    (["--optimize", "--n-trials", "1", "--n-evaluations", "0"], "--n-evaluations must be >= 1, got 0"),
    (["--optimize", "--n-jobs", "0"], "--n-jobs must be >= 1"),
    (["--optimize", "--resume"], "--resume continues one training run; it does not apply to --optimize"),
    (["--resume", "1.5"], "argument --resume: '1.5' is not a whole number"),
    (["--resume"], "--resume: logs/saeir_ppo/cn-sparse-n3_1 has no spec.json nor cn-sparse-n3/args.yml: it is not a run"),
]


@pytest.mark.parametrize("extra, message", RAW_TRAIN, ids=[m[:40] for _, m in RAW_TRAIN])
def test_raw_library_errors_of_train(root, capsys, extra, message):
    assert_refused(train_main, [*TRAIN, "-f", "logs", *extra], message, capsys, root)


BAD_CONFIG_VALUES = [
    ({"text": f"{TASK}:\n  n_steps: 10\n  n_steps: 20\n"}, "duplicate key 'n_steps' (line 3)"),
    ({"normalize_advantage": "no"}, "normalize_advantage='no' has type str"),
    ({"n_epochs": 2.5}, "n_epochs=2.5 has type float"),
]


@pytest.mark.parametrize("changes, message", BAD_CONFIG_VALUES, ids=[m[:40] for _, m in BAD_CONFIG_VALUES])
def test_config_file_values_are_checked_like_params(root, capsys, changes, message):
    assert_refused(train_main, [*TRAIN, "-f", "logs", "-conf", conf_with(root, **changes)], message, capsys, root)


def test_a_params_key_given_twice_is_refused(root, capsys):
    argv = [*TRAIN, "-f", "logs", "-params", "n_steps:10", "n_steps:20"]
    assert_refused(train_main, argv, "-params n_steps is given twice", capsys, root)


RAW_ENJOY = [
    (["-n", "0"], "-n/--n-episodes must be >= 1, got 0"),
    (["--n-games", "-1"], "--n-games must be >= 1, got -1"),
    (["--gif-episodes", "0", "--gif", "r.gif"], "--gif-episodes must be >= 1"),
    (["--n-games", "1.5"], "argument --n-games: '1.5' is not a whole number"),
    (["--task", "cn-sparse-n9"], "unknown task 'cn-sparse-n9'"),
]


@pytest.mark.parametrize("extra, message", RAW_ENJOY, ids=[m[:40] for _, m in RAW_ENJOY])
def test_raw_library_errors_of_enjoy(root, models, capsys, extra, message):
    argv = ["--algo", "saeir_ppo", "--model", str(models / "saeir.zip"), *extra]
    assert_refused(enjoy_main, argv, message, capsys, root)


def test_enjoy_of_a_file_that_is_no_model(root, capsys):
    (root / "notes.zip").write_text("not a model")
    argv = ["--algo", "saeir_ppo", "--model", "notes.zip", "-n", "1"]
    assert_refused(enjoy_main, argv, "cannot load saeir_ppo from notes.zip", capsys, root)


@pytest.mark.parametrize(
    "extra, message",
    [(["--n-games", "2.5"], "argument --n-games: '2.5' is not a whole number"), (["--jobs", "x"], "argument --jobs")],
)
def test_raw_library_errors_of_benchmark(root, capsys, extra, message):
    argv = ["--algos", "mappo", "--seeds", "1", "-n", "100", "--out", "bench", *extra]
    assert_refused(benchmark_main, argv, message, capsys, root)


def test_count_options_take_rl_zoo_numbers():
    from sb3_saeir.command_line import count

    assert count("100") == 100 and count("1e6") == 1_000_000 and count("2.5e5") == 250_000


# ------------------------------------------------------------------------------------------------ silent acceptance
SILENT_TRAIN = [
    (["-f", ""], "-f/--log-folder is empty"),
    (["-f", "logs", "--eval-freq", "-5"], "--eval-freq must be >= 0 (0: never), got -5"),
    (["-f", "logs", "--save-freq", "-7"], "--save-freq must be >= -1"),
    (["-f", "logs", "--optimize", "--n-trials", "0"], "--n-trials must be >= 1, got 0"),
]


@pytest.mark.parametrize("extra, message", SILENT_TRAIN, ids=[m[:40] for _, m in SILENT_TRAIN])
def test_silently_accepted_train_options(root, capsys, extra, message):
    """Each of these used to train (or start a study) without a word."""
    assert_refused(train_main, [*TRAIN, *extra], message, capsys, root)


def test_device_cuda_without_cuda_is_refused(root, capsys):
    import torch

    if torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    assert_refused(train_main, [*TRAIN, "-f", "logs", "--device", "cuda"], "no CUDA device is available", capsys, root)


def test_python_level_sizes_are_checked(env):
    from sb3_saeir.common.callbacks import EveryAgentSteps
    from sb3_saeir.evaluation import MultiAgentEvalCallback
    from sb3_saeir.experiment import Experiment

    for kwargs in (dict(n_games=2.5), dict(n_games=0), dict(num_cpus=-1), dict(n_games=True)):
        with pytest.raises(ValueError, match=next(iter(kwargs))):
            Experiment("mappo", TASK, **kwargs)
    for kwargs in (dict(n_eval_episodes=0), dict(n_eval_episodes=-2), dict(n_eval_episodes=2.5), dict(eval_freq=-1)):
        with pytest.raises(ValueError, match=next(iter(kwargs))):
            MultiAgentEvalCallback(env, **kwargs)
    with pytest.raises(ValueError, match="frequency"):
        EveryAgentSteps(MultiAgentEvalCallback(env), 2.5)


def test_zoo_train_refuses_duplicate_keys(root, capsys):
    conf = conf_with(root, text=f"{TASK}:\n  n_envs: 2\n  n_timesteps: 60\n  n_steps: 10\n  n_steps: 20\n")
    argv = ["train", "--algo", "mappo", "--env", TASK, "--conf-file", conf, "-f", "logs", "--device", "cpu"]
    assert_refused(zoo_main, [*argv, "--num-threads", "1"], "duplicate key 'n_steps' (line 5)", capsys, root)


# ------------------------------------------------------------------------------------------------ ETA line
def test_zoo_train_prints_the_eta_line_of_train(root, capsys):
    conf = conf_with(root, text=f"{TASK}:\n  n_envs: 2\n  n_timesteps: 120\n  n_steps: 10\n  policy: MAPPOPolicy\n")
    argv = ["train", "--algo", "mappo", "--env", TASK, "--conf-file", conf, "-f", "zoo_logs", "--device", "cpu"]
    assert zoo_main([*argv, "--num-threads", "1", "--seed", "0", "--eval-freq", "-1"]) == 0
    out = capsys.readouterr().out
    assert "First rollout and update:" in out and "the 120 agent-steps take about" in out, out[-2000:]


# ------------------------------------------------------------------------------------------------ issue 35
ZOO_TRAIN = ["train", "--algo", "mappo", "--env", TASK, "--device", "cpu", "--num-threads", "1", "--eval-freq", "-1"]
BAD_N_ENVS = [2.5, "2", "abc", 0, True]


def zoo_conf(root: Path, **changes) -> str:
    """A small rl-zoo3 config of mappo on ``TASK`` with ``changes``."""
    entry = {"n_envs": 2, "n_timesteps": 60, "n_steps": 10, "policy": "MAPPOPolicy", **changes}
    path = root / "zoo.yml"
    path.write_text(yaml.safe_dump({TASK: entry}))
    return str(path)


@pytest.mark.parametrize("value", BAD_N_ENVS, ids=[repr(value) for value in BAD_N_ENVS])
def test_n_envs_of_the_config_file_is_checked(root, capsys, value):
    """A float or a string ``n_envs`` in the YAML ended in a traceback (rl-zoo3's after creating the run folder)."""
    message = f"n_envs (number of games) must be a positive integer, got {value!r}"
    argv = ["--algo", "mappo", "-n", "100", "--eval-freq", "0", "--verbose", "0", "-f", "logs"]
    assert_refused(train_main, [*argv, "-conf", conf_with(root, "mappo", n_envs=value)], message, capsys, root)
    assert_refused(zoo_main, [*ZOO_TRAIN, "-f", "logs", "-conf", zoo_conf(root, n_envs=value)], message, capsys, root)


BAD_HIDDEN_SIZES = ["0", "-4", "2.5", "'8'"]


@pytest.mark.parametrize("value", BAD_HIDDEN_SIZES)
def test_hidden_size_is_checked_on_the_command_lines(root, capsys, value):
    """Torch's messages named no argument; rl-zoo3 also left an empty run folder behind."""
    params = ["-params", f"policy_kwargs:dict(hidden_size={value})"]
    message = "MAPPOPolicy: hidden_size must be a positive integer"
    argv = ["--algo", "mappo", "--n-games", "2", "-n", "100", "--eval-freq", "0", "--verbose", "0", "-f", "logs"]
    assert_refused(train_main, [*argv, *params], message, capsys, root)
    assert_refused(zoo_main, [*ZOO_TRAIN, "-f", "zoo_logs", "-conf", zoo_conf(root), *params], message, capsys, root)


@pytest.mark.parametrize("folder", ["/proc/logs", "/sys/logs"])
def test_log_folder_that_cannot_be_created(root, capsys, folder):
    """A folder the OS refuses although the permission bits allow it (root on /proc, /sys) ended in a traceback."""
    message = f"-f/--log-folder {folder}: "  # /proc: no file can be created in /proc; /sys: /sys is not writable
    assert_refused(train_main, [*TRAIN, "-f", folder], message, capsys, root)
    assert_refused(zoo_main, [*ZOO_TRAIN, "-f", folder, "-conf", zoo_conf(root)], message, capsys, root)


def test_the_writability_check_leaves_the_folder_as_it_was(tmp_path):
    """The probe file of the writability check changed the folder's modification time: a refused ``--resume`` left
    the run folder looking newer than its files."""
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "spec.json").write_text("{}")
    os.utime(folder, ns=(1_000_000_000_000_000_000, 1_500_000_000_000_000_000))  # 2001 and 2017
    assert unwritable_folder(folder) == ""
    assert unwritable_folder(folder / "not" / "made" / "yet") == ""  # probes the nearest existing folder, run/
    times = folder.stat()
    assert (times.st_atime_ns, times.st_mtime_ns) == (1_000_000_000_000_000_000, 1_500_000_000_000_000_000)
    assert sorted(path.name for path in folder.iterdir()) == ["spec.json"]  # no probe left, no folder made


def test_output_files_and_folders_the_os_refuses(root, models, capsys):
    """``--gif`` and ``--out`` under /proc passed the permission check as root and failed at the end (a traceback)."""
    enjoy = ["--algo", "saeir_ppo", "--model", str(models / "saeir.zip"), "-n", "1", "--n-games", "1"]
    assert_refused(enjoy_main, [*enjoy, "--gif", "/proc/replay.gif"], "--gif /proc/replay.gif is not writable", capsys, root)
    bench = ["--algos", "mappo", "--seeds", "1", "-n", "100", "--eval-freq", "50", "--n-games", "2"]
    assert_refused(
        benchmark_main, [*bench, "--out", "/proc/bench"], "--out /proc/bench: no file can be created in /proc", capsys, root
    )


@pytest.mark.parametrize("seed", ["-5", str(2**32)])
def test_seed_options_are_checked(root, models, capsys, seed):
    """``train --seed -5`` drew a seed as -1 does; enjoy's negative seeds ended in NumPy's message (a traceback)."""
    message = f"--seed={seed} is not a seed"
    assert_refused(train_main, [*TRAIN, "-f", "logs", "--seed", seed], message, capsys, root)
    enjoy = ["--algo", "saeir_ppo", "--model", str(models / "saeir.zip"), "-n", "1", "--n-games", "1", "--seed", seed]
    assert_refused(enjoy_main, enjoy, message, capsys, root)
    zoo_enjoy = ["enjoy", "--algo", "mappo", "--env", TASK, "-f", "logs", "--no-render", "-n", "10", "--seed", seed]
    assert_refused(zoo_main, zoo_enjoy, message, capsys, root)


def test_enjoy_n_games_too_large(root, models, capsys):
    """The memory estimate was right but arrived as a MemoryError traceback."""
    argv = ["--algo", "saeir_ppo", "--model", str(models / "saeir.zip"), "-n", "1", "--n-games", "1e9"]
    assert_refused(enjoy_main, argv, "--n-games 1000000000: n_games=1000000000 games of N=3 agents need", capsys, root)


@pytest.mark.parametrize(
    "extra, message",
    [
        (["-f", "nothere"], "enjoy: AssertionError: The nothere/mappo folder was not found"),
        (["-f", "logs", "--exp-id", "7"], "enjoy: AssertionError: The logs/mappo/cn-sparse-n3_7 folder was not found"),
    ],
)
def test_zoo_enjoy_errors_of_rl_zoo3_are_one_line(root, capsys, extra, message):
    (root / "logs" / "mappo").mkdir()
    argv = ["enjoy", "--algo", "mappo", "--env", TASK, "--no-render", "-n", "10", *extra]
    assert_refused(zoo_main, argv, message, capsys, root)


def _progress_without_saeir_logs(root: Path) -> str:
    run = root / "mappo_run"
    run.mkdir()
    (run / "progress.csv").write_text("time/total_timesteps,rollout/ep_rew_mean\n100,0.5\n")
    return str(run)


@pytest.mark.parametrize(
    "folder, message",
    [
        (lambda root: "nothere", "--entropy-plot nothere is not a folder"),
        (lambda root: "logs", "--entropy-plot logs has no progress.csv"),
        (_progress_without_saeir_logs, "has no SAEIR logs (rollout/intrinsic_reward_mean)"),
    ],
    ids=["missing", "no progress.csv", "not SAEIR"],
)
def test_entropy_plot_of_a_folder_that_is_no_saeir_run(root, capsys, folder, message):
    """A missing folder was reported as a run without SAEIR logs, in a traceback."""
    assert_refused(benchmark_main, ["--entropy-plot", folder(root)], message, capsys, root)


def test_more_env_workers_than_cores_warns_in_one_line(root, capsys, monkeypatch):
    import sb3_saeir.common.vec_env.factory as vec_env_module

    monkeypatch.setattr(vec_env_module, "usable_cores", lambda: 1)
    argv = ["--algo", "mappo", "--n-games", "2", "-n", "60", "--eval-freq", "0", "--verbose", "0", "-f", "logs"]
    assert train_main([*argv, "--num-cpus", "2", "-params", "n_steps:10"]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert warnings == [
        "sb3_saeir.train: warning: make_multiagent_vec_env: num_cpus=2 starts 2 env worker processes, but this machine "
        "gives this process 1 core(s): the workers take turns and step slower than fewer would; pass num_cpus=0 "
        "(every game in this process)."
    ]


def test_zoo_enjoy_replays_without_a_window_by_default(capsys):
    """rl_zoo3.enjoy asks for render_mode='human', which the tasks do not have: it ended in a traceback."""
    from sb3_saeir.zoo.launcher import prepare_enjoy_args

    assert "--no-render" in prepare_enjoy_args(["--algo", "mappo", "--env", TASK, "-n", "10"])
    assert "--no-render added" in capsys.readouterr().out
    assert prepare_enjoy_args(["--env", "CartPole-v1"]) == ["--env", "CartPole-v1"]  # other envs: untouched


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


# ------------------------------------------------------------------------------------------------ round 6 (issue 67)
@pytest.mark.parametrize(
    "extra, message",
    [
        (["--double-buffered", "on"], "(double_buffered=True) cannot sample this env: its games run in one process"),
        (["-conf", "."], "config file . is a folder; give a YAML file such as saeir_ppo.yml"),
        (["-conf", "empty.yml"], "empty.yml is empty: it must map task ids to dicts of hyperparameters"),
        (["-params", "n_envs:4"], "-params n_envs:4 and --n-games 2 disagree: give it once"),
        (["-params", "n_timesteps:60"], "-params n_timesteps:60 and -n 100 disagree: give it once"),
        (["--resume", ""], "argument --resume: give a run number or a run folder"),  # was the current folder
    ],
)
def test_round_6_train_refusals(root, capsys, extra, message):
    """Double buffering without workers failed at the first rollout, its run folder written; a folder as -conf was
    "does not exist", an empty file "has no entry ... Entries: ."."""
    (root / "empty.yml").write_text("")
    assert_refused(train_main, [*TRAIN, "-f", "logs", *extra], message, capsys, root)


def test_a_dangling_link_as_log_folder_is_named(tmp_path, capsys):
    """``-f`` a link to a folder that does not exist: "[Errno 17] File exists" before."""
    os.symlink(tmp_path / "nowhere", tmp_path / "dangling")
    assert run(train_main, [*TRAIN, "-f", str(tmp_path / "dangling")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"is a link to {tmp_path / 'nowhere'}, which does not exist" in line
    assert sorted(path.name for path in tmp_path.iterdir()) == ["dangling"]


@pytest.mark.parametrize(
    "extra, message",
    [
        (["-n", "0"], "-n 0: a budget is a number of agent-steps >= 1"),
        (["--eval-episodes", "0"], "--eval-episodes 0: an evaluation plays >= 1 game episode"),
        (["-optimize"], "-optimize: rl-zoo3 has no samplers for the package's methods"),
        (["--resume", ""], "sb3_saeir.zoo: error: argument --resume: give a run number or a run folder"),
    ],
)
def test_round_6_zoo_refusals(root, capsys, extra, message):
    """``-n 0`` trained the config's whole budget; ``--eval-episodes 0`` failed at the first evaluation."""
    argv = ["train", "--algo", "mappo", "--env", TASK, "-f", "logs", "-params", "n_envs:2", "n_steps:10"]
    assert_refused(zoo_main, [*argv, *extra], message, capsys, root)


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--algos", "mappo", "mappo"], "--algos names ['mappo'] more than once"),
        (["--tasks", TASK, TASK], f"--tasks names ['{TASK}'] more than once"),
        (["--seeds", "-1"], "--seeds '-1': -1 is not a seed; seeds are 0 .. 2**32 - 1"),
        (["--seeds", "4294967296"], "4294967296 is not a seed"),
        (["-params", "n_envs:4"], "-params n_envs:4 and --n-games 2 disagree: give it once"),
        (["-params", "n_timesteps:60"], "-params n_timesteps:60 and -n 100 disagree: give it once"),
    ],
)
def test_round_6_benchmark_refusals(root, capsys, extra, message):
    """Repeated methods or tasks listed each run twice (with --jobs 2, a job refused by its own driver's lock); a
    negative seed was named as make_multiagent_vec_env's argument."""
    argv = ["--algos", "mappo", "--seeds", "1", "-n", "100", "--eval-freq", "50", "--n-games", "2", "--out", "bench"]
    assert_refused(benchmark_main, [*argv, *extra], message, capsys, root)


def test_a_run_folder_numbered_with_a_non_ascii_digit_is_left_out(root, capsys):
    """``cn-sparse-n3_²`` (a digit to ``str.isdigit``, not to ``int``) stopped every new run in the log folder."""
    (root / "logs" / "mappo" / f"{TASK}_²").mkdir(parents=True)
    argv = ["--algo", "mappo", "--n-games", "2", "-n", "60", "--eval-freq", "0", "--verbose", "0", "-params", "n_steps:10"]
    assert run(train_main, [*argv, "-f", "logs"]) == 0
    assert (root / "logs" / "mappo" / f"{TASK}_1" / "done.json").is_file()
