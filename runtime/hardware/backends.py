"""The robot's backends, declared once: which robot backends (:data:`ROBOTS`) and which
fieldbuses for the digital I/O (:data:`FIELDBUSES`) there are, how each is made, what it
can be given and what a run with it needs. The robot system (runtime.loop.system) and the
command line (runtime.cli) read these tables and ask nothing else of a backend's kind: a
second robot backend is a class in runtime/hardware/ deriving from
:class:`~runtime.hardware.interface.RobotBackend` and an entry in :data:`ROBOTS`; a second
fieldbus one deriving from :class:`~runtime.hardware.interface.IoBackend`, its file's table
parser and an entry in :data:`FIELDBUSES` (its file's top-level table, ``[modbus]``, names
the entry).

Light to import (the command line reads it before anything heavy): each entry imports its
backend's module when it makes one.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from runtime.hardware.faults import FAULTS
from runtime.hardware.interface import FieldbusError, IoBackend, RobotBackend

__all__ = ["DEFAULT_ROBOT", "FIELDBUSES", "ROBOTS", "FieldbusError", "FieldbusKind", "RobotKind",
           "load_fieldbus", "load_io_files", "make_io", "make_robot", "parse_fieldbus"]


@dataclass(frozen=True)
class RobotKind:
    """A robot backend: ``make(spec, seed)`` builds one (not real-time); ``faults`` are
    what ``inject`` (``irl run --inject``) can give it; a ``simulated`` one is seeded (its
    identity in the robot's memory names the seed) and its digital inputs are the world's
    side (a cell scenario or the operator sets them)."""

    doc: str
    make: Callable[..., RobotBackend]
    faults: tuple[str, ...] = ()
    simulated: bool = False

    def identity(self, name: str, seed: int) -> str:
        """The backend as the robot's memory records it (calibration is kept for it only)."""
        return f"{name}-seed-{seed}" if self.simulated else name


def _sim_robot(spec, seed: int) -> RobotBackend:
    from runtime.hardware.sim.robot import SimRobot

    return SimRobot(spec, seed)


#: The robot backends, by name.
ROBOTS: dict[str, RobotKind] = {
    "sim": RobotKind("the simulated arm (runtime/hardware/sim): drives, encoders, brakes, homing sensors and "
                     "digital I/O of its own", _sim_robot, FAULTS, simulated=True),
}

#: The robot backend a run uses unless told otherwise.
DEFAULT_ROBOT = "sim"


def make_robot(name: str, spec, seed: int = 0) -> RobotBackend:
    """Not real-time: the robot backend ``name`` (a key of :data:`ROBOTS`) for ``spec``."""
    kind = ROBOTS.get(name)
    if kind is None:
        raise ValueError(f"unknown robot backend {name!r}: expected one of {', '.join(ROBOTS)}")
    return kind.make(spec, seed)


@dataclass(frozen=True)
class FieldbusKind:
    """A fieldbus carrying the robot's digital I/O to a PLC: ``parse(table, spec, where)``
    checks its file's table (raising :class:`FieldbusError`) and gives its configuration
    (with a ``timeout``: seconds without a good exchange after which the PLC is lost);
    ``make(config, spec)`` builds the I/O backend (not real-time); ``requires`` is the
    module it needs and what to install to get it."""

    doc: str
    parse: Callable[[dict, object, str], object]
    make: Callable[[object, object], IoBackend]
    requires: tuple[str, str] | None = None


def _parse_modbus(table: dict, spec, where: str):
    from runtime.hardware.fieldbus import parse_modbus

    return parse_modbus(table, spec, where)


def _modbus_io(config, spec) -> IoBackend:
    from runtime.hardware.fieldbus import ModbusIo

    return ModbusIo(config, spec.inputs, spec.outputs, spec.analog_inputs, spec.analog_outputs)


#: The fieldbuses, by the top-level table of their file.
FIELDBUSES: dict[str, FieldbusKind] = {
    "modbus": FieldbusKind("Modbus TCP (runtime/hardware/fieldbus.py): inputs on discrete inputs, outputs on coils",
                           _parse_modbus, _modbus_io, ("pymodbus", "irl[fieldbus]")),
}


@dataclass(frozen=True)
class FieldbusConfig:
    """A checked fieldbus file: which fieldbus (a key of :data:`FIELDBUSES`) and its
    configuration."""

    kind: str
    config: object

    @property
    def timeout(self) -> float:
        return self.config.timeout


def parse_fieldbus(data: dict, spec, name: str = "fieldbus") -> FieldbusConfig:
    """A fieldbus file's tables (one, naming the fieldbus) checked against ``spec``."""
    known = ", ".join(f"[{k}]" for k in FIELDBUSES)
    for key in data:
        if key not in FIELDBUSES:
            raise FieldbusError(f"{name}: unknown table [{key}]; known: {known}")
    if len(data) != 1 or not isinstance(next(iter(data.values())), dict):
        raise FieldbusError(f"{name}: one table is needed, naming the fieldbus: {known}")
    (kind, table), = data.items()
    return FieldbusConfig(kind, FIELDBUSES[kind].parse(table, spec, name))


def load_fieldbus(path: str | Path, spec) -> FieldbusConfig:
    """Not real-time: the fieldbus file at ``path``, checked (:class:`FieldbusError` says
    where and what is allowed)."""
    import importlib.util

    from runtime.config import read_toml

    data = read_toml(path, FieldbusError)
    config = parse_fieldbus(data, spec, str(path))
    requires = FIELDBUSES[config.kind].requires
    if requires is not None and importlib.util.find_spec(requires[0]) is None:
        raise FieldbusError(f"{requires[0]} is not installed: pip install '{requires[1]}'")
    return config


def make_io(fieldbus: FieldbusConfig, spec) -> IoBackend:
    """Not real-time: the I/O backend of a checked fieldbus file."""
    return FIELDBUSES[fieldbus.kind].make(fieldbus.config, spec)


def load_io_files(cell: str | Path | None, fieldbus: str | Path | None, spec) -> tuple:
    """Not real-time: a run's cell scenario and fieldbus files (either may be None), read
    and checked: (the cell, the fieldbus configuration), each None when not given. Raises
    ValueError saying which option's file is wrong and how, in the command line's words."""
    loaded_cell = loaded_fieldbus = None
    if cell is not None:
        from runtime.hardware.sim.cell import ScenarioError, load_scenario

        try:
            loaded_cell = load_scenario(cell, spec)
        except ScenarioError as exc:
            raise ValueError(f"--cell-scenario: {exc}") from None
    if fieldbus is not None:
        try:
            loaded_fieldbus = load_fieldbus(fieldbus, spec)
        except FieldbusError as exc:
            raise ValueError(f"--fieldbus: {exc}") from None
    return loaded_cell, loaded_fieldbus
