"""From the trajectory generator's 5 ms setpoints to the servo's 1 ms references.

The trajectory generator pushes a setpoint (time, positions, velocities of all axes)
every 5 ms; the servo asks for a position reference every 1 ms. Between the last two
setpoints ``(t0, p0, v0)`` and ``(t1, p1, v1)`` the reference of each axis is the cubic
Hermite polynomial that matches both positions and both velocities, with
``u = (t - t0) / h`` and ``h = t1 - t0``::

    p(t) = h00(u) p0 + h10(u) h v0 + h01(u) p1 + h11(u) h v1
    h00 = 2u^3 - 3u^2 + 1    h10 = u^3 - 2u^2 + u    h01 = 3u^2 - 2u^3    h11 = u^3 - u^2

so the references are continuous in position and velocity across setpoints (C1), hit
every setpoint exactly, and reproduce a quadratic (constant-acceleration) stretch exactly.

Delay: a reference for time ``t`` needs the setpoint at or after ``t``, so the servo
samples one period behind the generator: at servo time ``now`` it asks for
``sample(now - 0.005)``, between the setpoints pushed at ``now - 5 ms`` and ``now``
(or the generator pushes setpoints one period ahead). The interpolation therefore adds
one 5 ms period of delay between planning and the servo.

Limits: cubic Hermite interpolation cannot follow the corners of a trapezoidal
velocity profile (where the acceleration jumps). In a 5 ms interval that contains a
corner the reference departs from the profile by bounded amounts, with ``a`` the axis's
acceleration limit and ``h`` the setpoint period (sharp bounds, derived in the tests):

* velocity: up to :data:`VELOCITY_OVERSHOOT` ``* a * h`` (0.04365 a h) beyond the
  profile's velocity range -- so up to that much above the axis's velocity limit when
  the axis cruises at it (0.0087 deg/s for a = 40 deg/s^2), and as much below zero at
  the start and the end of a move;
* acceleration: up to :data:`ACCELERATION_FACTOR` ``* a`` (5/3 a, at an acceleration
  reversal);
* position: within ``a h^2 / 16`` of the profile (6e-5 deg for a = 40 deg/s^2; 0.033
  a h^2 for the corners of a trapezoid), and it may pass the target by up to about
  0.017 a h^2 in the last interval before coming back to it.

Elsewhere (inside an acceleration, cruise or deceleration phase) the reference equals
the profile. A caller that needs the 1 ms references strictly within a velocity limit
``v`` plans with ``v - VELOCITY_OVERSHOOT * a * h`` (the tests check this).

Real time: :meth:`Interpolator.push` and :meth:`Interpolator.hermite` (or :meth:`sample`) run in the loop;
plain floats and tuples, no NumPy, one small tuple per call.
"""
from __future__ import annotations

__all__ = ["ACCELERATION_FACTOR", "VELOCITY_OVERSHOOT", "Interpolator"]

#: Largest velocity excursion of the interpolated reference beyond the range of the
#: interpolated profile's velocity, in units of ``a * h`` (acceleration limit times
#: setpoint period). The sharp value is 0.043648 (one corner at 27 % of an interval).
VELOCITY_OVERSHOOT = 0.0437

#: Largest acceleration of the interpolated reference, in units of the profile's
#: acceleration limit: ``p''`` at an end point is ``integral of (4 - 6u) acc(u) du``,
#: at most ``(4/3 + 1/3) a``.
ACCELERATION_FACTOR = 5.0 / 3.0


class Interpolator:
    """Cubic Hermite interpolation between the last two pushed setpoints.

    Construct it with the positions to hold before any setpoint arrives (deg or mm per
    axis). Before two setpoints exist, and after the last one, :meth:`sample` holds the
    last position (the initial one if nothing was pushed); before the earlier of the two
    it returns that one's positions.
    """

    __slots__ = ("_n", "_t0", "_t1", "_h", "_p0", "_p1", "_v1", "_zeros", "_coeffs", "_count",
                 "_hold", "_hold_for")

    def __init__(self, initial_positions):
        self.reset(initial_positions)

    def reset(self, positions) -> None:
        """Forget all setpoints and hold ``positions``. Real-time safe."""
        p = tuple([float(x) for x in positions])
        n = self._n = len(p)
        self._p0 = self._p1 = p
        self._zeros = self._v1 = (0.0,) * n
        self._coeffs = ()  # per axis: (p0, p1 - p0, h v0, h v1) of the current interval
        self._t0 = self._t1 = self._h = 0.0
        self._count = 0
        self._hold_for = None  # the positions self._hold was made for
        self._hold = ()

    def shift(self, axis: int, delta: float) -> None:
        """Move every stored setpoint of ``axis`` by ``delta`` (its coordinates changed:
        an encoder reset). The interpolated path is the same, shifted. Real-time safe."""
        def moved(values: tuple) -> tuple:
            values = list(values)
            values[axis] += delta
            return tuple(values)

        self._p0 = moved(self._p0)
        self._p1 = moved(self._p1)
        if self._coeffs:
            coeffs = list(self._coeffs)
            p0, dp, hv0, hv1 = coeffs[axis]
            coeffs[axis] = (p0 + delta, dp, hv0, hv1)
            self._coeffs = tuple(coeffs)
        self._hold_for = None

    @property
    def setpoints(self) -> int:
        """How many setpoints were pushed since construction or :meth:`reset`."""
        return self._count

    @property
    def interval(self) -> tuple[float, float] | None:
        """``(t0, t1)`` of the two setpoints interpolated between, or ``None`` if fewer
        than two were pushed."""
        return (self._t0, self._t1) if self._count >= 2 else None

    def push(self, t: float, positions, velocities) -> bool:
        """Add the setpoint at time ``t`` (s): positions (unit) and velocities (unit/s) of
        every axis, as tuples of floats of the length given at construction.

        Returns ``False`` (and ignores the setpoint) if ``t`` is not later than the last
        setpoint's time or a length differs; ``True`` otherwise. Real-time safe: one
        tuple of per-axis coefficients per call.
        """
        if len(positions) != self._n or len(velocities) != self._n:
            return False
        if self._count:
            if not t > self._t1:  # also NaN
                return False
            h = t - self._t1
            self._t0 = self._t1
            self._h = h
            self._p0 = self._p1
            self._coeffs = tuple([(p0, p1 - p0, h * v0, h * v1) for p0, p1, v0, v1
                                  in zip(self._p1, positions, self._v1, velocities)])
        self._t1 = t
        self._p1 = positions
        self._v1 = velocities
        self._count += 1
        return True

    def sample(self, t: float) -> tuple[float, ...]:
        """Position reference of every axis at time ``t`` (s). Real-time safe.

        Between the last two setpoints: the cubic Hermite interpolation. At or after the
        last setpoint, or before two exist: the last position. Before the earlier of the
        two: its position.
        """
        if self._count < 2 or not t < self._t1:  # NaN holds too
            return self._p1
        s = t - self._t0
        if not s > 0.0:
            return self._p0
        u = s / self._h
        u2 = u * u
        u3 = u2 * u
        h01 = 3.0 * u2 - 2.0 * u3
        h10 = u3 - 2.0 * u2 + u
        h11 = u3 - u2
        # p0 + h01 (p1 - p0) + ... is the same polynomial (h00 = 1 - h01), exactly p0 while
        # the axis holds still, and better conditioned than h00 p0 + h01 p1
        return tuple([p0 + h01 * dp + h10 * hv0 + h11 * hv1
                      for p0, dp, hv0, hv1 in self._coeffs])

    def hermite(self, t: float) -> tuple:
        """The servo's call, for evaluating the reference inside its own per-axis loop:
        ``(coefficients, h01, h10, h11, d01, d10, d11)``, where per axis
        ``coefficients[i] = (p0, dp, hv0, hv1)`` and::

            position = p0 + h01 dp + h10 hv0 + h11 hv1      (= sample(t)[i])
            velocity = d01 dp + d10 hv0 + d11 hv1           (= sample_velocity(t)[i])

        bit for bit, in every case (holding the last position, before the first of the
        two setpoints, between them). Real-time safe: no allocation except when a new
        last setpoint is first held.
        """
        if self._count < 2 or not t < self._t1:  # hold the last position, at rest
            if self._hold_for is not self._p1:
                self._hold_for = self._p1
                self._hold = (tuple([(p, 0.0, 0.0, 0.0) for p in self._p1]), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            return self._hold
        h = self._h
        s = t - self._t0
        if not s > 0.0:  # before t0: its position, its velocity
            return self._coeffs, 0.0, 0.0, 0.0, 0.0, 1.0 / h, 0.0
        u = s / h
        u2 = u * u
        u3 = u2 * u
        return (self._coeffs, 3.0 * u2 - 2.0 * u3, u3 - 2.0 * u2 + u, u3 - u2,
                (6.0 * u - 6.0 * u2) / h, (3.0 * u2 - 4.0 * u + 1.0) / h, (3.0 * u2 - 2.0 * u) / h)

    def sample_velocity(self, t: float) -> tuple[float, ...]:
        """Velocity (unit/s) of the interpolated reference at ``t`` (s), for a servo's
        feed-forward: the derivative of :meth:`sample` for ``t0 <= t < t1`` (the first
        setpoint's velocity at ``t0``). Zero before two setpoints exist and from ``t1`` on
        (the stream of setpoints has ended: the reference holds still). A ``t`` before
        ``t0`` counts as ``t0``: a servo that computes ``now - period`` lands a rounding
        error before ``t0`` every fifth tick and must still get ``v0``. Real-time safe.
        """
        if self._count < 2 or not t < self._t1:
            return self._zeros
        s = t - self._t0
        if not s > 0.0:
            s = 0.0
        h = self._h
        u = s / h
        u2 = u * u
        d01 = (6.0 * u - 6.0 * u2) / h
        d10 = (3.0 * u2 - 4.0 * u + 1.0) / h
        d11 = (3.0 * u2 - 2.0 * u) / h
        return tuple([d01 * dp + d10 * hv0 + d11 * hv1 for _, dp, hv0, hv1 in self._coeffs])
