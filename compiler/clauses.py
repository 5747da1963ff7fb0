"""Every move clause, declared once: the motions it applies to, its value's type, unit
and allowed range (per motion; a bound may come from the robot's specification), where
its default comes from, and what it means.

Everything else reads :data:`CLAUSES`: the parser's "did you mean" (``compiler.syntax``),
the object code's clause mask, whose bit order is the table's order
(``compiler.objcode``), the checker's clause diagnostics (``compiler.check``), the
specification's ``[defaults]`` (``compiler.spec``), the runtime's check of every move it
is handed (:func:`validate_move_clauses`, ``runtime.loop.components.trajectory``) and the
documentation's tables (:func:`markdown`, :func:`defaults_markdown`, rendered into
``docs/language.md`` by ``python -m runtime.cli.docgen --write``). Nothing else declares a
clause's range.

A message about a value says what (the clause and its value), and the allowed range:
``speed = 2500 mm/s is out of range: expected 0 < speed <= 2000 (the robot's maximum)``.

Imports nothing from Lark, NumPy or ZeroMQ.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from .diagnostics import did_you_mean
from .params import MIN_TOOL_ACCELERATION, MIN_TOOL_SPEED, describe

__all__ = ["CLAUSES", "BY_NAME", "NAMES", "MOTIONS", "Motion", "Clause", "MoveClauses", "Problem", "Range",
           "defaults_markdown", "markdown", "validate_move_clauses"]

class Motion(enum.StrEnum):
    """The motions a move statement names (``move ptp``, ``move lin``, ``move circ``),
    declared once: the compiler, the object code (``MOVE_PTP``, ``MOVE_LIN``,
    ``MOVE_CIRC``), the runtime's moves and the clause table below compare against these
    members. Each is its keyword as a string (``Motion.PTP == "ptp"``, and ``"ptp"`` is
    what a message, a report or the object code shows)."""

    PTP = "ptp"
    LIN = "lin"
    CIRC = "circ"


#: The motions, in the object code's order.
MOTIONS: tuple[Motion, ...] = tuple(Motion)


@dataclass(frozen=True)
class Problem:
    """What is wrong with a clause: the message (what, and the allowed range) and an
    optional hint. ``str()`` gives both in one line (the runtime's form)."""

    message: str
    hint: str | None = None

    def __str__(self) -> str:
        return self.message if self.hint is None else f"{self.message}; {self.hint}"


def _number(x: float) -> str:
    """``x`` as ``:g`` shows it (2500, 1.5, 1e+09), or in full where that would round it
    to another number (1.0000001 is not "1": a message must not call 1 out of range)."""
    text = f"{x:g}"
    return text if float(text) == x or math.isnan(x) else repr(float(x))


def _show(value: object) -> str:
    """A value as a message shows it (never fails)."""
    if isinstance(value, float) or (isinstance(value, int) and not isinstance(value, bool)):
        try:
            return _number(float(value))
        except OverflowError:
            return describe(value)
    return describe(value)


def _quoted(text: str, limit: int = 60) -> str:
    return '"' + (text if len(text) <= limit else text[:limit - 3] + "...") + '"'


@dataclass(frozen=True)
class Range:
    """The values a numeric clause takes after ``motions``: ``low`` (excluded where
    ``low_open``) up to ``high`` included, none when ``high`` is None. ``high`` may name
    an attribute of the specification (``"max_speed"``), read where the range is checked.
    ``meaning``: what the value is after these motions (documentation, hints)."""

    motions: tuple[Motion, ...]
    low: float
    high: float | str | None
    low_open: bool = False
    unit: str = ""
    meaning: str = ""
    hint: str | None = None  # added to an out-of-range message

    def bounds(self, spec) -> tuple[float, float | None]:
        high = self.high
        return self.low, (float(getattr(spec, high)) if isinstance(high, str) else high)

    def contains(self, x: float, spec) -> bool:
        low, high = self.bounds(spec)
        return (x > low if self.low_open else x >= low) and (high is None or x <= high)

    def expected(self, name: str, spec, unit: bool = False, key: bool = False) -> str:
        """``0 < speed <= 2000 (the robot's maximum)``: the range as messages give it
        (``unit``: with the unit; ``key``: a bound from the specification named by its
        key, ``robot.max_speed``)."""
        low, high = self.bounds(spec)
        op = "<" if self.low_open else "<="
        shown_unit = f" {self.unit}" if unit and self.unit else ""
        if high is None:
            return f"{name} {'>' if self.low_open else '>='} {_number(low)}{shown_unit}"
        origin = ""
        if isinstance(self.high, str):
            origin = f" (robot.{self.high})" if key else " (the robot's maximum)"
        return f"{_number(low)} {op} {name} <= {_number(high)}{shown_unit}{origin}"

    def allowed(self) -> str:
        """The range as the documentation gives it (a bound from the specification by its
        key: ``0 < x ≤ `robot.max_speed```)."""
        low = f"{self.low:g}"
        if self.high is None:
            text = f"x {'>' if self.low_open else '≥'} {low}"
        else:
            high = f"`robot.{self.high}`" if isinstance(self.high, str) else f"{self.high:g}"
            text = f"{low} {'<' if self.low_open else '≤'} x ≤ {high}"
        return text + (f" {self.unit.replace('^2', '²')}" if self.unit else "")


@dataclass(frozen=True)
class Clause:
    """One move clause. ``type``: "real" (an integer or real value; the object code
    carries it as a real) or "robot" (a string: the name of the robot that executes the
    move). A real clause has one :class:`Range` per group of motions; together they
    cover ``motions``. ``field``: the :class:`MoveClauses` field it fills. ``default``:
    its key in the specification's ``[defaults]`` (None: the robot's own name),
    ``builtin``: the value when ``[defaults]`` leaves it out (at most the range's bound).
    ``instead``: the clause that does its job for the other motions (a hint). An "input"
    clause (``search``) names a digital input of the specification: an integer, none by
    default (the move does not search); ``excludes``: the clauses a move that gives it must
    leave out."""

    name: str
    motions: tuple[Motion, ...]
    type: str
    field: str
    ranges: tuple[Range, ...] = ()
    default: str | None = None
    builtin: float | None = None
    instead: str | None = None
    doc: str = ""
    excludes: tuple[str, ...] = ()

    @property
    def stack_type(self) -> str:
        """The type of its value in the object code (compiler.objcode's stack types)."""
        return _STACK_TYPES[self.type]

    @property
    def bit(self) -> int:
        """Its bit in the object code's clause mask."""
        return NAMES.index(self.name)

    def range_for(self, kind: str) -> Range | None:
        return next((r for r in self.ranges if kind in r.motions), None)

    def motions_text(self) -> str:
        return " and ".join(self.motions) + " moves" if len(self.motions) < 3 else "every move"

    # ---- problems ----
    def wrong_motion(self, kind: str) -> Problem:
        """The clause given to a motion it does not apply to."""
        hint = None
        other = BY_NAME.get(self.instead) if self.instead else None
        rng = other.range_for(kind) if other is not None else None
        if rng is not None:
            hint = f"use '{other.name}' ({rng.unit or rng.meaning}) for a {kind} move"
        return Problem(f"clause '{self.name}' applies to {self.motions_text()}, not {kind}", hint)

    def check(self, kind: str, value: object, spec, default: bool = False) -> tuple[object, Problem | None]:
        """``(value, None)``, the value normalized (a real clause's as a float), or
        ``(None, problem)``. ``kind`` must be one of the clause's motions; ``default``:
        the value is the specification's default, not the move's. Never raises."""
        if self.type == "robot":
            return self._check_robot(value, spec)
        if self.type == "input":
            if value is None and default:
                return None, None  # (not given: the move does not search)
            expected = f"a digital input 1..{spec.inputs} (the specification's inputs)"
            if isinstance(value, bool) or not isinstance(value, int):
                return None, Problem(f"{self.name} = {_show(value)} is not an input's number: expected {expected}")
            if not 1 <= value <= spec.inputs:
                return None, Problem(f"{self.name} = {_show(value)} is out of range: expected {expected}")
            return value, None
        rng = self.range_for(kind)
        source = "the specification's default " if default else ""
        where = f" for a {kind} move" if len(self.ranges) > 1 else ""
        unit = f" {rng.unit}" if rng.unit else ""
        expected = rng.expected(self.name, spec)
        hint = (f"give {self.name} on the move, or change [defaults] {self.name} in the specification"
                if default else rng.hint)
        shown = _show(value)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return None, Problem(f"{source}{self.name} = {shown} is not a number: expected {expected}", hint)
        try:
            x = float(value)
        except OverflowError:  # an integer beyond the floats: out of every range
            x = None
        if x is not None and not math.isfinite(x):
            what = "a number" if math.isnan(x) else "a finite number"
            return None, Problem(f"{source}{self.name} = {shown} is not {what}: expected {expected}", hint)
        if x is None or not rng.contains(x, spec):
            return None, Problem(f"{source}{self.name} = {shown}{unit} is out of range{where}: "
                                 f"expected {expected}", hint)
        return x, None

    def _check_robot(self, value: object, spec) -> tuple[object, Problem | None]:
        if not isinstance(value, str):
            return None, Problem(f"{self.name} = {_show(value)} is not a robot's name: "
                                 f"expected {_quoted(spec.name)}")
        if value != spec.name:
            guess = did_you_mean(value, [spec.name], cutoff=0.5)
            return None, Problem(f"{self.name} names robot {_quoted(value)}, but the system specification "
                                 f"describes {_quoted(spec.name)}",
                                 f"did you mean {_quoted(guess)}?" if guess else None)
        return value, None

    def excluded(self, given) -> Problem | None:
        """The problem of a move that gives this clause with one it ``excludes``
        (``given``: the names the move gives)."""
        both = [name for name in self.excludes if name in given]
        if not both:
            return None
        return Problem(f"clause '{self.name}' cannot be given with '{both[0]}': {_EXCLUDED_WHY[self.name]}")

    # ---- defaults ----
    def default_value(self, spec) -> object:
        """What a move that leaves the clause out takes: the specification's default (an
        "input" clause: None, nothing)."""
        if self.type == "input":
            return None
        return spec.name if self.default is None else getattr(spec.defaults, self.default)

    def builtin_default(self, limits) -> float:
        """The default when the specification's ``[defaults]`` leaves it out: ``builtin``,
        or a range's bound if that is smaller (``limits``: the robot's ``max_speed`` and
        ``max_acceleration``)."""
        value = self.builtin
        for rng in self.ranges:
            high = rng.bounds(limits)[1]
            if high is not None and high < value:
                value = high
        return value

    def accepts_default(self, value: float, limits) -> bool:
        """May ``[defaults]`` give ``value``? When it fits the clause's range after at
        least one of its motions (``approx = 5`` is a distance for lin and circ moves; a
        ptp move without approx is then an error)."""
        return any(rng.contains(value, limits) for rng in self.ranges)

    def default_expect(self, limits) -> str:
        """What ``[defaults]`` accepts, as the specification's errors say it."""
        parts = []
        for rng in self.ranges:
            text = rng.expected("x", limits, unit=True, key=True)
            if len(self.ranges) > 1:
                text += f" (after {', '.join(rng.motions)})"
            parts.append(text)
        return " or ".join(parts)


#: The object code's type of each kind of clause's value.
_STACK_TYPES = {"real": "real", "robot": "string", "input": "integer"}
#: Why a clause excludes others (said when a move gives both).
_EXCLUDED_WHY = {"search": "a search move ends at rest, where its input became true or at its target"}

#: THE table, in the object code's bit order: bit 0 (mask 1) is speed_ptp. The values of
#: the clauses a move gives are pushed in this order.
CLAUSES: tuple[Clause, ...] = (
    Clause("speed_ptp", (Motion.PTP,), "real", "speed",
           (Range((Motion.PTP,), 0.01, 1.0, meaning="a fraction of each axis's max_velocity",
                  hint="it is a fraction of each axis's max_velocity"),),
           default="speed_ptp", builtin=0.5, instead="speed",
           doc="speed of every axis, as a fraction of its max_velocity (the axes start and stop together)"),
    Clause("acc_ptp", (Motion.PTP,), "real", "acc",
           (Range((Motion.PTP,), 0.01, 1.0, meaning="a fraction of each axis's max_acceleration",
                  hint="it is a fraction of each axis's max_acceleration"),),
           default="acc_ptp", builtin=0.5, instead="acc",
           doc="acceleration of every axis, as a fraction of its max_acceleration (its max_jerk scales with it)"),
    Clause("speed", (Motion.LIN, Motion.CIRC), "real", "speed",
           (Range((Motion.LIN, Motion.CIRC), MIN_TOOL_SPEED, "max_speed", unit="mm/s", meaning="the tool's speed"),),
           default="speed", builtin=250.0, instead="speed_ptp",
           doc="speed of the tool centre point along the path (an upper bound: the move runs slower where "
               "an axis's limits ask for it)"),
    Clause("acc", (Motion.LIN, Motion.CIRC), "real", "acc",
           (Range((Motion.LIN, Motion.CIRC), MIN_TOOL_ACCELERATION, "max_acceleration", unit="mm/s^2",
                  meaning="the tool's acceleration"),),
           default="acc", builtin=1000.0, instead="acc_ptp",
           doc="acceleration of the tool centre point along the path (an upper bound, like speed)"),
    Clause("approx", MOTIONS, "real", "approx",
           (Range((Motion.PTP,), 0.0, 1.0, meaning="a fraction of the move's slowdown",
                  hint="after a ptp move it is a fraction of the slowdown (after lin and circ a distance in mm)"),
            Range((Motion.LIN, Motion.CIRC), 0.0, None, unit="mm", meaning="a distance from the target")),
           default="approx", builtin=0.0,
           doc="blend into the next move instead of stopping at the target: after ptp, the fraction of the "
               "slowdown overlapped with the next move's speed-up; after lin and circ, how far from the "
               "target the tool leaves the path (0: stop at the target)"),
    Clause("act_rob", MOTIONS, "robot", "robot",
           doc="the robot that executes the move (a program drives exactly the robot of its specification)"),
    Clause("search", (Motion.LIN,), "input", "search", excludes=("approx",),
           doc="a search move (RAPID's SearchL): the robot stops on its path where digital input N becomes "
               "true, and search_pose() is where it did; a move that reaches its target first, or an input "
               "already true, is the program's search error"),
)

NAMES: tuple[str, ...] = tuple(c.name for c in CLAUSES)
BY_NAME: dict[str, Clause] = {c.name: c for c in CLAUSES}
_FIELDS = ("speed", "acc", "approx", "robot")  # every motion has a value of each
_OPTIONAL = ("search",)  # a motion it applies to may have one (None: not given)

for _clause in CLAUSES:
    assert _clause.motions and set(_clause.motions) <= set(MOTIONS), _clause.name
    assert _clause.field in _FIELDS + _OPTIONAL, _clause.name
    assert all(name in NAMES for name in _clause.excludes), _clause.name
    if _clause.type == "real":
        _covered = [m for r in _clause.ranges for m in r.motions]
        assert sorted(_covered) == sorted(_clause.motions), f"{_clause.name}: one range per motion"
        assert _clause.default is not None and _clause.builtin is not None, _clause.name
    elif _clause.type == "input":
        assert _clause.field in _OPTIONAL and not _clause.ranges and _clause.default is None, _clause.name
    else:
        assert _clause.type == "robot" and not _clause.ranges and _clause.default is None, _clause.name
    assert _clause.instead is None or _clause.instead in NAMES, _clause.name
for _kind in MOTIONS:  # every motion gets one value for each field
    _filled = sorted(c.field for c in CLAUSES if _kind in c.motions and c.field in _FIELDS)
    assert _filled == sorted(_FIELDS), (_kind, _filled)


@dataclass(frozen=True)
class MoveClauses:
    """A move's clauses, checked and completed with the specification's defaults.

    ``speed`` and ``acc`` are ``speed_ptp`` and ``acc_ptp`` (fractions of each axis's
    limits) for a ptp move, ``speed`` (mm/s) and ``acc`` (mm/s^2) for lin and circ;
    ``approx`` is a fraction after ptp, mm after lin and circ; ``robot`` the robot's
    name; ``search`` the digital input a search move watches (None: it does not search)."""

    kind: str
    speed: float
    acc: float
    approx: float
    robot: str
    search: int | None = None

    def value(self, name: str) -> object:
        """The value of clause ``name`` (one that applies to this motion)."""
        clause = BY_NAME[name]
        if self.kind not in clause.motions:
            raise KeyError(f"clause '{name}' does not apply to {self.kind} moves")
        return getattr(self, clause.field)


def validate_move_clauses(kind: object, clauses: object, spec) -> MoveClauses | str:
    """The clauses a move was handed (``{name: value}``, only those the program gave)
    checked against the table and completed with the specification's defaults: a
    :class:`MoveClauses`, or a problem (a string naming the clause, its value and the
    allowed range). What the checker refuses at compile time is refused here too. Object
    code is untrusted: never raises, whatever the values (NaN, infinities, huge
    integers, strings, anything)."""
    if not isinstance(kind, str) or kind not in MOTIONS:
        return f"unknown motion {describe(kind)}: expected one of {', '.join(MOTIONS)}"
    if not isinstance(clauses, dict):
        return f"the move's clauses must be a table of names and values, not {describe(clauses)}"
    for name in clauses:
        if not isinstance(name, str) or name not in BY_NAME:
            return f"unknown clause {describe(name)}: clauses are {', '.join(NAMES)}"
    values: dict[str, object] = {}
    for clause in CLAUSES:
        given = clause.name in clauses
        if kind not in clause.motions:
            if given:
                return str(clause.wrong_motion(kind))
            continue
        if given and clause.excludes:
            problem = clause.excluded(clauses)
            if problem is not None:
                return str(problem)
        value = clauses[clause.name] if given else clause.default_value(spec)
        checked, problem = clause.check(kind, value, spec, default=not given)
        if problem is not None:
            return str(problem)
        values[clause.field] = checked
    return MoveClauses(kind, **values)


# ---- documentation ------------------------------------------------------------------------

def _cell(text: object) -> str:
    return str(text).replace("|", "\\|")


def _code_list(items) -> str:
    return ", ".join(f"`{item}`" for item in items)


def _allowed(clause: Clause) -> str:
    if clause.type == "input":
        return "a digital input 1..`io.inputs`, an integer"
    if clause.type == "robot":
        return "the robot's name in the specification (`[robot] name`), a constant string"
    if len(clause.ranges) == 1:
        return clause.ranges[0].allowed()
    return "; ".join(f"{_code_list(r.motions)}: {r.allowed()} ({r.meaning})" for r in clause.ranges)


def _default(clause: Clause) -> str:
    if clause.type == "input":
        return "none (the move does not search)"
    if clause.default is None:
        return "the specification's robot"
    return f"`[defaults] {clause.default}`"


def markdown() -> str:
    """The clause table of docs/language.md."""
    lines = ["| clause | applies to | value | allowed | default | meaning |", "|---|---|---|---|---|---|"]
    for c in CLAUSES:
        value = {"robot": "string", "input": "integer"}.get(c.type, "integer or real")
        lines.append(f"| `{c.name}` | {_code_list(c.motions)} | {value} | {_cell(_allowed(c))} "
                     f"| {_cell(_default(c))} | {_cell(c.doc)} |")
    return "\n".join(lines) + "\n"


def defaults_markdown() -> str:
    """The ``[defaults]`` table of the specification's reference (docs/language.md)."""
    lines = ["| key | default | allowed |", "|---|---|---|"]
    for c in CLAUSES:
        if c.default is None:
            continue
        capped = [f"`robot.{r.high}`" for r in c.ranges if isinstance(r.high, str)]
        default = f"{c.builtin:g}" + (f", or {' / '.join(capped)} if smaller" if capped else "")
        lines.append(f"| `{c.default}` | {_cell(default)} | {_cell(_allowed(c))} |")
    return "\n".join(lines) + "\n"
