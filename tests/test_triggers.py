"""Path triggers (issue 17, item 5): an output switched, or a global set, at a distance (mm
of the tool's path) or a time (ms) after a move's start or before its end, or a time after
its end; within one servo tick (1 ms) of the moment the servo's reference is there, across
random moves, blends and overrides."""
from __future__ import annotations

import dataclasses
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from compiler.driver import compile_source
from compiler.objcode import OP, ObjectCodeError, verify

from test_vm import FakeHost, compile_text, program_text, run

from conftest import ROOT, SPEC, examples
TICK = 0.001
DOWN = "rpy(180, 30, 180)"


def run_recorded(tmp_path: Path, body: str, decls: str = "", override: float = 100.0):
    """The program on the simulated robot; every 1 ms tick: (time, the servo's reference,
    the digital outputs)."""
    from runtime.loop.system import RobotSystem, RunOptions

    (tmp_path / "lola15.spc").write_text((ROOT / "programs" / "lola15.spc").read_text())
    result = compile_source(program_text(body, decls), str(tmp_path / "p.irl"))
    assert result.ok, result.diagnostics
    system = RobotSystem(SPEC, RunOptions(state_dir=tempfile.mkdtemp(dir=tmp_path), override=override))
    ticks: list = []
    system.executive.add("record-triggers", lambda now: ticks.append(
        (now, tuple(system.servo.reference), tuple(system.io.outputs.value or ()))), TICK, "record")
    summary = system.run(result.program)
    return summary, ticks, system


def switched(ticks, n: int) -> list[float]:
    """When output ``n`` changed (the tick it was first seen changed)."""
    out, last = [], False
    for now, _ref, outputs in ticks:
        value = bool(outputs[n - 1]) if outputs else False
        if value != last:
            out.append(now)
            last = value
    return out


def pose_text(p) -> str:
    return "pose(pos({!r}, {!r}, {!r}), rpy({!r}, {!r}, {!r}))".format(*p)


@pytest.mark.long
@settings(max_examples=examples(6), deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(start=st.tuples(st.floats(600, 750), st.floats(-150, 150), st.floats(350, 600)),
       travel=st.tuples(st.floats(100, 300), st.floats(-60, 60), st.floats(-80, 80)),
       after=st.floats(0, 1), before=st.floats(0, 1), ms=st.floats(0, 1), speed=st.floats(100, 600),
       override=st.sampled_from([100.0, 70.0, 35.0]))
def test_distance_triggers_fire_within_a_servo_tick_of_the_place(tmp_path_factory, start, travel, after, before,
                                                                 ms, speed, override):
    """The place is found from what the servo did (its reference, through the forward
    kinematics, projected on the line), independently of the planner: the output changes
    in the tick the reference passes it, or the next."""
    from compiler.frames import pose_of
    from runtime.motion.kinematics import Kinematics, KinematicsError

    kin = Kinematics(SPEC)
    p0 = (*start, 180.0, 30.0, 180.0)
    p1 = (start[0] + travel[0], start[1] + travel[1], start[2] + travel[2], 180.0, 30.0, 180.0)
    try:
        for p in (p0, p1):
            kin.inverse(pose_of(p), near=(0.0, -30.0, 30.0, 0.0, 60.0, 0.0))
    except KinematicsError:
        event("out of reach")
        return
    length = float(np.linalg.norm(np.array(p1[:3]) - np.array(p0[:3])))
    d_after, d_before = (math.floor(x * length * 10) / 10 for x in (after, before))  # (0.1 mm, within the path)
    body = (f"  move ptp {pose_text(p0)};\n"
            f"  trigger when {d_after!r} mm after start do out[1] := true;\n"
            f"  trigger when {d_before!r} mm before end do out[2] := true;\n"
            f"  move lin {pose_text(p1)} speed := {speed:.1f};\n")
    tmp_path = tmp_path_factory.mktemp("trig")
    summary, ticks, system = run_recorded(tmp_path, body, override=override)
    if summary["fault"] is not None:
        assert "refused" in summary["fault"], summary["fault"]
        event("lin refused")
        return
    a, b = np.array(p0[:3]), np.array(p1[:3])
    u = (b - a) / length
    # the move's time 0 was at t_start on the timeline; the servo's reference, a setpoint
    # period behind, leaves the start from then on
    begun = system.trajectory.moves[1].t_start + system.trajectory.period
    along = [(round(now, 3), float(np.dot(np.array(kin.forward(ref[:6])[:3]) - a, u))) for now, ref, _o in ticks
             if now >= begun - 1e-9]
    where = dict(along)
    for n, goal in ((1, d_after), (2, length - d_before)):
        fired = switched(ticks, n)
        assert len(fired) == 1, (n, fired)
        # the tick before it fired, the reference had not passed the place; the tick after,
        # it had reached it (to 1 um: near a rest the path creeps, and time says nothing)
        tick = round(fired[0] / TICK)
        before, after_ = where.get(round((tick - 1) * TICK, 3), 0.0), where[round((tick + 1) * TICK, 3)]
        assert before <= goal + 1e-3 and after_ >= goal - 1e-3, (n, goal, before, after_)
    event(f"fired at {override:g} %")


@pytest.mark.long
@settings(max_examples=examples(5), deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(approx=st.sampled_from([0.0, 20.0, 60.0]), t_before=st.integers(0, 400), t_after=st.integers(0, 300),
       t_end=st.integers(0, 300), override=st.sampled_from([100.0, 60.0]))
def test_time_triggers_on_blended_moves_fire_within_a_servo_tick(tmp_path_factory, approx, t_before, t_after, t_end,
                                                                 override):
    """A time is a place on the move's own timeline: the output changes within a tick of
    the moment the servo's reference (one setpoint period behind the timeline) is there,
    with the move blended into the next (approx) or not; 'after end' too."""
    body = (f"  move ptp {pose_text((650.0, 0.0, 400.0, 180.0, 30.0, 180.0))};\n"
            f"  trigger when {t_after} ms after start do out[1] := true;\n"
            f"  trigger when {t_before} ms before end do out[2] := true;\n"
            f"  trigger when {t_end} ms after end do out[3] := true;\n"
            f"  move lin {pose_text((950.0, 0.0, 400.0, 180.0, 30.0, 180.0))} speed := 400 approx := {approx};\n"
            f"  move lin {pose_text((950.0, 0.0, 550.0, 180.0, 30.0, 180.0))} speed := 400;\n")
    tmp_path = tmp_path_factory.mktemp("trig")
    summary, ticks, system = run_recorded(tmp_path, body, override=override)
    assert summary["fault"] is None, summary["fault"]
    record = system.trajectory.moves[1]
    rate = override / 100.0
    duration = record.planned_duration * rate  # (its own time, at 100 %)
    period = system.trajectory.period
    # the timeline's time 0 of the move was at record.t_start; the reference is there a period later
    for n, at in ((1, t_after / 1000.0), (2, duration - t_before / 1000.0), (3, duration + t_end / 1000.0)):
        expected = record.t_start + max(min(at, duration) if n < 3 else at, 0.0) / rate + period
        fired = switched(ticks, n)
        assert len(fired) == 1, (n, fired)
        assert abs(fired[0] - expected) <= TICK + 1e-6, (n, fired[0], expected)
    assert record.blended == (approx > 0.0)
    event("blended" if record.blended else "stopped at the corner")


def test_a_trigger_set_is_seen_by_wait_for_and_look_ahead_goes_on(tmp_path):
    body = (f"  move ptp {pose_text((650.0, 0.0, 400.0, 180.0, 30.0, 180.0))};\n"
            "  trigger when 15 mm before end do out[3] := true;\n"
            "  trigger when 0 ms before end do laid := true;\n"
            f"  move lin {pose_text((950.0, 0.0, 400.0, 180.0, 30.0, 180.0))} speed := 200 approx := 10;\n"
            f"  move lin {pose_text((950.0, 0.0, 550.0, 180.0, 30.0, 180.0))} speed := 200;\n"
            "  wait for laid;\n  print \"laid\";\n")
    summary, ticks, system = run_recorded(tmp_path, body, "var\n  laid : bool;\n")
    assert summary["fault"] is None, summary["fault"]
    assert [m["blended"] for m in summary["moves"]] == [False, True, False]  # the trigger did not stop look-ahead
    assert [entry["text"] for entry in summary["log"]] == ["laid"]
    assert len(switched(ticks, 3)) == 1


def test_a_distance_beyond_the_path_stops_the_program_at_the_move(tmp_path):
    body = (f"  move ptp {pose_text((650.0, 0.0, 400.0, 180.0, 30.0, 180.0))};\n"
            "  trigger when 500 mm before end do out[3] := true;\n"
            f"  move lin {pose_text((950.0, 0.0, 400.0, 180.0, 30.0, 180.0))};\n")
    summary, _ticks, _system = run_recorded(tmp_path, body)
    assert "trigger when 500 mm before end: the tool's path of this move is only 300 mm long" in summary["fault"]
    assert "line 7" in summary["fault"]  # (the move's)


def test_a_stopped_moves_triggers_go_with_the_rest_of_it(tmp_path):
    """A pause in the middle of a bead: the glue goes off 15 mm before the end of the rest,
    the same place; the one counted from the start, not reached yet, keeps its place too."""
    from runtime.motion.kinematics import Kinematics

    body = (f"  move ptp {pose_text((650.0, 0.0, 400.0, 180.0, 30.0, 180.0))};\n"
            "  trigger when 200 mm after start do out[1] := true;\n"
            "  trigger when 15 mm before end do out[2] := true;\n"
            f"  move lin {pose_text((950.0, 0.0, 400.0, 180.0, 30.0, 180.0))} speed := 150;\n")
    from runtime.loop.system import RobotSystem, RunOptions

    (tmp_path / "lola15.spc").write_text((ROOT / "programs" / "lola15.spc").read_text())
    result = compile_source(program_text(body), str(tmp_path / "p.irl"))
    system = RobotSystem(SPEC, RunOptions(state_dir=tempfile.mkdtemp(dir=tmp_path)))
    ticks: list = []
    paused = []

    def record(now):
        ticks.append((now, tuple(system.servo.reference), tuple(system.io.outputs.value or ())))
        moves = system.trajectory.moves
        if len(moves) == 2 and not paused and now > moves[1].t_start + 0.6:
            paused.append(now)
            system.trajectory.pause()
        elif paused and len(paused) == 1 and now > paused[0] + 1.0:
            paused.append(now)
            system.trajectory.resume()
    system.executive.add("record-triggers", record, TICK, "record")
    summary = system.run(result.program)
    assert summary["fault"] is None, summary["fault"]
    kin = Kinematics(SPEC)
    begun = system.trajectory.moves[1].t_start
    x = [(now, kin.forward(ref[:6])[0] - 650.0) for now, ref, _o in ticks if now >= begun]
    for n, goal in ((1, 200.0), (2, 285.0)):
        crossing = next(now for now, s in x if s >= goal - 1e-6)
        fired = switched(ticks, n)
        assert len(fired) == 1 and abs(fired[0] - crossing) <= TICK + 1e-9, (n, fired, crossing)


def test_the_vm_hands_triggers_to_the_next_move_and_hand_made_code_is_checked(tmp_path):
    text = program_text(f"  trigger when 5 mm after start do out[2] := true;\n"
                        f"  trigger when 7 ms before end do n := 3;\n  move lin {pose_text((650.0, 0, 400, 180, 30, 180))};\n",
                        "var\n  n : integer;\n")
    program = compile_text(tmp_path, text)
    machine, host = run(program)
    assert machine.status.name == "DONE"
    assert host.triggers == [(0, 1, 5.0, ("out", 2, True)), (1, 0, 7.0, ("set", 0, 3))]
    k = next(i for i, c in enumerate(program.code) if c[0] == OP.TRIGGER_OUT)
    code = list(program.code)
    code[k] = (OP.TRIGGER_OUT, 9, 1)
    with pytest.raises(ObjectCodeError, match="out of range"):
        verify(dataclasses.replace(program, code=tuple(code)))


@pytest.mark.parametrize("amount, action, message", [
    (-1.0, ("out", 1, True), "expected 0 <= amount <= 100000 mm"),
    (float("nan"), ("out", 1, True), "expected 0 <= amount"),
    (5.0, ("out", 99, True), "digital output 99 does not exist"),
    (5.0, ("out", 1, 3), "must be true or false"),
    ("5", ("out", 1, True), "must be a number"),
])
def test_the_trajectory_generator_checks_every_trigger_it_is_handed(tmp_path, amount, action, message):
    from runtime.loop.system import RobotSystem, RunOptions

    system = RobotSystem(SPEC, RunOptions(state_dir=tmp_path / "s"))
    problem = system.trajectory.trigger(0, 1, amount, action)
    assert problem is not None and message in problem, problem
    assert FakeHost  # (the VM's side: test_vm's fake host records triggers)
