"""Write ``interrupted_benchmark/``: a benchmark folder whose runs stopped mid-way, for the test that runs started
before a change of the code resume after it (``tests/test_benchmark_formats.py``).

Made with sb3-saeir at commit cf63ac6 (the last commit with ``sb3_saeir/benchmark.py`` as one module)::

    OMP_NUM_THREADS=1 python tests/data/make_interrupted_benchmark.py

Each run of ``ARGV`` fails at its third evaluation (504 agent-steps; its checkpoint is at 480), as a kill would
stop it there; ``expected_runs.csv`` is the same benchmark run uninterrupted by that code. Re-make both when the
packaged ``mappo`` or ``saeir_ppo`` config of ``cn-sparse-n3`` changes (the resume refuses a changed config).
"""

import shutil
import sys
import tempfile
from pathlib import Path

from sb3_saeir.benchmark import main
from sb3_saeir.run.output import RunEvalCallback as BenchmarkEvalCallback

ARGV = [
    "--algos", "mappo", "saeir_ppo", "--tasks", "cn-sparse-n3", "--seeds", "1", "-n", "900", "--n-games", "2",
    "--eval-freq", "250", "--eval-episodes", "2", "-params", "n_steps:10", "n_epochs:2",
]  # fmt: skip
HERE = Path(__file__).parent


def fail_at_third_evaluation() -> None:
    original = BenchmarkEvalCallback.evaluate

    def evaluate(self: BenchmarkEvalCallback) -> bool:
        if len(self.rows) == 2:
            raise RuntimeError("stopped here on purpose")
        return original(self)

    BenchmarkEvalCallback.evaluate = evaluate  # type: ignore[method-assign]


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as temp:
        assert main([*ARGV, "--out", temp]) == 0
        shutil.copyfile(Path(temp) / "runs.csv", HERE / "expected_runs.csv")
    target = HERE / "interrupted_benchmark"
    shutil.rmtree(target, ignore_errors=True)
    fail_at_third_evaluation()
    status = main([*ARGV, "--out", str(target)])
    assert status == 1, status  # every run failed at its third evaluation
    for name in ("failures.txt", "runs.csv", "curves.png", "table.md"):
        (target / name).unlink(missing_ok=True)
    sys.exit(0)
