"""Run-time values of L-IRL that are more than a Python scalar.

Shared by the compiler (constant folding, the constant pool) and the runtime (the VM),
so this module imports nothing heavy. All are immutable and compare by value; lengths in
mm, angles in degrees.
"""
from __future__ import annotations

import math
from dataclasses import astuple, dataclass
from typing import ClassVar

from .configs import Config, value_problem


@dataclass(frozen=True, slots=True)
class MainJoint:
    """``mainjoint(a1, ..., an)``: only meaningful as an argument of ``joint``."""

    values: tuple[float, ...]

    def __str__(self) -> str:
        return f"mainjoint({_nums(self.values)})"


@dataclass(frozen=True, slots=True)
class AddJoint:
    """``addjoint(e1, ..., em)``: only meaningful as an argument of ``joint``."""

    values: tuple[float, ...]

    def __str__(self) -> str:
        return f"addjoint({_nums(self.values)})"


@dataclass(frozen=True, slots=True)
class Joint:
    """One value per axis: main axes then additional axes (deg or mm)."""

    main: tuple[float, ...]
    add: tuple[float, ...] = ()

    @property
    def axes(self) -> tuple[float, ...]:
        return self.main + self.add

    def __str__(self) -> str:
        text = f"joint(mainjoint({_nums(self.main)})"
        if self.add:
            text += f", addjoint({_nums(self.add)})"
        return text + ")"


class _Numbers:
    """A literal written as its keyword and its numbers, in the order of its fields."""

    __slots__ = ()
    KEYWORD: ClassVar[str] = ""

    def __str__(self) -> str:
        return f"{self.KEYWORD}({_nums(astuple(self))})"


@dataclass(frozen=True, slots=True)
class Position(_Numbers):
    """``pos(x, y, z)`` in mm."""

    KEYWORD: ClassVar[str] = "pos"
    x: float
    y: float
    z: float


@dataclass(frozen=True, slots=True)
class Rpy(_Numbers):
    """``rpy(roll, pitch, yaw)`` in degrees."""

    KEYWORD: ClassVar[str] = "rpy"
    roll: float
    pitch: float
    yaw: float


@dataclass(frozen=True, slots=True)
class Quat(_Numbers):
    """``quat(w, x, y, z)``, a unit quaternion."""

    KEYWORD: ClassVar[str] = "quat"
    w: float
    x: float
    y: float
    z: float


@dataclass(frozen=True, slots=True)
class Pose:
    """The tool centre point in the robot's base frame; ``config``: the arm's
    configuration it names (compiler.configs), None when it names none."""

    position: Position
    orientation: Rpy | Quat
    config: Config | None = None

    def __str__(self) -> str:
        if self.config is None:
            return f"pose({self.position}, {self.orientation})"
        return f"pose({self.position}, {self.orientation}, {self.config})"


def format_number(value: float | int) -> str:
    """Shortest text that reads back as the same number (``45.0`` -> ``45``)."""
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def _nums(values) -> str:
    return ", ".join(format_number(v) for v in values)


class Record(list):
    """A record's value (compiler.records): its fields' values in declaration order, a list
    that the VM changes in place (as an array), with its type's name and its fields' names
    (to show it). Not immutable: a record stored or passed is a copy (:func:`copy_value`)."""

    __slots__ = ("type_name", "field_names")

    def __init__(self, type_name: str, field_names: tuple[str, ...], values=()):
        super().__init__(values)
        self.type_name = type_name
        self.field_names = field_names

    def __repr__(self) -> str:
        return f"Record({self.type_name!r}, {self.field_names!r}, {list(self)!r})"

    def __eq__(self, other):  # (a record of another type, or an array, is never equal)
        return type(other) is Record and other.type_name == self.type_name and list.__eq__(self, other)

    def __ne__(self, other):
        return not self == other

    __hash__ = None


#: The values the VM changes in place: arrays (lists) and records.
MUTABLE = (list, Record)


def copy_value(value):
    """A deep copy of an array or a record (they hold arrays, records or immutable values);
    any other value is immutable and comes back as it is."""
    t = type(value)
    if t is list:
        return [copy_value(item) for item in value] if value and type(value[0]) in MUTABLE else value[:]
    if t is Record:
        return Record(value.type_name, value.field_names,
                      [copy_value(item) if type(item) in MUTABLE else item for item in value])
    return value


def elements_of(value) -> int:
    """How many values an array or a record holds, all levels together (1 for any other)."""
    t = type(value)
    if t is list:
        return len(value) * elements_of(value[0]) if value else 0
    if t is Record:
        return sum(elements_of(item) for item in value)
    return 1


def format_value(value) -> str:
    """A value as L-IRL source text (a record as its type's name with each field named:
    ``part_t(name: "A", height: 12.5)``)."""
    if type(value) is Record:
        return f"{value.type_name}(" + ", ".join(f"{name}: {format_value(v)}"
                                                 for name, v in zip(value.field_names, value)) + ")"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (int, float)):
        return format_number(value)
    if isinstance(value, list):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    return str(value)


# ---- plain-data form, for msgpack and JSON -------------------------------------------
# Scalars are themselves; a structured value is a list whose first item is its kind.

def to_plain(value):
    """A value as msgpack/JSON-friendly data."""
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, Joint):
        return ["joint", list(value.main), list(value.add)]
    if isinstance(value, Position):
        return ["pos", value.x, value.y, value.z]
    if isinstance(value, Rpy):
        return ["rpy", value.roll, value.pitch, value.yaw]
    if isinstance(value, Quat):
        return ["quat", value.w, value.x, value.y, value.z]
    if isinstance(value, Pose):
        plain = ["pose", to_plain(value.position), to_plain(value.orientation)]
        return plain if value.config is None else plain + [to_plain(value.config)]
    if isinstance(value, Config):
        problem = value_problem(value)  # (one made in memory, not decoded: checked here)
        if problem is not None:
            raise TypeError(f"not an L-IRL configuration: {problem}")
        return ["config", value.shoulder, value.elbow, value.wrist,
                list(value.turns) if value.turns is not None else None]
    raise TypeError(f"not an L-IRL constant: {value!r}")


def _floats(items, count: int | None, what: str) -> tuple[float, ...]:
    if not isinstance(items, list) or (count is not None and len(items) != count):
        raise ValueError(f"{what}: expected {count if count is not None else 'a list of'} numbers")
    for item in items:
        if isinstance(item, bool) or not isinstance(item, (int, float)):
            raise ValueError(f"{what}: {_shape(item)} is not a number")
        if not math.isfinite(item):
            raise ValueError(f"{what}: {item} is not a finite number")
    return tuple(float(item) for item in items)


def _shape(data) -> str:
    """A short description of malformed data (never its repr: it may nest deeply)."""
    if isinstance(data, list):
        return f"a list of {len(data)} items" + (f" starting with {data[0]!r:.30}" if data and
                                                   isinstance(data[0], (str, int, float)) else "")
    return f"a {type(data).__name__}"


_INT_MIN, _INT_MAX = -(2 ** 63), 2 ** 63 - 1


def _config(rest: list) -> Config:
    """``["config", shoulder, elbow, wrist, turns]``: each group 0, 1 or nil, the turns
    three integers or nil."""
    if len(rest) != 4:
        raise ValueError("config: expected [shoulder, elbow, wrist, turns]")
    turns = rest[3]
    if turns is not None and (not isinstance(turns, list) or len(turns) != 3):
        raise ValueError(f"config: turns must be three integers or nil, not {_shape(turns)}")
    config = Config(*rest[:3], turns=tuple(turns) if turns is not None else None)
    problem = value_problem(config)
    if problem is not None:
        raise ValueError(f"config: {problem}")
    return config


def from_plain(data, nested: bool = False):
    """The inverse of :func:`to_plain`; raises ValueError on anything malformed, and on
    numbers no L-IRL value can hold (NaN, infinities, integers beyond 64 bits)."""
    if isinstance(data, (bool, str)):
        return data
    if isinstance(data, int):
        if not _INT_MIN <= data <= _INT_MAX:
            raise ValueError("integer outside the 64-bit range")
        return data
    if isinstance(data, float):
        if not math.isfinite(data):
            raise ValueError(f"{data} is not a finite number")
        return data
    if not isinstance(data, list) or not data or not isinstance(data[0], str):
        raise ValueError(f"not a constant: {_shape(data)}")
    kind, rest = data[0], data[1:]
    if nested and kind == "pose":
        raise ValueError("pose: a pose cannot contain a pose")
    if kind == "joint":
        if len(rest) != 2:
            raise ValueError("joint: expected [main, add]")
        return Joint(_floats(rest[0], None, "joint main axes"), _floats(rest[1], None, "joint additional axes"))
    if kind == "pos":
        return Position(*_floats(rest, 3, "pos"))
    if kind == "rpy":
        return Rpy(*_floats(rest, 3, "rpy"))
    if kind == "quat":
        return Quat(*_floats(rest, 4, "quat"))
    if kind == "pose":
        if len(rest) not in (2, 3):
            raise ValueError("pose: expected [position, orientation] or [position, orientation, configuration]")
        position, orientation = from_plain(rest[0], nested=True), from_plain(rest[1], nested=True)
        if not isinstance(position, Position) or not isinstance(orientation, (Rpy, Quat)):
            raise ValueError("pose: expected a position and an orientation")
        config = from_plain(rest[2], nested=True) if len(rest) == 3 else None
        if len(rest) == 3 and not isinstance(config, Config):
            raise ValueError("pose: its third item must be a configuration")
        return Pose(position, orientation, None if config is None or config.free else config)
    if kind == "config":
        return _config(rest)
    raise ValueError(f"unknown constant kind {kind!r:.30}")
