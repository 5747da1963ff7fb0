"""Object code -> instruction records -> text (or JSON).

Decoding yields :class:`Instruction` records; formatting them is a separate step, used by
``irl dis`` and by the VM's trace (CPython's ``dis`` is the model).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

from .objcode import BUILTIN_NAMES, BY_CODE, FIELDS, Program, checksum_of, clause_names
from .configs import operand_text as config_operand_text
from .triggers import PLACES, UNITS
from .zones import to_plain as to_plain_zone
from .values import format_value, to_plain


@dataclass(frozen=True)
class Instruction:
    offset: int
    name: str
    operands: tuple[int, ...]
    argrepr: str  # the operands resolved: constant values, names, clause lists
    line: int
    column: int
    starts_line: bool  # the first instruction of its source statement
    is_jump_target: bool


def _argrepr(program: Program, definition, operands: tuple[int, ...], routine_locals) -> str:
    parts = []
    for (op_name, kind), value in zip(definition.operands, operands):
        if kind in ("const", "name"):
            parts.append(format_value(program.constants[value]))
        elif kind == "global":
            parts.append(program.globals[value][0])
        elif kind == "local":
            parts.append(routine_locals[value][0] if routine_locals and value < len(routine_locals) else f"#{value}")
        elif kind == "target":
            parts.append(f"to {value}")
        elif kind == "proc":
            parts.append(program.procedures[value].name)
        elif kind == "builtin":
            parts.append(BUILTIN_NAMES[value])
        elif kind == "field":
            parts.append(FIELDS[value])
        elif kind == "clauses":
            parts.append(", ".join(clause_names(value)) or "no clauses")
        elif kind == "interrupt":
            parts.append(program.interrupts[value].name)
        elif kind == "place":
            parts.append(PLACES[value].words)
        elif kind == "unit":
            parts.append(UNITS[value].name)
        elif kind == "config":
            parts.append(config_operand_text(value))
        elif kind == "record":
            record = program.records[value]
            parts.append(f"{record.name}({', '.join(record.names)})")
        elif kind == "member":
            parts.append(f"field {value}")
    return "; ".join(parts)


def instructions(program: Program) -> Iterator[Instruction]:
    """One record per instruction, in code order."""
    targets = {instr[1] for instr in program.code
               if BY_CODE[instr[0]].operands[:1] and BY_CODE[instr[0]].operands[0][1] == "target"}
    entries = {p.entry: p for p in program.procedures}
    starts = {entry[0] for entry in program.lines}
    routine_locals = None
    for offset, instr in enumerate(program.code):
        if offset in entries:
            routine_locals = entries[offset].locals
        definition = BY_CODE[instr[0]]
        line, column = program.line_at(offset)
        yield Instruction(offset, definition.name, tuple(instr[1:]),
                          _argrepr(program, definition, tuple(instr[1:]), routine_locals),
                          line, column, offset in starts, offset in targets)


def header(program: Program, data: bytes | None = None) -> dict:
    """The program's identity, as shown at the top of a disassembly."""
    info = {
        "format_version": program.format_version,
        "program": program.name,
        "source": program.source,
        "spec_name": program.spec_name,
        "spec_hash": program.spec_hash,
        "robots": list(program.robots),
    }
    if data is not None:
        info["checksum"] = f"crc32:{checksum_of(data):08x}"
        info["size"] = len(data)
    return info


def _type_of(value) -> str:
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "real"
    if isinstance(value, str):
        return "string"
    return type(value).__name__.lower()


def _section(out: list[str], title: str, rows: list[str]) -> None:
    """A numbered section of the listing (none when it has no rows)."""
    if rows:
        out.append("")
        out.append(f"{title} ({len(rows)}):")
        out.extend(f"  {i:4d}  {row}" for i, row in enumerate(rows))


def format_text(program: Program, data: bytes | None = None, source: str | None = None,
                modules: dict[str, str] | None = None) -> str:
    """The human-readable listing of ``irl dis``.

    With ``source`` (the program's text), each statement's source line is shown above
    its instructions; with ``modules`` (a module's name in the object code -> its text),
    those of the modules too, each after its file's name.
    """
    info = header(program, data)
    out = [
        f"program        {info['program']}",
        f"source         {info['source']}",
        f"format         {info['format_version']}",
        f"specification  {info['spec_name']} sha256:{info['spec_hash'][:16]}",
        f"robots         {', '.join(info['robots'])}",
    ] + ([f"modules        {', '.join(program.files)}"] if program.files else [])
    if data is not None:
        out.append(f"checksum       {info['checksum']} ({info['size']} bytes)")
    out.append("")
    out.append(f"constants ({len(program.constants)}):")
    for i, value in enumerate(program.constants):
        out.append(f"  {i:4d}  {_type_of(value):8s} {format_value(value)}")
    if program.globals:
        out.append("")
        out.append(f"globals ({len(program.globals)}):")
        for i, (name, type_) in enumerate(program.globals):
            out.append(f"  {i:4d}  {name} : {type_}")
    _section(out, "records", [f"{r.name}({'; '.join(f'{n} : {t}' for n, t in r.fields)})" for r in program.records])
    _section(out, "zones", [f"{z.name}: {z.kind} {z.describe()}" + (f", output {z.output}" if z.output else "")
                            for z in program.zones])
    _section(out, "interrupts", [f"{x.name}: when {program.procedures[x.condition].name}, priority {x.priority}, "
                                 f"{'stop' if x.stop else 'continue'}, then {'halt' if x.halt else 'resume'}"
                                 for x in program.interrupts])
    _section(out, "error handlers", [f"protects {h.start}..{h.end - 1}, its code at {h.entry} (line "
                                     f"{program.line_at(h.entry)[0]}), {len(h.statements)} statements"
                                     for h in program.handlers])
    handlers = {program.procedures[x.handler].entry: x for x in program.interrupts}
    source_lines = source.split("\n") if source is not None else None  # as the parser counts lines
    module_lines = {name: text.split("\n") for name, text in (modules or {}).items()}
    entries = {p.entry: p for p in program.procedures}
    out.append("")
    out.append("code:")
    out.append("  line  offset  instruction")
    for ins in instructions(program):
        if ins.offset in entries:
            proc = entries[ins.offset]
            params = ", ".join(f"{n} : {t}" for n, t in proc.locals[:proc.params])
            out.append("")
            out.append(f"function {proc.name}({params}) : {proc.result}" if proc.result else
                       f"interrupt {proc.name}" if ins.offset in handlers else f"procedure {proc.name}({params})")
        if ins.starts_line:
            where = program.file_at(ins.offset)
            text_lines = module_lines.get(where) if where else source_lines
            if text_lines is not None and 1 <= ins.line <= len(text_lines):
                out.append(f"        ; {where + ':' if where else ''}{ins.line}: {text_lines[ins.line - 1].strip()}")
            elif where:
                out.append(f"        ; {where}:{ins.line}")
        line = f"{ins.line:6d}" if ins.starts_line else "      "
        marker = ">>" if ins.is_jump_target else "  "
        operands = " ".join(str(o) for o in ins.operands)
        text = f"{line} {marker}{ins.offset:5d}  {ins.name:14s} {operands:8s}"
        if ins.argrepr:
            text += f" ({ins.argrepr})"
        out.append(text.rstrip())
    return "\n".join(out) + "\n"


def format_json(program: Program, data: bytes | None = None) -> dict:
    """The same listing as plain data (``irl dis --json``)."""
    return {
        "header": header(program, data),
        "constants": [to_plain(c) for c in program.constants],
        "globals": [{"name": n, "type": t} for n, t in program.globals],
        "procedures": [{"name": p.name, "entry": p.entry, "params": p.params,
                        "locals": [{"name": n, "type": t} for n, t in p.locals], "result": p.result or None}
                       for p in program.procedures],
        "modules": list(program.files),
        "interrupts": [{"name": x.name, "condition": x.condition, "handler": x.handler, "priority": x.priority,
                        "stop": x.stop, "halt": x.halt} for x in program.interrupts],
        "handlers": [{"start": h.start, "end": h.end, "entry": h.entry, "statements": [list(s) for s in h.statements]}
                     for h in program.handlers],
        "records": [{"name": r.name, "fields": [{"name": n, "type": t} for n, t in r.fields]} for r in program.records],
        "zones": [to_plain_zone(z) for z in program.zones],
        "code": [{"offset": i.offset, "name": i.name, "operands": list(i.operands), "argrepr": i.argrepr,
                  "line": i.line, "column": i.column, "file": program.file_at(i.offset) or None}
                 for i in instructions(program)],
    }

