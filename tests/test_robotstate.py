"""The robot's own state and the clocks (compiler/robotstate.py, issue 33 item 2):
current_joint, current_pose, tcp_speed, timed_out, clock_start/stop/reset/read. In the VM
against a fake world, and end to end in the simulated robot (irl run)."""
from __future__ import annotations

import json
import math
import re
import shutil

import pytest

from compiler.configs import config_of
from compiler.values import Joint, Pose, Position, Rpy
from runtime.loop.vm import VMStatus
from runtime.motion.kinematics import Kinematics

from conftest import SPEC, SPEC_PATH, run_cli
from test_vm import DISPATCHES, FakeHost, run_source


@pytest.fixture(params=DISPATCHES)
def dispatch(request):
    return request.param


class StateHost(FakeHost):
    """A fake world that says where the robot is."""

    def current_joint(self):
        return Joint((1.0, 2.0, 3.0, 4.0, 5.0, 6.0))

    def current_pose(self):
        return Pose(Position(1.0, 2.0, 3.0), Rpy(0.0, 90.0, 0.0))

    def tcp_speed(self):
        return 250.0


def test_the_clocks_run_stop_keep_their_time_and_reset(tmp_path, dispatch):
    """A clock counts the seconds between its start and its stop on the world's clock
    (a dwell of 0.5 s reads 0.5), keeps its time while stopped, goes on from it when
    started again, reads 0 after a reset (running on if it ran); a clock never started
    reads 0; each clock is its own."""
    body = """
      print clock_read(3);
      call clock_start(1);
      wait 0.5 sec;
      print clock_read(1);
      call clock_stop(1);
      wait 0.3 sec;
      print clock_read(1);
      call clock_start(1);
      call clock_start(2);
      wait 0.2 sec;
      print clock_read(1), " ", clock_read(2);
      call clock_reset(1);
      print clock_read(1);
      wait 0.1 sec;
      print clock_read(1);
    """
    machine, host = run_source(tmp_path, body, host=StateHost(), dispatch=dispatch, dt=0.005)
    assert machine.status == VMStatus.DONE, machine.error
    values = [[float(x) for x in text.split()] for text in host.texts]
    expected = [[0.0], [0.5], [0.5], [0.7, 0.2], [0.0], [0.1]]
    assert len(values) == len(expected)
    for got, want in zip(values, expected):
        assert got == pytest.approx(want, abs=0.006), (values, expected)


def test_a_clock_number_out_of_range_stops_the_program_at_its_line(tmp_path):
    machine, _host = run_source(tmp_path, "n := 9;\ncall clock_start(n);", "var n: integer;", host=StateHost())
    assert machine.status == VMStatus.ERROR
    assert "clock 9 does not exist: a program has clocks 1..8" in str(machine.error)


def test_timed_out_says_how_the_last_wait_for_ended(tmp_path, dispatch):
    """False before any wait; true after a wait for that timed out; false again after one
    whose condition held (in[2] is on in this world)."""
    body = """
      print timed_out();
      wait for in[1] timeout 0.1 sec;
      print timed_out();
      wait for in[2] timeout 0.1 sec;
      print timed_out();
    """
    machine, host = run_source(tmp_path, body, host=StateHost(inputs={2: True}), dispatch=dispatch)
    assert machine.status == VMStatus.DONE, machine.error
    assert [text for text in host.texts if not text.startswith("wait for")] == ["false", "true", "false"]


def test_the_robot_state_functions_ask_the_world(tmp_path, dispatch):
    body = "print current_joint();\nprint current_pose();\nprint tcp_speed();"
    machine, host = run_source(tmp_path, body, host=StateHost(), dispatch=dispatch)
    assert machine.status == VMStatus.DONE, machine.error
    assert host.texts == ["joint(mainjoint(1, 2, 3, 4, 5, 6))", "pose(pos(1, 2, 3), rpy(0, 90, 0))", "250"]


def test_a_programs_own_routine_of_the_same_name_is_called_instead(tmp_path):
    """The names are not reserved: a program that declared a function current_pose or a
    procedure clock_start before they existed still calls its own."""
    decls = """
    function current_pose(): integer;
    seq
      return 7;
    endseq
    endfunction;
    procedure clock_start(n: integer);
    seq
      print "mine ", n;
    endseq
    endprocedure;
    """
    machine, host = run_source(tmp_path, "print current_pose();\ncall clock_start(2);", decls, host=StateHost())
    assert machine.status == VMStatus.DONE, machine.error
    assert host.texts == ["7", "mine 2"]


PROGRAM = """program state;
system_specification "lola15.spc";
var q: joint;
var p: pose;
seq
  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0)) speed_ptp:=0.5;
  call clock_start(1);
  move ptp joint(mainjoint(30, -20, 30, 0, 40, 0)) speed_ptp:=0.5 approx:=1;
  q := current_joint();
  p := current_pose();
  print "clock ", clock_read(1);
  print "joint ", q;
  print "pose ", p;
  print "speed ", tcp_speed();
  move lin p;
  use base frame(pos(100, 0, 0), rpy(0, 0, 90));
  print "in base ", current_pose();
endseq
endprogram;
"""


def test_in_the_simulated_robot_the_state_is_where_the_robot_stands(tmp_path):
    """End to end (irl run): current_joint waits for the move before it (an approx
    there does not blend) and gives its target; current_pose is the TCP there with the
    arm's configuration, in the world and then in a base; clock 1 measured the move
    (its actual time, to the control cycle); the TCP is at rest; and the pose read is a
    target the robot reaches again."""
    shutil.copy(SPEC_PATH, tmp_path / "lola15.spc")
    source = tmp_path / "state.irl"
    source.write_text(PROGRAM, encoding="utf-8")
    code, out, err = run_cli("run", source, "--json")
    assert code == 0, err
    summary = json.loads(out)
    log = {entry["text"].split(" ", 1)[0]: entry["text"].split(" ", 1)[1] for entry in summary["log"]}
    joints = (30.0, -20.0, 30.0, 0.0, 40.0, 0.0)
    assert log["joint"] == "joint(mainjoint(30, -20, 30, 0, 40, 0))"
    kinematics = Kinematics(SPEC)
    world = kinematics.forward(joints)
    numbers = [float(x) for x in re.findall(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", log["pose"].split("config")[0])]
    assert numbers == pytest.approx(list(world), abs=1e-6)
    assert log["pose"].endswith(f"{config_of(kinematics.configuration(joints), joints)})")
    moved = [m for m in summary["moves"] if m["line"] == 8][0]
    assert float(log["clock"]) == pytest.approx(moved["actual_duration"], abs=0.006)
    assert float(log["speed"]) == 0.0
    in_base = [float(x) for x in re.findall(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", log["in"].split("config")[0])]
    # the base: 100 mm along x, turned 90 deg about z: world (x, y) is base (y, 100 - x)
    assert in_base[:3] == pytest.approx([world[1], 100.0 - world[0], world[2]], abs=1e-6)
    assert math.isclose(in_base[5], world[5] - 90.0, abs_tol=1e-6) or math.isclose(in_base[5], world[5] + 270.0,
                                                                                   abs_tol=1e-6)
    assert summary["fault"] is None and summary["final_position"][:6] == pytest.approx(joints, abs=1e-3)


def test_tcp_speed_in_an_interrupts_handler_is_the_tools_speed_then(tmp_path):
    """tcp_speed() does not wait for the robot: an interrupt's handler, fired by a path
    trigger halfway along a lin move at 200 mm/s (its cruise), reads about 200 mm/s."""
    shutil.copy(SPEC_PATH, tmp_path / "lola15.spc")
    source = tmp_path / "speed.irl"
    source.write_text("""program speed;
system_specification "lola15.spc";
const down := rpy(180, 30, 180);
var halfway: bool;
interrupt measure when halfway priority 1 continue;
seq
  print "speed ", tcp_speed();
endseq
endinterrupt;
seq
  move ptp pose(pos(650, 0, 400), down);
  enable measure;
  trigger when 150 mm after start do halfway := true;
  move lin pose(pos(950, 0, 400), down) speed := 200;
endseq
endprogram;
""", encoding="utf-8")
    code, out, err = run_cli("run", source, "--json")
    assert code == 0, err
    speeds = [float(e["text"].split()[1]) for e in json.loads(out)["log"] if e["text"].startswith("speed")]
    assert speeds and speeds[0] == pytest.approx(200.0, rel=0.02), speeds


def test_the_manual_lists_every_routine_of_the_table():
    """docs/language.md's table has a row for each routine of compiler.robotstate.ROUTINES
    (the one declaration), and no row for a routine the table lacks."""
    from compiler.robotstate import ROUTINES
    from conftest import ROOT

    text = (ROOT / "docs" / "language.md").read_text(encoding="utf-8")
    section = text.split("## The robot's own state and clocks", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| `(?:call )?(\w+)\(", section, re.M)
    assert set(rows[:len(ROUTINES)]) == set(ROUTINES), rows


def test_a_pulse_is_on_for_its_time_and_an_output_reads_back_as_set(tmp_path):
    """call pulse_out(N, T): output N is on from where the robot is for T seconds while the
    program goes on (the report, every 1 ms, sees it on for T to the control cycle), and
    the program ends only when its last pulse has; out[N] reads what was set."""
    import csv

    from compiler.driver import compile_source
    from runtime.loop.system import RobotSystem, RunOptions
    from runtime.timing import TICK

    source = (f'program p;\nsystem_specification "{SPEC_PATH}";\nseq\n'
              '  out[2] := true;\n  print out[2], " ", out[3];\n  call pulse_out(3, 0.5);\n  print out[3];\n'
              '  wait 0.3 sec;\n  print out[3];\n  wait 0.3 sec;\n  print out[3];\n  call pulse_out(4, 0.2);\n'
              'endseq\nendprogram;\n')
    result = compile_source(source, str(tmp_path / "p.irl"))
    assert result.ok, result.diagnostics
    system = RobotSystem(SPEC, RunOptions())
    system.apply_settings({"report": {"period": TICK, "columns": ["io"]}})
    report = tmp_path / "r.csv"
    system.begin(result.program, report)
    while not system.supervisor.done:
        system.executive.step()
    summary = system.finish()
    assert summary["fault"] is None and [e["text"] for e in summary["log"]] == ["true false", "true", "true", "false"]
    rows = list(csv.DictReader(report.open()))

    def on(column):
        times = [float(r["time"]) for r in rows if r[column] == "1"]
        return times[0], times[-1]
    first, last = on("out_3")
    assert last - first == pytest.approx(0.5, abs=0.006)
    first, last = on("out_4")
    assert last - first == pytest.approx(0.2, abs=0.006)
    assert rows[-1]["out_4"] == "0" and rows[-1]["out_2"] == "1"
