"""A per-tick watch of a running RobotSystem against the robot's limits (tests only).

It reads what the simulated robot really does (its true positions) and what the drives
were really commanded (``drive_cmd``, while the torque is on and the brakes released), and
keeps the worst ratios seen. The tests assert on them; nothing here trusts the runtime.
"""
from __future__ import annotations

from operator import sub, truediv

TICK = 0.001


class LimitWatch:
    """Add to a system before it runs: ``LimitWatch(system)``; then read the figures.

    * ``velocity_ratio``: largest |command| / (max_velocity x velocity_limit_scale);
    * ``acceleration_ratio``: largest |command change| / tick / max_acceleration;
    * ``planned_velocity_ratio``, ``planned_acceleration_ratio``: the same of the setpoints
      the planners give the servo (``desi_pos`` from the trajectory generator, ``init_pos``
      from the homing: every 5 ms, a position and a velocity per axis): largest |velocity| /
      (max_velocity x velocity_limit_scale), and |velocity change| / the time between two samples / max_acceleration;
    * ``beyond``: largest distance (deg or mm) of a true position beyond min..max;
    * ``at_end_stop``: some axis reached its mechanical end stop.
    """

    def __init__(self, system):
        self.system = system
        axes = system.spec.axes
        self.axes = axes
        self.vmax = [a.max_velocity for a in axes]
        self.amax = [a.max_acceleration for a in axes]
        self.low = [a.min for a in axes]
        self.high = [a.max for a in axes]
        self.stops = system.backend.end_stops
        self.port = system.ports["drive_cmd"]
        self.setpoints = [system.ports["desi_pos"], system.ports["init_pos"]]
        self._scale, self._limits = None, []  # velocity_limit_scale, and max_velocity x it per axis
        self._ticks = [TICK] * len(axes)
        # every end stop beyond its software limit: an axis at an end stop is beyond the limits
        self._stops_outside = all(lo <= a.min and hi >= a.max for a, (lo, hi) in zip(axes, self.stops))
        self.reset()
        system.executive.add("limit-watch", self.tick, TICK, "record")

    def reset(self) -> None:
        self.velocity_ratio = self.acceleration_ratio = self.beyond = 0.0
        self.planned_velocity_ratio = self.planned_acceleration_ratio = 0.0
        self.at_end_stop = False
        self.worst: dict[str, tuple] = {}  # figure -> (time, state, axis) where it was largest
        self._previous = None
        self._previous_setpoints: list = [None] * len(self.setpoints)  # (time, velocities) per port

    def _note(self, figure: str, value: float, axis: int) -> None:
        if value > getattr(self, figure):
            setattr(self, figure, value)
            self.worst[figure] = (round(self.system.clock.now(), 3), self.system.supervisor.fsm.path(),
                                  self.axes[axis].name)

    def tick(self, now: float) -> None:
        """Every tick. Each figure's largest value over the axes (the same expression as
        ``_note`` is given, evaluated by ``map``) is compared with the figure first; only a
        tick that may set a new worst goes through ``_note`` axis by axis: the same figures
        and places at a fraction of the cost (the watch runs on every tick of the stateful
        test)."""
        system = self.system
        backend = system.backend
        port = self.port
        command = port.value
        if command is not None and port.stamp == now and backend.drives_enabled() \
                and backend.brakes_released():
            scale = system.robot_settings.robot.velocity_limit_scale
            if scale != self._scale:
                self._scale, self._limits = scale, [v * scale for v in self.vmax]
            if not max(map(truediv, map(abs, command), self._limits)) <= self.velocity_ratio:
                for i, (c, v) in enumerate(zip(command, self._limits)):
                    self._note("velocity_ratio", abs(c) / v, i)
            previous = self._previous
            if previous is not None and not max(map(truediv, map(truediv, map(abs, map(sub, command, previous)),
                                                                  self._ticks), self.amax)) <= self.acceleration_ratio:
                for i, (c, p) in enumerate(zip(command, previous)):
                    self._note("acceleration_ratio", abs(c - p) / TICK / self.amax[i], i)
            self._previous = command
        else:
            self._previous = None
        for k, port in enumerate(self.setpoints):
            if port.stamp == now:
                self._setpoint(k, port, now)
        positions = backend.true_positions
        beyond = max(max(map(sub, self.low, positions)), max(map(sub, positions, self.high)))
        if not beyond <= self.beyond:
            for i, x in enumerate(positions):
                self._note("beyond", max(self.low[i] - x, x - self.high[i]), i)
        if not self.at_end_stop and (beyond > 0.0 or not self._stops_outside or beyond != beyond):
            for x, (lo, hi) in zip(positions, self.stops):
                if x <= lo or x >= hi:
                    self.at_end_stop = True

    def _setpoint(self, k: int, port, now: float) -> None:
        """A setpoint written this tick, against the same port's previous one (a gap of more
        than one period, or a port the servo does not follow, starts over)."""
        if port.stamp != now:
            return
        value = port.value
        if value is None or self.system.servo.source is not port:
            self._previous_setpoints[k] = None
            return
        t, _positions, velocities = value[:3]  # (accelerations may follow)
        scale = self.system.robot_settings.robot.velocity_limit_scale
        if scale != self._scale:
            self._scale, self._limits = scale, [v * scale for v in self.vmax]
        # (as in tick: the largest over the axes first, axis by axis only when it may be a new worst)
        if not max(map(truediv, map(abs, velocities), self._limits)) <= self.planned_velocity_ratio:
            for i, v in enumerate(velocities):
                self._note("planned_velocity_ratio", abs(v) / (self.vmax[i] * scale), i)
        previous = self._previous_setpoints[k]
        if previous is not None and 0.0 < t - previous[0] <= 0.0101:
            dt = t - previous[0]
            if not max(map(truediv, map(truediv, map(abs, map(sub, velocities, previous[1])), [dt] * len(self.amax)),
                           self.amax)) <= self.planned_acceleration_ratio:
                for i, (v, p) in enumerate(zip(velocities, previous[1])):
                    self._note("planned_acceleration_ratio", abs(v - p) / dt / self.amax[i], i)
        self._previous_setpoints[k] = (t, velocities)


def at_rest_and_safe(system) -> bool:
    """The robot at rest: brakes applied, torque off, no axis moving."""
    backend = system.backend
    return (backend.brakes_applied() and not backend.drives_enabled()
            and all(v == 0.0 for v in backend.true_velocities))


def run_cycle(system, program, ticks: int = 400_000, during=None, report=None, record=None) -> dict:
    """One cycle of ``system`` with ``program`` to its end (at most ``ticks``), calling
    ``during(system, k)`` after tick k; the summary."""
    system.begin(program, report, record=record)
    k = 0
    while not system.supervisor.done and k < ticks:
        system.executive.step()
        k += 1
        if during is not None:
            during(system, k)
    assert system.supervisor.done, "the cycle did not end"
    return system.finish()


class IdleHost:
    """A motion host for a VM alone: no motion, the clock stands at 0, the log dropped."""

    def now(self) -> float:
        return 0.0

    def motion_done(self) -> bool:
        return True

    def log(self, text: str, line: int, kind: str = "print") -> None:
        pass
