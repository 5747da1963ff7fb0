"""``irl pose``: the pose literal, with its full configuration, that reaches given joint
values (typed, or the robot's current ones from a server): how a point is taught.

:func:`pose_literal` does the work: the tool centre point of the joints by the forward
kinematics (with the chosen tool, in the chosen base), the configuration they are in
(:func:`compiler.configs.config_of`), and the numbers rounded to 0.001 mm and deg, or
finer where that is what it takes for the literal to resolve to the same configuration
and turns (checked by solving it again, as a ``move ptp`` does). Not real-time.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass

from compiler.configs import TURN_AXES, Config, config_of, format_config, words_text
from compiler.frames import pose_of
from compiler.semantics import compose, inverse
from compiler.values import Pose, Position, Rpy, format_number

from runtime.cli import common
from runtime.motion.kinematics import Kinematics, KinematicsError, configuration_name

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


# ---- the command ------------------------------------------------------------------------------

def frame_values(spec, kind: str, name: str | None, default: str) -> tuple[str, tuple | None]:
    """(its name, its values) of the specification's ``[[kind]]`` named ``name`` (the
    default: None, or the specification's tool)."""
    if name is None or name.lower() == default:
        return default, (tuple(spec.tool) if kind == "tool" else None)
    names = [n for t, n, _v in spec.named_frames if t == kind]
    for type_, found, values in spec.named_frames:
        if type_ == kind and found == name.lower():
            return found, tuple(values)
    raise common.UsageError(f"--{'tool' if kind == 'tool' else 'base'} {name}: {spec.file} has no [[{kind}]] of that "
                            f"name (it has: {', '.join([default, *names])})")


def _server_joints(args, spec) -> tuple:
    """The robot's current main axes from a server's status (its specification checked)."""
    from runtime.cli.netcli import current_position

    hash_, position = current_position(args)
    if hash_ != spec.hash:
        raise PoseError(f"the server at {args.endpoint} drives another specification ({hash_[:12]}) than "
                        f"{spec.file} ({spec.hash[:12]}): give its specification with --spec")
    if len(position) < 6:
        raise PoseError(f"the server at {args.endpoint} reports no position of the six main axes")
    return tuple(position[:6])


def cmd_pose(args, env) -> int:
    from compiler.spec import SpecError, load_spec

    try:
        spec = load_spec(args.spec)
    except SpecError as exc:
        raise common.UsageError(str(exc)) from None
    if args.joints and len(args.joints) != 6:
        raise common.UsageError(f"expected the six main axes' values A1 .. A6, got {len(args.joints)}")
    if args.joints and args.endpoint:
        raise common.UsageError("give the joint values or --endpoint, not both")
    args.endpoint = args.endpoint or (None if args.joints else os.environ.get("IRL_ENDPOINT"))
    if not args.joints and not args.endpoint:
        raise common.UsageError("give the six joint values A1 .. A6, or --endpoint E (or $IRL_ENDPOINT) to take "
                                "the robot's current ones")
    tool_name, tool = frame_values(spec, "tool", args.tool, "default_tool")
    base_name, base = frame_values(spec, "frame", args.base, "world")
    try:
        kinematics = Kinematics(spec).with_tool(tool)
    except ValueError as exc:
        common.warn(env, f"irl pose: {spec.file}: this robot has no pose targets: {exc}")
        return common.EXIT_INVALID
    try:
        joints = tuple(args.joints) if args.joints else _server_joints(args, spec)
        taught = pose_literal(kinematics, joints, base, exact=args.exact)
    except ValueError as exc:  # (PoseError; a server that refused)
        common.warn(env, f"irl pose: {exc}")
        return common.EXIT_INVALID
    if args.json:
        p, o, c = taught.pose.position, taught.pose.orientation, taught.config
        common.say(env, json.dumps({
            "pose": taught.text, "position": [p.x, p.y, p.z], "rpy": [o.roll, o.pitch, o.yaw],
            "config": format_config(c), "configuration": configuration_name(taught.config_id),
            "config_id": taught.config_id, "turns": list(c.turns), "joints": list(taught.joints),
            "tool": tool_name, "base": base_name}, indent=2))
    else:
        common.say(env, taught.text)
        names = [kinematics.names[i] for i in TURN_AXES]
        common.say(env, f"-- {words_text(taught.config)}; {', '.join(names)} in turns "
                        f"{', '.join(map(str, taught.config.turns))}; tool {tool_name}, base {base_name}")
    return common.EXIT_OK


def add_arguments(p) -> None:
    """``irl pose``'s arguments."""
    p.add_argument("joints", nargs="*", type=float, metavar="A", help="the six main axes' values (deg), A1 .. A6")
    p.add_argument("--spec", required=True, metavar="FILE.spc", help="the robot's specification")
    p.add_argument("--tool", metavar="NAME", help="the TCP of this [[tool]] of the specification (default: its "
                                                  "[kinematics] tool, default_tool)")
    p.add_argument("--base", metavar="NAME", help="the pose in this [[frame]] of the specification (default: the "
                                                  "world)")
    p.add_argument("--endpoint", metavar="E", help="take the robot's current joints from the server at E (default "
                                                   "without joint values: $IRL_ENDPOINT)")
    p.add_argument("--keys", metavar="DIR", help="with --endpoint: CURVE keys (made by 'irl keys DIR')")
    from runtime.cli.netcli import REPLY_TIMEOUT

    p.add_argument("--timeout", type=float, default=REPLY_TIMEOUT, metavar="S",
                   help="with --endpoint: seconds to wait for a reply")
    p.add_argument("--exact", action="store_true", help="every digit of the numbers (default: to 0.001 mm and "
                                                        "deg, finer only where the configuration needs it)")
    p.add_argument("--json", action="store_true", help="the pose, its configuration and the joints as one JSON "
                                                       "object")
    p.set_defaults(run=cmd_pose)
