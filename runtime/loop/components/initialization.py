"""Initialization: the homing sequence that gives incremental encoders an absolute zero.

As in the paper: axis by axis the robot looks for its inductive sensor, then for the
encoder's index (Z) pulse; from the known position of that pulse it resets the encoder;
then all axes go to the start position. The Initialization component writes the
setpoints (``init_pos``, every 5 ms); the sequence itself is a sub-machine of the
supervisor's Initialization Sequence state (:meth:`Initialization.machine`). Every search
is bounded: a sensor or pulse that does not come is a fault, never a hang. The searches
start and stop with ramps at ``home_speed`` x each axis's max_acceleration (never a step
of velocity), at the search velocity (within ``velocity_limit_scale``); the move to the
start position begins only when every axis is at rest.
"""
from __future__ import annotations

from compiler.params import component_params

from runtime.loop.component import Component, DataPort
from runtime.loop.fsm import FSM, State, Transition
from runtime.motion.planner import PtpInput, plan_ptp
from runtime.settings import Settings
from runtime.timing import SETPOINT_PERIOD, START_SETTLE_TIMEOUT

#: How much farther (deg or mm) than expected a sensor search goes before it gives up: the
#: uncertainty of where an axis rests before homing (parked at home at power-up).
SEARCH_MARGIN = 10.0
#: How close (deg or mm) every axis must come to its start position, or within one encoder
#: count where a count is coarser: the program plans from the servo's reference, not from
#: the measured position, so a finer window only waits on the servo's integral (with the
#: least kp and the finest encoder, one count, 0.00005 deg, took longer than START_SETTLE_TIMEOUT).
SETTLE_WINDOW = 0.001
FROZEN_AFTER = 0.2  # s of commanded motion without a single encoder count -> frozen encoder


def settle_window(axis) -> float:
    """How far (deg or mm) ``axis`` may rest from its start position for homing to end:
    SETTLE_WINDOW, or one encoder count where that is coarser."""
    return max(SETTLE_WINDOW, 1.0 / axis.counts_per_unit)


class Initialization(Component):
    PROPERTIES = component_params("initialization")

    def __init__(self, spec, robot, init_pos: DataPort, sens_pos: DataPort, clock, period: float = SETPOINT_PERIOD,
                 settings: Settings | None = None):
        settings = settings if settings is not None else Settings(spec)
        super().__init__("initialization", period, settings)
        self.own = settings.initialization  # home_speed
        self.robot_section = settings.robot  # velocity_limit_scale
        # the encoder watch counts in tick time: after a stall of the host the catch-up
        # ticks are 1 ms apart, as the robot's samples are (the deadline policy reports
        # the stall itself; wall time would blame the encoder)
        self.robot_now = lambda: clock.tick_time
        self.spec, self.robot, self.init_pos, self.sens_pos = spec, robot, init_pos, sens_pos
        self.axes = spec.axes
        self.n = len(spec.axes)
        self.positions = [0.0] * self.n
        self.velocities = [0.0] * self.n
        self.targets = [0.0] * self.n  # the velocity each axis ramps to
        self.trajectory = None
        self.t_trajectory = 0.0
        self.fault: str | None = None
        self.done = False  # the sub-machine is in Done (also when it was stopped early)
        self.completed = False  # the sequence itself reached Done: every axis referenced, at the start
        self.step_name = ""
        self.on_encoder_reset = None  # called with (axis, delta) after an encoder reset (the servo re-bases)
        #: operating mode T1: each axis's speed that keeps the flange and the tool centre point
        #: within the reduced speed in any configuration (runtime.motion.reduced.axis_speed_bounds); None: AUT
        self.t1_bounds: tuple | None = None

    # ---- the setpoint generator (real-time, every 5 ms) ----
    def on_start(self) -> bool:
        position = self.sens_pos.read() or (0.0,) * self.n
        self.positions = list(position)
        self.velocities = [0.0] * self.n
        self.targets = [0.0] * self.n
        self.trajectory = None
        self.fault = None
        self.done = False
        self.completed = False
        self._first = True  # the first update publishes the rest state (the servo interpolates from it)
        self.init_pos.write((0.0, tuple(self.positions), tuple(self.velocities)), -1.0)
        return True

    def update(self, now: float) -> None:
        """Real-time: advance ramps or the go-to-start trajectory; write ``init_pos``."""
        dt = self.period
        if self._first:
            self._first = False
        elif self.trajectory is not None:
            self.t_trajectory += dt
            pos, vel = self.trajectory.sample(self.t_trajectory)
            self.positions, self.velocities = list(pos), list(vel)
        else:
            velocities, positions, targets = self.velocities, self.positions, self.targets
            home_speed = self.own.home_speed
            for i, v in enumerate(velocities):
                target = targets[i]
                if v != target:  # ramp at home_speed x max_acceleration
                    step = home_speed * self.axes[i].max_acceleration * dt
                    new = target if abs(target - v) <= step else v + step if target > v else v - step
                    positions[i] += 0.5 * (v + new) * dt
                    velocities[i] = new
                elif v:
                    positions[i] += v * dt
        self.init_pos.write((now, tuple(self.positions), tuple(self.velocities)), now)

    # ---- commands from the sequence (between ticks) ----
    def search_velocity(self, axis: int) -> float:
        """How fast ``axis`` searches: its search_velocity, within half the reduced speed
        (and, in T1, within the axis's T1 bound)."""
        a = self.axes[axis]
        speed = min(a.search_velocity, 0.5 * self.robot_section.velocity_limit_scale * a.max_velocity)
        return speed if self.t1_bounds is None else min(speed, self.t1_bounds[axis])

    def ramp(self, axis: int, velocity: float) -> None:
        """Ramp ``axis`` to ``velocity`` (not a step: see :meth:`update`)."""
        self.targets[axis] = velocity

    def halt_axis(self, axis: int) -> None:
        self.targets[axis] = 0.0

    def at_rest(self) -> bool:
        """Every axis's setpoint stands still."""
        return not any(self.velocities) and not any(self.targets)

    def shift(self, axis: int, delta: float) -> None:
        """The encoder of ``axis`` was reset: move its setpoint into the new coordinates,
        and republish it, so no reader sees the old coordinates again."""
        self.positions[axis] += delta
        value = self.init_pos.read()
        t = value[0] if value is not None else 0.0
        self.init_pos.write((t, tuple(self.positions), tuple(self.velocities)), self.init_pos.stamp)

    def go_to_start(self) -> str | None:
        start = tuple(self.positions)
        target = tuple(a.home for a in self.axes)
        f = min(self.own.home_speed, self.robot_section.velocity_limit_scale)
        velocities = tuple(a.max_velocity * f for a in self.axes)
        if self.t1_bounds is not None:  # every axis may move at once: their shares of the T1 speed add up
            k = min(1.0, 1.0 / sum(v / b for v, b in zip(velocities, self.t1_bounds)))
            velocities = tuple(v * k for v in velocities)
        result, trajectory, message = plan_ptp(PtpInput(
            start, target, velocities, tuple(a.max_acceleration * f for a in self.axes)))
        if result < 0:
            return message
        self.trajectory, self.t_trajectory = trajectory, 0.0
        return None

    def at_start(self) -> bool:
        """The move to the start position is over and every axis has settled there
        (within :func:`settle_window`), so the program starts from the start position."""
        if self.trajectory is None or self.t_trajectory < self.trajectory.duration:
            return False
        measured = self.robot.positions
        return all(abs(m - a.home) <= settle_window(a) for m, a in zip(measured, self.axes))

    # ---- the sequence: a sub-machine for the supervisor ----
    def machine(self, clock) -> FSM:
        """Find Sensors -> Find Index -> Go To Start -> Done, each axis in turn."""
        seq = _Sequence(self)
        states = [
            State("Find Sensors", entry=seq.begin_sensors, run=seq.run_sensors),
            State("Find Index", entry=seq.begin_index, run=seq.run_index),
            State("Go To Start", entry=seq.begin_start, run=seq.run_start),
            State("Done", entry=seq.finish),
        ]
        transitions = [
            Transition("Find Sensors", "Find Index", seq.all_axes_done, label="all sensors found"),
            Transition("Find Index", "Go To Start", seq.all_found_at_rest, label="all index pulses found, at rest"),
            Transition("Go To Start", "Done", self.at_start, program=seq.complete, label="at the start position"),
        ]
        return FSM("initialization", states, transitions, initial="Find Sensors", final="Done",
                   clock=lambda: clock.tick_time)


class _Sequence:
    """The programs of the initialization sub-machine; each call does one step's work."""

    def __init__(self, init: Initialization):
        self.init = init
        self.robot = init.robot
        self.axis = 0
        self.phase = ""
        self.travel_start = 0.0
        self.edge_counts = [0] * init.n
        self.index_seen = 0
        self.last_counts = 0
        self.search_counts = 0
        self.still_since = 0.0
        self.search_range = 0.0  # how far the current sensor search may go
        self.reversed = False  # the current sensor search has turned back once

    def _fail(self, message: str) -> None:
        if self.init.fault is None:
            self.init.fault = message
            for i in range(self.init.n):
                self.init.halt_axis(i)

    def all_axes_done(self) -> bool:
        return self.axis >= self.init.n

    def all_found_at_rest(self) -> bool:
        return self.axis >= self.init.n and self.init.at_rest()

    def _name(self) -> str:
        return self.init.axes[self.axis].name

    def _watch_encoder(self, now: float) -> None:
        counts = self.robot.counts[self.axis]
        if counts != self.last_counts:
            self.last_counts, self.still_since = counts, now
        elif now - self.still_since > FROZEN_AFTER:
            a = self.init.axes[self.axis]
            moved = abs(counts - self.search_counts) / a.counts_per_unit
            if moved > 1.0:  # it moved, then stopped: an end stop, before the sensor or pulse came
                what = "homing sensor" if self.init.step_name.startswith("sensor") else "index pulse"
                self._fail(f"{what} of {a.name} not found: the axis stopped after {moved:.1f} {a.unit} "
                           "of search (at its end stop?)")
            else:
                self._fail(f"no encoder counts from {a.name} for {FROZEN_AFTER:g} s while it was commanded "
                           "to move (encoder frozen or drive not responding)")

    def _travelled(self) -> float:
        return abs(self.init.positions[self.axis] - self.travel_start)

    def _estimate(self, axis: int) -> float:
        """Where ``axis`` is, in absolute terms, as far as homing can tell before its
        reference is found: its position if an earlier homing of this process reset its
        encoder, else its power-up position taken as its home (robots are parked there)."""
        offset = 0.0 if self.robot.zeroed[axis] else self.init.axes[axis].home
        return self.init.positions[axis] + offset

    def _search_failed(self, a, upwards: bool) -> str | None:
        """Why the current sensor search must stop (None: it goes on): it went farther
        than the sensor can be, or the axis would pass its software limit (by the
        estimate): the mechanical end stops beyond the limits are never searched."""
        x = self._estimate(self.axis)
        if not a.min <= x <= a.max:
            return (f"homing sensor of {a.name} not found before the axis's {'upper' if upwards else 'lower'} "
                    f"limit ({a.max if upwards else a.min:g} {a.unit}, by its estimated position)")
        if self._travelled() > self.search_range:
            return (f"homing sensor of {a.name} not found within {self.search_range:.1f} {a.unit} of search "
                    f"(where the sensor should be, and {SEARCH_MARGIN:g} {a.unit} more)")
        return None

    # -- Find Sensors --
    def begin_sensors(self) -> None:
        self.axis = 0
        self._start_axis_sensor()

    def _start_axis_sensor(self) -> None:
        if self.axis >= self.init.n:
            return
        a = self.init.axes[self.axis]
        self.init.step_name = f"sensor {a.name}"
        # Inside the window already? Leave it upwards first, so the edge found is the upper
        # one. Below it (by the last known positions, e.g. homing again after a fault)?
        # Approach it upwards, pass through, then search downwards as from above.
        x = self._estimate(self.axis)
        if self.robot.sensors[self.axis]:
            self.phase = "leave"
        elif x < a.sensor_position:
            self.phase = "approach"
        else:
            self.phase = "search"
        self.search_range = abs(x - a.sensor_position) + a.sensor_window + SEARCH_MARGIN
        self.reversed = False
        speed = self.init.search_velocity(self.axis)
        self._search(-speed if self.phase == "search" else speed)

    def _search(self, velocity: float) -> None:
        """Start moving the current axis at ``velocity``, watching its encoder."""
        self.init.ramp(self.axis, velocity)
        self.travel_start = self.init.positions[self.axis]
        self.last_counts, self.still_since = self.robot.counts[self.axis], self.init.robot_now()
        self.search_counts = self.last_counts

    def run_sensors(self) -> None:
        if self.all_axes_done() or self.init.fault:
            return
        a = self.init.axes[self.axis]
        now = self.init.robot_now()
        self._watch_encoder(now)
        active = self.robot.sensors[self.axis]
        if self.phase == "approach":
            if active:
                self.phase = "leave"
                self.travel_start = self.init.positions[self.axis]
            else:
                self._search_on(a, upwards=True)
            return
        if self.phase == "leave":
            if not active:
                self.phase = "search"
                self.init.ramp(self.axis, -self.init.search_velocity(self.axis))
                self.travel_start = self.init.positions[self.axis]
                self.search_range = 2 * a.sensor_window + SEARCH_MARGIN
            elif self._travelled() > 2 * a.sensor_window + 1.0:
                self._fail(f"homing sensor of {a.name} does not turn off")
            return
        if active:
            self.edge_counts[self.axis] = self.robot.counts[self.axis]
            self.init.halt_axis(self.axis)
            self.axis += 1
            self._start_axis_sensor()
        else:
            self._search_on(a, upwards=False)

    def _search_on(self, a, upwards: bool) -> None:
        """The sensor was not found yet: go on; at the end of the search's range (or at
        the software limit) turn back once, over the range searched and the margin again
        on the other side (the estimate of where the axis was may be off, as after a stop
        in the middle of a search); after that, fail."""
        problem = self._search_failed(a, upwards)
        if problem is None:
            return
        if self.reversed:
            self._fail(problem)
            return
        self.reversed = True
        self.search_range = self._travelled() + 2 * SEARCH_MARGIN + 2 * a.sensor_window
        self.travel_start = self.init.positions[self.axis]
        speed = self.init.search_velocity(self.axis)
        self.phase = "search" if upwards else "approach"
        self.init.ramp(self.axis, -speed if upwards else speed)

    # -- Find Index --
    def begin_index(self) -> None:
        self.axis = 0
        self._start_axis_index()

    def _start_axis_index(self) -> None:
        if self.axis >= self.init.n:
            return
        a = self.init.axes[self.axis]
        self.init.step_name = f"index {a.name}"
        self.index_seen = self.robot.index_events[self.axis]
        self._search(-self.init.search_velocity(self.axis))

    def run_index(self) -> None:
        if self.all_axes_done() or self.init.fault:
            return
        i = self.axis
        a = self.init.axes[i]
        self._watch_encoder(self.init.robot_now())
        if self.robot.index_events[i] != self.index_seen:
            latched = self.robot.latched[i]
            # The sensor's upper edge is at sensor_position + window (found moving down);
            # the pulse just seen lies (latched - edge) counts further: its absolute
            # position is the nearest multiple of the index spacing.
            edge = a.sensor_position + a.sensor_window
            estimate = edge + (latched - self.edge_counts[i]) / a.counts_per_unit
            z_abs = round(estimate / a.index_spacing) * a.index_spacing
            before = self.robot.positions[i]
            self.robot.reset_encoder(i, latched, z_abs)
            after = self.robot.counts[i] / a.counts_per_unit + self.robot.offset[i]
            self.init.shift(i, after - before)
            self.init.halt_axis(i)
            if self.init.on_encoder_reset is not None:
                self.init.on_encoder_reset(i, after - before)
            self.axis += 1
            self._start_axis_index()
        elif self._travelled() > 2 * a.index_spacing + 2 * a.sensor_window:
            self._fail(f"index pulse of {a.name} not found within "
                       f"{2 * a.index_spacing + 2 * a.sensor_window:g} {a.unit} after its sensor")

    # -- Go To Start --
    def begin_start(self) -> None:
        self.init.step_name = "start position"
        problem = self.init.go_to_start()
        if problem:
            self._fail(f"cannot plan the move to the start position: {problem}")

    def run_start(self) -> None:
        trajectory = self.init.trajectory
        if trajectory is not None and self.init.t_trajectory > trajectory.duration + START_SETTLE_TIMEOUT:
            far = [f"{a.name} ({m - a.home:+.4f} {a.unit})" for m, a in zip(self.robot.positions, self.init.axes)
                   if abs(m - a.home) > settle_window(a)]
            self._fail(f"the axes did not settle at the start position within {START_SETTLE_TIMEOUT:g} s: "
                       + ", ".join(far))

    def complete(self) -> None:
        """The transition Go To Start -> Done: the only way the sequence completes (a stop
        of the sub-machine from outside also enters Done, but not through here)."""
        self.init.completed = self.init.fault is None

    def finish(self) -> None:
        self.init.step_name = "done"
        self.init.done = True
