"""Servo Controller: every 1 ms, a velocity command per axis from the reference and the
measured position: feed-forward velocity plus a PI law on the position error, with
anti-windup, and a following-error limit.

The reference comes from the Trajectory Generator (``desi_pos``) or the Initialization
(``init_pos``), each writing a setpoint (time, positions, velocities) every 5 ms; an
interpolator turns those into 1 ms references (one 5 ms period of delay). Mode "zero"
commands nothing (calibration); mode "hold" holds the position where it was entered.
"""
from __future__ import annotations

from ..component import Component, DataPort


class ServoController(Component):
    PROPERTIES = {
        "kp": (float, "position gain (1/s)"),
        "ki": (float, "integral gain (1/s^2)"),
        "following_error_limit": (float, "largest allowed |reference - position| (deg)"),
    }
    OPERATIONS = Component.OPERATIONS + ("hold",)

    def __init__(self, spec, sens_pos: DataPort, desi_pos: DataPort, init_pos: DataPort, out_vel: DataPort,
                 interpolator_factory, tick: float = 0.001):
        super().__init__("servo", tick)
        controller = spec.controller
        self.kp = float(controller.get("kp", 40.0))
        self.ki = float(controller.get("ki", 2.0))
        self.following_error_limit = float(controller.get("following_error_limit", 2.0))
        self.spec = spec
        self.n = len(spec.axes)
        self.names = tuple(a.name for a in spec.axes)
        self.max_velocity = tuple(a.max_velocity for a in spec.axes)
        self.sens_pos, self.desi_pos, self.init_pos, self.out_vel = sens_pos, desi_pos, init_pos, out_vel
        self.tick = tick
        self.setpoint_period = 0.005  # the Trajectory Generator's and Initialization's period
        self.interpolator_factory = interpolator_factory  # called with the start positions
        self.measured_velocity = lambda: None  # the robot interface's velocity estimate, when wired
        self.interpolator = interpolator_factory((0.0,) * self.n)
        self.mode = "zero"  # "zero", "hold", "trajectory", "initialization"
        self.source: DataPort | None = None
        self.last_stamp = -1.0
        self.integral = [0.0] * self.n
        self.hold_position = (0.0,) * self.n
        self.reference = (0.0,) * self.n
        self.following_error = (0.0,) * self.n
        self.max_following_error = 0.0
        self._zeros = (0.0,) * self.n

    def set_mode(self, mode: str) -> None:
        """Not real-time: choose where the reference comes from."""
        position = self.sens_pos.read() or (0.0,) * self.n
        self.mode = mode
        self.source = {"trajectory": self.desi_pos, "initialization": self.init_pos}.get(mode)
        self.interpolator = self.interpolator_factory(tuple(position))
        self.last_stamp = -1.0
        self.integral = [0.0] * self.n
        self.hold_position = tuple(position)
        self.reference = tuple(position)

    def rebase(self) -> None:
        """An encoder was reset: drop setpoints in the old coordinates (start afresh from
        the position measured now, in the new ones)."""
        self.set_mode(self.mode)

    def hold(self) -> None:
        """Hold the position the robot is at now."""
        self.set_mode("hold")

    def hold_at(self, position) -> None:
        """Hold a given position (the last setpoint of a sequence, exactly)."""
        self.set_mode("hold")
        self.hold_position = self.reference = tuple(position)

    def hold_reference(self) -> None:
        """Hold the last reference (where a finished move wants the robot to be)."""
        reference = self.reference
        self.set_mode("hold")
        self.hold_position = reference
        self.reference = reference

    def on_start(self) -> bool:
        self.set_mode(self.mode)
        return True

    def update(self, now: float) -> None:
        """Real-time: one servo period."""
        position = self.sens_pos.read()
        n = self.n
        if self.mode == "zero" or position is None:
            self.out_vel.write(self._zeros, now)
            return
        if self.mode == "hold":
            reference, velocity = self.hold_position, self._zeros
        else:
            port = self.source
            if port.stamp != self.last_stamp and port.value is not None:
                t, pos, vel = port.value
                self.interpolator.push(t, pos, vel)
                self.last_stamp = port.stamp
            # The reference runs one setpoint period behind, so that there are always two
            # setpoints to interpolate between (the interpolator's documented delay).
            reference, velocity = self.interpolator.sample_both(now - self.setpoint_period)
        self.reference = reference
        kp, ki, dt = self.kp, self.ki, self.tick
        integral = self.integral
        max_velocity = self.max_velocity
        out = [0.0] * n
        errors = [0.0] * n
        worst = 0.0
        worst_axis = 0
        for i in range(n):
            e = reference[i] - position[i]
            errors[i] = e
            if e > worst or -e > worst:
                worst, worst_axis = (e if e > 0.0 else -e), i
            vmax = max_velocity[i]
            u = velocity[i] + kp * e + ki * integral[i]
            if -vmax < u < vmax:  # anti-windup: integrate only while the output is not saturated
                integral[i] += e * dt
            else:
                u = vmax if u > 0.0 else -vmax
            out[i] = u
        self.following_error = tuple(errors)
        if worst > self.max_following_error:
            self.max_following_error = worst
        self.out_vel.write(tuple(out), now)
        if worst > self.following_error_limit:
            self._following_error_fault(worst_axis, worst, out)

    def _following_error_fault(self, i: int, worst: float, out) -> None:
        why = ""
        measured = self.measured_velocity()
        if measured is not None and abs(measured[i]) < 0.05 and abs(out[i]) > 0.5:
            why = (f"; {self.names[i]} does not move although commanded at {out[i]:.2f} deg/s "
                   "(drive not responding, encoder frozen, or the axis is at an end stop)")
        self.error(f"following error on {self.names[i]}: {worst:.3f} deg exceeds the limit "
                   f"{self.following_error_limit:g} deg{why}")
