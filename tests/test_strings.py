"""The string functions (compiler/semantics.py STRING_BUILTINS; issue 33 item 3): what
they compute (property tests against Python's own string operations), at run time in the
VM and folded by the compiler, and a program's own function of the same name first."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler.semantics import EvalError, call_builtin
from runtime.loop.vm import VMStatus

from test_vm import DISPATCHES, run_source
from conftest import examples

TEXT = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=40)


@settings(max_examples=examples(200), deadline=None, derandomize=True, database=None)
@given(TEXT, TEXT)
def test_property_find_part_and_length_agree(s, part):
    """str_find gives where str_part finds the part again; 0 exactly when it does not occur."""
    at = call_builtin("str_find", [s, part])
    assert call_builtin("str_len", [s]) == len(s)
    if part in s:
        assert at >= 1 and call_builtin("str_part", [s, at, len(part)]) == part
        assert s.index(part) == at - 1  # (the first place)
    else:
        assert at == 0


@settings(max_examples=examples(200), deadline=None, derandomize=True, database=None)
@given(TEXT, st.integers(-3, 45), st.integers(-3, 45))
def test_property_str_part_is_the_slice_or_an_error_naming_the_range(s, first, count):
    try:
        got = call_builtin("str_part", [s, first, count])
    except EvalError as exc:
        assert not (count >= 0 and 1 <= first <= len(s) + 1 and first + count - 1 <= len(s))
        assert str(exc).startswith("str_part: ")
        return
    assert got == s[first - 1:first - 1 + count] and len(got) == count


@settings(max_examples=examples(300), deadline=None, derandomize=True, database=None)
@given(st.floats(allow_nan=False, allow_infinity=False, min_value=-1e15, max_value=1e15), st.integers(0, 15))
def test_property_num_to_str_rounds_to_its_decimals_and_reads_back(x, decimals):
    text = call_builtin("num_to_str", [x, decimals])
    assert "e" not in text.lower() and text != "-0" and not text.startswith("-0.") or text.strip("-0.")
    assert (len(text.split(".")[1]) if "." in text else 0) == decimals
    back = call_builtin("str_to_num", [text])
    assert abs(back - x) <= 0.5 * 10.0 ** -decimals * (1 + 1e-9) + abs(x) * 1e-15


def test_num_to_str_rounds_half_away_from_zero_and_never_says_minus_zero():
    assert [call_builtin("num_to_str", [x, d]) for x, d in ((2.5, 0), (-2.5, 0), (0.125, 2), (-0.04, 1), (7, 2),
                                                            (1e308, 0))][:5] == ["3", "-3", "0.13", "0.0", "7.00"]
    assert call_builtin("num_to_str", [1e308, 15]) == "1" + "0" * 308 + "." + "0" * 15  # (the shortest digits)


@pytest.mark.parametrize("text", ["12", " -1.5 ", "+.5", "3e2", "1E-3"])
def test_str_to_num_reads_what_a_number_literal_spells(text):
    assert call_builtin("str_to_num", [text]) == pytest.approx(float(text))


@pytest.mark.parametrize("text", ["", "12 mm", "1e999", "nan", "inf", "0x10", "1,5", "--1"])
def test_str_to_num_refuses_what_is_not_a_finite_number(text):
    with pytest.raises(EvalError):
        call_builtin("str_to_num", [text])


@pytest.mark.parametrize("dispatch", DISPATCHES)
def test_in_the_vm_a_message_is_built_from_strings_and_numbers(tmp_path, dispatch):
    body = """
      s := "pallet 12 done";
      n := str_to_num(str_part(s, 8, 2));
      print "layer " + num_to_str(n / 8, 2) + " of " + num_to_str(str_len(s), 0) + ", done at " +
            num_to_str(str_find(s, "done"), 0);
      print str_part(s, k, 5);
    """
    machine, host = run_source(tmp_path, body, "var s: string;\nvar n: real;\nvar k: integer := 14;",
                               dispatch=dispatch)
    assert host.texts[0] == "layer 1.50 of 14, done at 11"
    assert machine.status == VMStatus.ERROR and "str_part: characters 14..18 of a string of 14" in str(machine.error)


def test_a_programs_own_function_of_the_same_name_is_called_instead(tmp_path):
    decls = "function str_len(x: integer): integer;\nseq\n  return x * 2;\nendseq\nendfunction;"
    machine, host = run_source(tmp_path, "print str_len(21);", decls)
    assert machine.status == VMStatus.DONE and host.texts == ["42"]
    assert math.isfinite(call_builtin("str_to_num", ["1e308"]))
