"""The system specification (``.spc``): a TOML file that describes one robot.

Loading validates every key: a missing or wrong one is a :class:`SpecError` that names
the file, the key and what was expected; an unknown key is an error too (a misspelled
limit must never be silently ignored). The hash of a specification is taken over its
parsed content, so reformatting or comments do not change it.

Imports nothing from Lark, NumPy or ZeroMQ.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import re
import stat
import tomllib
from dataclasses import dataclass
from pathlib import Path

from . import clauses, geometry, params, zones
from .diagnostics import did_you_mean


class SpecError(Exception):
    """A specification that cannot be used: says which file, which key and why."""

    def __init__(self, file: str, key: str | None, message: str):
        self.file, self.key, self.message = file, key, message
        where = f"{file}: {key}: " if key else f"{file}: "
        super().__init__(where + message)


@dataclass(frozen=True)
class DH:
    """Denavit-Hartenberg parameters of one link (standard convention; mm and deg)."""

    a: float
    alpha: float
    d: float
    theta_offset: float = 0.0


@dataclass(frozen=True)
class Axis:
    """One ``[[axis]]`` table, validated; each key and its default declared once in
    :data:`compiler.params.PARAMS` (section ``axis``)."""

    name: str
    kind: str  # "revolute" (deg) or "prismatic" (mm)
    min: float
    max: float
    max_velocity: float
    max_acceleration: float
    max_jerk: float
    group: str  # "main" or "additional"
    dh: DH | None
    home: float  # the start position the initialization sequence drives to
    gear_ratio: float
    encoder_counts: int  # counts per motor revolution (after quadrature)
    sensor_position: float  # centre of the inductive homing sensor's window
    sensor_window: float  # half-width of that window
    search_velocity: float  # speed of the initialization's searches (unit/s)
    direction: int  # the DH angle is direction x the joint value (+ theta_offset)
    coupling: tuple | None  # (index of an earlier main axis, factor): its value x factor is added

    @property
    def counts_per_unit(self) -> float:
        """Encoder counts per deg (or mm) of axis motion."""
        return self.encoder_counts * self.gear_ratio / (360.0 if self.kind == "revolute" else 1.0)

    @property
    def index_spacing(self) -> float:
        """Axis distance between two index (Z) pulses: one motor revolution."""
        return (360.0 if self.kind == "revolute" else 1.0) / self.gear_ratio

    @property
    def unit(self) -> str:
        return "deg" if self.kind == "revolute" else "mm"

    def target_problem(self, value: float) -> str | None:
        """None when a move's target ``value`` lies within min..max, else what the checker
        (a constant target) and the trajectory generator (any other) say."""
        if self.min <= value <= self.max:
            return None
        return (f"axis {self.name} target {value:g} {self.unit} is outside its limits "
                f"{self.min:g}..{self.max:g} {self.unit}")


@dataclass(frozen=True)
class Defaults:
    """Values of the move clauses that a program leaves out (``[defaults]``; the built-in
    ones when it leaves them out are the clause table's, compiler.clauses)."""

    speed_ptp: float
    acc_ptp: float
    speed: float  # mm/s
    acc: float  # mm/s^2
    approx: float  # a fraction after ptp, mm after lin and circ


@dataclass(frozen=True)
class _Limits:
    """The robot's tool limits, which bound the ``speed`` and ``acc`` clauses (read by
    :mod:`compiler.clauses` like a :class:`Spec`'s) while the specification is loaded."""

    max_speed: float
    max_acceleration: float


@dataclass(frozen=True)
class AnalogChannel:
    """An analog input (``[[analog_input]]``) or output (``[[analog_output]]``): what it
    measures or drives (``name``, for people), its unit, and the range of its values
    (``low`` < ``high``): a sensor's reading, or what a program sets, is a real within it."""

    name: str
    unit: str
    low: float
    high: float

    def problem(self, n: int, value: object, what: str = "input") -> str | None:
        """What is wrong with ``value`` as a reading of analog input ``n`` (``what``
        "output": as the value analog output ``n`` is set to), or None."""
        verb = "reads" if what == "input" else "cannot be set to"
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return f"analog {what} {n} ({self.name}) {verb} a number, not {value!r}"
        if not self.low <= value <= self.high:
            return (f"analog {what} {n} ({self.name}) {verb} {value:g} {self.unit}: its range is "
                    f"{self.low:g}..{self.high:g} {self.unit}")
        return None


#: The most analog inputs a specification may declare.
MAX_ANALOG_INPUTS = 256


@dataclass(frozen=True)
class Spec:
    name: str
    file: str
    axes: tuple[Axis, ...]
    defaults: Defaults
    max_speed: float  # tool centre point, mm/s
    max_acceleration: float  # mm/s^2
    inputs: int
    outputs: int
    tool: tuple[float, ...]  # x, y, z (mm), roll, pitch, yaw (deg) of the TCP in the flange frame
    controller: object  # [controller], typed (compiler.params.SETTINGS): spec.controller.kp
    hash: str
    description: str = ""
    simulation: object = None  # [simulation], typed likewise: spec.simulation.brake_time
    safety: object = None  # [safety], typed likewise: spec.safety.stop_time_margin
    #: The [[frame]] and [[tool]] tables: (type, name, (x, y, z, roll, pitch, yaw)) each.
    named_frames: tuple = ()
    #: [kinematics] mounting: the robot's base in the world frame (x, y, z, roll, pitch, yaw).
    mounting: tuple = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    #: The [[analog_input]] tables, analog input n at index n - 1.
    analog_inputs: tuple["AnalogChannel", ...] = ()
    #: The [[analog_output]] tables, analog output n at index n - 1.
    analog_outputs: tuple["AnalogChannel", ...] = ()
    #: The [[zone]] tables (compiler.zones): where the flange and the tool centre point never go.
    zones: tuple = ()

    @property
    def main_axes(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.axes if a.group == "main")

    @property
    def additional_axes(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.axes if a.group == "additional")

    def arm_reach(self, tool: tuple | None = None) -> float:
        """An upper bound (mm) of the distance from the shoulder (axis 2) to any reachable
        TCP: the links after the first, plus the tool (the specification's, or ``tool``:
        x, y, z, ...). 0 when the DH data are missing."""
        links = self.main_axes[1:]
        if not links or any(axis.dh is None for axis in self.main_axes):
            return 0.0
        x, y, z = (self.tool if tool is None else tool)[:3]
        return sum(math.hypot(axis.dh.a, axis.dh.d) for axis in links) + math.hypot(x, y, z)

    def shoulder_distance(self, x: float, y: float, z: float) -> float:
        """Distance (mm) from a point in the world frame to the nearest place the shoulder
        can be: a circle of radius a1 at height d1 around the first axis (the robot's
        base is at ``mounting`` in the world)."""
        if self.mounting != (0.0,) * 6:
            mx, my, mz, roll, pitch, yaw = self.mounting
            (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = geometry.rpy_to_matrix(roll, pitch, yaw)
            dx, dy, dz = x - mx, y - my, z - mz
            x, y, z = (r00 * dx + r10 * dy + r20 * dz, r01 * dx + r11 * dy + r21 * dz,
                       r02 * dx + r12 * dy + r22 * dz)
        first = self.main_axes[0].dh
        if first is None:
            return math.hypot(x, y, z)
        return math.hypot(math.hypot(x, y) - abs(first.a), z - first.d)


# ---- validation helpers ----------------------------------------------------------------

class _Reader:
    """Reads one TOML table, recording which keys were used so the rest can be refused."""

    def __init__(self, file: str, prefix: str, table, required: bool = True):
        if not isinstance(table, dict):
            raise SpecError(file, prefix, "expected a table")
        self.file, self.prefix, self.table, self.used = file, prefix, table, set()

    def key(self, name: str) -> str:
        return f"{self.prefix}.{name}" if self.prefix else name

    def get(self, name: str, kind: str, default=..., check=None, expect: str = ""):
        self.used.add(name)
        if name not in self.table:
            if default is ...:
                typo = did_you_mean(name, [k for k in self.table if k not in self.used], cutoff=0.8)
                hint = f" (is '{typo}' a misspelling of it?)" if typo else ""
                raise SpecError(self.file, self.key(name), f"missing; expected {expect or kind}{hint}")
            return default
        value = self.table[name]
        if kind == "number":
            ok = params.is_number(value)
            value = float(value) if ok else value
        elif kind == "integer":
            ok = isinstance(value, int) and not isinstance(value, bool)
        elif kind == "string":
            ok = isinstance(value, str) and value != ""
        elif kind == "table":
            ok = isinstance(value, dict)
        else:  # pragma: no cover
            raise AssertionError(kind)
        if ok and check is not None:
            ok = check(value)
        if not ok:
            raise SpecError(self.file, self.key(name), f"expected {expect or kind}, got {value!r}")
        return value

    def finish(self) -> None:
        for name in self.table:
            if name not in self.used:
                guess = did_you_mean(name, self.used)
                hint = f" (did you mean '{guess}'?)" if guess else ""
                raise SpecError(self.file, self.key(name), f"unknown key{hint}")


#: The least [robot] max_speed and max_acceleration: the lower bounds of the speed and acc
#: clauses (compiler.clauses), which they bound from above (declared in compiler.params).
MIN_TOOL_SPEED = params.MIN_TOOL_SPEED
MIN_TOOL_ACCELERATION = params.MIN_TOOL_ACCELERATION
#: The [[axis]] and [robot] keys (compiler.params): their ranges and defaults.
_AXIS = params.section_params("axis")
_ROBOT = params.spec_section("robot")


def _param(r: "_Reader", param: params.Param, default=...):
    """The key ``param`` of the table ``r`` reads, checked by its declaration
    (compiler.params); when the table leaves it out, ``default`` if one is given (where
    it depends on other keys; None for an optional key), else the declaration's, else
    it is missing."""
    r.used.add(param.name)
    if param.name not in r.table:
        if default is ...:
            default = param.default
            if default is None:
                raise SpecError(r.file, r.key(param.name), f"missing; expected {param.allowed()}")
        return default
    try:
        return param.check(r.table[param.name])
    except params.ParamError as exc:
        raise SpecError(r.file, r.key(param.name), exc.reason) from None


def _canonical_hash(data: dict) -> str:
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _axis(file: str, index: int, table) -> Axis:
    r = _Reader(file, f"axis[{index + 1}]", table)
    name = r.get("name", "string")
    kind = r.get("kind", "string", check=lambda k: k in ("revolute", "prismatic"),
                 expect='"revolute" or "prismatic"')
    unit = "deg" if kind == "revolute" else "mm"
    low = r.get("min", "number", expect=f"a number ({unit})")
    high = r.get("max", "number", check=lambda v: v > low, expect=f"a number ({unit}) greater than min ({low:g})")
    def limit(key: str, default=..., cap: float | None = None, cap_name: str = ""):
        """A key declared in compiler.params (section "axis"), within its range (and at
        most ``cap``, another key's value)."""
        value = _param(r, _AXIS[key], default)
        if cap is not None and value > cap:
            raise SpecError(file, r.key(key), f"expected at most {cap_name} ({cap:g} {unit}/s), got {value:g}")
        return value

    vel = limit("max_velocity")
    acc = limit("max_acceleration")
    jerk = limit("max_jerk")
    group = _param(r, _AXIS["group"])
    home_default = _AXIS["home"].default if low <= _AXIS["home"].default <= high else ...  # none outside the limits
    home = r.get("home", "number", home_default, check=lambda v: low <= v <= high,
                 expect=f"a number ({unit}) within min..max ({low:g}..{high:g})")
    gear = limit("gear_ratio")
    counts = limit("encoder_counts")
    resolution = counts * gear / (360.0 if kind == "revolute" else 1.0)
    if not params.MIN_COUNTS_PER_UNIT <= resolution <= params.MAX_COUNTS_PER_UNIT:
        raise SpecError(file, r.key("gear_ratio"),
                        f"encoder_counts x gear_ratio{' / 360' if kind == 'revolute' else ''} gives "
                        f"{resolution:.4g} counts per {unit}: expected {params.MIN_COUNTS_PER_UNIT:g} to "
                        f"{params.MAX_COUNTS_PER_UNIT:g} (the encoder's resolution the servo and homing can use)")
    sensor_default = home + _AXIS["sensor_position"].default  # (relative to home)
    sensor_default = sensor_default if low <= sensor_default else ...
    sensor = r.get("sensor_position", "number", sensor_default, check=lambda v: low <= v <= high,
                   expect=f"a number ({unit}) within min..max, where the homing sensor is")
    window = limit("sensor_window")
    search = limit("search_velocity", min(_AXIS["search_velocity"].default, vel), cap=vel,
                   cap_name="max_velocity")
    direction = limit("direction")
    coupling = limit("coupling", None)
    dh = None
    if "dh" in r.table:
        d = _Reader(file, r.key("dh"), r.get("dh", "table"))
        dh = DH(d.get("a", "number", expect="a number (mm)"), d.get("alpha", "number", expect="a number (deg)"),
                d.get("d", "number", expect="a number (mm)"),
                d.get("theta_offset", "number", 0.0, expect="a number (deg)"))
        d.finish()
    r.finish()
    return Axis(name, kind, low, high, vel, acc, jerk, group, dh, home, gear, counts, sensor, window, search,
                direction, coupling)


def _couplings(file: str, axes: tuple) -> tuple:
    """The axes with each ``coupling`` resolved to the index of the axis it names: an
    earlier main axis, and only axes 2 and 3 of the arm coupled (the inverse kinematics
    solves the arm's axes in order and the wrist's from the arm's)."""
    index = {a.name: i for i, a in enumerate(axes)}
    out = []
    for i, a in enumerate(axes):
        if a.coupling is not None:
            name, factor = a.coupling
            key = f"axis[{i + 1}].coupling"
            if a.group != "main" or i not in (1, 2):
                raise SpecError(file, key, f"only axes 2 and 3 of the arm may be coupled (to an earlier axis), not "
                                           f"{a.name}: coupled wrist axes are not supported; give {a.name}'s "
                                           "joint values as its own angle")
            if index.get(name, i) >= i:
                known = ", ".join(x.name for x in axes[:i])
                raise SpecError(file, key, f"expected axis, an earlier main axis ({known}), got {name!r}")
            a = dataclasses.replace(a, coupling=(index[name], factor))
        out.append(a)
    return tuple(out)


def parse_spec(text: str, file: str = "<spec>") -> Spec:
    """Validate the text of a specification; raises :class:`SpecError`."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(file, None, f"not valid TOML: {exc}") from None
    except RecursionError:
        raise SpecError(file, None, "not valid TOML: nested too deeply") from None
    except ValueError as exc:  # e.g. an integer with more digits than Python converts
        raise SpecError(file, None, f"not valid TOML: {exc}") from None
    top = _Reader(file, "", data)
    robot = _Reader(file, "robot", top.get("robot", "table", expect="a [robot] table"))
    name = robot.get("name", "string", expect="the robot's name (what act_rob names)")
    description = _param(robot, _ROBOT["description"])
    # the tool's limits (they bound the speed and acc clauses, compiler.clauses): at least
    # the clauses' own lower bounds
    max_speed = _param(robot, _ROBOT["max_speed"])
    max_acc = _param(robot, _ROBOT["max_acceleration"])
    robot.finish()

    top.used.add("axis")
    axis_tables = data.get("axis")
    if not isinstance(axis_tables, list) or not axis_tables:
        raise SpecError(file, "axis", "missing; expected one [[axis]] table per axis")
    axes = tuple(_axis(file, i, t) for i, t in enumerate(axis_tables))
    seen = set()
    for i, axis in enumerate(axes):
        if axis.name in seen:
            raise SpecError(file, f"axis[{i + 1}].name", f"{axis.name!r} names two axes")
        seen.add(axis.name)
    if not any(a.group == "main" for a in axes):
        raise SpecError(file, "axis", "expected at least one main axis")
    groups = [a.group for a in axes]
    if "additional" in groups and "main" in groups[groups.index("additional"):]:
        raise SpecError(file, "axis", "main axes must come before additional axes")
    axes = _couplings(file, axes)

    # [defaults]: what a move that leaves a clause out takes, checked as the clause table
    # (compiler.clauses) says; a bound from [robot] caps the built-in default.
    limits = _Limits(max_speed, max_acc)
    d = _Reader(file, "defaults", top.get("defaults", "table", {}))
    values = {}
    for clause in clauses.CLAUSES:
        if clause.default is not None:
            values[clause.default] = d.get(clause.default, "number", clause.builtin_default(limits),
                                           check=lambda v, c=clause: c.accepts_default(v, limits),
                                           expect=clause.default_expect(limits))
    d.finish()
    defaults = Defaults(**values)

    inputs = outputs = 16
    if "io" in data:
        io = _Reader(file, "io", top.get("io", "table"))
        inputs = io.get("inputs", "integer", 16, check=lambda v: 0 <= v <= 4096, expect="an integer 0..4096")
        outputs = io.get("outputs", "integer", 16, check=lambda v: 0 <= v <= 4096, expect="an integer 0..4096")
        io.finish()
    else:
        top.get("io", "table", None)

    analog = _analog_channels(file, data, top, "input")
    analog_out = _analog_channels(file, data, top, "output")
    zones = _zones(file, data, top, outputs)
    if zones and any(axis.group == "additional" for axis in axes):
        raise SpecError(file, "zone", "world zones need a robot without additional axes for now (a track or a "
                                      "positioner would move the tool in ways the zone checks do not count)")
    kinematics = _parameters(file, "kinematics", top.get("kinematics", "table", {}))
    tool, mounting = kinematics["tool"], kinematics["mounting"]
    named = _named_frames(file, data, top)

    tables = {section: _parameters(file, section, top.get(section, "table", {})) for section in params.SPEC_SECTIONS}
    broken = params.check_spec_rules(tables) or params.check_axis_rules(tables, axes)
    if broken is not None:
        raise SpecError(file, *broken)
    top.finish()
    typed = {section: params.settings(section, values) for section, values in tables.items()}
    return Spec(name, file, axes, defaults, max_speed, max_acc, inputs, outputs, tool, typed["controller"],
                _canonical_hash(data), description, typed["simulation"], typed["safety"], named, mounting, analog,
                analog_outputs=analog_out, zones=zones)


#: A named frame's or tool's table is a pose table (compiler.params) with a name.
_POSE_PARAM = params.section_params("kinematics")["mounting"]


def _pose_values(r: "_Reader") -> tuple[float, ...]:
    """x, y, z (mm), roll, pitch, yaw (deg) of a pose table (the orientation as roll,
    pitch, yaw or as a quaternion), each key optional (0)."""
    keys = params.POSE_KEYS + params.QUAT_KEYS
    r.used.update(keys)
    try:
        return _POSE_PARAM.check({k: v for k, v in r.table.items() if k in keys})
    except params.ParamError as exc:
        raise SpecError(r.file, r.key(exc.field) if exc.field else r.prefix, exc.reason) from None


def _named_frames(file: str, data: dict, top: "_Reader") -> tuple:
    """The ``[[frame]]`` and ``[[tool]]`` tables (:data:`compiler.frames.FRAME_KINDS`):
    ``((type, name, values), ...)`` in file order, frames first. A name must be a name a
    program can use, unique across both tables and not a predeclared one."""
    from grammar import keywords

    from .frames import FRAME_KINDS, offset_problem

    named: list[tuple[str, str, tuple[float, ...]]] = []
    taken = {kind.default: "predeclared" for kind in FRAME_KINDS}
    for kind in FRAME_KINDS:
        top.used.add(kind.table)
        tables = data.get(kind.table, [])
        if not isinstance(tables, list):
            raise SpecError(file, kind.table, f"expected an array of tables ([[{kind.table}]])")
        for i, table in enumerate(tables):
            r = _Reader(file, f"{kind.table}[{i + 1}]", table)
            name = r.get("name", "string", check=lambda n: re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", n) is not None,
                         expect=f"the {kind.type}'s name, a name a program can use (letters, digits, _)").lower()
            key = f"{kind.table}[{i + 1}].name"
            if name in keywords():
                raise SpecError(file, key, f"{name!r} is a reserved word of the language")
            if name in taken:
                what = "is predeclared" if taken[name] == "predeclared" else f"already names {taken[name]}"
                raise SpecError(file, key, f"{name!r} {what}: expected another name")
            values = _pose_values(r)
            r.finish()
            offset = math.sqrt(sum(v * v for v in values[:3]))
            if offset > kind.max_offset:
                raise SpecError(file, f"{kind.table}[{i + 1}]", offset_problem(kind, offset))
            taken[name] = f"a {kind.type}"
            named.append((kind.type, name, values))
    return tuple(named)


def _analog_channels(file: str, data: dict, top: "_Reader", what: str) -> tuple[AnalogChannel, ...]:
    """The ``[[analog_input]]`` (``what`` "input") or ``[[analog_output]]`` tables, in file
    order: analog input (output) 1, 2, ..."""
    key = f"analog_{what}"
    top.used.add(key)
    tables = data.get(key, [])
    if not isinstance(tables, list):
        raise SpecError(file, key, f"expected an array of tables ([[{key}]])")
    if len(tables) > MAX_ANALOG_INPUTS:
        raise SpecError(file, key, f"{len(tables)} analog {what}s: at most {MAX_ANALOG_INPUTS}")
    verb = "reads" if what == "input" else "is set to"
    channels = []
    for i, table in enumerate(tables):
        r = _Reader(file, f"{key}[{i + 1}]", table)
        name = r.get("name", "string", f"analog {what} {i + 1}", check=lambda v: 0 < len(v) <= 80,
                     expect=f"what it {'measures' if what == 'input' else 'drives'}, 1 to 80 characters")
        unit = r.get("unit", "string", "", check=lambda v: len(v) <= 20, expect="its unit, at most 20 characters")
        low = r.get("min", "number", expect=f"the least value it {verb} (a finite number)")
        high = r.get("max", "number", check=lambda v: v > low, expect=f"the greatest value it {verb}, more than "
                                                                       f"min ({low:g})")
        r.finish()
        channels.append(AnalogChannel(name, unit, float(low), float(high)))
    return tuple(channels)


def _zones(file: str, data: dict, top: "_Reader", outputs: int) -> tuple:
    """The ``[[zone]]`` tables (compiler.zones), in file order."""
    top.used.add("zone")
    tables = data.get("zone", [])
    if not isinstance(tables, list):
        raise SpecError(file, "zone", "expected an array of tables ([[zone]])")
    if len(tables) > zones.MAX_ZONES:
        raise SpecError(file, "zone", f"{len(tables)} zones: at most {zones.MAX_ZONES}")
    found = []
    for i, table in enumerate(tables):
        r = _Reader(file, f"zone[{i + 1}]", table)
        name = r.get("name", "string", check=lambda v: len(v) <= 40 and v not in [z.name for z in found],
                     expect="its name, 1 to 40 characters, not another zone's")
        shape = r.get("shape", "string", check=lambda v: v in zones.SHAPES,
                      expect=" or ".join(f'"{s}"' for s in zones.SHAPES))
        kind = r.get("kind", "string", "forbidden", check=lambda v: v in zones.KINDS,
                     expect=" or ".join(f'"{k}"' for k in zones.KINDS))
        output = 0
        if kind == "signal":
            output = r.get("output", "integer", check=lambda v: 1 <= v <= outputs,
                           expect=f"the digital output the zone switches, 1..{outputs}")
        r.used.update(zones.SHAPES[shape][1])
        values, wrong = zones.checked_values(shape, table)
        if wrong is not None:
            raise SpecError(file, r.key(wrong[0]), wrong[1])
        r.finish()
        found.append(zones.zone_of(name, shape, values, kind, output))
    return tuple(found)


def _parameters(file: str, section: str, table: dict) -> dict:
    """One of the specification's parameter tables, validated through
    :mod:`compiler.params` (unknown keys are errors: a misspelled limit must never be
    silently ignored); every parameter of the table with its value or its default."""
    accepted = params.spec_section(section)
    values = {}
    for key, value in table.items():
        param = accepted.get(key)
        if param is None:
            guess = did_you_mean(key, list(accepted))
            hint = f" (did you mean '{guess}'?)" if guess else ""
            raise SpecError(file, f"{section}.{key}", f"unknown key{hint}; known: {', '.join(accepted)}")
        try:
            values[key] = param.check(value)
        except params.ParamError as exc:
            where = f"{section}.{key}" + (f".{exc.field}" if exc.field else "")
            raise SpecError(file, where, exc.reason) from None
    for key, param in accepted.items():
        values.setdefault(key, param.default)
    return values


#: The largest specification file read (a robot's data is a few kilobytes).
MAX_SPEC_BYTES = 1 << 20


def load_spec(path: str | Path) -> Spec:
    """Read and validate a specification file (a regular file of at most
    :data:`MAX_SPEC_BYTES`); raises :class:`SpecError`."""
    name = str(path)
    if "\0" in name:
        raise SpecError(repr(name), None, "the file name contains a NUL byte")
    path = Path(path)
    try:
        with open(path, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                raise SpecError(name, None, "not a regular file (expected a TOML specification file)")
            data = f.read(MAX_SPEC_BYTES + 1)
    except OSError as exc:
        raise SpecError(name, None, f"cannot read: {exc.strerror or exc}") from None
    except ValueError as exc:  # e.g. a name the operating system cannot take
        raise SpecError(repr(name), None, f"cannot read: {exc}") from None
    if len(data) > MAX_SPEC_BYTES:
        raise SpecError(name, None, f"larger than {MAX_SPEC_BYTES // 1024} KiB: not a specification file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise SpecError(name, None, "not a text file (expected UTF-8 TOML)") from None
    return parse_spec(text, name)


#: ``[controller] profile`` and ``lookahead`` (declared in :mod:`compiler.params`).
CONTROLLER_PROFILES = params.section_params("controller")["profile"].choices
DEFAULT_LOOKAHEAD = params.section_params("controller")["lookahead"].default
MAX_LOOKAHEAD = params.section_params("controller")["lookahead"].high
