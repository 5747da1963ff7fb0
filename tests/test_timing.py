"""The loop's periods are declared once (runtime/timing.py, from compiler.params): no
module of the runtime writes a period of its own."""
from __future__ import annotations

import io
import tokenize
from pathlib import Path

from compiler.params import TICK, component_params
from runtime import timing

RUNTIME = Path(__file__).resolve().parent.parent / "runtime"
PERIODS = {0.001, 0.005, 0.01}
#: Numbers of the same value that are no period: (file, the name on their line).
NOT_PERIODS = {("motion/paths.py", "POINT_TOL"), ("motion/pathcheck.py", "START_TOL"),
               ("motion/pathtiming.py", "SETTLED"), ("motion/pathtiming.py", "STOP_LOWEST"),
               ("cli/netcli.py", "WATCH_SLACK"),
               ("loop/components/initialization.py", "SETTLE_WINDOW")}


def period_literals(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every number in the code (not in strings or comments) equal to a period."""
    found = []
    source = path.read_text(encoding="utf-8")
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.NUMBER:
            try:
                value = float(token.string)
            except ValueError:
                continue
            if value in PERIODS:
                found.append((token.start[0], token.line.strip()))
    return found


def test_no_runtime_module_writes_a_period_of_its_own():
    found = []
    for path in sorted(RUNTIME.rglob("*.py")):
        name = path.relative_to(RUNTIME).as_posix()
        if name == "timing.py":
            continue
        for line, text in period_literals(path):
            if not any(name == file and text.startswith(f"{word} =") for file, word in NOT_PERIODS):
                found.append(f"runtime/{name}:{line}: {text}")
    assert not found, "periods written outside runtime/timing.py:\n" + "\n".join(found)


def test_the_scan_finds_a_period(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text('"""0.005 in a docstring is fine"""\nperiod = 0.005  # 0.001 in a comment too\nx = 5e-3\n')
    assert [line for line, _ in period_literals(bad)] == [2, 3]


def test_the_periods_are_the_parameters_defaults():
    assert timing.TICK == TICK == 0.001
    assert timing.SETPOINT_PERIOD == component_params("trajectory")["period"].default
    assert timing.SETPOINT_PERIOD == component_params("initialization")["period"].default
    assert timing.REPORT_PERIOD == component_params("report")["period"].default
