"""The rules of the real-time loop, enforced (not only documented): nothing that runs in a
tick opens a file, creates a thread or process, sleeps, touches a socket, or builds the
robot's kinematics.

A Python audit hook (sys.addaudithook; it cannot be removed, so it only records while a
flag is set) watches every task the executive runs, through whole cycles of programs that
exercise homing, PTP, lin, circ and blended moves, prints, pauses, aborts, emergency
stops, faults, the report writer, the recording and the calibration file, on the simulated clock and on
the wall clock (where moves are planned on the planner thread).
"""
from __future__ import annotations

import sys
import threading

import pytest

import limits_watch
from compiler.driver import compile_source
from runtime.loop.system import RobotSystem, RunOptions

from conftest import ROOT, SPEC_PATH, SPEC
from test_zones import ZONES  # (a forbidden box and cylinder, clear of these moves)

#: Audit events that must never happen inside a tick (prefixes).
FORBIDDEN = ("open", "os.", "socket.", "subprocess.", "_thread.start_new_thread", "time.sleep", "shutil.",
             "fcntl.", "pty.", "mmap.", "sqlite3.", "urllib.", "http.", "ftplib.", "smtplib.", "ctypes.",
             "irl.kinematics")  # (the robot's kinematics: tables and a solver, built before the loop)

_state = threading.local()
_seen: list[tuple[str, str]] = []


def _hook(event: str, args) -> None:
    if getattr(_state, "task", None) is not None and event.startswith(FORBIDDEN):
        _seen.append((_state.task, event))


sys.addaudithook(_hook)


@pytest.fixture(autouse=True)
def _thread_starts(monkeypatch):
    """Python 3.11 has no audit event for a new thread or a sleep: watch Thread.start,
    _thread.start_new_thread and time.sleep themselves (for this module's tests only); and
    the building of a robot's kinematics (``irl.kinematics``)."""
    import _thread
    import time

    from runtime.motion.kinematics import Kinematics

    build = Kinematics.__init__

    def watched_build(self, *args, **kwargs):
        _hook("irl.kinematics", ())
        return build(self, *args, **kwargs)
    monkeypatch.setattr(Kinematics, "__init__", watched_build)

    start, start_new, sleep = threading.Thread.start, _thread.start_new_thread, time.sleep

    def watched_sleep(seconds):
        _hook("time.sleep", (seconds,))
        return sleep(seconds)

    def watched_start(self, *args, **kwargs):
        _hook("_thread.start_new_thread", (self.name,))
        return start(self, *args, **kwargs)

    def watched_start_new(*args, **kwargs):
        _hook("_thread.start_new_thread", args[:1])
        return start_new(*args, **kwargs)
    monkeypatch.setattr(threading.Thread, "start", watched_start)
    monkeypatch.setattr(_thread, "start_new_thread", watched_start_new)
    monkeypatch.setattr(time, "sleep", watched_sleep)


def watch_tasks(system: RobotSystem) -> list:
    """Wrap every task of the system's executive so the hook knows it runs in a tick."""
    for task in system.executive.tasks:
        run = task.run

        def watched(now, run=run, name=task.name):
            _state.task = name
            try:
                run(now)
            finally:
                _state.task = None
        task.run = watched
    _seen.clear()
    return _seen


def program(body: str, decls: str = "") -> object:
    text = f'program rt;\nsystem_specification "{SPEC_PATH}";\n{decls}seq\n{body}endseq\nendprogram;\n'
    result = compile_source(text, "rt.irl", SPEC_PATH)
    assert result.ok, result.diagnostics
    return result.program


MOVES = program(
    '  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0)) speed_ptp := 0.5 acc_ptp := 0.5;\n'
    '  move ptp joint(mainjoint(20, -20, 30, 10, 50, 0)) approx := 0.5;\n'
    '  move ptp joint(mainjoint(-10, -30, 40, 0, 60, 10));\n'
    '  move lin pose(pos(900, 0, 700), rpy(180, 0, 180)) speed := 300 approx := 20;\n'
    '  move lin pose(pos(900, 200, 700), rpy(180, 0, 180)) speed := 300;\n'
    '  move circ pose(pos(1000, 100, 700), rpy(180, 0, 180)), pose(pos(900, 0, 700), rpy(180, 0, 180));\n'
    '  print "done ", 3;\n'
    '  out[2] := true;\n')


def run_cycle(system: RobotSystem, prog, ticks: int, during=None) -> dict:
    return limits_watch.run_cycle(system, prog, ticks, during, report=system.options.report,
                                  record=system.options.record)


def test_no_io_threads_or_sleeps_in_a_tick_on_the_simulated_clock(tmp_path):
    system = RobotSystem(SPEC, RunOptions(state_dir=tmp_path / "state", report=tmp_path / "r.csv",
                                          record=tmp_path / "r.mcap"))
    seen = watch_tasks(system)
    summary = run_cycle(system, MOVES, 200_000)
    assert summary["fault"] is None and summary["files_error"] is None, summary
    assert (tmp_path / "state" / "calibration.json").exists()  # written (off the loop) all the same
    assert (tmp_path / "r.csv").stat().st_size > 0 and (tmp_path / "r.states.csv").stat().st_size > 0
    assert (tmp_path / "r.mcap").stat().st_size > 0  # (the recording's rows made in the ticks, written off them)
    assert seen == [], seen[:10]

    def operator(system, k):  # pause, resume, then an emergency stop in the middle of a move
        tg = system.trajectory
        if k == 2000:
            tg.pause()
        elif k == 3000:
            tg.resume()
        elif k == 4000:
            system.emergency_stop()
    run_cycle(system, MOVES, 200_000, operator)
    assert seen == [], seen[:10]

    system.backend.inject("encoder_frozen", 2)  # a safety stop of category 0, then the next cycle
    summary = run_cycle(system, MOVES, 200_000)
    assert summary["stop"]["category"] == 0
    assert seen == [], seen[:10]


def test_no_io_threads_or_sleeps_in_a_tick_with_zones_a_search_and_the_cells_sensors(tmp_path):
    """The production cell's language in the tick: a forbidden and a signal zone (the safety
    supervisor's and the io component's checks), a search move stopped by a touch sensor
    (the cell's [[contact]] rule, the trajectory generator's watch and the motion's cut),
    group and analog outputs."""
    from compiler.spec import load_spec
    from runtime.hardware.sim.cell import parse_scenario

    spec_file = tmp_path / "rt.spc"
    spec_file.write_text(SPEC_PATH.read_text(encoding="utf-8") + ZONES + """
[[analog_output]]
name = "pressure"
min = 0
max = 6

[[zone]]
name = "above"
shape = "cylinder"
kind = "signal"
output = 6
centre = [600, -500]
radius = 100
z = [0, 2000]
""", encoding="utf-8")
    spec = load_spec(spec_file)
    text = (f'program rt;\nsystem_specification "{spec_file}";\nvar p : pose;\nseq\n'
            '  move ptp pose(pos(600, -500, 450), rpy(180, 0, 180));\n'
            '  move lin pose(pos(600, -500, 300), rpy(180, 0, 180)) search := 7 speed := 100;\n'
            '  p := search_pose();\n'
            '  call group_out(1, 4, 9);\n'
            '  call analog_out(1, 2.5);\n'
            '  move lin p + pos(0, 0, 100);\n'
            'endseq\nendprogram;\n')
    result = compile_source(text, "rt.irl", spec_file)
    assert result.ok, result.diagnostics
    scenario = parse_scenario({"contact": [{"input": 7, "z": 350.0}]}, spec)
    system = RobotSystem(spec, RunOptions(cell=scenario))
    seen = watch_tasks(system)
    summary = run_cycle(system, result.program, 200_000)
    assert summary["fault"] is None, summary["fault"]
    assert [m["line"] for m in summary["moves"]] == [5, 6, 10]
    assert system.io.output(6) and system.io.output(1) and system.io.output(4)  # (the signal zone; 9 = 0b1001)
    assert seen == [], seen[:10]


def test_no_io_threads_or_sleeps_in_a_tick_in_step_mode_from_a_line(tmp_path):
    """Step mode and a start from a line (runtime/loop/stepping.py): the run to line 8 without
    moving, the approach, and the moves held for steps given between ticks, as the loop's
    step command does."""
    system = RobotSystem(SPEC, RunOptions(state_dir=tmp_path / "state"))
    memory = system.memory
    memory.calibrated = memory.initialized = True  # homed already: only the moves
    memory.compensation = [0.0] * len(SPEC.axes)
    memory.encoder_offsets = [0.0] * len(SPEC.axes)
    seen = watch_tasks(system)
    system.begin(MOVES, step=True, from_line=8)  # (line 8: the second lin move)
    steps = 0
    for _ in range(100_000):
        if system.supervisor.done:
            break
        system.executive.step()
        if system.trajectory.waiting_for_step:
            steps += system.trajectory.step() is None
    summary = system.finish()
    assert summary["fault"] is None and [m["line"] for m in summary["moves"]] == [8, 9], summary["fault"]
    assert steps == 3  # the approach, then the two moves
    assert seen == [], seen[:10]


def test_no_io_threads_or_sleeps_in_a_tick_on_the_wall_clock(tmp_path):
    """On the wall clock moves are planned on the planner thread, made before the loop."""
    quick = program('  move ptp joint(mainjoint(2, 0, 0, 0, 0, 0)) speed_ptp := 1 acc_ptp := 1;\n'
                    '  move lin pose(pos(1145, 0, 1385), rpy(180, -90, 0)) speed := 100;\n')
    system = RobotSystem(SPEC, RunOptions(realtime=True, state_dir=tmp_path / "state"))
    system.memory.calibrated = True  # skip calibration and homing: a short wall-clock run
    system.memory.compensation = [0.0] * len(SPEC.axes)
    system.memory.initialized = True
    system.memory.encoder_offsets = [0.0] * len(SPEC.axes)
    seen = watch_tasks(system)
    summary = run_cycle(system, quick, 20_000)
    assert seen == [], seen[:10]  # (a thread started in a tick would be there too)
    assert len(summary["moves"]) == 2 or summary["fault"], summary
    assert any(t.name == "irl-plan" for t in threading.enumerate())  # planned off the loop


@pytest.mark.parametrize("event", ["open", "os.remove", "socket.connect", "_thread.start_new_thread", "time.sleep",
                                   "irl.kinematics"])
def test_the_watch_itself_catches_each_kind_of_event(event, tmp_path):
    """The watch is not blind: a task that does one of the forbidden things is caught."""
    import os
    import socket
    import time

    from runtime.motion.kinematics import Kinematics

    system = RobotSystem(SPEC, RunOptions())
    actions = {
        "open": lambda: open(tmp_path / "x", "w").close(),
        "os.remove": lambda: (open(tmp_path / "y", "w").close(), os.remove(tmp_path / "y")),
        "socket.connect": lambda: socket.socket().connect_ex(("127.0.0.1", 9)),
        "_thread.start_new_thread": lambda: threading.Thread(target=lambda: None).start(),
        "time.sleep": lambda: time.sleep(0),
        "irl.kinematics": lambda: Kinematics(SPEC),
    }
    system.executive.add("bad", lambda now: actions[event](), 0.001, "record")
    seen = watch_tasks(system)
    system.executive.step()
    assert any(name == "bad" and e.startswith(event) for name, e in seen), seen


@pytest.mark.long
def test_the_rules_hold_in_a_fresh_interpreter():
    """Run this file's tests again in an interpreter that has imported only what they
    import: in the whole suite, a module that an earlier test imported hides a lazy
    import inside a tick (numpy.ma, imported by np.unique's first call, read files in the
    first lin move's tick, and this file passed in the suite and failed alone)."""
    import subprocess

    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", __file__, "-k",
                           "not fresh_interpreter"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
