"""Golden-file tests: the disassembly of every example program, and the diagnostics of
every invalid program in tests/diagnostics/.

* ``programs/<name>.irl``          -> ``tests/golden/<name>.dis``: exactly the stdout of
  ``irl dis programs/<name>.irl`` run from the repository root.
* ``tests/diagnostics/<name>.irl`` -> ``tests/diagnostics/<name>.err``: exactly the stderr of
  ``irl check tests/diagnostics/<name>.irl`` run from the repository root (exit status 1).

The programs are found by glob, so a new program is tested as soon as it is added; one
without a golden file fails (it is not skipped). To (re)write the golden files after an
intended change, run

    IRL_UPDATE_GOLDEN=1 .venv/bin/pytest -q tests/test_golden.py

and review the diff before committing it.
"""
from __future__ import annotations

import io
import os
from pathlib import Path

import pytest

from runtime.cli.main import Environment, main

from conftest import ROOT, PROGRAMS
GOLDEN = ROOT / "tests" / "golden"
DIAGNOSTICS = ROOT / "tests" / "diagnostics"

UPDATE = os.environ.get("IRL_UPDATE_GOLDEN") == "1"
UPDATE_HOW = "run with IRL_UPDATE_GOLDEN=1 to write it, then review the diff"

PROGRAM_NAMES = sorted(p.stem for p in PROGRAMS.glob("*.irl"))
DIAGNOSTIC_NAMES = sorted(p.stem for p in DIAGNOSTICS.glob("*.irl"))


def run_cli(argv: list[str], monkeypatch) -> tuple[int, str, str]:
    """Run ``irl ARGV`` in-process from the repository root: (status, stdout, stderr)."""
    monkeypatch.chdir(ROOT)
    env = Environment(stdout=io.StringIO(), stderr=io.StringIO())
    status = main(argv, env)
    return status, env.stdout.getvalue(), env.stderr.getvalue()


def read_text(path: Path) -> str:
    return path.read_bytes().decode("utf-8")  # no newline translation


def check_golden(path: Path, actual: str) -> None:
    """Compare ``actual`` with the golden file, or rewrite it under IRL_UPDATE_GOLDEN=1."""
    if UPDATE:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(actual.encode("utf-8"))
        return
    rel = path.relative_to(ROOT)
    if not path.exists():
        pytest.fail(f"golden file {rel} is missing; {UPDATE_HOW}")
    expected = read_text(path)
    assert actual == expected, f"output differs from {rel}; if the change is intended, {UPDATE_HOW}"


def assert_no_crash(stdout: str, stderr: str) -> None:
    for text in (stdout, stderr):
        assert "Traceback" not in text
        assert "internal error" not in text


# ---- example programs: golden disassembly -------------------------------------------------

def test_programs_are_found():
    assert "test" in PROGRAM_NAMES, f"no programs found by {PROGRAMS}/*.irl"
    assert len(PROGRAM_NAMES) >= 8


@pytest.mark.parametrize("name", PROGRAM_NAMES)
def test_disassembly(name, monkeypatch):
    status, stdout, stderr = run_cli(["dis", f"programs/{name}.irl"], monkeypatch)
    assert_no_crash(stdout, stderr)
    assert status == 0, f"irl dis programs/{name}.irl failed:\n{stderr}"
    assert stderr == ""
    check_golden(GOLDEN / f"{name}.dis", stdout)


@pytest.mark.parametrize("name", PROGRAM_NAMES)
def test_program_checks(name, monkeypatch):
    """The compiler's checks (the motion check of every shipped program: tests/test_motion_check.py)."""
    status, stdout, stderr = run_cli(["check", "--no-motion", f"programs/{name}.irl"], monkeypatch)
    assert_no_crash(stdout, stderr)
    assert status == 0, stderr
    assert stdout == f"programs/{name}.irl: ok\n"


@pytest.mark.parametrize("name", [n for n in PROGRAM_NAMES if n != "test"])
def test_example_program_conventions(name):
    """Each example explains itself in a header comment and names the Lola 15's spec (or
    the Lola 15 in its cell: the same arm with the cell's frames and tools)."""
    text = read_text(PROGRAMS / f"{name}.irl")
    assert text.lstrip().startswith(("{", "(*", "--")), f"{name}.irl has no header comment"
    assert 'system_specification "lola15.spc";' in text or 'system_specification "lola15_cell.spc";' in text


def test_no_stale_golden_files():
    if UPDATE:
        pytest.skip("updating golden files")
    stale = sorted(p.name for p in GOLDEN.glob("*.dis") if p.stem not in PROGRAM_NAMES)
    assert not stale, f"golden files without a program in programs/: {stale}"


# ---- invalid programs: golden diagnostics -------------------------------------------------

def test_diagnostic_cases_are_found():
    assert len(DIAGNOSTIC_NAMES) >= 15, f"too few cases in {DIAGNOSTICS}"
    assert "paper_unmended" in DIAGNOSTIC_NAMES


@pytest.mark.parametrize("name", DIAGNOSTIC_NAMES)
def test_diagnostics(name, monkeypatch):
    status, stdout, stderr = run_cli(["check", f"tests/diagnostics/{name}.irl"], monkeypatch)
    assert_no_crash(stdout, stderr)
    assert status == 1, f"expected exit status 1, got {status}:\n{stderr}"
    assert stdout == ""
    assert f"tests/diagnostics/{name}.irl:" in stderr
    check_golden(DIAGNOSTICS / f"{name}.err", stderr)


def test_no_stale_diagnostic_files():
    if UPDATE:
        pytest.skip("updating golden files")
    stale = sorted(p.name for p in DIAGNOSTICS.glob("*.err") if p.stem not in DIAGNOSTIC_NAMES)
    assert not stale, f".err files without a program in tests/diagnostics/: {stale}"


def test_paper_unmended_points_at_the_typos(monkeypatch):
    """The paper's Figure 5, as printed: its typos are found at their lines, with hints.

    Independent of the golden file, so regenerating it cannot lose these properties.
    """
    status, _, stderr = run_cli(["check", "tests/diagnostics/paper_unmended.irl"], monkeypatch)
    assert status == 1
    lines = stderr.splitlines()
    file = "tests/diagnostics/paper_unmended.irl"
    speed = [i for i, line in enumerate(lines) if line.startswith(f"{file}:5:")]
    endseg = [i for i, line in enumerate(lines) if line.startswith(f"{file}:7:1:")]
    assert speed, stderr
    assert endseg, stderr
    assert any("hint: did you mean 'speed_ptp'?" in line for line in lines[speed[0]:endseg[0]]), stderr
    assert "hint: did you mean 'endseq'?" in "\n".join(lines[endseg[0]:]), stderr
    assert "'endseg'" in lines[endseg[0]]


def test_paper_unmended_is_the_papers_text():
    text = read_text(DIAGNOSTICS / "paper_unmended.irl")
    for typo in ("speed ptp:=0.1", "acc ptp:= 0.1", 'act_rob:="lola 15"', "\nendseg\n"):
        assert typo in text
