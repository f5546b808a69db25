"""benchmarks/cpu_scaling.py: the same job in 1 and 2 processes started together, and the speed-up it prints."""

import re
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).parent.parent / "benchmarks" / "cpu_scaling.py"


def test_prints_one_row_per_kind_and_process_count():
    result = subprocess.run(
        [sys.executable, str(SCRIPT), "--kinds", "python", "matmul", "--processes", "1", "2", "--seconds", "0.2"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    rows = [line.split() for line in result.stdout.splitlines() if re.match(r"\s+(python|matmul)\s", line)]
    assert [(kind, processes) for kind, processes, *_ in rows] == [
        ("python", "1"),
        ("python", "2"),
        ("matmul", "1"),
        ("matmul", "2"),
    ]
    for _, processes, wall, speed_up in rows:
        assert float(wall) > 0
        assert 0 < float(speed_up) <= int(processes) * 1.5  # alone: exactly 1
    assert all(float(speed_up) == 1.0 for _, processes, _, speed_up in rows if processes == "1")


def test_work_units_scale_the_time(load_benchmark_script):
    cpu_scaling = load_benchmark_script("cpu_scaling")
    assert cpu_scaling.calibrate("python", 0.0) == 1
    assert cpu_scaling.timed("python", 2) > 0
