"""Teaching a point: the L-IRL literals that name where the arm is (``irl pose``, ``irl
where``, the pendant's Teach).

:func:`pose_literal` does the work: the tool centre point of the joints by the forward
kinematics (with the chosen tool, in the chosen base), the configuration they are in
(:func:`compiler.configs.config_of`), and the numbers rounded to 0.001 mm and deg, or
finer where that is what it takes for the literal to resolve to the same configuration
and turns (checked by solving it again, as a ``move ptp`` does); :func:`joint_literal`
the ``joint(mainjoint(...))`` of joint values; :func:`named_frame` a tool or base of the
specification by its name. Not real-time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from compiler.configs import Config, config_of, format_config
from compiler.frames import pose_of
from compiler.semantics import compose, inverse
from compiler.values import Pose, Position, Rpy, format_number

from runtime.motion.kinematics import Kinematics, KinematicsError

#: Decimals (mm, deg) of a literal: the first that resolves to the same configuration.
DIGITS = (3, 4, 5, 6, 8, 10, 12)


class PoseError(ValueError):
    """Joint values no pose literal can name (outside the limits, at a singularity)."""


@dataclass(frozen=True)
class Taught:
    """What :func:`pose_literal` found: the literal's ``text`` and its ``pose`` (in the
    base), the joints, the configuration id and its :class:`Config`, and the joints the
    literal resolves to (``resolved``)."""

    text: str
    pose: Pose
    joints: tuple
    config_id: int
    config: Config
    resolved: tuple


def _rounded(pose: Pose, digits: int | None) -> Pose:
    if digits is None:
        return pose
    p, o = pose.position, pose.orientation

    def r(v: float) -> float:
        return round(v, digits) + 0.0  # (no -0)
    return Pose(Position(r(p.x), r(p.y), r(p.z)), Rpy(r(o.roll), r(o.pitch), r(o.yaw)), pose.config)


def limits_problem(kinematics: Kinematics, joints: tuple) -> str | None:
    """Which joint value is outside its axis's limits, or None."""
    for name, (lo, hi), v in zip(kinematics.names, kinematics.limits, joints):
        if not lo <= v <= hi:
            return f"{name} = {format_number(v)} deg is outside its limits {lo:g}..{hi:g}"
    return None


def pose_literal(kinematics: Kinematics, joints, base: tuple | None = None, exact: bool = False) -> Taught:
    """The pose literal (in ``base``, x y z roll pitch yaw in the world; None: the world)
    with its full configuration that reaches ``joints`` (the six main axes, deg) with
    ``kinematics``' tool. Rounded to 0.001 mm and deg (``exact``: every digit), finer
    where it must be to resolve to the same configuration and turns. Raises
    :class:`PoseError` for joints outside the limits or at a singularity."""
    joints = tuple(float(v) for v in joints)
    if len(joints) != 6 or not all(math.isfinite(v) for v in joints):
        raise PoseError(f"expected six finite joint values (the main axes), got {len(joints)}")
    problem = limits_problem(kinematics, joints)
    if problem is not None:
        raise PoseError(problem)
    cid = kinematics.configuration(joints)
    config = config_of(cid, joints)
    world = kinematics.forward_pose(joints)
    in_base = world if base is None else compose(inverse(pose_of(base)), world)
    full = Pose(in_base.position, in_base.orientation, config)
    why = ""
    for digits in (None,) if exact else DIGITS + (None,):
        pose = _rounded(full, digits)
        target = pose if base is None else compose(pose_of(base), pose)
        try:
            resolved = tuple(kinematics.inverse_config(target, config, near=kinematics.home))
        except KinematicsError as exc:
            why = str(exc)
            continue
        if config_of(kinematics.configuration(resolved), resolved) == config:
            return Taught(str(pose), pose, joints, cid, config, resolved)
        why = f"it resolves to {format_config(config_of(kinematics.configuration(resolved), resolved))}"
    hint = ("they are at (or too near) a singularity" if why.startswith("singular") else
            "a value of A1, A4 or A6 a hair below the end of its turn is the other end of it, the same pose")
    raise PoseError(f"no pose target reaches these joints in {format_config(config)} ({why}): {hint}; teach them "
                    "as joint(...) or move them away from it")


def joint_literal(position, main: int) -> str:
    """``joint(mainjoint(...))`` of axis positions (deg or mm, the ``main`` main axes first;
    the rest in ``addjoint(...)``), to 0.001."""
    values = [float(v) for v in position]
    text = f"joint(mainjoint({', '.join(f'{v:.3f}' for v in values[:main])})"
    extra = values[main:]
    return text + (f", addjoint({', '.join(f'{v:.3f}' for v in extra)}))" if extra else ")")


def named_frame(spec, kind: str, name: str | None, default: str) -> tuple[str, tuple | None]:
    """(its name, its values) of the specification's ``[[kind]]`` (``tool`` or ``frame``)
    named ``name``; ``name`` None or ``default`` (``default_tool``, ``world``): the
    specification's tool, or None (the world). ValueError for a name it does not have."""
    if name is None or name.lower() == default:
        return default, (tuple(spec.tool) if kind == "tool" else None)
    for type_, found, values in spec.named_frames:
        if type_ == kind and found == name.lower():
            return found, tuple(values)
    raise ValueError(f"{spec.file} has no [[{kind}]] of that name (it has: {', '.join(frame_names(spec, kind, default))})")


def frame_names(spec, kind: str, default: str) -> list[str]:
    """The names :func:`named_frame` takes for ``kind``: ``default`` first."""
    return [default, *(n for t, n, _v in spec.named_frames if t == kind)]


@dataclass(frozen=True)
class Where:
    """Where the arm is, as literals: ``joint`` (always), and the pose ``taught`` with the
    tool centre point of the given tool in the given base, or the ``problem`` why there is
    no pose literal (outside the limits, at a singularity, an arm without pose targets)."""

    joint: str
    taught: Taught | None
    problem: str | None


def where(spec, position, tool: tuple | None = None, base: tuple | None = None) -> Where:
    """The literals of axis ``position`` (the main axes first) of ``spec``'s arm, with
    ``tool`` (None: the specification's) in ``base`` (None: the world)."""
    main = len(spec.main_axes)
    joint = joint_literal(position, main)
    try:
        kinematics = Kinematics(spec)
        taught = pose_literal(kinematics if tool is None else kinematics.with_tool(tool), tuple(position[:main]),
                              base)
    except ValueError as exc:  # (PoseError; an arm the kinematics cannot take)
        return Where(joint, None, str(exc))
    return Where(joint, taught, None)
