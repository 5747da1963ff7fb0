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
    poll = 0.01       # s between exchanges
    timeout = 0.5     # s without a good exchange: the PLC is lost

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
    default: object  # None: required
    low: float
    high: float
    doc: str

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
            if field.default is None:
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
    return ModbusConfig(**values)


def markdown() -> str:
    """The ``[modbus]`` fields, for docs/runtime.md (``python -m runtime.cli.docgen``)."""
    lines = ["| field | allowed | default | meaning |", "|---|---|---|---|"]
    for key, field in FIELDS.items():
        default = "required" if field.default is None else f"{field.default:g}"
        lines.append(f"| `{key}` | {field.allowed()} | {default} | {field.doc} |")
    return "\n".join(lines) + "\n"


class ModbusIo(DigitalIo):
    """The robot's I/O on the PLC, as the loop sees it: a backend of the io component
    (its digital I/O as the last exchange saw it: ``inputs``, ``outputs``, ``input``,
    ``set_output``, ``output``, and ``lost``; ``start``, ``close``, ``wait_connected`` for
    its exchange thread). The thread replaces the inputs as a whole (one tuple: the loop
    never sees half an exchange)."""

    def __init__(self, config: ModbusConfig, n_inputs: int, n_outputs: int):
        super().__init__(n_inputs, n_outputs, f"the robot on the PLC at {config.host}:{config.port}")
        self.config = config
        self._inputs = tuple(self._inputs)
        self._written: tuple | None = None  # what the PLC has (None: not known: write all)
        self.last_ok: float | None = None  # monotonic time of the last good exchange
        self.error: str | None = None  # why the last exchange failed
        self.exchanges = 0
        self.failures = 0
        self.round_trips: list[float] = []  # s, the last 1,000 exchanges (read, and write when there was one)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ---- the loop's side: DigitalIo's (real-time: plain reads and writes) ----
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
                    self._written = None  # after a reconnection the PLC gets every output again
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
        wanted = tuple(self._outputs)
        if wanted != self._written:
            coils = f"the coils {c.outputs}..{c.outputs + len(wanted) - 1}"
            reply = client.write_coils(c.outputs, list(wanted), device_id=c.device)
            _check_reply(reply, WRITE_COILS, f"writing {coils}")
            if (reply.address, reply.count) != (c.outputs, len(wanted)):
                raise BadExchange(f"the PLC's reply to writing {coils} confirmed {reply.count} coils from "
                                  f"{reply.address}")
            self._written = wanted
        self.round_trips.append(time.perf_counter() - started)
        if len(self.round_trips) > 1000:
            del self.round_trips[:500]
        self.exchanges += 1
        self.error = None
        self.last_ok = time.monotonic()


READ_DISCRETE_INPUTS, WRITE_COILS = 2, 15  # the Modbus function codes of the exchange


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
