"""Frames and tools (issue 17, item 1): ``frame`` and ``tool`` values, ``use base`` and
``use tool``, the specification's ``[[frame]]`` and ``[[tool]]`` tables; pose targets in
the active base, reached by the active tool's centre point; the report and telemetry name
both and give the TCP in the world frame and in the base."""
from __future__ import annotations

import csv
import math
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from compiler.driver import compile_source
from compiler.frames import FRAME_KINDS, pose_of, values_of
from compiler.geometry import rotation_to_rpy
from compiler.semantics import compose, inverse
from compiler.spec import SpecError, load_spec, parse_spec
from compiler.values import Pose, Position, Rpy

from conftest import ROOT, PROGRAMS, SPEC_PATH as LOLA
CELL = PROGRAMS / "lola15_cell.spc"
SPEC = load_spec(LOLA)


def compile_program(tmp_path: Path, body: str, decls: str = "", spec: Path = LOLA):
    shutil.copy(spec, tmp_path / spec.name)
    text = f'program p;\nsystem_specification "{spec.name}";\n{decls}\nseq\n{body}\nendseq\nendprogram;\n'
    return compile_source(text, str(tmp_path / "p.irl"))


def errors(tmp_path: Path, body: str, decls: str = "", spec: Path = LOLA) -> list[str]:
    result = compile_program(tmp_path, body, decls, spec)
    return [d.message + (f" [hint: {d.hint}]" if d.hint else "") for d in result.diagnostics]


def matrix(values) -> np.ndarray:
    """4x4 of x, y, z, roll, pitch, yaw (the kinematics' convention: Rz(yaw) Ry(pitch) Rx(roll))."""
    x, y, z, r, p, w = values
    r, p, w = map(math.radians, (r, p, w))
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(w), -math.sin(w), 0], [math.sin(w), math.cos(w), 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx
    m[:3, 3] = (x, y, z)
    return m


# ---- the specification's tables ------------------------------------------------------------

def test_the_cell_specification_is_lola15_plus_its_frames_and_tools():
    """lola15_cell.spc must not drift from the arm it describes (it adds the cell's frames,
    tools, analog sensors and outputs, and world zones)."""
    cell = tomllib.loads(CELL.read_text())
    named = {kind.table: cell.pop(kind.table) for kind in FRAME_KINDS}
    assert [t["name"] for t in cell.pop("analog_input")] == ["part height"]
    assert [t["name"] for t in cell.pop("zone")] == ["fixture body", "guard post"]
    assert [t["name"] for t in cell.pop("analog_output")] == ["glue pressure"]
    assert cell == tomllib.loads(LOLA.read_text())
    assert [t["name"] for t in named["frame"]] == ["pallet_station", "glue_table"]
    assert [t["name"] for t in named["tool"]] == ["gripper", "glue_gun"]
    spec = load_spec(CELL)
    assert ("tool", "glue_gun", (60.0, 0.0, 150.0, 0.0, 20.0, 0.0)) in spec.named_frames


@pytest.mark.parametrize("table, message", [
    ('[[tool]]\nname = "world"\n', "tool[1].name: 'world' is predeclared"),
    ('[[frame]]\nname = "default_tool"\n', "frame[1].name: 'default_tool' is predeclared"),
    ('[[tool]]\nname = "a b"\n', "tool[1].name: expected the tool's name, a name a program can use"),
    ('[[tool]]\nname = "Seq"\n', "tool[1].name: 'seq' is a reserved word"),
    ('[[tool]]\nname = "g"\n[[frame]]\nname = "G"\n', "tool[1].name: 'g' already names a frame"),
    ('[[tool]]\nname = "g"\nz = 6000.0\n', "tool[1]: the tool's origin is 6000 mm from the origin of the flange "
                                             "frame: expected at most 5000 mm"),
    ('[[frame]]\nname = "f"\nx = nan\n', "frame[1].x: expected a number (mm), got nan"),
    ('[[tool]]\nname = "g"\nyaw = inf\n', "tool[1].yaw: expected a number (deg), got inf"),
    ('[[tool]]\nname = "g"\nlength = 3\n', "tool[1].length: unknown key"),
    ('tool = 3\n[robot]\nname = "r"\n', "tool: expected an array of tables ([[tool]])"),
])
def test_the_specifications_tables_are_checked(table, message):
    text = LOLA.read_text()
    if table.startswith("tool = 3"):  # a top-level key must come before the first table
        text = table.replace('[robot]\nname = "r"\n', "") + text
    else:
        text += "\n" + table
    with pytest.raises(SpecError) as info:
        parse_spec(text, "x.spc")
    assert message in str(info.value), str(info.value)


# ---- the compiler ------------------------------------------------------------------------

def test_frames_and_tools_are_poses_with_a_role(tmp_path):
    decls = ("const\n  f := frame(pos(600, 0, 300), rpy(0, 0, 30));\n  t := tool(pos(0, 0, 150), rpy(0, 0, 0));\n"
             "var\n  g : frame;\n  u : tool;\n  p : pose;\n  b : bool;\n")
    body = ("  g := pose(pos(1, 2, 3), rpy(0, 0, 0));\n  u := t + pos(0, 0, 10);\n  p := f * g;\n  p := t;\n"
            "  b := f = p;\n  use base f * g;\n  use tool u;\n  use base p;\n  use tool world;\n  g := t;\n"
            "  use base t;\n")
    assert errors(tmp_path, body, decls) == [
        "'use tool' needs a tool (or a pose), not a frame [hint: a frame is made active with 'use base']",
        "cannot assign a tool to 'g', which is a frame",
        "'use base' needs a frame (or a pose), not a tool [hint: a tool is made active with 'use tool']",
    ]


@pytest.mark.parametrize("body, decls, message", [
    ("  use frame world;\n", "", "'use frame': expected 'use base FRAME;' or 'use tool TOOL;'"),
    ("  use tool 5;\n", "", "'use tool' needs a tool (or a pose), not an integer"),
    ("  use tool tool(pos(0, 0, 9000), rpy(0, 0, 0));\n", "",
     "use tool: the tool's origin is 9000 mm from the origin of the flange frame: expected at most 5000 mm"),
    ("", "var\n  world : integer;\n", "'world' is predeclared by the language: a frame"),
    ("", "const\n  gripper := 1;\n", "'gripper' is predeclared by the system specification (lola15_cell.spc): a tool"),
    ("", "function f(x : integer) : integer;\nseq\n  use tool default_tool;\n  return x;\nendseq\nendfunction;\n",
     "a function computes a value: 'use' is not allowed in function 'f'"),
    ("", "procedure q(default_tool : real);\nseq\nendseq\nendprocedure;\n",
     "'default_tool' is predeclared by the language: a tool"),
])
def test_frame_errors(tmp_path, body, decls, message):
    found = errors(tmp_path, body, decls, spec=CELL)
    assert any(message in e for e in found), found


def test_the_reach_of_constant_targets_is_checked_in_the_frames_the_compiler_knows(tmp_path):
    far = "pose(pos(1000, 0, 500), rpy(180, 30, 180))"  # reachable from the world frame ...
    decls = "const\n  shifted := frame(pos(900, 0, 0), rpy(0, 0, 0));\n"
    known = errors(tmp_path, f"  move ptp {far};\n  use base shifted;\n  move ptp {far};\n", decls)
    assert len(known) == 1 and known[0].startswith("pose out of reach (in base 'shifted'): its position is"), known
    # ... unknown after a loop or an if that may change the base, or inside a procedure: checked when it runs
    assert errors(tmp_path, f"  while in[1] do\n    use base shifted;\n  endwhile;\n  move ptp {far};\n", decls) == []
    assert errors(tmp_path, "  call p;\n", decls + f"procedure p;\nseq\n  move ptp {far};\nendseq\nendprocedure;\n"
                  "procedure q;\nseq\n  use base shifted;\nendseq\nendprocedure;\n") == []
    # a longer tool reaches further
    reach = SPEC.arm_reach()
    a1, d1 = SPEC.main_axes[0].dh.a, SPEC.main_axes[0].dh.d
    edge = f"pose(pos({a1 + reach + 150:.0f}, 0, {d1:.0f}), rpy(0, 90, 0))"  # 150 mm beyond the reach
    assert errors(tmp_path, f"  move ptp {edge};\n")
    assert errors(tmp_path, f"  use tool tool(pos(0, 0, 300), rpy(0, 0, 0));\n  move ptp {edge};\n") == []


def test_the_name_of_an_active_frame_is_its_expressions_text(tmp_path):
    from compiler.disasm import instructions

    result = compile_program(tmp_path, "  use base pallet_station * frame(pos(25, -10, 0), rpy(0, 0, 3));\n"
                                       "  use tool gripper;\n", spec=CELL)
    assert result.ok, result.diagnostics
    uses = [(r.name, r.argrepr) for r in instructions(result.program) if r.name.startswith("USE_")]
    assert uses == [("USE_BASE", '"pallet_station * frame(pos(25, -10, 0..."'),  # (40 characters at most)
                    ("USE_TOOL", '"gripper"')]


# ---- the runtime ---------------------------------------------------------------------------

def run_program(tmp_path: Path, body: str, decls: str = "", spec: Path = LOLA, report: bool = False):
    from runtime.loop.system import RobotSystem, RunOptions

    result = compile_program(tmp_path, body, decls, spec)
    assert result.ok, result.diagnostics
    options = RunOptions(state_dir=tmp_path / "state", report=str(tmp_path / "r.csv") if report else None)
    system = RobotSystem(load_spec(spec), options)
    if report:
        system.report.columns = [*system.report.columns, "frame"]
    return system.run(result.program)


def reachable(world: tuple, tool: tuple) -> bool:
    from runtime.motion.kinematics import Kinematics, KinematicsError

    try:
        Kinematics(SPEC).with_tool(tool).inverse(pose_of(world), near=(0.0, -30.0, 30.0, 0.0, 60.0, 0.0))
    except KinematicsError:
        return False
    return True


coord = st.floats(-250, 250, allow_nan=False)
angle = st.floats(-25, 25, allow_nan=False)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(base=st.tuples(coord, coord, st.floats(-100, 100), angle, angle, st.floats(-180, 180)),
       tool=st.tuples(st.floats(-60, 60), st.floats(-60, 60), st.floats(0, 250), angle, angle, st.floats(-90, 90)),
       world=st.tuples(st.floats(600, 1000), st.floats(-300, 300), st.floats(300, 800), st.floats(160, 200),
                       st.floats(10, 40), st.floats(160, 200)),
       linear=st.booleans())
def test_a_target_in_a_shifted_base_reaches_the_hand_computed_world_pose(tmp_path_factory, base, tool, world, linear):
    """The target is written in the base (inv(base) * world, computed here with NumPy); the
    tool's centre point ends at ``world`` (measured: the final joints through the forward
    kinematics with that tool) within the servo's accuracy."""
    from runtime.motion.kinematics import Kinematics

    assume(reachable(world, tool))
    local = (np.linalg.inv(matrix(base)) @ matrix(world)).tolist()  # (plain floats: their repr is L-IRL)
    tmp_path = tmp_path_factory.mktemp("frames")
    b, t = (f"pose(pos({v[0]!r}, {v[1]!r}, {v[2]!r}), rpy({v[3]!r}, {v[4]!r}, {v[5]!r}))" for v in (base, tool))
    r = rotation_to_rpy(*local[0][:3], *local[1][:3], *local[2][:3])
    target = f"pose(pos({local[0][3]!r}, {local[1][3]!r}, {local[2][3]!r}), rpy({r[0]!r}, {r[1]!r}, {r[2]!r}))"
    body = (f"  use base {b};\n  use tool {t};\n  move ptp {target};\n"
            + (f"  move lin {target} + pos(0, 0, 30) speed := 500;\n  move lin {target} speed := 500;\n"
               if linear else ""))
    summary = run_program(tmp_path, body)
    if summary["fault"] is not None:  # a lin move may pass a singularity or a limit: refused, at rest
        assert linear and "refused" in summary["fault"], summary["fault"]
        event("a lin move refused")
        return
    event("lin" if linear else "ptp")
    reached = Kinematics(SPEC).with_tool(tool).forward(summary["final_position"][:6])
    assert np.abs(np.array(reached[:3]) - np.array(world[:3])).max() < 0.05, (reached, world)
    assert np.abs(matrix(reached)[:3, :3] - matrix(world)[:3, :3]).max() < 1e-3


def test_a_lin_move_with_another_tool_keeps_that_tools_centre_point_on_the_line():
    """The path is the active tool's: every setpoint's TCP (that tool) is on the segment;
    the flange is not (the tool turns about its own point)."""
    from runtime.motion.kinematics import Kinematics
    from runtime.motion.moves import Frames, MovePlanner, MoveRequest

    kin = Kinematics(SPEC)
    tool = (60.0, 0.0, 150.0, 0.0, 20.0, 0.0)
    frames = Frames("world", (0.0,) * 6, "glue_gun", tool)
    planner = MovePlanner(SPEC.axes, SPEC.main_axes, "jerk", kin)
    arm = kin.with_tool(tool)
    start_pose = (800.0, -200.0, 400.0, 180.0, 30.0, 180.0)
    start = arm.inverse(pose_of(start_pose), near=(0.0, -30.0, 30.0, 0.0, 60.0, 0.0))
    end_pose = (800.0, 200.0, 500.0, 150.0, 20.0, 200.0)
    request = MoveRequest("lin", (pose_of(end_pose),), 400.0, 2000.0, 0.0, 1, frames=frames)
    segment, problem = planner.plan(request, tuple(start), None, 0.001)
    assert problem is None, problem
    a, b = np.array(start_pose[:3]), np.array(end_pose[:3])
    worst = flange_off = 0.0
    for k in range(101):
        q = segment.trajectory.position_at(segment.duration * k / 100)
        p = np.array(arm.forward(q)[:3])
        s = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0, 1)
        worst = max(worst, float(np.linalg.norm(p - (a + s * (b - a)))))
        f = np.array(kin.forward(q)[:3])
        sf = np.clip(np.dot(f - a, b - a) / np.dot(b - a, b - a), 0, 1)
        flange_off = max(flange_off, float(np.linalg.norm(f - (a + sf * (b - a)))))
    assert worst < 0.01, worst
    assert flange_off > 10.0  # (the default tool's point is somewhere else: the test would see a wrong tool)
    assert np.abs(np.array(arm.forward(segment.trajectory.position_at(segment.duration))[:3]) - b).max() < 1e-6


def test_the_report_names_the_tool_and_base_and_gives_the_tcp_in_both(tmp_path):
    summary = run_program(tmp_path, (
        "  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0));\n"
        "  use base pallet_station;\n  use tool gripper;\n"
        "  move ptp pose(pos(100, 100, 150), rpy(180, 30, 180));\n"
        "  move lin pose(pos(100, 100, 20), rpy(180, 30, 180)) speed := 200;\n"
        "  wait 0.2 sec;\n"), spec=CELL, report=True)
    assert summary["fault"] is None, summary["fault"]
    rows = list(csv.DictReader(open(tmp_path / "r.csv")))
    first, last = rows[0], rows[-1]
    assert (first["tool"], first["base"]) == ("default_tool", "world")
    assert (last["tool"], last["base"]) == ("gripper", "pallet_station")
    base = [float(last[f"base_{f}"]) for f in ("x", "y", "z")]
    assert np.abs(np.array(base) - (100, 100, 20)).max() < 0.05, base
    world = np.array([float(last[f"tcp_{f}"]) for f in ("x", "y", "z", "roll", "pitch", "yaw")])
    want = matrix((650.0, -180.0, 250.0, 0.0, 0.0, 10.0)) @ matrix((100, 100, 20, 180, 30, 180))
    assert np.abs(world[:3] - want[:3, 3]).max() < 0.05


def test_hand_made_object_code_cannot_make_a_non_pose_or_a_non_finite_frame_active(tmp_path):
    """The trajectory generator checks every value ``USE_*`` hands it (object code is
    untrusted): an error at the line, the robot at rest, nothing planned with it."""
    from runtime.motion.moves import Frames
    from runtime.loop.system import RobotSystem, RunOptions

    system = RobotSystem(SPEC, RunOptions(state_dir=tmp_path / "s"))
    host = system.trajectory
    assert host.use_frame("tool", "t", 5).startswith("use tool: expected a pose, not ")
    nan = Pose(Position(math.nan, 0.0, 0.0), Rpy(0.0, 0.0, 0.0))
    assert host.use_frame("base", "b", nan) == "use base: x = nan is not a finite number"
    far = Pose(Position(0.0, 0.0, 1e6), Rpy(0.0, 0.0, 0.0))
    assert "expected at most 5000 mm" in host.use_frame("tool", "t", far)
    assert host.frames == Frames.default(SPEC)
    assert host.use_frame("tool", "x" * 500, pose_of((0.0, 0.0, 10.0, 0.0, 0.0, 0.0))) is None
    assert len(host.frames.tool_name) == 40


def test_telemetry_samples_carry_the_tool_base_and_tcp(tmp_path):
    from runtime.loop.robotloop import RobotLoop
    from runtime.loop.system import RunOptions
    from runtime.motion.moves import Frames
    from runtime.wire.messages import Snapshot

    loop = RobotLoop(load_spec(CELL), RunOptions(state_dir=tmp_path / "s"), lambda *_: True)
    frames = Frames("pallet_station", (650.0, -180.0, 250.0, 0.0, 0.0, 10.0), "gripper", (0.0, 0.0, 180.0, 0.0, 0.0, 0.0))
    q = [10.0, -20.0, 30.0, 5.0, 40.0, -15.0]
    loop.system.trajectory.frames_now = lambda: frames
    loop.system.robot.positions = q
    snap = Snapshot.from_wire(loop.snapshot().to_wire())  # (as the server has it)
    assert (snap.tool, snap.base) == ("gripper", "pallet_station")
    from runtime.motion.kinematics import Kinematics

    arm = Kinematics(load_spec(CELL)).with_tool((0.0, 0.0, 180.0, 0.0, 0.0, 0.0))
    assert snap.tcp == list(arm.forward(q))
    in_base = values_of(compose(inverse(pose_of(frames.base)), pose_of(tuple(snap.tcp))))
    assert np.allclose(snap.tcp_base, in_base)


def test_the_example_runs_and_its_report_plots(tmp_path, monkeypatch):
    from runtime.cli.main import main

    monkeypatch.chdir(ROOT)
    report = tmp_path / "tool_change.csv"
    assert main(["run", "programs/tool_change.irl", "--report", str(report), "--report-columns", "+frame,move",
                 "--state-dir", str(tmp_path / "state")]) == 0
    rows = list(csv.DictReader(open(report)))
    assert {r["tool"] for r in rows} == {"default_tool", "gripper", "glue_gun"}
    glue = [r for r in rows if r["tool"] == "glue_gun" and r["base"] == "glue_table" and int(r["line"]) == 50]
    assert glue and all(abs(float(r["base_z"]) - 5.0) < 0.05 for r in glue)  # the bead, on the table
    assert main(["plot", str(report), "-o", str(tmp_path / "tool_change.png")]) == 0
    assert (tmp_path / "tool_change.png").stat().st_size > 10_000
