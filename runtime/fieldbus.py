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
(runtime/components/io.py, whose backend this is) has the robot system stop the robot
(category 1, as an emergency stop) and end the program with that fault; a program does
not start while the PLC cannot be reached. The PLC lives in real
time: a fieldbus needs the wall clock.
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from .components.io import IoBackend
from .timing import FIELDBUS_POLL, TICK

__all__ = ["FIELDS", "FieldbusError", "ModbusConfig", "ModbusIo", "load_fieldbus"]


class FieldbusError(ValueError):
    """A fieldbus file that cannot be used: where, what, and what is allowed."""


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


def parse_fieldbus(data: dict, spec, name: str = "fieldbus") -> ModbusConfig:
    import difflib

    for key in data:
        if key != "modbus":
            raise FieldbusError(f"{name}: unknown table [{key}]; known: [modbus]")
    table = data.get("modbus")
    if not isinstance(table, dict):
        raise FieldbusError(f"{name}: a [modbus] table is needed (host, port, device, inputs, outputs, poll, "
                            "timeout)")
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


def load_fieldbus(path: str | Path, spec) -> ModbusConfig:
    try:
        import pymodbus  # noqa: F401
    except ImportError:
        raise FieldbusError("pymodbus is not installed: pip install 'irl[fieldbus]'") from None
    from .config import read_toml

    return parse_fieldbus(read_toml(path, FieldbusError), spec, str(path))


def markdown() -> str:
    """The ``[modbus]`` fields, for docs/runtime.md (``python -m runtime.docgen``)."""
    lines = ["| field | allowed | default | meaning |", "|---|---|---|---|"]
    for key, field in FIELDS.items():
        default = "required" if field.default is None else f"{field.default:g}"
        lines.append(f"| `{key}` | {field.allowed()} | {default} | {field.doc} |")
    return "\n".join(lines) + "\n"


class ModbusIo(IoBackend):
    """The robot's I/O on the PLC, as the loop sees it: a backend of the io component
    (runtime.components.io.IoBackend, as the simulated robot's own I/O is: ``inputs``,
    ``outputs``, ``input``, ``set_output``, ``lost``; and ``start``, ``close``,
    ``wait_connected`` for its exchange thread)."""

    def __init__(self, config: ModbusConfig, n_inputs: int, n_outputs: int):
        self.config = config
        self._inputs: tuple[bool, ...] = (False,) * n_inputs
        self._wanted = [False] * n_outputs
        self._written: tuple | None = None  # what the PLC has (None: not known: write all)
        self.last_ok: float | None = None  # monotonic time of the last good exchange
        self.error: str | None = None  # why the last exchange failed
        self.exchanges = 0
        self.failures = 0
        self.round_trips: list[float] = []  # s, the last 1,000 exchanges (read, and write when there was one)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ---- the loop's side (real-time: plain reads and writes) ----
    @property
    def inputs(self) -> tuple[bool, ...]:
        return self._inputs

    @property
    def outputs(self) -> tuple[bool, ...]:
        return tuple(self._wanted)

    def input(self, n: int) -> bool:
        return self._inputs[n - 1]

    def set_output(self, n: int, value: bool) -> None:
        self._wanted[n - 1] = bool(value)

    def output(self, n: int) -> bool:
        return self._wanted[n - 1]

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
        from pymodbus.client import ModbusTcpClient
        from pymodbus.exceptions import ModbusException

        c = self.config
        client = ModbusTcpClient(c.host, port=c.port, timeout=min(c.timeout, 1.0), retries=0)
        try:
            while not self._stop.is_set():
                started = time.monotonic()
                try:
                    self._exchange(client)
                except (ModbusException, OSError, ValueError) as exc:
                    self.failures += 1
                    self.error = str(exc) or type(exc).__name__
                    self._written = None  # after a reconnection the PLC gets every output again
                    client.close()
                self._stop.wait(max(0.0, c.poll - (time.monotonic() - started)))
        finally:
            client.close()

    def _exchange(self, client) -> None:
        c = self.config
        if not client.connected and not client.connect():
            raise OSError(f"cannot connect to {c.host}:{c.port}")
        started = time.perf_counter()
        reply = client.read_discrete_inputs(c.inputs, count=len(self._inputs), device_id=c.device)
        if reply.isError():
            raise ValueError(f"the PLC refused to read discrete inputs {c.inputs}..: {reply}")
        self._inputs = tuple(bool(b) for b in reply.bits[:len(self._inputs)])
        wanted = tuple(self._wanted)
        if wanted != self._written:
            reply = client.write_coils(c.outputs, list(wanted), device_id=c.device)
            if reply.isError():
                raise ValueError(f"the PLC refused to write coils {c.outputs}..: {reply}")
            self._written = wanted
        self.round_trips.append(time.perf_counter() - started)
        if len(self.round_trips) > 1000:
            del self.round_trips[:500]
        self.exchanges += 1
        self.error = None
        self.last_ok = time.monotonic()
