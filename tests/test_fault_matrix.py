"""Issue 13, "How we will know": the fault matrix.

Every fault the simulated arm can inject (``runtime.hardware.sim.robot.FAULTS``) x every phase of a
cycle (Calibrate Offsets; the homing steps Find Sensors, Find Index, Go To Start; Move
Robot during a move; an operator pause) x two axes (A2, a main axis, and A5, a wrist
axis). Each cell runs a fresh ``RobotSystem`` (seed 0, simulated clock) from power-up with
a program that moves both axes in both its moves, injects the fault a few ms after the
phase is entered, and lets the cycle run to its end (a pause is resumed 0.5 s after the
fault). The expected outcome of every cell is written down in EXPECTED below; each cell
asserts it: completed or faulted, the fault naming the axis, the part and where it was
found, the stop category that runtime/loop/components/safety.py CATEGORIES documents for the
cause, no limit exceeded (``tests/limits_watch.py``, which reads the arm's true positions
and the drives' real commands), and the arm at rest with brakes applied and torque off at
the end.

When is "the phase entered": Calibrate Offsets, Go To Start, when the supervisor (or the
homing sub-machine) enters it; Find Sensors and Find Index, when the step of the faulty
axis begins (the homing takes the axes one after another: a fault in another axis's step
would only be found when this axis's turn comes); Move Robot, 0.2 s into the first move;
the pause, once the operator's pause (``trajectory.pause()``, 0.5 s into the first move)
has brought the arm to rest (the safety supervisor monitors its standstill).
"""
from __future__ import annotations

from dataclasses import dataclass

import pytest

from compiler.driver import compile_source
from limits_watch import LimitWatch, at_rest_and_safe
from runtime.loop.components.safety import CATEGORIES
from runtime.hardware.sim.robot import FAULTS
from runtime.loop.supervisor import CALIBRATE, INITIALIZE, MOVE, STOP
from runtime.loop.system import RobotSystem, RunOptions

from conftest import SPEC_PATH, SPEC
AXES = [a.name for a in SPEC.axes]

#: How far (deg or mm) beyond a software limit an axis may come when the safety stops it:
#: the stopping tolerance that docs/safety.md documents.
STOP_TOLERANCE = 0.5
SEED = 0
#: The faulty axes: a main axis and a wrist axis.
FAULTY_AXES = ("A2", "A5")
#: Both moves move every axis, A2 and A5 among them (slowly: the faults land mid-move).
TARGETS = ((30, -30, 30, 0, 40, 0), (-30, 20, -20, 0, -40, 0))
BODY = "".join(f"  move ptp joint(mainjoint({', '.join(map(str, t))})) speed_ptp := 0.1 acc_ptp := 0.2;\n"
               for t in TARGETS)
PHASES = ("Calibrate Offsets", "Find Sensors", "Find Index", "Go To Start", "Move Robot", "Paused")
INJECT_AFTER = 0.005  # s after the phase is entered (Move Robot: MOVE_INJECT_AFTER)
MOVE_INJECT_AFTER = 0.2  # s into the first move
PAUSE_AFTER = 0.5  # s into the first move: the operator pauses
RESUME_AFTER = 0.5  # s after the fault: the operator resumes
MAX_TICKS = 120_000  # 2 simulated minutes at most per cell


@dataclass(frozen=True)
class Expect:
    """One cell's expected outcome. ``cause``: a key of CATEGORIES (the category follows
    from it), None when the program completes. ``where``: what the fault's text says of
    where the fault was found; ``words``: what else it must say ({axis}: the faulty
    axis). ``why``: the reason, as a safety engineer would give it."""

    cause: str | None
    where: str = ""
    words: tuple[str, ...] = ()
    why: str = ""


def _encoder(where: str, part: str, why: str) -> Expect:
    return Expect("encoder", where, ("{axis}", part, "without a single encoder count"), why)


FOUND_AT_SEARCH = "Initialization Sequence/Find Sensors (sensor {axis})"
FOUND_AT_INDEX = "Initialization Sequence/Find Index (index {axis})"
FOUND_GOING_TO_START = "Initialization Sequence/Go To Start (start position)"
FOUND_MOVING = "Move Robot: safety: "

#: (phase, fault) -> the expected outcome, the same for A2 and A5. In short ("found in": the
#: step the fault text names; "encoder, 0": the safety's encoder plausibility check,
#: category 0; "fault, 1": a component's fault, category 1):
#:
#: | phase             | sensor_dead                   | encoder_frozen             | drive_dead                 |
#: |-------------------|-------------------------------|----------------------------|----------------------------|
#: | Calibrate Offsets | faulted: homing sensor not    | faulted, found in the      | faulted, found in the      |
#: |                   | found, fault, 1, before the   | axis's sensor search:      | axis's sensor search:      |
#: |                   | end stop (*)                  | encoder, 0                 | encoder, 0                 |
#: | Find Sensors      | the same (*)                  | faulted there: encoder, 0  | faulted there: encoder, 0  |
#: | Find Index        | completes (sensor not used)   | faulted there: encoder, 0  | faulted there: encoder, 0  |
#: | Go To Start       | completes (sensor not used)   | faulted there: encoder, 0  | faulted there: encoder, 0  |
#: | Move Robot        | completes (sensor not used)   | faulted there: encoder, 0  | faulted there: encoder, 0  |
#: | Paused            | completes (sensor not used)   | faulted after the resume:  | faulted after the resume:  |
#: |                   |                               | encoder, 0                 | encoder, 0                 |
#:
#: (*) A violation found here (below): on d62cba7 the axis ran into its mechanical end stop
#: first; fixed by 467842e.
EXPECTED: dict[tuple[str, str], Expect] = {
    # ---- Calibrate Offsets: nothing moves yet; the fault is found by the homing that follows
    # A VIOLATION FOUND HERE (on d62cba7; fixed by 467842e): the search for a sensor that
    # never fires ran over the whole axis travel (max - min) while the axis was not
    # referenced (no position limits yet) and drove the axis into its mechanical end stop
    # (5 deg beyond the software limit) at the search velocity; only then did the encoder
    # check see a blocked axis (category 0, "encoder frozen, drive not responding, or the
    # axis blocked"). Reproduction: irl run programs/test.irl --inject sensor_dead:A2 (the
    # same with any axis): 29 simulated s, A2 at its end stop.
    ("Calibrate Offsets", "sensor_dead"): Expect(
        "fault", FOUND_AT_SEARCH, ("homing sensor of {axis}", "not found"),
        "the homing needs the sensor: its search must give up within a bounded distance, before the axis's end "
        "stop, with a homing fault (category 1)"),
    ("Calibrate Offsets", "encoder_frozen"): _encoder(
        FOUND_AT_SEARCH, "encoder frozen",
        "calibration measures no drift on the frozen axis (that is all it sees); the axis's homing search is "
        "the first command that moves it: no counts"),
    ("Calibrate Offsets", "drive_dead"): _encoder(
        FOUND_AT_SEARCH, "drive not responding",
        "a dead drive does not drift: calibration finds nothing; the homing search moves nothing: no counts"),
    # ---- Find Sensors: the axis is searching for its sensor
    # A VIOLATION FOUND HERE (fixed by 467842e): as above, the axis ran into its end stop.
    ("Find Sensors", "sensor_dead"): Expect(
        "fault", FOUND_AT_SEARCH, ("homing sensor of {axis}", "not found"),
        "the sensor goes dark before the axis reached it: the search must end before the end stop, with a "
        "homing fault (category 1)"),
    ("Find Sensors", "encoder_frozen"): _encoder(FOUND_AT_SEARCH, "encoder frozen",
                                                 "the searching axis's counts stop: found within 0.1 deg"),
    ("Find Sensors", "drive_dead"): _encoder(FOUND_AT_SEARCH, "drive not responding",
                                             "the searching axis stops: no counts within 0.1 deg of command"),
    # ---- Find Index: the axis's sensor was found; it searches for the index pulse
    ("Find Index", "sensor_dead"): Expect(
        None, why="the axis's sensor was found already: nothing reads it again in this cycle"),
    ("Find Index", "encoder_frozen"): _encoder(FOUND_AT_INDEX, "encoder frozen",
                                               "the searching axis's counts stop (and the index is not latched)"),
    ("Find Index", "drive_dead"): _encoder(FOUND_AT_INDEX, "drive not responding",
                                           "the searching axis stops: no counts"),
    # ---- Go To Start: every axis referenced, moving to the start position
    ("Go To Start", "sensor_dead"): Expect(None, why="homing has used the sensors: they are not needed any more"),
    ("Go To Start", "encoder_frozen"): _encoder(FOUND_GOING_TO_START, "encoder frozen",
                                                "the axis is commanded to the start position: no counts"),
    ("Go To Start", "drive_dead"): _encoder(FOUND_GOING_TO_START, "drive not responding",
                                            "the axis is commanded to the start position and does not move"),
    # ---- Move Robot, during the first move
    ("Move Robot", "sensor_dead"): Expect(None, why="the sensors are used only by homing"),
    ("Move Robot", "encoder_frozen"): _encoder(FOUND_MOVING, "encoder frozen",
                                               "the moving axis's counts stop: found within 0.1 deg"),
    ("Move Robot", "drive_dead"): _encoder(FOUND_MOVING, "drive not responding",
                                           "the moving axis coasts to rest: no counts while commanded"),
    # ---- an operator pause: at rest, drives powered (category 2), standstill monitored
    ("Paused", "sensor_dead"): Expect(None, why="the sensors are used only by homing"),
    ("Paused", "encoder_frozen"): _encoder(
        FOUND_MOVING, "encoder frozen",
        "at rest a frozen encoder looks like standstill (no false alarm); the first command after resume finds it"),
    ("Paused", "drive_dead"): _encoder(
        FOUND_MOVING, "drive not responding",
        "a dead drive at rest (no gravity in the simulation) stays put; the first command after resume finds it"),
}
assert set(EXPECTED) == {(p, f) for p in PHASES for f in FAULTS}, "a cell of the matrix has no expected outcome"


def _program():
    text = f'program fault_matrix;\nsystem_specification "{SPEC_PATH}";\nseq\n{BODY}endseq\nendprogram;\n'
    result = compile_source(text, "fault_matrix.irl", SPEC_PATH)
    assert result.ok, result.diagnostics
    return result.program


PROGRAM = _program()


def run_cell(phase: str, fault: str, axis: str):
    """Power-up to Stop Robot with ``fault`` injected on ``axis`` in ``phase``. Returns the
    summary, the watch, the system, when the fault was injected and when the pause was
    resumed (or None)."""
    system = RobotSystem(SPEC, RunOptions(seed=SEED))
    watch = LimitWatch(system)
    index = AXES.index(axis)
    sup, init, trajectory = system.supervisor, system.init, system.trajectory
    system.begin(PROGRAM, None)
    entered = injected = paused_at = resumed = None
    for _ in range(MAX_TICKS):
        if sup.done:
            break
        now = system.clock.now()
        state = sup.fsm.state
        if injected is None:
            if entered is None:
                if (phase == "Calibrate Offsets" and state == CALIBRATE
                        or phase == "Find Sensors" and state == INITIALIZE and init.step_name == f"sensor {axis}"
                        or phase == "Find Index" and state == INITIALIZE and init.step_name == f"index {axis}"
                        or phase == "Go To Start" and state == INITIALIZE and sup.fsm.path().endswith("Go To Start")):
                    entered = now + INJECT_AFTER
                elif phase == "Move Robot" and state == MOVE:
                    entered = now + MOVE_INJECT_AFTER
                elif phase == "Paused" and state == MOVE:
                    if paused_at is None:
                        paused_at = now + PAUSE_AFTER
                    elif now >= paused_at - 1e-9 and not trajectory.paused:
                        assert trajectory.pause(), "the operator's pause was refused"
                    elif trajectory.paused and system.safety.standstill_expected:
                        entered = now + INJECT_AFTER
            if entered is not None and now >= entered - 1e-9:
                system.backend.inject(fault, index)
                injected = now
        elif phase == "Paused" and resumed is None and now >= injected + RESUME_AFTER - 1e-9:
            assert trajectory.resume(), "the operator's resume was refused"
            resumed = now
        system.executive.step()
    assert sup.done, f"the cycle did not end within {MAX_TICKS / 1000:g} simulated s"
    assert injected is not None, f"the phase {phase!r} never came"
    return system.finish(), watch, system, injected, resumed


CELLS = [pytest.param(phase, fault, axis, id=f"{phase}-{fault}-{axis}".replace(" ", "_"))
         for phase in PHASES for fault in FAULTS for axis in FAULTY_AXES]


@pytest.mark.parametrize("phase, fault, axis", CELLS)
def test_fault_matrix(phase, fault, axis):
    expect = EXPECTED[(phase, fault)]
    summary, watch, system, injected, resumed = run_cell(phase, fault, axis)
    text = summary["fault"]
    stop = summary["stop"]
    problems = []
    # the outcome as tabled
    if expect.cause is None:
        if text is not None:
            problems.append(f"expected the program to complete ({expect.why}), got the fault: {text}")
        if stop is not None:
            problems.append(f"expected no safety stop, got category {stop['category']}: {stop['reason']}")
        if system.backend.faults() != ((fault, AXES.index(axis)),):
            problems.append("the fault was not in effect")
        final = summary["final_position"]
        if any(abs(x - t) > 0.01 for x, t in zip(final, TARGETS[-1])):
            problems.append(f"completed, but not at the last target: {final}")
        if not system.memory.initialized:
            problems.append("a completed cycle forgot the homing")
    else:
        category = CATEGORIES[expect.cause][0]
        if text is None:
            problems.append(f"expected a fault ({expect.cause}, category {category}: {expect.why}); the program "
                            "completed")
        else:
            for words in (expect.where, *expect.words):
                words = words.format(axis=axis)
                if words not in text:
                    problems.append(f"the fault does not say {words!r} ({expect.why}): {text}")
            if axis not in text:
                problems.append(f"the fault does not name {axis}: {text}")
        if stop is None or stop["category"] != category:
            problems.append(f"expected stop category {category} ({expect.cause}: {CATEGORIES[expect.cause][1]}), "
                            f"got {stop}")
        if system.memory.initialized:
            problems.append("a faulted cycle left the robot 'initialized'")
        if resumed is not None:  # found after the resume, not as a false alarm while paused
            t_stop = next(s["t_enter"] for s in summary["states"] if s["name"] == STOP)
            if t_stop < resumed:
                problems.append(f"faulted at {t_stop} s, while paused (resumed at {resumed} s)")
    # no limit exceeded, whatever the outcome
    if watch.velocity_ratio > 1.0 + 1e-9:
        problems.append(f"velocity ratio {watch.velocity_ratio:.4f} ({watch.worst.get('velocity_ratio')})")
    if watch.acceleration_ratio > SPEC.safety.acceleration_factor + 1e-9:
        problems.append(f"acceleration ratio {watch.acceleration_ratio:.4f} "
                        f"({watch.worst.get('acceleration_ratio')})")
    if watch.planned_velocity_ratio > 1.0 + 1e-9 or watch.planned_acceleration_ratio > 1.0 + 1e-6:
        problems.append(f"a setpoint beyond the limits: velocity ratio {watch.planned_velocity_ratio:.4f}, "
                        f"acceleration ratio {watch.planned_acceleration_ratio:.4f} ({watch.worst})")
    if watch.beyond > STOP_TOLERANCE:
        problems.append(f"{watch.beyond:.3f} beyond a software limit ({watch.worst.get('beyond')})")
    if watch.at_end_stop:
        problems.append(f"an axis reached its mechanical end stop: true positions "
                        f"{[round(x, 3) for x in system.backend.true_positions]}, end stops "
                        f"{system.backend.end_stops}")
    # at rest at the end, whatever the outcome
    if not at_rest_and_safe(system):
        problems.append("the arm is not at rest with brakes applied and torque off")
    assert not problems, (f"{phase} x {fault} on {axis} (injected at {injected:.3f} s):\n  "
                          + "\n  ".join(problems))
