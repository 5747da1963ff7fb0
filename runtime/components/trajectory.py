"""Trajectory Generator: interpreter, path planner and interpolator, every 5 ms.

It runs the program's object code (``runtime.vm``, a bounded number of instructions per
update), and is the VM's motion host: a move instruction hands a segment to the planner;
the trajectory is sampled every 5 ms into ``desi_pos`` (time, positions, velocities),
which the servo interpolates to 1 ms. Each move's line, planned duration and actual
duration (from its first setpoint to its last) are recorded for the run's summary.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

from compiler.objcode import Program
from compiler.values import Joint, Pose

from ..component import Component, DataPort
from ..motion.jerk import LineStop, plan_ptp_jerk
from ..motion.planner import PtpInput, StopRamp, plan_ptp, scaled_limits

PROFILES = ("jerk", "trapezoid")


def motion_profile(spec) -> str:
    """The PTP velocity profile the specification asks for (``[controller] profile``):
    "jerk" (seven-phase, jerk-limited; the default) or "trapezoid". ValueError otherwise."""
    profile = spec.controller.get("profile", "jerk")
    if profile not in PROFILES:
        raise ValueError(f"{spec.file}: controller.profile: expected \"jerk\" or \"trapezoid\", got {profile!r}")
    return profile
from ..vm import DONE, ERROR, VM


@dataclass
class MoveRecord:
    line: int
    kind: str
    target: tuple
    planned_duration: float
    t_start: float
    t_end: float | None = None

    @property
    def actual_duration(self) -> float | None:
        return None if self.t_end is None else self.t_end - self.t_start


class _PlanningJob:
    """A plan computed on a thread of its own (not real-time); ``done`` once ``result``
    is there. The thread only computes: the loop takes the result when it is done."""

    def __init__(self, plan, move: tuple):
        self.move = move
        self.result = (None, "not planned")
        self.done = False
        threading.Thread(target=self._run, args=(plan,), name="irl-plan", daemon=True).start()

    def _run(self, plan) -> None:
        try:
            self.result = plan()
        except Exception as exc:  # plan_lin/plan_circ never raise; a bug must not hang the move
            self.result = (None, f"internal error while planning ({type(exc).__name__}: {exc})")
        self.done = True


@dataclass
class _Interrupted:
    """A move stopped by the operator: what resuming it needs."""

    target: tuple
    speed: float  # the move's speed_ptp and acc_ptp (before the override)
    acc: float
    deceleration: float  # the fraction of each axis's acceleration limit it was planned with
    kind: str = "ptp"  # or "lin", "circ"
    stop: object = None  # the PathStop of a Cartesian move (what resuming needs)


class TrajectoryGenerator(Component):
    """Operator control (real-time safe, called between ticks): :meth:`pause` stops the
    program before its next instruction and brings a move under way to a controlled stop
    (a :class:`StopRamp`); :meth:`resume` continues the program and re-plans the rest of
    the interrupted move from where the robot stopped; :meth:`abort` stops the same way,
    then ends the program with a fault; ``override`` (percent) scales the time of the
    moves, the one under way too (a smooth, monotonic change of rate)."""

    PROPERTIES = {"budget": (int, "object-code instructions per 5 ms update")}

    def __init__(self, spec, robot, desi_pos: DataPort, sens_pos: DataPort, clock, period: float = 0.005):
        super().__init__("trajectory", period)
        self.spec, self.robot, self.desi_pos, self.sens_pos = spec, robot, desi_pos, sens_pos
        self.clock = clock
        self.n = len(spec.axes)
        self.axes = spec.axes
        self.budget = 200
        self.program: Program | None = None
        self.vm: VM | None = None
        self.trajectory = None
        self.t_move = 0.0
        self.positions: tuple = (0.0,) * self.n
        self.velocities: tuple = (0.0,) * self.n
        self.moves: list[MoveRecord] = []
        self.completed = 0
        self.log_lines: list[tuple[float, int, str]] = []
        self.fault: str | None = None
        self.start_position: tuple | None = None  # the commanded position to plan from (else sens_pos)
        self.rate = 1.0  # trajectory seconds per real second: the override, now
        self._rate_from = self._rate_to = 1.0
        self._rate_t = self._rate_T = 0.0  # progress and length (s) of a change of rate
        self._real_time = False  # the trajectory is a stop, planned in real time (no rate)
        self.profile = motion_profile(spec)
        self._kinematics = None  # built when a program first moves to a pose
        self.interrupted: _Interrupted | None = None  # a move stopped before its end (pause/abort)
        self._planning: _PlanningJob | None = None  # a Cartesian move being checked (wall clock)
        self.abort_reason: str | None = None  # set by abort(): end the program once at rest
        self._current: _Interrupted | None = None  # the move under way

    def load(self, program: Program | None) -> None:
        """Not real-time: the program to run at the next start; forgets the last one
        (its moves and log, its fault, an abort)."""
        self.program = program
        self._forget()

    def _forget(self) -> None:
        self.vm = None
        self.trajectory = None
        self.moves = []
        self.completed = 0  # moves that reached their end (telemetry reads it every 10 ms)
        self.log_lines = []
        self.fault = None
        self.abort_reason = None
        self.interrupted = self._current = None
        self._planning = None

    def on_start(self) -> bool:
        """Run the loaded program from its beginning."""
        if self.program is None:
            return False
        self._forget()
        position = self.start_position or self.sens_pos.read() or (0.0,) * self.n
        self.positions = tuple(position)
        self.velocities = (0.0,) * self.n
        self.vm = VM(self.program, self, self.budget)
        self.desi_pos.write((self.clock.now(), self.positions, self.velocities), self.clock.now())
        return True

    # ---- the speed override: a rate of trajectory time (real-time safe) ----
    @property
    def override(self) -> float:
        """The speed override in percent (1-100): the moves run at this fraction of their
        planned speed. Every move is planned at 100 % and its time is scaled, which is
        exactly the move planned with velocity x p, acceleration x p^2 and jerk x p^3: the
        same path. A change while a move runs is a smooth transition of the rate (a
        quintic smoothstep: continuous in rate, its derivative and second derivative),
        monotonic, so the speed never overshoots the new value."""
        return self._rate_to * 100.0

    @override.setter
    def override(self, percent: float) -> None:
        rate = min(max(float(percent), 1.0), 100.0) / 100.0
        if self.trajectory is None or self._real_time:
            self.rate = self._rate_from = self._rate_to = rate
            self._rate_t = self._rate_T = 0.0
            return
        self._rate_from, self._rate_to, self._rate_t = self.rate, rate, 0.0
        # long enough that v * dr/dt stays within the acceleration limits (dr/dt peaks at
        # 1.875 |dr| / T for the quintic), and at least 0.2 s
        ratio = max((a.max_velocity / a.max_acceleration for a in self.axes), default=0.0)
        self._rate_T = max(0.2, 1.875 * abs(rate - self.rate) * ratio)

    def _step_rate(self, dt: float) -> float:
        self._rate_t += dt
        u = self._rate_t / self._rate_T
        if u >= 1.0:
            self.rate = self._rate_from = self._rate_to
            self._rate_T = 0.0
        else:
            self.rate = self._rate_from + (self._rate_to - self._rate_from) * u * u * u * (10.0 + u * (6.0 * u - 15.0))
        return self.rate

    @property
    def finished(self) -> bool:
        """The program ended (DONE) and its last move is complete."""
        return self.vm is not None and self.vm.status is DONE and self.trajectory is None

    @property
    def line(self) -> int:
        return self.vm.line if self.vm is not None else 0

    @property
    def paused(self) -> bool:
        return self.vm is not None and self.vm.paused

    def update(self, now: float) -> None:
        """Real-time: sample the current move, then let the VM run its budget."""
        if self._planning is not None and self._planning.done:
            self._planned()
        trajectory = self.trajectory
        if trajectory is not None:
            if self._real_time:  # a stop ramp: real seconds
                self.t_move += self.period
                self.positions, self.velocities = trajectory.sample(self.t_move)
            else:
                rate = self._step_rate(self.period) if self._rate_T else self.rate
                self.t_move += self.period * rate
                positions, velocities = trajectory.sample(self.t_move)
                self.positions = positions
                self.velocities = velocities if rate == 1.0 else tuple([v * rate for v in velocities])
            if self.t_move >= trajectory.duration - 1e-12:
                self.trajectory = None
                self.velocities = (0.0,) * self.n
                self._real_time = False
                if self._rate_T:  # a change of override under way: the next move has it
                    self.override = self._rate_to * 100.0
                if self.interrupted is None:
                    self.moves[-1].t_end = now
                    self.completed += 1
                    self._current = None
                else:
                    self._at_rest_after_stop()
        self.desi_pos.write((now, self.positions, self.velocities), now)
        vm = self.vm
        if vm is not None and vm.status < DONE:
            status = vm.step()
            if status is ERROR and self.fault is None:
                e = vm.error
                self.fault = f"program error at line {e.line}: {e.message}"

    # ---- operator control (real-time safe) ----
    def pause(self) -> bool:
        """Hold the program; a move under way decelerates to rest: a PTP move in a
        controlled stop, a lin or circ move along its own line or arc. False if there is
        no program to pause."""
        vm = self.vm
        if vm is None or vm.status >= DONE or self.abort_reason is not None:
            return False
        vm.pause()
        self._stop_on_path()
        return True

    def resume(self) -> bool:
        """Continue after :meth:`pause`; the rest of an interrupted move is re-planned
        from where the robot stopped (at once, or when its stop ramp ends)."""
        vm = self.vm
        if vm is None or not vm.paused or self.abort_reason is not None:
            return False
        vm.resume()
        if self.interrupted is not None and self.trajectory is None:
            self._resume_move()
        return True

    def abort(self, reason: str = "aborted by the operator") -> bool:
        """A controlled stop, then end the program with ``reason`` as its fault."""
        vm = self.vm
        if vm is None or vm.status >= DONE:
            return False
        if self.abort_reason is None:
            self.abort_reason = reason
            vm.pause()
            self._stop_on_path()
            if self.trajectory is None:
                self._at_rest_after_stop()
        return True

    def _stop_on_path(self) -> None:
        if self.trajectory is None or self.interrupted is not None or self._current is None:
            return
        self.interrupted = self._current
        if self._current.kind != "ptp":  # decelerate along the line or arc itself
            from ..motion.cartesian import PathStop

            self.trajectory = self.interrupted.stop = PathStop(self.trajectory, self.t_move, self.positions,
                                                               rate=self.rate)
        elif getattr(self.trajectory, "synchronization", None) == "line":  # jerk-limited, on the line
            self.trajectory = LineStop(self.trajectory, self.t_move, rate=self.rate)
        else:
            amax = tuple(a.max_acceleration * self.interrupted.deceleration for a in self.axes)
            self.trajectory = StopRamp(self.positions, self.velocities, amax)
        self.t_move = 0.0
        self._real_time = True

    def _at_rest_after_stop(self) -> None:
        if self.abort_reason is not None:
            self.interrupted = self._current = None
            self.fault = self.fault or f"{self.abort_reason} at line {self.line}"
            self.vm.abort()
        elif not self.vm.paused:
            self._resume_move()

    def _resume_move(self) -> None:
        move = self.interrupted
        self.interrupted = None
        if move.kind != "ptp":  # the rest of the line or arc, from where it stopped
            kind, poses = move.stop.rest()
            problem = self._plan_cartesian(kind, poses, move.speed, move.acc, self.line, record=False)
        else:
            problem = self._plan(move.target, move.speed, move.acc)
        if problem is not None:
            self.fault = self.fault or f"cannot resume the move at line {self.line}: {problem}"
            self.vm.abort()

    def _plan(self, values: tuple, speed: float, acc: float) -> str | None:
        """Plan a PTP move from the current setpoint to ``values`` (at 100 %: the override
        scales its time)."""
        vmax, amax = scaled_limits(tuple(a.max_velocity for a in self.axes),
                                   tuple(a.max_acceleration for a in self.axes), speed, acc)
        if self.profile == "jerk":  # the jerk limit scales with acc_ptp
            jmax = tuple(a.max_jerk * acc for a in self.axes)
            result, trajectory, message = plan_ptp_jerk(self.positions, values, vmax, amax, jmax,
                                                        synchronization="auto")
        else:
            result, trajectory, message = plan_ptp(PtpInput(self.positions, values, vmax, amax))
        if result < 0:
            return message
        self.trajectory, self.t_move = trajectory, 0.0
        self._current = _Interrupted(values, speed, acc, acc * self.rate * self.rate)
        return None

    # ---- the VM's motion host ----
    def now(self) -> float:
        return self.clock.now()

    def move(self, kind: str, targets: tuple, clauses: dict, line: int) -> str | None:
        robot = clauses.get("act_rob")
        if robot is not None and robot != self.spec.name:
            return f"act_rob names robot {robot!r}, but this runtime drives {self.spec.name!r}"
        if kind != "ptp":
            return self._move_cartesian(kind, targets, clauses, line)
        target = targets[0]
        if isinstance(target, Pose):
            target, problem = self._joint_target(target)
            if problem is not None:
                return problem
        if not isinstance(target, Joint) or len(target.axes) != self.n:
            return f"the target must be a joint value with {self.n} axes"
        values = target.axes
        for axis, v in zip(self.axes, values):
            if not axis.min <= v <= axis.max:
                return (f"axis {axis.name} target {v:g} {axis.unit} is outside its limits "
                        f"{axis.min:g}..{axis.max:g} {axis.unit}")
        defaults = self.spec.defaults
        speed = clauses.get("speed_ptp", defaults.speed_ptp)
        acc = clauses.get("acc_ptp", defaults.acc_ptp)
        if not (0 < speed <= 1 and 0 < acc <= 1):
            return f"speed_ptp and acc_ptp must be fractions in (0, 1], got {speed:g} and {acc:g}"
        problem = self._plan(values, speed, acc)
        if problem is not None:
            return problem
        self.moves.append(MoveRecord(line, kind, values, self.trajectory.duration / self.rate, self.clock.now()))
        return None

    def _kinematics_or_problem(self):
        from ..motion.kinematics import Kinematics

        if self._kinematics is None:
            try:
                self._kinematics = Kinematics(self.spec)
            except ValueError as exc:
                return None, f"this robot's kinematics are not usable for poses: {exc}"
        return self._kinematics, None

    def _move_cartesian(self, kind: str, targets: tuple, clauses: dict, line: int) -> str | None:
        """``move lin TARGET`` / ``move circ VIA, TARGET``: the path is checked whole
        against the kinematics, the axis limits and velocities before it starts (a refused
        move leaves the robot where it is, and the program stops at its line with the
        reason and where along the path it fails)."""
        kinematics, problem = self._kinematics_or_problem()
        if problem is not None:
            return problem
        main = len(self.spec.main_axes)
        poses = []
        for target in targets:
            if isinstance(target, Joint):
                poses.append(kinematics.forward(target.axes[:main]))
            elif isinstance(target, Pose):
                poses.append(target)
            else:
                return f"a {kind} target must be a pose or a joint value"
        defaults = self.spec.defaults
        speed = float(clauses.get("speed", defaults.speed))
        acc = float(clauses.get("acc", defaults.acc))
        if not (0 < speed <= self.spec.max_speed and 0 < acc <= self.spec.max_acceleration):
            return (f"speed {speed:g} mm/s and acc {acc:g} mm/s^2 must be positive and within the robot's "
                    f"max_speed {self.spec.max_speed:g} mm/s and max_acceleration {self.spec.max_acceleration:g} mm/s^2")
        return self._plan_cartesian(kind, poses, speed, acc, line)

    def _plan_cartesian(self, kind: str, poses: list, speed: float, acc: float, line: int,
                        record: bool = True) -> str | None:
        from ..motion.cartesian import plan_circ, plan_lin

        kinematics = self._kinematics
        start = self.positions
        if kind == "lin":
            def plan():
                return plan_lin(kinematics, start, poses[0], speed, acc,
                                axis_limits=self.spec, period=self.period)
        else:
            def plan():
                return plan_circ(kinematics, start, poses[0], poses[1], speed, acc,
                                 axis_limits=self.spec, period=self.period)
        if self.clock.simulated:  # deterministic: plan at once (simulated time does not pass)
            stream, message = plan()
            return self._start_cartesian(stream, message, kind, speed, acc, line, record)
        # On the wall clock the check (tens of ms for a long path) must not hold up the
        # loop: a planning thread does it; the move starts at the first update after.
        self._planning = _PlanningJob(plan, (kind, speed, acc, line, record))
        return None

    def _start_cartesian(self, stream, message: str, kind: str, speed: float, acc: float,
                         line: int, record: bool = True) -> str | None:
        if stream is None:
            return f"move {kind} refused: {message}"
        self.trajectory, self.t_move = stream, 0.0
        end = stream.sample(stream.duration)[0]
        self._current = _Interrupted(end, speed, acc, 1.0, kind)
        if record:
            self.moves.append(MoveRecord(line, kind, end, stream.duration / self.rate, self.clock.now()))
        return None

    def _planned(self) -> None:
        """Real-time: take a finished background plan (start the move, or fault)."""
        job, self._planning = self._planning, None
        if self.abort_reason is not None or self.vm is None:
            return
        kind, speed, acc, line, record = job.move
        stream, message = job.result
        problem = self._start_cartesian(stream, message, kind, speed, acc, line, record)
        if problem is not None:
            self.fault = self.fault or f"program error at line {line}: {problem}"
            self.vm.abort()

    def _joint_target(self, pose: Pose) -> tuple[Joint | None, str | None]:
        """The joint values that put the tool at ``pose``: the inverse kinematics'
        configuration nearest the joints the move starts from."""
        from ..motion.kinematics import KinematicsError

        kinematics, problem = self._kinematics_or_problem()
        if problem is not None:
            return None, problem
        main = len(self.spec.main_axes)
        try:
            joints = kinematics.inverse(pose, near=self.positions[:main])
        except KinematicsError as exc:
            return None, f"the target pose cannot be reached: {exc}"
        return Joint(tuple(joints), tuple(self.positions[main:])), None

    def motion_done(self) -> bool:
        return self.trajectory is None and self.interrupted is None and self._planning is None

    def read_input(self, n: int) -> bool:
        if not 1 <= n <= self.spec.inputs:
            raise IndexError(f"digital input {n} does not exist (1..{self.spec.inputs})")
        return self.robot.read_input(n)

    def write_output(self, n: int, value: bool) -> None:
        if not 1 <= n <= self.spec.outputs:
            raise IndexError(f"digital output {n} does not exist (1..{self.spec.outputs})")
        self.robot.write_output(n, value)

    def log(self, text: str, line: int) -> None:
        self.log_lines.append((self.clock.now(), line, text))
