"""What every ``irl`` command shares: its environment, exit statuses, usage errors, output,
reading and compiling a source, and the formats of values both halves of the command line print.
"""
from __future__ import annotations

import shlex
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

EXIT_OK, EXIT_INVALID, EXIT_USAGE, EXIT_INTERNAL = 0, 1, 2, 70


@dataclass
class Environment:
    """Where the command reads and writes; tests pass their own to run it in-process."""

    stdout: TextIO = field(default_factory=lambda: sys.stdout)
    stderr: TextIO = field(default_factory=lambda: sys.stderr)
    stdin: TextIO = field(default_factory=lambda: sys.stdin)


class UsageError(Exception):
    """A bad command line or an unreadable file: exit status 2."""


def joint_values(values) -> str:
    """Joint values as a summary shows them: to 0.001, comma-separated, no "-0.000" (an axis
    resting a hair below zero is at 0.000 as far as a reader can tell)."""
    return ", ".join(f"{round(x, 3) + 0.0:.3f}" for x in values)


def say(env: Environment, text: str = "") -> None:
    env.stdout.write(text + "\n")


def warn(env: Environment, text: str) -> None:
    env.stderr.write(text + "\n")


def compile_source(path: str, spec: str | None, generate_code: bool = True):
    from compiler.driver import compile_file

    try:
        return compile_file(path, spec, generate_code)
    except FileNotFoundError:
        raise UsageError(f"cannot read {path}: no such file") from None
    except IsADirectoryError:
        raise UsageError(f"cannot read {path}: it is a directory") from None
    except UnicodeDecodeError:
        raise UsageError(f"cannot read {path}: not a UTF-8 text file") from None
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror or exc}") from None


def report_diagnostics(env: Environment, result, as_json: bool) -> None:
    if as_json:
        import json

        say(env, json.dumps([d.as_json() for d in result.diagnostics], indent=2))
    elif result.diagnostics:
        from compiler.diagnostics import render_all

        warn(env, render_all(result.diagnostics, result.source, result.sources))
        errors = sum(1 for d in result.diagnostics if d.severity == "error")
        counts = [f"{n} {word}{'s' if n != 1 else ''}" for n, word in
                  ((errors, "error"), (len(result.diagnostics) - errors, "warning")) if n]
        warn(env, f"{' and '.join(counts)} in {result.file}")


def read_object(path: str) -> bytes:
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise UsageError(f"cannot read {path}: no such file") from None
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror or exc}") from None


#: At most this many specification files beside an object file are read to find the one
#: it was compiled for (each at most compiler.spec.MAX_SPEC_BYTES).
MAX_SPEC_CANDIDATES = 64


def spec_compiled_for(program, object_path: Path) -> tuple[str | None, str | None]:
    """Not real-time: (the specification file ``program`` was compiled for, its source
    file), each where it can be found beside the object file ``object_path``, else None:
    a ``.spc`` file there whose hash is the one the object code names; the source the
    object code names, if it is there."""
    from compiler.spec import SpecError, load_spec

    folder = object_path.parent
    source = None
    if program.source and Path(program.source).name == program.source:  # (a name, no path: untrusted)
        candidate = folder / program.source
        if candidate.is_file():
            source = shlex.quote(str(candidate))
    try:
        files = sorted(p for p in folder.glob("*.spc") if p.is_file())[:MAX_SPEC_CANDIDATES]
    except OSError:
        files = []
    for file in files:
        try:
            if load_spec(file).hash == program.spec_hash:
                return str(file), source
        except SpecError:
            continue
    return None, source


def log_line(at: float, line: int, text: str) -> str:
    """One line of a program's ``print`` output, as ``irl run`` and ``irl submit --wait`` show it."""
    return f"  [{at:8.3f} s] line {line}: {text}"


def add_cell_scenario(p, what: str) -> None:
    """``--cell-scenario FILE.toml`` (irl check, irl run, irl serve): ``what`` the cell does there."""
    p.add_argument("--cell-scenario", metavar="FILE.toml", help=what)


def add_deadline_policy(p) -> None:
    """``--deadline-policy`` (irl run, irl serve): the servo's miss policy, the choices as
    compiler.params declares them."""
    from compiler.params import section_params

    param = section_params("controller")["servo_miss_policy"]
    p.add_argument("--deadline-policy", choices=param.choices, default=None,
                   help=f"what missed 1 ms deadlines do on the wall clock: hard (one faults), firm (too many "
                        f"within a window fault), soft (counted only); default: the specification's "
                        f"controller.servo_miss_policy ({param.default})")
