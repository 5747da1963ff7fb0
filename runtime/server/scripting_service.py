"""The scripting interface on the server: a ``call`` request's text parsed here; an
operation of the server itself (``server.reconfigure``: it queues work) carried out here,
everything else sent to the loop, which carries it out against the robot's components
between ticks (runtime/loop/scripting.py)."""
from __future__ import annotations

from runtime.wire.scripting import CallOperation, ServerTarget, check_operation, run_operation


def runs_in_server(command) -> bool:
    """Whether a parsed command is an operation of the server itself (it queues work)."""
    return isinstance(command, CallOperation) and command.component == ServerTarget.name


def call_in_server(command: CallOperation, front: dict, reconfigure) -> dict:
    """Carry out an operation of the server (:func:`runs_in_server`); ``front``: the
    server's values a script may read, ``reconfigure(name)``: its reconfigure request."""
    target = ServerTarget(front, reconfigure=reconfigure)
    check_operation(target, command)
    return run_operation(f"{command.component}.{command.name}", getattr(target, command.name), command.args)
