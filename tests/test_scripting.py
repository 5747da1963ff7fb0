"""The parser of the text scripting interface (runtime/wire/scripting.py).

* Every documented form parses to its command, with value types checked (an int stays an
  int: SetProperty(..., 2) == SetProperty(..., 2.0) == SetProperty(..., True) in Python).
* Every error: its message and 1-based column; the leftmost problem is the one reported.
* format_value, and the round trip parse(f"a.b = {format_value(v)}").value == v.
* Properties (Hypothesis, derandomized): no text makes parse raise anything but
  ScriptError, also text assembled from the language's own tokens.
* The module never hands text to Python to evaluate.
"""
from __future__ import annotations

import ast
import math
import pickle
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import runtime.wire.scripting as scripting
from runtime.wire.scripting import (
    HELP_TEXT,
    MAX_LENGTH,
    CallOperation,
    Components,
    GetProperty,
    Help,
    ScriptError,
    SetProperty,
    format_value,
    parse,
)

from conftest import examples

PROPERTY = settings(derandomize=True, deadline=None, database=None, max_examples=examples(500))


def same(a: object, b: object) -> bool:
    """Equal and of the same type, recursively; floats compared bit for bit (so -0.0 != 0.0)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return math.copysign(1.0, a) == math.copysign(1.0, b) and a == b
    if isinstance(a, tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


# ---- the forms ---------------------------------------------------------------------------

@pytest.mark.parametrize("text, expected", [
    ("components", Components()),
    ("help", Help(None)),
    ("help servo", Help("servo")),
    ("servo.kp", GetProperty("servo", "kp")),
    ("servo.kp = 2.5", SetProperty("servo", "kp", 2.5)),
    ("servo.kp=2", SetProperty("servo", "kp", 2)),
    ("report.start()", CallOperation("report", "start", ())),
    ('fsm.request_state("Calibrate Offsets")', CallOperation("fsm", "request_state", ("Calibrate Offsets",))),
    ("robot.write_output(3, true)", CallOperation("robot", "write_output", (3, True))),
    ("  servo . kp  ", GetProperty("servo", "kp")),
    # more of the same
    ("\tcomponents\t", Components()),
    ("  help\t servo ", Help("servo")),
    ("_a1._b2", GetProperty("_a1", "_b2")),
    ("servo.kp", GetProperty("servo", "kp")),
    ("help.kp", GetProperty("help", "kp")),  # "help" and "components" are commands only without "."
    ("components . list()", CallOperation("components", "list", ())),
    ("robot.enable = false", SetProperty("robot", "enable", False)),
    ("robot.enable = true", SetProperty("robot", "enable", True)),
    ("a.b( )", CallOperation("a", "b", ())),
    ("a.b ( 1 , -2.5 , 'x' , false )", CallOperation("a", "b", (1, -2.5, "x", False))),
    ("a.b(1,2,3)", CallOperation("a", "b", (1, 2, 3))),
    ("true.false = true", SetProperty("true", "false", True)),
    ("nan.inf", GetProperty("nan", "inf")),
])
def test_forms(text, expected):
    result = parse(text)
    assert result == expected
    if isinstance(expected, SetProperty):
        assert same(result.value, expected.value)
    if isinstance(expected, CallOperation):
        assert same(result.args, expected.args)


@pytest.mark.parametrize("literal, value", [
    ("3", 3), ("-2", -2), ("+7", 7), ("0", 0), ("-0", 0), ("007", 7),
    ("123456789012345678901234567890", 123456789012345678901234567890),
    ("2.5", 2.5), ("1e-3", 1e-3), (".5", 0.5), ("5.", 5.0), ("-.5", -0.5), ("+5.", 5.0),
    ("1E3", 1000.0), ("1e+3", 1000.0), ("2.5e-3", 2.5e-3), ("5.e2", 500.0), ("-0.0", -0.0),
    ("1e-400", 0.0), ("1.7976931348623157e308", 1.7976931348623157e308),
])
def test_numbers(literal, value):
    assert same(parse(f"a.b = {literal}").value, value)
    assert same(parse(f"a.b({literal})").args, (value,))


@pytest.mark.parametrize("literal, value", [
    ('""', ""), ("''", ""), ('"abc"', "abc"), ("'abc'", "abc"),
    ('"it\'s"', "it's"), ("'say \"hi\"'", 'say "hi"'),
    (r'"a\\b"', "a\\b"), (r'"a\"b"', 'a"b'), (r"'a\'b'", "a'b"), (r'"a\'b"', "a'b"), (r"'a\"b'", 'a"b'),
    (r'"a\nb"', "a\nb"), (r'"a\tb"', "a\tb"), (r'"a\rb"', "a\rb"),
    ('"a\tb"', "a\tb"), ('"Grüße, 世界 🤖"', "Grüße, 世界 🤖"), ('"\x00\x7f"', "\x00\x7f"),
    ('"  spaces  "', "  spaces  "), ('"a.b = (1, 2)"', "a.b = (1, 2)"),
])
def test_strings(literal, value):
    assert same(parse(f"a.b = {literal}").value, value)


# ---- errors ------------------------------------------------------------------------------

@pytest.mark.parametrize("text, message, column", [
    ("", "empty command (type 'help' for the forms)", 1),
    ("   ", "empty command (type 'help' for the forms)", 4),
    ("servo.kp =", "expected a value after '='", 11),
    ("servo.kp = nan", "expected a value after '='", 12),
    ("servo.kp = inf", "expected a value after '='", 12),
    ("servo.kp = -inf", "unexpected character '-'", 12),
    ("servo.kp = True", "expected a value after '='", 12),
    ("servo.kp = none", "expected a value after '='", 12),
    ("servo.kp = (1)", "expected a value after '='", 12),
    ("servo.kp = = 1", "expected a value after '='", 12),
    ('servo.kp = "abc', "unterminated string", 12),
    ("servo.kp = 'abc\"", "unterminated string", 12),
    ('servo.kp = "abc\\"', "unterminated string", 12),
    ('servo.kp = "abc\\', "unterminated string", 12),
    ("report.start())", "unexpected text after the command: ')'", 15),
    ("servo.kp = 2 3", "unexpected text after the command: '3'", 14),
    ("servo.kp 3", "unexpected text after the command: '3'", 10),
    ("servo.kp.x", "unexpected text after the command: '.'", 9),
    ('servo.kp = 1 "a long string that goes on"', "unexpected text after the command: '\"a long string that ...'", 14),
    ("components x", "unexpected text after the command: 'x'", 12),
    ("components()", "unexpected text after the command: '('", 11),
    ("help servo.kp", "unexpected text after the command: '.'", 11),
    ("help servo x", "unexpected text after the command: 'x'", 12),
    ("help 3", "expected a component name after 'help'", 6),
    ("servo", "expected 'component.member', e.g. servo.kp", 6),
    ("servo.", "expected 'component.member', e.g. servo.kp", 7),
    ("servo.3", "expected 'component.member', e.g. servo.kp", 6),  # ".3" is a number
    ("servo..kp", "expected 'component.member', e.g. servo.kp", 7),
    (".kp", "expected 'component.member', e.g. servo.kp", 1),
    ("3", "expected 'component.member', e.g. servo.kp", 1),
    ("= 3", "expected 'component.member', e.g. servo.kp", 1),
    ("'servo'.kp", "expected 'component.member', e.g. servo.kp", 1),
    ("x = 'abc", "expected 'component.member', e.g. servo.kp", 3),  # the leftmost error wins
    ("servo = 1", "expected 'component.member', e.g. servo.kp", 7),
    ("a.b(", "expected a value or ')'", 5),
    ("a.b(,)", "expected a value or ')'", 5),
    ("a.b(1", "expected ',' or ')'", 6),
    ("a.b(1 2)", "expected ',' or ')'", 7),
    ("a.b(1;2)", "unexpected character ';'", 6),
    ("a.b(1,)", "expected a value after ','", 7),
    ("a.b(1,,2)", "expected a value after ','", 7),
    ("a.b(x)", "expected a value or ')'", 5),
    ("a.b = 1e999", "number out of range: '1e999'", 7),
    ("a.b = -1e999", "number out of range: '-1e999'", 7),
    ("a.b = 2abc", "malformed number '2abc'", 7),
    ("a.b = 1e", "malformed number '1e'", 7),
    ("a.b = 1.2.3", "malformed number '1.2.3'", 7),
    ("a.b = 5..", "malformed number '5..'", 7),
    ("a.b(1)x", "unexpected text after the command: 'x'", 7),
    ("a.b = +", "unexpected character '+'", 7),
    ("a.b = --1", "unexpected character '-'", 7),
    ('a.b = "\\q"', "unknown escape '\\q' (use \\\\ \\\" \\' \\n \\t \\r)", 8),
    ('a.b = "\\x41"', "unknown escape '\\x' (use \\\\ \\\" \\' \\n \\t \\r)", 8),
    ("a.b\n", "a command must be on one line", 4),
    ("a.b\r\n", "a command must be on one line", 4),
    ('a.b = "x\ny"', "a command must be on one line", 9),
    ("a.b = 1\x00", "unexpected character '\\x00'", 8),
    ("servo.kp = 2,5", "unexpected text after the command: ','", 13),
    ("servo.kp ≔ 2", "unexpected character '≔'", 10),
    ("sérvo.kp", "unexpected character 'é'", 2),
    ("servo.kp = ２", "unexpected character '２'", 12),  # a fullwidth digit is no digit here
    ("servo.kp = \u00a0 1", "unexpected character '\\xa0'", 12),
])
def test_errors(text, message, column):
    with pytest.raises(ScriptError) as info:
        parse(text)
    assert info.value.message == message
    assert info.value.column == column
    assert str(info.value) == f"column {column}: {message}"


def test_script_error_is_a_value_error_and_pickles():
    error = ScriptError("unterminated string", 12)
    assert isinstance(error, ValueError)
    copy = pickle.loads(pickle.dumps(error))
    assert (type(copy), copy.message, copy.column, str(copy)) == (ScriptError, error.message, 12, str(error))


def test_length_limit():
    name = "a" * (MAX_LENGTH - 4)
    assert parse(f"{name}.b()") == CallOperation(name, "b", ())  # exactly at the limit
    with pytest.raises(ScriptError) as info:
        parse(f"{name}.bc()")
    assert (info.value.message, info.value.column) == ("command too long", MAX_LENGTH + 1)
    with pytest.raises(ScriptError, match="command too long"):
        parse("x" * 10**6)


def test_huge_numbers_within_the_length_limit():
    with pytest.raises(ScriptError, match="integer has too many digits"):
        parse("a.b = " + "9" * 9000)
    assert parse("a.b = " + "9" * 4300).value == int("9" * 4300)
    with pytest.raises(ScriptError, match="number out of range"):
        parse("a.b = " + "9" * 9000 + ".0")
    assert parse("a.b = 0." + "0" * 9000 + "1").value == 0.0
    assert parse("a.b = " + "1" * 9000 + "e-9000").value == pytest.approx(1 / 9)


def test_deep_and_long_inputs():
    assert parse("a.b(" + ", ".join(["1"] * 3000) + ")").args == (1,) * 3000
    with pytest.raises(ScriptError):
        parse("a.b" + "(" * 9000)
    with pytest.raises(ScriptError):
        parse("(" * 9000)


def test_commands_are_frozen():
    command = parse("servo.kp = 2")
    with pytest.raises(AttributeError):
        command.value = 3  # type: ignore[misc]


def test_help_text_lists_the_forms():
    assert "\n" in HELP_TEXT.strip()
    for form in ("components", "help", "servo.kp", "trajectory.budget = 500", "trajectory.configure()", "true"):
        assert form in HELP_TEXT
    # the examples in the help text parse (and a server accepts them: tests/test_netcli.py)
    assert parse("trajectory.budget = 500") and parse("trajectory.configure()")


# ---- format_value ------------------------------------------------------------------------

class Thing:
    def __repr__(self) -> str:
        return "<thing>"


@pytest.mark.parametrize("value, text", [
    (3, "3"), (-2, "-2"), (2.5, "2.5"), (1e-3, "0.001"), (1e-5, "1e-05"), (1e16, "1e+16"), (-0.0, "-0.0"),
    (float("inf"), "inf"), (True, "true"), (False, "false"), (None, "none"),
    ("abc", '"abc"'), ("", '""'), ('a"b', '"a\\"b"'), ("a'b", '"a\'b"'), ("a\\b", '"a\\\\b"'),
    ("a\nb\tc\rd", '"a\\nb\\tc\\rd"'), ("Grüße", '"Grüße"'),
    ((1, 2.5), "[1, 2.5]"), ([True, "x", None], '[true, "x", none]'), ((), "[]"), ([(1,), []], "[[1], []]"),
    ({"a": 1}, "{'a': 1}"), (Thing(), "<thing>"),
])
def test_format_value(value, text):
    assert format_value(value) == text


def test_format_value_odd_values():
    class Ratio(float):
        def __repr__(self) -> str:
            return "Ratio(...)"

    assert format_value(Ratio(0.5)) == "0.5"
    loop: list = [1]
    loop.append(loop)
    assert format_value(loop) == "[1, [...]]"
    assert format_value(10**5000).startswith("<integer of")  # repr() of it would raise


values = st.one_of(
    st.booleans(),
    st.integers(),
    st.integers(min_value=-10**300, max_value=10**300),
    st.floats(allow_nan=False, allow_infinity=False),
    st.text(),
)


@PROPERTY
@given(values)
def test_round_trip(value):
    text = f"a.b = {format_value(value)}"
    assert same(parse(text).value, value)
    assert same(parse(f"a.b({format_value(value)}, {format_value(value)})").args, (value, value))


# ---- no input makes parse raise anything but ScriptError ---------------------------------

def parses_or_script_error(text: str) -> None:
    try:
        result = parse(text)
    except ScriptError as error:
        assert isinstance(error.message, str) and error.message
        assert 1 <= error.column <= min(len(text), MAX_LENGTH) + 1
        assert str(error) == f"column {error.column}: {error.message}"
    else:
        assert isinstance(result, (Components, Help, GetProperty, SetProperty, CallOperation))


@PROPERTY
@given(st.text())
def test_arbitrary_text(text):
    parses_or_script_error(text)


@PROPERTY
@given(st.text(alphabet=st.characters(codec="utf-8"), max_size=200) | st.binary().map(lambda b: b.decode("latin-1")))
def test_arbitrary_characters(text):
    parses_or_script_error(text)


TOKENS = ["servo", "kp", "help", "components", "true", "false", "nan", ".", "=", "(", ")", ",", " ", "\t",
          "3", "-2", "2.5", "1e-3", ".5", "5.", "1e999", "+", "-", "e", '"', "'", '"x"', "'y'", "\\", "\\n",
          "\\q", "\n", "\x00", "é", "9" * 5000]


@PROPERTY
@given(st.lists(st.sampled_from(TOKENS), max_size=12).map("".join))
def test_token_soup(text):
    parses_or_script_error(text)


@PROPERTY
@given(st.lists(st.sampled_from(TOKENS), max_size=12).map("".join), st.integers(0, 50))
def test_valid_command_with_noise(noise, position):
    text = 'fsm.request_state("Calibrate Offsets", 3, true)'
    position = min(position, len(text))
    parses_or_script_error(text[:position] + noise + text[position:])


# ---- no evaluation -----------------------------------------------------------------------

def test_no_eval_or_exec():
    source = Path(scripting.__file__).read_text(encoding="utf-8")
    for word in ("eval(", "exec(", "literal_eval", "import ast", "__import__", "compile(\""):
        assert word not in source, word
    banned = {"eval", "exec", "compile", "literal_eval", "__import__", "getattr", "globals", "locals"}
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Name):
            assert node.id not in banned, node.id
        if isinstance(node, ast.Attribute):
            assert node.attr not in banned - {"compile"}, node.attr  # re.compile is fine
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            modules = [alias.name for alias in node.names] + [getattr(node, "module", None)]
            assert not {"ast", "builtins", "importlib"} & set(modules), modules
