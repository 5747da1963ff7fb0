"""Frames and tools, declared once: the two things a program makes active with ``use``
(the base its pose targets are in, and the tool whose centre point goes there), their
type names, their defaults, the specification's tables that name more of them, and the
bounds a value must keep.

Everything else reads :data:`FRAME_KINDS`: the specification loader's ``[[frame]]`` and
``[[tool]]`` tables (``compiler.spec``), the checker's types, predeclared names and
``use`` statement (``compiler.check``), the instruction table (``compiler.objcode``), the
runtime's check of every value made active (:func:`problem`, called by the trajectory
generator) and the documentation (:func:`markdown`, rendered into docs/language.md by
``python -m runtime.cli.docgen --write``).

Imports nothing from Lark, NumPy or ZeroMQ.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .geometry import quat_to_rpy
from .values import Pose, Position, Quat, Rpy

__all__ = ["FRAME_KINDS", "BY_KEYWORD", "BY_TYPE", "FrameKind", "IDENTITY", "describe_name", "markdown",
           "offset_problem", "pose_of", "problem", "values_of"]

#: x, y, z (mm), roll, pitch, yaw (deg): the identity.
IDENTITY = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

#: The longest name a report or telemetry gives an active frame or tool (characters).
MAX_NAME = 40


@dataclass(frozen=True)
class FrameKind:
    """One of the two: ``keyword`` (``use KEYWORD EXPR;``), ``type`` (its L-IRL type
    name and constructor), ``instruction`` (the object code's), ``default`` (the name
    predeclared for the value a program starts with), ``table`` (the specification's
    array of tables that names more of them), ``in_frame`` (what its pose is given in),
    ``max_offset`` (mm: the largest distance of its origin from that frame's) and
    ``doc``."""

    keyword: str
    type: str
    instruction: str
    default: str
    table: str
    in_frame: str
    max_offset: float
    doc: str


FRAME_KINDS: tuple[FrameKind, ...] = (
    FrameKind("base", "frame", "USE_BASE", "world", "frame", "the world frame", 100_000.0,
              "the frame a move's pose targets are given in"),
    FrameKind("tool", "tool", "USE_TOOL", "default_tool", "tool", "the flange frame", 5_000.0,
              "the tool centre point: the point (and its axes) that a move's pose target puts in place"),
)

BY_KEYWORD: dict[str, FrameKind] = {k.keyword: k for k in FRAME_KINDS}
BY_TYPE: dict[str, FrameKind] = {k.type: k for k in FRAME_KINDS}


def pose_of(values: tuple) -> Pose:
    """``pose(pos(x, y, z), rpy(roll, pitch, yaw))`` of six numbers."""
    x, y, z, roll, pitch, yaw = values
    return Pose(Position(x, y, z), Rpy(roll, pitch, yaw))


def values_of(pose: Pose) -> tuple:
    """The six numbers x, y, z, roll, pitch, yaw of a pose (a ``quat`` as roll, pitch,
    yaw; NaN for a quaternion that is not a rotation). Never raises on a pose the VM
    made (its fields are numbers)."""
    o = pose.orientation
    try:
        rpy = quat_to_rpy((o.w, o.x, o.y, o.z)) if isinstance(o, Quat) else (o.roll, o.pitch, o.yaw)
    except (ValueError, TypeError):  # not a rotation (hand-made object code): not finite, refused
        rpy = (math.nan,) * 3
    p = pose.position
    return (p.x, p.y, p.z, *rpy)


def problem(kind: FrameKind, values: tuple) -> str | None:
    """What is wrong with ``values`` (x, y, z, roll, pitch, yaw) as ``kind``'s active
    value, or None. Never raises."""
    names = ("x", "y", "z", "roll", "pitch", "yaw")
    for name, v in zip(names, values):
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            return f"use {kind.keyword}: {name} = {v!r} is not a finite number"
    offset = math.sqrt(sum(v * v for v in values[:3]))
    if offset > kind.max_offset:
        return f"use {kind.keyword}: {offset_problem(kind, offset)}"
    return None


def offset_problem(kind: FrameKind, offset: float) -> str:
    """The message for an origin ``offset`` mm from its frame's, beyond ``max_offset``."""
    return (f"the {kind.type}'s origin is {offset:.6g} mm from the origin of {kind.in_frame}: expected at most "
            f"{kind.max_offset:g} mm")


def describe_name(text: str) -> str:
    """A name as reports and telemetry give it: at most :data:`MAX_NAME` characters."""
    text = " ".join(text.split())
    return text if len(text) <= MAX_NAME else text[:MAX_NAME - 3] + "..."


def markdown() -> str:
    """docs/language.md's list of the bounds (the generated part of the frames section)."""
    return "".join(f"  a `{k.type}`'s origin at most {k.max_offset:,.0f} mm from the origin of {k.in_frame} "
                   f"(`use {k.keyword}`);\n" for k in FRAME_KINDS)
