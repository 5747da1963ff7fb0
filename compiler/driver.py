"""The compiler's front door: source text or file -> object code, or diagnostics.

``irl check``, ``irl compile``, ``irl dis FILE.irl`` and ``irl run FILE.irl`` all come
through here, so they agree on every diagnostic.
"""
from __future__ import annotations

import gc
import sys
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from .diagnostics import Diagnostic
from .objcode import Program
from .spec import Spec, SpecError, load_spec


@dataclass
class Result:
    """What compiling one file gave: a program, or the diagnostics that stopped it."""

    file: str
    source: str | None
    program: Program | None
    diagnostics: list[Diagnostic]
    spec: Spec | None = None

    @property
    def ok(self) -> bool:
        return self.program is not None and not any(d.severity == "error" for d in self.diagnostics)


def _error(file: str, message: str, span=None, hint=None) -> Diagnostic:
    if span is None:
        return Diagnostic(file, 1, 1, 1, 1, "error", message, hint)
    return Diagnostic(file, span.line, span.col, span.end_line, span.end_col, "error", message, hint)


def resolve_spec(tree, file: str, spec_path: str | Path | None) -> tuple[Spec | None, list[Diagnostic]]:
    """Load the program's system specification (``spec_path`` overrides the program's)."""
    overridden = spec_path is not None
    if spec_path is None:
        if tree.spec is None:
            return None, [_error(file, "the program names no system specification", tree.span,
                                 'add: system_specification "ROBOT.spc"; (or pass --spec FILE.spc)')]
        spec_path = Path(file).parent / tree.spec
    try:
        return load_spec(spec_path), []
    except SpecError as exc:
        span = tree.spec_span if tree.spec is not None and not overridden else None
        return None, [_error(file, f"system specification: {exc}", span)]


@contextmanager
def _no_cyclic_gc():
    """Pause the cyclic garbage collector: a compile allocates a large, cycle-free AST
    that the collector would otherwise scan again and again (reference counting still
    frees everything)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def compile_source(source: str, file: str = "<input>", spec_path: str | Path | None = None,
                   generate_code: bool = True) -> Result:
    """Parse, check and (unless ``generate_code`` is false) generate object code."""
    with _no_cyclic_gc():
        return _compile(source, file, spec_path, generate_code)


#: How deeply a program may nest (expressions, statements) before it is refused; the
#: checker and code generator recurse once or twice per level.
MAX_NESTING = 4000


def _compile(source: str, file: str, spec_path, generate_code: bool) -> Result:
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 3 * MAX_NESTING))
    try:
        return _compile_nested(source, file, spec_path, generate_code)
    except RecursionError:
        return Result(file, source, None, [_error(
            file, f"the program nests too deeply (more than about {MAX_NESTING} levels of expressions "
                  f"or statements)", hint="split long expressions with intermediate variables")])
    finally:
        sys.setrecursionlimit(limit)


def _compile_nested(source: str, file: str, spec_path, generate_code: bool) -> Result:
    from .check import check
    from .codegen import generate
    from .syntax import parse_recovering

    tree, syntax_errors = parse_recovering(source, file)
    if tree is None:
        return Result(file, source, None, syntax_errors)
    spec, diagnostics = resolve_spec(tree, file, spec_path)
    if spec is None:
        return Result(file, source, None, syntax_errors + diagnostics)
    checked, diagnostics = check(tree, spec, file)
    diagnostics = syntax_errors + diagnostics
    if diagnostics:
        diagnostics.sort(key=lambda d: (d.line, d.column))
        return Result(file, source, None, diagnostics, spec)
    program = generate(checked, file) if generate_code else None
    return Result(file, source, program, [], spec)


def read_source(path: str | Path) -> str:
    """The text of a source file; OSError and UnicodeDecodeError pass to the caller."""
    return Path(path).read_text(encoding="utf-8")


def compile_file(path: str | Path, spec_path: str | Path | None = None, generate_code: bool = True) -> Result:
    path = Path(path)
    return compile_source(read_source(path), str(path), spec_path, generate_code)
