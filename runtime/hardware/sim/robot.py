"""The simulated robot: drives, joints, hard stops, brakes, encoders, index pulses,
homing sensors, digital I/O and injectable faults.

It stands in for the hardware behind the paper's Robot Interface component: velocity
commands go in (``out_vel``), incremental encoder counts, latched index (Z) counts and the
inductive homing sensors come out (what ``sens_pos`` and the Initialization Sequence are
made from). The model, per axis:

* **Drive**: velocity-commanded, a first-order lag with time constant ``tau``
  (``spec.simulation.drive_time_constant``, default 0.005 s) and an unknown constant
  velocity offset ``b`` (seeded, uniform in +-``max_drive_offset`` deg/s, default 0.5)::

      dv/dt = (u - v) / tau,   u = clip(cmd) + b,   dx/dt = v

  integrated *exactly* for a command held constant over the step (zero-order hold), so it
  is stable and exact for any ``dt``::

      a = exp(-dt / tau)
      x' = x + u dt + (v - u) tau (1 - a)
      v' = u + (v - u) a

  The command is saturated at +-``drive_saturation`` x the axis' ``max_velocity``
  (default 1.5; a real amplifier has a limit too); a NaN command counts as 0.
* **Hard stops** (the mechanical end stops) ``end_stop_margin`` (default 5 deg or mm)
  beyond the axis ``min`` / ``max``, which are the software limits: the axis stops there
  (its velocity towards the stop becomes 0). :attr:`SimRobot.end_stops` gives them.
* **Drive enable** (safe torque off): the drives are enabled at power-up;
  :meth:`SimRobot.disable_drives` takes the torque away at once (the commands are ignored,
  each axis coasts to rest with the drive's lag, as a dead drive does) until
  :meth:`SimRobot.enable_drives`.
* **Brakes** (all axes together): engaged at power-up. While engaged the axis does not
  move and its velocity is 0. :meth:`SimRobot.release_brakes` / :meth:`apply_brakes` take
  ``spec.simulation.brake_time`` (default 0.05 s) of simulated time before they are
  effective; :meth:`brakes_released` / :meth:`brakes_applied` say when they are.
* **Power-up position**: ``home`` + seeded uniform in +-``park_spread`` (default 3 deg),
  clipped into min..max.
* The parameters (``[simulation]`` of the specification) are validated when the
  specification loads (:mod:`compiler.params`).
* **Incremental encoder**: ``counts = floor((x - x_power_up) * counts_per_unit)``: it counts
  from zero wherever the axis parks, quantised to whole counts.
* **Index (Z) pulse**: once per motor revolution, i.e. at the absolute axis positions
  ``k * index_spacing``. It is active during a step in which the axis crossed one; the
  encoder latches its count at that position (as encoder hardware does) and counts the
  event, so a reader that samples every 5 ms misses no pulse: it compares the event
  counter with the one it saw last.
* **Homing sensor**: active while ``|x - sensor_position| <= sensor_window``.
* **Faults** (:meth:`SimRobot.inject`): ``"sensor_dead"`` (the homing sensor never fires),
  ``"encoder_frozen"`` (the encoder stops: counts and index events stop changing; counts
  missed while frozen stay missed after :meth:`clear_faults`, as with a real incremental
  encoder), ``"drive_dead"`` (the drive ignores commands and its offset: the velocity
  decays to 0 with the drive's lag); and, for tests and scenarios,
  :meth:`SimRobot.set_drift` (the drive runs at a velocity of its own whatever it is
  commanded: a drift the servo cannot hold) and :meth:`SimRobot.set_drive_offset`.

Each concern is a class with its data: :class:`Drives` (the drives and the joints they
move, the hard stops, safe torque off, the drives' faults), :class:`Encoders` (counts,
index pulses, the frozen encoder), :class:`Brakes`, :class:`HomingSensors` and the digital
I/O (:class:`runtime.hardware.interface.DigitalIo`); :class:`SimRobot` steps them
together behind :class:`runtime.hardware.interface.RobotBackend`.

Axes are numbered from 0 in this Python interface (the order of ``spec.axes``); digital
inputs and outputs are numbered from 1, as in L-IRL (``IN[1]``..).

Real-time rules: :meth:`step`, :meth:`read`, the brake operations, the digital I/O and the
properties run in the real-time loop (plain floats and small tuples, no I/O, no NumPy);
the constructor, :meth:`inject` and :meth:`clear_faults` are meant for set-up and tests.
Everything is deterministic: the same spec, seed and sequence of calls give bit-identical
results.
"""
from __future__ import annotations

import math
import random

from runtime.accel import kernels
from runtime.hardware.faults import FAULTS
from runtime.hardware.interface import DigitalIo, RobotBackend
from runtime.hardware.sim.estimator import AxisStates

drive_step = kernels.drive_step


_floor = math.floor


class Drives(AxisStates):
    """The drives and the joints they move, per axis: the velocity-commanded first-order
    lag with its offset and saturation, the hard stops, safe torque off and the drives'
    faults (dead, drifting). The joints' positions and velocities are :attr:`positions`
    and :attr:`velocities` (the truth: the controller sees encoders). Not real-time
    (set-up); the methods say which run in the tick."""

    def __init__(self, axes, sim, offsets: list[float], parks: list[float]):
        super().__init__(parks)
        n = self.n_axes = len(axes)
        self.tau = sim.drive_time_constant
        self.offset = offsets
        self.vmax = [sim.drive_saturation * a.max_velocity for a in axes]
        margin = sim.end_stop_margin
        self.lo = [a.min - margin for a in axes]  # the mechanical end stops
        self.hi = [a.max + margin for a in axes]
        # the step's discretisation, cached for the last dt
        self.dt = -1.0
        self.decay = 0.0
        self.lag_gain = 0.0
        self.enabled = True  # safe torque off when False
        self.dead = [False] * n
        self.drift: list[float | None] = [None] * n  # a drive's own velocity, whatever it is commanded

    def discretise(self, dt: float) -> None:
        """Real-time: the exact lag's factors for a step of ``dt`` (cached until it changes)."""
        self.dt = dt
        self.decay = math.exp(-dt / self.tau)
        self.lag_gain = self.tau * (1.0 - self.decay)

    def hold(self) -> None:
        """Real-time: the brakes hold every joint: it stops dead."""
        vs = self.v
        for i in range(self.n_axes):
            vs[i] = 0.0

    def hard_stop(self, i: int, x: float, v: float) -> tuple[float, float]:
        """Real-time: joint ``i`` at ``x`` moving at ``v`` against its end stops (it stops
        there: its velocity towards the stop becomes 0)."""
        if x > self.hi[i]:
            x = self.hi[i]
            if v > 0.0:
                v = 0.0
        elif x < self.lo[i]:
            x = self.lo[i]
            if v < 0.0:
                v = 0.0
        return x, v

    def faulty(self) -> bool:
        """A drive dead or drifting, or the torque off: the step's slower path."""
        return any(self.dead) or any(d is not None for d in self.drift) or not self.enabled

    def fault_commands(self, velocity_commands) -> list[float]:
        """Real-time (the rare path): the commands the drives act on. A dead drive gets
        the command that cancels its offset (it then produces nothing: u = -b + b = 0
        exactly), as every drive does with the torque off (it coasts); a drifting one the
        command that makes its drift."""
        offset = self.offset
        if not self.enabled:
            return [-b for b in offset]
        dead, drift = self.dead, self.drift
        return [-offset[i] if dead[i] else c if drift[i] is None else drift[i] - offset[i]
                for i, c in enumerate(velocity_commands)]

    def clear_faults(self) -> None:
        for i in range(self.n_axes):
            self.dead[i] = False
            self.drift[i] = None


class Encoders:
    """The incremental encoders and their index (Z) pulses, per axis: counts from the
    power-up position, index pulses at ``k * index_spacing`` counted and latched, and the
    frozen encoder's fault. Not real-time (set-up); the methods say which run in the tick."""

    def __init__(self, axes, parks: list[float]):
        n = self.n_axes = len(axes)
        self.cpu = [a.counts_per_unit for a in axes]
        self.spacing = [a.index_spacing for a in axes]
        self.power_up = tuple(parks)
        self.rev = [_floor(x / s) for x, s in zip(parks, self.spacing)]  # index interval
        # counts = base + floor((x - origin) * cpu)
        self.origin = list(parks)
        self.base = [0] * n
        self.counts = [0] * n
        self.index_events = [0] * n
        self.latched = [0] * n
        self.index_active = [False] * n
        self.any_index_active = False  # some element of index_active is set (cleared at the next step)
        self.frozen = [False] * n

    def end_pulses(self) -> None:
        """Real-time: the pulses of the last step are over."""
        self.any_index_active = False
        index_active = self.index_active
        for i in range(self.n_axes):
            index_active[i] = False

    def index_check(self, i: int, x: float) -> bool:
        """Real-time: index pulses of axis ``i`` now at ``x``: detect a crossing of ``k *
        spacing``, count it and latch the encoder there. True when the axis changed index
        interval."""
        spacing = self.spacing[i]
        r = _floor(x / spacing)
        r_old = self.rev[i]
        if r == r_old:
            return False
        self.rev[i] = r
        self.index_active[i] = True
        self.any_index_active = True
        if r > r_old:  # moving up: the last crossed is r * spacing
            self.index_events[i] += r - r_old
            z = r * spacing
        else:  # moving down: the last crossed is (r + 1) * spacing
            self.index_events[i] += r_old - r
            z = (r + 1) * spacing
        self.latched[i] = self.base[i] + _floor((z - self.origin[i]) * self.cpu[i])
        return True

    def frozen_readings(self) -> list[tuple[int, int, int, int]]:
        """Real-time (the rare path): before a step, what each frozen encoder shows, to be
        put back after it (:meth:`restore`)."""
        return [(i, self.counts[i], self.index_events[i], self.latched[i])
                for i, frozen in enumerate(self.frozen) if frozen]

    def restore(self, saved: list[tuple[int, int, int, int]]) -> None:
        for i, counts, events, latched in saved:
            self.counts[i], self.index_events[i], self.latched[i] = counts, events, latched
            self.index_active[i] = False

    def thaw(self, positions: list[float]) -> None:
        """Not real-time: every frozen encoder counts on from the value it froze at, the
        axis now at ``positions`` (the counts it missed stay missed)."""
        for i in range(self.n_axes):
            if self.frozen[i]:
                self.base[i] = self.counts[i]
                self.origin[i] = positions[i]
                self.frozen[i] = False


class Brakes:
    """The brakes, all axes together: engaged at power-up; a release or an application
    takes ``brake_time`` of simulated time before it is effective. Real-time."""

    def __init__(self, brake_time: float):
        self.brake_time = brake_time
        self.engaged = True
        self.target = True
        self.timer = 0.0

    def command(self, engage: bool) -> bool:
        """Start engaging (or releasing) them; True when they engaged at once (no
        ``brake_time``): the axes stop dead."""
        if engage == self.engaged:  # already so: cancel a change under way
            self.target = engage
            self.timer = 0.0
        elif engage != self.target or self.timer == 0.0:
            self.target = engage
            if self.brake_time > 0.0:
                self.timer = self.brake_time
            else:
                self.engaged = engage
                return engage
        return False

    def run(self, dt: float) -> bool:
        """``dt`` seconds of a change under way; True when they just engaged (the axes stop
        dead)."""
        self.timer -= dt
        if self.timer <= 1e-9:
            self.timer = 0.0
            self.engaged = self.target
            return self.engaged
        return False

    def released(self) -> bool:
        return not self.engaged

    def applied(self) -> bool:
        return self.engaged and self.timer == 0.0


class HomingSensors:
    """The inductive homing sensors, per axis: active while ``|x - sensor_position| <=
    sensor_window``, unless dead (a fault). Real-time."""

    def __init__(self, axes):
        self.at = [a.sensor_position for a in axes]
        self.window = [a.sensor_window for a in axes]
        self.dead = [False] * len(axes)

    def active(self, positions: list[float]) -> tuple[bool, ...]:
        sensors = []
        for x, at, window, dead in zip(positions, self.at, self.window, self.dead):
            sensors.append(not dead and -window <= x - at <= window)
        return tuple(sensors)

    def clear_faults(self) -> None:
        for i in range(len(self.dead)):
            self.dead[i] = False


class SimRobot(RobotBackend, DigitalIo):
    """A simulated robot for ``spec``; ``seed`` fixes its drive offsets and park positions.
    Its parts: :attr:`drives` (and the joints they move), :attr:`encoders` (and index
    pulses), :attr:`brakes`, :attr:`sensors` (homing); its digital I/O is its own
    (:class:`~runtime.hardware.interface.DigitalIo`, forcible). It steps them together and
    keeps, per axis, what the step needs of two parts at once: the safe interval and the
    step's constants.

    Not real-time (set-up): builds the per-axis state from the specification.
    """

    forcible = True  # its inputs are the world's side: tests and scenarios set them
    FAULTS = FAULTS

    def __init__(self, spec, seed: int = 0):
        DigitalIo.__init__(self, spec.inputs, spec.outputs, spec.name, spec.analog_inputs, spec.analog_outputs)
        self.spec = spec
        self.seed = seed
        axes = spec.axes
        n = self.n_axes = len(axes)
        sim = spec.simulation  # validated (compiler.params), every key present
        max_offset = sim.max_drive_offset
        spread = sim.park_spread
        rng = random.Random(seed)
        offsets, parks = [], []
        for axis in axes:  # the order of draws is part of the determinism contract
            offsets.append(rng.uniform(-max_offset, max_offset))
            parks.append(min(max(axis.home + rng.uniform(-spread, spread), axis.min), axis.max))
        self.drives = Drives(axes, sim, offsets, parks)
        self.encoders = Encoders(axes, parks)
        self.brakes = Brakes(sim.brake_time)
        self.sensors = HomingSensors(axes)
        # Per axis, the open interval in which a step needs no hard-stop or index check:
        # strictly inside the current index interval and within the end stops (see _set_safe).
        self._safe_lo = [0.0] * n
        self._safe_hi = [0.0] * n
        for i in range(n):
            self._set_safe(i)
        # the step loop's per-axis constants, one tuple per axis (see _set_constants)
        self._constants: tuple = ()
        self._set_constants()
        self._fault_path = False  # a drive or encoder fault, or the torque off: step's slower path
        self.time = 0.0  # simulated seconds since power-up

    def _set_constants(self) -> None:
        """Not real-time: the per-axis values the step reads, as one tuple per axis
        (unpacked in the loop: cheaper than indexing six lists); again whenever a drive's
        offset or the encoder's base or origin change."""
        d, e = self.drives, self.encoders
        self._constants = tuple(zip(d.vmax, [-v for v in d.vmax], d.offset, e.origin, e.cpu, e.base))

    def _set_safe(self, i: int) -> None:
        """Axis ``i``'s safe interval: strictly inside its current index interval (a
        margin keeps the crossing test exact at the interval's ends) and within its end
        stops. Inside it a step needs neither the hard-stop nor the index check."""
        spacing, r = self.encoders.spacing[i], self.encoders.rev[i]
        margin = 1e-9 * spacing * (1 + abs(r))
        self._safe_lo[i] = max(r * spacing + margin, self.drives.lo[i])
        self._safe_hi[i] = min((r + 1) * spacing - margin, self.drives.hi[i])

    # ---- the real-time interface -----------------------------------------------------

    def step(self, dt: float, velocity_commands) -> None:
        """Advance the physics by ``dt`` seconds with the drives commanded to
        ``velocity_commands`` (unit/s, one per axis, held over the step; a tuple of floats
        goes straight to :func:`runtime.kernels.drive_step`, any other sequence is
        converted first; a wrong count is a ``ValueError``).

        Real-time: plain float arithmetic, no allocation beyond a few floats.
        """
        drives, encoders, brakes = self.drives, self.encoders, self.brakes
        if dt != drives.dt:
            drives.discretise(dt)
        if encoders.any_index_active:  # pulses last one step
            encoders.end_pulses()
        if brakes.engaged:
            drives.hold()
        else:
            saved = None
            if self._fault_path:  # rare: the loop below stays free of fault checks
                velocity_commands = drives.fault_commands(velocity_commands)
                saved = encoders.frozen_readings()
            if type(velocity_commands) is not tuple or len(velocity_commands) != self.n_axes:
                velocity_commands = self._command_tuple(velocity_commands)
            drive_step(dt, drives.decay, drives.lag_gain, velocity_commands, drives.x, drives.v, self._safe_lo,
                       self._safe_hi, self._constants, encoders.counts, self._edges)
            if saved is not None:
                encoders.restore(saved)
        if brakes.timer > 0.0 and brakes.run(dt):  # the brake holds the axis: it stops dead
            drives.hold()
        self.time += dt

    def _command_tuple(self, velocity_commands) -> tuple[float, ...]:
        """The commands as the tuple of floats the kernel takes (one per axis)."""
        commands = tuple([float(c) for c in velocity_commands])
        if len(commands) != self.n_axes:
            raise ValueError(f"{len(commands)} velocity commands for {self.n_axes} axes")
        return commands

    def _edges(self, i: int, x: float, v: float) -> tuple[float, float]:
        """The step's slow path for axis ``i`` at ``x`` moving at ``v``, outside its safe
        interval: the hard stops (the axis stops there), then the index pulses."""
        x, v = self.drives.hard_stop(i, x, v)
        if self.encoders.index_check(i, x):
            self._set_safe(i)
        return x, v

    def read(self):
        """The encoder side: ``(counts, index_event_counters, latched_index_counts,
        sensor_active)``, each a tuple with one element per axis.

        ``index_event_counters`` only grows: it counts every index pulse since power-up;
        ``latched_index_counts`` is the encoder count at the last one. Real-time.
        """
        e = self.encoders
        return tuple(e.counts), tuple(e.index_events), tuple(e.latched), self.sensors.active(self.drives.x)

    def read_counts(self) -> tuple[int, ...]:
        """Only the encoder counts (the per-tick read once homing is done). Real-time."""
        return tuple(self.encoders.counts)

    def release_brakes(self) -> None:
        """Start releasing the brakes; effective after ``brake_time``. Real-time."""
        self.brakes.command(False)

    def apply_brakes(self) -> None:
        """Start applying the brakes; effective after ``brake_time``. Real-time."""
        if self.brakes.command(True):
            self.drives.hold()

    def disable_drives(self) -> None:
        """Safe torque off: the drives ignore their commands from the next step on (the
        axes coast to rest with the drives' lag). Real-time."""
        self.drives.enabled = False
        self._fault_path = True

    def enable_drives(self) -> None:
        """Torque on again: the drives follow their commands. Real-time."""
        self.drives.enabled = True
        self._update_fault_path()

    def drives_enabled(self) -> bool:
        return self.drives.enabled

    @property
    def end_stops(self) -> tuple[tuple[float, float], ...]:
        """Per axis, where the mechanical end stops are: (low, high)."""
        return tuple(zip(self.drives.lo, self.drives.hi))

    def brakes_released(self) -> bool:
        """True once the brakes are released and the axes can move. Real-time."""
        return not self.brakes.engaged

    def brakes_applied(self) -> bool:
        """True once the brakes are engaged and hold the axes (and no release is under
        way). Real-time."""
        return self.brakes.applied()

    @property
    def index_active(self) -> tuple[bool, ...]:
        """Per axis: an index pulse happened during the last step. Real-time."""
        return tuple(self.encoders.index_active)

    # ---- faults (set-up and tests) -------------------------------------------------------

    def inject(self, fault: str, axis: int) -> None:
        """Inject ``fault`` (one of :data:`FAULTS`) on axis ``axis`` (0-based)."""
        flags = self._fault_flags(fault)
        self._check_axis(axis)
        flags[axis] = True
        self._update_fault_path()

    def _check_axis(self, axis: int) -> None:
        if not 0 <= axis < self.n_axes:
            raise IndexError(f"axis {axis} does not exist: {self.spec.name} has axes 0..{self.n_axes - 1}")

    def _update_fault_path(self) -> None:
        """Whether a step takes the slower path (the drives' fault commands, the frozen
        encoders' readings put back)."""
        self._fault_path = any(self.encoders.frozen) or self.drives.faulty()

    def clear_faults(self) -> None:
        """Remove every injected fault. The encoder of a frozen axis counts on from the
        value it froze at (the counts it missed stay missed)."""
        self.encoders.thaw(self.drives.x)
        self.drives.clear_faults()
        self.sensors.clear_faults()
        self._fault_path = not self.drives.enabled
        self._set_constants()

    def set_drive_offset(self, axis: int, offset: float) -> None:
        """Make the drive of ``axis`` drift at ``offset`` unit/s under a zero command (a
        drive whose offset changed since calibration; tests and scenarios)."""
        self._check_axis(axis)
        self.drives.offset[axis] = float(offset)
        self._set_constants()

    def set_drift(self, axis: int, velocity: float | None) -> None:
        """Make the drive of ``axis`` run at ``velocity`` unit/s whatever it is commanded
        (a drive that lost its command value or its current loop: a drift the servo cannot
        hold, unlike :meth:`set_drive_offset`'s), until ``None`` or :meth:`clear_faults`.
        The brakes and safe torque off still stop it. Tests and scenarios."""
        self._check_axis(axis)
        self.drives.drift[axis] = None if velocity is None else float(velocity)
        self._update_fault_path()

    def faults(self) -> tuple[tuple[str, int], ...]:
        """The faults in effect, as (fault, axis) pairs."""
        return tuple((f, i) for f in FAULTS for i in range(self.n_axes) if self._fault_flags(f)[i])

    def _fault_flags(self, fault: str) -> list[bool]:
        """The per-axis flags of ``fault``, held by the part it breaks."""
        if fault == "sensor_dead":
            return self.sensors.dead
        if fault == "encoder_frozen":
            return self.encoders.frozen
        if fault == "drive_dead":
            return self.drives.dead
        raise ValueError(f"unknown fault {fault!r}: expected one of {', '.join(FAULTS)}")

    # ---- the truth (tests and the report's truth column only) ----------------------------

    @property
    def true_positions(self) -> tuple[float, ...]:
        """The axes' actual positions (unit). Not for the controller: it sees encoders."""
        return self.drives.positions

    @property
    def true_velocities(self) -> tuple[float, ...]:
        """The axes' actual velocities (unit/s)."""
        return self.drives.velocities

    @property
    def power_up_positions(self) -> tuple[float, ...]:
        """Where each axis parked at power-up (its encoder's zero)."""
        return self.encoders.power_up

    @property
    def drive_offsets(self) -> tuple[float, ...]:
        """Each drive's constant velocity offset (unit/s)."""
        return tuple(self.drives.offset)
