"""The digital I/O as a component (``io``): the robot's inputs and outputs in two ports.

Ports (latest value, one writer: this component): ``inputs`` (every digital input, input n
at index n - 1) and ``outputs`` (every digital output), tuples of bools.

Sense (every 1 ms, the first task of the tick): the simulated cell acts first, when there
is one (:class:`runtime.hardware.sim.cell.Cell`: the world before anything reads it); then the
backend's inputs go to ``inputs``; then the backend's health is checked: a backend that
says it is lost (a PLC with no good exchange within its timeout) makes the robot system
take its emergency stop (category 1), once per cycle, with "the fieldbus is lost: <why>".
Inputs of another number than the backend had when it was opened are not taken (the port
keeps the last ones, of the right number) and stop the robot the same way ("the I/O is
not trusted: ...").
The program's outputs go through :meth:`IoComponent.set_output`: to the backend and to
``outputs`` in the same call (the same tick: never one later).

The I/O itself is a backend behind one small interface (:class:`IoBackend`, their base class): the simulated
robot's own I/O (:class:`runtime.hardware.sim.robot.SimRobot`, the default) or a PLC over Modbus
TCP (:class:`runtime.hardware.fieldbus.ModbusIo`, its exchange on a thread of its own). A hardware
robot backend brings its own I/O the same way; one without any leaves the ports empty.
"""
from __future__ import annotations


from runtime.hardware.interface import IoBackend, NoIo
from runtime.loop.component import Component, DataPort
from runtime.timing import TICK

LOST = "the fieldbus is lost: "  # the emergency stop's reason, then the backend's why


class ZoneSignals:
    """The signal zones (compiler.zones, ``kind = "signal"``): each one's digital output
    true while the tool centre point is inside the zone, false while it is not; set where
    that changes (so a program may still switch the output between changes). ``tcp()``
    gives the tool centre point in the world (x, y, z, mm), or None while it is not known
    (the axes not referenced yet: nothing is switched). Real-time: one forward kinematics
    a tick."""

    def __init__(self, zones: tuple, tcp):
        self.zones, self.tcp = zones, tcp
        self.reset()

    def reset(self) -> None:
        """A new cycle: each output is set at the first tick the tool is known."""
        self.inside: list = [None] * len(self.zones)

    def update(self, io: "IoComponent") -> None:
        point = self.tcp()
        if point is None:
            return
        x, y, z = point
        inside = self.inside
        for i, zone in enumerate(self.zones):
            now = zone.depth(x, y, z) > 0.0
            if now != inside[i]:
                inside[i] = now
                io.set_output(zone.output, now)


def backend_of(robot) -> IoBackend:
    """The I/O backend of a robot backend: itself when it has I/O (the simulated robot), else
    :class:`NoIo`."""
    return robot if isinstance(robot, IoBackend) else NoIo()


class IoComponent(Component):
    """The I/O component; also the scripting interface's ``io`` target (read-only
    ``inputs`` and ``outputs``, ``in[n]`` and ``out[n]``; ``in[n] = ...`` forces an input on
    the simulated robot only). It has no operations: the robot system alone drives its
    lifecycle (configured when the system is built, started by ``begin``, stopped when the
    cycle is finished)."""

    PROPERTIES: dict = {}
    READ_ONLY = {"inputs": "every digital input (input n at index n - 1)",
                 "outputs": "every digital output (output n at index n - 1)"}
    #: element-wise properties: name -> (what, writable)
    INDEXED = {"in": ("a digital input, numbered from 1", True), "out": ("a digital output, numbered from 1", False)}
    OPERATIONS: tuple[str, ...] = ()

    def __init__(self, backend: IoBackend, cell=None, on_lost=None, tick: float = TICK):
        super().__init__("io", tick)
        self.backend = backend
        self.cell = cell  # a runtime.hardware.sim.cell.Cell driving the simulated backend's inputs, or None
        self.zone_signals: ZoneSignals | None = None  # the signal zones' outputs (set by the system)
        self.on_lost = on_lost  # callable(reason): the system's emergency stop
        self.inputs = DataPort("inputs", ())
        self.outputs = DataPort("outputs", ())
        self.lost_reason: str | None = None  # why the backend was lost in this cycle (None: it was not)
        self.n_inputs: int | None = None  # how many inputs the backend has (from when it is opened)
        self._opened = False
        self._now = 0.0

    # -- lifecycle (not real-time) --
    def on_configure(self) -> bool:
        """Open the backend once (a fieldbus starts exchanging: its thread) and show its I/O."""
        if not self._opened:
            self.backend.start()
            self._opened = True
            self.n_inputs = len(self.backend.inputs)
        self.refresh()
        return True

    def on_start(self) -> bool:
        self.lost_reason = None  # a new cycle: a loss is taken once in each
        if self.zone_signals is not None:
            self.zone_signals.reset()
        self.refresh()
        return True

    def close(self) -> None:
        """Not real-time: end the backend's exchange (if it has one)."""
        if self._opened:
            self.backend.close()
        self._opened = False

    def wait_connected(self, timeout: float) -> bool:
        """Not real-time: wait up to ``timeout`` s for the backend to be reachable."""
        return self.backend.wait_connected(timeout)

    def lost(self) -> str | None:
        """Why the backend counts as lost now, or None."""
        return self.backend.lost()

    def refresh(self, now: float | None = None) -> None:
        """Real-time safe, outside the tick's task (set-up, and the server's idle turns, when
        no task reads the backend): the backend's inputs and outputs into the ports."""
        stamp = self._now if now is None else now
        inputs = tuple(self.backend.inputs)
        if self.n_inputs is None or len(inputs) == self.n_inputs:
            self.inputs.write(inputs, stamp)
        self.outputs.write(tuple(self.backend.outputs), stamp)

    # -- real-time --
    def update(self, now: float) -> None:
        """Sense: the cell acts, the inputs are read, the backend's health is checked."""
        self._now = now
        if self.cell is not None:
            self.cell.update(now)
        if self.zone_signals is not None:
            self.zone_signals.update(self)
        inputs = tuple(self.backend.inputs)
        if len(inputs) == self.n_inputs:
            self.inputs.write(inputs, now)
        elif self.lost_reason is None:  # not the robot's inputs: not taken (the port keeps the last ones)
            self.lost_reason = (f"the I/O is not trusted: it gave {len(inputs)} inputs, the robot has "
                                f"{self.n_inputs}")
            if self.on_lost is not None:
                self.on_lost(self.lost_reason)
        if self.lost_reason is None:
            why = self.backend.lost()
            if why is not None:
                self.lost_reason = why
                if self.on_lost is not None:
                    self.on_lost(LOST + why)

    def input(self, n: int) -> bool:
        """Digital input ``n`` (1..): as read at this tick's start."""
        return self.inputs.value[n - 1]

    def output(self, n: int) -> bool:
        return self.outputs.value[n - 1]

    def analog_input(self, n: int) -> float:
        """Analog input ``n`` (1..): what the backend reads now (the simulated cell's value, a
        PLC's register as its exchange last saw it)."""
        return self.backend.analog_input(n)

    def analog_output(self, n: int) -> float:
        """Analog output ``n`` (1..): what it was last set to."""
        return self.backend.analog_output(n)

    def set_analog_output(self, n: int, value: float) -> None:
        """Analog output ``n`` (1..) to ``value`` (checked against its range by the caller)."""
        self.backend.set_analog_output(n, value)

    def analog_values(self, inputs: int, outputs: int) -> tuple:
        """Real-time: analog inputs 1..``inputs`` as read now, then outputs 1..``outputs`` as
        last set (the report's analog columns); NaN for one the backend does not have (a PLC
        whose fieldbus file maps none)."""
        backend, values = self.backend, []
        for read, count in ((backend.analog_input, inputs), (backend.analog_output, outputs)):
            for n in range(1, count + 1):
                try:
                    values.append(read(n))
                except IndexError:
                    values.append(float("nan"))
        return tuple(values)

    def set_output(self, n: int, value: bool) -> None:
        """Digital output ``n`` (1..) to ``value``: the backend and the ``outputs`` port now."""
        backend = self.backend
        backend.set_output(n, value)
        self.outputs.write(tuple(backend.outputs), self._now)

    def set_outputs(self, first: int, values) -> None:
        """Digital outputs ``first``.. to ``values`` at once (a group: one exchange on a fieldbus)."""
        backend = self.backend
        backend.set_outputs(first, values)
        self.outputs.write(tuple(backend.outputs), self._now)

    # -- the scripting interface (between ticks) --
    def element(self, name: str, n: int) -> bool:
        values = self.inputs.value if name == "in" else self.outputs.value
        if not 1 <= n <= len(values):
            raise IndexError(f"io.{name}[{n}]: there is no {'input' if name == 'in' else 'output'} {n} "
                             f"(1..{len(values)})")
        return values[n - 1]

    def force(self, n: int, value) -> None:
        """Between ticks: set input ``n`` on the simulated robot (the port too: a read that
        follows sees it; a cell scenario's rule may change it again)."""
        if not self.backend.forcible:
            raise PermissionError("an input is forced on the simulated robot only; on hardware or a fieldbus the "
                                  "cell sets it")
        if not isinstance(value, bool):
            raise TypeError(f"io.in[{n}]: expected true or false, got {_format(value)}")
        self.element("in", n)  # (the range check)
        self.backend.set_input(n, value)
        self.inputs.write(tuple(self.backend.inputs), self._now)


def _format(value) -> str:
    from runtime.wire.scripting import format_value

    return format_value(value)
