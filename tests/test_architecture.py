"""The house's rules (docs/architecture.md): the import graph is a ladder of layers and the
processes' packages talk over runtime.wire only (import-linter's contracts in
pyproject.toml); no import circle, no module takes another's private names, and no class or
function outgrows what one person can hold in mind (tests/house.py measures them)."""
from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

import house


def _show(edges) -> str:
    return "\n".join(f"  {e.source} -> {e.target} (line {e.line}) {', '.join(e.names)}" for e in edges)


def test_the_imports_keep_the_layers_and_the_processes_apart():
    """import-linter checks pyproject.toml's contracts: each package imports only from the
    layers below it; the server and the client import nothing of the loop, the planners or
    the backends."""
    root = Path(__file__).resolve().parent.parent
    linter = Path(sys.executable).with_name("lint-imports")
    done = subprocess.run([str(linter), "--no-cache"], cwd=root, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "0 broken" in done.stdout, done.stdout


def test_the_imports_make_no_circle():
    found = house.circles(house.imports())
    assert not found, "import circles:\n" + "\n".join("  " + " <-> ".join(c) for c in found)


def test_no_private_name_is_imported_across_modules():
    found = house.private_imports(house.imports())
    assert not found, "private names imported from another module:\n" + _show(found)


def test_no_class_holds_more_than_thirty_fields():
    big = [m for m in house.classes() if m.size > house.MAX_FIELDS]
    assert not big, "\n".join(f"{m.where}: {m.size} fields" for m in big)


def test_no_function_is_longer_than_150_lines():
    long = [m for m in house.functions() if m.size > house.MAX_FUNCTION_LINES]
    assert not long, "\n".join(f"{m.where}: {m.size} lines" for m in long)


# ---- the measures measure what they say -------------------------------------------------------

def _parse(source: str) -> ast.ClassDef:
    return ast.parse(textwrap.dedent(source)).body[0]


def test_fields_are_counted_from_assignments_and_annotations():
    cls = _parse("""
        class A:
            LIMIT: int = 3
            name: str
            def __init__(self):
                self.a = 1
                self.b, self.c = 2, 3
            def step(self):
                self.a += 1
                self.d: float = 0.0
                self.e[0] = 1
        """)
    assert house._self_fields(cls) == {"name", "a", "b", "c", "d", "e"}


def test_a_circle_and_a_private_import_are_found():
    edges = [house.Import("runtime.motion.a", "runtime.motion.b", (), 1),
             house.Import("runtime.motion.b", "runtime.motion.a", ("_x",), 2),
             house.Import("runtime.motion.b", "runtime.loop.vm", (), 3)]
    assert house.circles(edges) == [["runtime.motion.a", "runtime.motion.b"]]
    assert [e.line for e in house.private_imports(edges)] == [2]
