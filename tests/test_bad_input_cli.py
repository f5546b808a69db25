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
