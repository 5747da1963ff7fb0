"""Robustness: no input makes ``irl`` crash, and the compiler's output is stable.

* Mutated source programs (every ``programs/*.irl``, found at test time) go through
  ``irl check``, ``irl compile`` and ``irl dis``: the exit status is 0, 1 or 2, never 70
  (an internal error); no traceback; an exit of 1 comes with a ``file:line:col: error:``
  diagnostic; what ``compile`` writes loads.
* Mutated object files (bit flips, truncations, garbage, bad headers, and msgpack bodies
  that are re-checksummed so decoding and verification run past the CRC): ``load`` gives a
  Program or raises ObjectCodeError, nothing else; ``irl dis`` exits 0 or 1.
* Invariants: compiling is deterministic; decode(encode(p)) == p; the result verifies.

Hypothesis runs derandomized, so every run tries the same inputs.
"""
from __future__ import annotations

import re
import shutil
import struct
import zlib
from pathlib import Path

import msgpack
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from compiler.driver import compile_file
from compiler.objcode import (
    BY_CODE,
    FORMAT_VERSION,
    INSTRUCTIONS,
    MAGIC,
    OP,
    ObjectCodeError,
    Program,
    decode,
    encode,
    load,
    verify,
)

from conftest import PROGRAMS, examples, run_cli
HEADER = struct.Struct(">4sHI")
DIAG_LINE = re.compile(r"^\S+:\d+:\d+: error: ", re.M)
BODY_KEYS = ("name", "source", "spec", "robots", "constants", "code", "lines", "globals", "procedures")

FUZZ = dict(deadline=None, derandomize=True, database=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                   HealthCheck.filter_too_much, HealthCheck.large_base_example])


def program_files() -> list[Path]:
    files = sorted(PROGRAMS.glob("*.irl"))
    assert files, f"no programs in {PROGRAMS}"
    return files


def assert_no_crash(code: int, err: str, allowed=(0, 1, 2)) -> None:
    assert code in allowed, f"exit status {code}:\n{err}"
    assert "Traceback" not in err, err
    assert "internal error" not in err, err


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    """A directory with every programs/*.spc, so a program's system_specification resolves."""
    d = tmp_path_factory.mktemp("robust")
    for spec in PROGRAMS.glob("*.spc"):
        shutil.copy(spec, d / spec.name)
    shutil.copytree(PROGRAMS / "lib", d / "lib")  # the modules programs import
    return d


_COMPILED: dict[Path, tuple[bytes, Program, str]] = {}


def compiled(path: Path) -> tuple[bytes, Program, str]:
    """(object bytes, program, spec hash) of a programs/*.irl; every example program
    compiles (a test fails, never skips, when one does not)."""
    if path not in _COMPILED:
        result = compile_file(path)
        assert result.ok, f"{path.name} does not compile: {[d.message for d in result.diagnostics]}"
        _COMPILED[path] = (encode(result.program), result.program, result.spec.hash)
    return _COMPILED[path]


def valid_programs() -> list[Path]:
    return program_files()


def largest_valid_program() -> Path:
    """The valid program with the most instructions (ties: by name), for the hand-picked cases."""
    return max(valid_programs(), key=lambda p: (len(compiled(p)[1].code), p.name))


# =====================================================================================
# Mutated source programs
# =====================================================================================

KEYWORDS = [
    "program", "endprogram", "system_specification", "const", "var", "array", "of", "procedure",
    "endprocedure", "seq", "endseq", "move", "ptp", "lin", "circ", "if", "then", "elsif", "else", "endif",
    "while", "do", "endwhile", "repeat", "until", "for", "to", "step", "endfor", "wait", "for", "sec",
    "timeout", "out", "in", "call", "print", "pause", "halt", "true", "false", "or", "and", "not", "div",
    "mod", "integer", "real", "bool", "string", "joint", "position", "orientation", "pose", "mainjoint",
    "addjoint", "pos", "rpy", "quat", "speed_ptp", "acc_ptp", "speed", "acc", "approx", "act_rob", "sin",
    "sqrt", "atan2", "round", "lola_15", "x", "y", "z", "SEQ", "EndSeq",
]
PUNCTUATION = [";", ":=", ":", ",", ".", "..", "(", ")", "[", "]", "+", "-", "*", "/", "=", "<>", "<=", ">=",
               "<", ">", '"', "'", "{", "}", "(*", "*)", "--", "\\", "#", "$", "@", "!", "?", "&", "|", "^"]
NUMBERS = ["0", "1", "-1", "2.5", ".5", "1e3", "45", "-170", "171", "0.1", "1.0e-3", "3 sec", "255", "65536"]
ODDITIES = ["\x00", "\t", "\r", "\r\n", "\x0b", "\x0c", "\x1b", "\x7f", "\u00a0", "\u00e9", "\u0131", "\u017f",
            "\u212a", "\u2028", "\ufeff", "\ufffd", "\u0663", "\U0001f916", '"unterminated', "\n", "\n\n",
            "\udcff"]  # a lone surrogate: written with surrogateescape it is an invalid UTF-8 byte
INSERTS = KEYWORDS + PUNCTUATION + NUMBERS + ODDITIES

TOKEN = re.compile(r'"[^"\n]*"|[A-Za-z_][A-Za-z0-9_]*|\d+(?:\.\d+)?|:=|<>|<=|>=|\.\.|\S')


def _insert_text():
    return st.one_of(
        st.sampled_from(INSERTS),
        st.sampled_from(INSERTS).map(lambda s: f" {s} "),
        st.characters(exclude_categories=("Cs",)),
        st.text(min_size=1, max_size=6),
    )


def _mutate(draw, text: str) -> str:
    kind = draw(st.sampled_from([
        "delete_char", "delete_span", "insert", "replace_char", "replace_span", "duplicate_line",
        "delete_line", "swap_tokens", "truncate", "swap_case",
    ]))
    n = len(text)
    if kind == "truncate":
        return text[:draw(st.integers(0, max(0, n - 1)))]
    if kind in ("duplicate_line", "delete_line"):
        lines = text.splitlines(keepends=True) or [""]
        i = draw(st.integers(0, len(lines) - 1))
        if kind == "duplicate_line":
            lines.insert(i, lines[i])
        else:
            del lines[i]
        return "".join(lines)
    if kind == "swap_tokens":
        tokens = list(TOKEN.finditer(text))
        if len(tokens) < 2:
            return text
        i = draw(st.integers(0, len(tokens) - 2))
        j = draw(st.integers(i + 1, len(tokens) - 1))
        a, b = tokens[i], tokens[j]
        return text[:a.start()] + b.group() + text[a.end():b.start()] + a.group() + text[b.end():]
    i = draw(st.integers(0, n))
    if kind == "insert":
        return text[:i] + draw(_insert_text()) + text[i:]
    if n == 0:
        return text
    i = min(i, n - 1)
    if kind == "delete_char":
        return text[:i] + text[i + 1:]
    if kind == "replace_char":
        return text[:i] + draw(_insert_text()) + text[i + 1:]
    j = min(n, i + draw(st.integers(1, 40)))
    if kind == "delete_span":
        return text[:i] + text[j:]
    if kind == "replace_span":
        return text[:i] + draw(_insert_text()) + text[j:]
    assert kind == "swap_case"
    return text[:i] + text[i:j].swapcase() + text[j:]


#: Programs larger than this are left out of the mutation search (each example compiles
#: the program three times); test_unmodified_programs_pass_the_same_checks covers them.
FUZZ_MAX_BYTES = 16_000


def fuzz_programs() -> list[Path]:
    files = program_files()
    return [p for p in files if p.stat().st_size <= FUZZ_MAX_BYTES] or [min(files, key=lambda p: p.stat().st_size)]


@st.composite
def mutated_sources(draw) -> tuple[str, str]:
    path = draw(st.sampled_from(fuzz_programs()))
    text = path.read_text(encoding="utf-8")
    for _ in range(draw(st.integers(1, 4))):
        text = _mutate(draw, text)
    return path.name, text


def check_source_text(workdir: Path, text: str) -> int:
    """Run check / compile / dis on ``text``, assert that irl behaves; the exit status."""
    src = workdir / "p.irl"
    out = workdir / "p.irlo"
    src.write_bytes(text.encode("utf-8", "surrogateescape"))
    out.unlink(missing_ok=True)
    codes = {}
    for command in (["check", "--no-motion", src], ["compile", src, "-o", out], ["dis", src]):
        code, stdout, stderr = run_cli(*command)
        assert_no_crash(code, stderr)
        if code == 1:
            assert DIAG_LINE.search(stderr), f"{command[0]}: exit 1 without a diagnostic:\n{stderr}"
        if code == 2:
            assert stderr.startswith("irl: cannot read"), stderr
        if command[0] == "compile":
            if code == 0:
                program = load(out.read_bytes())  # decodes and verifies
                assert program.name
            else:
                assert not out.exists()
        if command[0] == "dis" and code == 0:
            assert stdout.startswith("program ")
        codes[command[0]] = code
    assert len(set(codes.values())) == 1, f"check, compile and dis disagree: {codes}"
    if codes["check"] == 0 and zlib.crc32(text.encode("utf-8", "surrogateescape")) % 2 == 0:
        # the motion check runs what compiles (half the cases, chosen by their text; its first 8 moves)
        code, stdout, stderr = run_cli("check", "--max-moves", "8", src)
        assert_no_crash(code, stderr)
        assert code in (0, 1) and stdout.splitlines()[-1].startswith(("motion: ", "note: ", "assumed: ")), stdout
        if code == 1:
            assert DIAG_LINE.search(stderr), f"check: exit 1 without a diagnostic:\n{stderr}"
    return codes["check"]


@pytest.mark.long
@settings(max_examples=examples(100), **FUZZ)
@given(case=mutated_sources())
def test_mutated_programs_never_crash_the_cli(workdir, case):
    name, text = case
    check_source_text(workdir, text)


@pytest.mark.parametrize("path", program_files(), ids=lambda p: p.name)
def test_unmodified_programs_pass_the_same_checks(workdir, path):
    check_source_text(workdir, path.read_text(encoding="utf-8"))


# ---- pathological but legal-looking sources -----------------------------------------------

HEAD = 'program p;\nsystem_specification "lola15.spc";\n'


def _program(decls: str, body: str) -> str:
    return HEAD + decls + "seq\n" + body + "endseq\nendprogram;\n"


@pytest.mark.parametrize("text", [
    _program("var x : integer;\n", "  x := " + "(" * 300 + "1" + ")" * 300 + ";\n"),
    _program("var x : integer;\n", "  x := " + "+".join(["x"] * 200) + ";\n"),
    _program("", "  print " + ", ".join(['"s"'] * 200) + ";\n"),
    _program("", "  pause;\n" * 3000),
    _program("", "  print 1.7976931348623157e308;\n  print 9223372036854775807;\n"),
    _program("var x : integer;\n", "  x := 2147483647 + 1;\n"),
    _program("var a : array[1..255] of integer;\n", "  a[255] := 1;\n"),
    _program("var a : array[1..100001] of integer;\n", "  a[1] := 1;\n"),
    HEAD + "\x00" * 1000,
    "",
    "\ufeff" + _program("", "  pause;\n"),
], ids=["parens300", "sum200", "print200", "pause3000", "big-literals", "int-overflow", "array-255",
        "array-too-big", "nuls", "empty", "bom"])
def test_pathological_sources(workdir, text):
    check_source_text(workdir, text)


# Regression tests: these crashed with RecursionError / OverflowError (exit 70) until the
# compiler gained a nesting limit and 64-bit integer / finite real literal checks.

@pytest.mark.parametrize("text", [
    _program("var x : integer;\n", "  x := " + "+".join(["x"] * 1000) + ";\n"),
    _program("var x : bool;\n", "  x := " + " and ".join(["x"] * 1000) + ";\n"),
    _program("var x : integer;\n", "  x := " + "-(" * 400 + "x" + ")" * 400 + ";\n"),
    _program("var x : integer;\n", "  if x > 0 then\n" * 600 + "  x := 1;\n" + "  endif;\n" * 600),
], ids=["sum1000", "and1000", "neg400", "if600"])
def test_long_expressions_and_deep_nesting(workdir, text):
    assert check_source_text(workdir, text) == 0


@pytest.mark.parametrize("text", [
    _program("var x : integer;\n", "  x := " + "+".join(["x"] * 10000) + ";\n"),
    _program("var x : integer;\n", "  x := " + "abs(" * 5000 + "x" + ")" * 5000 + ";\n"),
], ids=["sum10000", "calls5000"])
def test_nesting_beyond_the_limit_is_a_diagnostic(workdir, text):
    assert check_source_text(workdir, text) == 1


@pytest.mark.parametrize("literal", ["99999999999999999999999", "18446744073709551616", "9223372036854775808",
                                     "9999999999 * 9999999999", "1e999", "-1e999", "1e308 * 10"])
def test_numbers_beyond_the_value_range_are_diagnostics(workdir, literal):
    kind = "real" if "e" in literal else "integer"
    assert check_source_text(workdir, _program(f"var x : {kind};\n", f"  x := {literal};\n")) == 1


def test_largest_numbers_compile(workdir):
    assert check_source_text(workdir, _program("var x : integer;\n    y : real;\n",
                                               "  x := 9223372036854775807;\n  y := 1.7976931348623157e308;\n")) == 0


@pytest.mark.parametrize("decls, body, status", [
    ("var a : array[1..256] of integer;\n", "  a[1] := 1;\n", 0),
    ("var a : array[1..100000] of integer;\n", "  a[100000] := 1;\n", 0),
    ("", "  print " + ", ".join(["1"] * 300) + ";\n", 0),
    ("var a : array[4000000000..4000000001] of integer;\n    i : integer;\n", "  a[i] := 1;\n", 1),
    ("var a : array[-2147483649..-2147483648] of integer;\n    i : integer;\n", "  a[i] := 1;\n", 1),
], ids=["array-256", "array-100000", "print-300", "array-bounds-2**32", "array-bounds-negative"])
def test_compiled_object_code_is_within_the_verifiers_limits(workdir, decls, body, status):
    """Regression: arrays of more than 255 elements, print with more than 255 values and
    array bounds beyond 32 bits compiled (exit 0) to object code that load() rejected."""
    assert check_source_text(workdir, _program(decls, body)) == status


# ---- mutated system specifications ---------------------------------------------------------

SPEC_VALUE = re.compile(r"(?<== )[^\n#,}]+")  # the value after "key = ", inline tables included
SPEC_VALUES = st.one_of(
    st.sampled_from(["0", "-1", "1", "0.0", "-0.0", "1e300", "-1e300", "1.7976931348623157e308", "5e-324",
                     "nan", "inf", "-inf", "true", '""', '"x"', '"additional"', '"prismatic"', "[]", "[1, 2]",
                     "{}", "{ a = 1 }", "1979-05-27", "07:32:00", "1979-05-27T07:32:00Z", "0x10", "1_000",
                     "'literal'", '"""multi"""', "9223372036854775807", "-9223372036854775808"]),
    st.floats().map(repr),
    # integers beyond the float range crash the loader: test_cli.py::test_spec_number_beyond_float_range
    st.integers(-(2 ** 63), 2 ** 63 - 1).map(str),
)


@st.composite
def mutated_specs(draw) -> str:
    text = (PROGRAMS / "lola15.spc").read_text(encoding="utf-8")
    for _ in range(draw(st.integers(1, 4))):
        values = list(SPEC_VALUE.finditer(text))
        if values and draw(st.booleans()):
            m = draw(st.sampled_from(values))
            text = text[:m.start()] + draw(SPEC_VALUES) + " " + text[m.end():]
        else:
            text = _mutate(draw, text)
    return text


@settings(max_examples=examples(150), **FUZZ)
@given(spec=mutated_specs())
def test_mutated_specifications_never_crash_the_cli(tmp_path_factory, spec):
    d = tmp_path_factory.mktemp("spec", numbered=True)
    shutil.copy(PROGRAMS / "test.irl", d / "test.irl")
    (d / "lola15.spc").write_bytes(spec.encode("utf-8", "surrogateescape"))
    for command in (["check", d / "test.irl"], ["compile", d / "test.irl", "-o", d / "t.irlo"]):
        code, _, err = run_cli(*command)
        assert_no_crash(code, err, allowed=(0, 1))
        if code == 1:
            assert DIAG_LINE.search(err), err
        elif command[0] == "compile":
            load((d / "t.irlo").read_bytes())


# =====================================================================================
# Mutated object files
# =====================================================================================

def with_crc(body: bytes, version: int = FORMAT_VERSION, magic: bytes = MAGIC) -> bytes:
    return HEADER.pack(magic, version, zlib.crc32(body)) + body


def pack(obj) -> bytes:
    return msgpack.packb(obj, use_bin_type=True)


def load_contract(data: bytes) -> Program | None:
    """``load`` returns a Program or raises ObjectCodeError: anything else fails the test."""
    try:
        program = load(data)
    except ObjectCodeError as exc:
        assert isinstance(exc.message, str) and exc.message
        assert exc.offset is None or isinstance(exc.offset, int)
        return None
    assert isinstance(program, Program)
    return program


def dis_contract(workdir: Path, data: bytes) -> None:
    """``irl dis`` on the bytes exits 0 (and lists) or 1 (and says why), never 70."""
    path = workdir / "x.irlo"
    path.write_bytes(data)
    code, out, err = run_cli("dis", path)
    assert_no_crash(code, err, allowed=(0, 1))
    if code == 1:
        assert err.startswith(f"{path}: invalid object code: "), err
    else:
        assert out.startswith("program ")
        code, out, err = run_cli("dis", "--json", path)
        assert_no_crash(code, err, allowed=(0,))


def _header_classes(size: int) -> list[int]:
    """Every length when the file is small, else every 'class': no magic, partial header,
    bare header, partial body, one byte short."""
    if size <= 2048:
        return list(range(size))
    return sorted({0, 1, 3, 4, 5, 6, 9, 10, 11, 12, 13, 16, 17, size // 4, size // 2, size - 2, size - 1}
                  | set(range(10, size, max(1, size // 200))))


@pytest.mark.parametrize("path", program_files(), ids=lambda p: p.name)
def test_truncated_object_files(workdir, path):
    data = compiled(path)[0]
    body = data[HEADER.size:]
    for n in _header_classes(len(data)):
        with pytest.raises(ObjectCodeError):  # raw truncation: the header or the checksum catches it
            load(data[:n])
    for n in _header_classes(len(body)):
        with pytest.raises(ObjectCodeError):  # the body truncated and re-checksummed: msgpack catches it
            load(with_crc(body[:n]))
    for n in (0, 3, 9, 10, len(data) // 2, len(data) - 1):
        dis_contract(workdir, data[:n])
        dis_contract(workdir, with_crc(body[:max(0, n - HEADER.size)]))


def test_header_errors(workdir):
    data, program, _ = compiled(PROGRAMS / "test.irl")
    body = data[HEADER.size:]
    assert load(data) == program
    for version in (0, 2, 0xFFFF):
        with pytest.raises(ObjectCodeError, match=f"version {version} is not supported"):
            load(with_crc(body, version=version))
        dis_contract(workdir, with_crc(body, version=version))
    for magic in (b"IRLo", b"\x00IRL", b"OLRI", b"\x89PNG"):
        with pytest.raises(ObjectCodeError, match="bad magic"):
            load(with_crc(body, magic=magic))
        dis_contract(workdir, with_crc(body, magic=magic))


@st.composite
def corrupted_objects(draw) -> tuple[str, bytes]:
    path = draw(st.sampled_from(valid_programs()))
    data = compiled(path)[0]
    body = data[HEADER.size:]
    kind = draw(st.sampled_from(["flip", "flip_body_rechecksummed", "append", "append_rechecksummed",
                                 "version", "magic", "splice_rechecksummed"]))
    if kind == "flip":
        buf = bytearray(data)
        for i in draw(st.lists(st.integers(0, len(buf) - 1), min_size=1, max_size=4, unique=True)):
            buf[i] ^= draw(st.integers(1, 255))  # distinct positions: the file always changes
        return kind, bytes(buf)
    if kind == "flip_body_rechecksummed":
        buf = bytearray(body)
        for _ in range(draw(st.integers(1, 4))):
            i = draw(st.integers(0, len(buf) - 1))
            buf[i] = draw(st.one_of(st.integers(0, 255), st.sampled_from([0xC0, 0xC1, 0xC2, 0xC3, 0xCC, 0xCD,
                                                                           0xCE, 0xCF, 0xD0, 0xDC, 0xDD, 0xDE,
                                                                           0xDF, 0xD9, 0xDA, 0xDB, 0xC4, 0xC6,
                                                                           0xFF, 0x7F, 0x80, 0x90, 0xA0])))
        return kind, with_crc(bytes(buf))
    if kind == "append":
        return kind, data + draw(st.binary(min_size=1, max_size=64))
    if kind == "append_rechecksummed":
        return kind, with_crc(body + draw(st.binary(min_size=1, max_size=64)))
    if kind == "version":
        return kind, with_crc(body, version=draw(st.integers(0, 0xFFFF).filter(lambda v: v != FORMAT_VERSION)))
    if kind == "magic":
        return kind, with_crc(body, magic=draw(st.binary(min_size=4, max_size=4).filter(lambda m: m != MAGIC)))
    # splice: a random slice of the body replaced by random bytes, then re-checksummed
    i = draw(st.integers(0, len(body)))
    j = draw(st.integers(i, min(len(body), i + 16)))
    return kind, with_crc(body[:i] + draw(st.binary(max_size=16)) + body[j:])


@settings(max_examples=examples(300), **FUZZ)
@given(case=corrupted_objects())
def test_corrupted_object_files(workdir, case):
    kind, data = case
    program = load_contract(data)
    if kind in ("flip", "append", "append_rechecksummed", "version", "magic"):
        assert program is None, f"{kind}: a corrupt file was accepted"
    dis_contract(workdir, data)


# ---- valid msgpack of the wrong shape -------------------------------------------------------

SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(-(2 ** 63), 2 ** 64 - 1), st.integers(-3, 300),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12), st.binary(max_size=12),
)
OBJECTS = st.recursive(
    SCALARS,
    lambda children: st.one_of(st.lists(children, max_size=6),
                               st.dictionaries(st.text(max_size=10), children, max_size=6),
                               st.dictionaries(st.sampled_from(BODY_KEYS), children, max_size=9)),
    max_leaves=20,
)


@settings(max_examples=examples(150), **FUZZ)
@given(body=st.one_of(OBJECTS, st.fixed_dictionaries({k: OBJECTS for k in BODY_KEYS})))
def test_msgpack_of_the_wrong_shape(workdir, body):
    data = with_crc(pack(body))
    assert load_contract(data) is None or isinstance(body, dict)
    dis_contract(workdir, data)


# ---- near-miss bodies: a real body with one thing wrong ----------------------------------------

OPCODES = [d.code for d in INSTRUCTIONS]
JUMPS = {d.code for d in INSTRUCTIONS if d.operands and d.operands[0][1] == "target"}
BAD_CONSTANTS = st.one_of(
    OBJECTS,
    st.sampled_from([
        [], ["joint"], ["joint", [1.0], "x"], ["joint", [True], []], ["joint", [1.0], [None]], ["pos", 1, 2],
        ["pos", 1, 2, "3"], ["pos", 1, 2, 3, 4], ["rpy", None, 0, 0], ["quat", 1, 0, 0], ["quat", 1, 0, 0, True],
        ["pose", ["pos", 1, 2, 3]], ["pose", ["pos", 1, 2, 3], ["pos", 1, 2, 3]],
        ["pose", ["rpy", 0, 0, 0], ["pos", 1, 2, 3]], ["pose", 1, 2], ["Joint", [], []], [1, 2, 3], [None],
        ["unknown"], {"joint": [1]}, b"\x00", ["pose", ["pos", 1, 2, 3], ["quat", 1, 0, 0, 0], 5],
    ]),
)


def _real_body(path: Path) -> dict:
    return msgpack.unpackb(compiled(path)[0][HEADER.size:], raw=False)


def _instruction_starts(flat: list[int]) -> list[int]:
    starts, pos = [], 0
    while pos < len(flat):
        starts.append(pos)
        pos += 1 + len(BY_CODE[flat[pos]].operands)
    return starts


@st.composite
def near_miss_bodies(draw) -> tuple[str, dict]:
    body = _real_body(draw(st.sampled_from(valid_programs())))
    kind = draw(st.sampled_from(["remove_key", "retype_field", "random_code", "operand", "jump_target",
                                 "append_code", "constant", "lines", "procedures", "globals", "truncate_code"]))
    code = body["code"]
    starts = _instruction_starts(code)
    if kind == "remove_key":
        del body[draw(st.sampled_from(BODY_KEYS))]
    elif kind == "retype_field":
        body[draw(st.sampled_from(BODY_KEYS))] = draw(OBJECTS)
    elif kind == "random_code":
        body["code"] = draw(st.lists(st.one_of(st.sampled_from(OPCODES), st.integers(-2, 70),
                                               st.integers(-(2 ** 63), 2 ** 63 - 1)), max_size=40))
    elif kind == "operand":  # one operand of one instruction set to a random (often out-of-range) value
        with_operands = [s for s in starts if BY_CODE[code[s]].operands]
        if with_operands:
            s = draw(st.sampled_from(with_operands))
            k = draw(st.integers(1, len(BY_CODE[code[s]].operands)))
            code[s + k] = draw(st.one_of(st.integers(-3, 300), st.integers(-(2 ** 63), 2 ** 63 - 1)))
    elif kind == "jump_target":  # an existing jump, or a new one at the start, aimed anywhere
        target = draw(st.one_of(st.integers(-3, len(starts) + 3), st.integers(-(2 ** 40), 2 ** 40)))
        jumps = [s for s in starts if code[s] in JUMPS]
        if jumps and draw(st.booleans()):
            code[draw(st.sampled_from(jumps)) + 1] = target
        else:
            body["code"] = [OP.JUMP, target] + code
    elif kind == "append_code":  # instructions after the final END: never executed
        body["code"] = code + draw(st.lists(st.one_of(st.sampled_from(OPCODES), st.integers(-2, 300)),
                                            min_size=1, max_size=12))
    elif kind == "truncate_code":
        body["code"] = code[:draw(st.integers(0, max(0, len(code) - 1)))]
    elif kind == "constant":
        constants = body["constants"]
        bad = draw(BAD_CONSTANTS)
        if constants and draw(st.booleans()):
            constants[draw(st.integers(0, len(constants) - 1))] = bad
        else:
            constants.append(bad)
    elif kind == "lines":
        body["lines"] = draw(st.lists(st.integers(-3, 2 ** 33), max_size=12))
    elif kind == "procedures":
        body["procedures"] = draw(st.lists(st.tuples(st.text(max_size=4), st.integers(-2, 40), st.integers(-2, 4),
                                                     st.lists(st.tuples(st.text(max_size=3), st.text(max_size=3)),
                                                              max_size=3)).map(list), max_size=3))
    else:
        body["globals"] = draw(st.one_of(OBJECTS, st.lists(st.lists(st.text(max_size=3), min_size=0, max_size=3),
                                                            max_size=3)))
    return kind, body


def _unreachable_example() -> tuple[str, dict]:
    """Regression (found by the search below): an instruction after the final END with an
    operand out of range was accepted by verify() and crashed `irl dis` (IndexError, exit 70).
    Built without the compiler, as the decorator runs at import time."""
    program = Program("p", "p.irl", "lola_15", "0" * 64, ("lola_15",), (1,), ((OP.END,),), ((0, 3, 1),), ())
    body = msgpack.unpackb(encode(program)[HEADER.size:], raw=False)
    body["code"] = body["code"] + [OP.CONST, 10_000]
    return "append_code", body


@settings(max_examples=examples(300), **FUZZ)
@given(case=near_miss_bodies())
def test_near_miss_bodies_load_or_raise_object_code_error(case):
    kind, body = case
    program = load_contract(with_crc(pack(body)))
    if kind == "remove_key":
        assert program is None


@settings(max_examples=examples(300), **FUZZ)
@given(case=near_miss_bodies())
@example(case=_unreachable_example())
def test_near_miss_bodies_dis(workdir, case):
    kind, body = case
    dis_contract(workdir, with_crc(pack(body)))


def test_near_miss_bodies_dis_hand_picked(workdir):
    """The same `irl dis` contract on hand-picked near misses, each of which must be rejected."""
    body = _real_body(largest_valid_program())
    invalid = []  # each of these must be rejected
    for key in BODY_KEYS:
        b = dict(body)
        del b[key]
        invalid.append(b)
        for value in (None, 1, {}, [[1]], b"x"):
            invalid.append({**body, key: value})
    for bad in (["pos", 1, 2], ["pose", 1, 2], [None], {"a": 1}, b"x"):
        invalid.append({**body, "constants": body["constants"] + [bad]})
    invalid.append({**body, "code": [OP.JUMP, 10 ** 6] + body["code"]})
    invalid.append({**body, "code": [OP.CONST, -1] + body["code"]})
    invalid.append({**body, "code": body["code"] + [OP.JUMP]})  # (ends inside its operands)
    invalid.append({**body, "code": []})
    invalid.append({**body, "lines": [0, 0, 0]})
    invalid.append({**body, "procedures": body["procedures"] + [["q", 10 ** 9, 0, []]]})
    for b in invalid:
        data = with_crc(pack(b))
        assert load_contract(data) is None, sorted(b)
        dis_contract(workdir, data)
    for key in BODY_KEYS:  # values that may or may not fit: only the contracts
        for value in ("x", [], ["x"], [["a", "b"]]):
            data = with_crc(pack({**body, key: value}))
            load_contract(data)
            dis_contract(workdir, data)


@pytest.mark.parametrize("shape", ["pose", "list"])
def test_deeply_nested_constant(workdir, shape):
    """Regression: constants nested ~1000 deep (msgpack allows it) raised RecursionError in
    decode() (values.from_plain and repr() in its message) and `irl dis` exited 70."""
    body = _real_body(largest_valid_program())
    constant = 1.0
    for _ in range(1000):
        constant = ["pose", constant, 0] if shape == "pose" else [constant]
    body["constants"] = [constant]
    data = with_crc(pack(body))
    assert load_contract(data) is None
    dis_contract(workdir, data)


# =====================================================================================
# Invariants
# =====================================================================================

@pytest.mark.parametrize("path", program_files(), ids=lambda p: p.name)
def test_compiler_invariants(path, tmp_path):
    first = compile_file(path)
    assert first.ok, f"{path.name} does not compile: {[d.message for d in first.diagnostics]}"
    second = compile_file(path)
    assert second.ok
    data = encode(first.program)
    assert encode(second.program) == data, "compiling twice gave different bytes"
    assert first.program == second.program
    # through the CLI as well: two compiles, identical files
    outs = [tmp_path / "a.irlo", tmp_path / "b.irlo"]
    for out in outs:
        code, _, err = run_cli("compile", path, "-o", out)
        assert code == 0, err
    assert outs[0].read_bytes() == outs[1].read_bytes() == data
    # decode(encode(p)) == p, and it verifies
    decoded = decode(data)
    assert decoded == first.program
    assert encode(decoded) == data
    depth = verify(decoded)
    assert isinstance(depth, int) and depth >= 0
    assert verify(decoded, spec_hash=first.spec.hash) == depth
    assert load(data, spec_hash=first.spec.hash) == first.program
    with pytest.raises(ObjectCodeError, match="recompile"):
        load(data, spec_hash="0" * 64)


def test_test_irl_is_among_the_programs():
    assert PROGRAMS / "test.irl" in program_files()
    assert compiled(PROGRAMS / "test.irl")[0]
