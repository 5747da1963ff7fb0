"""The scripting interface in the loop: parsed text commands (``runtime.wire.scripting``)
carried out against the robot's components, as the paper's task browser does.

Only what a target declares is reachable: its ``PROPERTIES`` (declared in
:mod:`compiler.params`; their values are the robot's one settings object,
:mod:`runtime.settings`, read and written through the component), ``READ_ONLY`` properties, and whitelisted ``OPERATIONS``. The
server parses a command; an operation of the server itself (``server.reconfigure``) runs
there (runtime/server/scripting_service.py), everything else here, in the real-time loop
between ticks (runtime/loop/robotloop.py), against the loop's components. What the network
may change is limited (docs/safety.md):

* a property is written only if its declaration says ``live``; a safety-relevant
  parameter (or any other that changes by configuration) is refused: it changes only
  with a whole configuration applied in Robot Reconfiguration (``irl reconfigure NAME``);
  a value outside the declared range is refused with the name, the value and the range;
* a component's operations (its lifecycle, the brakes, the servo's hold) run only while
  no program runs (they could move the robot or lose data); ``robot.release_brakes`` never
  (Start Robot alone releases the brakes); the supervisor's mode is read-only.
"""
from __future__ import annotations

from compiler.params import ParamError

from runtime.loop.component import DataPort
from runtime.wire.protocol import ProtocolError
from runtime.wire.scripting import (
    HELP_TEXT, CallOperation, Components, GetProperty, Help, ServerTarget, SetProperty, check_operation,
    format_value, parse_call, run_operation,
)


class FsmTarget:
    """The supervisor's state machine as a scripting target (``fsm``)."""

    name = "fsm"
    PROPERTIES: dict = {}
    READ_ONLY = {"state": "the current state (with the sub-machine's)",
                 "mode": "'automatic' (guards fire); fixed while the supervisor drives the robot"}
    OPERATIONS = ("request_state", "post")

    def __init__(self, loop):
        self.loop = loop

    @property
    def _fsm(self):
        return self.loop.system.supervisor.fsm

    @property
    def state(self) -> str:
        return self._fsm.path() if self.loop.job is not None else "Idle"

    @property
    def mode(self) -> str:
        return self._fsm.mode

    @property
    def lifecycle(self):
        return None

    def request_state(self, name: str) -> bool:
        """Ask for a transition to ``name`` at the next step (if one leads there)."""
        if self.loop.job is None:
            raise ValueError("no program is running: the supervisor is idle")
        return self._fsm.request_state(name)

    def post(self, event: str) -> None:
        """Post an event for the next step."""
        self._fsm.post(event)


#: Operations of the components that the network may never call (the others: only while
#: no program runs).
NEVER = {("robot", "release_brakes"): "the brakes are released only by Start Robot, when a program begins"}


def _operation_refused(job: int | None, component: str, name: str, target) -> str | None:
    """Why the operation may not run now (None: it may). Runs in the loop."""
    if (component, name) in NEVER:
        return NEVER[(component, name)]
    if getattr(target, "lifecycle", None) is not None and job is not None:
        return (f"program {job} is running: a component's operations could move the robot or "
                "lose data (call it when the robot is idle; to stop the robot: irl abort or irl estop)")
    return None


def loop_targets(loop) -> dict:
    """What a script reaches in the loop (runtime.loop.robotloop.RobotLoop). The digital I/O
    (``io``) is the io component itself (runtime.loop.components.io: read-only ``inputs`` and
    ``outputs``, ``in[n]`` and ``out[n]``; ``in[n] = ...`` forces an input, on the simulated
    robot only)."""
    s = loop.system
    return {"robot": s.robot, "servo": s.servo, "initialization": s.init, "trajectory": s.trajectory,
            "report": s.report, "fsm": FsmTarget(loop), "io": s.io, "server": ServerTarget(loop.front)}


def call(table: dict, job: int | None, text: str):
    """The result of a ``call`` request (a dict), or a callable to run between ticks;
    ``table``: the targets (``loop_targets``), ``job``: the running program's id."""
    command = parse_call(text)
    if isinstance(command, Components):
        lines = [f"{name:15s} {_lifecycle(t)}" for name, t in table.items()]
        return {"output": "\n".join(lines), "value": list(table)}
    if isinstance(command, Help):
        if command.component is None:
            return {"output": HELP_TEXT.rstrip() + "\ncomponents: " + ", ".join(table), "value": None}
        return {"output": _describe(command.component, _target(table, command.component)), "value": None}
    target = _target(table, command.component)
    where = f"{command.component}.{command.name}"
    if isinstance(command, (GetProperty, SetProperty)) and command.index is not None:
        return _element(target, command, f"{where}[{command.index}]")
    if isinstance(command, GetProperty):
        if command.name not in _properties(target):
            raise ProtocolError("script_error", f"{command.component} has no property {command.name!r} "
                                                f"({_names(target)})")
        value = _plain(_value(target, command.name))
        return {"output": f"{where} = {format_value(value)}", "value": value}
    if isinstance(command, SetProperty):
        if command.name not in target.PROPERTIES:
            read_only = command.name in getattr(target, "READ_ONLY", {})
            raise ProtocolError("script_error", f"{where} is read-only" if read_only else
                                f"{command.component} has no property {command.name!r} ({_names(target)})")
        param = target.PROPERTIES[command.name]
        if param.change != "live":
            what = f"{where} is safety-relevant: it" if param.safety else where
            raise ProtocolError("refused", f"{what} changes only with a whole configuration applied between "
                                           "programs (irl reconfigure NAME; docs/safety.md), never by a single "
                                           "write over the network")
        try:
            value = param.check(command.value)
        except ParamError as exc:
            raise ProtocolError("bad_request", f"{where}: {exc.reason}") from None

        def set_property():
            target.set_property(command.name, value)
            shown = _plain(target.get_property(command.name))
            return {"output": f"{where} = {format_value(shown)}", "value": shown}
        return set_property
    assert isinstance(command, CallOperation)
    check_operation(target, command)

    def operation():
        refused = _operation_refused(job, command.component, command.name, target)
        if refused is not None:
            raise ProtocolError("refused", f"{where}: {refused}")
        return run_operation(where, getattr(target, command.name), command.args, _plain)
    return operation() if getattr(target, "IMMEDIATE", False) else operation


def _element(target, command, where: str):
    """``io.in[3]`` (read now) or ``io.in[3] = true`` (a callable for the loop)."""
    indexed = getattr(target, "INDEXED", {})
    if command.name not in indexed:
        raise ProtocolError("script_error", f"{command.component}.{command.name} has no elements"
                                            + (f" (indexed: {', '.join(indexed)})" if indexed else ""))
    try:
        if isinstance(command, GetProperty):
            value = target.element(command.name, command.index)
            return {"output": f"{where} = {format_value(value)}", "value": value}
    except IndexError as exc:
        raise ProtocolError("bad_request", str(exc)) from None
    if not indexed[command.name][1]:
        raise ProtocolError("refused", f"{where} is read-only (the program sets the outputs)")

    def force():
        try:
            target.force(command.index, command.value)
        except (IndexError, TypeError) as exc:
            raise ProtocolError("bad_request", str(exc)) from None
        except PermissionError as exc:
            raise ProtocolError("refused", f"{where}: {exc}") from None
        return {"output": f"{where} = {format_value(command.value)}", "value": command.value}
    return force


def _target(table: dict, name: str):
    if name not in table:
        raise ProtocolError("script_error", f"no component {name!r} (components: {', '.join(table)})")
    return table[name]


def _value(target, name: str):
    """A property's value: a setting from the robot's settings (runtime.settings, the
    component's section), a read-only one from the target itself."""
    return target.get_property(name) if name in target.PROPERTIES else getattr(target, name)


def _properties(target) -> dict:
    return {**target.PROPERTIES, **getattr(target, "READ_ONLY", {})}


def _names(target) -> str:
    props = ", ".join(_properties(target)) or "none"
    return f"properties: {props}; operations: {', '.join(target.OPERATIONS)}"


def _lifecycle(target) -> str:
    state = getattr(target, "lifecycle", None)
    return state.value if state is not None else "-"


def _describe(name: str, target) -> str:
    lines = [f"{name} ({_lifecycle(target)})", "  properties:"]
    for prop, param in target.PROPERTIES.items():
        how = "writable" if param.change == "live" else ("safety-relevant, by configuration" if param.safety
                                                         else "by configuration")
        lines.append(f"    {prop} = {format_value(_plain(target.get_property(prop)))}  ({param.allowed()}; {how}) "
                     f"{param.doc}")
    for prop, doc in getattr(target, "READ_ONLY", {}).items():
        lines.append(f"    {prop} = {format_value(_plain(getattr(target, prop)))}  (read-only) {doc}")
    for prop, (what, writable) in getattr(target, "INDEXED", {}).items():
        lines.append(f"    {prop}[n]  ({'writable in simulation' if writable else 'read-only'}) {what}")
    lines.append("  operations: " + ", ".join(f"{op}()" for op in target.OPERATIONS))
    return "\n".join(lines)


def _plain(value):
    """What msgpack can carry: tuples become lists, a data port its value, other objects
    their text."""
    if isinstance(value, (bool, int, float, str)) or value is None:
        return value
    if isinstance(value, DataPort):
        return _plain(value.read())
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    return str(value)
