"""Servo Controller: every 1 ms, a velocity command per axis from the reference and the
measured position: feed-forward velocity plus a PI law on the position error, with
anti-windup, and a following-error limit.

The reference comes from the Trajectory Generator (``desi_pos``) or the Initialization
(``init_pos``), each writing a setpoint (time, positions, velocities[, accelerations])
every 5 ms; an interpolator turns those into 1 ms references within the axes' limits
(one 5 ms period of delay; runtime/motion/interpolator.py). Mode "zero" commands nothing
(calibration); mode "hold" holds the position where it was entered.
"""
from __future__ import annotations

from compiler.params import component_params

from runtime.accel import kernels
from runtime.loop.component import Component, DataPort
from runtime.settings import Settings
from runtime.timing import TICK

servo_law = kernels.servo_law
segment_position = kernels.segment_position
_NO_BREAK = kernels.NO_BREAK


class ServoController(Component):
    PROPERTIES = component_params("servo")
    OPERATIONS = Component.OPERATIONS + ("hold",)

    def __init__(self, spec, sens_pos: DataPort, desi_pos: DataPort, init_pos: DataPort, out_vel: DataPort,
                 interpolator_factory, tick: float = TICK, settings: Settings | None = None):
        settings = settings if settings is not None else Settings(spec)
        super().__init__("servo", tick, settings)
        self.own = settings.servo  # kp, ki, following_error_limit (read every tick)
        self.spec = spec
        self.n = len(spec.axes)
        self.names = tuple(a.name for a in spec.axes)
        self.set_velocity_limit_scale(settings.robot.velocity_limit_scale)
        settings.watch("robot", "velocity_limit_scale", self.set_velocity_limit_scale)
        self.sens_pos, self.desi_pos, self.init_pos, self.out_vel = sens_pos, desi_pos, init_pos, out_vel
        self.tick = tick
        self._set_setpoint_period(settings.trajectory.period)
        settings.watch("trajectory", "period", self._set_setpoint_period)
        # called with the start positions and the axes' limits, which the references keep
        self.interpolator_factory = interpolator_factory
        self.limits = (tuple(a.max_velocity for a in spec.axes), tuple(a.max_acceleration for a in spec.axes),
                       tuple(a.max_jerk for a in spec.axes))
        self.measured_velocity = lambda: None  # the robot interface's velocity estimate, when wired
        self.interpolator = interpolator_factory((0.0,) * self.n, self.limits)
        self.mode = "zero"  # "zero", "hold", "trajectory", "initialization"
        self.epoch = 0  # counts the times the reference started anew (a hold, a new mode, an encoder reset)
        self.source: DataPort | None = None
        self.last_stamp = -1.0
        self.integral = [0.0] * self.n
        self.position = (0.0,) * self.n  # sens_pos at the last update
        self._hold((0.0,) * self.n)
        self.max_following_error = 0.0
        self.worst_error = 0.0  # the largest |following error| of the last update
        self._zeros = (0.0,) * self.n

    def _set_setpoint_period(self, period: float) -> None:
        """Not real-time: the Trajectory Generator's and Initialization's period
        (trajectory.period, which initialization.period equals)."""
        self.setpoint_period = period

    def set_velocity_limit_scale(self, scale: float) -> None:
        """Not real-time (told by the settings): the commands saturate at ``scale`` x each
        axis's max_velocity (robot.velocity_limit_scale; the safety supervisor enforces the
        same limit)."""
        self.max_velocity = tuple(a.max_velocity * scale for a in self.spec.axes)
        self._min_velocity = tuple(-v for v in self.max_velocity)

    def set_mode(self, mode: str) -> None:
        """Not real-time: choose where the reference comes from."""
        position = tuple(self.sens_pos.read() or (0.0,) * self.n)
        self.mode = mode
        self.source = {"trajectory": self.desi_pos, "initialization": self.init_pos}.get(mode)
        self.interpolator = self.interpolator_factory(position, self.limits)
        self.last_stamp = -1.0
        self.integral = [0.0] * self.n
        self._hold(position)
        self.position = position
        self.worst_error = 0.0

    def _hold(self, position) -> None:
        self.epoch += 1  # the reference starts anew here (the T1 speed check takes a new baseline)
        self.hold_position = tuple(position)
        self._held = (tuple([(float(p), 0.0, 0.0, 0.0, 0.0, 0.0, _NO_BREAK, 0.0, 0.0, _NO_BREAK, 0.0, 0.0)
                             for p in self.hold_position]), 0.0, 0.0)
        self._reference = self._held

    def rebase(self, axis: int, delta: float) -> None:
        """Real-time safe: the encoder of ``axis`` was reset, its positions now read
        ``delta`` more: move the reference into the new coordinates (the command goes on
        smoothly; the integral is kept)."""
        self.interpolator.shift(axis, delta)
        held = list(self.hold_position)
        held[axis] += delta
        self._hold(held)
        if self.position is not None and len(self.position) == self.n:
            moved = list(self.position)
            moved[axis] += delta
            self.position = tuple(moved)

    def hold(self) -> None:
        """Hold the position the robot is at now."""
        self.set_mode("hold")

    def hold_at(self, position) -> None:
        """Hold a given position (the last setpoint of a sequence, exactly)."""
        self.set_mode("hold")
        self._hold(position)

    def hold_reference(self) -> None:
        """Hold the last reference (where a finished move wants the robot to be)."""
        reference = self.reference
        self.set_mode("hold")
        self._hold(reference)

    @property
    def reference(self) -> tuple[float, ...]:
        """The position reference of the last update (deg per axis)."""
        segments, s, _ = self._reference
        return tuple([segment_position(c, s) for c in segments])

    @property
    def reference_segments(self) -> tuple:
        """The reference of the last update as the servo evaluates it: ``(segments, s,
        inv_h)``, each axis's segment (runtime.kernels) at ``s`` (real-time: no copy)."""
        return self._reference

    @property
    def following_error(self) -> tuple[float, ...]:
        """Reference - measured position of the last update (deg per axis)."""
        return tuple([r - x for r, x in zip(self.reference, self.position)])

    def on_start(self) -> bool:
        self.set_mode(self.mode)
        return True

    def update(self, now: float) -> None:
        """Real-time: one servo period. The reference and its velocity (feed-forward) are
        evaluated inside the per-axis loop (:func:`runtime.kernels.servo_law`) on the
        interpolator's segments. A setpoint is ``(t, positions, velocities)`` or ``(t,
        positions, velocities, accelerations)``."""
        position = self.sens_pos.value
        mode = self.mode
        if mode == "zero" or position is None:
            self.out_vel.write(self._zeros, now)
            return
        if mode == "hold":
            reference = self._held
        else:
            port = self.source
            if port.stamp != self.last_stamp and port.value is not None:
                self.interpolator.push(*port.value)
                self.last_stamp = port.stamp
            # The reference runs one setpoint period behind, so that there are always two
            # setpoints to interpolate between (the interpolator's documented delay).
            reference = self.interpolator.segment(now - self.setpoint_period)
        self._reference = reference
        self.position = position
        segments, s, inv_h = reference
        out = [0.0] * self.n
        own = self.own
        worst = servo_law(segments, s, inv_h, position, self.integral, self.max_velocity, self._min_velocity,
                          own.kp, own.ki, self.tick, out)
        self.worst_error = worst
        if worst > self.max_following_error:
            self.max_following_error = worst
        self.out_vel.write(tuple(out), now)
        if worst > own.following_error_limit:
            self._following_error_fault(out)

    def _following_error_fault(self, out) -> None:
        errors = [abs(e) for e in self.following_error]
        worst = max(errors)
        i = errors.index(worst)
        why = ""
        measured = self.measured_velocity()
        if measured is not None and abs(measured[i]) < 0.05 and abs(out[i]) > 0.5:
            why = (f"; {self.names[i]} does not move although commanded at {out[i]:.2f} deg/s "
                   "(drive not responding, encoder frozen, or the axis is at an end stop)")
        self.error(f"following error on {self.names[i]}: {worst:.3f} deg exceeds the limit "
                   f"{self.own.following_error_limit:g} deg{why}")
