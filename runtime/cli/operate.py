"""The operator's commands (docs/safety.md, "Operating modes"; docs/protocol.md, ``mode``
and ``jog``): ``irl mode`` (show or switch T1 / AUT), ``irl jog`` (move the arm by hand in
T1: one increment, or continuously for a while), ``irl where`` (the robot's position as
L-IRL literals to paste into a program). Each needs only ``--endpoint``: the robot's
specification comes from the server (``hello``'s ``spec_file``).

While no client holds control these work without taking it (as ``submit`` does); while
one does, only its holder's (``irl control take``) are accepted.
"""
from __future__ import annotations

import json
import time

from runtime.cli import common
from runtime.cli.netcli import Refused, call_op, client_for, guarded

#: Seconds ``irl jog`` waits at most for an increment to end.
STEP_WAIT = 60.0


@guarded
def cmd_mode(args, env) -> int:
    client = client_for(args)
    try:
        if args.mode is None:
            mode = call_op(client, "status")["mode"]
        else:
            mode = call_op(client, "mode", {"mode": args.mode})["mode"]
    finally:
        client.close()
    from runtime.wire.protocol import MODES

    if args.json:
        common.say(env, json.dumps({"mode": mode}))
    else:
        common.say(env, f"operating mode {mode.upper()}: {MODES[mode]}")
    return common.EXIT_OK


def _amount(text: str) -> tuple[int, float | None]:
    """``+1`` / ``-10`` / ``0.5``: (direction, step); ``+`` / ``-``: continuous."""
    text = text.strip()
    if text in ("+", "-"):
        return (1 if text == "+" else -1), None
    try:
        value = float(text)
    except ValueError:
        raise common.UsageError(f"irl jog: {text!r} is not a signed step (e.g. +1, -10, 0.1) nor + or -") from None
    if not value or value != value or abs(value) == float("inf"):
        raise common.UsageError(f"irl jog: the step must be a number other than 0, got {text!r}")
    return (1 if value > 0 else -1), abs(value)


@guarded
def cmd_jog(args, env) -> int:
    direction, step = _amount(args.amount)
    if step is None and args.hold is None:
        raise common.UsageError("irl jog AXIS + or -: a continuous jog needs --hold S (it moves while irl jog holds "
                                "it, S seconds at most; Ctrl-C releases)")
    if step is not None and args.hold is not None:
        raise common.UsageError("irl jog: --hold is for a continuous jog (+ or -), not a step")
    from runtime.wire.protocol import JOG_HEARTBEAT

    request = {"axis": args.axis, "direction": direction, "frame": args.frame}
    if step is not None:
        request["step"] = step
    client = client_for(args)
    try:
        state = _jog(client, request)
        if step is None:
            end = time.monotonic() + args.hold
            try:
                while time.monotonic() < end:
                    time.sleep(min(JOG_HEARTBEAT, max(0.0, end - time.monotonic())))
                    state = call_op(client, "jog", request)
            except KeyboardInterrupt:
                pass
            call_op(client, "jog", {**request, "direction": 0})
        state = _wait_at_rest(client, state)
        status = call_op(client, "status")
        axes = call_op(client, "hello").get("axes")
    finally:
        client.close()
    reason = (state or {}).get("reason")
    if args.json:
        common.say(env, json.dumps({"jog": state, "position": status["position"]}))
    else:
        if reason:
            common.say(env, reason)
        names = axes or [f"A{i + 1}" for i in range(len(status["position"]))]
        common.say(env, "position: " + ", ".join(f"{n} {v:.3f}" for n, v in zip(names, status["position"])))
    return common.EXIT_OK


def _jog(client, request: dict) -> dict:
    """The first jog request: sent again while the jog session before it ends (its brakes
    closing), a new session then starting."""
    from runtime.wire.protocol import JOG_SESSION_ENDING

    deadline = time.monotonic() + 5.0
    while True:
        try:
            return call_op(client, "jog", request)
        except Refused as exc:
            if JOG_SESSION_ENDING not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.1)


def _wait_at_rest(client, state: dict | None) -> dict | None:
    """Poll ``status`` until the jog session has no jog under way (or STEP_WAIT passed):
    the jog's last state (the session's summary's, when it has ended)."""
    deadline = time.monotonic() + STEP_WAIT
    session = (state or {}).get("program")
    while time.monotonic() < deadline:
        status = call_op(client, "status")
        jog = status.get("jog")
        running = status.get("running")
        if running is None or not running.get("kind") == "jog" or running.get("id") != session:
            if session is not None:
                ended = call_op(client, "status", {"program": session})
                return (ended.get("summary") or {}).get("jog") or state
            return state
        if jog is not None:
            state = jog
            if jog.get("active") is None and not jog.get("stopping"):
                return state
        time.sleep(0.05)
    return state


@guarded
def cmd_where(args, env) -> int:
    """The robot's position as a joint literal and a pose literal (the server's
    specification, its tool or a [[tool]] of it, in the world or a [[frame]])."""
    from compiler.configs import format_config
    from compiler.spec import SpecError, load_spec
    from runtime.cli.teach import frame_values
    from runtime.motion.kinematics import configuration_name
    from runtime.motion.teach import where

    client = client_for(args)
    try:
        hello = call_op(client, "hello")
        status = call_op(client, "status")
    finally:
        client.close()
    try:
        spec = load_spec(args.spec or hello["spec_file"])
    except SpecError as exc:
        raise common.UsageError(f"{exc} (the server's specification; give one with --spec)") from None
    if spec.hash != hello.get("spec_hash"):
        raise common.UsageError(f"{spec.file} is not the specification the server drives (its hash differs): give "
                                "the server's with --spec")
    position = list(status["position"])
    tool_name, tool = frame_values(spec, "tool", args.tool, "default_tool")
    base_name, base = frame_values(spec, "frame", args.base, "world")
    found = where(spec, position, tool, base)
    taught = found.taught
    if args.json:
        out = {"joint": found.joint, "position": position, "tool": tool_name, "base": base_name,
               "pose": taught.text if taught else None, "problem": found.problem}
        if taught:
            out.update(config=format_config(taught.config), configuration=configuration_name(taught.config_id))
        common.say(env, json.dumps(out, indent=2))
        return common.EXIT_OK
    common.say(env, found.joint)
    if taught is not None:
        common.say(env, taught.text)
        common.say(env, f"-- tool {tool_name}, base {base_name}; {configuration_name(taught.config_id)}")
    else:
        common.say(env, f"-- no pose literal: {found.problem}")
    return common.EXIT_OK


def add_commands(declare) -> None:
    """Declare ``irl mode``, ``irl jog`` and ``irl where``."""
    from runtime.cli.netcli import add_connection as connection
    from runtime.wire.protocol import JOG_FRAMES, MODES

    if (p := declare("mode", help="show or switch the operating mode: t1 (manual reduced speed, jogging) or aut")) \
            is not None:
        p.add_argument("mode", nargs="?", choices=tuple(MODES), help="the mode to switch to (only with no program "
                                                                     "running and the robot at rest); none: show it")
        p.add_argument("--json", action="store_true", help="the mode as one JSON object")
        connection(p)
        p.set_defaults(run=cmd_mode)
    if (p := declare("jog", help="in T1, move the arm by hand: an axis, or the tool centre point along or about "
                                 "x, y, z")) is not None:
        p.add_argument("axis", metavar="AXIS", help="an axis by name (A1 .. A6), or x, y, z, rx, ry, rz")
        p.add_argument("amount", metavar="STEP", help="the signed step, deg or mm (+1, -10, 0.1); + or - with --hold: "
                                                      "continuously")
        p.add_argument("--frame", choices=JOG_FRAMES, default="world",
                       help="for x .. rz: the frame whose axes they are (default: world; base: the active base, "
                            "tool: the tool's own)")
        p.add_argument("--hold", type=float, metavar="S",
                       help="with + or -: jog continuously for S seconds (heartbeats every 0.1 s; Ctrl-C releases)")
        p.add_argument("--json", action="store_true", help="the jog's end and the position as one JSON object")
        connection(p)
        p.set_defaults(run=cmd_jog)
    if (p := declare("where", help="the robot's position as L-IRL literals (joint and pose) to paste into a "
                                   "program")) is not None:
        p.add_argument("--tool", metavar="NAME", help="the TCP of this [[tool]] (default: the specification's tool)")
        p.add_argument("--base", metavar="NAME", help="the pose in this [[frame]] (default: the world)")
        p.add_argument("--spec", metavar="FILE.spc", help="the robot's specification (default: the server's file)")
        p.add_argument("--json", action="store_true", help="the literals as one JSON object")
        connection(p)
        p.set_defaults(run=cmd_where)
