"""``irl check``'s motion verification: the program run offline (runtime.loop.offline), its
findings shown as diagnostics at their lines, its cycle time, its moves, and what was
assumed. What the compiler finds is shown by runtime.cli.common; this adds what the runtime
would refuse."""
from __future__ import annotations

from dataclasses import replace

from compiler.diagnostics import Diagnostic, render, source_lines

from runtime.cli.common import Environment, UsageError, say, warn

__all__ = ["MotionCheck", "report"]

#: How a run of the main path ended, as the summary says it.
ENDED = {"completed": "", "stopped": "the program stops with an error (above)",
         "bounded": "the check stopped it at a bound (below): what comes after is not checked", "idles": "the program does not end (below)",
         "waits": "the program does not end: it waits for ever (above)",
         "cannot start": "the program cannot start (above): its moves are not checked"}


class MotionCheck:
    """The motion verification of one compiled program (``result``, a
    compiler.driver.Result with its object code): :meth:`run` runs it; then
    ``diagnostics`` (with ``extras``, what ``--json`` adds to each) and :meth:`summary`."""

    def __init__(self, result, scenario_path: str | None, max_moves: int):
        self.result = result
        self.scenario_path = scenario_path
        self.max_moves = max_moves
        self.outcome = None
        self.diagnostics: list[Diagnostic] = []
        self.extras: list[dict] = []  # per diagnostic

    def run(self) -> None:
        from runtime.loop.offline import check_motion

        scenario = None
        if self.scenario_path is not None:
            from runtime.hardware.backends import load_io_files

            try:
                scenario, _fieldbus = load_io_files(self.scenario_path, None, self.result.spec)
            except ValueError as exc:
                raise UsageError(str(exc)) from None
        if self._cannot_start():
            from runtime.loop.offline import Outcome

            self.outcome = Outcome(ended="cannot start", paths=0)
            return
        self.outcome = check_motion(self.result.program, self.result.spec, scenario, max_moves=self.max_moves)
        for finding in self.outcome.findings:
            diagnostic, extra = self._diagnostic(finding)
            self.diagnostics.append(diagnostic)
            self.extras.append(extra)

    def _cannot_start(self) -> bool:
        """A program whose own world zones the runtime would refuse (one over the home
        position, where every program starts): said at the zone's declaration, and nothing
        else is checked (every move would be refused)."""
        from runtime.motion.kinematics import Kinematics
        from runtime.motion.zonecheck import start_problem

        program, spec = self.result.program, self.result.spec
        if not program.zones:
            return False
        try:
            kinematics = Kinematics(spec)
        except ValueError:
            kinematics = None
        problem = start_problem(spec, kinematics, program.zones)
        if problem is None:
            return False
        name, what = problem
        path, line, column = self._declaration_of(name)
        text = source_lines(self._text(path))
        end = len(text[line - 1].rstrip()) + 1 if 1 <= line <= len(text) else column + 1
        self.diagnostics.append(Diagnostic(path, line, column, line, max(end, column + 1), "error",
                                           f"the program cannot start: {what}"))
        self.extras.append({"motion": True, "kind": "zone", "count": 1, "first": 1, "assumed": []})
        return True

    def _declaration_of(self, zone: str) -> tuple[str, int, int]:
        """(file, line, column) of world zone ``zone``'s declaration (``zone NAME :=``) in the
        program or a module it imports; the program's first line when none is found."""
        import re

        pattern = re.compile(rf"^([ \t]*)zone[ \t]+{re.escape(zone)}[ \t]*:=", re.I | re.M)
        result = self.result
        for path, text in ((result.file, result.source), *result.sources.items()):
            found = pattern.search(text or "")
            if found is not None:
                return path, text.count("\n", 0, found.start()) + 1, len(found.group(1)) + 1
        return result.file, 1, 1

    def _text(self, path: str) -> str | None:
        result = self.result
        return result.source if path == result.file else result.sources.get(path)

    def _diagnostic(self, f) -> tuple[Diagnostic, dict]:
        path = self.result.path_of(f.file)
        lines = source_lines(self._text(path))
        end = f.column + 1
        if 1 <= f.line <= len(lines):  # the statement, to its ';' on this line
            text = lines[f.line - 1]
            stop = text.find(";", f.column - 1)
            end = (stop + 2) if stop >= 0 else len(text.rstrip()) + 1
        message = f.message
        if f.first > 1:
            message = f"the {_ordinal(f.first)} time it runs: {message}"
        if f.count > 1:
            message += f" (and {f.count - 1} more time{'s' if f.count > 2 else ''})"
        diagnostic = Diagnostic(path, f.line, f.column, f.line, max(end, f.column + 1), f.severity, message, f.hint)
        extra = {"motion": True, "kind": f.kind, "count": f.count, "first": f.first,
                 "assumed": list(f.assumed)}
        if f.fraction is not None:
            extra["at"] = {"fraction": f.fraction, "mm": f.distance}
        return diagnostic, extra

    def render(self, diagnostic: Diagnostic, extra: dict) -> str:
        """A motion diagnostic as the compiler's are shown, with the assumption it was found
        under (a branch explored) before its hint."""
        text = render(replace(diagnostic, hint=None), self._text(diagnostic.file))
        if extra["assumed"]:
            text += "\n  when: " + "; then ".join(extra["assumed"])
        if diagnostic.hint:
            text += f"\n  hint: {diagnostic.hint}"
        return text

    # ---- the summary ----
    def assumed(self) -> list[str]:
        """What the check assumed of the world, in words (nothing: it assumed nothing)."""
        if self.scenario_path is not None:
            return [f"the cell of {self.scenario_path}, as irl run --cell-scenario follows it"]
        return list(self.outcome.assumed)

    def summary(self) -> list[str]:
        """The lines ``irl check`` prints after the diagnostics."""
        o = self.outcome
        refused = sum(m.refused for m in o.moves)
        moves = f"{len(o.moves)} move{'s' if len(o.moves) != 1 else ''}" + (f" ({refused} refused)" if refused else "")
        if o.cycle_time is not None:
            cycle = f"cycle time {o.cycle_time:.3f} s"
            if any(f.kind == "move" and not f.assumed for f in o.findings):
                cycle += " (the refused moves taken as reaching their targets)"
        else:
            cycle = f"no cycle time: {ENDED.get(o.ended, o.ended)}"
        lines = [f"motion: {moves}, {cycle}"]
        if o.branches:
            shown = "; ".join(o.branches[:5]) + (f"; and {len(o.branches) - 5} more" if len(o.branches) > 5 else "")
            lines.append(f"branches: {len(o.branches)} more run{'s' if len(o.branches) != 1 else ''} of the program, "
                         f"each another way at one choice: {shown}")
        lines += [f"assumed: {text}" for text in self.assumed()]
        lines += [f"note: {note}" for note in o.notes]
        return lines

    def as_json(self) -> dict:
        o = self.outcome
        result = self.result
        return {
            "cycle_time": o.cycle_time,
            "ended": o.ended,
            "runs": o.paths,
            "assumed": self.assumed(),
            "branches": list(o.branches),
            "notes": list(o.notes),
            "moves": [{"file": result.path_of(m.file), "line": m.line, "column": m.column, "kind": m.kind,
                       "refused": m.refused, "start": m.start, "duration": m.duration, "blended": m.blended,
                       "joints": list(m.joints) if m.joints is not None else None,
                       "configuration": m.configuration} for m in o.moves],
        }


def _ordinal(n: int) -> str:
    return f"{n}{'th' if 10 <= n % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"


def report(env: Environment, result, check: MotionCheck | None, as_json: bool) -> int:
    """Print ``irl check``'s outcome: the compiler's diagnostics, then (``check``) the
    motion's; returns the exit status (1 when there is an error)."""
    import json

    diagnostics = list(result.diagnostics)
    extras: list[dict] = [{"motion": False} for _ in diagnostics]
    if check is not None:
        diagnostics += check.diagnostics
        extras += check.extras
    errors = sum(1 for d in diagnostics if d.severity == "error")
    if as_json:
        say(env, json.dumps({"file": result.file, "ok": errors == 0,
                             "diagnostics": [d.as_json() | e for d, e in zip(diagnostics, extras)],
                             "motion": check.as_json() if check is not None else None}, indent=2))
        return 1 if errors else 0
    if result.diagnostics:
        from compiler.diagnostics import render_all

        warn(env, render_all(result.diagnostics, result.source, result.sources))
    if check is not None:
        for diagnostic, extra in zip(check.diagnostics, check.extras):
            warn(env, check.render(diagnostic, extra))
    warnings = len(diagnostics) - errors
    if errors or warnings:
        counts = [f"{n} {word}{'s' if n != 1 else ''}" for n, word in ((errors, "error"), (warnings, "warning")) if n]
        warn(env, f"{' and '.join(counts)} in {result.file}")
    if not errors:
        bounded = check is not None and check.outcome.ended == "bounded"
        say(env, f"{result.file}: ok as far as the check went: it stopped at a bound (below)" if bounded else
            f"{result.file}: ok")
    if check is not None:
        for line in check.summary():
            say(env, line)
    return 1 if errors else 0


