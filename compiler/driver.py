"""The compiler's front door: source text or file -> object code, or diagnostics.

``irl check``, ``irl compile``, ``irl dis FILE.irl`` and ``irl run FILE.irl`` all come
through here, so they agree on every diagnostic.
"""
from __future__ import annotations

import gc
import sys
from contextlib import contextmanager
import os
from dataclasses import dataclass, field
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
    modules: dict = field(default_factory=dict)  # a module's name in the object code -> its text
    sources: dict = field(default_factory=dict)  # a module's path (as diagnostics name it) -> its text

    module_files: dict = field(default_factory=dict)  # a module's name in the object code -> its path

    def path_of(self, name: str) -> str:
        """The file a diagnostic names for a file of the object code (``Program.file_at``:
        "" for the program's own source, else a module's name in the object code)."""
        return self.module_files.get(name, name) if name else self.file

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
    from .syntax import parse_recovering

    from . import ast

    tree, syntax_errors = parse_recovering(source, file)
    if tree is None:
        return Result(file, source, None, syntax_errors)
    if isinstance(tree, ast.Module):
        return Result(file, source, None, [_error(
            file, f"'{tree.name}' is a module: it is not compiled or run by itself", tree.span,
            f'import it from a program: import "{Path(file).name}";')])
    modules, module_errors, sources, sees = load_modules(tree, file)
    if module_errors:  # (checking without a module's declarations would only cascade)
        module_errors.sort(key=lambda d: (d.file != file, d.file, d.line, d.column))
        return Result(file, source, None, syntax_errors + module_errors, sources=sources)
    spec, diagnostics = resolve_spec(tree, file, spec_path)
    if spec is None:
        return Result(file, source, None, syntax_errors + module_errors + diagnostics)
    decl_files = {id(decl): path for path, (_name, _text, module) in modules.items() for decl in module.decls}
    merged = ast.replace(tree, decls=tuple(d for _name, _text, m in modules.values() for d in m.decls) + tree.decls)
    checked, diagnostics = check(merged, spec, file, decl_files, sees)
    checked.modules = {path: name for path, (name, _text, _m) in modules.items()}
    texts = {name: text for name, text, _m in modules.values()}
    files = {name: path for path, (name, _text, _m) in modules.items()}
    diagnostics = syntax_errors + module_errors + diagnostics
    diagnostics.sort(key=lambda d: (d.file != file, d.file, d.line, d.column))
    if any(d.severity == "error" for d in diagnostics):
        return Result(file, source, None, diagnostics, spec, texts, sources)
    # (warnings only: the program is made, and they go with it)
    if not generate_code:  # (irl check: the code generator is not even imported)
        return Result(file, source, None, diagnostics, spec, texts, sources, files)
    from .codegen import generate

    return Result(file, source, generate(checked, file), diagnostics, spec, texts, sources, files)


def load_modules(tree, file: str) -> tuple[dict, list[Diagnostic], dict, dict]:
    """Every module ``tree`` imports, directly or through other modules, each once, in the
    order their declarations come (a module's imports before it): {path: (name in the
    object code, text, Module)}; the diagnostics of those that could not be read; the text
    of every module read (for showing a diagnostic's line); and, per module path, the
    module paths its code may use (itself and what it imports, directly or not)."""
    from . import ast
    from .syntax import parse_recovering

    base = Path(file).parent
    modules: dict = {}
    texts: dict = {}
    sees: dict = {}
    diagnostics: list[Diagnostic] = []
    done: dict = {}  # resolved path -> its module path (None: it could not be loaded)

    def visit(importer: str, imports, chain: tuple) -> set:
        seen: set = set()
        for imp in imports:
            path = Path(importer).parent / imp.path
            try:
                key = os.path.realpath(path)
                is_file = path.is_file()  # (a directory, a device such as /dev/zero: never read)
            except (OSError, ValueError) as exc:  # a NUL byte, a name too long, a symlink loop
                reason = "the file name contains a NUL byte" if isinstance(exc, ValueError) else \
                    (exc.strerror or str(exc)).lower()
                diagnostics.append(_error(importer, f"cannot read module '{imp.path[:200]}': {reason}", imp.span))
                continue
            if key in chain:
                what = "the program" if key == chain[0] else "a module that imports it"
                names = " -> ".join([Path(k).name for k in chain] + [Path(key).name])
                diagnostics.append(_error(importer, f"'{imp.path}' is {what}: the imports go round in a circle "
                                                    f"({names})", imp.span))
                continue
            if key in done:
                if done[key] is not None:
                    seen |= {done[key]} | sees[done[key]]
                continue
            done[key] = None
            if not is_file:
                diagnostics.append(_error(importer, f"cannot read module '{imp.path}': "
                                                    f"{'no such file' if not path.exists() else 'not a file'}",
                                          imp.span))
                continue
            try:
                text = read_source(path)
            except UnicodeDecodeError:
                diagnostics.append(_error(importer, f"cannot read module '{imp.path}': it is not UTF-8 text",
                                          imp.span))
                continue
            except OSError as exc:
                diagnostics.append(_error(importer, f"cannot read module '{imp.path}': {exc.strerror or exc}",
                                          imp.span))
                continue
            texts[str(path)] = text
            module, errors = parse_recovering(text, str(path))
            diagnostics.extend(errors)
            if module is None:
                continue
            if not isinstance(module, ast.Module):
                diagnostics.append(_error(importer, f"'{imp.path}' is a program, not a module", imp.span,
                                          "a module starts with 'module NAME;' and has no seq ... endseq"))
                continue
            sees[str(path)] = visit(str(path), module.imports, chain + (key,))
            done[key] = str(path)
            seen |= {str(path)} | sees[str(path)]
            modules[str(path)] = (Path(os.path.relpath(path, base)).as_posix(), text, module)
        return seen
    visit(file, tree.imports, (os.path.realpath(file),))
    return modules, diagnostics, texts, sees


def read_source(path: str | Path) -> str:
    """The text of a source file; OSError and UnicodeDecodeError pass to the caller."""
    return Path(path).read_text(encoding="utf-8")


def compile_file(path: str | Path, spec_path: str | Path | None = None, generate_code: bool = True) -> Result:
    path = Path(path)
    return compile_source(read_source(path), str(path), spec_path, generate_code)
