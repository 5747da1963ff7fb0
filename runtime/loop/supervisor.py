"""The supervisor: the paper's five-state FSM (its "Viewer"), stepped every 1 ms.

Start Robot -> Calibrate Offsets (if not calibrated) -> Initialization Sequence (if not
initialized; a sub-machine) -> Move Robot -> Stop Robot (final). Calibration is kept in a
state file (written atomically) across restarts; initialization only while the process
lives (incremental encoders lose their zero on power-down), and only until a cycle ends
early. Every state that waits for the world has a way out: a fault from any component,
a safety violation, a deadline fault, an operator stop or a time-out leads to Stop Robot
with the fault named. Every stop goes through the safety supervisor
(:mod:`runtime.loop.components.safety`, stop categories in docs/safety.md): Stop Robot ends
only with the robot at rest, the brakes applied and the torque off.
"""
from __future__ import annotations

import json
import math
import os
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from runtime.loop.fsm import FSM, State, Transition
from runtime.timing import BRAKE_TIMEOUT, STOP_SETTLE_TIMEOUT

START, CALIBRATE, INITIALIZE, MOVE, STOP = (
    "Start Robot", "Calibrate Offsets", "Initialization Sequence", "Move Robot", "Stop Robot")
RECONFIGURE = "Robot Reconfiguration"

CALIBRATION_SETTLE = 0.05  # s before measuring (the drives' lag)
CALIBRATION_TIME = 0.25  # s of measurement
SETTLE_TOLERANCE_COUNTS = 1.0  # encoder counts: "at rest" before the brakes go on


@dataclass
class RobotMemory:
    """What the supervisor remembers between programs in one process, and why.

    ``initialized`` is set only by a homing sequence that completed, and cleared by any
    cycle that does not end normally (a fault, an abort, an emergency stop): after those
    the encoders' zero is not trusted and the next program homes again. ``calibrated``
    is set by a calibration measured in range and then confirmed by the same cycle (its
    homing completed, or the cycle ended normally: every drive and encoder was seen to
    follow its commands; a frozen encoder or a dead drive measures a plausible zero
    drift), or by a state file that passes every check (:class:`StateFile`). The
    ``*_why`` texts say how each came to be what it is (``irl status`` shows them)."""

    calibrated: bool = False
    compensation: list = field(default_factory=list)
    calibration_why: str = "not calibrated: no calibration measured or loaded yet"
    initialized: bool = False
    encoder_offsets: list = field(default_factory=list)
    initialization_why: str = "not initialized: no homing sequence has completed in this process"

    def forget_initialization(self, why: str) -> None:
        """The encoders' zero is no longer trusted (or a homing did not complete): the
        next program homes again."""
        self.initialized = False
        self.encoder_offsets = []
        self.initialization_why = f"not initialized: {why}"

    def forget_calibration(self, why: str) -> None:
        self.calibrated = False
        self.compensation = []
        self.calibration_why = f"not calibrated: {why}"


#: The state file's format (a file of another format is measured again).
STATE_FORMAT = 2


class StateFile:
    """Calibration across restarts: ``calibration.json`` in the state directory.

    It holds the robot's name, the specification's hash and the backend it was measured
    on (what the calibration depends on), and one compensation per axis. :meth:`load`
    accepts it only if all of these match and every value is a finite number within
    ``drift_limits`` (the specification's ``[safety] max_drive_drift`` per axis), and says
    why not otherwise. :meth:`save` hands the data to a writer thread (the loop never
    does file I/O), which writes atomically (temporary file, fsync, rename);
    :meth:`flush` waits for it (not real-time)."""

    def __init__(self, directory: str | Path | None, identity: dict, drift_limits: tuple = ()):
        self.path = Path(directory) / "calibration.json" if directory else None
        self.identity = dict(identity)
        self.drift_limits = tuple(drift_limits)
        self._queue: queue.Queue = queue.Queue(maxsize=4)
        self._writer: threading.Thread | None = None
        self.error: str | None = None  # the last write that failed

    def load(self) -> tuple[list | None, str]:
        """Not real-time: ``(compensation, why)``; ``compensation`` is None when there is
        nothing usable, ``why`` says what was found."""
        if self.path is None:
            return None, "no state directory: calibration is not kept across runs"
        try:
            with open(self.path, "rb") as f:
                raw = f.read(MAX_STATE_FILE_BYTES + 1)
        except FileNotFoundError:
            return None, f"no saved calibration in {self.path.parent}"
        except OSError as exc:
            return None, f"cannot read {self.path}: {exc.strerror or exc}"
        if len(raw) > MAX_STATE_FILE_BYTES:
            return None, f"{self.path} is larger than {MAX_STATE_FILE_BYTES} bytes: not a calibration file"
        try:
            data = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError):
            return None, f"{self.path} is not a calibration file (not JSON)"
        if not isinstance(data, dict) or data.get("format") != STATE_FORMAT:
            return None, f"{self.path} is not a calibration file of format {STATE_FORMAT}"
        for key, what in (("robot", "robot"), ("spec_hash", "specification"), ("backend", "robot backend")):
            if data.get(key) != self.identity.get(key):
                return None, (f"the saved calibration was measured with another {what} "
                              f"({_short(data.get(key))}, now {_short(self.identity.get(key))})")
        values = data.get("compensation")
        n = len(self.drift_limits)
        if not isinstance(values, list) or len(values) != n:
            return None, f"the saved calibration does not hold {n} values"
        for i, (v, limit) in enumerate(zip(values, self.drift_limits)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or abs(v) > limit:
                return None, (f"the saved calibration of axis {i + 1} ({_short(v)}) is outside the allowed "
                              f"drift -{limit:g}..{limit:g} per second")
        return [float(v) for v in values], f"loaded from {self.path}"

    def save(self, compensation: list) -> None:
        """Real-time safe: hand the calibration to the writer thread (never waits; a
        calibration that finds the queue full is not kept, and the next cycle measures again)."""
        if self.path is None:
            return
        data = {"format": STATE_FORMAT, **self.identity, "compensation": list(compensation)}
        try:
            self._queue.put_nowait(data)
        except queue.Full:
            self.error = "the calibration writer is behind: this calibration was not saved"

    def start(self) -> None:
        """Not real-time: start the writer thread (once, before the loop runs)."""
        if self.path is not None and self._writer is None:
            self._writer = threading.Thread(target=self._write_loop, name="irl-state-writer", daemon=True)
            self._writer.start()

    def flush(self, timeout: float = 10.0) -> None:
        """Not real-time: wait until every saved calibration is on disk."""
        if self._writer is not None:
            deadline = time.monotonic() + timeout
            while self._queue.unfinished_tasks and time.monotonic() < deadline:
                time.sleep(0.002)

    def _write_loop(self) -> None:
        while True:  # never dies: a write that fails is said in ``error`` (the summary's files_error)
            data = self._queue.get()
            try:
                self._write(data)
            except OSError as exc:
                self.error = f"cannot save the calibration in {self.path}: {exc.strerror or exc}"
            except Exception:  # noqa: BLE001
                self.error = f"the calibration could not be saved in {self.path} (an internal error of its writer)"
            finally:
                self._queue.task_done()

    def _write(self, data: dict) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(data, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.path)


#: A calibration file is a few hundred bytes; anything larger is not one.
MAX_STATE_FILE_BYTES = 65536


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 24 else text[:21] + "..."


class Supervisor:
    def __init__(self, clock, robot, servo, initialization, trajectory, report, executive,
                 memory: RobotMemory, state_file: StateFile, safety):
        self.clock = clock
        self.robot, self.servo, self.init, self.safety = robot, servo, initialization, safety
        self.trajectory, self.report, self.executive = trajectory, report, executive
        self.memory, self.state_file = memory, state_file
        self.reconfigure = lambda settings: None  # applies settings to the stopped components (set by the system)
        self.n = robot.n
        self.fault: str | None = None
        self.operator_stop: str | None = None
        self.settled_since: float | None = None
        self.reset()

    def reset(self) -> None:
        """Not real-time: a fresh cycle (the machine before Start Robot); what the robot
        remembers (``memory``) stays."""
        self.fault = None
        self.fault_at: tuple[float, int] | None = None  # (time, the program's line) of the fault
        self.operator_stop = None
        self.t_state = 0.0
        self.calibration_sums = [0.0] * self.n
        self.calibration_samples = 0
        self.calibration_done = False
        self.provisional: list | None = None  # measured in this cycle, not confirmed yet
        self.settled_since = None
        self.braking = False  # a normal end: the brakes are closing
        self.emergency = False
        self.done = False
        self.pending_settings: dict | None = None  # a reconfiguration cycle: the settings to apply
        self.init_machine = self.init.machine(self.clock)
        self.fsm = self._build()

    # ---- guards ----
    def faulted(self) -> bool:
        """Any fault anywhere (checked first in every state: the fallbacks). The fault is
        named with where the robot was: the state, and the homing step if any."""
        if self.fault is None:
            found = (self.safety.fault or self.robot.unguarded or self.operator_stop or self.executive.fault
                     or self.robot.error_message or self.servo.error_message or self.init.fault
                     or self.trajectory.fault or self.trajectory.error_message or self.report.error_message)
            if found is not None:
                where = self.fsm.path()
                if self.fsm.state == INITIALIZE and self.init.step_name:
                    where += f" ({self.init.step_name})"
                self._fault(f"{where}: {found}" if where else found)
        return self.fault is not None

    def _fault(self, message: str) -> None:
        """The cycle's first fault: remembered, and the encoders' zero is no longer
        trusted (whatever ended the cycle early may have moved the robot unobserved)."""
        if self.fault is None:
            self.fault = message
            self.fault_at = (self.clock.tick_time, self.trajectory.line)
            why = f"the cycle at {self.clock.tick_time:.3f} s ended early: {message}"
            self.memory.forget_initialization(why)
            if self.provisional is not None:  # measured, never confirmed: measured again next time
                self.provisional = None
                self.memory.forget_calibration(f"the calibration measured in the cycle at {self.clock.tick_time:.3f} s "
                                               f"was never confirmed: {message}")

    def reconfiguring(self) -> bool:
        return self.pending_settings is not None

    def prepared(self) -> bool:
        return self.robot.brakes_released()

    def need_calibration(self) -> bool:
        return self.prepared() and not self.memory.calibrated

    def need_initialization(self) -> bool:
        return self.prepared() and self.memory.calibrated and not self.memory.initialized

    def ready_to_move(self) -> bool:
        return self.prepared() and self.memory.calibrated and self.memory.initialized

    def calibrated_need_init(self) -> bool:
        return self.calibration_done and not self.memory.initialized

    def calibrated_ready(self) -> bool:
        return self.calibration_done and self.memory.initialized

    def initialization_done(self) -> bool:
        return self.init_machine.finished

    def program_finished(self) -> bool:
        return self.trajectory.finished

    # ---- helpers ----
    def _elapsed(self) -> float:
        return self.clock.tick_time - self.t_state

    def _start_servo_and_report(self) -> None:
        if not self.servo.running:
            self.servo.start()
        if not self.report.running:
            self.report.start()

    # ---- Start Robot ----
    def load_calibration(self) -> None:
        """Not real-time (before a cycle): take a saved calibration that passes every
        check of :meth:`StateFile.load`; remember why one was not taken."""
        if self.memory.calibrated:
            return
        saved, why = self.state_file.load()
        if saved is not None:
            self.memory.calibrated, self.memory.compensation = True, saved
            self.memory.calibration_why = f"calibrated: {why}"
        elif self.state_file.path is not None:
            self.memory.calibration_why = f"not calibrated: {why}"

    def start_entry(self) -> None:
        self.t_state = self.clock.tick_time
        self.robot.enable_drives()  # torque on (a stop of the last cycle took it off)
        if self.memory.calibrated:
            self.robot.compensation[:] = self.memory.compensation
        if self.pending_settings is None:  # a reconfiguration keeps the brakes on
            self.robot.release_brakes()

    def start_run(self) -> None:
        if not self.prepared() and self._elapsed() > BRAKE_TIMEOUT:
            self._fault(f"Start Robot: the brakes did not release within {BRAKE_TIMEOUT:g} s")

    # ---- Calibrate Offsets ----
    def calibrate_entry(self) -> None:
        self.t_state = self.clock.tick_time
        self.servo.set_mode("zero")
        self._start_servo_and_report()
        self.robot.compensation[:] = [0.0] * self.n
        self.calibration_sums = [0.0] * self.n
        self.calibration_samples = 0
        self.calibration_done = False

    def calibrate_run(self) -> None:
        """Measure each drive's drift under a zero command; compensate it."""
        if self.calibration_done:
            return
        elapsed = self._elapsed()
        if elapsed < CALIBRATION_SETTLE:
            return
        if elapsed < CALIBRATION_SETTLE + CALIBRATION_TIME:
            for i, v in enumerate(self.robot.velocities):
                self.calibration_sums[i] += v
            self.calibration_samples += 1
            return
        k = max(1, self.calibration_samples)
        compensation = [-s / k for s in self.calibration_sums]
        for axis, c, limit in zip(self.robot.axes, compensation, self.state_file.drift_limits):
            if not abs(c) <= limit:  # NaN too
                self._fault(f"Calibrate Offsets: drive {axis.name} drifts {-c:.3f} {axis.unit}/s under a zero "
                            f"command; the allowed drift is -{limit:g}..{limit:g} {axis.unit}/s "
                            "([safety] max_drive_drift): the drive or its encoder is faulty")
                return
        self.robot.compensation[:] = compensation
        self.provisional = compensation  # remembered once the cycle confirms it (_confirm_calibration)
        self.calibration_done = True

    def _confirm_calibration(self) -> None:
        """The drives and encoders followed their commands (homing completed, or the
        cycle ended normally): remember this cycle's calibration and save it."""
        if self.provisional is not None:
            compensation, self.provisional = self.provisional, None
            self.memory.calibrated, self.memory.compensation = True, compensation
            self.memory.calibration_why = (f"calibrated: measured and confirmed by the cycle at "
                                           f"{self.clock.tick_time:.3f} s")
            self.state_file.save(compensation)

    def calibrate_exit(self) -> None:
        self.servo.set_mode("hold")

    # ---- Initialization Sequence ----
    def init_entry(self) -> None:
        self.robot.homing = True
        self._start_servo_and_report()
        self.init.configure()
        self.init.start()
        self.servo.set_mode("initialization")

    def init_exit(self) -> None:
        self.robot.homing = False
        self.init.stop()
        if self.init.completed and self.fault is None:  # the sequence itself reached Done
            self.memory.initialized = True
            self.memory.encoder_offsets = list(self.robot.offset)
            self.memory.initialization_why = f"initialized: homing completed at {self.clock.tick_time:.3f} s"
            self._confirm_calibration()
            self.servo.hold_at(self.init.positions)  # exactly the start position
        else:
            self.servo.hold()

    # ---- Move Robot ----
    def move_entry(self) -> None:
        self._start_servo_and_report()
        if self.memory.initialized and self.memory.encoder_offsets:
            self.robot.offset[:] = self.memory.encoder_offsets
        self.trajectory.start_position = self.servo.reference  # plan from where the robot is commanded to be
        if not self.trajectory.start():
            self._fault("Move Robot: the trajectory generator did not start (no program?)")
            return
        self.servo.set_mode("trajectory")

    def move_exit(self) -> None:
        self.trajectory.stop()

    # ---- Robot Reconfiguration ----
    def reconfigure_entry(self) -> None:
        """Stop the components, apply the settings, start the robot interface again."""
        for component in (self.trajectory, self.init, self.report, self.servo):
            component.stop()
        self.robot.stop()
        try:
            self.reconfigure(self.pending_settings)
        except ValueError as exc:  # (the settings' own checks: messages in the robot's terms)
            self._fault(f"Robot Reconfiguration: {exc}")
        except KeyError as exc:
            self._fault(f"Robot Reconfiguration: the settings name {exc.args[0]!r}, which this robot does not have")
        self.pending_settings = None
        self.robot.configure()
        self.robot.start()

    # ---- Stop Robot ----
    def stop_entry(self) -> None:
        """A fault (or anything but a normal end): the safety supervisor stops the robot
        (category 1, unless a stricter stop is under way). A normal end: the servo
        settles on the last reference, then the brakes close (standstill monitored)."""
        self.t_state = self.clock.tick_time
        self.settled_since = None
        self.braking = False
        if self.fault is not None:
            self.safety.stop_robot("fault", self.fault)
            return
        self._confirm_calibration()
        if self.servo.running:
            self.servo.hold_reference()
        else:  # nothing moved (a reconfiguration): the brakes close at once
            self.safety.expect_standstill(True)
            self.robot.apply_brakes()
            self.braking = True

    def stop_run(self) -> None:
        """Come to rest, apply the brakes, take the torque off, then stop the components
        (one step at a time). The report records until the end."""
        if self.done:
            return
        safety, robot = self.safety, self.robot
        if not safety.running:  # the guard itself is gone: torque off and brakes, at once
            robot.disable_drives()
            robot.apply_brakes()
            if not robot.brakes_applied() and self._elapsed() < BRAKE_TIMEOUT:
                return
        elif safety.stopping:
            if not safety.at_rest:
                return
        elif not self.braking:
            now = self.clock.tick_time
            worst = max((abs(e) * a.counts_per_unit for e, a in zip(self.servo.following_error, robot.axes)),
                        default=0.0)
            if worst <= SETTLE_TOLERANCE_COUNTS:
                self.settled_since = self.settled_since if self.settled_since is not None else now
            else:
                self.settled_since = None
            if (self.settled_since is not None and now - self.settled_since >= 0.02) or self._elapsed() > STOP_SETTLE_TIMEOUT:
                safety.expect_standstill(True)  # from here on nothing may move
                robot.apply_brakes()
                self.braking = True
            return
        elif not robot.brakes_applied():
            if self._elapsed() > STOP_SETTLE_TIMEOUT + BRAKE_TIMEOUT:
                self._fault(f"Stop Robot: the brakes did not engage within {BRAKE_TIMEOUT:g} s")
                safety.stop_robot("brakes", self.fault)
            return
        else:
            robot.disable_drives()
        for component in (self.servo, self.report, self.safety, self.robot):
            component.stop()
        self.done = True

    def request_stop(self, reason: str = "stopped by the operator", emergency: bool = False) -> None:
        """An operator stop: every state leaves for Stop Robot at the next step."""
        self.operator_stop = self.operator_stop or reason
        self.emergency = self.emergency or emergency

    # ---- the machine ----
    def _build(self) -> FSM:
        states = [
            State(START, entry=self.start_entry, run=self.start_run,
                  doc="prepare the robot: release the brakes"),
            State(CALIBRATE, entry=self.calibrate_entry, run=self.calibrate_run, exit=self.calibrate_exit,
                  doc="start servo and report; measure and compensate each drive's offset"),
            State(INITIALIZE, entry=self.init_entry, exit=self.init_exit, sub=self.init_machine,
                  doc="find sensors and index pulses, reset the encoders, go to the start position"),
            State(MOVE, entry=self.move_entry, exit=self.move_exit,
                  doc="run the program; stop the trajectory generator and the report on exit"),
            State(RECONFIGURE, entry=self.reconfigure_entry,
                  doc="between programs: stop the components, apply a configuration, restart them"),
            State(STOP, entry=self.stop_entry, run=self.stop_run,
                  doc="come to rest, apply the brakes, stop the components"),
        ]
        faulted = self.faulted
        t = Transition
        transitions = [
            t(START, STOP, faulted, label="fault"),
            t(START, RECONFIGURE, self.reconfiguring, label="reconfiguration requested"),
            t(START, CALIBRATE, self.need_calibration, label="prepared, not calibrated"),
            t(START, INITIALIZE, self.need_initialization, label="prepared, calibrated, not initialized"),
            t(START, MOVE, self.ready_to_move, label="prepared, calibrated, initialized"),
            t(RECONFIGURE, STOP, None, label="reconfigured"),
            t(CALIBRATE, STOP, faulted, label="fault"),
            t(CALIBRATE, INITIALIZE, self.calibrated_need_init, label="calibrated, not initialized"),
            t(CALIBRATE, MOVE, self.calibrated_ready, label="calibrated, initialized"),
            t(INITIALIZE, STOP, faulted, label="fault"),
            t(INITIALIZE, MOVE, self.initialization_done, label="initialization done"),
            t(MOVE, STOP, faulted, label="fault"),
            t(MOVE, STOP, self.program_finished, label="program finished"),
        ]
        # the machine's times are the ticks' (runtime.loop.executive): after a stall of the host the
        # catch-up ticks are 1 ms apart, as the robot's samples are
        return FSM("supervisor", states, transitions, initial=START, final=STOP,
                   clock=lambda: self.clock.tick_time)

    def step(self, now: float) -> None:
        """Real-time (decide): one step of the machine."""
        self.fsm.step()
