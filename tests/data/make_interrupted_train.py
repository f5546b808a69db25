"""Write ``interrupted_train/``: ``python -m sb3_saeir.train`` run folders that stopped mid-way, for the test that
runs started before a change of the code resume after it (``tests/test_train_formats.py``).

Made with sb3-saeir at commit 2ff651c (the last commit before one ``Run`` owns a training run, issue 34)::

    OMP_NUM_THREADS=1 python tests/data/make_interrupted_train.py

The ``mappo`` run of ``SETTINGS`` stops at the first rollout start at or after 600 agent-steps, as a kill would
stop it there (its checkpoints are at 240 and 480 agent-steps: the one at 480 is kept, with ``progress.csv`` and
``games.monitor.csv`` holding rows past it, as after a kill; ``best_model.zip`` and the checkpoint at 240 are left
out to keep the data small); ``interrupted_train/expected/`` holds what the same run uninterrupted by that code ends
with: its final parameters, ``progress.csv`` and ``evaluations.npz``. Re-make them when the packaged ``mappo``
config of ``cn-sparse-n3`` changes (the resume refuses a changed config).
"""

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch as th

from sb3_saeir.common.run_state import RunCheckpointCallback
from sb3_saeir.train import main

# 2 games x 3 agents: 60 agent-steps per rollout; checkpoints every 240 agent-steps, evaluations every 250
SETTINGS = [
    "--task", "cn-sparse-n3", "--seed", "1", "-n", "900", "--n-games", "2", "--eval-freq", "250", "--eval-episodes", "2",
    "--save-freq", "240", "--num-threads", "1", "-params", "n_steps:10", "n_epochs:2",
]  # fmt: skip
ALGOS = ("mappo",)  # the benchmark's interrupted runs cover saeir_ppo's resume state; this keeps the data small
STOP_AT = 600  # agent-steps
HERE = Path(__file__).parent


def stop_at_600_agent_steps() -> None:
    original = RunCheckpointCallback._on_rollout_start

    def on_rollout_start(self: RunCheckpointCallback) -> None:
        original(self)
        if self.model.num_timesteps >= STOP_AT:
            raise RuntimeError("stopped here on purpose")

    RunCheckpointCallback._on_rollout_start = on_rollout_start  # type: ignore[method-assign]


def save_expected(run: Path, target: Path) -> None:
    """The final parameters (as float64 arrays by name), ``progress.csv`` and ``evaluations.npz`` of a finished run."""
    from stable_baselines3.common.save_util import load_from_zip_file

    target.mkdir(parents=True)
    _, params, _ = load_from_zip_file(run / "cn-sparse-n3.zip")
    arrays = {f"{part}.{name}": tensor.numpy() for part, tensors in params.items() for name, tensor in tensors.items()
              if isinstance(tensor, th.Tensor)}  # fmt: skip
    np.savez(target / "parameters.npz", **arrays)
    shutil.copyfile(run / "progress.csv", target / "progress.csv")
    shutil.copyfile(run / "evaluations.npz", target / "evaluations.npz")


if __name__ == "__main__":
    target = HERE / "interrupted_train"
    shutil.rmtree(target, ignore_errors=True)
    with tempfile.TemporaryDirectory() as temp:
        for algo in ALGOS:
            assert main(["--algo", algo, *SETTINGS, "-f", temp]) == 0
            save_expected(Path(temp) / algo / "cn-sparse-n3_1", target / "expected" / algo)
    stop_at_600_agent_steps()
    for algo in ALGOS:
        try:
            main(["--algo", algo, *SETTINGS, "-f", str(target / "logs")])
        except RuntimeError as error:
            assert "on purpose" in str(error), error
        else:
            raise AssertionError("the run was not stopped")
        run = target / "logs" / algo / "cn-sparse-n3_1"
        (run / "best_model.zip").unlink()
        (run / "rl_model_240_steps.zip").unlink()
    sys.exit(0)
