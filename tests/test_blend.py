"""Look-ahead and blending (``approx``) in the Trajectory Generator, in-process on the
simulated clock: every 5 ms setpoint of random blended PTP programs within the axes'
velocity, acceleration and jerk limits; blending saves time and does not stop at its
corners; lin-lin and lin-circ corners are cut within ``approx`` mm; instructions that must
happen where the robot is (``print``) stop the look-ahead; ``[controller] lookahead``;
a move that cannot be planned stops the program after the moves before it; pause and
abort inside a blend; and the VM's side of the look-ahead on a fake host.

The setpoint stream is what the generator writes to ``desi_pos`` (time, positions,
velocities) every 5 ms; a spy port records it. Its finite differences at h = 5 ms are
compared with each axis's limits from the specification.
"""
from __future__ import annotations

import io
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler.driver import compile_source
from compiler.objcode import Program, verify
from compiler.spec import SpecError, load_spec
from runtime.cli.main import Environment, main
from runtime.loop.component import DataPort
from runtime.loop.components.trajectory import LOOKAHEAD, lookahead_depth
from runtime.motion.kinematics import Kinematics
from runtime.loop.supervisor import MOVE
from runtime.loop.system import RobotSystem, RunOptions
from runtime.loop.vm import VM, VMStatus

from conftest import PROGRAMS, SPEC_PATH, SPEC
AXES = SPEC.axes
H = 0.005  # the trajectory generator's period
COUNTS = [1.0 / a.counts_per_unit for a in AXES]
LIMITS = [np.array([getattr(a, name) for a in AXES], dtype=float)
          for name in ("max_velocity", "max_acceleration", "max_jerk")]
RATIO_OK = 1.0 + 1e-6
P0 = (0.0, -30.0, 30.0, 0.0, 60.0, 0.0)
FIRST_LINE = 4  # the first statement of the programs built by source()


# ---- helpers ------------------------------------------------------------------------------------

def source(body: str, decls: str = "", name: str = "blendtest") -> str:
    return f'program {name};\nsystem_specification "lola15.spc";\n{decls}seq\n{body}endseq\nendprogram;\n'


def build(body: str, decls: str = "", spec_path: Path = SPEC_PATH) -> Program:
    text = source(body, decls)
    result = compile_source(text, "blendtest.irl", spec_path)
    assert result.ok, result.diagnostics
    return result.program


def joint(values) -> str:
    return f"joint(mainjoint({', '.join(f'{v:g}' for v in values)}))"


def ptp(values, **clauses) -> str:
    extra = "".join(f" {k} := {v:g}" for k, v in clauses.items())
    return f"  move ptp {joint(values)}{extra};\n"


class Bench:
    """One simulated robot (calibration and initialization once) and a spy on the
    trajectory generator's ``desi_pos`` port: ``rows`` holds, for every setpoint written
    while a program runs, (time, timeline time, positions, velocities)."""

    def __init__(self, spec=SPEC, seed: int = 2):
        self.system = RobotSystem(spec, RunOptions(seed=seed))
        self.tg = tg = self.system.trajectory
        self.rows: list[tuple] = []
        self.segments: dict[int, object] = {}  # every segment seen on the timeline (id -> segment)
        rows, segments = self.rows, self.segments

        class Spy(DataPort):
            __slots__ = ()

            def write(self, value, stamp=0.0):
                DataPort.write(self, value, stamp)
                if tg.vm is not None:
                    rows.append((value[0], tg.motion.t_move, value[1], value[2]))
                    for seg in tg.motion._segments:
                        if seg.start is not None:
                            segments.setdefault(id(seg), seg)

        spy = Spy("desi_pos", tg.desi_pos.value)
        tg.desi_pos = self.system.servo.desi_pos = self.system.ports["desi_pos"] = spy

    def begin(self, program: Program) -> None:
        self.rows.clear()
        self.segments.clear()
        self.system.begin(program)

    def finish(self) -> dict:
        sup = self.system.supervisor
        self.system.executive.run(lambda: sup.done, 10**7)
        return self.system.finish()

    def run(self, program: Program) -> dict:
        self.begin(program)
        return self.finish()

    def to_move(self) -> None:
        sup = self.system.supervisor
        self.system.executive.run(lambda: sup.fsm.state == MOVE, 10**6)

    def tick_until(self, condition, max_ticks: int = 10**6) -> None:
        self.system.executive.run(condition, max_ticks)
        assert condition(), "the condition was not reached"

    # the recorded stream
    @property
    def times(self) -> np.ndarray:
        return np.array([r[0] for r in self.rows])

    @property
    def positions(self) -> np.ndarray:
        return np.array([r[2] for r in self.rows], dtype=float)

    @property
    def velocities(self) -> np.ndarray:
        return np.array([r[3] for r in self.rows], dtype=float)


_BENCH: list[Bench] = []


def shared_bench() -> Bench:
    """One robot for the whole module (a second program skips calibration and initialization)."""
    if not _BENCH:
        _BENCH.append(Bench())
    return _BENCH[0]


@pytest.fixture()
def bench() -> Bench:
    return shared_bench()


def limit_ratios(positions: np.ndarray, h: float = H) -> tuple[float, float, float]:
    """The largest |first, second, third difference| / h^k of the stream over each axis's
    velocity, acceleration and jerk limit."""
    out = []
    d = positions
    for order, limit in enumerate(LIMITS, start=1):
        d = np.diff(d, axis=0)
        out.append(float(np.max(np.abs(d) / h ** order / limit)) if len(d) else 0.0)
    return out[0], out[1], out[2]


def records(bench: Bench) -> list:
    return list(bench.tg.moves)


def move_robot_time(summary: dict) -> float:
    (state,) = [s for s in summary["states"] if s["name"] == MOVE]
    return state["t_exit"] - state["t_enter"]


def within_counts(actual, want, counts: int = 3) -> bool:
    return all(abs(x - w) <= counts * c for x, w, c in zip(actual, want, COUNTS))


# ---- 1. every setpoint of random blended PTP programs within every axis's limits ----------------

# targets in a box well inside lola15.spc's axis limits (A1 +-170, A2 -135..90, A3 -120..156,
# A4 +-185, A5 +-120, A6 +-350)
BOX = ((-90.0, 90.0), (-40.0, 40.0), (-40.0, 60.0), (-90.0, 90.0), (-30.0, 90.0), (-90.0, 90.0))
assert all(a.min <= lo and hi <= a.max for a, (lo, hi) in zip(AXES, BOX))

_target = st.tuples(*[st.floats(lo, hi).map(lambda v: round(v, 2)) for lo, hi in BOX])
_fraction = st.floats(0.2, 1.0).map(lambda v: round(v, 3))
_approx = st.one_of(st.just(0.0), st.floats(0.0, 1.0).map(lambda v: round(v, 3)), st.just(1.0))
_move = st.tuples(_target, _fraction, _fraction, _approx)


def test_property_every_setpoint_of_random_blended_ptp_programs_keeps_the_axis_limits():
    """3-6 PTP moves with random speed_ptp, acc_ptp and approx: the 5 ms stream's first,
    second and third differences stay within every axis's velocity, acceleration and jerk
    limit (blended corners included), no fault, the robot ends at the last target, and a
    move without approx never blends."""
    blended_corners = []

    @settings(max_examples=30, deadline=None, derandomize=True, database=None)
    @given(st.lists(_move, min_size=3, max_size=6))
    def check(moves):
        body = "".join(ptp(t, speed_ptp=s, acc_ptp=a, approx=x) for t, s, a, x in moves)
        bench = shared_bench()
        summary = bench.run(build(body))
        assert summary["fault"] is None, summary["fault"]
        assert [m["line"] for m in summary["moves"]] == list(range(FIRST_LINE, FIRST_LINE + len(moves)))
        for m, (_t, _s, _a, x) in zip(summary["moves"], moves):
            if x == 0.0:
                assert not m["blended"], m
            assert m["actual_duration"] is not None
        assert not summary["moves"][-1]["blended"]
        blended_corners.append(sum(m["blended"] for m in summary["moves"]))
        ratios = limit_ratios(bench.positions)
        assert max(ratios) <= RATIO_OK, ratios
        last = moves[-1][0]
        assert bench.tg.motion.positions == pytest.approx(last, abs=1e-9)  # the last setpoint is the target
        assert within_counts(summary["final_position"], last), (summary["final_position"], last)

    check()
    assert sum(blended_corners) >= 10, blended_corners  # the examples did exercise blends


# ---- 2. blending saves time and does not stop at its corners -----------------------------------------

TOUR = ((40.0, -10.0, 40.0, 20.0, 40.0, 30.0), (-30.0, 10.0, 20.0, -20.0, 70.0, -40.0),
        (20.0, -20.0, 50.0, 30.0, 30.0, 60.0), (-20.0, 0.0, 10.0, 10.0, 50.0, 0.0))


def tour_program(approx: float) -> Program:
    body = ptp(P0) + "".join(ptp(t, speed_ptp=0.6, acc_ptp=0.6, approx=approx) for t in TOUR) + ptp(P0)
    return build(body)


def speeds(bench: Bench) -> tuple[np.ndarray, np.ndarray]:
    """The commanded joint speed at every setpoint: the norm of the stream's velocities,
    and of its first differences / h (0 for the first setpoint)."""
    v = np.linalg.norm(bench.velocities, axis=1)
    d = np.linalg.norm(np.diff(bench.positions, axis=0), axis=1) / H
    return v, np.concatenate([[0.0], d])


def test_blending_saves_time_and_never_stops_at_a_blended_corner(bench):
    plain = bench.run(tour_program(0.0))
    assert plain["fault"] is None
    plain_moves = records(bench)
    plain_times = bench.times
    plain_v, _ = speeds(bench)
    assert not any(m["blended"] for m in plain["moves"])

    blended = bench.run(tour_program(1.0))
    assert blended["fault"] is None
    moves = records(bench)
    times = bench.times
    v, d = speeds(bench)
    n = len(TOUR)
    assert [m["blended"] for m in blended["moves"]] == [False] + [True] * n + [False]
    # the same moves (each planned rest to rest), only overlapped
    for a, b in zip(plain["moves"][1:], blended["moves"][1:]):
        assert b["planned_duration"] == pytest.approx(a["planned_duration"], rel=1e-12)

    # shorter: the tour after the first (positioning) move, and the whole Move Robot phase
    # apart from that first move (the robot may start anywhere)
    tour_plain = plain_moves[-1].t_end - plain_moves[1].t_start
    tour_blended = moves[-1].t_end - moves[1].t_start
    overlaps = [a.t_end - b.t_start for a, b in zip(moves[1:-1], moves[2:])]
    gaps = [b.t_start - a.t_end for a, b in zip(plain_moves[1:-1], plain_moves[2:])]
    assert min(overlaps) > 0.05 and all(-1e-9 <= g <= H + 1e-9 for g in gaps)
    assert tour_blended < tour_plain - 0.1 * n
    # the time saved is what the moves overlap (each move itself takes as long as before, to
    # a tick: the records' times are whole ticks)
    assert tour_plain - tour_blended == pytest.approx(sum(overlaps) + sum(gaps), abs=H * n)
    assert (move_robot_time(blended) - blended["moves"][0]["actual_duration"]
            < move_robot_time(plain) - plain["moves"][0]["actual_duration"] - 0.1 * n)

    # at each blended corner the commanded speed never falls to zero between the two moves
    for a, b in zip(moves[1:-1], moves[2:]):
        assert a.blended and b.t_start < a.t_end  # they overlap on the clock
        window = (times > a.t_start) & (times < b.t_end)
        assert window.sum() > 50
        assert v[window].min() > 0.0 and d[window].min() > 0.0, (a.line, v[window].min(), d[window].min())
    # ... while the tour without approx stops exactly at each of these corners
    for a, b in zip(plain_moves[1:-1], plain_moves[2:]):
        assert a.t_end <= b.t_start + 1e-9
        window = (plain_times >= a.t_start) & (plain_times < b.t_end)
        assert plain_v[window].min() == 0.0  # (a single setpoint at rest: its differences are not 0)
    # the same tour, the same end
    assert bench.tg.motion.positions == pytest.approx(P0, abs=1e-9)


# ---- 3. lin-lin and lin-circ corners: cut within approx mm, without stopping, within the limits ------

TOOL = "const\n  tool := rpy(180, 0, 180);\n"
APPROX_MM = 30.0
CARTESIAN = (
    "  move ptp pose(pos(900, -200, 600), tool);\n"
    f"  move lin pose(pos(900, 200, 600), tool) speed := 300 approx := {APPROX_MM:g};\n"
    f"  move lin pose(pos(1100, 200, 600), tool) speed := 300 approx := {APPROX_MM:g};\n"
    "  move circ pose(pos(1200, 0, 600), tool), pose(pos(1100, -200, 600), tool)"
    f" speed := 300 approx := {APPROX_MM:g};\n"
    "  move lin pose(pos(900, -200, 600), tool) speed := 300;\n")
A_START, CORNER_1, CORNER_2, CIRC_VIA, CORNER_3 = (np.array(p, dtype=float) for p in (
    (900, -200, 600), (900, 200, 600), (1100, 200, 600), (1200, 0, 600), (1100, -200, 600)))


def distance_to_segment(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    u = np.clip((points - a) @ d / (d @ d), 0.0, 1.0)
    return np.linalg.norm(points - (a + u[:, None] * d), axis=1)


def circle_through(a, b, c) -> tuple[np.ndarray, float, np.ndarray]:
    """Centre, radius and unit normal of the circle through three points."""
    ab, ac = b - a, c - a
    normal = np.cross(ab, ac)
    n2 = normal @ normal
    centre = a + (np.cross(normal, ab) * (ac @ ac) + np.cross(ac, normal) * (ab @ ab)) / (2.0 * n2)
    return centre, float(np.linalg.norm(a - centre)), normal / math.sqrt(n2)


def distance_to_circle(points: np.ndarray, centre, radius, normal) -> np.ndarray:
    rel = points - centre
    h = rel @ normal
    in_plane = np.linalg.norm(rel - h[:, None] * normal, axis=1)
    return np.hypot(in_plane - radius, h)


def check_corner(tcp, times, corner, on_first, on_second, approx, since, until):
    """At a blended corner: the TCP leaves the first path within ``approx`` of the corner,
    joins the second within ``approx`` of it, passes it at a distance in (0, approx], and
    does not stop. ``since``..``until``: from where the TCP is on the first path only (the
    first move's start, or the end of the blend before) to where it is on the second only
    (the second move's end, or the start of the next blend)."""
    window = (times >= since) & (times <= until)
    idx = np.flatnonzero(window)
    points = tcp[idx]
    off_first = on_first(points) > 1e-3
    off_second = on_second(points) > 1e-3
    leave = np.argmax(off_first)  # the first setpoint off the first path
    assert leave >= 1 and off_first[leave] and not off_first[:leave].any()
    assert np.linalg.norm(points[leave - 1] - corner) <= approx + 1e-6  # left it within approx
    join = len(points) - np.argmax(off_second[::-1])  # from here on, on the second path
    assert off_second[join - 1] and not off_second[join:].any()
    assert np.linalg.norm(points[join] - corner) <= approx + 1e-6
    # in between, off both paths (the corner is cut), near it
    assert join - leave >= 5
    closest = float(np.min(np.linalg.norm(points - corner, axis=1)))
    assert 0.5 < closest <= approx, closest
    assert np.all(np.minimum(on_first(points[leave:join]), on_second(points[leave:join])) > 0.0)
    # never stopping: the TCP moves at every setpoint of the window
    step = np.linalg.norm(np.diff(tcp[idx[0] - 1:idx[-1] + 1], axis=0), axis=1)
    assert step.min() > 0.0, step.min()
    return closest


def test_lin_lin_and_lin_circ_corners_are_cut_within_approx_without_stopping(bench):
    summary = bench.run(build(CARTESIAN, TOOL))
    assert summary["fault"] is None, summary["fault"]
    assert [m["blended"] for m in summary["moves"]] == [False, True, True, True, False]
    assert [r.kind for r in bench.tg.moves] == ["ptp", "lin", "lin", "circ", "lin"]
    _ptp, lin1, lin2, circ, lin3 = records(bench)
    times, joints = bench.times, bench.positions

    # every setpoint within every axis's limits: the lines, the arc and the three blends
    ratios = limit_ratios(joints)
    assert max(ratios) <= RATIO_OK, ratios
    for a, b in ((lin1, lin2), (lin2, circ), (circ, lin3)):
        assert b.t_start < a.t_end  # the blends overlap on the clock (they are in the stream)

    kin = Kinematics(SPEC)
    tcp = np.array([kin.forward(p[:6])[:3] for p in joints])
    centre, radius, normal = circle_through(CORNER_2, CIRC_VIA, CORNER_3)
    on_circle = lambda pts: distance_to_circle(pts, centre, radius, normal)  # noqa: E731
    # lin-lin
    check_corner(tcp, times, CORNER_1, lambda pts: distance_to_segment(pts, A_START, CORNER_1),
                 lambda pts: distance_to_segment(pts, CORNER_1, CORNER_2), APPROX_MM, lin1.t_start, circ.t_start)
    # lin-circ
    check_corner(tcp, times, CORNER_2, lambda pts: distance_to_segment(pts, CORNER_1, CORNER_2),
                 on_circle, APPROX_MM, lin1.t_end, lin3.t_start)
    # circ-lin
    check_corner(tcp, times, CORNER_3, on_circle, lambda pts: distance_to_segment(pts, CORNER_3, A_START),
                 APPROX_MM, lin2.t_end, lin3.t_end)
    end = kin.forward(bench.tg.motion.positions[:6])[:3]
    assert end == pytest.approx(tuple(A_START), abs=1e-6)


def test_the_blend_example_program_blends_every_corner():
    """programs/blend.irl through ``irl run --json``: every move but the last blends."""
    import json

    out, err = io.StringIO(), io.StringIO()
    code = main(["run", str(PROGRAMS / "blend.irl"), "--json"], Environment(stdout=out, stderr=err))
    assert code == 0, err.getvalue()
    summary = json.loads(out.getvalue())
    assert summary["fault"] is None
    flags = [m["blended"] for m in summary["moves"]]
    assert len(flags) == 8 and flags == [True] * 7 + [False]
    assert all(m["actual_duration"] is not None for m in summary["moves"])


# ---- 4. look-ahead: where the robot must be, and [controller] lookahead ---------------------------

def test_a_print_between_moves_waits_for_the_robot_and_is_not_blended_across(bench):
    a, b, c = TOUR[0], TOUR[1], TOUR[2]
    body = (ptp(a, approx=1) + '  print "at a";\n' + ptp(b, approx=1) + '  print "at b";\n' + ptp(c, approx=1)
            + ptp(P0))
    summary = bench.run(build(body))
    assert summary["fault"] is None
    moves = records(bench)
    # the print stops the look-ahead: no blend across it (the last two moves do blend)
    assert [m.blended for m in moves] == [False, False, True, False]
    log = summary["log"]
    assert [(e["line"], e["text"]) for e in log] == [(FIRST_LINE + 1, "at a"), (FIRST_LINE + 3, "at b")]
    times, velocities = bench.times, bench.velocities
    for entry, before, after in ((log[0], moves[0], moves[1]), (log[1], moves[1], moves[2])):
        # printed where the robot reached the point: after the move before it ended ...
        assert entry["time"] >= before.t_end
        # ... at rest there, and before the next move started
        assert after.t_start >= entry["time"]
        at = np.flatnonzero(np.isclose(times, entry["time"], atol=1e-9, rtol=0.0))
        assert len(at) == 1 and np.all(velocities[at[0]] == 0.0)
        assert bench.rows[at[0]][2] == pytest.approx(before.target, abs=1e-9)


def test_the_program_runs_at_most_lookahead_moves_ahead_of_the_robot(bench):
    body = "".join(ptp(t, approx=0.5) for t in TOUR + TOUR[:2]) + ptp(P0)
    bench.begin(build(body))
    tg, sup = bench.tg, bench.system.supervisor
    queued = []
    bench.system.executive.run(lambda: (queued.append(tg.motion.queued), sup.done)[1], 10**7)
    summary = bench.system.finish()
    assert summary["fault"] is None
    assert tg.lookahead == LOOKAHEAD == 4
    assert max(queued) == tg.lookahead  # it ran ahead as far as it may, not further
    assert all(m["blended"] for m in summary["moves"][:-1])


def spec_copy(tmp_path: Path, line: str) -> Path:
    text = SPEC_PATH.read_text(encoding="utf-8")
    assert "[controller]\n" in text
    path = tmp_path / "lola15.spc"
    path.write_text(text.replace("[controller]\n", f"[controller]\n{line}\n", 1), encoding="utf-8")
    return path


def test_lookahead_zero_waits_for_each_move_and_nothing_blends(tmp_path):
    path = spec_copy(tmp_path, "lookahead = 0")
    spec = load_spec(path)
    assert lookahead_depth(spec) == 0
    body = "".join(ptp(t, approx=1) for t in TOUR) + ptp(P0)
    program = build(body, spec_path=path)
    zero = Bench(spec)
    assert zero.tg.lookahead == 0
    zero.begin(program)
    tg, sup = zero.tg, zero.system.supervisor
    queued = []
    zero.system.executive.run(lambda: (queued.append(tg.motion.queued), sup.done)[1], 10**7)
    summary = zero.system.finish()
    assert summary["fault"] is None
    assert len(summary["moves"]) == len(TOUR) + 1
    assert not any(m["blended"] for m in summary["moves"])
    assert max(queued) <= 1  # the move just handed over, nothing beyond it
    moves = records(zero)
    assert all(a.t_end <= b.t_start + 1e-9 for a, b in zip(moves, moves[1:]))  # one after the other
    assert max(limit_ratios(zero.positions)) <= RATIO_OK
    # the same program with the default look-ahead blends its corners
    assert all(m["blended"] for m in shared_bench().run(build(body))["moves"][:-1])


@pytest.mark.parametrize("value", ["99", "17", "-1", '"x"', "2.5", '"4"'])
def test_an_invalid_lookahead_is_refused_naming_the_setting(tmp_path, value):
    """Refused when the specification is loaded (so irl check, run and serve all say so)."""
    path = spec_copy(tmp_path, f"lookahead = {value}")
    with pytest.raises(SpecError, match=r"controller\.lookahead: expected an integer 0 <= x <= 16"):
        load_spec(path)


@pytest.mark.parametrize("value", ["0", "1", "16"])
def test_lookahead_bounds_are_accepted(tmp_path, value):
    assert lookahead_depth(load_spec(spec_copy(tmp_path, f"lookahead = {value}"))) == int(value)


def test_irl_run_refuses_an_invalid_lookahead_without_a_traceback(tmp_path):
    spec_copy(tmp_path, "lookahead = 99")
    shutil.copy(PROGRAMS / "blend.irl", tmp_path / "blend.irl")
    out, err = io.StringIO(), io.StringIO()
    code = main(["run", str(tmp_path / "blend.irl"), "--json"], Environment(stdout=out, stderr=err))
    assert code != 0, err.getvalue()
    assert "controller.lookahead" in err.getvalue() and "99" in err.getvalue()
    for text in (out.getvalue(), err.getvalue()):
        assert "Traceback" not in text and "internal error" not in text


# ---- 5. a move that cannot be planned: the moves before it complete, then the fault ---------------

GOOD = ptp(P0) + "  move ptp joint(mainjoint(0, -30, 30, 0, 45, 0)) approx := 1;\n"
BAD = {
    "ptp pose outside the axis limits": ("  move ptp pose(pos(-900, 0, -300), rpy(180, 0, 180));\n",
                                         "no solution within the axis limits"),
    "lin through the wrist singularity": ("  move lin pose(pos(0, 0, 1800), rpy(180, 0, 180));\n",
                                          "move lin refused"),
}


@pytest.mark.parametrize("bad", sorted(BAD))
def test_a_move_that_cannot_be_planned_stops_the_program_after_the_moves_before_it(bench, bad):
    statement, reason = BAD[bad]
    bench.begin(build(GOOD + statement))
    tg, sup = bench.tg, bench.system.supervisor
    seen = []  # (vm status, motion done, fault) before every tick

    def watch():
        if tg.vm is not None:
            seen.append((tg.vm.status, tg.motion_done(), tg.fault))
        return sup.done

    bench.system.executive.run(watch, 10**7)
    summary = bench.system.finish()
    bad_line = FIRST_LINE + 2
    # found ahead of the robot (look-ahead), reported only when the robot has done the rest
    first_error = next(i for i, (status, _done, _fault) in enumerate(seen) if status == VMStatus.ERROR)
    assert not seen[first_error][1] and seen[first_error][2] is None
    assert summary["fault"].startswith(f"Move Robot: program error at line {bad_line}: "), summary["fault"]
    assert reason in summary["fault"]
    moves = summary["moves"]
    assert [m["line"] for m in moves] == [FIRST_LINE, FIRST_LINE + 1]
    for m in moves:
        assert m["actual_duration"] is not None
        assert m["actual_duration"] == pytest.approx(m["planned_duration"], abs=2 * H)
    assert not moves[1]["blended"]  # its approx had nothing to blend into: it stops at its target
    assert moves[1]["actual_duration"] > 0.2
    assert tg.motion.positions == pytest.approx((0, -30, 30, 0, 45, 0), abs=1e-9)  # commanded: there
    # the fault stops the robot at once: it is there within the following error
    limit = SPEC.controller.following_error_limit
    assert summary["final_position"] == pytest.approx((0, -30, 30, 0, 45, 0), abs=0.1 * limit)
    ended = records(bench)[-1].t_end
    (state,) = [s for s in summary["states"] if s["name"] == MOVE]
    assert state["t_exit"] >= ended


# ---- 6. pause and abort inside a blend ---------------------------------------------------------------

# long overlaps (acc_ptp 0.4: the superposed accelerations stay within the axis limits, so
# the overlaps are not halved), so that a pause at the start of one ends inside it
PAUSE_TOUR = ptp(P0) + "".join(ptp(t, speed_ptp=0.8, acc_ptp=0.4, approx=1) for t in TOUR[:3]) + ptp(P0)
PAUSE_SEED = 7


def timeline_path(segments):
    """The reference run's commanded path as a function of timeline time: the segments'
    joint trajectories superposed (each from its start on the timeline; a finished one
    contributes its whole displacement): ``p(tm) = start + sum_i (q_i(tm - s_i) - q_i(0))``."""
    segs = sorted(segments, key=lambda s: s.start)
    base = np.array(segs[0].trajectory.sample(0.0)[0], dtype=float)
    plan = [(s.start, s.trajectory, np.array(s.trajectory.sample(0.0)[0], dtype=float)) for s in segs]

    def at(tm: float) -> np.ndarray:
        p = base.copy()
        for start, trajectory, origin in plan:
            if tm > start:
                p += np.array(trajectory.sample(tm - start)[0], dtype=float) - origin
        return p

    return at


@pytest.fixture(scope="module")
def reference():
    """The pause tour run without interruption on a robot of its own (deterministic: the
    paused runs below use another robot with the same seed)."""
    ref = Bench(seed=PAUSE_SEED)
    program = build(PAUSE_TOUR)
    summary = ref.run(program)
    assert summary["fault"] is None
    assert [m["blended"] for m in summary["moves"]] == [False, True, True, True, False]
    path = timeline_path(ref.segments.values())
    for _t, tm, p, _v in ref.rows:  # the superposition reproduces the run's own setpoints
        assert np.max(np.abs(path(tm) - np.array(p))) <= 1e-9
    return {"program": program, "summary": summary, "rows": list(ref.rows), "path": path,
            "final": ref.tg.motion.positions}


def in_blend(tg) -> bool:
    segs = tg.motion._segments
    return (len(segs) >= 2 and segs[0].start is not None and segs[1].start is not None
            and tg.motion.t_move > segs[1].start)


def into_first_blend(reference) -> Bench:
    paused = Bench(seed=PAUSE_SEED)
    paused.begin(reference["program"])
    paused.to_move()
    tg = paused.tg
    paused.tick_until(lambda: in_blend(tg))
    assert [s.request.line for s in list(tg.motion._segments)[:2]] == [FIRST_LINE + 1, FIRST_LINE + 2]
    # identical to the reference run so far
    n = len(paused.rows)
    assert paused.rows == reference["rows"][:n]
    return paused


def test_pause_inside_a_blend_stops_on_the_blended_path_and_resume_continues_on_it(reference):
    paused = into_first_blend(reference)
    tg, ex, path = paused.tg, paused.system.executive, reference["path"]
    first, second = tg.motion._segments[0], tg.motion._segments[1]
    assert tg.pause() and tg.paused
    k0 = len(paused.rows)
    paused.tick_until(lambda: tg.motion.rate == 0.0 and all(v == 0.0 for v in tg.motion.velocities), 10**5)
    # at rest inside the blend, on the timeline: both moves are still there
    assert list(tg.motion._segments)[:2] == [first, second] and tg.motion.interrupted is None and tg.trajectory is not None
    assert tg.motion.t_move < first.start + first.duration
    stopping = paused.rows[k0:]
    assert len(stopping) > 20
    for _t, tm, p, _v in stopping:  # every setpoint of the stop on the path the unpaused run takes
        assert np.max(np.abs(np.array(p) - path(tm))) <= 1e-6, tm
    tms = [r[1] for r in stopping]
    assert all(b >= a for a, b in zip(tms, tms[1:]))  # the timeline slows down, never back
    assert max(limit_ratios(np.array([r[2] for r in paused.rows[k0 - 3:]]))) <= RATIO_OK
    # held: nothing moves while paused
    held = tg.motion.positions
    ex.run(lambda: False, 500)
    assert tg.motion.positions == held and tg.paused and tg.line == FIRST_LINE + 1
    assert within_counts(paused.system.robot.positions, held, 10)
    k1 = len(paused.rows)
    assert tg.resume() and not tg.paused
    summary = paused.finish()
    assert summary["fault"] is None
    for _t, tm, p, _v in paused.rows[k1:]:  # speeds up again on the same path, to the end
        assert np.max(np.abs(np.array(p) - path(tm))) <= 1e-6, tm
    ref = reference["summary"]
    assert [(m["line"], m["blended"]) for m in summary["moves"]] == [(m["line"], m["blended"]) for m in ref["moves"]]
    assert tg.motion.positions == pytest.approx(reference["final"], abs=1e-9)
    assert within_counts(summary["final_position"], P0)


def test_abort_inside_a_blend_comes_to_rest_on_the_path_then_faults(reference):
    aborted = into_first_blend(reference)
    tg, path = aborted.tg, reference["path"]
    line = tg.motion._segments[0].request.line  # the move under way (the one the robot is finishing)
    k0 = len(aborted.rows)
    active = []  # moves under way before each tick, until the motion is cleared

    def watch():
        if tg.vm is not None and tg.motion._segments:
            active.append(sum(1 for s in tg.motion._segments if s.start is not None and tg.motion.t_move > s.start))
        return tg.motion_done()

    assert tg.abort()
    assert tg.fault is None  # not yet: it stops first
    aborted.tick_until(watch, 10**5)
    assert active and active[-1] == 2  # it came to rest inside the blend
    rows = aborted.rows[k0:]
    assert len(rows) > 20
    for _t, tm, p, _v in rows:
        assert np.max(np.abs(np.array(p) - path(tm))) <= 1e-6, tm
    assert all(v == 0.0 for v in tg.motion.velocities)
    summary = aborted.finish()
    assert summary["fault"] == f"Move Robot: aborted by the operator at line {line}"
    assert line == FIRST_LINE + 1
    assert len(summary["moves"]) == 3 and summary["moves"][-1]["actual_duration"] is None


# ---- 7. the VM's side: run on while there is room, and wait for the robot where it must be -----------

class QueueHost:
    """A motion host with a look-ahead queue: ``ready`` answers queue_ready(), ``done``
    answers motion_done(); moves, log, inputs and outputs are recorded."""

    def __init__(self, ready: bool = True, done: bool = False, inputs=None):
        self.t = 0.0
        self.ready = ready
        self.done = done
        self.moves: list[tuple] = []
        self.log_lines: list[tuple[int, str]] = []
        self.outputs: list[tuple[int, bool]] = []
        self.inputs = dict(inputs or {})
        self.input_reads = 0
        self.motion_asks = 0

    def now(self) -> float:
        return self.t

    room: int | None = None  # when set: places left in the queue (a move takes one)

    def move(self, kind, targets, clauses, line, tag=0):
        self.moves.append((kind, targets, clauses, line))
        if self.room is not None:
            self.room -= 1
        return None

    def motion_done(self) -> bool:
        self.motion_asks += 1
        return self.done

    def queue_ready(self) -> bool:
        return self.ready if self.room is None else self.room > 0

    def read_input(self, n):
        self.input_reads += 1
        return self.inputs.get(n, False)

    def write_output(self, n, value):
        self.outputs.append((n, value))

    def log(self, text, line, kind="print"):
        self.log_lines.append((line, text))


class NoQueueHost(QueueHost):
    """The older interface: no queue_ready; a move keeps the robot busy until ``done``."""

    def __getattribute__(self, name):
        if name == "queue_ready":
            raise AttributeError(name)
        return super().__getattribute__(name)

    def move(self, kind, targets, clauses, line, tag=0):
        self.done = False
        return super().move(kind, targets, clauses, line, tag)


def vm_program(tmp_path: Path, body: str, decls: str = "") -> tuple[Program, str]:
    shutil.copy(SPEC_PATH, tmp_path / "lola15.spc")
    text = source(body, decls, name="p")
    result = compile_source(text, str(tmp_path / "p.irl"))
    assert result.ok, result.diagnostics
    verify(result.program)
    return result.program, text


def line_of(text: str, marker: str) -> int:
    return next(n for n, line in enumerate(text.splitlines(), 1) if marker in line)


MOVES3 = ptp((10, 0, 0, 0, 0, 0)) + ptp((20, 0, 0, 0, 0, 0)) + ptp((30, 0, 0, 0, 0, 0))


@pytest.fixture(params=["inline", "table"])
def dispatch(request):
    return request.param


def test_the_vm_runs_on_after_a_move_while_the_queue_has_room(tmp_path, dispatch):
    program, _ = vm_program(tmp_path, MOVES3 + "  x := 1;\n", "var x : integer;\n")
    host = QueueHost(ready=True, done=False)
    machine = VM(program, host, dispatch=dispatch)
    assert machine.step() == VMStatus.DONE  # the robot has not moved yet: END needs no wait
    assert len(host.moves) == 3 and machine.moves_issued == 3 and machine.globals == [1]


def test_the_vm_waits_after_a_move_while_the_queue_is_full(tmp_path, dispatch):
    program, text = vm_program(tmp_path, MOVES3)
    host = QueueHost(ready=False, done=False)
    machine = VM(program, host, dispatch=dispatch)
    assert machine.step() == VMStatus.WAITING
    assert len(host.moves) == 1
    for _ in range(5):
        assert machine.step() == VMStatus.WAITING
    assert len(host.moves) == 1  # never more than the queue lets through
    host.ready = True
    assert machine.step() == VMStatus.DONE
    first = line_of(text, "mainjoint(10,")
    assert [m[3] for m in host.moves] == [first, first + 1, first + 2]


def test_the_vm_hands_over_one_move_per_free_place(tmp_path, dispatch):
    program, _ = vm_program(tmp_path, MOVES3)
    host = QueueHost(done=False)
    host.room = 1
    machine = VM(program, host, dispatch=dispatch)
    counts = []
    for freed in (0, 1, 0, 0, 1):
        host.room += freed  # the robot started a move: a place is free
        status = machine.step()
        counts.append(len(host.moves))
    assert counts == [1, 2, 2, 2, 3] and status == VMStatus.WAITING  # even after the last move
    host.room += 1
    assert machine.step() == VMStatus.DONE and len(host.moves) == 3


ROBOT_STATEMENTS = {
    "print": ('  print "n=", 1 + x;\n', "var x : integer;\n"),
    "out": ("  out[x + 1] := x = 0;\n", "var x : integer;\n"),
    "in": ("  b := in[x + 2];\n  print b;\n", "var x : integer;\n    b : bool;\n"),
    "wait for": ("  wait for in[x + 3];\n  print \"went\";\n", "var x : integer;\n"),
}


@pytest.mark.parametrize("kind", sorted(ROBOT_STATEMENTS))
def test_statements_where_the_robot_is_wait_for_the_motion_then_run_once(tmp_path, dispatch, kind):
    statement, decls = ROBOT_STATEMENTS[kind]
    program, text = vm_program(tmp_path, MOVES3 + statement + '  print "end";\n', decls)
    host = QueueHost(ready=True, done=False, inputs={2: True, 3: True})
    machine = VM(program, host, dispatch=dispatch)
    stacks = []
    for _ in range(4):
        assert machine.step() == VMStatus.WAITING
        assert len(host.moves) == 3  # the moves went ahead (look-ahead) ...
        # ... but the statement has not run: nothing logged, written or read
        assert host.log_lines == [] and host.outputs == [] and host.input_reads == 0
        stacks.append(list(machine.stack))
    assert all(s == stacks[0] for s in stacks)  # its operands wait on the stack, untouched
    host.done = True
    assert machine.step() == VMStatus.DONE
    assert machine.stack == []
    texts = [t for _, t in host.log_lines]
    assert texts[-1] == "end"
    if kind == "print":
        assert host.log_lines[0] == (line_of(text, 'print "n="'), "n=1") and len(texts) == 2
    elif kind == "out":
        assert host.outputs == [(1, True)]
    elif kind == "in":
        assert host.input_reads == 1 and texts == ["true", "end"]
    else:
        assert host.input_reads == 1 and texts == ["went", "end"]


def test_a_wait_for_time_out_counts_from_when_the_robot_arrived(tmp_path, dispatch):
    program, text = vm_program(tmp_path, MOVES3 + "  wait for in[5] timeout 2 sec;\n  print \"on\";\n")
    host = QueueHost(ready=True, done=False)
    machine = VM(program, host, dispatch=dispatch)
    host.t = 0.0
    assert machine.step() == VMStatus.WAITING
    host.t = 10.0  # still moving long after the time-out would have passed
    assert machine.step() == VMStatus.WAITING and host.log_lines == []
    host.done = True
    assert machine.step() == VMStatus.WAITING  # the wait starts now: until 12.0
    host.t = 11.9
    assert machine.step() == VMStatus.WAITING and host.log_lines == []
    host.t = 12.0
    assert machine.step() == VMStatus.DONE
    assert [t for _, t in host.log_lines] == ["wait for timed out after 2 s", "on"]


def test_a_pause_statement_waits_for_the_robot(tmp_path, dispatch):
    program, _ = vm_program(tmp_path, MOVES3 + "  pause;\n  print \"after\";\n")
    host = QueueHost(ready=True, done=False)
    machine = VM(program, host, dispatch=dispatch)
    assert machine.step() == VMStatus.WAITING
    assert not machine.paused and host.log_lines == []
    host.done = True
    assert machine.step() == VMStatus.WAITING and machine.paused
    assert len(host.log_lines) == 1 and "paused" in host.log_lines[0][1]
    machine.resume()
    assert machine.step() == VMStatus.DONE
    assert [t for _, t in host.log_lines][-1] == "after"


def test_a_host_without_queue_ready_gets_one_move_at_a_time(tmp_path, dispatch):
    program, _ = vm_program(tmp_path, MOVES3 + '  print "end";\n')
    host = NoQueueHost(ready=True, done=True)
    assert not hasattr(host, "queue_ready")
    machine = VM(program, host, dispatch=dispatch)
    counts = []
    for _ in range(3):
        assert machine.step() == VMStatus.WAITING  # waits for the motion after each move
        assert machine.step() == VMStatus.WAITING
        counts.append(len(host.moves))
        host.done = True
    assert counts == [1, 2, 3]
    assert machine.step() == VMStatus.DONE
    assert host.log_lines[-1][1] == "end"
