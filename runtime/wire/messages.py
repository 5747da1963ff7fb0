"""What crosses between ``irl serve``'s two processes (docs/runtime.md, "Process layout"),
declared once and used by both sides: the server (runtime/server/server.py) and the loop
(runtime/loop/robotloop.py). The model is LinuxCNC's ``emcmot_command_t`` and
``emcmot_status_t``: the commands the loop carries out and the snapshot it sends back are
typed values here, each with its msgpack-able form (``to_wire``) and back (``from_wire``);
neither side builds or reads the other's dicts by hand.

The network protocol to clients (runtime/wire/protocol.py, docs/protocol.md) is another
thing: the server answers clients from these values.
"""
from __future__ import annotations

#: How a user gets the wall clock, by command: said when a fieldbus needs it.
WALL_CLOCK_HOW = {"run": "add --realtime", "serve": "drop --sim-clock"}


def io_sources_problem(fieldbus: bool, cell: bool, wall_clock: bool, command: str = "run") -> str | None:
    """The rule of where the robot's inputs come from, once (``irl run``, ``irl serve``
    and the robot's assembly check it): a PLC (``--fieldbus``) and the simulated cell
    (``--cell-scenario``) both drive the inputs, so at most one of them; a PLC lives in
    real time, so only on the wall clock. Returns what is wrong, or None."""
    if fieldbus and cell:
        return "--fieldbus and --cell-scenario both drive the inputs: choose one"
    if fieldbus and not wall_clock:
        return f"--fieldbus needs the wall clock (the PLC lives in real time): {WALL_CLOCK_HOW[command]}"
    return None
