"""The interfaces the loop's components use of a backend (the hardware side of the robot, as
ros2_control's hardware interfaces are): a backend derives from them, and nothing above
``runtime.hardware`` asks which backend it has.
"""
from __future__ import annotations

from typing import Sequence


class FieldbusError(ValueError):
    """A fieldbus file that cannot be used: where, what, and what is allowed."""


class IoBackend:
    """What the I/O component needs of a backend; a backend derives from it. Real-time:
    ``inputs``, ``outputs``, ``input``, ``set_output`` and ``lost`` (plain reads and
    assignments, never a wait). Not real-time: ``start`` (begin exchanging: a fieldbus's
    thread), ``close`` and ``wait_connected``. The defaults: never lost, nothing to start
    or close, always connected."""

    @property
    def inputs(self) -> Sequence[bool]:
        raise NotImplementedError

    @property
    def outputs(self) -> Sequence[bool]:
        raise NotImplementedError

    def input(self, n: int) -> bool:
        raise NotImplementedError

    def set_output(self, n: int, value: bool) -> None:
        raise NotImplementedError

    def set_outputs(self, first: int, values) -> None:
        """Outputs ``first``, ``first + 1``, ... to ``values`` at once (a group's: a fieldbus
        sends them in one exchange)."""
        for i, value in enumerate(values):
            self.set_output(first + i, value)

    def lost(self) -> str | None:
        """Why the backend counts as lost now (a PLC not heard from), or None."""
        return None

    def analog_input(self, n: int) -> float:
        """Real-time: what analog input ``n`` (1-based) reads now."""
        raise IndexError(f"analog input {n} does not exist: this robot's I/O has no analog inputs")

    def set_analog_output(self, n: int, value: float) -> None:
        """Real-time: analog output ``n`` (1-based) to ``value`` (checked by the caller)."""
        raise IndexError(f"analog output {n} does not exist: this robot's I/O has no analog outputs")

    def analog_output(self, n: int) -> float:
        """Real-time: what analog output ``n`` (1-based) was last set to."""
        raise IndexError(f"analog output {n} does not exist: this robot's I/O has no analog outputs")

    def start(self) -> None:
        pass

    def close(self) -> None:
        pass

    def wait_connected(self, timeout: float) -> bool:
        return True

    #: whether an input can be set from outside (:meth:`set_input`): the simulated robot's can,
    #: a real cell's are set by the cell
    forcible = False

    def set_input(self, n: int, value: bool) -> None:
        """Between ticks, on a forcible backend: set input ``n`` (1-based)."""
        raise PermissionError("an input is forced on the simulated robot only")


class DigitalIo(IoBackend):
    """Digital I/O held by the backend itself, numbered from 1 (input n is element n - 1
    of ``_inputs``, output n of ``_outputs``; ``owner`` names who has them in the
    messages): the simulated arm's own, or a PLC's as its exchange last saw them. Every
    method is real-time (plain reads and assignments); a number out of range is an
    ``IndexError`` that says which exist."""

    def __init__(self, n_inputs: int, n_outputs: int, owner: str, analog: tuple = (), analog_outputs: tuple = ()):
        self._inputs: list[bool] | tuple[bool, ...] = [False] * n_inputs
        self._outputs = [False] * n_outputs
        self._owner = owner
        # (compiler.spec.AnalogChannel: each reads the middle of its range, a typical reading, until set)
        self._analog = [(channel.low + channel.high) / 2.0 for channel in analog]
        # (each output at 0, or at its range's end nearest 0, until a program sets it)
        self._analog_out = [min(max(0.0, channel.low), channel.high) for channel in analog_outputs]

    @property
    def inputs(self) -> tuple[bool, ...]:
        """All digital inputs; input n is element n - 1."""
        return tuple(self._inputs)

    @property
    def outputs(self) -> tuple[bool, ...]:
        """All digital outputs; output n is element n - 1."""
        return tuple(self._outputs)

    def input(self, n: int) -> bool:
        return self._inputs[self._index(n, len(self._inputs), "input")]

    def output(self, n: int) -> bool:
        return self._outputs[self._index(n, len(self._outputs), "output")]

    def set_output(self, n: int, value: bool) -> None:
        self._outputs[self._index(n, len(self._outputs), "output")] = bool(value)

    def set_outputs(self, first: int, values) -> None:
        """Outputs ``first``, ``first + 1``, ... to ``values`` at once (a group's)."""
        for i, value in enumerate(values):
            self.set_output(first + i, value)

    def set_input(self, n: int, value: bool) -> None:
        """Between ticks, on a forcible backend (the world's side: tests and scenarios)."""
        if not self.forcible:
            super().set_input(n, value)
        self._inputs[self._index(n, len(self._inputs), "input")] = bool(value)

    def analog_input(self, n: int) -> float:
        return self._analog[self._index(n, len(self._analog), "input", "analog")]

    def set_analog_input(self, n: int, value: float) -> None:
        """Between ticks, on a forcible backend: what analog input ``n`` reads (checked by the caller)."""
        if not self.forcible:
            raise PermissionError("an analog input is set on the simulated robot only")
        self._analog[self._index(n, len(self._analog), "input", "analog")] = float(value)

    def set_analog_output(self, n: int, value: float) -> None:
        self._analog_out[self._index(n, len(self._analog_out), "output", "analog")] = float(value)

    def analog_output(self, n: int) -> float:
        return self._analog_out[self._index(n, len(self._analog_out), "output", "analog")]

    def _index(self, n: int, count: int, what: str, kind: str = "digital") -> int:
        if not 1 <= n <= count:
            named = f"{what}s" if kind == "digital" else f"{kind} {what}s"
            raise IndexError(f"{kind} {what} {n} does not exist: {self._owner} has {named} 1..{count}")
        return n - 1


class NoIo(IoBackend):
    """A robot without digital I/O (a hardware backend that does not derive from
    IoBackend): no inputs, no outputs."""

    inputs = outputs = ()

    def input(self, n: int) -> bool:
        raise IndexError(f"digital input {n} does not exist: this robot has no digital I/O")

    def set_output(self, n: int, value: bool) -> None:
        raise IndexError(f"digital output {n} does not exist: this robot has no digital I/O")


class RobotBackend:
    """What the loop needs of a robot (the arm's drives, encoders, brakes and homing sensors;
    the hardware interface of ros2_control): the Robot Interface component
    (runtime.loop.components.robot_interface) and the robot system
    (runtime.loop.system) call these and nothing else. A backend derives from it (the
    simulated arm, :class:`runtime.hardware.sim.robot.SimRobot`); one with digital I/O of its
    own derives from :class:`IoBackend` too. Axes are numbered from 0, in the order of
    ``spec.axes``.

    Real-time (every 1 ms tick, or a fault's reaction within one): ``read``,
    ``read_counts``, ``step``, the brake and drive operations and their states: plain
    reads and assignments, never a wait. Not real-time: ``inject`` (set-up)."""

    #: the faults ``inject`` can give this backend (:data:`runtime.hardware.faults.FAULTS` on
    #: the simulated arm; none on hardware)
    FAULTS: tuple[str, ...] = ()

    def read(self) -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...], tuple[bool, ...]]:
        """The encoder side, one element per axis in each tuple: ``(counts,
        index_event_counters, latched_index_counts, sensor_active)``: the incremental
        counts; how many index (Z) pulses since power-up (it only grows); the count latched
        at the last one; whether the homing sensor is active."""
        raise NotImplementedError

    def read_counts(self) -> tuple[int, ...]:
        """Only the encoder counts (the per-tick read once homing is done)."""
        raise NotImplementedError

    def step(self, dt: float, velocity_commands: tuple[float, ...]) -> None:
        """Command the drives to ``velocity_commands`` (unit/s, one per axis) for the next
        ``dt`` seconds (a simulation advances its physics by ``dt``)."""
        raise NotImplementedError

    def release_brakes(self) -> None:
        """Start releasing the brakes (:meth:`brakes_released` says when they are)."""
        raise NotImplementedError

    def apply_brakes(self) -> None:
        """Start applying the brakes (:meth:`brakes_applied` says when they hold)."""
        raise NotImplementedError

    def brakes_released(self) -> bool:
        """True once the brakes are released and the axes can move."""
        raise NotImplementedError

    def brakes_applied(self) -> bool:
        """True once the brakes hold the axes (and no release is under way)."""
        raise NotImplementedError

    def disable_drives(self) -> None:
        """Safe torque off, at once: the drives ignore their commands until
        :meth:`enable_drives`."""
        raise NotImplementedError

    def enable_drives(self) -> None:
        """Torque on: the drives follow their commands again."""
        raise NotImplementedError

    def drives_enabled(self) -> bool:
        raise NotImplementedError

    def inject(self, fault: str, axis: int) -> None:
        """Set-up: give axis ``axis`` the fault ``fault`` (one of :attr:`FAULTS`)."""
        raise ValueError(f"the fault {fault!r} cannot be injected: this robot backend has "
                         + (f"the faults {', '.join(self.FAULTS)}" if self.FAULTS else "no injectable faults"))
