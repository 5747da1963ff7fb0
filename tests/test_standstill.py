"""Standstill monitoring starts when each axis is in position (runtime/components/safety.py,
docs/safety.md "Standstill").

The false emergency stop of the issue: on an arm with a fast wrist (the Staubli TX2-60's
A4: 995 deg/s, 3,800 deg/s^2), a full-acceleration ptp followed by a dwell ended in a
category-0 stop, "J4 moved 11 encoder counts while the robot must be at rest (allowed:
10)": standstill was monitored from a fixed 50 ms after the setpoint stopped, while the
servo was still settling the last counts of its lag.
"""
from __future__ import annotations

from compiler.driver import compile_source
from compiler.spec import parse_spec
from limits_watch import LimitWatch, at_rest_and_safe, run_cycle
from runtime.system import RobotSystem, RunOptions

from conftest import SPEC_PATH

LOLA = SPEC_PATH.read_text(encoding="utf-8")


def with_axis(text: str, name: str, **values) -> str:
    """``text`` with the ``[[axis]]`` named ``name`` given ``values`` (keys it has)."""
    start = text.index(f'name = "{name}"')
    end = text.find("[[axis]]", start)
    end = len(text) if end < 0 else end
    lines = text[start:end].split("\n")
    for key, value in values.items():
        index = next(i for i, line in enumerate(lines) if line.startswith(f"{key} = "))
        lines[index] = f"{key} = {value!r}"
    return text[:start] + "\n".join(lines) + text[end:]


#: The Lola 15 with a wrist as fast as the TX2-60's (its published A4 speed; 3,800 deg/s^2,
#: a jerk of ten times that) and the plausibility distance that wrist needs
#: (compiler.params.least_plausibility_distance: 0.19 deg).
FAST_WRIST = with_axis(LOLA, "A4", max_velocity=995.0, max_acceleration=3800.0, max_jerk=38000.0).replace(
    "[simulation]", "[safety]\nplausibility_distance = 0.2\n\n[simulation]")
ISSUE = """  move ptp joint(mainjoint(0,0,90,0,45,0));
  move ptp joint(mainjoint(0,0,90,180,45,0)) speed_ptp := 1 acc_ptp := 1;
  wait 0.5 sec;
"""


def compiled(spec_text: str, body: str, tmp_path, name: str = "standstill"):
    path = tmp_path / f"{name}.spc"
    path.write_text(spec_text, encoding="utf-8")
    source = f'program {name};\nsystem_specification "{path}";\nseq\n{body}endseq\nendprogram;\n'
    result = compile_source(source, f"{name}.irl", path)
    assert result.ok, result.diagnostics
    return parse_spec(spec_text, str(path)), result.program


def test_a_fast_wrist_comes_to_rest_after_a_full_acceleration_ptp_without_a_false_stop(tmp_path):
    """The issue's program on the fast wrist, three seeds (on the unfixed code seeds 0 and
    2 stopped: A4 moved 11 encoder counts, allowed 10)."""
    spec, program = compiled(FAST_WRIST, ISSUE, tmp_path)
    for seed in (0, 1, 2):
        system = RobotSystem(spec, RunOptions(seed=seed))
        watch = LimitWatch(system)
        summary = run_cycle(system, program)
        assert summary["fault"] is None, (seed, summary["fault"])
        assert at_rest_and_safe(system) and watch.beyond == 0.0
