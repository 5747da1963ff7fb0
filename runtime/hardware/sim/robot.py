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
from runtime.hardware.interface import IoBackend, RobotBackend
from runtime.hardware.faults import FAULTS

drive_step = kernels.drive_step


_floor = math.floor


class SimRobot(RobotBackend, IoBackend):
    """A simulated robot for ``spec``; ``seed`` fixes its drive offsets and park positions.

    Not real-time (set-up): builds the per-axis state from the specification.
    """

    forcible = True  # its inputs are the world's side: tests and scenarios set them
    FAULTS = FAULTS

    def __init__(self, spec, seed: int = 0):
        self.spec = spec
        self.seed = seed
        axes = spec.axes
        n = self.n_axes = len(axes)
        sim = spec.simulation  # validated (compiler.params), every key present
        self.tau = sim.drive_time_constant
        max_offset = sim.max_drive_offset
        spread = sim.park_spread
        self.brake_time = sim.brake_time
        saturation = sim.drive_saturation
        margin = sim.end_stop_margin

        rng = random.Random(seed)
        offsets, parks = [], []
        for axis in axes:  # the order of draws is part of the determinism contract
            offsets.append(rng.uniform(-max_offset, max_offset))
            parks.append(min(max(axis.home + rng.uniform(-spread, spread), axis.min), axis.max))

        # constants per axis
        self._offset = offsets
        self._lo = [a.min - margin for a in axes]  # the mechanical end stops
        self._hi = [a.max + margin for a in axes]
        self._vmax = [saturation * a.max_velocity for a in axes]
        self._cpu = [a.counts_per_unit for a in axes]
        self._spacing = [a.index_spacing for a in axes]
        self._sensor_at = [a.sensor_position for a in axes]
        self._sensor_window = [a.sensor_window for a in axes]
        self._power_up = tuple(parks)

        # physical state
        self._x = list(parks)
        self._v = [0.0] * n
        self._rev = [_floor(x / s) for x, s in zip(parks, self._spacing)]  # index interval
        # encoder state: counts = base + floor((x - origin) * cpu)
        self._origin = list(parks)
        self._base = [0] * n
        self._counts = [0] * n
        self._index_events = [0] * n
        self._latched = [0] * n
        self._index_active = [False] * n
        self._any_index_active = False  # some element of _index_active is set (cleared at the next step)
        # Per axis, the open interval in which a step needs no hard-stop or index check:
        # strictly inside the current index interval and within min..max (see _set_safe).
        self._safe_lo = [0.0] * n
        self._safe_hi = [0.0] * n
        for i in range(n):
            self._set_safe(i)
        # the step loop's per-axis constants, one tuple per axis (see _set_constants)
        self._constants: tuple = ()
        self._set_constants()
        # faults
        self._sensor_dead = [False] * n
        self._encoder_frozen = [False] * n
        self._drive_dead = [False] * n
        self._drift: list[float | None] = [None] * n  # a drive's own velocity, whatever it is commanded
        self._drives_enabled = True  # safe torque off when False
        self._drive_or_encoder_fault = False  # a fault above, or drives disabled: step's slower path
        # brakes: engaged at power-up
        self._brakes_engaged = True
        self._brake_target = True
        self._brake_timer = 0.0
        # digital I/O, numbered from 1 (element n - 1)
        self._inputs = [False] * spec.inputs
        self._outputs = [False] * spec.outputs
        # the step's discretisation, cached for the last dt
        self._dt = -1.0
        self._decay = 0.0
        self._lag_gain = 0.0
        self.time = 0.0  # simulated seconds since power-up

    def _set_constants(self) -> None:
        """Not real-time: the per-axis values the step reads, as one tuple per axis
        (unpacked in the loop: cheaper than indexing six lists); again whenever the
        encoder's base or origin change."""
        self._constants = tuple(zip(self._vmax, [-v for v in self._vmax], self._offset,
                                    self._origin, self._cpu, self._base))

    # ---- the real-time interface -----------------------------------------------------

    def step(self, dt: float, velocity_commands) -> None:
        """Advance the physics by ``dt`` seconds with the drives commanded to
        ``velocity_commands`` (unit/s, one per axis, held over the step; a tuple of floats
        goes straight to :func:`runtime.kernels.drive_step`, any other sequence is
        converted first; a wrong count is a ``ValueError``).

        Real-time: plain float arithmetic, no allocation beyond a few floats.
        """
        if dt != self._dt:
            self._dt = dt
            self._decay = math.exp(-dt / self.tau)
            self._lag_gain = self.tau * (1.0 - self._decay)
        a = self._decay
        k = self._lag_gain
        xs, vs = self._x, self._v
        if self._any_index_active:  # pulses last one step
            self._any_index_active = False
            index_active = self._index_active
            for i in range(self.n_axes):
                index_active[i] = False
        if self._brakes_engaged:
            for i in range(self.n_axes):
                vs[i] = 0.0
        else:
            saved = None
            if self._drive_or_encoder_fault:  # rare: the loop below stays free of fault checks
                velocity_commands, saved = self._fault_commands(velocity_commands)
            if type(velocity_commands) is not tuple or len(velocity_commands) != self.n_axes:
                velocity_commands = self._command_tuple(velocity_commands)
            drive_step(dt, a, k, velocity_commands, xs, vs, self._safe_lo, self._safe_hi, self._constants,
                       self._counts, self._edges)
            if saved is not None:
                self._restore_frozen(saved)
        if self._brake_timer > 0.0:
            self._brake_timer -= dt
            if self._brake_timer <= 1e-9:
                self._brake_timer = 0.0
                self._brakes_engaged = self._brake_target
                if self._brakes_engaged:  # the brake holds the axis: it stops dead
                    for i in range(self.n_axes):
                        vs[i] = 0.0
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
        if x > self._hi[i]:
            x = self._hi[i]
            if v > 0.0:
                v = 0.0
        elif x < self._lo[i]:
            x = self._lo[i]
            if v < 0.0:
                v = 0.0
        self._index_check(i, x)
        return x, v

    def _fault_commands(self, velocity_commands) -> tuple[list, list]:
        """Before a step with drive or encoder faults: a dead drive gets the command that
        cancels its offset (it then produces nothing: u = -b + b = 0 exactly), and what a
        frozen encoder shows is saved, to be put back after the step."""
        dead, offset = self._drive_dead, self._offset
        if not self._drives_enabled:  # no torque: every axis coasts (as a dead drive does)
            commands = [-b for b in offset]
        else:
            drift = self._drift
            commands = [-offset[i] if dead[i] else c if drift[i] is None else drift[i] - offset[i]
                        for i, c in enumerate(velocity_commands)]
        saved = [(i, self._counts[i], self._index_events[i], self._latched[i])
                 for i, frozen in enumerate(self._encoder_frozen) if frozen]
        return commands, saved

    def _restore_frozen(self, saved: list) -> None:
        for i, counts, events, latched in saved:
            self._counts[i], self._index_events[i], self._latched[i] = counts, events, latched
            self._index_active[i] = False

    def _index_check(self, i: int, x: float) -> None:
        """Index pulses of axis ``i`` now at ``x``: detect a crossing of ``k * spacing``,
        count it and latch the encoder there."""
        spacing = self._spacing[i]
        r = _floor(x / spacing)
        r_old = self._rev[i]
        if r == r_old:
            return
        self._rev[i] = r
        self._set_safe(i)
        self._index_active[i] = True
        self._any_index_active = True
        if r > r_old:  # moving up: the last crossed is r * spacing
            self._index_events[i] += r - r_old
            z = r * spacing
        else:  # moving down: the last crossed is (r + 1) * spacing
            self._index_events[i] += r_old - r
            z = (r + 1) * spacing
        self._latched[i] = self._base[i] + _floor((z - self._origin[i]) * self._cpu[i])

    def _set_safe(self, i: int) -> None:
        """Axis ``i``'s safe interval: strictly inside its current index interval (a
        margin keeps the crossing test exact at the interval's ends) and within its
        min..max. Inside it a step needs neither the hard-stop nor the index check."""
        spacing, r = self._spacing[i], self._rev[i]
        margin = 1e-9 * spacing * (1 + abs(r))
        self._safe_lo[i] = max(r * spacing + margin, self._lo[i])
        self._safe_hi[i] = min((r + 1) * spacing - margin, self._hi[i])

    def read(self):
        """The encoder side: ``(counts, index_event_counters, latched_index_counts,
        sensor_active)``, each a tuple with one element per axis.

        ``index_event_counters`` only grows: it counts every index pulse since power-up;
        ``latched_index_counts`` is the encoder count at the last one. Real-time.
        """
        sensors = []
        for x, at, window, dead in zip(self._x, self._sensor_at, self._sensor_window, self._sensor_dead):
            sensors.append(not dead and -window <= x - at <= window)
        return tuple(self._counts), tuple(self._index_events), tuple(self._latched), tuple(sensors)

    def read_counts(self) -> tuple[int, ...]:
        """Only the encoder counts (the per-tick read once homing is done). Real-time."""
        return tuple(self._counts)

    def release_brakes(self) -> None:
        """Start releasing the brakes; effective after ``brake_time``. Real-time."""
        self._command_brakes(False)

    def apply_brakes(self) -> None:
        """Start applying the brakes; effective after ``brake_time``. Real-time."""
        self._command_brakes(True)

    def _command_brakes(self, engage: bool) -> None:
        if engage == self._brakes_engaged:  # already so: cancel a change under way
            self._brake_target = engage
            self._brake_timer = 0.0
        elif engage != self._brake_target or self._brake_timer == 0.0:
            self._brake_target = engage
            if self.brake_time > 0.0:
                self._brake_timer = self.brake_time
            else:
                self._brakes_engaged = engage
                if engage:
                    for i in range(self.n_axes):
                        self._v[i] = 0.0

    def disable_drives(self) -> None:
        """Safe torque off: the drives ignore their commands from the next step on (the
        axes coast to rest with the drives' lag). Real-time."""
        self._drives_enabled = False
        self._drive_or_encoder_fault = True

    def enable_drives(self) -> None:
        """Torque on again: the drives follow their commands. Real-time."""
        self._drives_enabled = True
        self._update_fault_path()

    def drives_enabled(self) -> bool:
        return self._drives_enabled

    @property
    def end_stops(self) -> tuple[tuple[float, float], ...]:
        """Per axis, where the mechanical end stops are: (low, high)."""
        return tuple(zip(self._lo, self._hi))

    def brakes_released(self) -> bool:
        """True once the brakes are released and the axes can move. Real-time."""
        return not self._brakes_engaged

    def brakes_applied(self) -> bool:
        """True once the brakes are engaged and hold the axes (and no release is under
        way). Real-time."""
        return self._brakes_engaged and self._brake_timer == 0.0

    @property
    def index_active(self) -> tuple[bool, ...]:
        """Per axis: an index pulse happened during the last step. Real-time."""
        return tuple(self._index_active)

    # ---- digital I/O (numbered from 1, as in L-IRL; a backend of runtime.loop.components.io) --

    def set_input(self, n: int, value: bool) -> None:
        """Set digital input ``n`` (1..spec.inputs): the world's side, for tests and
        scenarios. Real-time."""
        self._inputs[self._io_index(n, len(self._inputs), "input")] = bool(value)

    def input(self, n: int) -> bool:
        """Digital input ``n`` (1..spec.inputs). Real-time."""
        return self._inputs[self._io_index(n, len(self._inputs), "input")]

    def set_output(self, n: int, value: bool) -> None:
        """Set digital output ``n`` (1..spec.outputs). Real-time."""
        self._outputs[self._io_index(n, len(self._outputs), "output")] = bool(value)

    def output(self, n: int) -> bool:
        """Digital output ``n`` (1..spec.outputs). Real-time."""
        return self._outputs[self._io_index(n, len(self._outputs), "output")]

    @property
    def inputs(self) -> tuple[bool, ...]:
        """All digital inputs; input n is element n - 1."""
        return tuple(self._inputs)

    @property
    def outputs(self) -> tuple[bool, ...]:
        """All digital outputs; output n is element n - 1."""
        return tuple(self._outputs)

    def _io_index(self, n: int, count: int, what: str) -> int:
        if not 1 <= n <= count:
            raise IndexError(f"digital {what} {n} does not exist: {self.spec.name} has {what}s 1..{count}")
        return n - 1

    # ---- faults (set-up and tests) -------------------------------------------------------

    def inject(self, fault: str, axis: int) -> None:
        """Inject ``fault`` (one of :data:`FAULTS`) on axis ``axis`` (0-based)."""
        table = self._fault_table(fault)
        if not 0 <= axis < self.n_axes:
            raise IndexError(f"axis {axis} does not exist: {self.spec.name} has axes 0..{self.n_axes - 1}")
        table[axis] = True
        self._update_fault_path()

    def _update_fault_path(self) -> None:
        """Whether a step takes the slower path of :meth:`_fault_commands`."""
        self._drive_or_encoder_fault = (any(self._encoder_frozen) or any(self._drive_dead)
                                        or any(d is not None for d in self._drift) or not self._drives_enabled)

    def clear_faults(self) -> None:
        """Remove every injected fault. The encoder of a frozen axis counts on from the
        value it froze at (the counts it missed stay missed)."""
        for i in range(self.n_axes):
            if self._encoder_frozen[i]:
                self._base[i] = self._counts[i]
                self._origin[i] = self._x[i]
            self._sensor_dead[i] = self._encoder_frozen[i] = self._drive_dead[i] = False
            self._drift[i] = None
        self._drive_or_encoder_fault = not self._drives_enabled
        self._set_constants()

    def set_drive_offset(self, axis: int, offset: float) -> None:
        """Make the drive of ``axis`` drift at ``offset`` unit/s under a zero command (a
        drive whose offset changed since calibration; tests and scenarios)."""
        if not 0 <= axis < self.n_axes:
            raise IndexError(f"axis {axis} does not exist: {self.spec.name} has axes 0..{self.n_axes - 1}")
        self._offset[axis] = float(offset)
        self._set_constants()

    def set_drift(self, axis: int, velocity: float | None) -> None:
        """Make the drive of ``axis`` run at ``velocity`` unit/s whatever it is commanded
        (a drive that lost its command value or its current loop: a drift the servo cannot
        hold, unlike :meth:`set_drive_offset`'s), until ``None`` or :meth:`clear_faults`.
        The brakes and safe torque off still stop it. Tests and scenarios."""
        if not 0 <= axis < self.n_axes:
            raise IndexError(f"axis {axis} does not exist: {self.spec.name} has axes 0..{self.n_axes - 1}")
        self._drift[axis] = None if velocity is None else float(velocity)
        self._update_fault_path()

    def faults(self) -> tuple[tuple[str, int], ...]:
        """The faults in effect, as (fault, axis) pairs."""
        return tuple((f, i) for f in FAULTS for i in range(self.n_axes) if self._fault_table(f)[i])

    def _fault_table(self, fault: str) -> list[bool]:
        if fault == "sensor_dead":
            return self._sensor_dead
        if fault == "encoder_frozen":
            return self._encoder_frozen
        if fault == "drive_dead":
            return self._drive_dead
        raise ValueError(f"unknown fault {fault!r}: expected one of {', '.join(FAULTS)}")

    # ---- the truth (tests and the report's truth column only) ----------------------------

    @property
    def true_positions(self) -> tuple[float, ...]:
        """The axes' actual positions (unit). Not for the controller: it sees encoders."""
        return tuple(self._x)

    @property
    def true_velocities(self) -> tuple[float, ...]:
        """The axes' actual velocities (unit/s)."""
        return tuple(self._v)

    @property
    def power_up_positions(self) -> tuple[float, ...]:
        """Where each axis parked at power-up (its encoder's zero)."""
        return self._power_up

    @property
    def drive_offsets(self) -> tuple[float, ...]:
        """Each drive's constant velocity offset (unit/s)."""
        return tuple(self._offset)
