"""Operating modes (T1, AUT) and jogging: docs/safety.md, "Operating modes"; docs/protocol.md,
``mode`` and ``jog``.

The speeds are checked by a watch of the tests' own (:class:`SpeedWatch`): every 1 ms it
takes the servo's reference and computes the tool centre point and the flange with the
forward kinematics (``Kinematics.forward`` with the tool and without one: not the code the
safety supervisor runs), so a supervisor that looked away would not hide a fast reference.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from compiler.driver import compile_source
from compiler.spec import load_spec
from runtime.loop.system import RobotSystem, RunOptions
from runtime.motion.kinematics import Kinematics
from runtime.server.server import Server, ServeOptions
from runtime.timing import TICK
from runtime.wire.protocol import ProtocolError

from conftest import examples

SPEC = "programs/lola15.spc"
SPEC_FILE = str(Path(SPEC).resolve())
#: How long after the last heartbeat a continuous jog must be at rest (docs/protocol.md, jog).
AT_REST_WITHIN = 0.5
#: Closest an axis comes past a software limit (docs/safety.md: the tests' STOP_TOLERANCE).
STOP_TOLERANCE = 0.5


class SpeedWatch:
    """Every tick: the largest speed (mm/s) of the tool centre point and of the flange at the
    servo's reference, while the robot is in T1 (``peak``) and in AUT (``aut_peak``); the
    references kept for the last second; any axis beyond its limits."""

    def __init__(self, system: RobotSystem):
        self.system = system
        spec = system.spec
        self.arm = Kinematics(spec)
        self.flange = Kinematics(spec).with_tool((0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        self.axes = spec.axes
        self.peak = self.aut_peak = 0.0
        self.last = None
        self.epoch = None
        self.references: list[tuple[float, tuple]] = []
        self.beyond: list[str] = []
        system.executive.add("speed watch", self.update, TICK, "record")

    def update(self, now: float) -> None:
        system = self.system
        servo = system.servo
        reference = servo.reference
        if servo.epoch != self.epoch or not servo.running:  # the reference restarted from where the arm is
            self.epoch, self.last = servo.epoch, None
        tool = system.trajectory.frames_now().tool
        arm = self.arm if tuple(tool) == tuple(self.arm.tool) else self.arm.with_tool(tool)
        points = (arm.forward(reference[:6])[:3], self.flange.forward(reference[:6])[:3], tuple(tool))
        if self.last is not None and self.last[2] == points[2] and system.safety.category is None:
            speed = max(math.dist(points[0], self.last[0]), math.dist(points[1], self.last[1])) / TICK
            if system.mode == "t1":
                self.peak = max(self.peak, speed)
            else:
                self.aut_peak = max(self.aut_peak, speed)
        self.last = points
        self.references.append((now, reference))
        if len(self.references) > 1000:
            del self.references[:500]
        if system.memory.initialized:
            for a, x in zip(self.axes, system.robot.positions):
                if not a.min - STOP_TOLERANCE <= x <= a.max + STOP_TOLERANCE:
                    self.beyond.append(f"{a.name} at {x:.3f} beyond {a.min:g}..{a.max:g}")

    def still_since(self, t: float) -> bool:
        """No reference changed from time ``t`` on."""
        later = [r for at, r in self.references if at >= t - 1e-9]
        return bool(later) and all(max(abs(a - b) for a, b in zip(r, later[0])) < 1e-9 for r in later)


def _program(text: str):
    if not text.startswith("program"):
        text = f"program t1;\nseq\n{text}endseq\nendprogram;\n"
    result = compile_source(text, "t1.irl", SPEC)
    assert result.ok, [str(d) for d in result.diagnostics]
    return result.program


@pytest.fixture(scope="module")
def spec():
    return load_spec(SPEC)


# ---- programs in T1 ------------------------------------------------------------------------------
def test_a_program_in_t1_keeps_the_tool_and_the_flange_under_250_mm_per_s(spec):
    program = _program(open("programs/test.irl").read())
    t1 = RobotSystem(spec, RunOptions(mode="t1"))
    watch = SpeedWatch(t1)
    summary = t1.run(program)
    assert summary["fault"] is None and summary["mode"] == "t1"
    assert 150.0 < watch.peak <= 250.0, watch.peak  # planned to 225 mm/s: the reduced speed is used
    assert summary["t1_peak_speed"] == pytest.approx(watch.peak, rel=0.05)
    assert not watch.beyond
    aut = RobotSystem(spec, RunOptions())
    fast = SpeedWatch(aut)
    at_speed = aut.run(program)
    assert at_speed["fault"] is None and fast.aut_peak > 250.0  # the same program is faster in AUT
    assert at_speed["sim_time"] < summary["sim_time"]


def test_the_supervisor_stops_a_t1_move_planned_too_fast(spec):
    system = RobotSystem(spec, RunOptions(mode="t1"))
    system.trajectory.planner.reduced = None  # a planner that ignores T1: the supervisor has the last word
    summary = system.run(_program("move ptp joint(mainjoint(0, 0, 0, 0, 30, 0));\n"
                                  "move ptp joint(mainjoint(60, -20, 30, 0, 30, 0)) speed_ptp:=1.0;\n"))
    assert summary["stop"]["category"] == 1
    assert "in T1 the flange or the tool centre point moved at" in summary["fault"]
    assert "beyond [safety] t1_speed 250 mm/s" in summary["fault"]


@pytest.fixture(scope="module")
def t1_robot(spec):
    system = RobotSystem(spec, RunOptions(mode="t1"))
    watch = SpeedWatch(system)
    assert system.run(_program("move ptp joint(mainjoint(0, 0, 0, 0, 30, 0));\n"))["fault"] is None  # homed
    return system, watch


#: Joint targets about a pose in front of the arm (T1 moves are slow: a few seconds each).
JOINT = st.tuples(st.floats(-25, 25), st.floats(-20, 20), st.floats(-20, 20), st.floats(-40, 40),
                  st.floats(30, 70), st.floats(-60, 60))


@settings(max_examples=examples(4), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(moves=st.lists(st.tuples(st.sampled_from(["ptp", "lin"]), JOINT, st.floats(0.2, 1.0), st.booleans()),
                      min_size=1, max_size=3))
def test_random_moves_in_t1_never_pass_250_mm_per_s(t1_robot, moves):
    """Random ptp and lin moves (joint targets, any speed, with approx) in T1: every 1 ms
    reference keeps the tool centre point and the flange at most 250 mm/s, no limit is
    passed, and nothing but a refused path ends a program early."""
    system, watch = t1_robot
    kinematics = system.trajectory.planner.kinematics
    lines = []
    for kind, q, speed, approx in moves:
        target = "joint(mainjoint(" + ", ".join(f"{v:.2f}" for v in q) + "))"
        if kind == "lin":
            x, y, z, r, p, w = kinematics.forward(q)
            target = f"pose(pos({x:.3f}, {y:.3f}, {z:.3f}), rpy({r:.3f}, {p:.3f}, {w:.3f}))"
        clauses = f"speed_ptp:={speed:.2f}" if kind == "ptp" else f"speed:={speed * 2000:.0f}"
        blend = (0.5 if kind == "ptp" else 50) if approx else 0
        lines.append(f"move {kind} {target} {clauses} approx:={blend};")
    summary = system.run(_program("\n".join(lines) + "\n"))
    assert watch.peak <= 250.0, watch.peak
    assert not watch.beyond, watch.beyond
    fault = summary["fault"] or ""
    assert "safety" not in fault, fault
    assert not fault or "refused" in fault or "cannot be reached" in fault, fault


# ---- jogging on a server ---------------------------------------------------------------------------
class Cell:
    """A server with its loop in this process on the simulated clock: one turn, one tick."""

    def __init__(self, spec, tmp, mode="t1"):
        self.server = Server(spec, ServeOptions(sim_clock=True, loop_process=False, state_dir=tmp, mode=mode))
        self.system = self.server.system
        self.watch = SpeedWatch(self.system)

    def turns(self, n: int) -> None:
        for _ in range(n):
            self.server.turn()

    def request(self, op: str, args: dict | None = None):
        return self.server.request(op, args)

    @property
    def t(self) -> float:
        return self.system.clock.tick_time

    def jog(self, **args) -> dict:
        return self.request("jog", args)

    def settle(self, limit: int = 40_000) -> dict:
        """Turns until no jog is under way (and the session has reached Move Robot)."""
        for _ in range(limit):
            self.server.turn()
            jogger = self.system.trajectory.jogger
            if jogger is not None and jogger.active is None and jogger.pending is None and not jogger.stopping:
                return jogger.state()
        raise AssertionError("the jog did not end")

    def hold(self, seconds: float, **args) -> float:
        """A continuous jog held ``seconds`` with a heartbeat every 0.1 s; the time of the last one."""
        last = self.t
        for _ in range(max(1, round(seconds / 0.1))):
            self.jog(**args)
            last = self.t
            self.turns(100)
        return last

    def clear(self) -> None:
        """Every program waiting cancelled, the one running aborted, until idle."""
        jobs = self.server.jobs
        for job in list(jobs.queue):
            self.request("abort", {"program": job.id})
        if jobs.current is not None:
            try:
                self.request("abort", {"program": jobs.current.id})
            except ProtocolError:
                pass  # (ending already)
        self.idle()

    def idle(self) -> None:
        """Until the jog session (or program) has ended."""
        for _ in range(200_000):
            if self.server.jobs.current is None:
                return
            self.server.turn()
        raise AssertionError("the session did not end")


@pytest.fixture(scope="module")
def cell(spec, tmp_path_factory):
    cell = Cell(spec, tmp_path_factory.mktemp("jog"))
    cell.jog(axis="A5", direction=1, step=30.0)  # homes first (in T1), then A5 off the wrist singularity
    assert cell.settle()["reason"] == "jog A5+, 30 deg done"
    return cell


def test_an_increment_moves_one_axis_by_its_step(cell):
    before = list(cell.system.trajectory.motion.positions)
    cell.jog(axis="A1", direction=-1, step=1.5)
    state = cell.settle()
    after = cell.system.trajectory.motion.positions
    assert state["reason"] == "jog A1-, 1.5 deg done"
    assert after[0] == pytest.approx(before[0] - 1.5, abs=1e-9)
    assert after[1:] == pytest.approx(before[1:], abs=1e-9)


def test_an_increment_past_a_limit_is_refused_with_the_limit(cell):
    with pytest.raises(ProtocolError) as refused:
        cell.jog(axis="A2", direction=1, step=100.0)
    assert "beyond its software limits" in refused.value.message and "A2" in refused.value.message


def test_a_held_jog_stops_within_half_a_second_of_its_last_heartbeat(cell):
    start = cell.system.trajectory.motion.positions[:6]
    kinematics = cell.system.trajectory.planner.kinematics
    before = kinematics.forward(start)
    last = cell.hold(1.0, axis="z", direction=-1, frame="tool")
    cell.turns(round(AT_REST_WITHIN / TICK) + 50)
    assert cell.watch.still_since(last + AT_REST_WITHIN)
    state = cell.system.trajectory.jogger.state()
    assert "no heartbeat for 0.25 s" in state["reason"]
    after = kinematics.forward(cell.system.trajectory.motion.positions[:6])
    assert math.dist(before[:3], after[:3]) > 100.0  # it moved, along the tool's z
    assert cell.watch.peak <= 250.0


def test_a_released_jog_stops_at_once(cell):
    cell.jog(axis="A1", direction=1)
    cell.turns(300)
    released = cell.t
    cell.jog(axis="A1", direction=0)
    cell.turns(400)
    assert cell.watch.still_since(released + 0.3)
    assert "released" in cell.system.trajectory.jogger.state()["reason"]


def test_a_cartesian_jog_stops_before_the_arm_cannot_go_on_and_says_why(cell):
    cell.hold(8.0, axis="x", direction=1, frame="world")  # outwards, held on after the end of the reach
    state = cell.settle()
    assert "before the arm cannot go on" in state["reason"] and "reach" in state["reason"], state["reason"]
    assert cell.watch.peak <= 250.0 and not cell.watch.beyond
    cell.hold(1.0, axis="x", direction=-1)  # and back
    cell.settle()


def test_jogging_and_switching_are_refused_where_they_must_be(cell, spec):
    with pytest.raises(ProtocolError, match="axis must be one of"):
        cell.jog(axis="A9", direction=1, step=1.0)
    cell.idle()
    assert cell.request("mode", {"mode": "aut"}) == {"mode": "aut"}
    with pytest.raises(ProtocolError, match="jogging needs operating mode T1"):
        cell.jog(axis="A1", direction=1, step=1.0)
    cell.request("submit", {"object": _object("move ptp joint(mainjoint(10, 0, 0, 0, 30, 0));\n"
                                               "move ptp joint(mainjoint(0, 0, 0, 0, 30, 0));\n")})
    cell.turns(50)
    with pytest.raises(ProtocolError, match="only with the robot at rest and no program running"):
        cell.request("mode", {"mode": "t1"})
    cell.idle()
    assert cell.request("mode", {"mode": "t1"}) == {"mode": "t1"}
    assert cell.request("status")["mode"] == "t1"


def _object(text: str) -> bytes:
    from compiler.objcode import encode

    return encode(_program(text))


# ---- a stateful search: modes, jogs, lost heartbeats, programs, pauses and e-stops ---------------
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule, run_state_machine_as_test  # noqa: E402

AXES = ("A1", "A2", "A3", "A4", "A5", "A6", "x", "y", "z", "rx", "ry", "rz")
PROGRAM = ("move ptp joint(mainjoint(10, -10, 15, 0, 40, 0)) speed_ptp:=0.6;\n"
           "move lin pose(pos(1000, 100, 1300), rpy(180, -50, 0)) speed:=1500;\n"
           "move ptp joint(mainjoint(-10, 0, 5, 20, 50, 10)) speed_ptp:=1.0 approx:=0.5;\n"
           "move ptp joint(mainjoint(0, 0, 0, 0, 30, 0));\n")


class Operator(RuleBasedStateMachine):
    """An operator (and a client beside) doing anything in any order to a served robot."""

    cell: Cell  # set by the test (one server for every example: the robot remembers its homing)

    def _refused(self, op: str, args: dict | None = None) -> str | None:
        try:
            self.cell.request(op, args)
        except ProtocolError as exc:
            assert exc.code in ("refused", "not_found"), exc.message
            return exc.message
        return None

    @initialize()
    def at_rest_in_t1(self):
        self.cell.clear()
        self.cell.request("mode", {"mode": "t1"})

    @rule(mode=st.sampled_from(["t1", "aut"]))
    def switch(self, mode):
        busy = self.cell.server.jobs.current is not None and not self.cell.server.jobs.current.jog
        problem = self._refused("mode", {"mode": mode})
        assert (problem is not None) == busy, problem
        self.cell.turns(20)

    @rule(axis=st.sampled_from(AXES), direction=st.sampled_from([1, -1]), frame=st.sampled_from(["world", "base", "tool"]),
          step=st.sampled_from([0.1, 1.0, 10.0]))
    def increment(self, axis, direction, frame, step):
        problem = self._refused("jog", {"axis": axis, "direction": direction, "frame": frame, "step": step})
        if self.cell.system.mode != "t1":
            assert problem is not None and "T1" in problem
            return
        if problem is None:
            self.cell.settle()

    @rule(axis=st.sampled_from(AXES), direction=st.sampled_from([1, -1]), frame=st.sampled_from(["world", "tool"]),
          beats=st.integers(1, 6), release=st.booleans())
    def hold(self, axis, direction, frame, beats, release):
        """Held for some heartbeats, then released or simply no more heartbeats (a lost
        connection): at rest within 0.5 s of the last one."""
        cell = self.cell
        if cell.system.mode != "t1" or (cell.server.jobs.current is not None and not cell.server.jobs.current.jog):
            return
        last = None
        for _ in range(beats):
            if self._refused("jog", {"axis": axis, "direction": direction, "frame": frame}) is not None:
                break
            last = cell.t
            cell.turns(100)
        if last is None:
            return
        if release:
            self._refused("jog", {"axis": axis, "direction": 0, "frame": frame})
        while cell.system.trajectory.jogger is None and cell.server.jobs.current is not None:
            cell.turns(100)  # (still homing: the jog waits for Move Robot)
        cell.turns(max(0, round((last + AT_REST_WITHIN - cell.t) / TICK)) + 20)
        if cell.system.trajectory.jogger is not None and cell.system.safety.category is None:
            assert cell.watch.still_since(max(last + AT_REST_WITHIN, cell.t - 0.015)), \
                f"still moving {cell.t - last:.3f} s after the last heartbeat"

    @rule(pause=st.booleans(), estop=st.sampled_from([False, False, False, True]), ticks=st.integers(100, 3000),
          steps=st.sampled_from([None, 0, 2]))
    def program(self, pause, estop, ticks, steps):
        """A program (in step mode: some steps given, then the rest), paused, e-stopped."""
        cell = self.cell
        try:
            submitted = cell.request("submit", {"object": _object(PROGRAM),
                                                **({"step": True} if steps is not None else {})})["program"]
        except ProtocolError as exc:
            assert exc.code == "refused", exc.message
            return
        cell.turns(ticks)
        for _ in range(steps or 0):
            self._refused("step")
            cell.turns(ticks)
        if steps is not None and not estop:
            self._refused("abort", {"program": submitted})  # (it may still wait behind a jog session)
        if pause and self._refused("pause") is None:
            cell.turns(500)
            self._refused("resume")
        if estop:
            self._refused("estop")
        cell.idle()

    @rule()
    def idle(self):
        self.cell.idle()

    @invariant()
    def kept(self):
        watch = self.cell.watch
        assert watch.peak <= 250.0, f"T1: {watch.peak:.1f} mm/s"
        assert not watch.beyond, watch.beyond[:3]
        for job_id in self.cell.server.jobs:
            fault = self.cell.server.jobs[job_id].fault or ""
            assert "t1 speed" not in fault and "t1_speed" not in fault, fault

    def teardown(self):
        self.cell.clear()


def test_any_sequence_of_modes_jogs_programs_and_stops_keeps_t1_and_the_limits(spec, tmp_path):
    Operator.cell = cell = Cell(spec, tmp_path, mode="t1")
    cell.request("submit", {"object": _object("move ptp joint(mainjoint(0, 0, 0, 0, 30, 0));\n")})
    cell.idle()  # homed (a lost homing, after an e-stop, is searched too: it homes again)
    run_state_machine_as_test(Operator, settings=settings(max_examples=6, stateful_step_count=10, deadline=None))


# ---- the commands, against a served robot --------------------------------------------------------
def test_an_operator_switches_jogs_and_teaches_from_the_command_line(tmp_path):
    """irl mode, irl jog (an increment and a held jog), irl where, and the taught literals
    pasted into a program that irl check accepts."""
    from tests.conftest import ServerProcess, no_traceback, run_irl

    server = ServerProcess(tmp_path / "serve", tmp_path / "state").start()
    try:
        at = ("--endpoint", server.endpoint)
        refused = run_irl("jog", "A1", "+1", *at)
        assert refused.returncode == 1 and "jogging needs operating mode T1" in refused.stderr
        shown = run_irl("mode", "t1", *at)
        assert shown.returncode == 0 and shown.stdout.startswith("operating mode T1: manual reduced speed")
        stepped = run_irl("jog", "A5", "+30", *at)  # (homes first)
        assert stepped.returncode == 0, stepped.stderr
        assert "jog A5+, 30 deg done" in stepped.stdout and "A5 30.0" in stepped.stdout
        bad = run_irl("jog", "A5", "+100", *at)  # (A5 at 30 deg: 130 is beyond its 120)
        assert bad.returncode == 1 and "beyond its software limits -120..120 deg" in bad.stderr
        moved = run_irl("jog", "z", "-", "--frame", "tool", "--hold", "0.5", "--json", *at)
        assert moved.returncode == 0, moved.stderr
        assert "stopped: released" in json.loads(moved.stdout)["jog"]["reason"]
        where = run_irl("where", *at)
        assert where.returncode == 0, where.stderr
        joint, pose = where.stdout.splitlines()[:2]
        assert joint.startswith("joint(mainjoint(") and pose.startswith("pose(pos(") and "config(" in pose
        program = tmp_path / "taught.irl"
        program.write_text(f'program taught;\nsystem_specification "{SPEC_FILE}";\nseq\n  move ptp {joint};\n'
                           f"  move ptp joint(mainjoint(0, 0, 0, 0, 30, 0));\n  move ptp {pose};\n"
                           f"  move lin {pose.replace('pos(', 'pos(', 1)};\nendseq\nendprogram;\n")
        checked = run_irl("check", program)
        assert checked.returncode == 0, checked.stdout + checked.stderr
        for proc in (refused, shown, stepped, moved, bad, where, checked):
            no_traceback(proc)
    finally:
        server.stop()
