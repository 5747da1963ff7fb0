"""Render ``docs/objcode.md``, the object-code reference, from :mod:`compiler.objcode`.

Every table in the document comes from the object-code module itself: the instruction
table (:data:`~compiler.objcode.INSTRUCTIONS`), the operand kinds, the built-in
function numbers, the clause bits (from :mod:`compiler.clauses`) and the field numbers. Stack effects that depend on
operands are worked out by evaluating each instruction's ``pops`` function over sample
operands, so the document cannot drift from the code. The examples (the body of a small
program, the constant encodings) are produced by encoding real values.

    python -m compiler.objdoc            # print the document
    python -m compiler.objdoc --write    # (re)write docs/objcode.md
    python -m compiler.objdoc --check    # exit 1 when docs/objcode.md is stale

Imports nothing from Lark.
"""
from __future__ import annotations

import argparse
import itertools
import json
import re
import sys
from pathlib import Path

import msgpack

from . import objcode
from .clauses import CLAUSES as CLAUSE_TABLE
from .records import MAX_FIELDS
from .objcode import (
    BUILTIN_NAMES,
    BUILTINS,
    BY_CODE,
    BY_NAME,
    CLAUSES,
    FIELDS,
    FORMAT_VERSION,
    INSTRUCTIONS,
    MAGIC,
    MAX_ARRAY_ELEMENTS,
    MAX_SIZE,
    MOTION_KINDS,
    OPERAND_KINDS,
    TYPE_RULES,
    VALUE_TYPES,
    InstrDef,
    ProcInfo,
    RecordInfo,
    Program,
    encode,
    verify,
)
from .configs import MAX_OPERAND as MAX_CONFIG_OPERAND
from .configs import TURNS_FLAG, Config
from .configs import operand_problem as config_operand_problem
from .values import Joint, Pose, Position, Quat, Rpy, format_value, to_plain

ROOT = Path(__file__).resolve().parent.parent
DOC_PATH = ROOT / "docs" / "objcode.md"
WRITE_COMMAND = "python -m compiler.objdoc --write"
CHECK_COMMAND = "python -m compiler.objdoc --check"

# The header's layout is defined once, in objcode; read it from there.
_HEADER = objcode._HEADER  # noqa: SLF001 - the module's own (private) source of truth

#: What each body key holds. A key the encoder writes but this table lacks is still
#: listed (marked undocumented), so a new key cannot go missing from the document.
_BODY_KEYS = {
    "name": "string: the program's name (from `program NAME;`, lower-cased).",
    "source": "string: the source file's name (without its folder).",
    "spec": "`[name, hash]`: the robot's name and the SHA-256 (hex) of the parsed system "
            "specification the program was compiled against. `verify(program, spec_hash)` refuses "
            "a program whose hash is not the given one.",
    "robots": "list of strings: the robots the program's moves use (each `act_rob` value, and "
              "the specification's robot for moves without `act_rob`); never empty.",
    "constants": "list: the constant pool, each constant encoded as below. `CONST k` pushes "
                 "entry k.",
    "code": "flat list of integers: each instruction's opcode followed by its operands "
            "(the instruction table gives the number of operands of each opcode).",
    "lines": "flat list of integers, a multiple of 3 long: `offset, line, column` triples.",
    "globals": "list of `[name, type]` pairs, one per global variable slot, in slot order. "
               "Names starting with `$` are hidden slots the compiler adds (a `for` loop's "
               "end value: `$end@LINE:COL`).",
    "procedures": "list of `[name, entry, params, locals]` (a procedure) or `[name, entry, params, "
                  "locals, result]` (a function): the routine's name, the offset "
                  "of its first instruction, its number of parameters, its local slots "
                  "as `[name, type]` pairs (the parameters first, in order; hidden `$` slots "
                  "last), and a function's result type (a non-empty string).",
}

#: How control continues after an instruction (the ``flow`` column).
_FLOWS = {
    "next": "continue with the next instruction",
    "jump": "continue at the target operand",
    "branch": "continue with the next instruction or at the target operand",
    "wait": "may take more than one control cycle (the robot moves or stands still), then "
            "continues with the next instruction",
    "call": "run the called procedure, then continue with the next instruction",
    "return": "return to the instruction after the `CALL`",
    "stop": "the program ends",
    "raise": "an error handler's jump (compiler.recovery): to the handler that takes the error, or to the "
             "statement its table names (`RETRY`, `TRYNEXT`); none takes it: the program ends with the error",
}

#: Valid values of the operand kinds whose range depends on the program's own tables.
_TABLE_RANGES = {
    "const": "0 .. (number of constants − 1)",
    "name": "0 .. (number of constants − 1), a string constant",
    "global": "0 .. (number of globals − 1)",
    "local": "0 .. (the procedure's number of local slots − 1); only inside a procedure",
    "target": "0 .. (number of instructions − 1)",
    "proc": "0 .. (number of procedures − 1)",
    "interrupt": "0 .. (number of interrupts − 1)",
    "record": "0 .. (number of record types − 1)",
    "member": f"0 .. (the record's number of fields − 1), at most {MAX_FIELDS - 1} (checked against the record on "
              "the stack)",
}


# ---- helpers ------------------------------------------------------------------------------

def _cell(text: object) -> str:
    """Text for one Markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _code(text: object) -> str:
    return f"`{text}`" if str(text) else ""


def _table(header: list[str], rows: list[list[object]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return out


def _operand_range(kind: str) -> str:
    """The values the verifier accepts for an operand of ``kind``, from the verifier itself."""
    if kind in _TABLE_RANGES:
        return _TABLE_RANGES[kind]
    problem = objcode._check_operand(kind, -(2 ** 40), _probe_program(), 0)  # noqa: SLF001
    match = re.search(r"is out of range \((.*)\)$", problem or "")
    return match.group(1) if match else "see `OPERAND_KINDS`"


# ---- stack effects that depend on the operands ---------------------------------------------

_PROBE_PARAMS = (0, 1, 2, 3, 5)
_VARIABLE = "variable (see the stack effect)"


def _probe_program() -> Program:
    """A program whose procedure i has _PROBE_PARAMS[i] parameters (for CALL's pops)."""
    procs = tuple(ProcInfo(f"p{i}", 0, n, tuple((f"a{j}", "integer") for j in range(n)))
                  for i, n in enumerate(_PROBE_PARAMS))
    records = tuple(RecordInfo(f"r{i}", tuple((f"f{j}", "integer") for j in range(n)))
                    for i, n in enumerate(_PROBE_PARAMS) if n)
    return Program("probe", "probe.irl", "probe", "0" * 64, (), (0, 0.0, ""), ((BY_NAME["END"].code,),) * 3,
                   (), (("g", "integer"),) * 3, procs, records=records)


def _samples(kind: str) -> list[int]:
    """Valid sample values of an operand kind."""
    if kind == "count":
        return [0, 1, 2, 3, 7]
    if kind == "flag":
        return [0, 1]
    if kind == "clauses":
        return list(range(1 << len(CLAUSES)))
    if kind == "proc":
        return list(range(len(_PROBE_PARAMS)))
    if kind == "record":
        return list(range(len([n for n in _PROBE_PARAMS if n])))
    if kind == "builtin":
        return list(range(len(BUILTIN_NAMES)))
    if kind == "field":
        return list(range(len(FIELDS)))
    if kind == "int":
        return [0, 1, -1, 5]
    if kind == "config":
        return [v for v in range(MAX_CONFIG_OPERAND + 1) if config_operand_problem(v) is None]
    return [0, 1, 2]


def _measure(kind: str, value: int) -> int | None:
    """The quantity of an operand that a stack effect can count, or None."""
    if kind in ("count", "flag", "int"):
        return value
    if kind == "clauses":
        return bin(value).count("1")
    if kind == "proc":
        return _PROBE_PARAMS[value]
    if kind == "record":
        return [n for n in _PROBE_PARAMS if n][value]
    if kind == "config":
        return 1 if value & TURNS_FLAG else 0
    return None


def _measure_words(kind: str, name: str) -> str:
    if kind == "clauses":
        return f"one per clause bit set in `{name}`"
    if kind == "proc":
        return f"the parameter count of procedure `{name}`"
    if kind == "record":
        return f"the field count of record type `{name}`"
    if kind == "config":
        return f"bit 6 of `{name}`"
    return f"`{name}`"


def describe_pops(definition: InstrDef) -> str:
    """How many values an instruction pops, in words: a number, or a formula in its operands.

    A variable count is fitted as ``c + sum(k_i * measure(operand_i))`` and the fit is
    checked on every combination of sample operands; when no such formula fits, the
    answer points to the stack-effect column.
    """
    if isinstance(definition.pops, int):
        return str(definition.pops)
    program = _probe_program()
    kinds = [kind for _, kind in definition.operands]
    sample_sets = [_samples(kind) for kind in kinds]
    combos = list(itertools.product(*sample_sets))
    if len(combos) > 20000:
        return _VARIABLE
    try:
        values = {ops: definition.pop_count(ops, program) for ops in combos}
    except Exception:  # noqa: BLE001 - a pops function this fitter cannot drive
        return _VARIABLE
    base = tuple(s[0] for s in sample_sets)
    coefficients = []
    for i, kind in enumerate(kinds):
        # (measure, pops) when only operand i changes
        points = [(_measure(kind, v), values[base[:i] + (v,) + base[i + 1:]]) for v in sample_sets[i]]
        if points[0][0] is None:  # an operand that only names something: must not matter
            if len({n for _, n in points}) > 1:
                return _VARIABLE
            coefficients.append(0)
            continue
        m0, n0 = points[0]
        k = next(((n - n0) / (m - m0) for m, n in points if m != m0), 0)
        if not float(k).is_integer():
            return _VARIABLE
        coefficients.append(int(k))
    constant = values[base] - sum(k * (_measure(kind, v) or 0) for k, kind, v in zip(coefficients, kinds, base))

    def model(ops):
        return constant + sum(k * (_measure(kind, v) or 0) for k, kind, v in zip(coefficients, kinds, ops))

    if any(model(ops) != n for ops, n in values.items()):
        return _VARIABLE
    terms = [str(constant)] if constant else []
    for (name, kind), k in zip(definition.operands, coefficients):
        if k:
            words = _measure_words(kind, name)
            terms.append(words if k == 1 else f"{k} × ({words})")
    return " + ".join(terms) or "0"


# ---- examples ----------------------------------------------------------------------------

def _example_program() -> Program:
    """A small, valid program: print a real, then call a procedure that prints its argument.

    Roughly ``var r : real := 1.5; seq print r; call show(7); endseq`` with
    ``procedure show(v : integer); seq print v; endseq``.
    """
    op = {d.name: d.code for d in INSTRUCTIONS}
    code = (
        (op["CONST"], 0), (op["STORE_GLOBAL"], 0),  # var r : real := 1.5;
        (op["LOAD_GLOBAL"], 0), (op["PRINT"], 1),  # print r;
        (op["CONST"], 1), (op["CALL"], 0),  # call show(7);
        (op["END"],),
        (op["LOAD_LOCAL"], 0), (op["PRINT"], 1),  # print v;
        (op["RET"],),
    )
    program = Program("example", "example.irl", "lola_15", "ab" * 32, ("lola_15",), (1.5, 7), code,
                      ((0, 2, 5), (2, 6, 3), (4, 7, 3), (6, 8, 1), (7, 12, 3), (9, 13, 1)),
                      (("r", "real"),), (ProcInfo("show", 7, 1, (("v", "integer"),)),))
    verify(program)  # the example must itself be valid object code
    return program


def _example_body() -> dict:
    data = encode(_example_program())
    return msgpack.unpackb(data[_HEADER.size:], raw=False)


_CONSTANT_EXAMPLES = [
    ("integer", 42),
    ("real", 0.5),
    ("bool", True),
    ("string", "lola_15"),
    ("joint", Joint((45.0, 0.0, -45.0, 0.0, 0.0, 0.0))),
    ("joint (with additional axes)", Joint((10.0, 20.0), (300.0,))),
    ("position", Position(100.0, 0.0, 500.0)),
    ("orientation (rpy)", Rpy(0.0, 90.0, 0.0)),
    ("orientation (quat)", Quat(1.0, 0.0, 0.0, 0.0)),
    ("pose", Pose(Position(100.0, 0.0, 500.0), Rpy(0.0, 90.0, 0.0))),
    ("config", Config(shoulder=0, elbow=None, wrist=1, turns=(0, 0, -1))),
    ("config (nothing named)", Config()),
    ("pose (with a configuration)", Pose(Position(100.0, 0.0, 500.0), Rpy(0.0, 90.0, 0.0), Config(wrist=1))),
]


# ---- the document ------------------------------------------------------------------------

def _section_format() -> list[str]:
    header_fields = [
        ["magic", "4 bytes", f"`{MAGIC.decode('ascii')}`"],
        ["format version", "u16, big-endian", f"{FORMAT_VERSION} (this build reads only this version)"],
        ["checksum", "u32, big-endian", "CRC-32 (zlib) of the body bytes"],
    ]
    body = _example_body()
    out = [
        "## File format",
        "",
        f"An object file (`.irlo`; the same bytes go over the wire to the runtime) is a "
        f"{_HEADER.size}-byte header followed by the body. The header is "
        f"`struct.pack({_HEADER.format!r}, magic, version, crc)`:",
        "",
        *_table(["field", "encoding", "value"], header_fields),
        "",
        f"The body is one [msgpack](https://msgpack.org) map (strings as UTF-8 `str`, "
        f"integers as msgpack integers). A file is at most {MAX_SIZE:,} bytes. The body's keys:",
        "",
        *_table(["key", "holds"], [[f"`{key}`", _BODY_KEYS.get(key, "(undocumented)")] for key in body]),
        "",
        "A program made with modules (`import \"FILE\";`) has two more keys, together: `files`, the "
        "module files (non-empty strings, as imported, relative to the program's source), and "
        "`line_files`, one integer per `lines` entry: the file that statement is in (0 the "
        "program's source, k `files[k - 1]`). A program of one file has neither, so its bytes "
        "are what they were before modules. `Program.file_at(offset)` gives an offset's file.",
        "",
        "A program with error handlers (`when error do`, compiler.recovery) has the key `handlers`: "
        "a list of `[start, end, entry, statements]`, one per handler: the offsets it protects "
        "(`start` to `end`, the body of one routine without its handler), where its own code "
        "starts, and a flat list of `start, end` pairs, the body's statements (nested ones too). "
        "An error raised at an offset the handler protects (or in a routine called from there "
        "that does not handle it) continues at `entry` with the routine's stack empty; `RETRY` "
        "continues at the start of the innermost statement that holds the offset, `TRYNEXT` at "
        "its end. The verifier walks the handler's code and each of those statements' starts and "
        "ends with an empty stack, and refuses a handler whose offsets are not all in one routine. "
        "A program without handlers has no such key.",
        "",
        "A program with persistent variables (`persistent`, compiler.persistent) has the key "
        "`persistent`: the list of their global slots (distinct). Only those slots may be the "
        "operand of `PERS_LOAD` and `PERS_STORE`. A program without has no such key.",
        "",
        "A program with record types (`record NAME ... endrecord;`, compiler.records) has the key "
        "`records`: a list of `[name, [[field, type], ...]]`, one per record type, in declaration "
        "order. A record type's name is a name and no type of the language; its fields (at least "
        "one, each named once) have the language's types, arrays, or a record type *earlier* in "
        "the list (so no record holds itself), and it holds at most "
        f"{MAX_ARRAY_ELEMENTS:,} values in all. A slot's or a field's declared type may then be a "
        "record's name (`part_t`, `array[1..4] of part_t`); on the stack it is `record NAME`. "
        "A program without has no such key.",
        "",
        "A program with world zones of its own (`zone NAME := box(...);`, compiler.zones) has the key "
        "`zones`: a list of `[name, shape, kind, output, {key: value}]`, one per zone, the shape's keys "
        "those of a specification's `[[zone]]` table (a box's `min` and `max`, a cylinder's `centre`, "
        "`radius` and `z`), checked as the specification's are when the object code is read; the "
        "output is a signal zone's (1..), 0 for a forbidden zone. A runtime refuses to start a "
        "program whose zones do not fit its robot (more than 64 with its specification's, a name "
        "one of them has, an output it lacks, a zone over its home position). A program without "
        "has no such key.",
        "",
        "Offsets (jump targets, procedure entries, line-table offsets) count *instructions*, "
        "not integers of the flat `code` list: offset 0 is the first instruction, offset 1 the "
        "instruction after it, however many operands the first one has. Execution starts at "
        "offset 0. The compiler puts the main program first (ending with `END`), then each "
        "procedure, from its `entry` to its `RET`.",
        "",
        "### Constant encoding",
        "",
        "Scalars are themselves; a structured value is a list whose first item names its kind. "
        "The compiler writes every number inside a structured value as a real (msgpack "
        "float); the decoder also accepts integers there.",
        "",
        *_table(["type", "L-IRL value", "encoded (shown as JSON)"],
                [[kind, f"`{format_value(v)}`", f"`{json.dumps(to_plain(v))}`"] for kind, v in _CONSTANT_EXAMPLES]),
        "",
        "A quaternion in the pool is already normalised (`quat(...)` normalises at compile "
        "time). An integer constant must fit msgpack's integer range (−2^63 .. 2^64 − 1). A "
        "configuration (`config(...)`, compiler.configs) is `[\"config\", shoulder, elbow, wrist, "
        "turns]`: each group `0` (its first word: `front`, `elbow_up`, `noflip`), `1` (its second: "
        "`back`, `elbow_down`, `flip`) or nil (free), the turns of A1, A4, A6 three integers "
        "(within 64 bits) or nil; anything else (a `2`, a `true`, two turns) is refused. A pose "
        "that names a configuration has it as a third item; one that names none has two items, "
        "as before configurations existed, so a program without them is encoded as it was.",
        "",
        "### Line table",
        "",
        "`lines` maps code back to the source: the triple `offset, line, column` says that "
        "the instructions from `offset` up to the next entry's offset belong to the statement "
        "that starts at that 1-based line and column. Offsets never decrease. "
        "`Program.line_at(offset)` returns the line and column of the last entry whose offset "
        "is at or before `offset` (what the disassembler shows, and where a run-time error is "
        "reported).",
        "",
        "### Example",
        "",
        "The body of a small program (`var r : real := 1.5;` … `print r; call show(7);` and a "
        "procedure `show(v : integer)` that prints `v`), shown as JSON:",
        "",
        "```json",
        "{",
        ",\n".join(f"  {json.dumps(key)}: {json.dumps(value)}" for key, value in body.items()),
        "}",
        "```",
        "",
        "Decoded, `code` reads: " + "; ".join(
            f"{i}: `{' '.join([BY_CODE[ins[0]].name] + [str(x) for x in ins[1:]])}`"
            for i, ins in enumerate(_example_program().code)) + ".",
        "",
    ]
    return out



def _section_tables() -> list[str]:
    kinds_used = sorted({kind for d in INSTRUCTIONS for _, kind in d.operands})
    out = [
        "## Operand kinds",
        "",
        "Every operand is an integer; its kind says what it means and which values the "
        "verifier accepts.",
        "",
        *_table(["kind", "meaning", "valid values", "used by"],
                [[f"`{kind}`", meaning, _operand_range(kind),
                  ", ".join(f"`{d.name}`" for d in INSTRUCTIONS if any(k == kind for _, k in d.operands))]
                 for kind, meaning in OPERAND_KINDS.items()]),
        "",
    ]
    unknown = [k for k in kinds_used if k not in OPERAND_KINDS]
    if unknown:
        out += [f"Kinds used but not described in `OPERAND_KINDS`: {', '.join(unknown)}.", ""]
    out += [
        "## Built-in functions",
        "",
        "The `fn` operand of `CALL_BUILTIN`; `argc` must equal the function's argument count. "
        "Angles are in degrees.",
        "",
        *_table(["number", "function", "arguments"],
                [[i, f"`{name}`", BUILTINS[name]] for i, name in enumerate(BUILTIN_NAMES)]),
        "",
        "## Move clauses",
        "",
        f"The `clauses` operand of {', '.join(f'`MOVE_{k.upper()}`' for k in MOTION_KINDS)} is a bit "
        "mask of the clauses the move gives. The values of the given clauses are on the stack "
        "above the target(s), in bit order (lowest bit deepest). A clause that is not given takes "
        "the system specification's default. The runtime checks every move's clauses as the "
        "compiler does (`compiler/clauses.py`, the clause table this list comes from; ranges in "
        "docs/language.md): a clause on a motion it does not apply to, a value of another type or "
        "out of range stops the program at the move's line.",
        "",
        *_table(["bit", "mask", "clause", "applies to", "value"],
                [[c.bit, 1 << c.bit, f"`{c.name}`", ", ".join(f"`MOVE_{k.upper()}`" for k in c.motions),
                  c.stack_type] for c in CLAUSE_TABLE]),
        "",
        "## Fields",
        "",
        "The `f` operand of `GET_FIELD` (positions and poses, in mm).",
        "",
        *_table(["number", "field"], [[i, f"`{name}`"] for i, name in enumerate(FIELDS)]),
        "",
        "## Control flow",
        "",
        "The `flow` column of the instruction table:",
        "",
        *_table(["flow", "meaning"],
                [[f"`{flow}`", _FLOWS.get(flow, "(undocumented)")]
                 for flow in dict.fromkeys(d.flow for d in INSTRUCTIONS)]),
        "",
    ]
    return out


def _section_instructions() -> list[str]:
    rows = []
    for d in INSTRUCTIONS:
        operands = ", ".join(f"`{name}`: {kind}" for name, kind in d.operands) or "—"
        takes = " ".join(f"`{t}`" for t in d.takes) or "—"
        rows.append([d.code, f"`{d.name}`", operands, _code(d.effect) or "—", describe_pops(d), d.pushes,
                     takes, f"`{d.gives}`" if d.gives else "—", f"`{d.flow}`", "yes" if d.barrier else "—", d.doc])
    return [
        "## Instructions",
        "",
        f"{len(INSTRUCTIONS)} instructions, opcodes 0 to {len(INSTRUCTIONS) - 1}. The stack effect "
        "reads `before -> after`, the top of the stack on the right; *pops* and *pushes* are "
        "what the verifier counts (a formula when the count depends on the operands). *takes* "
        "are the types the popped values must have (deepest first; one pattern for a count that "
        "depends on the operands: each value), *gives* the type of the value pushed (below). "
        "*barrier*: the instruction is a barrier to the motion look-ahead. The runtime's VM runs "
        "ahead of the robot (a move hands its request over and the program goes on), but an "
        "instruction marked here acts where the robot is: the VM executes it only when every move "
        "handed over has ended (inside an interrupt's handler at once: it acts beside the motion), "
        "and until then the program waits before it with the stack untouched. (`DWELL` waits for "
        "the motion too, after it has taken its seconds: the dwell starts when the robot stands.)",
        "",
        *_table(["code", "name", "operands", "stack effect", "pops", "pushes", "takes", "gives", "flow",
                 "barrier", "description"], rows),
        "",
        "### Stack types",
        "",
        f"A stack value has one of the types {', '.join(f'`{t}`' for t in VALUE_TYPES)}, or is an "
        "array, `array of T` (a declared `array[1..7] of joint` is `array of joint`). In *takes*: "
        "`number` is an integer or a real, `real` accepts an integer too (it is converted), `array` "
        "is any array, `any` anything, `a|b` either; `@g` and `@l` are the declared type of the "
        "global or local slot the instruction names, `@item` the element type of the array below, "
        "`@params` the called routine's parameters (their declared types), `@clauses` the move's "
        "clause values (real, `act_rob` a string), `@result` the function's result type. The "
        "rules of *gives*:",
        "",
        *_table(["rule", "the type pushed"], [[f"`{rule}`", text] for rule, text in TYPE_RULES.items()]),
        "",
    ]


def _section_verifier() -> list[str]:
    return [
        "## What the loader checks",
        "",
        "`compiler.objcode.load` (what the runtime calls on every program it receives) first "
        "decodes, then verifies. Anything wrong is an `ObjectCodeError` that says what, and "
        "where (the instruction offset) when there is a where.",
        "",
        "Decoding (`decode`) checks the shape:",
        "",
        f"- the data are bytes, start with `{MAGIC.decode('ascii')}`, are at least the "
        f"{_HEADER.size}-byte header long and at most {MAX_SIZE:,} bytes;",
        f"- the format version is {FORMAT_VERSION};",
        "- the CRC-32 of the body equals the header's;",
        "- the body is valid msgpack and a map with every key above (other keys are ignored);",
        "- `name` and `source` are strings, `spec` is two strings, `robots` a list of strings;",
        "- every constant is a valid encoding (the right kind names, counts and numbers);",
        "- `code` is a list of integers, every opcode is known and no instruction is cut "
        "short by the end of the list;",
        "- `lines` is a list of integers whose length is a multiple of 3;",
        "- `files` and `line_files` come together or not at all; `files` is a non-empty list of "
        "non-empty strings and `line_files` has one file number 0..len(files) per line entry;",
        "- `globals` and every procedure's locals are `[name, type]` string pairs, and every "
        "procedure is `[name, entry, params, locals]` or `[name, entry, params, locals, result]` "
        "with a non-empty `result`.",
        "",
        "Verification (`verify`) checks that the code is safe to run, without running it:",
        "",
        "- the format version is supported and, when the runtime passes its specification's "
        "hash, the program was compiled for that specification (otherwise: recompile);",
        "- there is code, and every instruction has its opcode's number of operands;",
        "- every line-table entry has an offset inside the code, offsets never decrease, and "
        "lines and columns are at least 1;",
        "- every procedure's entry is inside the code and not inside another routine's code, "
        "and its parameter count is at most its number of local slots;",
        "- from offset 0 (the main program, which has no locals) and from every procedure "
        "entry, every reachable instruction is walked along every path, and:",
        "  - every operand is valid for its kind (table above); `local` operands only occur "
        "in procedures;",
        "  - `CALL_BUILTIN`'s `argc` equals the function's argument count;",
        "  - no instruction pops more values than the stack holds;",
        "  - every value an instruction pops has the type the instruction takes (*takes* above), "
        "and every constant `CONST` pushes is a value of the language, so that no verified "
        "program gives an operation a value it is not defined for;",
        "  - where paths meet, the stack depth and the types of the stack values are the same "
        "on each of them;",
        "  - no path runs past the end of the code;",
        "  - `CALL` names a procedure and `CALL_FUNC` a function (one with a result);",
        "  - `RET` only occurs in procedures, `RET_VALUE` only in functions, and `END` only in "
        "the main program;",
        "  - `RET`, `HALT` and `END` leave the stack empty, and `RET_VALUE` leaves it holding "
        "exactly the result;",
        "  - no instruction belongs to two routines;",
        "- the result is the largest stack depth any path reaches (so a VM can size its "
        "stack before it starts).",
        "",
        "Every global and local slot, and every function's result, has a declared type of the "
        "language (the types above). "
        "The loader checks the code's structure and the types of its values, not the values it "
        "computes: array indexes, joint axis numbers, digital I/O numbers, division by "
        "zero, the domains of the built-in functions, clause values that were not constants, "
        "and the axis limits and reachability of targets that were not constants are left to "
        "the VM while it runs (`compiler/semantics.py` defines the arithmetic and its errors, "
        "shared by the compiler's constant folding and the VM).",
        "",
    ]


def render() -> str:
    """The whole of ``docs/objcode.md``."""
    lines = [
        f"_Generated by `{WRITE_COMMAND}` from `compiler/objcode.py`: do not edit by hand._",
        "",
        "# L-IRL object code",
        "",
        "The contract between the offline compiler (`irl compile`) and the runtime. Everything "
        "below is generated from `compiler/objcode.py` (the instruction table `INSTRUCTIONS`, "
        "`OPERAND_KINDS`, `BUILTINS`, `FIELDS`) and `compiler/clauses.py` (the clause table "
        f"`CLAUSES`) by `compiler/objdoc.py`; after changing a table, run `{WRITE_COMMAND}` "
        f"(`{CHECK_COMMAND}` and `tests/test_docs.py` fail while "
        "this file is stale). `irl dis FILE.irlo` (or `irl dis FILE.irl`) prints a program's "
        "code in the same terms.",
        "",
        "The machine is a stack machine: expressions push values, statements pop them; every "
        "statement leaves the stack as it found it. Global variables live in numbered global "
        "slots, a procedure's parameters and variables in numbered local slots (parameters "
        "first). Arrays are values: storing or passing one stores or passes a copy.",
        "",
    ]
    lines += _section_format()
    lines += _section_tables()
    lines += _section_instructions()
    lines += _section_verifier()
    return "\n".join(lines).rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m compiler.objdoc",
                                     description="Render the object-code reference (docs/objcode.md).")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--write", action="store_true", help=f"write {DOC_PATH.relative_to(ROOT)}")
    group.add_argument("--check", action="store_true",
                       help=f"exit 1 when {DOC_PATH.relative_to(ROOT)} differs from what would be generated")
    args = parser.parse_args(argv)
    text = render()
    if args.write:
        DOC_PATH.parent.mkdir(parents=True, exist_ok=True)
        DOC_PATH.write_text(text, encoding="utf-8")
        print(f"wrote {DOC_PATH.relative_to(ROOT)} ({len(INSTRUCTIONS)} instructions)")
        return 0
    if args.check:
        try:
            current = DOC_PATH.read_text(encoding="utf-8")
        except OSError:
            current = None
        if current != text:
            print(f"{DOC_PATH.relative_to(ROOT)} is stale: regenerate it with `{WRITE_COMMAND}`",
                  file=sys.stderr)
            return 1
        print(f"{DOC_PATH.relative_to(ROOT)} is up to date")
        return 0
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
