"""The robot's digital I/O on a PLC, over Modbus TCP (pymodbus).

A fieldbus file (TOML) maps the robot's inputs to the PLC's discrete inputs and its
outputs to the PLC's coils:

.. code-block:: toml

    [modbus]
    host = "192.168.0.10"
    port = 502
    device = 1        # the Modbus unit (device) id
    inputs = 0        # the discrete input address of in[1] (in[n] at inputs + n - 1)
    outputs = 0       # the coil address of out[1]
    analog_inputs = 0     # the input register of analog input 1 (optional)
    analog_outputs = 0    # the holding register of analog output 1 (optional)
    analog_counts = 27648 # a register's value at its channel's high end (0: the low end)
    poll = 0.01       # s between exchanges
    timeout = 0.5     # s without a good exchange: the PLC is lost

The analog channels are the specification's (``[[analog_input]]``, ``[[analog_output]]``:
their names, units and ranges); a register holds a channel's value scaled linearly, 0 at
its range's low end and ``analog_counts`` at its high end (a reading beyond is outside the
channel's range: the program's ``io`` error when it reads it). A group of digital outputs
(``group_out``) reaches the PLC in one exchange.

Every field is declared once (:data:`FIELDS`, with its type, range and meaning): the
loader, its messages and docs/runtime.md read the table.

The exchange runs **off the loop**, on a thread of its own: every ``poll`` seconds it
reads every input and writes the outputs when the program changed them (all of them again
after a reconnection). The loop only reads the last inputs and sets the outputs it wants
(plain assignments, never a wait). The connection is supervised: when no exchange has
succeeded for ``timeout`` seconds, :meth:`ModbusIo.lost` says why and the io component
(runtime/loop/components/io.py, whose backend this is) has the robot system stop the robot
(category 1, as an emergency stop) and end the program with that fault; a program does
not start while the PLC cannot be reached. The PLC lives in real
time: a fieldbus needs the wall clock.
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

from runtime.hardware.interface import DigitalIo, FieldbusError
from runtime.timing import FIELDBUS_POLL, TICK

__all__ = ["FIELDS", "FieldbusError", "ModbusConfig", "ModbusIo", "parse_modbus"]


@dataclass(frozen=True)
class Field:
    kind: str  # "host", "int", "seconds"
    default: object  # None: required (unless optional)
    low: float
    high: float
    doc: str
    optional: bool = False  # left out: None (nothing of that kind on the PLC)

    def allowed(self) -> str:
        if self.kind == "host":
            return "a host name or address (a string)"
        what = "an integer" if self.kind == "int" else "a number of seconds"
        return f"{what} {self.low:g}..{self.high:g}"


#: The ``[modbus]`` table's fields.
FIELDS: dict[str, Field] = {
    "host": Field("host", None, 0, 0, "the PLC's host name or address"),
    "port": Field("int", 502, 1, 65535, "its Modbus TCP port"),
    "device": Field("int", 1, 0, 255, "the Modbus unit (device) id"),
    "inputs": Field("int", 0, 0, 65535, "the discrete input address of in[1]"),
    "outputs": Field("int", 0, 0, 65535, "the coil address of out[1]"),
    "analog_inputs": Field("int", None, 0, 65535, "the input register of analog input 1 (analog input n at "
                           "analog_inputs + n - 1); left out: the PLC has none of the robot's analog inputs",
                           optional=True),
    "analog_outputs": Field("int", None, 0, 65535, "the holding register of analog output 1; left out: the PLC "
                            "has none of the robot's analog outputs", optional=True),
    "analog_counts": Field("int", 65535, 1, 65535, "a register's value at its channel's high end (0 at its low "
                           "end, linear between: 27648 for a Siemens PLC's analog modules)"),
    "poll": Field("seconds", FIELDBUS_POLL, TICK, 1.0, "time between exchanges"),
    "timeout": Field("seconds", 0.5, 0.05, 10.0, "time without a good exchange after which the PLC is lost"),
}


@dataclass(frozen=True)
class ModbusConfig:
    host: str
    port: int
    device: int
    inputs: int
    outputs: int
    analog_inputs: int | None
    analog_outputs: int | None
    analog_counts: int
    poll: float
    timeout: float


def parse_modbus(table: dict, spec, name: str = "fieldbus") -> ModbusConfig:
    """The ``[modbus]`` table of the fieldbus file ``name``, checked against ``spec`` (the
    file itself: :func:`runtime.hardware.backends.load_fieldbus`)."""
    import difflib

    for key in table:
        if key not in FIELDS:
            close = difflib.get_close_matches(key, list(FIELDS), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise FieldbusError(f"{name}: [modbus] unknown {key!r}{hint}; known: {', '.join(FIELDS)}")
    values = {}
    for key, field in FIELDS.items():
        where = f"{name}: [modbus] {key}"
        if key not in table:
            if field.default is None and not field.optional:
                raise FieldbusError(f"{where} is missing ({field.doc}: {field.allowed()})")
            values[key] = field.default
            continue
        value = table[key]
        if field.kind == "host":
            ok = isinstance(value, str) and 0 < len(value) <= 255
        elif field.kind == "int":
            ok = isinstance(value, int) and not isinstance(value, bool) and field.low <= value <= field.high
        else:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) \
                and field.low <= value <= field.high
        if not ok:
            raise FieldbusError(f"{where}: expected {field.allowed()}, got {value!r}")
        values[key] = float(value) if field.kind == "seconds" else value
    if values["inputs"] + spec.inputs - 1 > 65535 or values["outputs"] + spec.outputs - 1 > 65535:
        raise FieldbusError(f"{name}: [modbus] the {spec.inputs} inputs and {spec.outputs} outputs must fit below "
                            "address 65536")
    for key, channels in (("analog_inputs", spec.analog_inputs), ("analog_outputs", spec.analog_outputs)):
        if values[key] is not None and values[key] + len(channels) - 1 > 65535:
            raise FieldbusError(f"{name}: [modbus] {key}: the {len(channels)} {key.replace('_', ' ')} from register "
                                f"{values[key]} must fit below address 65536")
    return ModbusConfig(**values)


def markdown() -> str:
    """The ``[modbus]`` fields, for docs/runtime.md (``python -m runtime.cli.docgen``)."""
    lines = ["| field | allowed | default | meaning |", "|---|---|---|---|"]
    for key, field in FIELDS.items():
        default = "none" if field.optional else "required" if field.default is None else f"{field.default:g}"
        lines.append(f"| `{key}` | {field.allowed()} | {default} | {field.doc} |")
    return "\n".join(lines) + "\n"


class ModbusIo(DigitalIo):
    """The robot's I/O on the PLC, as the loop sees it: a backend of the io component
    (its digital I/O as the last exchange saw it: ``inputs``, ``outputs``, ``input``,
    ``set_output``, ``output``, and ``lost``; ``start``, ``close``, ``wait_connected`` for
    its exchange thread). The thread replaces the inputs as a whole (one tuple: the loop
    never sees half an exchange)."""

    def __init__(self, config: ModbusConfig, n_inputs: int, n_outputs: int, analog: tuple = (),
                 analog_outputs: tuple = ()):
        super().__init__(n_inputs, n_outputs, f"the robot on the PLC at {config.host}:{config.port}",
                         analog if config.analog_inputs is not None else (),
                         analog_outputs if config.analog_outputs is not None else ())
        self.config = config
        self._inputs = tuple(self._inputs)
        self._analog = tuple(self._analog)
        #: (low, high) of each analog channel on the PLC (the specification's ranges)
        self._ranges_in = tuple((c.low, c.high) for c in analog) if config.analog_inputs is not None else ()
        self._ranges_out = tuple((c.low, c.high) for c in analog_outputs) if config.analog_outputs is not None \
            else ()
        self._written: tuple | None = None  # what the PLC has (None: not known: write all)
        self._written_analog: tuple | None = None
        self.last_ok: float | None = None  # monotonic time of the last good exchange
        self.error: str | None = None  # why the last exchange failed
        self.exchanges = 0
        self.failures = 0
        self.round_trips: list[float] = []  # s, the last 1,000 exchanges (read, and write when there was one)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ---- the loop's side: DigitalIo's (real-time: plain reads and writes) ----
    def set_outputs(self, first: int, values) -> None:
        """Outputs ``first``.. to ``values`` at once: the exchange thread sees all or none."""
        outputs = list(self._outputs)
        for i, value in enumerate(values):
            outputs[self._index(first + i, len(outputs), "output")] = bool(value)
        self._outputs = outputs

    def analog_input(self, n: int) -> float:
        self._mapped(n, self._ranges_in, "input")
        return super().analog_input(n)

    def set_analog_output(self, n: int, value: float) -> None:
        self._mapped(n, self._ranges_out, "output")
        super().set_analog_output(n, value)

    def analog_output(self, n: int) -> float:
        self._mapped(n, self._ranges_out, "output")
        return super().analog_output(n)

    def _mapped(self, n: int, ranges: tuple, what: str) -> None:
        if not ranges:
            raise IndexError(f"analog {what} {n} is not on the PLC: its fieldbus file maps no analog {what}s "
                             f"(analog_{what}s in [modbus])")

    def lost(self, now: float | None = None) -> str | None:
        """Why the PLC counts as lost (no good exchange for ``timeout`` s), or None."""
        now = time.monotonic() if now is None else now
        last = self.last_ok
        if last is not None and now - last <= self.config.timeout:
            return None
        c = self.config
        since = "ever" if last is None else f"for {now - last:.2f} s"
        return (f"no exchange with the PLC at {c.host}:{c.port} (device {c.device}) {since}, the limit is "
                f"{c.timeout:g} s" + (f": {self.error}" if self.error else ""))

    # ---- the exchange thread (not real-time) ----
    def start(self) -> None:
        self._thread = threading.Thread(target=self._main, name="irl-modbus", daemon=True)
        self._thread.start()

    def wait_connected(self, timeout: float) -> bool:
        """Not real-time: wait up to ``timeout`` s for a good exchange."""
        deadline = time.monotonic() + timeout
        while self.lost() is not None:
            if time.monotonic() > deadline:
                return False
            time.sleep(self.config.poll)
        return True

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)

    def _main(self) -> None:
        """The exchange thread: it never dies of a bad exchange (any failure is counted,
        said in robot terms in ``error``, and the next poll tries again)."""
        from pymodbus.client import ModbusTcpClient

        c = self.config
        client = ModbusTcpClient(c.host, port=c.port, timeout=min(c.timeout, 1.0), retries=0)
        try:
            while not self._stop.is_set():
                started = time.monotonic()
                try:
                    self._exchange(client)
                except Exception as exc:  # noqa: BLE001 - a failed exchange, whatever failed
                    self.failures += 1
                    self.error = self._why(exc)
                    self._written = self._written_analog = None  # after a reconnection: every output again
                    try:
                        client.close()
                    except Exception:  # noqa: BLE001 - closing a broken connection
                        pass
                self._stop.wait(max(0.0, c.poll - (time.monotonic() - started)))
        finally:
            client.close()

    def _why(self, exc: Exception) -> str:
        """A failed exchange in the robot's terms (never a library's exception text)."""
        from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

        c = self.config
        if isinstance(exc, BadExchange):
            return str(exc)
        if isinstance(exc, ConnectionException):
            return f"the connection to {c.host}:{c.port} failed or was closed"
        if isinstance(exc, ModbusIOException):
            return f"the PLC did not answer within {min(c.timeout, 1.0):g} s"
        if isinstance(exc, OSError):
            return f"the connection to {c.host}:{c.port} failed" + (f" ({exc.strerror})" if exc.strerror else "")
        if isinstance(exc, ModbusException):
            return "the PLC's reply broke the Modbus protocol"
        return "the Modbus client failed on the PLC's reply (an internal error in the exchange)"

    def _exchange(self, client) -> None:
        c = self.config
        if not client.connected and not client.connect():
            raise BadExchange(f"cannot connect to {c.host}:{c.port}")
        started = time.perf_counter()
        n = len(self._inputs)
        asked = f"the discrete inputs {c.inputs}..{c.inputs + n - 1}"
        reply = client.read_discrete_inputs(c.inputs, count=n, device_id=c.device)
        _check_reply(reply, READ_DISCRETE_INPUTS, f"reading {asked}")
        bits = list(reply.bits)
        # a reply holds whole bytes: at least the n bits asked for, at most the byte's padding more
        if not n <= len(bits) <= 8 * ((n + 7) // 8):
            raise BadExchange(f"the PLC's reply to reading {asked} held {len(bits)} of the {n} inputs asked for"
                              if len(bits) < n else
                              f"the PLC's reply to reading {asked} held {len(bits)} bits for the {n} inputs asked for")
        self._inputs = tuple(bool(b) for b in bits[:n])
        if self._ranges_in:
            self._analog = self._read_analog(client)
        wanted = tuple(self._outputs)
        if wanted != self._written:
            coils = f"the coils {c.outputs}..{c.outputs + len(wanted) - 1}"
            reply = client.write_coils(c.outputs, list(wanted), device_id=c.device)
            _check_reply(reply, WRITE_COILS, f"writing {coils}")
            if (reply.address, reply.count) != (c.outputs, len(wanted)):
                raise BadExchange(f"the PLC's reply to writing {coils} confirmed {reply.count} coils from "
                                  f"{reply.address}")
            self._written = wanted
        if self._ranges_out:
            self._write_analog(client)
        self.round_trips.append(time.perf_counter() - started)
        if len(self.round_trips) > 1000:
            del self.round_trips[:500]
        self.exchanges += 1
        self.error = None
        self.last_ok = time.monotonic()


    def _read_analog(self, client) -> tuple[float, ...]:
        """The analog inputs' registers, in their channels' units."""
        c, ranges = self.config, self._ranges_in
        asked = f"the input registers {c.analog_inputs}..{c.analog_inputs + len(ranges) - 1}"
        reply = client.read_input_registers(c.analog_inputs, count=len(ranges), device_id=c.device)
        _check_reply(reply, READ_INPUT_REGISTERS, f"reading {asked}")
        raw = list(reply.registers)
        if len(raw) != len(ranges) or not all(isinstance(r, int) and 0 <= r <= 65535 for r in raw):
            raise BadExchange(f"the PLC's reply to reading {asked} held {len(raw)} registers for the "
                              f"{len(ranges)} analog inputs asked for")
        return tuple(low + (high - low) * r / c.analog_counts for r, (low, high) in zip(raw, ranges))

    def _write_analog(self, client) -> None:
        """The analog outputs into their registers, when the program changed them."""
        c, wanted = self.config, tuple(self._analog_out)
        if wanted == self._written_analog:
            return
        raw = [min(c.analog_counts, max(0, round((v - low) / (high - low) * c.analog_counts))) if high > low else 0
               for v, (low, high) in zip(wanted, self._ranges_out)]
        asked = f"the holding registers {c.analog_outputs}..{c.analog_outputs + len(raw) - 1}"
        reply = client.write_registers(c.analog_outputs, raw, device_id=c.device)
        _check_reply(reply, WRITE_REGISTERS, f"writing {asked}")
        if (reply.address, reply.count) != (c.analog_outputs, len(raw)):
            raise BadExchange(f"the PLC's reply to writing {asked} confirmed {reply.count} registers from "
                              f"{reply.address}")
        self._written_analog = wanted


# the Modbus function codes of the exchange
READ_DISCRETE_INPUTS, READ_INPUT_REGISTERS, WRITE_COILS, WRITE_REGISTERS = 2, 4, 15, 16


class BadExchange(Exception):
    """A reply that does not answer the request (its text says what, in the robot's terms)."""


def _check_reply(reply, function_code: int, doing: str) -> None:
    """A reply that refuses or answers something else fails the exchange."""
    if reply.isError():
        code = getattr(reply, "exception_code", None)
        raise BadExchange(f"the PLC refused {doing}" + (f" (Modbus exception code {code})" if code else ""))
    if reply.function_code != function_code:
        raise BadExchange(f"the PLC answered {doing} with a reply of another kind (function code "
                          f"{reply.function_code}, not {function_code})")
