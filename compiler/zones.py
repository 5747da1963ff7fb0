"""World zones (docs/language.md, "World zones"; ABB's World Zones, KUKA's workspaces):
boxes and vertical cylinders of the cell, in the world frame, declared in the system
specification (``[[zone]]``), that the tool centre point and the flange never enter
(forbidden zones), or whose digital output is true while the tool centre point is inside
(signal zones: runtime.loop.components.io.ZoneSignals, every 1 ms).

One declaration each: :data:`SHAPES` (a shape's keys, what they mean and their checks),
:data:`KINDS` and :class:`Zone` (the geometry: whether a point is inside, how far it is from the zone). The
specification's loader, the planners' check of every move before it starts
(runtime.motion.zonecheck), the safety supervisor's check of every 1 ms reference
(runtime.loop.components.safety) and the manual's table read them.

Of the forbidden zones:

* **Before a move starts** its whole path is checked (the flange's and the tool centre
  point's, sampled at most :data:`STEP` mm apart) against each zone grown by
  :data:`MARGIN` mm: a move whose path would come closer is refused, the program's
  ``move`` error ("the path enters zone 'fixture' at 40 % of its duration: the tool centre
  point would be 12.0 mm inside it"); ``irl check`` finds it before anything moves. A
  blend that would come closer is not made (the robot stops at the corner). The margin
  holds the 1 ms references (interpolated between the checked 5 ms setpoints) and the
  stops on the path (a pause, an abort: on the checked path) outside the zone.
* **Every 1 ms** the safety supervisor checks the servo's reference: the flange or the
  tool centre point inside a zone (itself, not grown) stops the robot (category 1, "zone"):
  a backstop for what no plan covers (a fault's stop ramp).

Imports nothing from Lark, NumPy or ZeroMQ.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["CONSTRUCTORS", "KINDS", "MARGIN", "MAX_ZONES", "SHAPES", "SIGNAL_WORD", "STEP", "WORD", "Zone",
           "checked_values", "forbidden", "from_plain", "markdown", "run_problem", "shape_problem", "shown", "signals",
           "to_plain", "values_of"]

#: mm: how far from a zone a planned path must stay (the flange and the tool centre point).
MARGIN = 5.0
#: mm: the most the flange or the tool centre point moves between two samples of the check.
STEP = 2.0
#: The most zones a specification and a program may declare together.
MAX_ZONES = 64
#: The largest coordinate a zone may have (mm).
MAX_COORDINATE = 100_000.0

#: The shapes: name -> (what it is, its keys: name -> what the key gives). Every key is
#: required; ``name`` and ``shape`` are every zone's.
SHAPES: dict[str, tuple[str, dict[str, str]]] = {
    "box": ("a box whose sides are parallel to the world's axes", {
        "min": "the corner with the least x, y and z: [x, y, z] (mm)",
        "max": "the corner with the greatest x, y and z: [x, y, z] (mm), each more than min's",
    }),
    "cylinder": ("a cylinder standing upright (its axis along the world's z)", {
        "centre": "where its axis is: [x, y] (mm)",
        "radius": "its radius (mm, more than 0)",
        "z": "its bottom and top: [low, high] (mm, high more than low)",
    }),
}


#: The kinds of zone (``kind``; "forbidden" when a zone does not say).
KINDS: dict[str, str] = {
    "forbidden": "the flange and the tool centre point never enter it (every move is checked before it starts, "
                 "every 1 ms reference by the safety supervisor)",
    "signal": "digital output `output` is true while the tool centre point is inside it, false while it is not, "
              "every 1 ms (KUKA's workspace signals, ABB's WZDOSet); the robot may enter it",
}


#: A program's own zones (``zone NAME := box(LOW, HIGH);``, ``zone NAME := cylinder(FOOT,
#: RADIUS, HEIGHT) signal N;``): the declaration's words (names to the parser, checked by the
#: checker), and each shape's constructor: its parameters and what they give.
WORD, SIGNAL_WORD = "zone", "signal"
CONSTRUCTORS: dict[str, tuple[str, str]] = {
    "box": ("LOW, HIGH", "two positions: the corners with the least and the greatest x, y and z"),
    "cylinder": ("FOOT, RADIUS, HEIGHT", "a position, the centre of its bottom; its radius and its height (mm)"),
}


def values_of(shape: str, args: tuple) -> dict:
    """A program's shape's constructor arguments (positions as (x, y, z), numbers) as the
    specification's keys of that shape (:data:`SHAPES`), to be checked by :func:`problem`."""
    if shape == "box":
        return {"min": [float(v) for v in args[0]], "max": [float(v) for v in args[1]]}
    (x, y, z), radius, height = args
    return {"centre": [float(x), float(y)], "radius": float(radius), "z": [float(z), float(z) + float(height)]}


def shape_problem(shape: str, args: tuple) -> str | None:
    """What is wrong with a program's ``box(LOW, HIGH)`` or ``cylinder(FOOT, RADIUS,
    HEIGHT)`` (positions as (x, y, z), numbers), in the program's words, or None. Whether
    it is wrong is :func:`problem`'s to say (one rule for both)."""
    values, checked = values_of(shape, args), {}
    for key, value in values.items():
        if problem(shape, key, value, checked) is None:
            checked[key] = value
            continue
        far = [v for v in (value if isinstance(value, list) else [value]) if not abs(v) <= MAX_COORDINATE]
        if far:
            return f"{far[0]:g} mm is beyond the cell's extent: each coordinate and size is at most " \
                   f"{MAX_COORDINATE:g} mm"
        if key == "max":
            low, high = values["min"], value
            axes = [axis for axis, lo, hi in zip("xyz", low, high) if not hi > lo]
            swapped = all(hi < lo for lo, hi in zip(low, high))
            return (f"HIGH {_point(high)} is not above LOW {_point(low)} in {', '.join(axes)}: box(LOW, HIGH) takes "
                    "the corner with the least x, y and z first, and a box has a size in each axis"
                    + (": swap them" if swapped else ""))
        if key == "radius":
            return f"its RADIUS must be more than 0 mm, not {value:g}"
        return f"its HEIGHT must be more than 0 mm, not {value[1] - value[0]:g}"
    return None


@dataclass(frozen=True)
class Zone:
    """A zone: ``low`` and ``high`` its bounding box's corners (x, y, z, mm, world); a
    cylinder's ``centre`` (x, y) and ``radius`` besides (a box's radius is 0)."""

    name: str
    shape: str
    low: tuple[float, float, float]
    high: tuple[float, float, float]
    centre: tuple[float, float] = (0.0, 0.0)
    radius: float = 0.0
    kind: str = "forbidden"
    output: int = 0  # a signal zone's digital output

    def depth(self, x: float, y: float, z: float) -> float:
        """How far the point is inside the zone (mm, > 0), or minus how far it is outside
        (< 0; exactly for a box's faces and a cylinder's side, a lower bound of the distance
        beyond an edge). Real-time safe (plain floats)."""
        lx, ly, lz = self.low
        hx, hy, hz = self.high
        dz = min(z - lz, hz - z)
        if self.shape == "box":
            d = min(x - lx, hx - x, y - ly, hy - y, dz)
        else:
            d = min(self.radius - math.hypot(x - self.centre[0], y - self.centre[1]), dz)
        return d

    def describe(self) -> str:
        if self.shape == "box":
            return (f"box {_point(self.low)}..{_point(self.high)}")
        return (f"cylinder at ({self.centre[0]:g}, {self.centre[1]:g}), radius {self.radius:g} mm, "
                f"z {self.low[2]:g}..{self.high[2]:g} mm")


def _point(p) -> str:
    return "(" + ", ".join(shown(v, "g") for v in p) + ")"


def shown(value: float, spec: str = ".1f") -> str:
    """A coordinate as a message shows it (``-0.0`` as ``0.0``: a rounded small negative)."""
    text = format(value, spec)
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def zone_of(name: str, shape: str, values: dict, kind: str = "forbidden", output: int = 0) -> Zone:
    """A zone from its checked keys (the specification's loader checks them: :data:`SHAPES`)."""
    if shape == "box":
        return Zone(name, shape, tuple(values["min"]), tuple(values["max"]), kind=kind, output=output)
    cx, cy = values["centre"]
    r = values["radius"]
    low, high = values["z"]
    return Zone(name, shape, (cx - r, cy - r, low), (cx + r, cy + r, high), (cx, cy), r, kind, output)


def to_plain(zone: Zone) -> list:
    """A zone as the object code holds it: ``[name, shape, kind, output, {key: value}]``."""
    if zone.shape == "box":
        values = {"min": list(zone.low), "max": list(zone.high)}
    else:
        values = {"centre": list(zone.centre), "radius": zone.radius, "z": [zone.low[2], zone.high[2]]}
    return [zone.name, zone.shape, zone.kind, zone.output, values]


def checked_values(shape: str, table: dict) -> tuple[dict, tuple[str, str] | None]:
    """The keys of a ``shape`` (:data:`SHAPES`) from ``table``, in order: each present and
    right by :func:`problem`, converted to floats. (the values, None), or (the values checked
    so far, (the first key missing or wrong, what is wrong with it))."""
    values: dict = {}
    for key, expect in SHAPES[shape][1].items():
        if key not in table:
            return values, (key, f"missing; expected {expect}")
        said = problem(shape, key, table[key], values)
        if said is not None:
            return values, (key, said)
        values[key] = [float(v) for v in table[key]] if isinstance(table[key], list) else float(table[key])
    return values, None


def from_plain(data) -> Zone:
    """The inverse of :func:`to_plain`, every key checked as the specification's are;
    ValueError says what is wrong."""
    if not (isinstance(data, list) and len(data) == 5 and isinstance(data[0], str) and 0 < len(data[0]) <= 40
            and data[1] in SHAPES and data[2] in KINDS and isinstance(data[3], int) and not isinstance(data[3], bool)
            and (data[3] >= 1 if data[2] == "signal" else data[3] == 0) and isinstance(data[4], dict)
            and set(data[4]) == set(SHAPES[data[1]][1])):
        raise ValueError("expected [name (1..40 characters), shape, kind, output (a signal zone's: 1.., else 0), "
                         "{the shape's keys}]")
    name, shape, kind, output, table = data
    values, wrong = checked_values(shape, table)
    if wrong is not None:
        raise ValueError(f"zone {name!r:.40}: {wrong[0]}: {wrong[1]}")
    return zone_of(name, shape, values, kind, output)


def run_problem(spec, zones: tuple) -> str | None:
    """What is wrong with a program's ``zones`` on the robot of ``spec`` (beside its own),
    or None: at most :data:`MAX_ZONES` in all, each named once, a signal zone's output one
    the robot has, and a robot without additional axes."""
    if not zones:
        return None
    together = tuple(spec.zones) + tuple(zones)
    names = [zone.name.lower() for zone in together]  # (a program's are names, lower-cased: "Clamp" is clamp)
    if len(together) > MAX_ZONES:
        return f"{len(zones)} zones of the program and {len(spec.zones)} of the specification: at most {MAX_ZONES}"
    if len(set(names)) != len(names):
        twice = next(n for n in names if names.count(n) > 1)
        return f"two zones are called {twice!r}: a zone of the program needs a name of its own"
    for zone in zones:
        if zone.kind == "signal" and not 1 <= zone.output <= spec.outputs:
            return f"zone {zone.name!r} switches output {zone.output}: the robot has outputs 1..{spec.outputs}"
    if any(axis.group == "additional" for axis in spec.axes):
        return ("world zones need a robot without additional axes for now (a track or a positioner would move the "
                "tool in ways the zone checks do not count)")
    return None


def forbidden(zones) -> tuple:
    """The zones the flange and the tool centre point never enter."""
    return tuple(z for z in zones if z.kind == "forbidden")


def signals(zones) -> tuple:
    """The zones that switch an output while the tool centre point is inside."""
    return tuple(z for z in zones if z.kind == "signal")


def problem(shape: str, key: str, value: object, values: dict) -> str | None:
    """What is wrong with ``value`` for ``key`` of a ``shape`` (``values``: the keys checked
    before it), or None."""
    def numbers(n: int) -> bool:
        return (isinstance(value, list) and len(value) == n and all(
            not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
            and abs(v) <= MAX_COORDINATE for v in value))
    expect = SHAPES[shape][1][key]
    if key in ("min", "max"):
        ok = numbers(3) and (key == "min" or "min" not in values or all(h > lo for h, lo in zip(value, values["min"])))
    elif key == "centre":
        ok = numbers(2)
    elif key == "z":
        ok = numbers(2) and value[1] > value[0]
    else:  # radius
        ok = (not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
              and 0 < value <= MAX_COORDINATE)
    return None if ok else f"expected {expect} (|x| <= {MAX_COORDINATE:g} mm), got {value!r}"


def markdown() -> str:
    """The zone keys, for docs/language.md (``python -m runtime.cli.docgen``)."""
    lines = ["| shape | key | what it gives |", "|---|---|---|",
             "| every zone | `name` | its name, in messages (1 to 40 characters, each zone's own) |",
             "| | `shape` | " + " or ".join(f"`\"{s}\"`" for s in SHAPES) + " |",
             "| | `kind` | " + "; ".join(f"`\"{k}\"`: {doc}" for k, doc in KINDS.items())
             + " (default `\"forbidden\"`) |",
             "| | `output` | a signal zone's digital output (1 .. `io.outputs`); a forbidden zone has none |"]
    for shape, (doc, keys) in SHAPES.items():
        first = True
        for key, text in keys.items():
            lines.append(f"| {f'`{shape}`: {doc}' if first else ''} | `{key}` | {text} |")
            first = False
    return "\n".join(lines) + "\n"
