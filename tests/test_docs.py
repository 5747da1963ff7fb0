"""The documentation stays true to the code.

- docs/objcode.md is exactly what compiler.objdoc renders from the instruction table;
- every instruction is in that table and has a disassembly form;
- opcodes are unique and dense;
- docs/language.md mentions every built-in function, constructor, clause, type and
  keyword that the compiler accepts.
"""
from __future__ import annotations

import io
import re

import pytest

from compiler import objdoc
from compiler.disasm import instructions
from compiler.objcode import (
    BUILTIN_NAMES,
    BUILTINS,
    BY_CODE,
    BY_NAME,
    InterruptInfo,
    RecordInfo,
    CLAUSES,
    FIELDS,
    INSTRUCTIONS,
    OPERAND_KINDS,
    ProcInfo,
    Program,
)
from compiler.values import Joint

from conftest import ROOT
OBJCODE_MD = ROOT / "docs" / "objcode.md"
LANGUAGE_MD = ROOT / "docs" / "language.md"
GRAMMAR = ROOT / "grammar" / "lirl.lark"


# ---- docs/objcode.md ---------------------------------------------------------------------

def test_objcode_md_is_up_to_date():
    assert OBJCODE_MD.exists(), f"docs/objcode.md is missing: generate it with `{objdoc.WRITE_COMMAND}`"
    assert OBJCODE_MD.read_text(encoding="utf-8") == objdoc.render(), (
        f"docs/objcode.md is stale (compiler/objcode.py or compiler/objdoc.py changed): regenerate it with "
        f"`{objdoc.WRITE_COMMAND}`")


def test_objcode_md_says_it_is_generated():
    first = objdoc.render().splitlines()[0]
    assert "generated" in first.lower() and objdoc.WRITE_COMMAND in first


def _instruction_rows(text: str) -> dict[str, list[str]]:
    """name -> cells of the rows of the instruction table."""
    rows = {}
    for line in text.splitlines():
        m = re.match(r"\| (\d+) \| `([A-Z_]+)` \|", line)
        if m:
            rows[m.group(2)] = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
            assert int(m.group(1)) == BY_NAME[m.group(2)].code
    return rows


def test_every_instruction_is_in_the_rendered_table():
    rows = _instruction_rows(objdoc.render())
    assert set(rows) == {d.name for d in INSTRUCTIONS}
    for d in INSTRUCTIONS:
        cells = rows[d.name]
        assert len(cells) == 11, cells
        for name, kind in d.operands:
            assert f"`{name}`: {kind}" in cells[2]
        assert cells[5] == str(d.pushes)
        assert cells[6].replace("\\|", "|") == (" ".join(f"`{t}`" for t in d.takes) or "—")  # the types checked
        assert cells[7] == (f"`{d.gives}`" if d.gives else "—")
        assert cells[8] == f"`{d.flow}`"
        assert cells[9] == ("yes" if d.barrier else "—")  # the motion look-ahead's barriers
        if isinstance(d.pops, int):
            assert cells[4] == str(d.pops)
        else:  # a variable count is described by a formula, never left open
            assert "variable" not in cells[4], f"{d.name}: pops not described: {cells[4]}"


def test_every_table_of_objcode_is_rendered():
    text = objdoc.render()
    for kind in OPERAND_KINDS:
        assert f"| `{kind}` |" in text
    for number, name in enumerate(BUILTIN_NAMES):
        assert f"| {number} | `{name}` | {BUILTINS[name]} |" in text
    for bit, name in enumerate(CLAUSES):
        assert f"| {bit} | {1 << bit} | `{name}` |" in text
    for number, name in enumerate(FIELDS):
        assert f"| {number} | `{name}` |" in text


def test_objdoc_check_and_write_commands(tmp_path, monkeypatch, capsys):
    doc = tmp_path / "docs" / "objcode.md"
    monkeypatch.setattr(objdoc, "DOC_PATH", doc)
    monkeypatch.setattr(objdoc, "ROOT", tmp_path)
    assert objdoc.main(["--check"]) == 1  # missing
    assert objdoc.WRITE_COMMAND in capsys.readouterr().err
    assert objdoc.main(["--write"]) == 0
    assert doc.read_text(encoding="utf-8") == objdoc.render()
    assert objdoc.main(["--check"]) == 0
    doc.write_text(objdoc.render() + "edited by hand\n", encoding="utf-8")
    assert objdoc.main(["--check"]) == 1
    capsys.readouterr()
    assert objdoc.main([]) == 0
    assert capsys.readouterr().out == objdoc.render()


# ---- the instruction table ---------------------------------------------------------------

def test_the_instruction_table_only_grows():
    """Every opcode keeps its instruction (tests/golden/opcodes.txt): object files written by
    an earlier build still mean what they meant. A new instruction goes at the table's end
    (and into the file); renumbering one needs a new object format version."""
    from conftest import ROOT

    known = [line.split() for line in (ROOT / "tests" / "golden" / "opcodes.txt").read_text().splitlines()]
    now = [[str(d.code), d.name] for d in INSTRUCTIONS]
    assert now[:len(known)] == known, "an instruction changed its opcode: append new ones to compiler/objcode.py"
    assert len(now) == len(known), "new instructions: add them to tests/golden/opcodes.txt"


def test_opcodes_are_unique_and_dense():
    codes = [d.code for d in INSTRUCTIONS]
    assert len(set(codes)) == len(codes)
    assert sorted(codes) == list(range(len(INSTRUCTIONS)))
    assert len({d.name for d in INSTRUCTIONS}) == len(INSTRUCTIONS)
    assert set(BY_CODE) == set(codes) and set(BY_NAME) == {d.name for d in INSTRUCTIONS}


def test_every_operand_kind_is_described():
    for d in INSTRUCTIONS:
        for _, kind in d.operands:
            assert kind in OPERAND_KINDS, f"{d.name}: operand kind {kind!r} is not in OPERAND_KINDS"


# A valid value for an operand of each kind in the program built below.
_OPERAND_VALUE = {
    "const": 0, "global": 0, "local": 0, "target": 0, "proc": 0, "count": 1, "int": 1,
    "builtin": 0, "field": 0, "clauses": 0b100001, "flag": 1, "name": 2, "interrupt": 0, "place": 1, "unit": 0,
    "config": 0b1100001, "record": 0, "member": 0,
}


def _one_of_each() -> Program:
    code = []
    for d in INSTRUCTIONS:
        operands = [_OPERAND_VALUE[kind] for _, kind in d.operands]
        if d.name == "CALL_BUILTIN":
            operands[1] = BUILTINS[BUILTIN_NAMES[operands[0]]]
        code.append((d.code, *operands))
    return Program(
        name="each", source="each.irl", spec_name="lola_15", spec_hash="0" * 64, robots=("lola_15",),
        constants=(Joint((1.0, 2.0, 3.0, 4.0, 5.0, 6.0)), 2.5, "text"),
        code=tuple(code), lines=((0, 1, 1),),
        globals=(("g", "integer"),),
        procedures=(ProcInfo("p", 0, 1, (("a", "real"),)),),
        interrupts=(InterruptInfo("i", 0, 0, 1, True, False),),
        records=(RecordInfo("r", (("a", "real"),)),),
    )


def test_every_instruction_has_a_disassembly_form():
    program = _one_of_each()
    records = list(instructions(program))
    assert [r.name for r in records] == [d.name for d in INSTRUCTIONS]
    for record, d in zip(records, INSTRUCTIONS):
        assert record.offset == d.code
        assert isinstance(record.argrepr, str)
        assert len(record.operands) == len(d.operands)
        if any(kind in ("const", "global", "proc", "builtin", "field", "clauses", "target", "name", "interrupt", "place", "unit", "config",
                            "record", "member")
               for _, kind in d.operands):
            assert record.argrepr, f"{d.name}: operands are not resolved in the disassembly"


# ---- docs/language.md --------------------------------------------------------------------

def _language_md() -> str:
    assert LANGUAGE_MD.exists(), "docs/language.md is missing"
    return LANGUAGE_MD.read_text(encoding="utf-8")


def _code_spans(text: str) -> str:
    """All text inside `code spans` and ``` blocks, lower-cased, joined."""
    blocks = re.findall(r"```.*?```", text, flags=re.S)
    spans = re.findall(r"`([^`\n]+)`", re.sub(r"```.*?```", "", text, flags=re.S))
    return "\n".join(blocks + spans).lower()


def _mentioned(word: str, code: str) -> bool:
    return re.search(rf"(?<![a-z0-9_]){re.escape(word.lower())}(?![a-z0-9_])", code) is not None


def _grammar_keywords() -> set[str]:
    """Every keyword of the grammar: named terminals ("program"i) and anonymous ones ("then"i)."""
    words = set(re.findall(r'"([a-z_]+)"i', GRAMMAR.read_text(encoding="utf-8")))
    assert {"program", "seq", "move", "then", "timeout"} <= words  # the pattern still matches
    return words


@pytest.mark.parametrize("group, names", [
    ("built-in function", list(BUILTINS)),
    ("clause", list(CLAUSES)),
    ("field", list(FIELDS)),
])
def test_language_md_covers_the_objcode_tables(group, names):
    code = _code_spans(_language_md())
    missing = [n for n in names if not _mentioned(n, code)]
    assert not missing, f"docs/language.md does not mention the {group}s {missing}"


def test_language_md_covers_the_grammar_keywords():
    code = _code_spans(_language_md())
    missing = sorted(k for k in _grammar_keywords() if not _mentioned(k, code))
    assert not missing, f"docs/language.md does not mention the keywords {missing}"


def test_language_md_covers_types_and_constructors():
    from compiler.check import CONSTRUCTORS, NAMED_TYPES

    code = _code_spans(_language_md())
    missing = [n for n in list(NAMED_TYPES) + list(CONSTRUCTORS) + ["array"] if not _mentioned(n, code)]
    assert not missing, f"docs/language.md does not mention {missing}"


#: Each statement the checker knows -> text that its section in docs/language.md shows.
STATEMENT_SYNTAX = {
    "Assign": ["NAME := EXPR;", "NAME[INDEX]"],
    "OutSet": ["out[N] := BOOL;", "in[N]"],
    "Move": ["move ptp", "move lin", "move circ"],
    "If": ["if COND then", "elsif COND then", "endif;"],
    "While": ["while COND do", "endwhile;"],
    "Repeat": ["repeat", "until COND;"],
    "For": ["for NAME := START to END [step STEP] do", "endfor;"],
    "WaitTime": ["wait SECONDS sec;"],
    "WaitFor": ["wait for COND;", "wait for COND timeout SECONDS sec;"],
    "CallProc": ["call NAME;", "call NAME(EXPR, ...);"],
    "Print": ["print EXPR {, EXPR};"],
    "Pause": ["pause;"],
    "Halt": ["halt;"],
    "Return": ["return;", "return EXPRESSION;"],
    "Use": ["use base EXPR;", "use tool EXPR;"],
    "Enable": ["enable NAME;", "disable NAME;"],
    "Trigger": ["trigger when AMOUNT mm|ms after start|before end|after end do out[N] := BOOL;"],
    "OnError": ["when error do"],
    "Word": ["`retry;`", "`trynext;`", "`raise;`", "`raise N, \"message\";`"],
}


def test_language_md_covers_every_statement():
    from compiler.check import Checker

    handled = {name[2:] for name in dir(Checker) if name.startswith("s_")}
    undocumented = handled - set(STATEMENT_SYNTAX)
    assert not undocumented, (f"statements {sorted(undocumented)} are not documented: describe them in "
                              f"docs/language.md and add them to STATEMENT_SYNTAX")
    text = _language_md()
    for statement, snippets in STATEMENT_SYNTAX.items():
        for snippet in snippets:
            assert snippet in text, f"docs/language.md: the {statement} statement lacks {snippet!r}"


def test_protocol_page_describes_every_operation_and_error_code():
    """docs/protocol.md is what a client in another language is written from: every
    operation and every error code of runtime/wire/protocol.py must be on it."""
    from runtime.wire import protocol

    text = (ROOT / "docs" / "protocol.md").read_text(encoding="utf-8")
    headings = [line for line in text.splitlines() if line.startswith("### ")]
    for op, (args, _doc) in protocol.OPS.items():
        assert any(f"`{op}`" in h for h in headings), f"operation {op!r} has no section"
        for name in args:
            assert f"`{name}`" in text, f"argument {op}.{name} is not described"
    for code in protocol.ERRORS:
        assert f"| `{code}` |" in text, f"error code {code!r} is not in the table"
    assert f"version {protocol.VERSION}" in text


def test_generated_tables_are_up_to_date():
    """docs/safety.md, docs/runtime.md and docs/language.md hold tables rendered from their
    one declaration (compiler.params, runtime.loop.components.safety.CATEGORIES,
    compiler.clauses)."""
    from runtime.cli import docgen

    pages = docgen.pages()
    assert {p.name for p in pages} >= {"safety.md", "runtime.md", "language.md"}
    for page in pages:
        text = page.read_text(encoding="utf-8")
        assert docgen.render(text) == text, f"{page.name} is stale: python -m runtime.cli.docgen --write"
    text = (ROOT / "docs" / "safety.md").read_text(encoding="utf-8")
    from compiler.params import PARAMS
    from runtime.loop.components.safety import CATEGORIES

    for param in PARAMS:
        assert f"`{param.key}`" in text, param.key
    for cause in CATEGORIES:
        assert f"| {cause} |" in text, cause
    language = _language_md()
    assert "<!-- generated: clauses -->" in language and "<!-- generated: defaults -->" in language
    for name in CLAUSES:
        assert f"| `{name}` |" in language, name


def test_docgen_check_and_write(tmp_path, monkeypatch):
    from runtime.cli import docgen

    page = tmp_path / "x.md"
    page.write_text("a\n<!-- generated: categories -->\nold\n<!-- end generated -->\nb\n", encoding="utf-8")
    monkeypatch.setattr(docgen, "DOCS", tmp_path)
    assert docgen.main(["--check"]) == 1
    assert docgen.main(["--write"]) == 0
    assert docgen.main(["--check"]) == 0
    assert "| emergency stop | 1 |" in page.read_text(encoding="utf-8")
    assert docgen.main([]) == 2


def _doc_programs():
    """(page, line, text) of every whole program in a code block of docs/ (a block whose
    first line is ``program name;``; the grammar's ``program NAME;`` outline is not one)."""
    found = []
    for page in sorted((ROOT / "docs").glob("*.md")):
        lines = page.read_text(encoding="utf-8").splitlines()
        inside, start, block = False, 0, []
        for number, line in enumerate(lines, 1):
            if line.startswith("```"):
                if inside and block and re.match(r"program [a-z_][a-z0-9_]*;", block[0]):
                    found.append((page.name, start + 1, "\n".join(block) + "\n"))
                inside, start, block = not inside, number, []
            elif inside:
                block.append(line)
    return found


DOC_PROGRAMS = _doc_programs()


@pytest.mark.parametrize("page, line, text", DOC_PROGRAMS, ids=[f"{p}:{n}" for p, n, _ in DOC_PROGRAMS])
def test_every_program_in_the_docs_runs_to_completion_and_checks_clean(tmp_path, page, line, text):
    import shutil

    from runtime.cli.main import Environment, main

    shutil.copy(ROOT / "programs" / "lola15.spc", tmp_path / "lola15.spc")
    shutil.copytree(ROOT / "programs" / "lib", tmp_path / "lib")  # the modules the examples import
    source = tmp_path / "example.irl"
    source.write_text(text, encoding="utf-8")
    out, err = io.StringIO(), io.StringIO()
    code = main(["run", str(source)], Environment(stdout=out, stderr=err))
    assert code == 0, f"docs/{page}:{line}: the example does not run:\n{out.getvalue()[:600]}{err.getvalue()}"
    # and irl check (its motion check too) has nothing to say about it: no false alarm
    out, err = io.StringIO(), io.StringIO()
    code = main(["check", str(source)], Environment(stdout=out, stderr=err))
    assert code == 0 and err.getvalue() == "", f"docs/{page}:{line}: irl check finds:\n{err.getvalue()}"


def test_the_docs_hold_programs_to_run():
    assert any(page == "language.md" for page, _, _ in DOC_PROGRAMS)
