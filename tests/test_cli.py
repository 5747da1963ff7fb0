"""The ``irl`` command, run in-process through ``runtime.cli.main.main(argv, env)``.

Exit status: 0 ok, 1 invalid program or object file, 2 usage or file error, 70 a bug.
"""
from __future__ import annotations

import io
import json
import re
import shutil
import subprocess
import sys
import zlib
from pathlib import Path

import pytest

from compiler.disasm import instructions
from compiler.objcode import BY_NAME, FORMAT_VERSION, decode, load
from compiler.spec import load_spec
from runtime.cli.main import NOT_FOR_CHECKING, Environment, main

from conftest import ROOT, TEST_IRL, SPEC_PATH as SPEC, run_cli as run
DIAG = re.compile(r"^(?P<file>\S+):(?P<line>\d+):(?P<col>\d+): error: (?P<msg>.+)$")

HEAD = 'program p;\nsystem_specification "lola15.spc";\n'
VALID = HEAD + "var x : real;\nseq\n  x := 1.5;\n  print x;\nendseq\nendprogram;\n"
INVALID = HEAD + "var x : real;\nseq\n  x := y + 1;\nendseq\nendprogram;\n"


def no_crash(err: str) -> None:
    assert "Traceback" not in err
    assert "internal error" not in err


@pytest.fixture
def work(tmp_path: Path) -> Path:
    """A directory holding the robot's specification, test.irl and the VALID/INVALID programs."""
    shutil.copy(SPEC, tmp_path / "lola15.spc")
    shutil.copy(TEST_IRL, tmp_path / "test.irl")
    (tmp_path / "valid.irl").write_text(VALID, encoding="utf-8")
    (tmp_path / "invalid.irl").write_text(INVALID, encoding="utf-8")
    return tmp_path


# ---- check ---------------------------------------------------------------------------------

def test_check_ok(work):
    code, out, err = run("check", work / "valid.irl")
    assert code == 0
    assert out.splitlines()[0] == f"{work / 'valid.irl'}: ok"
    assert out.splitlines()[1].startswith("motion: 0 moves, cycle time ")  # (the motion check: no move)
    assert err == ""
    code, out, err = run("check", "--no-motion", work / "valid.irl")
    assert (code, out.strip(), err) == (0, f"{work / 'valid.irl'}: ok", "")


def test_check_invalid_renders_diagnostics(work):
    path = work / "invalid.irl"
    code, out, err = run("check", path)
    assert code == 1
    assert out == ""
    no_crash(err)
    lines = err.splitlines()
    m = DIAG.match(lines[0])
    assert m, lines[0]
    assert m["file"] == str(path)
    assert (int(m["line"]), int(m["col"])) == (5, 8)
    assert "undeclared name 'y'" in m["msg"]
    assert lines[1] == "    x := y + 1;"  # the source line, indented by two
    assert re.fullmatch(r" *\^~*", lines[2])
    assert lines[2].index("^") == lines[1].index("y")  # the caret is under the error
    assert lines[-1] == f"1 error in {path}"


def test_check_reports_several_errors(work):
    path = work / "multi.irl"
    path.write_text(HEAD + "var x : real;\nseq\n  x := y;\n  x := \"s\";\n  z := 1;\nendseq\nendprogram;\n",
                    encoding="utf-8")
    code, _, err = run("check", path)
    assert code == 1
    found = [DIAG.match(line) for line in err.splitlines() if DIAG.match(line)]
    assert [int(m["line"]) for m in found] == [5, 6, 7]
    assert err.splitlines()[-1] == f"3 errors in {path}"


def test_check_syntax_error(work):
    path = work / "syntax.irl"
    path.write_text(HEAD + "var x : real;\nseq\n  x := 1\n  pause;\nendseq\nendprogram;\n", encoding="utf-8")
    code, _, err = run("check", path)
    assert code == 1
    no_crash(err)
    lines = err.splitlines()
    m = DIAG.match(lines[0])
    assert m and (int(m["line"]), int(m["col"])) == (5, 9)
    assert m["msg"] == "expected ';' after '1'"
    assert lines[1] == "    x := 1"
    assert lines[2] == "          ^"


def test_check_json_valid_program_has_no_diagnostics(work):
    code, out, err = run("check", "--json", work / "valid.irl")
    assert code == 0 and err == ""
    data = json.loads(out)
    assert data["ok"] is True and data["diagnostics"] == [] and data["file"] == str(work / "valid.irl")
    assert data["motion"]["moves"] == [] and data["motion"]["runs"] == 1
    code, out, err = run("check", "--json", "--no-motion", work / "valid.irl")
    assert code == 0 and json.loads(out) == {"file": str(work / "valid.irl"), "ok": True, "diagnostics": [],
                                             "motion": None}


def test_check_json_invalid_program(work):
    path = work / "invalid.irl"
    code, out, err = run("check", "--json", path)
    assert code == 1
    assert err == ""
    data = json.loads(out)
    assert data["ok"] is False and data["motion"] is None  # (a program with errors does not run)
    [d] = data["diagnostics"]
    assert set(d) == {"file", "line", "column", "end", "severity", "message", "hint", "motion"}
    assert d["motion"] is False
    assert d["file"] == str(path)
    assert (d["line"], d["column"]) == (5, 8)
    assert d["end"] == {"line": 5, "column": 9}
    assert d["severity"] == "error"
    assert "undeclared name 'y'" in d["message"]
    assert d["hint"] is None or isinstance(d["hint"], str)


def test_check_json_hint(work):
    path = work / "hint.irl"
    path.write_text(HEAD + "var speed_val : real;\nseq\n  speed_vla := 1;\nendseq\nendprogram;\n", encoding="utf-8")
    code, out, _ = run("check", "--json", path)
    assert code == 1
    [d] = json.loads(out)["diagnostics"]
    assert "speed_val" in d["hint"]


# ---- compile -------------------------------------------------------------------------------

def test_compile_default_output_beside_the_source(work):
    code, out, err = run("compile", work / "test.irl")
    assert code == 0, err
    target = work / "test.irlo"
    assert target.is_file()
    data = target.read_bytes()
    assert str(target) in out and f"{len(data)} bytes" in out
    program = load(data, spec_hash=load_spec(work / "lola15.spc").hash)
    assert program.name == "test"
    assert [name for name in (i.name for i in instructions(program))].count("MOVE_PTP") == 3
    assert not list(work.glob(".*.tmp"))  # the atomic write left nothing behind


def test_compile_output_option(work):
    assert run("compile", work / "test.irl")[0] == 0
    out_dir = work / "out"
    out_dir.mkdir()
    for option in ("-o", "--output"):
        target = out_dir / f"x{option}.bin"
        code, out, err = run("compile", work / "test.irl", option, target)
        assert code == 0, err
        assert target.read_bytes() == (work / "test.irlo").read_bytes()


def test_compile_json(work):
    code, out, err = run("compile", "--json", work / "valid.irl", "-o", work / "v.irlo")
    assert code == 0 and json.loads(out) == [] and err == ""
    load((work / "v.irlo").read_bytes())
    code, out, err = run("compile", "--json", work / "invalid.irl", "-o", work / "i.irlo")
    assert code == 1 and len(json.loads(out)) == 1
    assert not (work / "i.irlo").exists()


def test_compile_invalid_writes_nothing(work):
    code, _, err = run("compile", work / "invalid.irl")
    assert code == 1
    assert DIAG.match(err.splitlines()[0])
    assert not (work / "invalid.irlo").exists()


def test_compile_to_unwritable_path(work):
    code, out, err = run("compile", work / "test.irl", "-o", work / "no" / "such" / "dir" / "x.irlo")
    assert code == 2
    no_crash(err)
    assert err.startswith("irl: cannot write")


# ---- dis -----------------------------------------------------------------------------------

CODE_LINE = re.compile(r"^(?P<line>[ \d]{6}) (?P<jump>>>|  )(?P<offset>[ \d]{5})  (?P<name>[A-Z_]+)"
                       r"(?: +(?P<operands>-?\d+(?: -?\d+)*))?(?: +\((?P<argrepr>.*)\))?$")


def parse_listing(text: str) -> tuple[dict, list[dict]]:
    header, code = {}, []
    for line in text.splitlines():
        m = re.match(r"^(program|source|format|specification|robots|checksum) +(.*)$", line)
        if m and not code:
            header[m[1]] = m[2]
        m = CODE_LINE.match(line)
        if m:
            code.append({"line": m["line"].strip(), "offset": int(m["offset"]), "name": m["name"],
                         "operands": [int(x) for x in (m["operands"] or "").split()], "argrepr": m["argrepr"],
                         "jump": m["jump"] == ">>"})
    return header, code


def test_dis_object_file(work):
    assert run("compile", work / "test.irl")[0] == 0
    data = (work / "test.irlo").read_bytes()
    program = decode(data)
    spec = load_spec(work / "lola15.spc")
    code, out, err = run("dis", work / "test.irlo")
    assert code == 0, err
    assert err == ""
    header, listing = parse_listing(out)
    assert header["format"] == str(FORMAT_VERSION)
    assert header["program"] == "test"
    assert header["specification"] == f"{spec.name} sha256:{spec.hash[:16]}"
    assert header["robots"] == "lola_15"
    assert header["checksum"] == f"crc32:{zlib.crc32(data[10:]):08x} ({len(data)} bytes)"
    # one listing line per instruction, with its offset, name and operands
    assert [c["offset"] for c in listing] == list(range(len(program.code)))
    for entry, instr in zip(listing, program.code):
        assert BY_NAME[entry["name"]].code == instr[0]
        assert entry["operands"] == list(instr[1:])
    # resolved values and line numbers of the paper's program
    first = listing[0]
    assert first["name"] == "CONST" and first["line"] == "4"
    assert first["argrepr"] == "joint(mainjoint(45, 0, -45, 0, 0, 0))"
    moves = [c for c in listing if c["name"] == "MOVE_PTP"]
    assert len(moves) == 3 and all(c["argrepr"] == "speed_ptp, acc_ptp, act_rob" for c in moves)
    assert any(c["argrepr"] == '"lola_15"' for c in listing)
    assert [c["line"] for c in listing if c["line"]] == ["4", "5", "6", "8"]
    assert listing[-1]["name"] == "END" and listing[-1]["line"] == "8"
    assert "constants (5):" in out


def test_dis_source_file_shows_source_lines(work):
    code, out, err = run("dis", work / "test.irl")
    assert code == 0, err
    header, listing = parse_listing(out)
    assert header["program"] == "test" and header["format"] == str(FORMAT_VERSION)
    assert header["checksum"].startswith("crc32:")
    assert "        ; 4: move ptp joint(mainjoint(45, 0,-45, 0, 0, 0))" in out
    assert listing[0]["offset"] == 0


def test_dis_of_source_and_of_its_object_agree(work):
    assert run("compile", work / "test.irl")[0] == 0
    from_source = [line for line in run("dis", work / "test.irl")[1].splitlines() if not line.startswith("        ;")]
    from_object = run("dis", work / "test.irlo")[1].splitlines()
    assert from_source == from_object


def test_dis_shows_jump_targets_and_procedures(work):
    path = work / "flow.irl"
    path.write_text(HEAD + "var i : integer;\nprocedure q(a : integer);\nseq\n  print a;\nendseq\nendprocedure;\n"
                    "seq\n  while i < 3 do\n    call q(i);\n    i := i + 1;\n  endwhile;\nendseq\nendprogram;\n",
                    encoding="utf-8")
    code, out, err = run("dis", path)
    assert code == 0, err
    assert "procedure q(a : integer)" in out
    _, listing = parse_listing(out)
    assert any(c["jump"] for c in listing)
    assert any(c["name"] == "CALL" and c["argrepr"] == "q" for c in listing)
    assert any(c["name"] == "LOAD_LOCAL" and c["argrepr"] == "a" for c in listing)
    assert any(c["name"] == "JUMP_IF_FALSE" and c["argrepr"].startswith("to ") for c in listing)


def test_dis_json(work):
    assert run("compile", work / "test.irl")[0] == 0
    data = (work / "test.irlo").read_bytes()
    code, out, err = run("dis", "--json", work / "test.irlo")
    assert code == 0, err
    doc = json.loads(out)
    assert {"header", "constants", "code"} <= set(doc)
    h = doc["header"]
    assert h["format_version"] == FORMAT_VERSION and h["program"] == "test" and h["spec_name"] == "lola_15"
    assert h["checksum"] == f"crc32:{zlib.crc32(data[10:]):08x}" and h["size"] == len(data)
    assert len(doc["code"]) == len(decode(data).code)
    assert doc["code"][0] == {"offset": 0, "name": "CONST", "operands": [0],
                              "argrepr": "joint(mainjoint(45, 0, -45, 0, 0, 0))", "line": 4, "column": 4,
                              "file": None}
    assert doc["constants"][2] == "lola_15"
    code, out2, _ = run("dis", "--json", work / "test.irl")
    assert code == 0 and json.loads(out2) == doc


def test_dis_invalid_object_file(work):
    path = work / "bad.irlo"
    path.write_bytes(b"IRLO\x00\x01\x00\x00\x00\x00garbage")
    code, out, err = run("dis", path)
    assert code == 1
    assert out == ""
    no_crash(err)
    assert err.startswith(f"{path}: invalid object code: checksum mismatch")


def test_dis_invalid_source_file(work):
    code, out, err = run("dis", work / "invalid.irl")
    assert code == 1 and out == ""
    assert DIAG.match(err.splitlines()[0])


# ---- file and usage errors --------------------------------------------------------------------

@pytest.mark.parametrize("command, name", [("check", "nope.irl"), ("compile", "nope.irl"), ("dis", "nope.irl"),
                                           ("dis", "nope.irlo")])
def test_missing_file(work, command, name):
    path = work / name
    code, out, err = run(command, path)
    assert code == 2
    assert out == ""
    no_crash(err)
    assert err.startswith(f"irl: cannot read {path}: no such file")


@pytest.mark.parametrize("command", ["check", "compile", "dis"])
def test_directory_instead_of_file(work, command):
    d = work / "dir.irl"
    d.mkdir()
    code, _, err = run(command, d)
    assert code == 2
    no_crash(err)
    assert err.startswith(f"irl: cannot read {d}")
    d2 = work / "dir.irlo"
    d2.mkdir()
    code, _, err = run("dis", d2)
    assert code == 2
    no_crash(err)


@pytest.mark.parametrize("command", ["check", "compile", "dis"])
def test_binary_source_file(work, command):
    path = work / "binary.irl"
    path.write_bytes(b"program p;\n\xff\xfe\x00\x81 seq endseq endprogram;\n")
    code, _, err = run(command, path)
    assert code == 2
    no_crash(err)
    assert err.startswith(f"irl: cannot read {path}: not a UTF-8 text file")


@pytest.mark.parametrize("argv", [[], ["frobnicate"], ["check"], ["compile"], ["dis"], ["check", "a", "b"],
                                  ["check", "--bogus", "x.irl"], ["compile", "x.irl", "-o"]])
def test_usage_errors(argv):
    code, out, err = run(*argv)
    assert code == 2
    assert out == ""
    no_crash(err)
    assert err.startswith("irl: ")
    assert "usage: irl" in err


def test_help(capsys):
    assert main(["--help"], Environment(io.StringIO(), io.StringIO())) == 0
    assert "check" in capsys.readouterr().out


# ---- system specifications ----------------------------------------------------------------------

def test_spec_override_with_another_robot(work):
    other = work / "other.spc"
    other.write_text(SPEC.read_text(encoding="utf-8").replace('name = "lola_15"', 'name = "lola_16"'),
                     encoding="utf-8")
    assert run("check", work / "test.irl")[0] == 0
    code, _, err = run("check", "--spec", other, work / "test.irl")
    assert code == 1
    no_crash(err)
    first = DIAG.match(err.splitlines()[0])
    assert first and int(first["line"]) == 4
    assert "act_rob" in first["msg"] and '"lola_15"' in first["msg"] and '"lola_16"' in first["msg"]
    assert err.splitlines()[-1] == f"3 errors in {work / 'test.irl'}"
    # compile and dis take --spec too
    assert run("compile", "--spec", other, work / "test.irl", "-o", work / "x.irlo")[0] == 1
    assert run("dis", "--spec", other, work / "test.irl")[0] == 1


def test_spec_override_is_used_instead_of_the_programs(work):
    alt = work / "sub" / "renamed.spc"
    alt.parent.mkdir()
    shutil.copy(SPEC, alt)
    (work / "lola15.spc").unlink()
    code, _, err = run("check", work / "test.irl")
    assert code == 1 and "cannot read" in err
    code, out, err = run("check", "--spec", alt, work / "test.irl")
    assert code == 0, err


def _broken_spec(work: Path, old: str, new: str) -> None:
    text = SPEC.read_text(encoding="utf-8")
    assert old in text
    (work / "lola15.spc").write_text(text.replace(old, new, 1), encoding="utf-8")


@pytest.mark.parametrize("old, new, key, what", [
    ('name = "lola_15"\n', "", "robot.name", "missing"),
    ("inputs = 16", 'inputs = "16"', "io.inputs", "expected an integer"),
    ("max_speed = 2000.0", "max_sped = 2000.0", "robot.max_sped", "unknown key (did you mean 'max_speed'?)"),
    ("max_jerk = 4000.0", "max_jerk = -1.0", "axis[1].max_jerk", "expected a number 10 <= x <= 1e+06 (deg/s^3 or mm/s^3), got -1.0"),
    ("[robot]", "[robot", None, "not valid TOML"),
])
def test_broken_spec_is_a_diagnostic(work, old, new, key, what):
    _broken_spec(work, old, new)
    spec_path = work / "lola15.spc"
    for command in ("check", "compile", "dis"):
        code, out, err = run(command, work / "test.irl")
        assert code == 1, (command, err)
        no_crash(err)
        m = DIAG.match(err.splitlines()[0])
        assert m, err
        assert (int(m["line"]), int(m["col"])) == (2, 22)  # the program's system_specification string
        assert m["msg"].startswith(f"system specification: {spec_path}: ")
        if key:
            assert f"{spec_path}: {key}: " in m["msg"]
        assert what in m["msg"]
    # also when the broken file is named by --spec
    code, _, err = run("check", "--spec", spec_path, work / "valid.irl")
    assert code == 1 and str(spec_path) in err and (key or "TOML") in err


def test_program_without_spec(work):
    path = work / "nospec.irl"
    path.write_text("program p;\nseq\nendseq\nendprogram;\n", encoding="utf-8")
    code, _, err = run("check", path)
    assert code == 1
    assert "names no system specification" in err
    code, _, err = run("check", "--spec", work / "lola15.spc", path)
    assert code == 0, err


# ---- the paper's program and the real console script ---------------------------------------------

def test_papers_test_program_compiles(tmp_path):
    out = tmp_path / "test.irlo"
    code, stdout, err = run("compile", TEST_IRL, "-o", out)
    assert code == 0, err
    assert stdout.startswith(f"{TEST_IRL} -> {out} (")
    program = load(out.read_bytes(), spec_hash=load_spec(SPEC).hash)
    assert program.spec_name == "lola_15" and program.robots == ("lola_15",)
    assert [BY_NAME["MOVE_PTP"].code in i for i in program.code].count(True) == 3
    assert run("check", TEST_IRL)[0] == 0


def test_console_script_entry_point():
    script = Path(sys.executable).parent / "irl"
    assert script.exists(), f"console script not installed at {script}"
    proc = subprocess.run([str(script), "check", "programs/test.irl"], cwd=ROOT, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0] == "programs/test.irl: ok"
    assert proc.stdout.splitlines()[1] == "motion: 3 moves, cycle time 15.896 s"
    assert proc.stderr == ""


# ---- regression tests for bugs found by these tests ------------------------------------------------

def test_source_line_under_diagnostic_after_form_feed(work):
    """The source line shown is the one the parser counted (str.splitlines() also breaks at \\f)."""
    path = work / "ff.irl"
    path.write_text(HEAD + "var x : real;\n\fseq\n  x := y;\nendseq\nendprogram;\n", encoding="utf-8")
    code, _, err = run("check", path)
    assert code == 1
    lines = err.splitlines()
    m = DIAG.match(lines[0])
    assert m and (int(m["line"]), int(m["col"])) == (5, 8)
    assert lines[1] == "    x := y;"


def test_real_literal_overflow_is_an_error(work):
    path = work / "inf.irl"
    path.write_text(HEAD + "var x : real;\nseq\n  x := 1e999;\nendseq\nendprogram;\n", encoding="utf-8")
    code, out, err = run("dis", "--json", path)
    if code == 0:
        json.loads(out, parse_constant=lambda name: pytest.fail(f"dis --json printed {name}"))
    assert code == 1
    m = DIAG.match(err.splitlines()[0])
    assert m and (int(m["line"]), int(m["col"])) == (5, 8)
    assert "too large" in m["msg"]


@pytest.mark.parametrize("after", ["  pause;\nendseq\n", "endseq\n"])
def test_missing_semicolon_after_move(work, after):
    path = work / "move.irl"
    path.write_text(HEAD + "seq\n  move ptp joint(mainjoint(0, 0, 0, 0, 0, 0))\n" + after + "endprogram;\n",
                    encoding="utf-8")
    code, _, err = run("check", path)
    assert code == 1
    no_crash(err)
    lines = err.splitlines()
    m = DIAG.match(lines[0])
    assert m and (int(m["line"]), int(m["col"])) == (4, 46), err
    assert m["msg"] == "expected ';' after ')'"
    assert lines[-1] == f"1 error in {path}"


@pytest.mark.parametrize("constant", [float("nan"), float("inf")], ids=["nan", "inf"])
def test_dis_json_is_strict_json_or_the_file_is_rejected(work, constant):
    from compiler.objcode import OP, Program, encode

    path = work / "nan.irlo"
    path.write_bytes(encode(Program("p", "p.irl", "lola_15", "0" * 64, ("lola_15",), (constant,),
                                    ((OP.CONST, 0), (OP.PRINT, 1), (OP.END,)), (), ())))
    code, out, err = run("dis", "--json", path)
    no_crash(err)
    assert code in (0, 1)
    if code == 0:
        json.loads(out, parse_constant=lambda name: pytest.fail(f"dis --json printed {name}"))


@pytest.mark.parametrize("old, new, key", [
    ("max_speed = 2000.0", "max_speed = 1" + "0" * 400, "robot.max_speed"),
    ("max_jerk = 4000.0", "max_jerk = -1" + "0" * 400, "axis[1].max_jerk"),
], ids=["robot.max_speed", "axis.max_jerk"])
def test_spec_number_beyond_float_range(work, old, new, key):
    _broken_spec(work, old, new)
    code, _, err = run("check", work / "test.irl")
    no_crash(err)
    assert code == 1
    m = DIAG.match(err.splitlines()[0])
    assert m and f"{work / 'lola15.spc'}: {key}: " in m["msg"]


# ---- irl check stays light (issue 26) --------------------------------------------------------

#: The runtime modules `irl` itself is made of (the command line and the names it offers).
CLI_MODULES = {"runtime", "runtime.cli", "runtime.cli.main", "runtime.cli.common", "runtime.cli.checking", "runtime.hardware",
               "runtime.hardware.faults", "runtime.timing"}


def modules_imported_by(*argv: str) -> set[str]:
    """The modules a fresh interpreter has imported after running ``irl ARGV`` in it."""
    probe = ("import sys; from runtime.cli.main import main; code = main(sys.argv[1:]); "
             "print(code, *sorted(sys.modules), file=sys.stderr)")
    proc = subprocess.run([sys.executable, "-c", probe, *argv], cwd=ROOT, capture_output=True, text=True,
                          timeout=60)
    code, *modules = proc.stderr.splitlines()[-1].split()
    assert code in ("0", "1"), proc.stderr
    return set(modules)


@pytest.mark.parametrize("argv", [("check", "--no-motion", "programs/test.irl"),
                                  ("check", "--no-motion", "--json", "tests/diagnostics/paper_unmended.irl")])
def test_check_imports_only_what_checking_needs(argv):
    """`irl check --no-motion` starts fast (benchmarks/check_startup.py: <= 8x `python -c pass`)
    because it imports neither the runtime nor the heavy libraries; a fresh interpreter shows
    what it did."""
    modules = modules_imported_by(*argv)
    heavy = sorted(m for m in modules if any(m == n or m.startswith(n + ".") for n in NOT_FOR_CHECKING))
    assert not heavy, f"irl {' '.join(argv)} imported what checking does not need: {heavy}"
    runtime = sorted(m for m in modules if m.split(".")[0] == "runtime" and m not in CLI_MODULES)
    assert not runtime, f"irl {' '.join(argv)} imported runtime modules: {runtime}"


def test_a_command_parsed_alone_takes_the_same_arguments_as_in_the_whole_parser():
    """main() declares only the arguments of the command it runs (build_parser(command)):
    each command must come out the same as in the parser that declares them all."""
    import argparse

    from runtime.cli.main import build_parser

    def commands(parser):
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        return sub.choices

    def shape(command):
        return [(a.option_strings, a.dest, a.default, a.help, a.choices, a.required) for a in command._actions], \
            command.get_default("run")

    everything = commands(build_parser())
    for name, command in everything.items():
        alone = commands(build_parser(name))
        assert shape(alone[name]) == shape(command), name
        assert alone[name].description == command.description, name
