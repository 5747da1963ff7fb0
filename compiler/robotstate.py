"""The robot's own state, the program's clocks and output pulses (docs/language.md, "The
robot's own state and clocks"): built-in functions that read where the robot is, how fast
its tool moves and whether the last ``wait for`` timed out, built-in procedures and a
function that measure time, and a procedure that pulses an output (RAPID's PulseDO,
KRL's PULSE), as RAPID's CJointT, CRobT, ClkStart/ClkStop/ClkReset/ClkRead and the
``\\TimeFlag`` of WaitUntil, and KRL's $AXIS_ACT, $POS_ACT, $VEL_ACT and $TIMER do.

One declaration each (:data:`ROUTINES`): the name, the parameters' and the result's
types (no result: a procedure, called with ``call``), the instruction it compiles to
(compiler.objcode, which says whether it waits for the robot) and what it does. The
checker, the code generator and the manual's table read it. The names are not reserved:
a program's own routine of the same name is called instead (so every program that checked
before still means what it meant).
"""
from __future__ import annotations

from dataclasses import dataclass

from .recovery import ERRORS

__all__ = ["CLOCKS", "ERROR_ROUTINES", "FUNCTIONS", "PROCEDURES", "ROUTINES", "StateRoutine"]

#: The clocks a program has, numbered 1..CLOCKS.
CLOCKS = 8
#: The most digital signals a group reads or writes as one integer (group_in, group_out).
GROUP_BITS = 32


def group_problem(first: object, bits: object, count: int, what: str) -> str | None:
    """Why digital ``what``s (``"input"``, ``"output"``) ``first`` .. ``first + bits - 1``
    are not a group the robot has (``count`` of them), or None. Never raises."""
    if not (type(bits) is int and 1 <= bits <= GROUP_BITS):
        return f"a group of {bits!r} {what}s: a group has 1..{GROUP_BITS}"
    if not (type(first) is int and 1 <= first and first + bits - 1 <= count):
        last = first + bits - 1 if type(first) is int else "?"
        return f"{what}s {first}..{last} do not exist: the robot has {what}s 1..{count}"
    return None


def group_value_problem(value: object, bits: int) -> str | None:
    """Why ``value`` cannot be written to a group of ``bits`` signals, or None."""
    if not (type(value) is int and 0 <= value < 1 << bits):
        return f"{value!r} does not fit a group of {bits} outputs: expected 0..{(1 << bits) - 1}"
    return None


@dataclass(frozen=True)
class StateRoutine:
    """A built-in routine of the robot's state: ``params`` the parameters' types,
    ``result`` the result's ("" for a procedure), ``instruction`` the one it compiles to."""

    name: str
    params: tuple[str, ...]
    result: str
    instruction: str
    doc: str
    #: What the first argument numbers (its constant checked against the range): "clock"
    #: (1..CLOCKS), "output" (the specification's outputs), "analog input" (its analog
    #: inputs), "input group" / "output group" (the first two arguments: the first signal
    #: and how many, group_problem), or "" (nothing).
    number: str = ""


ROUTINES: dict[str, StateRoutine] = {r.name: r for r in (
    StateRoutine("current_joint", (), "joint", "ROBOT_JOINT",
                 "where the robot stands: every axis, once every move before it has ended"),
    StateRoutine("current_pose", (), "pose", "ROBOT_POSE",
                 "the tool centre point of the active tool in the active base, with the arm's configuration "
                 "(turns included), once every move before it has ended"),
    StateRoutine("tcp_speed", (), "real", "TCP_SPEED",
                 "the speed of the tool centre point now (mm/s; 0 at rest): it does not wait for the robot, so "
                 "it is for an interrupt's handler or a path trigger's moment"),
    StateRoutine("timed_out", (), "bool", "TIMED_OUT",
                 "whether the last 'wait for ... timeout' ended by its time-out (false before any)"),
    StateRoutine("clock_start", ("integer",), "", "CLOCK_START",
                 "clock N runs from now on (where the robot is: once every move before it has ended)", "clock"),
    StateRoutine("clock_stop", ("integer",), "", "CLOCK_STOP", "clock N stops; it keeps its time", "clock"),
    StateRoutine("clock_reset", ("integer",), "", "CLOCK_RESET", "clock N reads 0 (and runs on if it ran)", "clock"),
    StateRoutine("clock_read", ("integer",), "real", "CLOCK_READ",
                 "the seconds clock N has run, to the control cycle", "clock"),
    StateRoutine("analog_in", ("integer",), "real", "AIN_GET",
                 "what analog input N reads now (in its unit, within its range: the specification's "
                 "[[analog_input]] N), where the robot is", "analog input"),
    StateRoutine("search_pose", (), "pose", "SEARCH_POSE",
                 "where the last search move's input became true (move lin ... search := N): the tool centre point "
                 "of the move's tool in its base, with the arm's configuration; the program's value error before "
                 "any search has found its input"),
    StateRoutine("analog_out", ("integer", "real"), "", "AOUT_SET",
                 "analog output N set to VALUE (in its unit, within its range: the specification's [[analog_output]] "
                 "N), where the robot is", "analog output"),
    StateRoutine("analog_out_value", ("integer",), "real", "AOUT_GET",
                 "what analog output N was last set to (in its unit), where the robot is", "analog output"),
    StateRoutine("group_in", ("integer", "integer"), "integer", "GROUP_IN",
                 "digital inputs FIRST .. FIRST + BITS - 1 read as one unsigned integer, input FIRST its lowest bit "
                 f"(BITS 1..{GROUP_BITS}), where the robot is", "input group"),
    StateRoutine("group_out", ("integer", "integer", "integer"), "", "GROUP_OUT",
                 "digital outputs FIRST .. FIRST + BITS - 1 set to VALUE's bits, output FIRST its lowest bit, all in "
                 "the same 1 ms tick (VALUE 0 .. 2^BITS - 1), where the robot is", "output group"),
    StateRoutine("pulse_out", ("integer", "real"), "", "PULSE_OUT",
                 "digital output N on now (where the robot is), off again SECONDS later while the program goes on; "
                 "a pulse of an output already pulsing starts again", "output"),
)}
#: What an error handler reads of the error it took (compiler.recovery; RAPID's ERRNO and
#: ERRSTR): built-in functions as those above, whose names are not reserved either.
ERROR_ROUTINES: dict[str, StateRoutine] = {r.name: r for r in (
    StateRoutine("error_number", (), "integer", "ERROR_NUMBER",
                 "the number of the error the handler took (compiler.recovery.ERRORS; a program's own: its "
                 "number); 0 before any"),
    StateRoutine("error_name", (), "string", "ERROR_NAME",
                 "the name of the error the handler took: "
                 + ", ".join(f'\"{kind.name}\"' for kind in ERRORS[:-1]) + f' or \"{ERRORS[-1].name}\"; '
                 '\"\" before any'),
    StateRoutine("error_message", (), "string", "ERROR_MESSAGE",
                 "the message of the error the handler took, as the operator's log would say it"),
)}
FUNCTIONS = {name: r for name, r in (ROUTINES | ERROR_ROUTINES).items() if r.result}
PROCEDURES = {name: r for name, r in ROUTINES.items() if not r.result}
