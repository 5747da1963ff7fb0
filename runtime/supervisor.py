"""The supervisor: the paper's five-state FSM (its "Viewer"), stepped every 1 ms.

Start Robot -> Calibrate Offsets (if not calibrated) -> Initialization Sequence (if not
initialized; a sub-machine) -> Move Robot -> Stop Robot (final). Calibration is kept in a
state file (written atomically) across restarts; initialization only while the process
lives (incremental encoders lose their zero on power-down). Every state that waits for
the world has a way out: a fault from any component, a deadline fault, an operator stop
or a time-out leads to Stop Robot with the fault named.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from .fsm import FSM, State, Transition

START, CALIBRATE, INITIALIZE, MOVE, STOP = (
    "Start Robot", "Calibrate Offsets", "Initialization Sequence", "Move Robot", "Stop Robot")
RECONFIGURE = "Robot Reconfiguration"

BRAKE_TIMEOUT = 1.0  # s for the brakes to release or engage
CALIBRATION_SETTLE = 0.05  # s before measuring (the drives' lag)
CALIBRATION_TIME = 0.25  # s of measurement
SETTLE_TOLERANCE_COUNTS = 1.0  # encoder counts: "at rest" before the brakes go on
SETTLE_TIMEOUT = 1.0  # s at most spent settling in Stop Robot


@dataclass
class RobotMemory:
    """What the supervisor remembers between programs in one process."""

    calibrated: bool = False
    compensation: list = field(default_factory=list)
    initialized: bool = False
    encoder_offsets: list = field(default_factory=list)


class StateFile:
    """Calibration across restarts: ``calibration.json`` in the state directory, written
    atomically (temporary file, fsync, rename), keyed by the robot's identity."""

    def __init__(self, directory: str | Path | None, identity: str):
        self.path = Path(directory) / "calibration.json" if directory else None
        self.identity = identity

    def load(self) -> list | None:
        if self.path is None:
            return None
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        if not isinstance(data, dict) or data.get("robot") != self.identity:
            return None
        values = data.get("compensation")
        if isinstance(values, list) and all(isinstance(v, (int, float)) for v in values):
            return [float(v) for v in values]
        return None

    def save(self, compensation: list) -> None:
        if self.path is None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump({"robot": self.identity, "compensation": compensation}, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.path)


class Supervisor:
    def __init__(self, clock, robot, servo, initialization, trajectory, report, executive,
                 memory: RobotMemory, state_file: StateFile):
        self.clock = clock
        self.robot, self.servo, self.init = robot, servo, initialization
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
        self.operator_stop = None
        self.t_state = 0.0
        self.calibration_sums = [0.0] * self.n
        self.calibration_samples = 0
        self.calibration_done = False
        self.settled_since = None
        self.done = False
        self.pending_settings: dict | None = None  # a reconfiguration cycle: the settings to apply
        self.init_machine = self.init.machine(self.clock)
        self.fsm = self._build()

    # ---- guards ----
    def faulted(self) -> bool:
        """Any fault anywhere (checked first in every state: the fallbacks). The fault is
        named with where the robot was: the state, and the homing step if any."""
        if self.fault is None:
            found = (self.operator_stop or self.executive.fault or self.robot.error_message
                     or self.servo.error_message or self.init.fault or self.trajectory.fault
                     or self.trajectory.error_message or self.report.error_message)
            if found is not None:
                where = self.fsm.path()
                if self.fsm.state == INITIALIZE and self.init.step_name:
                    where += f" ({self.init.step_name})"
                self.fault = f"{where}: {found}" if where else found
        return self.fault is not None

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
        return self.clock.now() - self.t_state

    def _start_servo_and_report(self) -> None:
        if not self.servo.running:
            self.servo.start()
        if not self.report.running:
            self.report.start()

    # ---- Start Robot ----
    def start_entry(self) -> None:
        self.t_state = self.clock.now()
        saved = self.state_file.load()
        if saved is not None and len(saved) == self.n:
            self.memory.calibrated, self.memory.compensation = True, saved
        if self.memory.calibrated:
            self.robot.compensation[:] = self.memory.compensation
        if self.pending_settings is None:  # a reconfiguration keeps the brakes on
            self.robot.release_brakes()

    def start_run(self) -> None:
        if not self.prepared() and self._elapsed() > BRAKE_TIMEOUT:
            self.fault = self.fault or f"Start Robot: the brakes did not release within {BRAKE_TIMEOUT:g} s"

    # ---- Calibrate Offsets ----
    def calibrate_entry(self) -> None:
        self.t_state = self.clock.now()
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
        self.robot.compensation[:] = compensation
        self.memory.calibrated, self.memory.compensation = True, compensation
        self.state_file.save(compensation)
        self.calibration_done = True

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
        if self.init_machine.finished:
            self.memory.initialized = True
            self.memory.encoder_offsets = list(self.robot.offset)
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
            self.fault = self.fault or "Move Robot: the trajectory generator did not start (no program?)"
            return
        self.servo.set_mode("trajectory")

    def move_exit(self) -> None:
        self.trajectory.stop()
        self.report.stop()

    # ---- Robot Reconfiguration ----
    def reconfigure_entry(self) -> None:
        """Stop the components, apply the settings, start the robot interface again."""
        for component in (self.trajectory, self.init, self.report, self.servo):
            component.stop()
        self.robot.stop()
        try:
            self.reconfigure(self.pending_settings)
        except (ValueError, KeyError) as exc:
            self.fault = self.fault or f"Robot Reconfiguration: {exc}"
        self.pending_settings = None
        self.robot.configure()
        self.robot.start()

    # ---- Stop Robot ----
    def stop_entry(self) -> None:
        self.t_state = self.clock.now()
        self.settled_since = None
        if self.fault is None and self.servo.running:
            self.servo.hold_reference()  # a normal end: settle on the last reference
        elif self.servo.running:
            self.servo.hold()  # a fault: stay where the robot is
        if self.report.running:
            self.report.stop()
        if not self.servo.running:
            self.robot.apply_brakes()

    def stop_run(self) -> None:
        """Come to rest, apply the brakes, then stop the components (one step at a time)."""
        if self.done:
            return
        if self.servo.running:
            worst = max((abs(e) * a.counts_per_unit for e, a in zip(self.servo.following_error, self.robot.axes)),
                        default=0.0)
            now = self.clock.now()
            if worst <= SETTLE_TOLERANCE_COUNTS:
                self.settled_since = self.settled_since if self.settled_since is not None else now
            else:
                self.settled_since = None
            settled = self.settled_since is not None and now - self.settled_since >= 0.02
            if settled or self._elapsed() > SETTLE_TIMEOUT:
                self.robot.apply_brakes()
                if self.robot.brakes_applied() or self._elapsed() > SETTLE_TIMEOUT + BRAKE_TIMEOUT:
                    self.servo.stop()
            return
        if not self.robot.brakes_applied() and self._elapsed() < SETTLE_TIMEOUT + BRAKE_TIMEOUT:
            self.robot.apply_brakes()
            return
        self.robot.stop()
        self.done = True

    def request_stop(self, reason: str = "stopped by the operator") -> None:
        """An operator stop: every state leaves for Stop Robot at the next step."""
        self.operator_stop = reason

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
        return FSM("supervisor", states, transitions, initial=START, final=STOP, clock=self.clock.now)

    def step(self, now: float) -> None:
        """Real-time (decide): one step of the machine."""
        self.fsm.step()
