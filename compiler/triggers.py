"""Path triggers, declared once: where on a move's path a trigger may be (``after start``,
``before end``, ``after end``), in which units (``mm`` of the tool's path, ``ms``), the
allowed amounts, and what it may do.

Read by the checker (``compiler.check``), the code generator and the instruction table
(``compiler.objcode``: the operands of ``TRIGGER_OUT`` and ``TRIGGER_SET`` are indexes
into :data:`PLACES` and :data:`UNITS`), the runtime (``runtime.loop.vm``, the trajectory
generator and ``runtime.motion``: :func:`problem` checks every trigger a program hands
over) and the documentation (:func:`markdown`). Imports nothing from Lark, NumPy or ZeroMQ.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .clauses import MOTIONS, Motion

__all__ = ["PLACES", "PLACE_INDEX", "UNITS", "UNIT_INDEX", "Place", "Unit", "markdown", "problem", "MAX_PENDING",
           "SET_TYPES"]


@dataclass(frozen=True)
class Unit:
    """``mm`` or ``ms``: the largest amount, and which motions take it."""

    name: str
    high: float
    motions: tuple[Motion, ...]
    doc: str


@dataclass(frozen=True)
class Place:
    """Where a trigger is counted from: ``words`` as written (``after start``), the
    units it takes, and what it means."""

    words: str
    units: tuple[str, ...]
    doc: str

    @property
    def direction(self) -> str:
        return self.words.split()[0]

    @property
    def reference(self) -> str:
        return self.words.split()[1]


#: In the object code's order (a TRIGGER instruction's ``unit`` operand indexes it).
UNITS: tuple[Unit, ...] = (
    Unit("ms", 60_000.0, MOTIONS,
         "a time: where the robot is that long after the start (before the end) at 100 % override"),
    Unit("mm", 100_000.0, (Motion.LIN, Motion.CIRC), "a distance along the tool's path (lin and circ moves)"),
)

#: In the object code's order (a TRIGGER instruction's ``place`` operand indexes it).
PLACES: tuple[Place, ...] = (
    Place("after start", ("ms", "mm"), "that far into the move (0: as it starts)"),
    Place("before end", ("ms", "mm"), "that far before the move's target (0: as it reaches it)"),
    Place("after end", ("ms",), "that long after the move reached its target (on the next move's path, or at "
                                "rest)"),
)

#: Index in the object code of a place (by its words) and of a unit (by its name).
PLACE_INDEX: dict[str, int] = {p.words: i for i, p in enumerate(PLACES)}
UNIT_INDEX: dict[str, int] = {u.name: i for i, u in enumerate(UNITS)}

#: The types a trigger may store into (a global variable; the value is evaluated when the
#: trigger statement runs).
SET_TYPES = ("bool", "integer", "real")

#: The most triggers one move may have (more is an error at the move's line).
MAX_PENDING = 32


def problem(place: int, unit: int, amount: object) -> str | None:
    """What is wrong with a trigger's place, unit and amount (object code is untrusted), or
    None. Never raises."""
    if not (isinstance(place, int) and 0 <= place < len(PLACES) and isinstance(unit, int) and 0 <= unit < len(UNITS)):
        return "unknown trigger place or unit"
    p, u = PLACES[place], UNITS[unit]
    if u.name not in p.units:
        return f"a trigger {p.words} is given in {' or '.join(p.units)}, not {u.name}"
    if isinstance(amount, bool) or not isinstance(amount, (int, float)):
        return f"a trigger's amount must be a number, not {type(amount).__name__}"
    try:
        x = float(amount)
    except OverflowError:
        x = math.inf
    if not (0.0 <= x <= u.high):
        return f"trigger when {amount} {u.name} {p.words}: expected 0 <= amount <= {u.high:g} {u.name}"
    return None


def markdown() -> str:
    """docs/language.md's table of the places and units."""
    lines = ["| where | units | fires |", "|---|---|---|"]
    for p in PLACES:
        units = ", ".join(f"`{u}` (0..{next(x for x in UNITS if x.name == u).high:,.0f})" for u in p.units)
        lines.append(f"| `{p.words}` | {units} | {p.doc} |")
    lines.append("")
    for u in UNITS:
        lines.append(f"- `{u.name}`: {u.doc}.")
    return "\n".join(lines) + "\n"
