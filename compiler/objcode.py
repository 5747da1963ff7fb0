"""The object-code contract between the offline compiler and the runtime.

One instruction table (:data:`INSTRUCTIONS`) is the source of truth: the encoder, the
decoder, the verifier, the disassembler, the VM's dispatch and the generated reference
in ``docs/objcode.md`` all derive from it. A :class:`Program` is plain data; on disk and
on the wire it is ``MAGIC + version (u16, big-endian) + CRC-32 of the body (u32) +
body``, the body being msgpack.

This module imports nothing from Lark, so the runtime loads object code without the
compiler's parser.
"""
from __future__ import annotations

import re
import struct
import zlib
from dataclasses import dataclass
from functools import cached_property
from typing import Callable

from .clauses import BY_NAME as _CLAUSES_BY_NAME
from .clauses import MOTIONS as _MOTIONS
from .clauses import NAMES as _CLAUSE_NAMES
from .configs import TURN_AXES as _TURN_AXES
from .configs import TURNS_FLAG as _TURNS_FLAG
from .configs import operand_problem as _config_operand_problem
from .records import MAX_FIELDS as _MAX_FIELDS
from . import zones as _zones
from .semantics import MAX_STRING_LENGTH as _MAX_STRING_LENGTH
from .semantics import STRING_BUILTINS as _STRING_BUILTINS
from .values import Record, from_plain, to_plain

MAGIC = b"IRLO"
FORMAT_VERSION = 1
_HEADER = struct.Struct(">4sHI")

#: Largest object file the decoder accepts (a 10,000-line program is well under 1 MiB).
MAX_SIZE = 64 * 1024 * 1024
#: Largest "count" operand (array length, values printed, arguments).
MAX_COUNT = 100_000
#: Largest array value, in elements (all levels of an array of arrays together): the
#: compiler refuses a larger declaration, the VM a larger array built by forged code.
MAX_ARRAY_ELEMENTS = 100_000
#: Longest string value, in characters (declared with the values' semantics): a longer
#: constant is refused by the decoder, a longer string built at run time (``+``) stops
#: the program at its line.
MAX_STRING_LENGTH = _MAX_STRING_LENGTH


class ObjectCodeError(Exception):
    """Object code that is malformed or does not fit the robot; says what and where."""

    def __init__(self, message: str, offset: int | None = None):
        self.message = message
        self.offset = offset
        super().__init__(message if offset is None else f"at offset {offset}: {message}")


# ---- the tables ---------------------------------------------------------------------

#: Operand kinds: what an operand's value means and how it is checked.
OPERAND_KINDS = {
    "const": "index into the constant pool",
    "global": "global variable slot",
    "local": "local variable slot of the current procedure",
    "target": "code offset to jump to",
    "proc": "index into the procedure table",
    "count": "a non-negative count (at most 100,000)",
    "int": "a signed integer",
    "builtin": "built-in function number (see below)",
    "field": "field number: 0 x, 1 y, 2 z",
    "clauses": "bit mask of the move's clauses (see below)",
    "flag": "0 or 1",
    "name": "index into the constant pool of a string (a name)",
    "interrupt": "index into the interrupt table",
    "place": "where a trigger is counted from: 0 after start, 1 before end, 2 after end (compiler.triggers)",
    "unit": "a trigger's unit: 0 ms, 1 mm (compiler.triggers)",
    "config": "the words of config(...) (compiler.configs): two bits per group, the shoulder's lowest (0 free, "
              "1 front, 2 back; bits 2-3: 0 free, 1 elbow_up, 2 elbow_down; bits 4-5: 0 free, 1 noflip, 2 flip); "
              "bit 6: the turns of A1, A4, A6 follow on the stack; two bits of 3 are refused",
    "record": "index into the record table (compiler.records)",
    "member": f"a field's number in the record on the stack, from 0 in declaration order (at most {_MAX_FIELDS - 1})",
}

#: Built-in functions: name -> number of arguments. Angles in degrees.
BUILTINS: dict[str, int] = {
    "sin": 1, "cos": 1, "tan": 1, "asin": 1, "acos": 1, "atan2": 2, "sqrt": 1,
    "abs": 1, "min": 2, "max": 2, "round": 1, "trunc": 1,
    "inv": 1, "distance": 2, "tool_offset": 2,  # (on poses and positions: compiler.semantics.GEOMETRIC_BUILTINS)
    **{name: len(params) for name, (params, _result) in _STRING_BUILTINS.items()},  # (on strings: the same table)
}
BUILTIN_NAMES = tuple(BUILTINS)

FIELDS = ("x", "y", "z")

#: Move clauses, in bit order; the values of the present ones are pushed in this order
#: (declared, with their motions and ranges, in compiler.clauses).
CLAUSES = _CLAUSE_NAMES

MOTION_KINDS = _MOTIONS


def clause_names(mask: int) -> list[str]:
    return [name for bit, name in enumerate(CLAUSES) if mask & (1 << bit)]


def _bits(mask: int) -> int:
    return bin(mask).count("1")


@dataclass(frozen=True)
class InstrDef:
    """One instruction: its name, opcode, operands (name, kind), stack effect and doc.

    ``pops`` is how many values the instruction takes from the stack, either a number or
    a function of (operands, program); ``effect`` says the same for people.
    """

    name: str
    code: int
    operands: tuple[tuple[str, str], ...]
    pops: int | Callable
    pushes: int
    doc: str
    effect: str = ""
    flow: str = "next"  # next | jump | branch | wait | call | return | stop
    #: The types of the values it pops, deepest first (:data:`VALUE_TYPES`), one pattern
    #: per value, or for a count that depends on the operands one pattern that each of them
    #: must fit; and the type of the value it pushes (or a rule: :data:`TYPE_RULES`). The
    #: verifier reads both.
    takes: tuple[str, ...] = ()
    gives: str = ""
    #: A barrier to the motion look-ahead: the instruction acts where the robot is (I/O,
    #: ``print``, ``wait for``, ``pause``, switching an interrupt), so the VM executes it
    #: only when every move handed over has ended (in an interrupt's handler at once: it acts
    #: beside the motion); until then the program waits before it, its stack untouched.
    barrier: bool = False

    def pop_count(self, operands: tuple, program: "Program") -> int:
        return self.pops if isinstance(self.pops, int) else self.pops(operands, program)


def _call_pops(operands, program):
    return program.procedures[operands[0]].params


def _config_pops(operands, program):
    return len(_TURN_AXES) if operands[0] & _TURNS_FLAG else 0


_DEFS = [
    # name, operands, pops, pushes, doc, effect, flow, barrier. Append only: an
    # instruction's code is its place here, and object files already written keep theirs.
    ("NOP", (), 0, 0, "Do nothing.", "", "next", False),
    ("CONST", (("k", "const"),), 0, 1, "Push constant k.", "-> value", "next", False),
    ("LOAD_GLOBAL", (("g", "global"),), 0, 1, "Push global variable g.", "-> value", "next", False),
    ("STORE_GLOBAL", (("g", "global"),), 1, 0, "Pop a value into global variable g.", "value ->", "next", False),
    ("LOAD_LOCAL", (("l", "local"),), 0, 1, "Push local variable (or parameter) l.", "-> value", "next", False),
    ("STORE_LOCAL", (("l", "local"),), 1, 0, "Pop a value into local variable l.", "value ->", "next", False),
    ("COPY", (), 1, 1, "Replace an array on top of the stack by a copy of it (arrays are values).",
     "array -> array'", "next", False),
    ("TO_REAL", (), 1, 1, "Convert the integer on top of the stack to real.", "int -> real", "next", False),
    ("NEG", (), 1, 1, "Negate a number.", "a -> -a", "next", False),
    ("NOT", (), 1, 1, "Logical not.", "a -> not a", "next", False),
    ("ADD", (), 2, 1, "a + b (numbers, or two strings joined).", "a b -> a+b", "next", False),
    ("SUB", (), 2, 1, "a - b.", "a b -> a-b", "next", False),
    ("MUL", (), 2, 1, "a * b.", "a b -> a*b", "next", False),
    ("DIV", (), 2, 1, "a / b, real division; division by zero is a run-time error.", "a b -> a/b", "next", False),
    ("IDIV", (), 2, 1, "a div b, integer division truncating toward zero.", "a b -> a div b", "next", False),
    ("MOD", (), 2, 1, "a mod b, the remainder of div (sign of a).", "a b -> a mod b", "next", False),
    ("EQ", (), 2, 1, "a = b.", "a b -> bool", "next", False),
    ("NE", (), 2, 1, "a <> b.", "a b -> bool", "next", False),
    ("LT", (), 2, 1, "a < b.", "a b -> bool", "next", False),
    ("LE", (), 2, 1, "a <= b.", "a b -> bool", "next", False),
    ("GT", (), 2, 1, "a > b.", "a b -> bool", "next", False),
    ("GE", (), 2, 1, "a >= b.", "a b -> bool", "next", False),
    ("AND", (), 2, 1, "a and b (both are evaluated).", "a b -> bool", "next", False),
    ("OR", (), 2, 1, "a or b (both are evaluated).", "a b -> bool", "next", False),
    ("CALL_BUILTIN", (("fn", "builtin"), ("argc", "count")), lambda ops, p: ops[1], 1,
     "Call built-in function fn with argc arguments.", "args... -> result", "next", False),
    ("MAKE_JOINT", (("main", "count"), ("add", "count")), lambda ops, p: ops[0] + ops[1], 1,
     "Build a joint value from main + add axis values.", "a1..an e1..em -> joint", "next", False),
    ("MAKE_POS", (), 3, 1, "Build pos(x, y, z).", "x y z -> position", "next", False),
    ("MAKE_RPY", (), 3, 1, "Build rpy(roll, pitch, yaw).", "r p y -> orientation", "next", False),
    ("MAKE_QUAT", (), 4, 1, "Build quat(w, x, y, z), normalised; a zero quaternion is a run-time error.",
     "w x y z -> orientation", "next", False),
    ("MAKE_POSE", (), 2, 1, "Build pose(position, orientation).", "position orientation -> pose", "next", False),
    ("MAKE_ARRAY", (("n", "count"),), 1, 1, "Build an array of n copies of the value on top.",
     "element -> array", "next", False),
    ("GET_ITEM", (("low", "int"),), 2, 1, "Array element; index out of low..high is a run-time error.",
     "array index -> element", "next", False),
    ("SET_ITEM", (("low", "int"),), 3, 0, "Store into an array element (the array is changed in place).",
     "array index value ->", "next", False),
    ("GET_AXIS", (), 2, 1, "Axis value of a joint, axes numbered from 1.", "joint axis -> real", "next", False),
    ("SET_AXIS", (), 3, 1, "A joint with one axis value replaced.", "joint axis value -> joint", "next", False),
    ("GET_FIELD", (("f", "field"),), 1, 1, "Field x, y or z of a position or pose (mm).",
     "position|pose -> real", "next", False),
    ("JUMP", (("target", "target"),), 0, 0, "Continue at target.", "", "jump", False),
    ("JUMP_IF_FALSE", (("target", "target"),), 1, 0, "Pop a bool; continue at target when false.",
     "bool ->", "branch", False),
    ("CALL", (("p", "proc"),), _call_pops, 0,
     "Call procedure p; its parameters are popped into its first local slots.", "args... ->", "call", False),
    ("RET", (), 0, 0, "Return from the current procedure.", "", "return", False),
    ("IN_GET", (), 1, 1, "Read digital input n (bool).", "n -> bool", "next", True),
    ("OUT_SET", (), 2, 0, "Set digital output n.", "n value ->", "next", True),
    ("MOVE_PTP", (("clauses", "clauses"),), lambda ops, p: 1 + _bits(ops[0]), 0,
     "Point-to-point move to a joint or pose target, with the clauses in the mask.",
     "target clause-values... ->", "wait", False),
    ("MOVE_LIN", (("clauses", "clauses"),), lambda ops, p: 1 + _bits(ops[0]), 0,
     "Straight-line move of the tool centre point to a pose.", "pose clause-values... ->", "wait", False),
    ("MOVE_CIRC", (("clauses", "clauses"),), lambda ops, p: 2 + _bits(ops[0]), 0,
     "Circular move through a via pose to an end pose.", "via end clause-values... ->", "wait", False),
    ("DWELL", (), 1, 0, "Stand still for the given seconds.", "seconds ->", "wait", False),
    ("WAIT_BEGIN", (("timeout", "flag"),), lambda ops, p: ops[0], 0,
     "Start a 'wait for'; with timeout = 1, pop the time-out in seconds.", "[seconds] ->", "next", True),
    ("WAIT_TEST", (("target", "target"),), 1, 0,
     "Pop the condition; when false and not timed out, yield and continue at target next cycle.",
     "bool ->", "branch", False),
    ("PRINT", (("n", "count"),), lambda ops, p: ops[0], 0, "Send n values to the operator log.",
     "values... ->", "next", True),
    ("PAUSE", (), 0, 0, "Hold until the operator resumes.", "", "wait", True),
    ("HALT", (), 0, 0, "End the program here.", "", "stop", False),
    ("END", (), 0, 0, "The end of the main program.", "", "stop", False),
    ("CALL_FUNC", (("f", "proc"),), _call_pops, 1,
     "Call function f (a routine with a result); its parameters are popped into its first local slots, and its "
     "result is on the stack when it returns.", "args... -> result", "call", False),
    ("RET_VALUE", (), 1, 0, "Return from the current function with the value on top of the stack (left there for "
                            "the caller).", "result ->", "return", False),
    ("USE_BASE", (("name", "name"),), 1, 0,
     "Make the pose on top of the stack the active base (the frame later pose targets are in), called name "
     "(compiler.frames).", "pose ->", "next", False),
    ("USE_TOOL", (("name", "name"),), 1, 0,
     "Make the pose on top of the stack the active tool (the TCP, in the flange frame, that later targets put in "
     "place), called name (compiler.frames).", "pose ->", "next", False),
    ("INT_ENABLE", (("i", "interrupt"),), 0, 0,
     "Switch interrupt i on: its condition is checked every period from now on (compiler.interrupts).", "",
     "next", True),
    ("INT_DISABLE", (("i", "interrupt"),), 0, 0, "Switch interrupt i off.", "", "next", True),
    ("TRIGGER_OUT", (("place", "place"), ("unit", "unit")), 3, 0,
     "A path trigger of the next move: set digital output n to value when the robot is amount (unit) from "
     "place (compiler.triggers).", "amount n value ->", "next", False),
    ("TRIGGER_SET", (("place", "place"), ("unit", "unit"), ("g", "global")), 2, 0,
     "A path trigger of the next move: store value into global variable g when the robot is amount (unit) from "
     "place.", "amount value ->", "next", False),
    ("MAKE_CONFIG", (("words", "config"),), _config_pops, 1,
     "Build config(...): the words the operand names and, when it says so, the turns of A1, A4, A6 popped "
     "(compiler.configs).", "[t1 t4 t6] -> config", "next", False),
    ("MAKE_POSE_CONFIG", (), 3, 1, "Build pose(position, orientation, configuration).",
     "position orientation config -> pose", "next", False),
    ("ROBOT_JOINT", (), 0, 1, "Push where the robot stands: every axis (compiler.robotstate).", "-> joint", "next",
     True),
    ("ROBOT_POSE", (), 0, 1, "Push the tool centre point of the active tool in the active base, with the arm's "
                             "configuration.", "-> pose", "next", True),
    ("TCP_SPEED", (), 0, 1, "Push the speed of the tool centre point now (mm/s).", "-> real", "next", False),
    ("TIMED_OUT", (), 0, 1, "Push whether the last 'wait for' with a time-out ended by it.", "-> bool", "next",
     False),
    ("CLOCK_START", (), 1, 0, "Clock n runs from now on.", "n ->", "next", True),
    ("CLOCK_STOP", (), 1, 0, "Clock n stops (it keeps its time).", "n ->", "next", True),
    ("CLOCK_RESET", (), 1, 0, "Clock n reads 0 (it runs on if it ran).", "n ->", "next", True),
    ("CLOCK_READ", (), 1, 1, "Push the seconds clock n has run.", "n -> real", "next", True),
    ("OUT_GET", (), 1, 1, "Read digital output n back (bool): as last set.", "n -> bool", "next", True),
    ("PULSE_OUT", (), 2, 0, "Set digital output n, and clear it again after the given seconds.", "n seconds ->",
     "next", True),
    ("KEEP", (("l", "local"),), 0, 0, "Keep local variable l (a 'var' parameter) for the caller, before a "
                                      "procedure returns.", "", "next", False),
    ("TAKE", (("p", "proc"), ("l", "count")), 0, 1, "Push what procedure p kept of its local l (the caller, just "
                                                    "after the call: a 'var' parameter's value, to store into the "
                                                    "variable passed).", "-> value", "next", False),
    ("RAISE", (), 2, 0, "Raise the program's own error: its number and message popped (compiler.recovery).",
     "number message ->", "raise", False),
    ("RERAISE", (), 0, 0, "In an error handler: pass the error it took on to the caller's handler.", "", "raise",
     False),
    ("RETRY", (), 0, 0, "In an error handler: continue at the start of the statement that raised the error.", "",
     "raise", False),
    ("TRYNEXT", (), 0, 0, "In an error handler: continue after the statement that raised the error.", "", "raise",
     False),
    ("ERROR_NUMBER", (), 0, 1, "Push the number of the error the handler took (compiler.recovery.ERRORS).",
     "-> integer", "next", False),
    ("ERROR_NAME", (), 0, 1, "Push the name of the error the handler took (\"move\", \"timeout\", ...).",
     "-> string", "next", False),
    ("ERROR_MESSAGE", (), 0, 1, "Push the message of the error the handler took, as the operator would read it.",
     "-> string", "next", False),
    ("PERS_LOAD", (("g", "global"),), 0, 0, "Persistent global g takes the value the runtime kept of it from an "
                                            "earlier run, when it kept one of its type (compiler.persistent).", "",
     "next", False),
    ("PERS_STORE", (("g", "global"),), 0, 0, "The runtime keeps persistent global g's value now (for later runs).",
     "", "next", False),
    ("AIN_GET", (), 1, 1, "Read analog input n (real, in its unit: the specification's [[analog_input]] n).",
     "n -> real", "next", True),
    ("SEARCH_BEGIN", (), 0, 0, "Before a search move (a MOVE_LIN with the search clause): wait until every move "
                               "handed over has ended (a search starts at rest).", "", "next", True),
    ("SEARCH_END", (), 0, 0, "After a search move: wait until it has ended; the program's search error when its "
                             "input did not become true on the way (compiler.recovery).", "", "next", True),
    ("SEARCH_POSE", (), 0, 1, "Push where the last search move's input became true: the tool centre point of its "
                              "tool in its base, with the arm's configuration (compiler.robotstate).", "-> pose",
     "next", False),
    ("GROUP_IN", (), 2, 1, "Read digital inputs first .. first + bits - 1 as one unsigned integer (input first: its "
                           "lowest bit).", "first bits -> integer", "next", True),
    ("GROUP_OUT", (), 3, 0, "Set digital outputs first .. first + bits - 1 to value's bits (output first: its lowest "
                            "bit), in one tick.", "first bits value ->", "next", True),
    ("AOUT_SET", (), 2, 0, "Set analog output n to value (real, in its unit: the specification's [[analog_output]] "
                           "n).", "n value ->", "next", True),
    ("AOUT_GET", (), 1, 1, "Push what analog output n was last set to (real).", "n -> real", "next", True),
    ("MAKE_RECORD", (("r", "record"),), lambda ops, p: len(p.records[ops[0]].fields), 1,
     "Build a record of type r (the record table's) from its fields' values, in declaration order "
     "(compiler.records).", "f1..fn -> record", "next", False),
    ("GET_MEMBER", (("f", "member"),), 1, 1, "Push field f of a record.", "record -> value", "next", False),
    ("SET_MEMBER", (("f", "member"),), 2, 0, "Store into field f of a record (the record is changed in place).",
     "record value ->", "next", False),
]

#: The types of the values on the stack (what a popped value must be, what is pushed). A
#: value has one of the language's types (compiler.semantics), is an array, ``array of
#: T``, or a record of the record table, ``record NAME``. In patterns: ``number`` is an
#: integer or a real, ``real`` accepts an integer too (it is converted), ``array`` any
#: array, ``record`` any record, ``any`` anything, ``a|b`` either; ``@g`` / ``@l`` the
#: declared type of the global / local slot the instruction names, ``@item`` the element
#: type of the array popped first, ``@member`` the type of field f of the record popped
#: first, ``@fields`` the fields of record type r, ``@params`` the called routine's
#: parameters, ``@clauses`` the move's clause values, ``@result`` the function's result.
VALUE_TYPES = ("integer", "real", "bool", "string", "joint", "position", "orientation", "pose", "config")

#: The rules for a pushed value whose type depends on what was popped or on an operand.
TYPE_RULES = {
    "@const": "the constant's type",
    "@g": "the global slot's declared type",
    "@l": "the local slot's declared type",
    "@same": "the type of the value popped",
    "@item": "the array's element type",
    "@array": "an array of the value popped",
    "@arith": "integer for two integers, real for two numbers (real for /), a string for two strings (+), "
              "the pose arithmetic's result (compiler.semantics.GEOMETRY)",
    "@builtin": "the built-in function's result (real, integer for round and trunc, the argument's for abs, "
                "min and max; compiler.semantics.GEOMETRIC_BUILTINS)",
    "@result": "the called function's result type",
    "@order": "bool, of two numbers or two strings",
    "@kept": "the declared type of the called procedure's local slot",
    "@record": "a record of type r",
    "@member": "the type of field f of the record popped",
}

#: The stack types of each instruction: (takes, gives), see InstrDef.
_TYPES: dict[str, tuple[str, str]] = {
    "NOP": ("", ""), "CONST": ("", "@const"), "LOAD_GLOBAL": ("", "@g"), "STORE_GLOBAL": ("@g", ""),
    "LOAD_LOCAL": ("", "@l"), "STORE_LOCAL": ("@l", ""), "COPY": ("array|record", "@same"),
    "TO_REAL": ("number", "real"),
    "NEG": ("number|position", "@same"), "NOT": ("bool", "bool"),
    "ADD": ("integer|real|string|position|pose integer|real|string|position", "@arith"),
    "SUB": ("number|position|pose number|position", "@arith"),
    "MUL": ("number|position|pose|orientation number|position|pose|orientation", "@arith"),
    "DIV": ("number|position number", "@arith"), "IDIV": ("integer integer", "integer"),
    "MOD": ("integer integer", "integer"),
    "EQ": ("any any", "bool"), "NE": ("any any", "bool"),
    "LT": ("number|string number|string", "@order"), "LE": ("number|string number|string", "@order"),
    "GT": ("number|string number|string", "@order"), "GE": ("number|string number|string", "@order"),
    "AND": ("bool bool", "bool"), "OR": ("bool bool", "bool"),
    "CALL_BUILTIN": ("number|position|pose|orientation|string", "@builtin"), "MAKE_JOINT": ("real", "joint"),
    "MAKE_POS": ("real real real", "position"), "MAKE_RPY": ("real real real", "orientation"),
    "MAKE_QUAT": ("real real real real", "orientation"), "MAKE_POSE": ("position orientation", "pose"),
    "MAKE_ARRAY": ("any", "@array"), "GET_ITEM": ("array integer", "@item"), "SET_ITEM": ("array integer @item", ""),
    "GET_AXIS": ("joint integer", "real"), "SET_AXIS": ("joint integer real", "joint"),
    "GET_FIELD": ("position|pose", "real"), "JUMP": ("", ""), "JUMP_IF_FALSE": ("bool", ""),
    "CALL": ("@params", ""), "RET": ("", ""), "IN_GET": ("integer", "bool"), "OUT_SET": ("integer bool", ""),
    "MOVE_PTP": ("joint|pose @clauses", ""), "MOVE_LIN": ("pose @clauses", ""),
    "MOVE_CIRC": ("pose pose @clauses", ""), "DWELL": ("real", ""), "WAIT_BEGIN": ("real", ""),
    "WAIT_TEST": ("bool", ""), "PRINT": ("any", ""), "PAUSE": ("", ""), "HALT": ("", ""), "END": ("", ""),
    "CALL_FUNC": ("@params", "@result"), "RET_VALUE": ("@result", ""), "USE_BASE": ("pose", ""),
    "USE_TOOL": ("pose", ""), "INT_ENABLE": ("", ""), "INT_DISABLE": ("", ""),
    "TRIGGER_OUT": ("real integer bool", ""), "TRIGGER_SET": ("real @g", ""),
    "MAKE_CONFIG": ("integer", "config"), "MAKE_POSE_CONFIG": ("position orientation config", "pose"),
    "ROBOT_JOINT": ("", "joint"), "ROBOT_POSE": ("", "pose"), "TCP_SPEED": ("", "real"), "TIMED_OUT": ("", "bool"),
    "CLOCK_START": ("integer", ""), "CLOCK_STOP": ("integer", ""), "CLOCK_RESET": ("integer", ""),
    "CLOCK_READ": ("integer", "real"), "OUT_GET": ("integer", "bool"), "PULSE_OUT": ("integer real", ""),
    "KEEP": ("", ""), "TAKE": ("", "@kept"), "RAISE": ("integer string", ""), "RERAISE": ("", ""),
    "RETRY": ("", ""), "TRYNEXT": ("", ""), "ERROR_NUMBER": ("", "integer"), "ERROR_NAME": ("", "string"),
    "ERROR_MESSAGE": ("", "string"), "PERS_LOAD": ("", ""), "PERS_STORE": ("", ""), "AIN_GET": ("integer", "real"),
    "SEARCH_BEGIN": ("", ""), "SEARCH_END": ("", ""), "SEARCH_POSE": ("", "pose"),
    "GROUP_IN": ("integer integer", "integer"), "GROUP_OUT": ("integer integer integer", ""),
    "AOUT_SET": ("integer real", ""), "AOUT_GET": ("integer", "real"),
    "MAKE_RECORD": ("@fields", "@record"), "GET_MEMBER": ("record", "@member"), "SET_MEMBER": ("record @member", ""),
}
_missing_types = [d[0] for d in _DEFS if d[0] not in _TYPES]
if _missing_types:  # pragma: no cover - the table is complete
    raise ImportError(f"compiler.objcode: no stack types for {', '.join(_missing_types)}")

INSTRUCTIONS: tuple[InstrDef, ...] = tuple(
    InstrDef(name, code, operands, pops, pushes, doc, effect, flow, tuple(_TYPES[name][0].split()), _TYPES[name][1],
             barrier)
    for code, (name, operands, pops, pushes, doc, effect, flow, barrier) in enumerate(_DEFS)
)
BY_NAME: dict[str, InstrDef] = {d.name: d for d in INSTRUCTIONS}
BY_CODE: dict[int, InstrDef] = {d.code: d for d in INSTRUCTIONS}
OP = type("OP", (), {d.name: d.code for d in INSTRUCTIONS})  # OP.CONST == 1, ...
#: The move instructions, one per motion (``MOVE_PTP``, ``MOVE_LIN``, ``MOVE_CIRC``).
MOVE_CODES = frozenset(BY_NAME[f"MOVE_{motion.upper()}"].code for motion in _MOTIONS)


# ---- the program ----------------------------------------------------------------------

@dataclass(frozen=True)
class ProcInfo:
    """A procedure or a function: where its code starts, how many parameters, its local
    slots, and a function's result type (empty for a procedure)."""

    name: str
    entry: int
    params: int
    locals: tuple[tuple[str, str], ...]  # (name, type) per slot, parameters first
    result: str = ""  # a function's result type; "" for a procedure


@dataclass(frozen=True)
class InterruptInfo:
    """An interrupt (compiler.interrupts): its name, its condition (a function of the
    procedure table: no parameters, a bool result, only the instructions of
    ``CONDITION_OPS``), its handler (a procedure without parameters), its priority (1 the
    highest), whether the robot stops when it fires, and whether the program then ends."""

    name: str
    condition: int
    handler: int
    priority: int
    stop: bool
    halt: bool


@dataclass(frozen=True)
class HandlerInfo:
    """An error handler (compiler.recovery): the code it protects, ``start`` to ``end``
    (the body of one routine, without its handler), where its code starts, and the
    statements of the body, ``(start, end)`` each, nested ones too: ``retry`` goes on at
    the start of the innermost one holding the instruction that raised the error,
    ``trynext`` at its end."""

    start: int
    end: int
    entry: int
    statements: tuple[tuple[int, int], ...]

    def statement_at(self, offset: int) -> tuple[int, int]:
        """The innermost statement of the body that holds ``offset`` (the whole body if none)."""
        best = (self.start, self.end)
        for start, end in self.statements:
            if start <= offset < end and start >= best[0] and end - start <= best[1] - best[0]:
                best = (start, end)
        return best


@dataclass(frozen=True)
class RecordInfo:
    """A record type (compiler.records): its name and its fields, ``(name, declared type)``
    each, in declaration order (a field's type: one of the language's, an array, or a record
    type earlier in the table)."""

    name: str
    fields: tuple[tuple[str, str], ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _t in self.fields)


@dataclass(frozen=True)
class Program:
    """Object code as plain data. ``code`` holds (opcode, operand, ...) tuples."""

    name: str
    source: str
    spec_name: str
    spec_hash: str
    robots: tuple[str, ...]
    constants: tuple
    code: tuple[tuple[int, ...], ...]
    lines: tuple[tuple[int, int, int], ...]  # (offset, line, column), offsets ascending
    globals: tuple[tuple[str, str], ...]  # (name, type) per slot
    procedures: tuple[ProcInfo, ...] = ()
    format_version: int = FORMAT_VERSION
    #: The modules the program was made with (as imported, relative to its source), and
    #: for each line-table entry the file it is in: 0 the program's source, k files[k - 1].
    #: Both empty for a program of one file.
    files: tuple[str, ...] = ()
    line_files: tuple[int, ...] = ()
    #: The interrupts (empty for a program without: then the object code has no such key).
    interrupts: tuple[InterruptInfo, ...] = ()
    #: The error handlers (empty for a program without: then the object code has no such key).
    handlers: tuple[HandlerInfo, ...] = ()
    #: The global slots of persistent variables (compiler.persistent; empty: no such key).
    persistent: tuple[int, ...] = ()
    #: The record types (compiler.records; empty: no such key).
    records: tuple[RecordInfo, ...] = ()
    #: The program's own world zones (compiler.zones.Zone; empty: no such key).
    zones: tuple = ()

    @cached_property
    def record_table(self) -> dict[str, RecordInfo]:
        """The record types by name."""
        return {record.name: record for record in self.records}

    def handler_at(self, offset: int) -> HandlerInfo | None:
        """The error handler that protects ``offset`` (None: none does)."""
        for handler in self.handlers:
            if handler.start <= offset < handler.end:
                return handler
        return None

    def line_at(self, offset: int) -> tuple[int, int]:
        """The (line, column) of the statement that ``offset`` belongs to, or (0, 0)."""
        from bisect import bisect_right

        i = bisect_right(self.lines, (offset, float("inf"), 0)) - 1
        return (self.lines[i][1], self.lines[i][2]) if i >= 0 else (0, 0)

    def file_at(self, offset: int) -> str:
        """The module file that ``offset``'s statement comes from, or "" for the program's
        own source."""
        if not self.line_files:
            return ""
        from bisect import bisect_right

        i = bisect_right(self.lines, (offset, float("inf"), 0)) - 1
        k = self.line_files[i] if i >= 0 else 0
        return self.files[k - 1] if k else ""

    def move_lines(self) -> tuple[int, ...]:
        """The lines of the program's own source (not of a module it imports) that hold a
        move instruction, ascending: where ``irl run --from-line`` may start."""
        return tuple(sorted({self.line_at(offset)[0] for offset, instr in enumerate(self.code)
                             if instr[0] in MOVE_CODES and not self.file_at(offset)}))

    def starts_at(self, offset: int, line: int) -> bool:
        """Whether ``offset`` is a move instruction on ``line`` of the program's own source."""
        return self.code[offset][0] in MOVE_CODES and self.line_at(offset)[0] == line and not self.file_at(offset)


def from_line_problem(program: Program, line: object) -> str | None:
    """What is wrong with starting ``program`` at the move on ``line`` (``irl run
    --from-line``, ``submit``'s ``from_line``), or None: the line must hold a move of the
    program's own source; the message names the lines that do."""
    lines = program.move_lines()
    if isinstance(line, int) and not isinstance(line, bool) and line in lines:
        return None
    shown = ", ".join(map(str, lines[:40])) + (f" ... ({len(lines)} lines)" if len(lines) > 40 else "")
    where = f"line {line}" if isinstance(line, int) and not isinstance(line, bool) and line > 0 else f"{line!r}"
    has = (f"the lines with a move: {shown}" if lines else "the program has no move of its own to start at")
    return f"{where} of {program.source or program.name} has no move to start at; {has}"


# ---- encoding ---------------------------------------------------------------------------

def _body(program: Program) -> dict:
    flat_code: list[int] = []
    for instr in program.code:
        flat_code.extend(instr)
    return {
        "name": program.name,
        "source": program.source,
        "spec": [program.spec_name, program.spec_hash],
        "robots": list(program.robots),
        "constants": [to_plain(c) for c in program.constants],
        "code": flat_code,
        "lines": [x for entry in program.lines for x in entry],
        "globals": [list(g) for g in program.globals],
        "procedures": [[p.name, p.entry, p.params, [list(l) for l in p.locals]] + ([p.result] if p.result else [])
                       for p in program.procedures],
    } | ({"files": list(program.files), "line_files": list(program.line_files)} if program.files else {}) \
      | ({"interrupts": [[i.name, i.condition, i.handler, i.priority, i.stop, i.halt] for i in program.interrupts]}
         if program.interrupts else {}) \
      | ({"handlers": [[h.start, h.end, h.entry, [x for span in h.statements for x in span]]
                       for h in program.handlers]} if program.handlers else {}) \
      | ({"persistent": list(program.persistent)} if program.persistent else {}) \
      | ({"records": [[r.name, [list(f) for f in r.fields]] for r in program.records]} if program.records else {}) \
      | ({"zones": [_zones.to_plain(z) for z in program.zones]} if program.zones else {})


def encode(program: Program) -> bytes:
    """The object file's bytes: header (magic, version, CRC-32) + msgpack body."""
    import msgpack  # (here, not above: checking a program needs the tables, not the encoding)

    body = msgpack.packb(_body(program), use_bin_type=True)
    return _HEADER.pack(MAGIC, program.format_version, zlib.crc32(body)) + body


def checksum_of(data: bytes) -> int:
    """The CRC-32 recorded in an object file's header."""
    return _HEADER.unpack_from(data)[2]


def _expect(cond: bool, message: str) -> None:
    if not cond:
        raise ObjectCodeError(message)


def _is_str(x) -> bool:
    return isinstance(x, str)


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _pairs(data, what: str) -> tuple[tuple[str, str], ...]:
    _expect(isinstance(data, list) and all(isinstance(x, list) and len(x) == 2 and all(map(_is_str, x))
                                           for x in data), f"{what}: expected a list of [name, type] pairs")
    return tuple((a, b) for a, b in data)


def decode(data: bytes) -> Program:
    """Bytes -> Program, checking the header and the body's shape (not its logic: see
    :func:`verify`). Raises :class:`ObjectCodeError` for anything malformed."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ObjectCodeError("object code must be bytes")
    data = bytes(data)
    _expect(len(data) >= _HEADER.size and data[:4] == MAGIC, "not an L-IRL object file (bad magic)")
    _expect(len(data) <= MAX_SIZE, f"object file too large ({len(data)} bytes, limit {MAX_SIZE})")
    magic, version, crc = _HEADER.unpack_from(data)
    _expect(version == FORMAT_VERSION,
            f"object format version {version} is not supported (this build reads version {FORMAT_VERSION})")
    body_bytes = data[_HEADER.size:]
    _expect(zlib.crc32(body_bytes) == crc, "checksum mismatch: the object file is corrupt")
    import msgpack

    try:
        body = msgpack.unpackb(body_bytes, raw=False, strict_map_key=True, use_list=True)
    except Exception as exc:  # msgpack raises several unrelated types for bad input
        raise ObjectCodeError(f"body is not valid msgpack ({type(exc).__name__})") from None
    _expect(isinstance(body, dict), "body: expected a map")
    keys = {"name", "source", "spec", "robots", "constants", "code", "lines", "globals", "procedures"}
    missing = keys - set(body)
    _expect(not missing, f"body: missing {', '.join(sorted(missing))}")
    _expect(_is_str(body["name"]) and _is_str(body["source"]), "body: name and source must be strings")
    spec = body["spec"]
    _expect(isinstance(spec, list) and len(spec) == 2 and all(map(_is_str, spec)),
            "body: spec must be [name, hash]")
    robots = body["robots"]
    _expect(isinstance(robots, list) and all(map(_is_str, robots)), "body: robots must be a list of strings")
    _expect(isinstance(body["constants"], list), "body: constants must be a list")
    constants = []
    for i, c in enumerate(body["constants"]):
        _expect(not isinstance(c, str) or len(c) <= MAX_STRING_LENGTH,
                f"constant {i}: a string of {len(c) if isinstance(c, str) else 0} characters "
                f"(at most {MAX_STRING_LENGTH})")
        try:
            constants.append(from_plain(c))
        except ValueError as exc:
            raise ObjectCodeError(f"constant {i}: {exc}") from None
    flat = body["code"]
    _expect(isinstance(flat, list) and all(map(_is_int, flat)), "body: code must be a list of integers")
    code = []
    pos = 0
    while pos < len(flat):
        op = flat[pos]
        definition = BY_CODE.get(op)
        if definition is None:
            raise ObjectCodeError(f"unknown opcode {op}", len(code))
        n = len(definition.operands)
        if pos + 1 + n > len(flat):
            raise ObjectCodeError(f"{definition.name}: code ends inside its operands", len(code))
        code.append(tuple(flat[pos:pos + 1 + n]))
        pos += 1 + n
    lines = body["lines"]
    _expect(isinstance(lines, list) and len(lines) % 3 == 0 and all(map(_is_int, lines)),
            "body: lines must be a flat list of (offset, line, column) integers")
    line_table = tuple(tuple(lines[i:i + 3]) for i in range(0, len(lines), 3))
    files, line_files = body.get("files", []), body.get("line_files", [])
    _expect(("files" in body) == ("line_files" in body), "body: files and line_files come together")
    _expect(isinstance(files, list) and all(_is_str(f) and f for f in files) and ("files" not in body or files),
            "body: files must be a non-empty list of file names")
    _expect(isinstance(line_files, list) and all(_is_int(k) and 0 <= k <= len(files) for k in line_files)
            and (not files or len(line_files) == len(line_table)),
            f"body: line_files must give, for each of the {len(line_table)} line entries, a file 0..{len(files)}")
    procs = body["procedures"]
    _expect(isinstance(procs, list), "body: procedures must be a list")
    procedures = []
    for i, p in enumerate(procs):
        _expect(isinstance(p, list) and len(p) in (4, 5) and _is_str(p[0]) and _is_int(p[1]) and _is_int(p[2])
                and (len(p) == 4 or (_is_str(p[4]) and p[4] != "")),
                f"procedure {i}: expected [name, entry, params, locals] or, for a function, "
                "[name, entry, params, locals, result type]")
        procedures.append(ProcInfo(p[0], p[1], p[2], _pairs(p[3], f"procedure {p[0]} locals"),
                                   p[4] if len(p) == 5 else ""))
    interrupts = []
    raw = body.get("interrupts", [])
    _expect(isinstance(raw, list) and ("interrupts" not in body or raw), "body: interrupts must be a non-empty list")
    for i, x in enumerate(raw):
        _expect(isinstance(x, list) and len(x) == 6 and _is_str(x[0]) and all(map(_is_int, x[1:4]))
                and all(isinstance(v, bool) for v in x[4:]),
                f"interrupt {i}: expected [name, condition, handler, priority, stop, halt]")
        interrupts.append(InterruptInfo(*x))
    handlers = []
    raw = body.get("handlers", [])
    _expect(isinstance(raw, list) and ("handlers" not in body or raw), "body: handlers must be a non-empty list")
    for i, h in enumerate(raw):
        _expect(isinstance(h, list) and len(h) == 4 and all(map(_is_int, h[:3])) and isinstance(h[3], list)
                and len(h[3]) % 2 == 0 and all(map(_is_int, h[3])),
                f"handler {i}: expected [start, end, entry, [statement start, end, ...]]")
        handlers.append(HandlerInfo(h[0], h[1], h[2], tuple(tuple(h[3][k:k + 2]) for k in range(0, len(h[3]), 2))))
    persistent = body.get("persistent", [])
    _expect(isinstance(persistent, list) and ("persistent" not in body or persistent)
            and all(map(_is_int, persistent)), "body: persistent must be a non-empty list of global slots")
    raw = body.get("records", [])
    _expect(isinstance(raw, list) and ("records" not in body or raw), "body: records must be a non-empty list")
    records = []
    for i, r in enumerate(raw):
        _expect(isinstance(r, list) and len(r) == 2 and _is_str(r[0]), f"record {i}: expected [name, fields]")
        records.append(RecordInfo(r[0], _pairs(r[1], f"record {r[0]!r:.40} fields")))
    raw = body.get("zones", [])
    _expect(isinstance(raw, list) and ("zones" not in body or raw) and len(raw) <= _zones.MAX_ZONES,
            f"body: zones must be a non-empty list of at most {_zones.MAX_ZONES}")
    zones = []
    for i, z in enumerate(raw):
        try:
            zones.append(_zones.from_plain(z))
        except ValueError as exc:
            raise ObjectCodeError(f"zone {i}: {exc}") from None
    _expect(len({z.name for z in zones}) == len(zones), "body: zones must each have a name of their own")
    return Program(body["name"], body["source"], spec[0], spec[1], tuple(robots), tuple(constants),
                   tuple(code), line_table, _pairs(body["globals"], "globals"), tuple(procedures), version,
                   tuple(files), tuple(line_files), tuple(interrupts), tuple(handlers), tuple(persistent),
                   tuple(records), tuple(zones))


# ---- verification ------------------------------------------------------------------------

def _check_operand(kind: str, value: int, program: Program, nlocals: int | None) -> str | None:
    """None when ``value`` is valid for an operand of ``kind``, else what is wrong."""
    if kind == "const":
        ok, limit = 0 <= value < len(program.constants), f"0..{len(program.constants) - 1}"
    elif kind == "global":
        ok, limit = 0 <= value < len(program.globals), f"0..{len(program.globals) - 1}"
    elif kind == "local":
        if nlocals is None:
            return "local variable used outside a procedure"
        ok, limit = 0 <= value < nlocals, f"0..{nlocals - 1}"
    elif kind == "target":
        ok, limit = 0 <= value < len(program.code), f"0..{len(program.code) - 1}"
    elif kind == "proc":
        ok, limit = 0 <= value < len(program.procedures), f"0..{len(program.procedures) - 1}"
    elif kind == "count":
        ok, limit = 0 <= value <= MAX_COUNT, f"0..{MAX_COUNT}"
    elif kind == "int":
        ok, limit = -(2 ** 31) <= value < 2 ** 31, "a 32-bit integer"
    elif kind == "builtin":
        ok, limit = 0 <= value < len(BUILTIN_NAMES), f"0..{len(BUILTIN_NAMES) - 1}"
    elif kind == "field":
        ok, limit = 0 <= value < len(FIELDS), f"0..{len(FIELDS) - 1}"
    elif kind == "clauses":
        ok, limit = 0 <= value < (1 << len(CLAUSES)), f"a mask below {1 << len(CLAUSES)}"
    elif kind == "flag":
        ok, limit = value in (0, 1), "0 or 1"
    elif kind == "place":
        from .triggers import PLACES

        ok, limit = 0 <= value < len(PLACES), f"0..{len(PLACES) - 1}"
    elif kind == "unit":
        from .triggers import UNITS

        ok, limit = 0 <= value < len(UNITS), f"0..{len(UNITS) - 1}"
    elif kind == "interrupt":
        ok, limit = 0 <= value < len(program.interrupts), f"0..{len(program.interrupts) - 1}"
    elif kind == "config":
        return _config_operand_problem(value)
    elif kind == "record":
        ok, limit = 0 <= value < len(program.records), f"0..{len(program.records) - 1}"
    elif kind == "member":
        ok, limit = 0 <= value < _MAX_FIELDS, f"0..{_MAX_FIELDS - 1}"
    elif kind == "name":
        ok, limit = 0 <= value < len(program.constants), f"0..{len(program.constants) - 1}"
        if ok and not isinstance(program.constants[value], str):
            return f"constant {value} is not a string (a name)"
    else:  # pragma: no cover - the table only uses the kinds above
        return f"unknown operand kind {kind}"
    return None if ok else f"{value} is out of range ({limit})"


# ---- the types of stack values (InstrDef.takes, InstrDef.gives) --------------------------------

_BOUNDS = re.compile(r"array\s*\[[^\]]*\]\s*of\s+")


def declared_type(text: object, records=()) -> str | None:
    """The stack type of a declared type (``array[1..7] of joint`` -> ``array of joint``,
    ``part_t`` -> ``record part_t`` when ``records`` holds that name), or None when ``text``
    is no type of the language or of the records."""
    if not isinstance(text, str):
        return None
    typ = _BOUNDS.sub("array of ", text.strip())
    base = typ
    while base.startswith("array of "):
        base = base[len("array of "):]
    if base in VALUE_TYPES:
        return typ
    return typ[:len(typ) - len(base)] + "record " + base if base in records else None


def declared_elements(text: str, records) -> int | None:
    """How many values a variable of declared type ``text`` holds, all levels together (a
    record's fields' summed; ``records``: name -> :class:`RecordInfo`), or None when more
    than :data:`MAX_ARRAY_ELEMENTS` or no type (object code is untrusted: every nesting)."""
    count, text = 1, text.strip()
    match = _ARRAY_DECL.match(text)
    while match is not None:
        count *= int(match.group(2)) - int(match.group(1)) + 1
        if not 0 <= count <= MAX_ARRAY_ELEMENTS:
            return None
        text = match.group(3).strip()
        match = _ARRAY_DECL.match(text)
    record = records.get(text) if records else None
    if record is not None:
        inner = 0
        for _name, field_type in record.fields:
            n = declared_elements(field_type, records)
            if n is None:
                return None
            inner += n
        count *= inner
    return count if count <= MAX_ARRAY_ELEMENTS else None


def zero_of(text: object, main_axes: int = 6, additional_axes: int = 0, records=None) -> object:
    """The zero value of a declared type (``array[1..3] of integer`` -> ``[0, 0, 0]``, a
    fresh list; a record of ``records``, name -> :class:`RecordInfo`, with each field's
    zero), or None for no type of the language: what a variable holds before its program
    stores into it (the code generator's initialiser, and the VM's global slots, so that a
    slot read before any store still holds its declared type)."""
    from .values import Config, Joint, Pose, Position, Rpy

    if not isinstance(text, str):
        return None
    text = text.strip()
    match = _ARRAY_DECL.match(text)
    if match is not None:  # (at most MAX_ARRAY_ELEMENTS in all, however nested: object code is untrusted)
        if declared_elements(text, records) is None:
            return None
        length = int(match.group(2)) - int(match.group(1)) + 1
        return [zero_of(match.group(3).strip(), main_axes, additional_axes, records) for _ in range(length)]
    record = records.get(text) if records else None
    if record is not None:
        return Record(record.name, record.names,
                      [zero_of(t, main_axes, additional_axes, records) for _n, t in record.fields])
    pose = Pose(Position(0.0, 0.0, 0.0), Rpy(0.0, 0.0, 0.0))
    zeros = {"integer": 0, "real": 0.0, "bool": False, "string": "", "position": Position(0.0, 0.0, 0.0),
             "orientation": Rpy(0.0, 0.0, 0.0), "pose": pose, "frame": pose, "tool": pose, "config": Config(),
             "joint": Joint((0.0,) * main_axes, (0.0,) * additional_axes)}
    return zeros.get(text)


_ARRAY_DECL = re.compile(r"array\s*\[\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*\]\s*of\s+(.+)$", re.S)


def value_type(value: object) -> str | None:
    """The stack type of a constant, or None (no value of the language)."""
    from .values import Config, Joint, Pose, Position, Quat, Rpy

    for cls, name in ((bool, "bool"), (int, "integer"), (float, "real"), (str, "string"), (Joint, "joint"),
                      (Position, "position"), (Rpy, "orientation"), (Quat, "orientation"), (Pose, "pose"),
                      (Config, "config")):
        if isinstance(value, cls):
            return name
    return None


def fits(actual: str, pattern: str) -> bool:
    """Does a value of type ``actual`` fit ``pattern`` (see :data:`VALUE_TYPES`)?"""
    for alt in pattern.split("|"):
        if alt in ("any", actual) or (alt in ("number", "real") and actual in ("integer", "real")) \
                or (alt == "array" and actual.startswith("array of ")) or (alt == "record" and
                                                                          actual.startswith("record ")):
            return True
    return False


_SYMBOLS = {"ADD": "+", "SUB": "-", "MUL": "*", "DIV": "/"}


def _arith_type(name: str, a: str, b: str) -> str | None:
    symbol = _SYMBOLS[name]
    numbers = ("integer", "real")
    if a in numbers and b in numbers:
        return "integer" if a == b == "integer" and symbol != "/" else "real"
    if symbol == "+" and a == b == "string":
        return "string"
    from .semantics import GEOMETRY

    found = GEOMETRY.get((symbol, "number" if a in numbers else a, "number" if b in numbers else b))
    return found[0] if found is not None else None


def _builtin_type(fn: str, args: list[str]) -> str | None:
    from .semantics import GEOMETRIC_BUILTINS, STRING_BUILTINS, geometric_result

    if fn in STRING_BUILTINS:
        params, result = STRING_BUILTINS[fn]
        return result if len(args) == len(params) and all(map(fits, args, params)) else None

    if fn in GEOMETRIC_BUILTINS:
        result = geometric_result(fn, tuple(args))
        return {"number": "real"}.get(result, result) if result is not None else None
    if not all(a in ("integer", "real") for a in args):
        return None
    if fn in ("round", "trunc"):
        return "integer"
    if fn in ("abs", "min", "max"):
        return "integer" if all(a == "integer" for a in args) else "real"
    return "real"


def _stack_types(definition: InstrDef, operands: tuple, program: Program, local_types: tuple, result: str,
                 stack: tuple) -> tuple[tuple, str | None]:
    """Check the types of the values ``definition`` pops from ``stack``; the stack after it.
    Raises ObjectCodeError (without an offset: the caller adds it)."""
    names = [n for n, _k in definition.operands]

    def operand(name: str) -> int:
        return operands[names.index(name)]

    records = program.record_table
    patterns: list[str] = []
    for t in definition.takes:
        if t == "@params":
            callee = program.procedures[operands[0]]
            patterns.extend(declared_type(typ, records) or "?" for _n, typ in callee.locals[:callee.params])
        elif t == "@fields":
            patterns.extend(declared_type(typ, records) or "?" for _n, typ in program.records[operand("r")].fields)
        elif t == "@clauses":
            patterns.extend(_CLAUSES_BY_NAME[c].stack_type for c in clause_names(operands[0]))
        elif t == "@g":
            patterns.append(declared_type(program.globals[operand("g")][1], records) or "?")
        elif t == "@l":
            patterns.append(local_types[operand("l")])
        elif t == "@result":
            patterns.append(result)
        else:
            patterns.append(t)
    pops = definition.pop_count(operands, program)
    if len(patterns) == 1 and pops != 1:
        patterns = patterns * pops
    popped = list(stack[len(stack) - pops:]) if pops else []
    for i, (actual, pattern) in enumerate(zip(popped, patterns)):
        if pattern == "@item":
            pattern = popped[0][len("array of "):]
        elif pattern == "@member":
            pattern = _member_type(program, popped[0], operand("f"))
        if not fits(actual, pattern):
            which = f"value {i + 1} of {pops}" if pops > 1 else "its value"
            raise ObjectCodeError(f"{definition.name}: {which} must be {pattern.replace('|', ' or ')}, "
                                  f"not {actual}")
    rule = definition.gives
    if not rule:
        return stack[:len(stack) - pops], None
    if rule == "@const":
        gives = value_type(program.constants[operands[0]])
        if gives is None:
            raise ObjectCodeError(f"CONST: constant {operands[0]} is no value of the language")
    elif rule == "@g":
        gives = declared_type(program.globals[operand("g")][1], records)
    elif rule == "@l":
        gives = local_types[operand("l")]
    elif rule == "@same":
        gives = popped[0]
    elif rule == "@item":
        gives = popped[0][len("array of "):]
    elif rule == "@array":
        gives = "array of " + popped[0]
    elif rule == "@result":
        gives = declared_type(program.procedures[operands[0]].result, records)
    elif rule == "@record":
        gives = "record " + program.records[operand("r")].name
    elif rule == "@member":
        gives = _member_type(program, popped[0], operand("f"))
    elif rule == "@arith":
        gives = _arith_type(definition.name, *popped)
        if gives is None:
            raise ObjectCodeError(f"{definition.name}: {popped[0]} {_SYMBOLS[definition.name]} {popped[1]} "
                                  "is not defined")
    elif rule == "@order":
        if fits(popped[0], "number") != fits(popped[1], "number"):
            raise ObjectCodeError(f"{definition.name}: {popped[0]} and {popped[1]} cannot be compared "
                                  "(two numbers or two strings)")
        gives = "bool"
    elif rule == "@kept":
        callee = program.procedures[operands[0]]
        if not operands[1] < len(callee.locals):
            raise ObjectCodeError(f"TAKE: procedure {callee.name!r} has no local slot {operands[1]}")
        gives = declared_type(callee.locals[operands[1]][1], records)
    elif rule == "@builtin":
        fn = BUILTIN_NAMES[operands[0]]
        gives = _builtin_type(fn, popped)
        if gives is None:
            raise ObjectCodeError(f"CALL_BUILTIN: {fn}({', '.join(popped)}) is not defined")
    else:
        gives = rule
    return stack[:len(stack) - pops] + (gives,), gives


def _member_type(program: Program, record: str, f: int) -> str:
    """The stack type of field ``f`` of a value of stack type ``record`` (``record NAME``)."""
    info = program.record_table.get(record[len("record "):]) if record.startswith("record ") else None
    if info is None:  # (the pattern "record" was checked first: this is a program's record type)
        raise ObjectCodeError(f"{record} is no record")
    if not f < len(info.fields):
        raise ObjectCodeError(f"record {info.name} has no field {f} (it has {len(info.fields)})")
    return declared_type(info.fields[f][1], program.record_table) or "?"


def _routine_types(program: Program, proc: ProcInfo | None) -> tuple[tuple, str]:
    """The declared types of a routine's local slots and its result, checked."""
    if proc is None:
        return (), ""
    local_types = []
    for name, typ in proc.locals:
        checked = declared_type(typ, program.record_table)
        if checked is None:
            raise ObjectCodeError(f"procedure {proc.name!r}: local {name!r} has type {typ!r}, no type of the "
                                  f"language ({', '.join(VALUE_TYPES)}, or an array of one)")
        local_types.append(checked)
    result = ""
    if proc.result:
        result = declared_type(proc.result, program.record_table) or ""
        if not result:
            raise ObjectCodeError(f"function {proc.name!r}: result type {proc.result!r} is no type of the language")
    return tuple(local_types), result


def _verify_routine(program: Program, entry: int, nlocals: int | None, owner: list, result: str = "",
                    proc: ProcInfo | None = None) -> int:
    """Walk every path from ``entry`` (a function's when ``result``); returns the largest
    stack depth reached. Follows the type of every stack value too. An error handler whose
    protected code the walk reaches belongs to this routine: its code, and the statements
    it may go on at, are walked too (each entered with an empty stack)."""
    local_types, result_type = _routine_types(program, proc)
    types_at: dict[int, tuple] = {entry: ()}
    work = [entry]
    deepest = 0
    seeded: set[int] = set()  # the error handlers found in this routine
    while True:
        deepest = max(deepest, _walk(program, entry, nlocals, owner, result, local_types, result_type, types_at,
                                     work))
        # an error handler of this routine: its code, and every statement it may go on at
        # (retry, trynext), are entered with an empty stack
        for k, handler in enumerate(program.handlers):
            if k not in seeded and owner[handler.start] == entry:
                seeded.add(k)
                for root in (handler.entry,) + tuple(x for span in handler.statements for x in span):
                    known = types_at.get(root)
                    if known is None:
                        types_at[root] = ()
                        work.append(root)
                    elif known:
                        raise ObjectCodeError(f"error handler {k}: the stack holds {len(known)} values where it "
                                              "enters or goes on (a statement's start or end, its code)", root)
        if not work:
            return deepest


def _walk(program: Program, entry: int, nlocals: int | None, owner: list, result: str, local_types: tuple,
          result_type: str, types_at: dict, work: list) -> int:
    """Walk every path from the pcs in ``work`` (their stack types in ``types_at``) within
    the routine at ``entry``; returns the largest stack depth reached."""
    code = program.code
    deepest = 0
    while work:
        pc = work.pop()
        stack = types_at[pc]
        depth = len(stack)
        if owner[pc] is None:
            owner[pc] = entry
        elif owner[pc] != entry:
            raise ObjectCodeError("code is shared between two routines", pc)
        instr = code[pc]
        definition = BY_CODE[instr[0]]
        operands = instr[1:]
        for (name, kind), value in zip(definition.operands, operands):
            if kind == "local":  # the other kinds were checked for every instruction
                problem = _check_operand(kind, value, program, nlocals)
                if problem:
                    raise ObjectCodeError(f"{definition.name} operand {name}: {problem}", pc)
        if definition.name == "CALL_BUILTIN" and BUILTINS[BUILTIN_NAMES[operands[0]]] != operands[1]:
            raise ObjectCodeError(f"CALL_BUILTIN {BUILTIN_NAMES[operands[0]]} takes "
                                  f"{BUILTINS[BUILTIN_NAMES[operands[0]]]} arguments, not {operands[1]}", pc)
        if definition.name in ("CALL", "CALL_FUNC") and \
                bool(program.procedures[operands[0]].result) != (definition.name == "CALL_FUNC"):
            callee = program.procedures[operands[0]]
            raise ObjectCodeError(f"{definition.name} of {'function' if callee.result else 'procedure'} "
                                  f"{callee.name!r}: a function is called with CALL_FUNC, a procedure with CALL", pc)
        if flow_of_return(definition.name, nlocals, result):
            raise ObjectCodeError(flow_of_return(definition.name, nlocals, result), pc)
        pops = definition.pop_count(operands, program)
        if pops > depth:
            raise ObjectCodeError(f"{definition.name} needs {pops} stack values but the stack holds {depth}", pc)
        try:
            stack, _gives = _stack_types(definition, operands, program, local_types, result_type, stack)
        except ObjectCodeError as exc:
            raise ObjectCodeError(exc.message, pc) from None
        depth = len(stack)
        deepest = max(deepest, depth)
        flow = definition.flow
        successors = []
        if flow in ("next", "call", "wait"):
            successors.append(pc + 1)
        elif flow == "jump":
            successors.append(operands[0])
        elif flow == "branch":
            successors.extend((pc + 1, operands[0]))
        elif flow == "stop" and definition.name == "END" and nlocals is not None:
            raise ObjectCodeError("END inside a procedure", pc)
        if flow in ("return", "stop", "raise") and depth != 0:
            raise ObjectCodeError(f"{definition.name} with {depth} values left on the stack", pc)
        for nxt in successors:
            if nxt >= len(code):
                raise ObjectCodeError("execution runs past the end of the code", pc)
            known = types_at.get(nxt)
            if known is None:
                types_at[nxt] = stack
                work.append(nxt)
            elif len(known) != depth:
                raise ObjectCodeError(f"inconsistent stack depth: {len(known)} on one path, {depth} on another", nxt)
            elif known != stack:
                raise ObjectCodeError(f"inconsistent stack types: {', '.join(known)} on one path, "
                                      f"{', '.join(stack)} on another", nxt)
    return deepest


def flow_of_return(name: str, nlocals: int | None, result: str) -> str | None:
    """Why a return instruction cannot be where it is (RET in a procedure, RET_VALUE in a
    function, neither in the main program), or None."""
    if name not in ("RET", "RET_VALUE"):
        return None
    if nlocals is None:
        return f"{name} outside a procedure or function"
    if name == "RET" and result:
        return "RET in a function: a function returns its value with RET_VALUE"
    if name == "RET_VALUE" and not result:
        return "RET_VALUE in a procedure: a procedure returns with RET"
    return None


def _shown(text: str | None, fallback: str) -> str:
    """A file name for a message and a command to paste: shell-quoted; ``fallback`` for
    none, or for an untrusted one that is not a short line of printable text."""
    import shlex

    if not text or len(text) > 300 or not text.isprintable():
        return fallback
    return shlex.quote(text)


def spec_mismatch(program: Program, spec, *, compiled_for: str | None = None, source: str | None = None,
                  spec_file: str | None = None, unknown: str = "its file is not known here",
                  instead: str = "run it with the specification it was compiled for (irl run PROGRAM.irlo --spec {})"
                  ) -> str:
    """Why ``program`` cannot run on the runtime that drives ``spec`` (a
    :class:`compiler.spec.Spec`): it was compiled for another specification (another robot,
    or another version of this robot's file). Names both specifications (robot, hash, and
    file where known: ``spec_file`` or ``spec.file``, ``compiled_for``) and both fixes: recompile
    ``source`` (default: the source file the object code names) for ``spec``, or what
    ``instead`` says (``{}``: the file it was compiled for); ``unknown`` says why that
    file is not named."""
    theirs = f"{program.spec_name!r} ({program.spec_hash[:12]}"
    theirs += f", {_shown(compiled_for, '')})" if compiled_for else f": {unknown})"
    ours = _shown(spec_file or spec.file, "THIS_ROBOT.spc")
    src = source if source is not None else _shown(program.source, "PROGRAM.irl")
    return (f"compiled for specification {theirs}, but this runtime drives {spec.name!r} ({spec.hash[:12]}, "
            f"{ours}): recompile it for this runtime (irl compile {src} --spec {ours}), or "
            + instead.format(_shown(compiled_for, "THE_SPEC_IT_WAS_COMPILED_FOR.spc")))


def verify(program: Program, spec_hash: str | None = None) -> int:
    """Check that ``program`` is safe to run; returns the largest stack depth it needs.

    Checks every opcode and operand, jump targets, procedure entries, the stack depth on
    every path, and (when ``spec_hash`` is given) that it was compiled for that robot.
    Raises :class:`ObjectCodeError` naming the offset of the first problem.
    """
    if program.format_version != FORMAT_VERSION:
        raise ObjectCodeError(f"object format version {program.format_version} is not supported")
    if spec_hash is not None and program.spec_hash != spec_hash:
        raise ObjectCodeError(
            f"compiled for specification {program.spec_name!r} ({program.spec_hash[:12]}), "
            f"but this robot's specification is {spec_hash[:12]}: recompile the program")
    if not program.code:
        raise ObjectCodeError("the program has no code")
    for i, constant in enumerate(program.constants):
        try:
            from_plain(to_plain(constant))  # the same rules as decoding: finite, 64-bit
        except (TypeError, ValueError) as exc:
            raise ObjectCodeError(f"constant {i}: {exc}") from None
    for offset, instr in enumerate(program.code):
        if not instr:
            raise ObjectCodeError("empty instruction", offset)
        definition = BY_CODE.get(instr[0])
        if definition is None:
            raise ObjectCodeError(f"unknown opcode {instr[0]}", offset)
        if len(instr) != 1 + len(definition.operands):
            n = len(definition.operands)
            raise ObjectCodeError(f"{definition.name} takes {n} operand{'s' if n != 1 else ''}, "
                                  f"not {len(instr) - 1}", offset)
    previous = -1
    problem = _records_problem(program)
    if problem is not None:
        raise ObjectCodeError(problem)
    for offset, line, column in program.lines:
        if not (0 <= offset < len(program.code)) or offset < previous or line < 1 or column < 1:
            raise ObjectCodeError(f"line table entry ({offset}, {line}, {column}) is invalid")
        previous = offset
    for proc in program.procedures:
        if not (0 <= proc.entry < len(program.code)):
            raise ObjectCodeError(f"procedure {proc.name!r} starts outside the code ({proc.entry})")
        if not (0 <= proc.params <= len(proc.locals)):
            raise ObjectCodeError(f"procedure {proc.name!r} has {proc.params} parameters "
                                  f"but {len(proc.locals)} local slots")
    # Every operand is checked, reachable or not (what is loaded is also disassembled);
    # the walks below then check local slots and stack depths per routine.
    most_locals = max((len(p.locals) for p in program.procedures), default=None)
    for offset, instr in enumerate(program.code):
        definition = BY_CODE[instr[0]]
        for (name, kind), value in zip(definition.operands, instr[1:]):
            problem = _check_operand(kind, value, program, most_locals)
            if problem:
                raise ObjectCodeError(f"{definition.name} operand {name}: {problem}", offset)
    for interrupt in program.interrupts:
        problem = _interrupt_problem(program, interrupt)
        if problem is not None:
            raise ObjectCodeError(f"interrupt {interrupt.name!r}: {problem}")
    for slot, (name, typ) in enumerate(program.globals):
        if declared_type(typ, program.record_table) is None or declared_elements(typ, program.record_table) is None:
            raise ObjectCodeError(f"global {slot} ({name!r}) has type {typ!r:.80}, no type of the language "
                                  f"({', '.join(VALUE_TYPES)}, a record type of the program, or an array of one, "
                                  f"at most {MAX_ARRAY_ELEMENTS} values)")
    if len(set(program.persistent)) != len(program.persistent) or \
            not all(0 <= g < len(program.globals) for g in program.persistent):
        raise ObjectCodeError(f"the persistent slots {list(program.persistent)[:20]} are not distinct global slots "
                              f"(0..{len(program.globals) - 1})")
    kept = {BY_NAME["PERS_LOAD"].code, BY_NAME["PERS_STORE"].code}
    for offset, instr in enumerate(program.code):
        if instr[0] in kept and instr[1] not in program.persistent:
            raise ObjectCodeError(f"{BY_CODE[instr[0]].name} of global {instr[1]}, which is not persistent", offset)
    for k, handler in enumerate(program.handlers):
        problem = _handler_problem(program, k, handler)
        if problem is not None:
            raise ObjectCodeError(f"error handler {k}: {problem}")
    owner: list = [None] * len(program.code)
    deepest = _verify_routine(program, 0, None, owner)
    for proc in program.procedures:
        if owner[proc.entry] is not None:
            raise ObjectCodeError(f"procedure {proc.name!r} starts inside other code", proc.entry)
        deepest = max(deepest, _verify_routine(program, proc.entry, len(proc.locals), owner, proc.result, proc))
    for k, handler in enumerate(program.handlers):
        routine = owner[handler.start]
        if routine is None or any(owner[pc] not in (None, routine) for pc in range(handler.start, handler.end)) \
                or owner[handler.entry] != routine:
            raise ObjectCodeError(f"error handler {k}: the code it protects and its own code must be of one routine")
    return deepest


_IDENTIFIER = re.compile(r"[a-z_][a-z0-9_]*")


def _records_problem(program: Program) -> str | None:
    """What is wrong with the record table, or None: each record named once (a name, no
    type of the language), with 1 to MAX_FIELDS fields named once, each of a type of the
    language or of a record before it (so no record holds itself), holding at most
    MAX_ARRAY_ELEMENTS values."""
    earlier: dict[str, RecordInfo] = {}
    for i, record in enumerate(program.records):
        what = f"record {i} ({record.name!r:.40})"
        if not _IDENTIFIER.fullmatch(record.name) or record.name in VALUE_TYPES or record.name in earlier \
                or record.name == "array":
            return f"{what}: its name must be a name, no type of the language, and given once"
        names = record.names
        if not 1 <= len(names) <= _MAX_FIELDS or len(set(names)) != len(names) \
                or not all(_IDENTIFIER.fullmatch(n) for n in names):
            return f"{what}: 1..{_MAX_FIELDS} fields, each named once by a name"
        for name, typ in record.fields:
            if declared_type(typ, earlier) is None:
                return (f"{what}: field {name!r} has type {typ!r:.80}, no type of the language or of a record "
                        "before it")
        earlier[record.name] = record
        if declared_elements(record.name, earlier) is None:
            return f"{what}: it holds more than {MAX_ARRAY_ELEMENTS} values"
    return None


def _handler_problem(program: Program, k: int, handler: HandlerInfo) -> str | None:
    """What is wrong with an error handler's table entry by itself, or None."""
    n = len(program.code)
    if not 0 <= handler.start <= handler.end < n:
        return f"it protects {handler.start}..{handler.end}, which is not inside the code (0..{n - 1})"
    if not 0 <= handler.entry < n or handler.start <= handler.entry < handler.end:
        return f"its code at {handler.entry} must be inside the code and outside what it protects"
    for start, end in handler.statements:
        if not handler.start <= start <= end <= handler.end:
            return f"its statement {start}..{end} is not inside what it protects ({handler.start}..{handler.end})"
    for other in program.handlers[:k]:
        if other.start < handler.end and handler.start < other.end:
            return "it protects code another handler protects"
    return None


def _interrupt_problem(program: Program, interrupt: InterruptInfo) -> str | None:
    """What is wrong with an interrupt table entry (compiler.interrupts), or None."""
    from .interrupts import CONDITION_OPS, MAX_CONDITION_CODE, PRIORITY

    procs = program.procedures
    if not (0 <= interrupt.condition < len(procs) and 0 <= interrupt.handler < len(procs)):
        return f"its condition and handler must be procedures 0..{len(procs) - 1}"
    cond, handler = procs[interrupt.condition], procs[interrupt.handler]
    if cond.result != "bool" or cond.params or cond.locals:
        return f"its condition {cond.name!r} must be a function without parameters or locals, of result bool"
    if handler.result or handler.params:
        return f"its handler {handler.name!r} must be a procedure without parameters"
    if not PRIORITY[0] <= interrupt.priority <= PRIORITY[1]:
        return f"priority {interrupt.priority} is out of range ({PRIORITY[0]}..{PRIORITY[1]})"
    allowed = {BY_NAME[name].code for name in CONDITION_OPS}
    for offset in range(cond.entry, min(cond.entry + MAX_CONDITION_CODE, len(program.code))):
        op = program.code[offset][0]
        if op not in allowed:
            return (f"its condition holds {BY_CODE[op].name} at {offset}: a condition may hold only "
                    f"{', '.join(CONDITION_OPS)}")
        if op == BY_NAME["RET_VALUE"].code:
            return None
    return f"its condition does not end in RET_VALUE within {MAX_CONDITION_CODE} instructions"


def load(data: bytes, spec_hash: str | None = None) -> Program:
    """Decode and verify: what the runtime calls on every program it receives."""
    program = decode(data)
    verify(program, spec_hash)
    return program
