"""Diagnostics: what is wrong, where, and how to fix it; rendered like a C compiler's."""
from __future__ import annotations

import difflib
from dataclasses import asdict, dataclass


@dataclass(frozen=True, slots=True)
class Diagnostic:
    """One finding. Lines and columns are 1-based; ``end_col`` is exclusive."""

    file: str
    line: int
    column: int
    end_line: int
    end_column: int
    severity: str  # "error" or "warning"
    message: str
    hint: str | None = None

    def as_json(self) -> dict:
        data = asdict(self)
        data["end"] = {"line": data.pop("end_line"), "column": data.pop("end_column")}
        return data


class CompileError(Exception):
    """Raised by the compiler's entry points when a program has errors."""

    def __init__(self, diagnostics: list[Diagnostic]):
        super().__init__(f"{len(diagnostics)} error(s)")
        self.diagnostics = diagnostics


def did_you_mean(word: str, candidates, cutoff: float = 0.6) -> str | None:
    """The closest candidate to a misspelled ``word``, or None."""
    matches = difflib.get_close_matches(word.lower(), list(candidates), n=1, cutoff=cutoff)
    return matches[0] if matches else None


def render(diagnostic: Diagnostic, source: str | None) -> str:
    """``file:line:col: error: message``, then the source line and a caret under the span."""
    return _render(diagnostic, source_lines(source))


def source_lines(source: str | None) -> list[str]:
    """The lines of ``source`` as diagnostics number them. Split at "\n" only, as the
    parser counts lines (splitlines() also breaks at form feeds and other characters
    that are plain white space in L-IRL)."""
    return source.split("\n") if source is not None else []


def _render(d: Diagnostic, lines: list[str]) -> str:
    out = [f"{d.file}:{d.line}:{d.column}: {d.severity}: {d.message}"]
    if 1 <= d.line <= len(lines):
        text = lines[d.line - 1].rstrip("\r").expandtabs(1)
        width = (d.end_column - d.column) if d.end_line == d.line else len(text) - d.column + 1
        width = max(1, min(width, len(text) - d.column + 1))
        out.append(f"  {text}")
        out.append("  " + " " * (d.column - 1) + "^" + "~" * (width - 1))
    if d.hint:
        out.append(f"  hint: {d.hint}")
    return "\n".join(out)


def render_all(diagnostics, source: str | None, others: dict | None = None) -> str:
    """Every diagnostic rendered, in order, with its line from ``source`` (the program's),
    or from ``others`` (file -> text: the modules') for a diagnostic in another file. Each
    text is split into lines once, so the time is linear in the diagnostics and the texts."""
    lines = source_lines(source)
    split = {file: source_lines(text) for file, text in (others or {}).items()}
    return "\n".join(_render(d, split.get(d.file, lines)) for d in diagnostics)
