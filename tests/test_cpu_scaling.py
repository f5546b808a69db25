"""benchmarks/cpu_scaling.py: the same job in 1 and 2 processes started together, and the speed-up it prints.

The figures themselves depend on the machine and on what else runs (pytest-xdist runs other tests beside this one),
so the tests check the table's shape, the formula, and that the printed speed-up follows from the printed times; never
a bound on the speed-up (see the script's docstring: it measures the machine, on an idle one).
"""

import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

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
    alone = {kind: float(wall) for kind, processes, wall, _ in rows if processes == "1"}
    for kind, processes, wall, printed in rows:
        assert float(wall) > 0 and float(printed) > 0
        # the printed speed-up is k x alone / wall of the printed times, up to their rounding to 0.01 s
        k, rounding = int(processes), 0.005
        low = k * (alone[kind] - rounding) / (float(wall) + rounding)
        high = k * (alone[kind] + rounding) / (float(wall) - rounding)
        assert low - 0.005 <= float(printed) <= high + 0.005
    assert all(float(printed) == 1.0 for _, processes, _, printed in rows if processes == "1")


def test_speed_up_closed_form(load_benchmark_script):
    cpu_scaling = load_benchmark_script("cpu_scaling")
    assert cpu_scaling.speed_up(1, 3.0, 3.0) == 1.0
    assert cpu_scaling.speed_up(2, 3.0, 3.0) == 2.0  # two independent cores: twice the work in the same time
    assert cpu_scaling.speed_up(2, 3.0, 6.0) == 1.0  # one core shared: no gain
    assert cpu_scaling.speed_up(4, 2.0, 5.0) == pytest.approx(1.6)


def test_timed_runs_the_units_asked_and_measures_them(load_benchmark_script, monkeypatch):
    cpu_scaling = load_benchmark_script("cpu_scaling")
    asked = []

    def work(units):
        asked.append(units)
        time.sleep(0.01 * units)

    monkeypatch.setitem(cpu_scaling.WORK, "python", work)
    assert cpu_scaling.timed("python", 3) >= 0.03
    assert asked == [3]


def test_calibration_divides_the_target_by_one_unit(load_benchmark_script, monkeypatch):
    cpu_scaling = load_benchmark_script("cpu_scaling")
    timed_units = []

    def one_unit_takes_10_ms(kind, units):
        timed_units.append((kind, units))
        return 0.01 * units

    monkeypatch.setattr(cpu_scaling, "timed", one_unit_takes_10_ms)
    assert cpu_scaling.calibrate("matmul", 0.5) == 50
    assert cpu_scaling.calibrate("matmul", 0.004) == 1  # never less than one unit
    assert timed_units == [("matmul", 1), ("matmul", 1)]
