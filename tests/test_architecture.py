"""The house's rules (docs/architecture.md), measured from the source by tests/house.py: the
import graph is a ladder of layers with no circle, the processes' packages talk over
runtime.wire only, no module takes another's private names, and no class or function
outgrows what one person can hold in mind."""
from __future__ import annotations

import ast
import textwrap

import house


def _show(edges) -> str:
    return "\n".join(f"  {e.source} -> {e.target} (line {e.line}) {', '.join(e.names)}" for e in edges)


def test_every_module_is_in_a_layer():
    missing = []
    for module in house.modules():
        try:
            house.layer(module)
        except KeyError:
            missing.append(module)
    assert not missing, f"modules in no layer of tests/house.py LAYERS: {missing}"


def test_the_imports_make_no_circle():
    found = house.circles(house.imports())
    assert not found, "import circles:\n" + "\n".join("  " + " <-> ".join(c) for c in found)


def test_no_import_runs_up_a_layer():
    found = house.upward(house.imports())
    assert not found, "imports from a lower layer to a higher one (tests/house.py LAYERS):\n" + _show(found)


def test_the_processes_talk_over_the_wire_only():
    found = house.apart(house.imports())
    assert not found, "imports between packages kept apart (tests/house.py APART):\n" + _show(found)


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


def test_a_circle_and_an_upward_import_are_found():
    edges = [house.Import("runtime.motion.a", "runtime.motion.b", (), 1),
             house.Import("runtime.motion.b", "runtime.motion.a", ("_x",), 2),
             house.Import("runtime.motion.b", "runtime.loop.vm", (), 3),
             house.Import("runtime.server.server", "runtime.loop.vm", (), 4)]
    assert house.circles(edges) == [["runtime.motion.a", "runtime.motion.b"]]
    assert [e.line for e in house.upward(edges)] == [3]
    assert [e.line for e in house.apart(edges)] == [4]
    assert [e.line for e in house.private_imports(edges)] == [2]
