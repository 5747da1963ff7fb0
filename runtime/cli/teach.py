"""``irl pose``: the pose literal, with its full configuration, that reaches given joint
values (typed, or the robot's current ones from a server): how a point is taught.
:mod:`runtime.motion.teach` does the work (``irl where`` and the pendant use it too).
"""
from __future__ import annotations

import json
import os

from compiler.configs import TURN_AXES, format_config, words_text

from runtime.cli import common
from runtime.motion.kinematics import Kinematics, configuration_name
from runtime.motion.teach import PoseError, named_frame, pose_literal


# ---- the command ------------------------------------------------------------------------------

def frame_values(spec, kind: str, name: str | None, default: str) -> tuple[str, tuple | None]:
    """(its name, its values) of the specification's ``[[kind]]`` named ``name`` (the
    default: None, or the specification's tool); a name it does not have is a usage error."""
    try:
        return named_frame(spec, kind, name, default)
    except ValueError as exc:
        raise common.UsageError(f"--{'tool' if kind == 'tool' else 'base'} {name}: {exc}") from None


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
