"""Record types (compiler/records.py; issue 33 item 3; RAPID's RECORD, KRL's STRUC): declared
once, made by their type's name, read and assigned field by field through any path of
indices and fields, values (a stored or passed record is a copy), function results and
'var' parameters, persistent; the object code's record table and its verifier; the words
'record' and 'endrecord' take no name a program already uses."""
from __future__ import annotations

import copy
import dataclasses
import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler.disasm import instructions
from compiler.objcode import OP, ObjectCodeError, RecordInfo, decode, encode, verify
from compiler.values import Record, format_value
from runtime.loop.persistence import fitted, plain_of, value_of
from runtime.loop.vm import VMStatus

from conftest import examples
from test_persistent import Keeping
from test_vm import DISPATCHES, compile_text, program_text, run

RECORDS = """
record part_t
  name : string;
  height, width : real;
endrecord;
record slot_t
  part : part_t;
  full : bool;
  home : joint;
endrecord;
record pallet_t
  slots : array[1..3] of slot_t;
  count : integer;
endrecord;
"""


@pytest.fixture(params=DISPATCHES)
def dispatch(request):
    return request.param


def texts(tmp_path, body, decls, dispatch="inline"):
    machine, host = run(compile_text(tmp_path, program_text(body, RECORDS + decls)), dispatch=dispatch)
    assert machine.status is VMStatus.DONE, machine.error
    return host.texts


def test_a_record_is_a_value_read_and_assigned_through_any_path(tmp_path, dispatch):
    decls = """var p, q : pallet_t;
    one : part_t := part_t("bolt", 12, 4.5);"""
    body = """
      p.slots[2].part.height := 12.5;
      p.slots[2].home[3] := 45;
      p.count := p.count + 1;
      q := p;
      q.slots[2].part.name := "nut";
      q.slots[1] := p.slots[2];
      q.slots[1].part.width := 7;
      print p.slots[2].part, " ", q.slots[2].part.name;
      print p.slots[2].home, " ", p.count;
      print q.slots[1].part.width, " ", p.slots[2].part.width;
      print one;
    """
    assert texts(tmp_path, body, decls, dispatch) == [
        'part_t(name: "", height: 12.5, width: 0) nut',
        "joint(mainjoint(0, 0, 45, 0, 0, 0)) 1",
        "7 0",
        'part_t(name: "bolt", height: 12, width: 4.5)',
    ]


def test_functions_parameters_and_var_parameters_take_records(tmp_path, dispatch):
    decls = """var one : part_t := part_t("bolt", 12, 4.5);
    s : slot_t;
function taller(x : part_t; by : real) : part_t;
seq
  x.height := x.height + by;
  return x;
endseq
endfunction;
procedure fill(var into : slot_t; what : part_t);
seq
  into.part := what;
  into.full := true;
  what.name := "changed here only";
endseq
endprocedure;"""
    body = """
      print taller(one, 1).height, " ", one.height;
      call fill(s, one);
      print s.full, " ", s.part.name, " ", one.name;
      print taller(part_t("x", 1, 2), 0.5);
    """
    assert texts(tmp_path, body, decls, dispatch) == ["13 12", "true bolt bolt",
                                                      'part_t(name: "x", height: 1.5, width: 2)']


def test_an_array_of_records_holds_separate_records(tmp_path):
    """MAKE_ARRAY of a record element copies it for each element (no two elements alias)."""
    decls = "var parts : array[1..3] of part_t;\n  i : integer;"
    body = """
      for i := 1 to 3 do
        parts[i].height := i * 10;
      endfor;
      print parts[1].height, " ", parts[2].height, " ", parts[3].height;
    """
    assert texts(tmp_path, body, decls) == ["10 20 30"]


def test_the_words_take_no_name_a_program_uses(tmp_path):
    """'record' and 'endrecord' are names to the parser: variables so called keep working,
    in a section's first place and after another item, beside a record's declaration."""
    decls = """var record : integer := 2;
    endrecord : integer := 3;
var a : integer;
    record_count : integer;
record pair_t
  record : integer;
  endrecord_x : integer;
endrecord;
var b : pair_t;"""
    body = """
      record := record + endrecord;
      b.record := record;
      print record, " ", b;
    """
    assert texts(tmp_path, body, decls) == ["5 pair_t(record: 5, endrecord_x: 0)"]


def test_the_object_code_has_the_record_table_and_the_disassembly_names_it(tmp_path):
    program = compile_text(tmp_path, program_text('print part_t("a", 1, 2);', RECORDS))
    assert program.records[0] == RecordInfo("part_t", (("name", "string"), ("height", "real"), ("width", "real")))
    assert [r.name for r in program.records] == ["part_t", "slot_t", "pallet_t"]
    assert program.records[2].fields[0] == ("slots", "array[1..3] of slot_t")
    assert decode(encode(program)) == program
    made = [i for i in instructions(program) if i.name == "MAKE_RECORD"]
    assert made and made[0].argrepr == "part_t(name, height, width)"


# ---- the verifier ---------------------------------------------------------------------------

def _compiled(tmp_path):
    decls = "var p : slot_t;"
    return compile_text(tmp_path, program_text("p.part.height := 1.5;\nprint p.part.height, p.full;", RECORDS + decls))


@pytest.mark.parametrize("records, message", [
    ((RecordInfo("slot_t", (("part", "part_t"),)), RecordInfo("part_t", (("name", "string"),))),
     "no type of the language or of a record before it"),
    ((RecordInfo("a", (("me", "a"),)),), "no type of the language or of a record before it"),
    ((RecordInfo("a", ()),), "1..255 fields"),
    ((RecordInfo("a", (("x", "real"), ("x", "real"))),), "each named once"),
    ((RecordInfo("pose", (("x", "real"),)),), "no type of the language"),
    ((RecordInfo("a", (("x", "real"),)), RecordInfo("a", (("y", "real"),))), "given once"),
    ((RecordInfo("a", (("x", "array[1..1000] of real"),)), RecordInfo("b", (("y", "array[1..1000] of a"),))),
     "more than 100000 values"),
])
def test_a_bad_record_table_is_refused(tmp_path, records, message):
    program = dataclasses.replace(_compiled(tmp_path), records=records)
    with pytest.raises(ObjectCodeError, match=message):
        verify(program)


def test_the_verifier_types_every_field_access(tmp_path):
    program = _compiled(tmp_path)
    code = list(program.code)
    member = next(k for k, instr in enumerate(code) if instr[0] == OP.GET_MEMBER)
    for f, message in ((9, "has no field 9"),):
        bad = dataclasses.replace(program, code=tuple(code[:member] + [(OP.GET_MEMBER, f)] + code[member + 1:]))
        with pytest.raises(ObjectCodeError, match=message):
            verify(bad)
    # a field's value of another type: SET_MEMBER of a string into the real 'height'
    store = next(k for k, instr in enumerate(code) if instr[0] == OP.SET_MEMBER)
    text = len(program.constants)
    bad = dataclasses.replace(program, constants=program.constants + ("text",),
                              code=tuple(code[:store - 1] + [(OP.CONST, text)] + code[store:]))
    with pytest.raises(ObjectCodeError, match="must be real, not string"):
        verify(bad)
    # a global typed with a record type the table does not have
    bad = dataclasses.replace(program, globals=(("p", "slot_u"),) + program.globals[1:])
    with pytest.raises(ObjectCodeError, match="no type of the language"):
        verify(bad)


# ---- persistent records ----------------------------------------------------------------------

def test_a_persistent_record_keeps_its_value_across_runs_and_a_changed_type_starts_afresh(tmp_path, dispatch):
    decls = "var persistent\n  last : slot_t;"
    body = 'print last.part.name, " ", last.full;\nlast.part.name := "kept";\nlast.full := true;'
    program = compile_text(tmp_path, program_text(body, RECORDS + decls))
    machine, host = run(program, Keeping(), dispatch=dispatch)
    assert machine.status is VMStatus.DONE and host.texts == [" false"]
    machine, again = run(program, Keeping(host.store), dispatch=dispatch)
    assert again.texts == ["kept true"]
    # the record type gains a field: the kept value no longer fits, and the log says so
    changed = compile_text(tmp_path, program_text(body, RECORDS.replace("full : bool;", "full : bool;\n  n : integer;")
                                                 + decls))
    machine, third = run(changed, Keeping(host.store), dispatch=dispatch)
    assert machine.status is VMStatus.DONE
    assert "does not fit its declaration now" in third.texts[0] and third.texts[1] == " false"


_SCALARS = st.one_of(st.integers(-2**63, 2**63 - 1), st.floats(allow_nan=False, allow_infinity=False),
                     st.booleans(), st.text(max_size=10))
_NAMES = st.lists(st.from_regex(r"[a-z][a-z0-9_]{0,6}", fullmatch=True), min_size=1, max_size=4, unique=True)


@st.composite
def _record(draw, inner):
    names = draw(_NAMES)
    return Record(draw(st.from_regex(r"[a-z]{1,6}_t", fullmatch=True)), tuple(names),
                  [draw(inner) for _ in names])


_VALUES = st.recursive(_SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=3), _record(inner)), max_leaves=10)


@settings(max_examples=examples(60), deadline=None)
@given(_VALUES)
def test_a_record_round_trips_through_the_store_and_fits_itself(value):
    back = value_of(json.loads(json.dumps(plain_of(value))))
    assert back == value and format_value(back) == format_value(value)
    assert fitted(back, value) == value


# ---- value semantics, searched -----------------------------------------------------------------

_PATHS = [  # (path in L-IRL, the model's keys, a value's L-IRL text and Python value)
    (".count", ("count",), "int"),
    (".slots[{i}].full", ("slots", "i", "full"), "bool"),
    (".slots[{i}].part.height", ("slots", "i", "part", "height"), "real"),
    (".slots[{i}].part.name", ("slots", "i", "part", "name"), "string"),
    (".slots[{i}].home[{k}]", ("slots", "i", "home", "k"), "real"),
]
_OPS = st.one_of(
    st.tuples(st.just("set"), st.sampled_from("ab"), st.integers(0, len(_PATHS) - 1), st.integers(1, 3),
              st.integers(1, 6), st.integers(-99, 99)),
    st.tuples(st.just("copy"), st.sampled_from(["a := b", "b := a", "a.slots[1] := b.slots[2]",
                                                "b.slots[3].part := a.slots[1].part"])),
)


def _model_set(model, keys, i, k, value):
    target = model
    for key in keys[:-1]:
        target = target[i - 1] if key == "i" else target[key]
    last = keys[-1]
    if last == "k":
        target[k - 1] = value
    else:
        target[last] = value


def _model():
    slot = {"part": {"name": "", "height": 0.0, "width": 0.0}, "full": False, "home": [0.0] * 6}
    return {"slots": [copy.deepcopy(slot) for _ in range(3)], "count": 0}


@settings(max_examples=examples(25), deadline=None)
@given(st.lists(_OPS, min_size=1, max_size=12))
def test_records_behave_as_values_under_any_sequence_of_assignments(tmp_path_factory, ops):
    """Random assignments through paths and whole copies, against a model of deep copies: no
    two variables ever share a part."""
    models = {"a": _model(), "b": _model()}
    lines = []
    for op in ops:
        if op[0] == "copy":
            statement = op[1]
            lines.append(statement + ";")
            left, right = (side.strip() for side in statement.split(":="))
            src = copy.deepcopy(_resolve(models, right))
            _assign(models, left, src)
            continue
        _, var, p, i, k, n = op
        path, keys, kind = _PATHS[p]
        text, value = {"int": (str(n), n), "bool": (("true", True) if n > 0 else ("false", False)),
                       "real": (f"{n}.5", float(f"{n}.5")), "string": (f'"s{n}"', f"s{n}")}[kind]
        lines.append(f"{var}{path.format(i=i, k=k)} := {text};")
        _model_set(models[var], keys, i, k, value)
    lines.append('print a;\nprint b;')
    tmp = tmp_path_factory.mktemp("records")
    machine, host = run(compile_text(tmp, program_text("\n".join(lines), RECORDS + "var a, b : pallet_t;")))
    assert machine.status is VMStatus.DONE, machine.error
    assert host.texts == [_shown(models["a"]), _shown(models["b"])]


def _resolve(models, text):
    var, *rest = text.split(".")
    value = models[var]
    for part in rest:
        name, _, index = part.partition("[")
        value = value[name]
        if index:
            value = value[int(index.rstrip("]")) - 1]
    return value


def _assign(models, text, src):
    var, *rest = text.split(".")
    if not rest:
        models[var] = src
        return
    holder = _resolve(models, ".".join([var] + rest[:-1]))
    name, _, index = rest[-1].partition("[")
    if index:
        holder[name][int(index.rstrip("]")) - 1] = src
    else:
        holder[name] = src


def _shown(model):
    def number(x):
        return format_value(float(x))

    def slot(s):
        part = s["part"]
        return (f'slot_t(part: part_t(name: {format_value(part["name"])}, height: {number(part["height"])}, '
                f'width: {number(part["width"])}), full: {format_value(s["full"])}, '
                f'home: joint(mainjoint({", ".join(number(v) for v in s["home"])})))')
    return f'pallet_t(slots: [{", ".join(slot(s) for s in model["slots"])}], count: {model["count"]})'


def test_a_var_parameter_takes_an_element_or_a_field_and_gives_it_back_where_it_was_taken(tmp_path, dispatch):
    """RAPID's INOUT of a record's component: the path's indices are computed once, at the
    call, so a procedure that changes the index variable still gives the value back into
    the element it was passed."""
    decls = """var slots : array[1..3] of slot_t;
    i : integer;
    persistent_free : integer;
procedure fill_next(var s : slot_t);
seq
  s.full := true;
  i := i + 1;
endseq
endprocedure;
procedure grow(var h : real; by : real);
seq
  h := h + by;
endseq
endprocedure;"""
    body = """
      i := 1;
      call fill_next(slots[i]);
      call fill_next(slots[i]);
      call grow(slots[2].part.height, 2.5);
      call grow(slots[2].home[3], 1);
      print slots[1].full, " ", slots[2].full, " ", slots[3].full, " ", i, " ", slots[2].part.height;
    """
    with pytest.raises(AssertionError, match="or an element or a field of one"):  # (an axis of a joint is not)
        texts(tmp_path, body, decls, dispatch)
    body = body.replace("      call grow(slots[2].home[3], 1);\n", "")
    assert texts(tmp_path, body, decls, dispatch) == ["true true false 3 2.5"]


def test_a_module_declares_a_record_type_its_importers_use(tmp_path):
    (tmp_path / "parts.irl").write_text("module parts;\n" + RECORDS + """
function made(n : string) : part_t;
seq
  return part_t(n, 10, 1);
endseq
endfunction;
endmodule;
""")
    text = program_text("p := made(\"x\");\np.height := p.height * 2;\nprint p;",
                        'import "parts.irl";\nvar p : part_t;')
    machine, host = run(compile_text(tmp_path, text))
    assert host.texts == ['part_t(name: "x", height: 20, width: 1)']


def test_an_operators_value_for_a_persistent_record_fits_only_its_type_and_fields():
    """persistent_set's rule (runtime.loop.robotloop: fitted of value_of): the plain form irl
    persistent --json shows, with an integer where a real is taken as a real; another type's
    name, a field missing or renamed, a value of another type are not taken."""
    like = Record("part_t", ("name", "height"), ["bolt", 12.5])
    good = value_of(["record", "part_t", {"name": "nut", "height": 13}])
    assert fitted(good, like) == Record("part_t", ("name", "height"), ["nut", 13.0])
    assert type(fitted(good, like)[1]) is float
    for plain in (["record", "slot_t", {"name": "nut", "height": 13}], ["record", "part_t", {"name": "nut"}],
                  ["record", "part_t", {"nom": "nut", "height": 13}], ["record", "part_t", {"name": 3, "height": 13}],
                  ["array", ["nut", 13]]):
        assert fitted(value_of(plain), like) is None, plain
