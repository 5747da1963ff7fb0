"""World zones (issue 33 item 6; compiler.zones, docs/language.md "World zones"): boxes and
cylinders of the specification that the flange and the tool centre point never enter.

* the property: whatever moves a program asks for (ptp, lin, circ, blends), no 1 ms
  reference of the servo has either point inside a zone (the planner refuses a path that
  comes within MARGIN, and makes no blend that would);
* the checks before anything moves: a constant target in a zone (irl check), a path
  through one (irl check's motion check, irl run's move error, which a handler can take);
* the safety supervisor's backstop: a reference inside a zone (here: a planner told of no
  zone) stops the robot (category 1, "zone"), which ends at rest;
* the specification's [[zone]] tables and their errors."""
from __future__ import annotations

import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from compiler.spec import SpecError, parse_spec
from compiler.zones import MARGIN, Zone
from runtime.loop.system import RobotSystem, RunOptions
from runtime.motion.kinematics import Kinematics
from runtime.motion.motionqueue import MotionQueue
from runtime.motion.moves import MovePlanner
from runtime.timing import SETPOINT_PERIOD

from conftest import SPEC, SPEC_PATH, examples, run_cli
from test_motionqueue import programs, servo_references

KIN = Kinematics(SPEC)
TOOL = tuple(SPEC.tool[:3])
ZONES = """
[[zone]]
name = "fixture"
shape = "box"
min = [800, 200, 0]
max = [1000, 400, 340]

[[zone]]
name = "post"
shape = "cylinder"
centre = [300, 700]
radius = 80
z = [0, 2000]
"""


def zoned(text: str = ZONES):
    return parse_spec(SPEC_PATH.read_text(encoding="utf-8") + text, "zoned.spc")


def deepest(references) -> float:
    """How far the flange or the tool centre point of any reference gets into ZONE (mm; < 0:
    it stays that far outside)."""
    worst = -1e9
    for q in references:
        flange, tcp = KIN.flange_and_tcp(q[:6], TOOL)
        worst = max(worst, ZONE_BOX.depth(*flange), ZONE_BOX.depth(*tcp))
    return worst


ZONE_BOX = Zone("zone", "box", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))  # (set by the property for each example)


@st.composite
def zoned_programs(draw):
    """A program of test_motionqueue's and a box near where its tool starts (not around it)."""
    q0, moves = draw(programs())
    flange, tcp = KIN.flange_and_tcp(q0[:6], TOOL)
    centre = [c + draw(st.floats(-180.0, 180.0)) for c in tcp]
    size = [draw(st.floats(20.0, 160.0)) for _ in range(3)]
    box = Zone("box", "box", tuple(c - s / 2 for c, s in zip(centre, size)),
               tuple(c + s / 2 for c, s in zip(centre, size)))
    return q0, moves, box


@settings(max_examples=examples(25), deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(zoned_programs())
def test_no_1_ms_reference_enters_a_zone_whatever_the_program_asks_for(program):
    global ZONE_BOX
    q0, moves, box = program
    ZONE_BOX = box
    if deepest([q0]) > -MARGIN:
        return  # (the robot starts in or at the zone: every move is refused, nothing to see)
    queue = MotionQueue(MovePlanner(SPEC.axes, SPEC.main_axes, "jerk", KIN, zones=(box,)), SPEC.axes)
    queue.start(q0, SETPOINT_PERIOD)
    for move in moves:
        if queue.add(move) is not None:
            break  # (refused: the program stops at it, as the runtime's does)
    setpoints, now = [(0.0, queue.positions, queue.velocities)], 0.0
    while not queue.done():
        now += SETPOINT_PERIOD
        queue.sample(now)
        setpoints.append((now, queue.positions, queue.velocities))
    assert deepest(servo_references(q0, setpoints)) < 0.0


def test_a_planner_without_zones_would_have_entered_one():
    # (the property above is not empty: the same planner without the zone goes through it)
    from compiler.values import Joint
    from runtime.motion.moves import MoveRequest

    box = Zone("box", "box", (-50.0, -50.0, -50.0), (50.0, 50.0, 50.0))
    q0 = (0.0, -30.0, 30.0, 0.0, 45.0, 0.0)
    x, y, z, r, p, w = KIN.forward(q0)
    box = Zone("box", "box", (x + 100, y - 50, z - 50), (x + 150, y + 50, z + 50))
    through = MoveRequest("lin", ((x + 300, y, z, r, p, w),), 250.0, 1000.0, 0.0, 1)
    refused = MovePlanner(SPEC.axes, SPEC.main_axes, "jerk", KIN, zones=(box,)).plan(through, q0, None, 0.005)
    assert refused[0] is None and "enters zone 'box'" in refused[1] and "the tool centre point" in refused[1]
    planned, _ = MovePlanner(SPEC.axes, SPEC.main_axes, "jerk", KIN).plan(through, q0, None, 0.005)
    global ZONE_BOX
    ZONE_BOX = box
    assert deepest([planned.trajectory.position_at(t / 100 * planned.duration) for t in range(101)]) > 0.0
    assert Joint  # (imported for the ptp below)
    ptp = MoveRequest("ptp", (Joint(q0[:1] + (q0[1] + 1.0,) + q0[2:]),), 0.5, 0.5, 0.0, 2)
    assert MovePlanner(SPEC.axes, SPEC.main_axes, "jerk", KIN, zones=(box,)).plan(ptp, q0, None, 0.005)[1] is None


@pytest.fixture
def cell(tmp_path):
    (tmp_path / "zoned.spc").write_text(SPEC_PATH.read_text(encoding="utf-8") + ZONES, encoding="utf-8")
    return tmp_path


def write(cell, name: str, body: str, handler: str = "") -> str:
    path = cell / f"{name}.irl"
    path.write_text(f"""program {name};
system_specification "zoned.spc";
seq
  move ptp pose(pos(900, 300, 500), rpy(180, 0, 90));
{body}
{handler}endseq
endprogram;
""", encoding="utf-8")
    return path


def test_a_target_in_a_zone_is_a_compile_time_error(cell):
    path = write(cell, "inside", "  move lin pose(pos(900, 300, 330), rpy(180, 0, 90));")
    code, _, err = run_cli("check", path)
    assert code == 1 and "inside.irl:5:12: error: the target is in zone 'fixture'" in err, err


def test_a_path_through_a_zone_is_found_by_irl_check_and_refused_by_irl_run(cell):
    # (the ptp move from the far side swings the flange over the box's top, 5 mm too close)
    body = ("  move ptp pose(pos(900, -300, 300), rpy(180, 0, 90));\n"
            "  move ptp pose(pos(900, 300, 345), rpy(180, 0, 90));")
    path = write(cell, "through", body)
    code, _, err = run_cli("check", path)
    assert code == 1 and "through.irl:6:3: error: the path enters zone 'fixture'" in err, err
    handled = write(cell, "handled", body, "when error do\n  print error_name(), \": \", error_message();\n")
    code, out, err = run_cli("run", handled, "--json")
    assert code == 0, err
    said = json.loads(out)["log"][-1]["text"]
    assert said.startswith("move: the path enters zone 'fixture'"), said
    assert json.loads(out)["moves"][-1]["line"] == 5  # (the refused move never started)


def test_the_safety_supervisor_stops_a_reference_that_enters_a_zone(cell):
    # a planner that knows of no zone stands in for what no plan covers: the 1 ms backstop
    from compiler.driver import compile_source

    source = write(cell, "backstop", "  depth := 300;\n"
                                     "  move lin pose(pos(900, 300, depth), rpy(180, 0, 90)) speed := 100;")
    text = source.read_text(encoding="utf-8").replace("seq\n", "var depth : real;\nseq\n", 1)
    result = compile_source(text, str(source), cell / "zoned.spc")
    assert result.ok, result.diagnostics
    system = RobotSystem(zoned(), RunOptions())
    system.begin(result.program, None)
    system.trajectory.planner.zones = ()  # (after begin, which gives the planner the cycle's zones)
    for _ in range(400_000):
        if system.supervisor.done:
            break
        system.executive.step()
    summary = system.finish()
    assert summary["stop"] is not None and summary["stop"]["category"] == 1, summary["stop"]
    assert "entered zone 'fixture'" in summary["fault"], summary["fault"]
    inside = float(summary["fault"].split("entered zone 'fixture' (")[1].split(" mm inside")[0])
    assert inside < 1.0, summary["fault"]  # (caught in the tick it entered: at 100 mm/s, 0.1 mm per ms)
    assert system.safety.at_rest


def test_a_signal_zone_switches_its_output_while_the_tool_is_inside(cell):
    (cell / "zoned.spc").write_text((cell / "zoned.spc").read_text(encoding="utf-8") + """
[[zone]]
name = "over the fixture"
shape = "box"
kind = "signal"
output = 6
min = [800, 200, 340]
max = [1000, 400, 700]
""", encoding="utf-8")
    path = cell / "signal.irl"
    path.write_text("""program signal;
system_specification "zoned.spc";
seq
  move ptp pose(pos(900, -300, 500), rpy(180, 0, 90));
  print out[6];
  move lin pose(pos(900, 300, 500), rpy(180, 0, 90)) speed := 200;   -- into it (the robot may enter)
  print out[6];
  move lin pose(pos(900, -300, 500), rpy(180, 0, 90)) speed := 200;
  print out[6];
endseq
endprogram;
""", encoding="utf-8")
    code, out, err = run_cli("run", path, "--json")
    assert code == 0, err
    assert [e["text"] for e in json.loads(out)["log"]] == ["false", "true", "false"]
    assert run_cli("check", path)[0] == 0  # (irl check's run switches it alike: no path into a forbidden zone)


@pytest.mark.parametrize("table, why", [
    ('name = "a"\nshape = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\nkind = "signal"', r"zone\[1\]\.output: missing"),
    ('name = "a"\nshape = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\nkind = "signal"\noutput = 17',
     r"zone\[1\]\.output: expected the digital output the zone switches, 1..16"),
    ('name = "a"\nshape = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\noutput = 3', r"zone\[1\]\.output: unknown key"),
    ('name = "a"\nshape = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\nkind = "warn"', r"zone\[1\]\.kind: expected"),
    ('name = "a"\nshape = "sphere"\nmin = [0, 0, 0]', r"zone\[1\]\.shape: expected \"box\" or \"cylinder\""),
    ('name = "a"\nshape = "box"\nmin = [0, 0, 0]\nmax = [10, 0, 10]', r"zone\[1\]\.max: expected the corner"),
    ('name = "a"\nshape = "box"\nmin = [0, 0, 0]', r"zone\[1\]\.max: missing"),
    ('name = "a"\nshape = "cylinder"\ncentre = [0, 0]\nradius = 0\nz = [0, 1]', r"zone\[1\]\.radius"),
    ('name = "a"\nshape = "cylinder"\ncentre = [0, 0]\nradius = 5\nz = [1, 0]', r"zone\[1\]\.z"),
    ('name = "a"\nshape = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\nheight = 3', r"zone\[1\]\.height: unknown key"),
    ('name = "a"\nshape = "box"\nmin = [0, 0, "x"]\nmax = [1, 1, 1]', r"zone\[1\]\.min"),
])
def test_a_wrong_zone_names_its_key(table, why):
    with pytest.raises(SpecError, match=why):
        zoned(f"\n[[zone]]\n{table}\n")
    with pytest.raises(SpecError, match="not another zone's"):
        zoned(ZONES + '\n[[zone]]\nname = "post"\nshape = "box"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n')


def test_the_specification_declares_them():
    spec = zoned()
    assert [(z.name, z.shape) for z in spec.zones] == [("fixture", "box"), ("post", "cylinder")]
    post = spec.zones[1]
    assert post.depth(300.0, 700.0, 100.0) == 80.0 and post.depth(300.0, 800.0, 100.0) == -20.0
    assert spec.hash != SPEC.hash


def test_a_home_position_in_a_zone_is_refused_before_anything_moves():
    # (every move from home would be refused: the robot could not leave it)
    spec = zoned(ZONES + '\n[[zone]]\nname = "lamp"\nshape = "cylinder"\ncentre = [1145, 0]\nradius = 30\n'
                         'z = [1300, 1500]\n')
    with pytest.raises(ValueError, match="the home position is in zone 'lamp'.*every move from there would be "
                                         "refused"):
        RobotSystem(spec, RunOptions())
    RobotSystem(zoned(), RunOptions())  # (the zones of the other tests leave home clear)


def test_a_robot_with_additional_axes_takes_no_zones_yet():
    # (a track or a positioner moves the tool in ways the zone checks do not count: refused, not ignored)
    text = SPEC_PATH.read_text(encoding="utf-8")
    a6 = text[text.rindex("[[axis]]"):].split("\n[", 1)[0]  # (the last axis's table, as a seventh: additional)
    track = a6.replace('name = "A6"', 'name = "track"\ngroup = "additional"')
    with pytest.raises(SpecError, match="world zones need a robot without additional axes"):
        zoned("\n" + track + ZONES)


def test_a_message_shows_no_negative_zero():
    """A coordinate that rounds to zero from below is shown as 0 (a planner's message said
    "(-0.0, 412.3, 300.0)")."""
    from compiler.zones import shown

    assert [shown(-0.04), shown(-0.06), shown(0.0), shown(-0.0, "g"), shown(-3.2, "g")] == \
        ["0.0", "-0.1", "0.0", "0", "-3.2"]


# ---- zones declared in a program ------------------------------------------------------------

PROGRAM_ZONES = """program own_zones;
system_specification "lola15.spc";
zone pillar := cylinder(pos(600, 0, 0), 60, 2000);
zone over_table := box(pos(300, -600, 0), pos(900, -200, 1500)) signal 6;
const
  left := pose(pos(600, -400, 600), rpy(180, 0, 180));
  right := pose(pos(600, 400, 600), rpy(180, 0, 180));
seq
  move ptp left;
  print "at left, out[6] is ", out[6];
  move lin right speed := 200;
  print "not here";
when error do
  print error_name(), ": ", error_message();
  halt;
endseq
endprogram;
"""


def test_a_program_s_own_zones_refuse_a_path_and_switch_an_output(tmp_path):
    """The pillar the program declares stands between left and right: the lin move is the
    program's move error at run time and irl check says so before; the signal zone's output
    is true at left."""
    import shutil

    from conftest import ROOT

    shutil.copy(ROOT / "programs" / "lola15.spc", tmp_path / "lola15.spc")
    source = tmp_path / "own_zones.irl"
    source.write_text(PROGRAM_ZONES, encoding="utf-8")
    code, out, err = run_cli("run", source, "--json")
    assert code == 0, err
    texts = [e["text"] for e in json.loads(out)["log"]]
    assert texts[0] == "at left, out[6] is true"
    assert texts[-1].startswith("move: the path enters zone 'pillar' (cylinder at (600, 0), radius 60 mm"), texts
    code, out, err = run_cli("check", source)
    said = out + err
    assert code == 0 and "the path enters zone 'pillar'" in said and "handler at line 14 takes it" in said, said


def test_a_cycle_s_zones_are_the_specification_s_and_the_loaded_program_s(cell):
    """begin gives the planner, the safety supervisor and the signal zones the program's
    zones beside the specification's; the next program without any has the specification's
    alone again."""
    from compiler.driver import compile_source

    spec = zoned()
    with_zones = compile_source(PROGRAM_ZONES, str(cell / "own.irl"), cell / "zoned.spc")
    plain = compile_source("program plain;\nseq\n  wait 0.1 sec;\nendseq\nendprogram;\n", str(cell / "plain.irl"),
                           cell / "zoned.spc")
    assert with_zones.ok and plain.ok, (with_zones.diagnostics, plain.diagnostics)
    system = RobotSystem(spec, RunOptions())
    names = lambda zones: [z.name for z in zones]  # noqa: E731
    assert names(system.trajectory.planner.zones) == ["fixture", "post"]
    system.begin(with_zones.program, None)
    assert names(system.trajectory.planner.zones) == ["fixture", "post", "pillar"]
    assert names(system.safety.zones.zones) == ["fixture", "post", "pillar"]
    assert names(system.io.zone_signals.zones) == ["over_table"]
    system.begin(plain.program, None)
    assert names(system.trajectory.planner.zones) == names(system.safety.zones.zones) == ["fixture", "post"]
    assert system.io.zone_signals is None


@pytest.mark.parametrize("zone, words", [
    (Zone("lamp", "box", (0.0, 0.0, 0.0), (10.0, 10.0, 10.0), kind="signal", output=99),
     "zone 'lamp' switches output 99: the robot has outputs 1..16"),
    (Zone("fixture", "box", (0.0, 0.0, 0.0), (10.0, 10.0, 10.0)), "two zones are called 'fixture'"),
    (Zone("everything", "box", (-5000.0, -5000.0, -5000.0), (5000.0, 5000.0, 5000.0)),
     "the home position is in zone 'everything'"),
])
def test_object_code_whose_zones_do_not_fit_the_robot_does_not_start(cell, zone, words):
    """Object code is untrusted: a zone table the compiler would not have written for this
    robot (an output it lacks, a name its specification uses, a zone over home) is refused
    when the program is to start, with the reason."""
    import dataclasses

    from compiler.driver import compile_source

    spec = zoned()
    result = compile_source("program p;\nseq\n  wait 0.1 sec;\nendseq\nendprogram;\n", str(cell / "p.irl"),
                            cell / "zoned.spc")
    system = RobotSystem(spec, RunOptions())
    with pytest.raises(ValueError, match="the program cannot start: ") as error:
        system.begin(dataclasses.replace(result.program, zones=(zone,)), None)
    assert words in str(error.value), str(error.value)


@pytest.mark.parametrize("entry, words", [
    (["z", "box", "forbidden", 0, {"min": [0, 0, 0], "max": [0, 10, 10]}], "each more than min's"),
    (["z", "sphere", "forbidden", 0, {}], "expected [name"),
    (["z", "box", "signal", 0, {"min": [0, 0, 0], "max": [1, 1, 1]}], "expected [name"),
    (["z", "cylinder", "forbidden", 0, {"centre": [0, 0], "radius": float("nan"), "z": [0, 1]}], "radius"),
])
def test_a_malformed_zone_table_is_refused_when_the_object_code_is_read(tmp_path, entry, words):
    import msgpack
    import zlib

    from compiler.objcode import _HEADER, ObjectCodeError, decode, encode

    program = compile_source_ok(tmp_path)
    data = encode(program)
    body = msgpack.unpackb(data[_HEADER.size:], raw=False)
    body["zones"] = [entry]
    packed = msgpack.packb(body, use_bin_type=True)
    with pytest.raises(ObjectCodeError, match=None) as error:
        decode(_HEADER.pack(b"IRLO", 1, zlib.crc32(packed)) + packed)
    assert words in str(error.value), str(error.value)


def compile_source_ok(tmp_path):
    from compiler.driver import compile_source

    result = compile_source(PROGRAM_ZONES.replace('"lola15.spc"', f'"{SPEC_PATH}"'), str(tmp_path / "own.irl"))
    assert result.ok, result.diagnostics
    assert [z.name for z in result.program.zones] == ["pillar", "over_table"]
    return result.program


def test_irl_check_says_at_the_zone_that_a_program_whose_zone_holds_home_cannot_start(tmp_path):
    """A zone of the program over the home position: the runtime would refuse the program
    (every move from home would be refused); irl check says so at the zone's declaration,
    once, and checks no move."""
    import shutil

    from conftest import ROOT

    shutil.copy(ROOT / "programs" / "lola15.spc", tmp_path / "lola15.spc")
    source = tmp_path / "over_home.irl"
    source.write_text('program over_home;\nsystem_specification "lola15.spc";\nvar n : integer;\n'
                      "  zone overhome := box(pos(1100, -50, 1350), pos(1200, 50, 1450));\n"
                      "seq\n  move ptp joint(mainjoint(10, 0, 0, 0, 0, 0));\nendseq\nendprogram;\n", encoding="utf-8")
    code, out, err = run_cli("check", source)
    assert code == 1
    assert f"{source}:4:3: error: the program cannot start: the home position is in zone 'overhome'" in err, err
    assert err.count("error:") == 1 and "motion: 0 moves, no cycle time: the program cannot start" in out, out
