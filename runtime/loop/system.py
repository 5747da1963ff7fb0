"""One robot, assembled: the simulated arm (or hardware), the components, their ports,
the supervisor and the executive; and a run of one program from power-up to Stop Robot.

This is what ``irl run`` drives in-process (and what the network server will drive).
"""
from __future__ import annotations

import gc
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from compiler.objcode import Program
from compiler.zones import forbidden, signals

from runtime import accel
from runtime.loop.batches import Events
from runtime.loop.component import DataPort
from runtime.loop.components.initialization import Initialization
from runtime.loop.components.io import IoComponent, ZoneSignals, backend_of
from runtime.loop.components.recorder import Recorder
from runtime.loop.components.report import Report
from runtime.motion.zonecheck import home_problem, start_problem
from runtime.motion.tcp import tcp_of
from runtime.loop.components.robot_interface import RobotInterface
from runtime.loop.components.safety import SafetySupervisor
from runtime.loop.components.servo import ServoController
from runtime.loop.components.trajectory import TrajectoryGenerator
from runtime.loop.executive import Executive, MissPolicy, SimClock, WallClock
from runtime.motion.interpolator import Interpolator
from runtime.motion.reduced import Reduced, axis_speed_bounds
from runtime.hardware.backends import DEFAULT_ROBOT, ROBOTS, make_io, make_robot
from runtime.hardware.interface import RobotBackend
from runtime.hardware.sim.estimator import AlphaBeta
from runtime.loop.persistence import PersistentStore
from runtime.loop.supervisor import RobotMemory, StateFile, Supervisor
from runtime.settings import Settings
from runtime.timing import RECORD_PERIOD, TICK
from runtime.wire.messages import io_sources_problem
from runtime.wire.protocol import MODES


@dataclass
class RunOptions:
    seed: int = 0
    realtime: bool = False
    report: str | Path | None = None
    record: str | Path | None = None  # the recording (MCAP) of the run (runtime.loop.components.recorder)
    state_dir: str | Path | None = None
    max_time: float = 3600.0  # simulated (or wall) seconds before the run is stopped
    robot: str = DEFAULT_ROBOT  # the robot backend (a key of runtime.hardware.backends.ROBOTS)
    faults: list = field(default_factory=list)  # [(fault, axis)] injected into the robot backend (its kind's faults)
    override: float = 100.0  # speed override (percent, 1-100) of every move
    deadline_policy: str | None = None  # the servo's miss policy ("hard", "firm", "soft"); None: the spec's
    cell: object = None  # a runtime.hardware.sim.cell.Scenario: what the simulated cell does with the I/O
    fieldbus: object = None  # a runtime.hardware.backends.FieldbusConfig: the I/O on a PLC (wall clock only)
    mode: str = "aut"  # the operating mode (a key of runtime.wire.protocol.MODES)


class RobotSystem:
    def __init__(self, spec, options: RunOptions, backend: RobotBackend | None = None,
                 memory: RobotMemory | None = None, clock=None):
        self.spec = spec
        self.options = options
        # ``clock``: another clock with the same interface (``now``, ``tick_time``,
        # ``wait_until``, ``simulated``); the tests' stalling clock (tests/test_stall.py)
        self.clock = clock if clock is not None else WallClock() if options.realtime else SimClock(TICK)
        n = len(spec.axes)
        self.ports = {name: DataPort(name) for name in ("sens_pos", "desi_pos", "init_pos", "out_vel", "drive_cmd")}
        p = self.ports
        # the robot backend: one given (hardware, a test's), else the kind options.robot names
        self.backend = backend if backend is not None else make_robot(options.robot, spec, options.seed)
        for fault, axis in options.faults:
            self.backend.inject(fault, axis)
        # every component's settings, one object: each component reads its own section there
        self.robot_settings = settings = Settings(spec)
        self.robot = RobotInterface(spec, self.backend, p["sens_pos"], p["drive_cmd"], AlphaBeta(n, TICK), TICK,
                                    settings)
        self.servo = ServoController(spec, p["sens_pos"], p["desi_pos"], p["init_pos"], p["out_vel"],
                                     Interpolator, TICK, settings)
        self.safety = SafetySupervisor(spec, self.robot, self.servo, p["out_vel"], p["drive_cmd"], self.clock, TICK,
                                       settings)
        self.init = Initialization(spec, self.robot, p["init_pos"], p["sens_pos"], self.clock,
                                   settings.initialization.period, settings)
        self.init.on_encoder_reset = self._encoder_reset
        self.servo.measured_velocity = lambda: self.robot.velocities
        self.trajectory = TrajectoryGenerator(spec, self.robot, p["desi_pos"], p["sens_pos"], self.clock,
                                              settings.trajectory.period, settings)
        self.trajectory.safety = self.safety
        planner = self.trajectory.planner
        problem = home_problem(planner.kinematics, tuple(axis.home for axis in spec.main_axes), tuple(spec.tool[:3]),
                               planner.zones)
        if problem is not None:
            raise ValueError(f"{spec.file}: {problem}")
        self.safety.use_tool_of(lambda: self.trajectory.frames_now().tool)  # T1 and the zones: the move's tool
        self.mode = "aut"
        self.set_mode(options.mode)
        io_backend = backend_of(self.backend)  # the digital I/O: the robot's own, or a PLC's over a fieldbus
        problem = io_sources_problem(options.fieldbus is not None, options.cell is not None, options.realtime)
        if problem is not None:
            raise ValueError(problem)
        if options.fieldbus is not None:
            io_backend = make_io(options.fieldbus, spec)
        self.cell = None
        if options.cell is not None:
            if backend is not None or not ROBOTS[options.robot].simulated:
                raise ValueError("a cell scenario drives the simulated robot's inputs: it cannot be used with "
                                 "hardware (its inputs come from the cell itself)")
            from runtime.hardware.sim.cell import Cell

            self.cell = Cell(options.cell, self.backend,
                             self.trajectory.tool_position if self.trajectory.tcp is not None else None)
            self.cell.reset(0.0)  # the cell as it stands before any program (a server shows it idle)
        self.io = IoComponent(io_backend, self.cell, on_lost=self.emergency_stop)
        self.io.configure()  # the backend opened (a PLC's exchange starts), its I/O in the ports
        self.trajectory.io = self.io
        self._use_zones(None)
        self.report = Report(spec, p["sens_pos"], p["drive_cmd"], self.servo, lambda: self.supervisor.fsm.path(),
                             settings.report.period, history=lambda: self.supervisor.fsm.history,
                             io=(self.io.inputs, self.io.outputs), settings=settings,
                             events=Events(self.trajectory, lambda: self.supervisor, self.safety))
        self.report.motion = self.trajectory.motion  # the move columns: the program's moves as they run
        self.report.frames_now = self.trajectory.frames_now  # the TCP of the move's tool, in its base
        # the recording: its rows while the report records (its task runs only while a recording is open)
        self.recorder = Recorder(spec, p["sens_pos"], self.robot, self.trajectory, (self.io.inputs, self.io.outputs),
                                 lambda: self.supervisor.fsm.path(), lambda: self.supervisor.fsm.history,
                                 Events(self.trajectory, lambda: self.supervisor, self.safety), tcp_of(spec))
        if options.cell is not None or options.fieldbus is not None:  # the cell's I/O in every row
            analog = ("analog",) if spec.analog_inputs or spec.analog_outputs else ()
            self.report.columns = [*self.report.columns, *(c for c in ("io", *analog) if c not in self.report.columns)]
        counts = (len(spec.analog_inputs), len(spec.analog_outputs))
        self.report.analog = self.recorder.analog = lambda: self.io.analog_values(*counts)
        self.executive = Executive(self.clock, TICK)
        identity = {"robot": spec.name, "spec_hash": spec.hash,
                    "backend": ROBOTS[options.robot].identity(options.robot, options.seed) if backend is None
                    else "hardware"}
        drift = spec.safety.max_drive_drift
        self.memory = memory or RobotMemory()
        self.state_file = StateFile(options.state_dir, identity, tuple(drift for _ in spec.axes))
        self.state_file.start()
        # the persistent variables' store, beside the calibration (runtime.loop.persistence)
        self.persistent = PersistentStore(options.state_dir)
        self.persistent.load()
        self.persistent.start()
        self.trajectory.persistent = self.persistent
        self.supervisor = Supervisor(self.clock, self.robot, self.servo, self.init, self.trajectory, self.report,
                                     self.executive, self.memory, self.state_file, self.safety)
        self.supervisor.reconfigure = self.apply_settings
        # what the robot remembers across restarts is known from the start (a server's status
        # says calibrated before its first program), not only when the first cycle begins
        self.supervisor.load_calibration()
        if self.cell is not None:  # a scenario's timelines count from the program's first step
            self.trajectory.on_program_start = self.cell.start_program
        ex, robot = self.executive, self.robot
        controller = spec.controller  # validated (compiler.params), every key present
        servo_policy = MissPolicy(options.deadline_policy or controller.servo_miss_policy,
                                  limit=controller.servo_miss_limit,
                                  window=controller.servo_miss_window)
        # the world first: the cell acts, then the inputs as they are this tick, the backend's health
        ex.add("io", self.io.update, TICK, "sense", component=self.io)
        ex.add("robot.read", robot.read, TICK, "sense", component=robot)
        ex.add("supervisor", self.supervisor.step, TICK, "decide")
        ex.add("initialization", self.init.update, self.init.period, "plan", component=self.init)
        ex.add("trajectory", self.trajectory.update, self.trajectory.period, "plan", component=self.trajectory)
        ex.add("triggers", self.trajectory.fire_triggers, TICK, "plan", component=self.trajectory)
        ex.add("servo", self.servo.update, TICK, "control", policy=servo_policy, component=self.servo)
        ex.add("safety", self.safety.update, TICK, "guard", component=self.safety)
        ex.add("robot.write", robot.write, TICK, "act", component=robot)
        ex.add("report", self.report.update, self.report.period, "record", component=self.report)
        recorder = self.recorder
        ex.add("recording", recorder.update, RECORD_PERIOD, "record", enabled=lambda: recorder.recording,
               component=self.report)
        for component in (self.trajectory, self.init, self.report):  # a period is the executive's schedule
            settings.watch(component.name, "period", lambda period, c=component: self._set_period(c, period))

    def set_mode(self, mode: str) -> None:
        """Not real-time (between cycles): the operating mode (runtime.wire.protocol.MODES):
        the safety supervisor's checks, the moves' planning and homing's speeds follow it.
        ValueError: no such mode, or T1 on a robot whose kinematics give no tool centre point."""
        if mode not in MODES:
            raise ValueError(f"no operating mode {mode!r}: the modes are {', '.join(MODES)}")
        t1 = mode == "t1"
        if t1 and self.safety.reduced.kinematics is None:
            raise ValueError("T1 needs the robot's kinematics (the tool centre point's speed is supervised): this "
                             "robot's specification gives none")
        self.mode = mode
        self.safety.set_t1(t1)
        self.trajectory.planner.reduced = Reduced.of(self.spec) if t1 else None
        self.init.t1_bounds = axis_speed_bounds(self.safety.reduced.kinematics, self.spec) if t1 else None

    def _set_period(self, component, period: float) -> None:
        """Not real-time (told by the settings): ``component``'s period changed."""
        self.executive.set_period(component.name, period)
        component.period = period

    def _use_zones(self, program: Program | None) -> None:
        """Not real-time (building the system, a cycle's begin): the world zones of the cycle,
        the specification's and, while it is the program loaded, the program's own
        (compiler.zones): the planner's, the safety supervisor's, the signal zones' outputs."""
        zones = tuple(self.spec.zones) + (program.zones if program is not None else ())
        planner = self.trajectory.planner
        planner.zones = forbidden(zones) if planner.kinematics is not None else ()
        self.safety.zones.use(forbidden(zones))
        self.io.zone_signals = None
        if signals(zones) and self.trajectory.tcp is not None:  # (the tool once the axes are referenced)
            self.io.zone_signals = ZoneSignals(signals(zones), lambda: self.trajectory.tool_position()
                                               if all(self.safety.limits.referenced) else None)

    def begin(self, program: Program | None, report: str | Path | None = None, settings: dict | None = None,
              record: str | Path | None = None, job: int | None = None, jog: bool = False, step: bool = False,
              from_line: int | None = None) -> None:
        """Not real-time: start one cycle of the supervisor (power-up to Stop Robot) with
        ``program``, its report into ``report`` and its recording into ``record`` (``job``:
        the server's id of the program, in the recording); the executive's ticks then carry
        it out (until ``supervisor.done``).
        Calibration and initialization are remembered from earlier cycles. Raises
        ValueError if the program cannot run here (checked before anything moves).
        With ``settings`` instead of a program, the cycle is a reconfiguration: Start
        Robot -> Robot Reconfiguration -> Stop Robot, brakes kept on. With ``jog`` instead,
        a jog session (runtime.loop.jogging): Move Robot runs the jogs asked for, in T1.
        ``step``: the program in step mode; ``from_line``: it starts at the move on that line
        (runtime.loop.stepping; ValueError: a line without a move)."""
        if jog and self.mode != "t1":
            raise ValueError("jogging needs operating mode T1 (manual reduced speed): switch with irl mode t1")
        if program is not None and program.zones:  # (object code is untrusted: checked here, for this robot)
            problem = start_problem(self.spec, self.trajectory.planner.kinematics, program.zones)
            if problem is not None:
                raise ValueError(f"the program cannot start: {problem[1]}")
        if from_line is not None and program is not None:
            from compiler.objcode import from_line_problem

            problem = from_line_problem(program, from_line)
            if problem is not None:
                raise ValueError(f"--from-line {from_line}: {problem}")
        self._wall0 = time.perf_counter()
        if self.options.fieldbus is not None:  # a program does not start without its cell's PLC
            if not self.io.wait_connected(self.options.fieldbus.timeout + 1.0):
                raise ValueError(f"the program cannot start: {self.io.lost()}")
        self._report_path = report
        self.supervisor.reset()
        self.supervisor.pending_settings = settings
        self.executive.reset_statistics()  # the summary's deadlines are this cycle's
        for component in (self.io, self.robot, self.servo, self.init, self.trajectory, self.report, self.safety):
            component.recover()  # a fault of the last cycle is not this one's
            component.stop()  # a clean slate: the supervisor alone starts what the cycle needs
        self.init.fault = None
        self.servo.max_following_error = 0.0
        self.supervisor.load_calibration()
        self.safety.set_referenced(None, self.memory.initialized)
        self.trajectory.load(program, jog=jog, step=step, from_line=from_line)
        self._use_zones(program)
        self.trajectory.override = self.options.override
        self.report.open(report)
        self.recorder.open(record, program, job, "simulated" if self.clock.simulated else "wall")
        if self.cell is not None:
            self.cell.reset(self.clock.tick_time)
        self.io.start()  # the inputs as the cycle begins (the cell reset), its outputs; a loss taken anew
        if self.options.realtime:  # the threads beside the loop (now all started) one below it
            from runtime.loop.realtime import rank_helpers

            rank_helpers()
        self.robot.configure()
        self.robot.start()
        self.safety.start()
        if self.options.realtime:  # the wall clock ran on while this set-up (or a server's idle time) took
            self.executive.resync()  # its time: the first tick is the next one due, not a burst of late ones
        self.supervisor.fsm.start()  # at that tick's time (the components count in tick time)
        self._ticks0 = self.executive.ticks  # (a server's executive counts on across cycles)

    def _encoder_reset(self, axis: int, delta: float) -> None:
        """Homing reset the encoder of ``axis``: the servo follows, the axis is referenced."""
        self.servo.rebase(axis, delta)
        self.safety.set_referenced(axis)

    # ---- configuration (not real-time: between programs) ----
    def settings(self) -> dict:
        """The current value of every configurable setting (runtime.config.SCHEMA)."""
        return self.robot_settings.values()

    def apply_settings(self, settings: dict) -> None:
        """Set every setting given (validated ones: runtime.config.validate_settings),
        with the components stopped; whoever derives something from a setting (the
        servo's and the safety's limits, the executive's schedule) is told at once."""
        self.robot_settings.apply(settings)

    def emergency_stop(self, reason: str = "emergency stop by the operator") -> None:
        """Real-time safe: a stop of category 1 by the safety supervisor at once (its own
        ramp to zero at each axis's max_acceleration, then brakes, then torque off; see
        docs/safety.md), and the supervisor to Stop Robot."""
        if self.safety.running and self.robot.brakes_released():
            self.safety.stop_robot("emergency stop", reason)
        self.supervisor.request_stop(reason, emergency=True)

    def finish(self) -> dict:
        """Not real-time: after a cycle ended, flush the report and the state transitions
        beside it and the recording (written as the cycle ran), and return the cycle's summary."""
        error = "; ".join(e for e in (self.report.close(), self.recorder.close()) if e) or None
        self.io.stop()  # the cycle is over: no task reads the I/O until the next begins
        self.state_file.flush()
        self.persistent.flush()
        summary = self.summary(time.perf_counter() - self._wall0)
        if error:
            summary["fault"] = summary["fault"] or error
        # what the writers could not write (the report, its states file, the calibration): said even
        # when the cycle faulted for another reason
        state_error, self.state_file.error = self.state_file.error, None
        kept_error, self.persistent.error = self.persistent.error, None
        summary["files_error"] = "; ".join(e for e in (error, state_error, kept_error) if e) or None
        return summary

    def run(self, program: Program, on_pause=None, on_log=None, step: bool = False,
            from_line: int | None = None) -> dict:
        """Power-up to Stop Robot with ``program``; returns the summary (see ``summary``).
        ``on_pause(line, kind) -> "resume" | "abort"`` decides what each hold of the program
        for the operator leads to: ``kind`` ``"pause"`` for a ``pause;`` of the program; in
        step mode (``step``) ``"step"`` before each move and ``"approach"`` before the
        approach of a start from a line (resume: it goes) (None: the program waits for a
        resume or a step that nothing here sends, until ``max_time``). On the simulated clock time stands still while it decides; on
        the wall clock the loop runs on (the robot held) and it decides on a thread.
        ``from_line``: the program starts at the move on that line (runtime.loop.stepping).
        ``on_log(time, line, text)`` is handed each line of the program's ``print``
        output as it comes, never by the loop (see :class:`LogFeed`); every line comes
        before the ``on_pause`` of a pause that follows it, and before this returns."""
        feed = LogFeed(self.trajectory, on_log) if on_log is not None else None
        if feed is not None and not self.clock.simulated:
            feed.start()  # (before begin: ranked with the loop's other helper threads)
        self.begin(program, self.options.report, record=self.options.record, step=step, from_line=from_line)
        max_ticks = int(self.options.max_time / TICK)
        sup = self.supervisor
        # The loop allocates small, cycle-free objects every tick; reference counting frees
        # them. A cyclic collection would walk the whole heap at an arbitrary tick, so it is
        # paused for the run: freeze what setup built, then disable. It is re-enabled (and
        # run) when the run ends.
        gc_was_enabled = gc.isenabled()
        gc.freeze()
        gc.disable()
        # On the wall clock, other threads (the report writer, a Cartesian move's planner)
        # must hand the interpreter back to the loop quickly: 0.5 ms instead of 5 ms.
        switch_interval = sys.getswitchinterval()
        if self.options.realtime:
            sys.setswitchinterval(0.0005)
        held = self._held if on_pause is not None else (lambda: None)
        # On the simulated clock the run stops between two ticks to hand over print output
        # (time stands still meanwhile); on the wall clock the feed's thread does.
        fresh = feed.pending if feed is not None and self.clock.simulated else (lambda: False)
        before_pause = feed.drain if feed is not None else None
        try:
            left = max_ticks
            while True:
                left -= self.executive.run(lambda: sup.done or held() or fresh(), left)
                if fresh():
                    feed.drain()
                if sup.done or left <= 0:
                    break
                if held():
                    left -= self._decide(on_pause, left, before_pause)
            if not sup.done:  # the time limit: stop through Stop Robot like any other fault
                sup.request_stop(f"the run did not end within {self.options.max_time:g} s")
                self.executive.run(lambda: sup.done, int(5.0 / TICK))
        except KeyboardInterrupt:
            sup.request_stop("interrupted by the operator")
            self.executive.run(lambda: sup.done, int(3.0 / TICK))
        finally:
            sys.setswitchinterval(switch_interval)
            if gc_was_enabled:
                gc.enable()
            gc.unfreeze()
            if feed is not None:
                feed.stop()
        summary = self.finish()
        if feed is not None:
            feed.close()  # the lines not handed over yet (a print just before the end)
        return summary

    def _held(self) -> str | None:
        """What holds the program for the operator: ``"pause"`` (it paused itself),
        ``"step"`` (step mode: before a move), ``"approach"`` (before the approach of a start
        from a line, in step mode), else None."""
        trajectory = self.trajectory
        vm = trajectory.vm
        if vm is None:
            return None
        if vm.paused:
            return None if trajectory.motion.paused else "pause"
        return None if not trajectory.waiting_for_step else "approach" if trajectory.stepping.approach_next else "step"

    def _decide(self, on_pause, left: int, before=None) -> int:
        """Not real-time: the program paused itself, or waits for a step: ask ``on_pause``
        (after ``before()``: the print output so far), then resume (or step) or abort;
        returns the ticks run meanwhile (wall clock: the loop goes on)."""
        line = self.trajectory.line
        kind = self._held()
        if kind is None:
            return 0

        def decide() -> str:
            if before is not None:
                before()
            return on_pause(line, kind)

        if self.clock.simulated:
            choice, ticks = decide(), 0
        else:
            import threading

            box: list = []
            threading.Thread(target=lambda: box.append(decide()), name="irl-pause", daemon=True).start()
            ticks = self.executive.run(lambda: self.supervisor.done or bool(box), left)
            choice = box[0] if box else "abort"
        if self.supervisor.done:
            return ticks
        trajectory = self.trajectory
        if kind != "pause":
            if choice != "resume" or trajectory.step() is not None:
                trajectory.abort("aborted by the operator before the move (step mode)")
        elif choice != "resume" or not trajectory.resume():
            trajectory.abort("aborted at the program's pause")
        return ticks

    def summary(self, wall_time: float) -> dict:
        sup = self.supervisor
        history = sup.fsm.history
        end = self.clock.tick_time
        states = []
        for i, (t, _source, name) in enumerate(history):
            t_exit = history[i + 1][0] if i + 1 < len(history) else end
            states.append({"name": name, "t_enter": round(t, 6), "t_exit": round(t_exit, 6)})
        moves = [{"line": m.line, "planned_duration": m.planned_duration,
                  "actual_duration": m.actual_duration, "target": list(m.target), "blended": m.blended}
                 for m in self.trajectory.moves]
        stats = self.executive.statistics()
        return {
            "program": self.trajectory.program.name if self.trajectory.program else None,
            "robot": self.spec.name,
            "mode": self.mode,
            "jog": self.trajectory.jogger.state() if self.trajectory.jogger is not None else None,
            "t1_peak_speed": round(self.safety.reduced.peak, 3) if self.mode == "t1" else None,
            "states": states,
            "moves": moves,
            "step": self.trajectory.stepping.step,
            "from_line": self.trajectory.stepping.summary(self.trajectory.motion.moves),
            "final_position": list(self.robot.positions),
            "max_following_error": self.servo.max_following_error,
            "fault": sup.fault,
            "stop": ({"category": self.safety.category, "reason": self.safety.stop_reason}
                     if self.safety.category is not None else None),
            "log": [{"time": t, "line": line, "text": text, "kind": kind}
                    for t, line, text, kind in self.trajectory.log_lines],
            "sim_time": round(end, 6),
            "wall_time": wall_time,
            "kernels": accel.DESCRIPTION,
            "ticks": self.executive.ticks - self._ticks0,
            # the ticks late for some task (at most ``ticks``; each task's own in ``deadlines``)
            "deadline_misses": self.executive.missed_ticks,
            "deadlines": stats,
            "wakeups": self.executive.wakeup_statistics(),
        }


class LogFeed:
    """A program's ``print`` output handed to ``on_log(time, line, text)`` as it comes
    (``irl run`` shows it so), never by the loop: the lines are read from the Trajectory
    Generator's log, which only the loop appends to. On the wall clock a thread of its own
    looks every :data:`POLL` s (:meth:`start`); on the simulated clock the run calls
    :meth:`drain` between ticks. Whoever hands lines over holds the feed's lock, so each
    line is handed over once, in order."""

    #: s between two looks of the wall clock's thread.
    POLL = 0.02

    def __init__(self, trajectory: TrajectoryGenerator, on_log):
        import threading

        self.trajectory = trajectory
        self.on_log = on_log
        self.seen = 0
        self.error: BaseException | None = None  # what on_log raised on the thread (a closed pipe)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def pending(self) -> bool:
        """Real-time safe: whether a line has come since the last hand-over."""
        return len(self.trajectory.log_lines) > self.seen

    def drain(self) -> None:
        """Not real-time: hand over every line not handed over yet."""
        with self._lock:
            if self.error is not None:
                return
            lines = self.trajectory.log_lines  # (load() makes a new list: read it each time)
            while self.seen < len(lines):
                at, line, text, _kind = lines[self.seen]
                self.seen += 1
                self.on_log(at, line, text)

    def start(self) -> None:
        import threading

        self._thread = threading.Thread(target=self._poll, name="irl-print", daemon=True)
        self._thread.start()

    def _poll(self) -> None:
        while not self._stop.wait(self.POLL):
            try:
                self.drain()
            except Exception as exc:  # noqa: BLE001 (re-raised by close, off the thread)
                self.error = exc
                return

    def stop(self) -> None:
        """The thread ends (the lines it has not handed over wait for :meth:`close`)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def close(self) -> None:
        """After the run: the rest of the lines; what ``on_log`` raised on the thread."""
        self.stop()
        if self.error is not None:
            raise self.error
        self.drain()
