"""The house's shape, measured from the source: import circles and private names imported
across modules (the layers and the processes kept apart are import-linter's contracts in
pyproject.toml), the fields of every class and the length of every function.
``tests/test_architecture.py`` holds the limits; ``python tests/house.py`` prints the
figures (docs/architecture.md).
"""
from __future__ import annotations

import ast
import functools
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("grammar", "compiler", "runtime")

#: compiled modules that stand for a source module (setup.py builds runtime/_kernels_c from
#: runtime/kernels.py)
COMPILED = ("runtime._kernels_c",)

MAX_FIELDS = 30
MAX_FUNCTION_LINES = 150


def modules() -> dict[str, Path]:
    """Every source module of the packages, by its dotted name."""
    found: dict[str, Path] = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


@functools.lru_cache(maxsize=None)
def tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"))


@dataclass(frozen=True)
class Import:
    source: str
    target: str
    names: tuple[str, ...]
    line: int


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    if node.level > 1:
        base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports(known: dict[str, Path] | None = None) -> list[Import]:
    """Every import of one project module by another, lazy ones (inside functions) included."""
    known = known if known is not None else modules()
    found: list[Import] = []

    def owner(name: str) -> str | None:
        while name and name not in known:
            name = name.rpartition(".")[0]
        return name or None

    for module, path in known.items():
        module_tree = tree(path)
        is_package = path.name == "__init__.py"
        for node in ast.walk(module_tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    target = owner(alias.name)
                    if target and target != module:
                        found.append(Import(module, target, (), node.lineno))
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(module, is_package, node)
                for alias in node.names:
                    full = f"{base}.{alias.name}" if base else alias.name
                    if full in COMPILED:
                        continue
                    if full in known:  # a submodule: `from . import protocol`
                        if full != module:
                            found.append(Import(module, full, (), node.lineno))
                        continue
                    target = owner(base)
                    if target and target != module:
                        found.append(Import(module, target, (alias.name,), node.lineno))
    return found


def circles(edges: list[Import]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    graph: dict[str, set[str]] = {}
    for edge in edges:
        graph.setdefault(edge.source, set()).add(edge.target)
        graph.setdefault(edge.target, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(graph[node]):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def private_imports(edges: list[Import]) -> list[Import]:
    """Private names (``_name``) one module takes from another."""
    return [e for e in edges if any(n.startswith("_") and not n.startswith("__") for n in e.names)]


@dataclass(frozen=True)
class Measure:
    where: str  # "path:line name"
    size: int


def _self_fields(cls: ast.ClassDef) -> set[str]:
    fields: set[str] = set()
    for node in cls.body:  # class-level annotations: dataclass fields
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) \
                and not node.target.id.isupper():  # (a constant of the class is no field)
            fields.add(node.target.id)
        if isinstance(node, ast.Assign):
            for target in node.targets:
                if isinstance(target, ast.Name) and target.id == "__slots__" and isinstance(
                        node.value, (ast.Tuple, ast.List)):
                    fields.update(e.value for e in node.value.elts if isinstance(e, ast.Constant))
    for node in ast.walk(cls):
        targets: list[ast.expr] = []
        if isinstance(node, ast.Assign):
            targets = list(node.targets)
        elif isinstance(node, (ast.AnnAssign, ast.AugAssign)):
            targets = [node.target]
        for target in targets:
            for sub in ast.walk(target):
                if (isinstance(sub, ast.Attribute) and isinstance(sub.value, ast.Name)
                        and sub.value.id == "self"):
                    fields.add(sub.attr)
    return fields


def classes() -> list[Measure]:
    """Every class with its number of fields (instance attributes and dataclass fields)."""
    found = []
    for module, path in modules().items():
        for node in ast.walk(tree(path)):
            if isinstance(node, ast.ClassDef):
                found.append(Measure(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}",
                                     len(_self_fields(node))))
    return sorted(found, key=lambda m: -m.size)


def functions() -> list[Measure]:
    """Every function with its number of lines."""
    found = []
    for module, path in modules().items():
        for node in ast.walk(tree(path)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                found.append(Measure(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}",
                                     node.end_lineno - node.lineno + 1))
    return sorted(found, key=lambda m: -m.size)


def main() -> int:
    edges = imports()
    print(f"modules: {len(modules())}, imports between them: {len({(e.source, e.target) for e in edges})}")
    found = circles(edges)
    print(f"circles: {len(found)}")
    for component in found:
        print("   ", " <-> ".join(component))
    privates = private_imports(edges)
    print(f"private names imported across modules: {len(privates)}")
    for e in privates:
        print(f"    {e.source} -> {e.target}: {', '.join(e.names)}")
    big = [m for m in classes() if m.size > MAX_FIELDS]
    print(f"classes over {MAX_FIELDS} fields: {len(big)}; largest: "
          + ", ".join(f"{m.where} {m.size}" for m in classes()[:6]))
    long = [m for m in functions() if m.size > MAX_FUNCTION_LINES]
    print(f"functions over {MAX_FUNCTION_LINES} lines: {len(long)}; longest: "
          + ", ".join(f"{m.where} {m.size}" for m in functions()[:6]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
