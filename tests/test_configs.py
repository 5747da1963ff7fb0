"""Configurations: a pose target that names the arm's configuration (compiler/configs.py,
docs/language.md "Configurations").

* the declarations: turns, formatting, config_of, the MAKE_CONFIG operand;
* the language: config(...)'s contextual words, a program's own `config` shadowing the
  constructor (every such program means what it meant), pose arithmetic's rule;
* object code: round trips of configurations and poses with one; forged values and
  operands refused by the verifier, never a traceback;
* the runtime: ptp reaches exactly the configuration and turns named, or is refused with
  a reason (never raises); lin and circ refuse a target naming another configuration;
  naming what the default rule would choose changes nothing;
* irl pose: the literal it prints, compiled and planned from anywhere, reaches exactly
  its joints on every shipped arm (hypothesis); the rounded literal resolves to the same
  configuration; --tool and --base; exit statuses; the endpoint form against a server;
* end to end: programs with configurations run with irl run.
"""
from __future__ import annotations

import io
import json
import math
import re
from pathlib import Path

import msgpack
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from compiler.clauses import Motion
from compiler.configs import (ELBOW_DOWN, GROUPS, MAX_OPERAND, SHOULDER_BACK, TURN_AXES, TURNS_FLAG, WORDS,
                              WRIST_FLIP, Config, config_of, format_config, from_operand, in_turn, operand_of,
                              operand_problem, turn_of, turn_range, value_problem)
from compiler.driver import compile_source
from compiler.frames import pose_of
from compiler.objcode import FORMAT_VERSION, OP, ObjectCodeError, Program, decode, encode, load, verify
from compiler.semantics import binary, call_builtin, compose
from compiler.spec import load_spec
from compiler.values import Pose, Position, Quat, Rpy, format_value, from_plain, to_plain
from runtime.motion.teach import PoseError, pose_literal
from runtime.motion.kinematics import Kinematics, KinematicsError, configuration_name
from runtime.motion.moves import Frames, MovePlanner, MoveRequest

from conftest import PROGRAMS, ROOT, SPEC, SPEC_PATH, objcode, run_cli, submit, wait_end, examples

ARMS = [PROGRAMS / "lola15.spc", *sorted((PROGRAMS / "robots").glob("*.spc"))]
_SPECS = {path: load_spec(path) for path in ARMS}
_KINEMATICS = {path: Kinematics(spec) for path, spec in _SPECS.items()}
_PLANNERS = {path: MovePlanner(spec.axes, spec.main_axes, "jerk", _KINEMATICS[path]) for path, spec in _SPECS.items()}
KIN = _KINEMATICS[SPEC_PATH]
HOME = (0.0, -30.0, 30.0, 0.0, 60.0, 0.0)
DOWN = (180.0, 30.0, 180.0)


def arm_joints(path: Path):
    """Joint values within the limits of the arm's six main axes."""
    limits = _KINEMATICS[path].limits
    return st.tuples(*(st.floats(lo, hi, allow_nan=False, allow_infinity=False) for lo, hi in limits))


def clear_of_singularities(kin: Kinematics, q) -> bool:
    shoulder, elbow, wrist = kin.singularity_margins(q)
    return shoulder > 5.0 and elbow > 0.02 and wrist > 0.02


def clear_of_turn_boundaries(q) -> bool:
    """A1, A4, A6 on a turn's boundary or clear of it: not within 1e-8 deg below one (a
    value a hair below a turn's end is its other end, the same pose: docs/language.md,
    known limitations)."""
    return all(not 0.0 < 360.0 * math.ceil((q[i] + 180.0) / 360.0) - (q[i] + 180.0) < 1e-8 for i in TURN_AXES)


def compiled_constant(text: str, spec_path: Path = SPEC_PATH):
    """The value the compiler folds ``text`` to (a constant of a small program)."""
    source = (f'program t;\nsystem_specification "{spec_path}";\nconst\n  k := {text};\nseq\n  print k;\nendseq\n'
              "endprogram;\n")
    result = compile_source(source, "t.irl")
    assert result.ok, [d.message for d in result.diagnostics]
    code = result.program.code
    assert [c[0] for c in code[:2]] == [OP.CONST, OP.PRINT]  # (folded: one constant)
    return result.program.constants[code[0][1]]


CONFIGS = st.builds(Config, st.sampled_from([None, 0, 1]), st.sampled_from([None, 0, 1]), st.sampled_from([None, 0, 1]),
                    st.none() | st.tuples(*(st.integers(-(2 ** 63), 2 ** 63 - 1),) * 3))


# ---- the declarations ------------------------------------------------------------------------------

@given(q=st.floats(-1e6, 1e6, allow_nan=False))
def test_a_turn_holds_its_values(q):
    k = turn_of(q)
    lo, hi = turn_range(k)
    assert lo <= q < hi
    assert in_turn(q, k) and not in_turn(q, k + 1) or abs(q - hi) <= 1e-6


def test_the_turns_of_the_brief():
    assert [turn_of(q) for q in (-180.0, -179.9, 0.0, 179.999, 180.0, 539.9, 540.0, -180.01, -540.0)] == \
        [0, 0, 0, 0, 1, 1, 2, -1, -1]
    assert turn_range(1) == (180.0, 540.0)


def test_the_bits_are_the_kinematics_own():
    from runtime.motion import kinematics

    assert (kinematics.SHOULDER_BACK, kinematics.ELBOW_DOWN, kinematics.WRIST_FLIP) == \
        (SHOULDER_BACK, ELBOW_DOWN, WRIST_FLIP)
    assert kinematics.SHOULDER_BACK is SHOULDER_BACK  # one declaration, not a copy
    assert [g.bit for g in GROUPS] == [1, 2, 4]
    assert set(WORDS) == {"front", "back", "elbow_up", "elbow_down", "noflip", "flip"}
    assert not re.search(r"(?m)^(SHOULDER_BACK|ELBOW_DOWN|WRIST_FLIP)\s*=",
                         (ROOT / "runtime" / "motion" / "kinematics.py").read_text())


@given(config=CONFIGS)
def test_format_config_is_source_text_that_compiles_to_the_same_value(config):
    assume(config.turns is None or all(abs(k) < 2 ** 40 for k in config.turns))
    text = format_config(config)
    assert re.fullmatch(r"config\(([a-z_]+|-?\d+)?(, ([a-z_]+|-?\d+))*\)", text)
    folded = compiled_constant(text)
    assert folded == config and str(folded) == text


def test_formats():
    assert format_config(Config(0, 0, 1, (0, 0, -1))) == "config(front, elbow_up, flip, 0, 0, -1)"
    assert format_config(Config(wrist=1)) == "config(flip)"
    assert format_config(Config()) == "config()"
    assert format_config(Config(turns=(1, 0, 0))) == "config(1, 0, 0)"


@given(cid=st.integers(0, 7), q=st.tuples(*(st.floats(-1000, 1000, allow_nan=False),) * 6))
def test_config_of_gives_every_group_and_the_turns(cid, q):
    config = config_of(cid, q)
    assert config.mask == 7 and config.bits == cid and config.matches(cid)
    assert not any(config.matches(other) for other in range(8) if other != cid)
    assert config.turns == tuple(math.floor((q[i] + 180.0) / 360.0) for i in (0, 3, 5))
    assert configuration_name(cid) == ", ".join(g.meanings[1 if cid & g.bit else 0] for g in GROUPS)


def test_config_of_refuses_what_is_no_configuration():
    for bad in (8, -1, 2.0, True):
        with pytest.raises(ValueError):
            config_of(bad, (0.0,) * 6)


def test_every_operand_round_trips_and_the_others_are_refused():
    valid = 0
    for value in range(-2, MAX_OPERAND + 3):
        problem = operand_problem(value)
        fields = [(value >> (2 * i)) & 3 for i in range(3)]
        if 0 <= value <= MAX_OPERAND and 3 not in fields:
            assert problem is None, value
            config = from_operand(value, (1, 2, 3) if value & TURNS_FLAG else None)
            assert operand_of(config, config.turns is not None) == value
            valid += 1
        else:
            assert problem is not None and str(value) in problem, value
    assert valid == 3 ** 3 * 2


# ---- the language ----------------------------------------------------------------------------------

def _output(source: str, tmp_path: Path, name: str = "p") -> list[str]:
    path = tmp_path / f"{name}.irl"
    path.write_text(source.replace("SPEC", str(SPEC_PATH)), encoding="utf-8")
    code, out, err = run_cli("run", path, "--json")
    assert code == 0, out + err
    summary = json.loads(out)
    assert summary["fault"] is None, summary["fault"]
    return [entry["text"] for entry in summary["log"]]


SHADOWING = {
    "constant": """program s; system_specification "SPEC";
const config := 3;
var front, flip, up : integer;
function twice(x : integer) : integer; seq return 2 * x; endseq endfunction;
seq front := config + twice(config); flip := front * 2; up := flip - 1; print front, " ", flip, " ", up; endseq
endprogram;""",
    "function": """program s; system_specification "SPEC";
var n : integer;
function config(a, b : integer) : integer; seq return a * 10 + b; endseq endfunction;
procedure show(flip : integer); seq print "flip ", flip, " ", config(flip, 2); endseq endprocedure;
seq n := config(4, 5); call show(n); endseq
endprogram;""",
    "variable": """program s; system_specification "SPEC";
var config : pose;
seq config := pose(pos(1, 2, 3), rpy(0, 0, 0)); print config, " ", config.x + config.z; endseq
endprogram;""",
    "procedure": """program s; system_specification "SPEC";
procedure config; seq print "the procedure"; endseq endprocedure;
seq call config; call config(); endseq
endprogram;""",
    "parameter": """program s; system_specification "SPEC";
function f(config : real; back : integer) : real; seq return config * back; endseq endfunction;
seq print f(1.5, 4); endseq
endprogram;""",
}


@pytest.mark.parametrize("kind", list(SHADOWING))
def test_a_program_that_declares_config_means_what_it_meant(kind, tmp_path):
    """Each program runs and prints what the same program with its own 'config' renamed
    (a name no constructor has) prints: the declaration shadows the constructor."""
    source = SHADOWING[kind]
    renamed = re.sub(r"\bconfig\b", "cfg_", source)
    assert renamed != source
    assert _output(source, tmp_path, "a") == _output(renamed, tmp_path, "b")


def test_a_module_may_declare_config(tmp_path):
    (tmp_path / "m.irl").write_text("module m;\nfunction config(x : integer) : integer;\nseq\n  return x + 1;\nendseq\n"
                                    "endfunction;\nendmodule;\n", encoding="utf-8")
    assert _output('program s; system_specification "SPEC";\nimport "m.irl";\nseq print config(41); endseq\n'
                   "endprogram;", tmp_path) == ["42"]


def test_words_are_words_only_inside_config(tmp_path):
    lines = _output("""program w; system_specification "SPEC";
var front, back, flip, noflip, elbow_up, elbow_down, up, down : integer; c : config;
seq
  front := 1; back := 2; flip := 3; noflip := 4; elbow_up := 5; elbow_down := 6; up := 7; down := 8;
  c := config(back, flip, front + back, elbow_down - 6, -flip);
  print c, " ", front + back + flip + noflip + elbow_up + elbow_down + up + down;
  c := config(FLIP, Elbow_Down);
  print c, " ", c = config(elbow_down, flip), " ", c <> config(flip);
endseq
endprogram;""", tmp_path)
    assert lines == ["config(back, flip, 3, 0, -3) 36", "config(elbow_down, flip) true true"]


def test_a_misspelled_word_gets_a_hint_and_every_error_its_argument(tmp_path):
    path = tmp_path / "e.irl"
    path.write_text(f'program e; system_specification "{SPEC_PATH}";\nvar c : config; x : real;\nseq\n'
                    "  c := config(elbow_dwn);\n  c := config(front, 1, 2, x);\n  c := config(flip, back, noflip);\n"
                    "endseq\nendprogram;\n", encoding="utf-8")
    code, out, err = run_cli("check", path)
    assert code == 1
    assert "4:15: error: unknown configuration word 'elbow_dwn'" in err and "did you mean 'elbow_down'?" in err
    assert "5:28: error: a turn number must be an integer, not real" in err
    assert "6:27: error: 'noflip': the wrist is already given ('flip')" in err


def test_pose_arithmetic_keeps_the_pose_operands_configuration():
    c = Config(1, None, 0, (0, 1, -1))
    p = Pose(Position(800.0, 0.0, 300.0), Rpy(*DOWN), c)
    frame = Pose(Position(10.0, 20.0, 30.0), Rpy(0.0, 0.0, 10.0), Config(wrist=1))
    v = Position(1.0, 2.0, 3.0)
    assert binary("+", p, v).config == c and binary("-", p, v).config == c
    assert call_builtin("tool_offset", [p, v]).config == c
    assert binary("*", frame, p).config == c  # the right operand's: the target placed in the frame
    assert binary("*", p, frame).config == Config(wrist=1)
    assert binary("*", frame, Pose(Position(0.0, 0.0, 0.0), Rpy(0.0, 0.0, 0.0))).config is None
    assert call_builtin("inv", [p]).config is None
    assert binary("*", p, v) == binary("*", Pose(p.position, p.orientation), v)  # a point has none
    # the geometry is the same with or without a configuration
    bare = Pose(p.position, p.orientation)
    assert binary("*", frame, p).position == binary("*", frame, bare).position
    assert binary("=", p, bare) is False and binary("=", p, Pose(p.position, p.orientation, c)) is True


def test_the_compiler_and_the_vm_agree_on_configurations(tmp_path):
    """Folded constants and values computed by the VM print alike."""
    body = ("pose(pos(800, 0, 300), rpy(180, 30, 180), config(back, 0, 1, -1)) + pos(1, 2, 3)",
            "pose(pos(10, 0, 0), rpy(0, 0, 90)) * pose(pos(1, 0, 0), rpy(0, 0, 0), config(flip))",
            "inv(pose(pos(10, 0, 0), rpy(0, 0, 90), config(flip)))",
            "tool_offset(pose(pos(1, 2, 3), rpy(0, 0, 0), config(elbow_down)), pos(0, 0, 1))",
            "pose(pos(1, 2, 3), rpy(0, 0, 0), config()) = pose(pos(1, 2, 3), rpy(0, 0, 0))")
    folded = [format_value(compiled_constant(text)) for text in body]
    # the same expressions with every number plus a variable holding 0: computed by the VM
    unfolded = [re.sub(r"\b(\d+)\b", r"(\1 + z)", text) for text in body]
    computed = _output('program v; system_specification "SPEC";\nvar z : integer;\nseq\n'
                       + "".join(f"  print {text};\n" for text in unfolded) + "endseq\nendprogram;", tmp_path)
    assert computed == folded
    # and with turns known only at run time (MAKE_CONFIG), the same value as folded
    lines = _output('program v; system_specification "SPEC";\nvar k : integer;\nseq\n  k := -1;\n'
                    "  print pose(pos(1, 2, 3), rpy(0, 0, 0), config(back, noflip, k + 1, k, 2 * k)) = "
                    "pose(pos(1, 2, 3), rpy(0, 0, 0), config(back, noflip, 0, -1, -2));\n"
                    "  print config(elbow_up, k, k, k);\nendseq\nendprogram;", tmp_path, "w")
    assert lines == ["true", "config(elbow_up, -1, -1, -1)"]


# ---- object code -----------------------------------------------------------------------------------

def _program(constants=(), code=((OP.END,),), globals_=()) -> Program:
    return Program("t", "t.irl", "lola_15", SPEC.hash, ("lola_15",), tuple(constants), tuple(code),
                   ((0, 1, 1),), tuple(globals_))


POSES = st.builds(Pose, st.builds(Position, *(st.floats(-1e4, 1e4),) * 3),
                  st.builds(Rpy, *(st.floats(-180, 180),) * 3) | st.just(Quat(1.0, 0.0, 0.0, 0.0)),
                  st.none() | CONFIGS.filter(lambda c: not c.free))


@given(values=st.lists(CONFIGS | POSES, min_size=1, max_size=6))
def test_configurations_and_poses_with_one_round_trip(values):
    program = _program(values)
    verify(program)
    again = decode(encode(program))
    assert again.constants == program.constants
    assert [from_plain(to_plain(v)) for v in values] == values


def test_a_program_without_configurations_encodes_as_before():
    """A pose without a configuration is two items, as before there were any."""
    assert to_plain(Pose(Position(1.0, 2.0, 3.0), Rpy(0.0, 0.0, 0.0))) == ["pose", ["pos", 1.0, 2.0, 3.0],
                                                                          ["rpy", 0.0, 0.0, 0.0]]


def _with_constants(constants: list) -> bytes:
    """Object bytes whose body has these (plain, possibly forged) constants."""
    data = encode(_program())
    body = msgpack.unpackb(data[10:], raw=False)
    body["constants"] = constants
    raw = msgpack.packb(body, use_bin_type=True)
    import struct
    import zlib

    return struct.pack(">4sHI", b"IRLO", FORMAT_VERSION, zlib.crc32(raw)) + raw


FORGED = [["config", 2, None, None, None], ["config", True, None, None, None], ["config", None, None, -1, None],
          ["config", None, None, None, [0, 0]], ["config", None, None, None, [0, 0, 1.5]],
          ["config", None, None, None, [0, True, 0]], ["config", None, None, None, [0, 0, 2 ** 63]],
          ["config", None, None, None], ["config", None, None, None, 7], ["config", "front", None, None, None],
          ["pose", ["pos", 1, 2, 3], ["rpy", 0, 0, 0], ["pos", 1, 2, 3]],
          ["pose", ["pos", 1, 2, 3], ["rpy", 0, 0, 0], ["config", 3, None, None, None]],
          ["pose", ["pos", 1, 2, 3], ["rpy", 0, 0, 0], ["config", None, None, None, None], 5],
          ["config", None, None, None, ["pose", ["pos", 1, 2, 3], ["rpy", 0, 0, 0]]]]


@pytest.mark.parametrize("constant", FORGED, ids=range(len(FORGED)))
def test_forged_configuration_constants_are_refused(constant, tmp_path):
    data = _with_constants([constant])
    with pytest.raises(ObjectCodeError, match=r"constant 0: (config|pose)"):
        load(data)
    path = tmp_path / "f.irlo"
    path.write_bytes(data)
    code, out, err = run_cli("dis", path)
    assert code == 1 and "invalid object code: constant 0:" in err and "Traceback" not in out + err


@pytest.mark.parametrize("config", [Config(shoulder=2), Config(elbow=True), Config(turns=(0, 0)),
                                    Config(turns=[0, 0, 0]), Config(turns=(0, 0, 0.5)), Config(wrist="flip")])
def test_forged_configuration_objects_are_refused_by_the_verifier(config):
    for constant in (config, Pose(Position(0.0, 0.0, 0.0), Rpy(0.0, 0.0, 0.0), config)):
        with pytest.raises(ObjectCodeError, match="constant 0: not an L-IRL configuration"):
            verify(_program([constant]))
    assert value_problem(config) is not None


@pytest.mark.parametrize("operand, message", [
    (3, "names the shoulder twice"), (12, "names the elbow twice"), (0b110000, "names the wrist twice"),
    (128, "out of range"), (-1, "out of range"), (2 ** 31, "out of range")])
def test_forged_make_config_operands_are_refused(operand, message, tmp_path):
    program = _program(code=((OP.MAKE_CONFIG, operand), (OP.STORE_GLOBAL, 0), (OP.END,)),
                       globals_=(("c", "config"),))
    with pytest.raises(ObjectCodeError, match=f"MAKE_CONFIG operand words: .*{message}"):
        verify(program)
    path = tmp_path / "f.irlo"
    path.write_bytes(encode(program))
    code, out, err = run_cli("dis", path)
    assert code == 1 and message in err and "Traceback" not in out + err


def test_the_verifier_types_configurations():
    ok = _program([1, 0.5, Position(0.0, 0.0, 0.0), Rpy(0.0, 0.0, 0.0)],
                  code=((OP.CONST, 0), (OP.CONST, 0), (OP.CONST, 0), (OP.MAKE_CONFIG, TURNS_FLAG | 2),
                        (OP.STORE_GLOBAL, 0), (OP.CONST, 2), (OP.CONST, 3), (OP.LOAD_GLOBAL, 0),
                        (OP.MAKE_POSE_CONFIG,), (OP.STORE_GLOBAL, 1), (OP.END,)),
                  globals_=(("c", "config"), ("p", "pose")))
    verify(ok)
    real_turn = ok.code[:1] + ((OP.CONST, 1),) + ok.code[2:]
    with pytest.raises(ObjectCodeError, match="MAKE_CONFIG: value 2 of 3 must be integer, not real"):
        verify(_program(ok.constants, real_turn, ok.globals))
    no_config = ok.code[:7] + ((OP.CONST, 0),) + ok.code[8:]
    with pytest.raises(ObjectCodeError, match="MAKE_POSE_CONFIG: value 3 of 3 must be config, not integer"):
        verify(_program(ok.constants, no_config, ok.globals))
    missing = ok.code[1:]
    with pytest.raises(ObjectCodeError, match="MAKE_CONFIG needs 3 stack values"):
        verify(_program(ok.constants, missing, ok.globals))
    with pytest.raises(ObjectCodeError, match="global 0 .* has type 'configuration'"):
        verify(_program(ok.constants, ((OP.END,),), (("c", "configuration"),)))


# ---- the runtime -----------------------------------------------------------------------------------

def _ptp(path: Path, pose: Pose, start) -> tuple:
    return _PLANNERS[path].joint_target(pose, tuple(start))


@settings(max_examples=60, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data(), index=st.integers(0, len(ARMS) - 1))
def test_the_pose_irl_pose_prints_reaches_exactly_its_joints_from_anywhere(data, index):
    """For joints within the limits of every shipped arm, the literal irl pose prints
    (--exact, through format_config and the values' formatting), compiled and planned as a
    ptp target from random start joints, reaches exactly those joints: its configuration
    and turns pin the solution."""
    path = ARMS[index]
    kin = _KINEMATICS[path]
    joints = data.draw(arm_joints(path), "joints")
    assume(clear_of_singularities(kin, joints) and clear_of_turn_boundaries(joints))
    taught = pose_literal(kin, joints, exact=True)
    assert taught.config == config_of(kin.configuration(joints), joints)
    assert taught.text == format_value(taught.pose) and format_config(taught.config) in taught.text
    pose = compiled_constant(taught.text, path)
    assert pose == taught.pose
    for _ in range(2):
        start = data.draw(arm_joints(path), "start")
        target, problem = _ptp(path, pose, start)
        assert problem is None, problem
        assert max(abs(a - b) for a, b in zip(target.main, joints)) < 1e-6, (target.main, joints)


@settings(max_examples=40, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data(), index=st.integers(0, len(ARMS) - 1))
def test_the_rounded_literal_resolves_to_the_same_configuration(data, index):
    path = ARMS[index]
    kin = _KINEMATICS[path]
    joints = data.draw(arm_joints(path), "joints")
    assume(clear_of_singularities(kin, joints) and clear_of_turn_boundaries(joints))
    taught = pose_literal(kin, joints)
    pose = compiled_constant(taught.text, path)
    target, problem = _ptp(path, pose, data.draw(arm_joints(path), "start"))
    assert problem is None, problem
    assert config_of(kin.configuration(target.main), target.main) == taught.config
    assert max(abs(a - b) for a, b in zip(target.main, joints)) < 0.5


@pytest.mark.parametrize("arm, joints", [
    ("lola15", (10.0, 20.0, 30.0, 182.0, -40.0, -300.0)), ("lola15", (10.0, 20.0, 30.0, -182.0, 40.0, 300.0)),
    ("lola15", (10.0, 20.0, 30.0, -180.0, 40.0, 180.0)), ("lola15", (10.0, 20.0, 30.0, 180.0, 40.0, -180.0)),
    ("staubli_tx2_60", (180.0, 10.0, 40.0, -180.0, 30.0, 180.0)),
    ("staubli_tx2_60", (-180.0, 10.0, 40.0, 260.0, -30.0, -260.0)),
    ("abb_irb120", (-60.0, 10.0, 20.0, 100.0, 30.0, 399.0)), ("yaskawa_gp8", (20.0, 10.0, 20.0, -30.0, 30.0, -359.0))])
def test_turns_on_and_beyond_their_boundaries_are_reached_exactly(arm, joints):
    """A value on a turn's boundary (-180 + 360 k) is in the turn above it, and reached there."""
    path = next(p for p in ARMS if p.stem == arm)
    taught = pose_literal(_KINEMATICS[path], joints, exact=True)
    assert taught.config.turns == tuple(turn_of(joints[i]) for i in TURN_AXES)
    for start in (HOME, tuple(lo for lo, _hi in _KINEMATICS[path].limits), tuple(hi for _lo, hi in _KINEMATICS[path].limits)):
        target, problem = _ptp(path, compiled_constant(taught.text, path), start)
        assert problem is None and max(abs(a - b) for a, b in zip(target.main, joints)) < 1e-6, (start, target)


def test_the_rounded_literal_is_to_a_thousandth_where_that_suffices():
    taught = pose_literal(KIN, (-16.11, 44.885, 49.736, -14.183, -34.454, 177.738))
    assert taught.text == ("pose(pos(799.946, -200.023, 299.946), rpy(179.999, 29.993, 179.988), "
                           "config(front, elbow_up, flip, 0, 0, 0))")  # (docs/language.md shows it)


@settings(max_examples=examples(150), suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), index=st.integers(0, len(ARMS) - 1), config=CONFIGS.map(
    lambda c: Config(c.shoulder, c.elbow, c.wrist, None if c.turns is None else tuple(k % 5 - 2 for k in c.turns))))
def test_a_ptp_to_a_pose_with_a_configuration_reaches_it_or_is_refused_with_a_reason(data, index, config):
    path = ARMS[index]
    kin = _KINEMATICS[path]
    if data.draw(st.booleans(), "reachable"):
        pose = kin.forward_pose(data.draw(arm_joints(path), "joints"))
    else:
        pose = pose_of(data.draw(st.tuples(*(st.floats(-2000, 2000),) * 3, *(st.floats(-180, 180),) * 3), "pose"))
    pose = Pose(pose.position, pose.orientation, config)
    start = data.draw(arm_joints(path), "start")
    target, problem = _ptp(path, pose, start)
    if target is None:
        assert isinstance(problem, str) and problem.startswith("the target pose cannot be reached")
        assert config.free or format_config(config) in problem
        return
    q = target.main
    assert problem is None
    assert config.matches(kin.configuration(q))
    for axis, k in zip(TURN_AXES, config.turns or ()):
        assert in_turn(q[axis], k)
    assert all(lo - 1e-9 <= v <= hi + 1e-9 for v, (lo, hi) in zip(q, kin.limits))
    fk = kin.forward_pose(q)
    assert math.dist((fk.position.x, fk.position.y, fk.position.z),
                     (pose.position.x, pose.position.y, pose.position.z)) < 1e-6


@settings(max_examples=80, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data(), index=st.integers(0, len(ARMS) - 1))
def test_naming_what_the_default_rule_chooses_changes_nothing(data, index):
    """Without turns, the configuration the nearest solution has gives that solution, bit
    for bit; with its turns too, the same to 1e-9 deg."""
    path = ARMS[index]
    kin = _KINEMATICS[path]
    joints = data.draw(arm_joints(path), "joints")
    near = data.draw(arm_joints(path), "near")
    assume(clear_of_singularities(kin, joints) and clear_of_turn_boundaries(joints))
    pose = kin.forward_pose(joints)
    try:
        q = kin.inverse(pose, near=near)
    except KinematicsError:
        return
    assume(clear_of_turn_boundaries(q))
    full = config_of(kin.configuration(q), q)
    assert kin.inverse_config(pose, Config(full.shoulder, full.elbow, full.wrist), near=near) == q
    assert max(abs(a - b) for a, b in zip(kin.inverse_config(pose, full, near=near), q)) < 1e-9
    assert _ptp(path, Pose(pose.position, pose.orientation, Config()), near)[0].main == q


@settings(max_examples=60, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data(), group=st.sampled_from(GROUPS))
def test_lin_and_circ_to_a_target_naming_another_configuration_are_refused(data, group):
    joints = data.draw(arm_joints(SPEC_PATH), "start")
    assume(clear_of_singularities(KIN, joints))
    cid = KIN.configuration(joints)
    other = 0 if cid & group.bit else 1
    pose = KIN.forward_pose(joints)
    target = Pose(Position(pose.position.x, pose.position.y, pose.position.z - 10.0), pose.orientation,
                  Config(**{group.field: other}))
    planner = _PLANNERS[SPEC_PATH]
    segment, problem = planner.plan(MoveRequest(Motion.LIN, (target,), 100.0, 1000.0, 0.0, 7), tuple(joints),
                                    None, 0.005)
    assert segment is None
    assert problem == (f"move lin keeps the arm's configuration ({configuration_name(cid)}); its target names "
                       f"{group.meanings[other]} ({format_config(target.config)}): change the configuration with "
                       "a ptp move")
    via = Pose(Position(pose.position.x, pose.position.y + 10.0, pose.position.z - 5.0), pose.orientation,
               Config(**{group.field: other}))
    end = Pose(target.position, target.orientation)
    segment, problem = planner.plan(MoveRequest(Motion.CIRC, (via, end), 100.0, 1000.0, 0.0, 7), tuple(joints),
                                    None, 0.005)
    assert segment is None and "move circ keeps the arm's configuration" in problem and "its via pose" in problem


def test_the_tool_down_pose_the_docs_use():
    """The Lola 15 from joint(mainjoint(0, -30, 30, 0, 60, 0)): pose(pos(800, -200, 300),
    rpy(180, 30, 180)) nearest is the wrist not flipped (A4 about 166), and the line to
    y = 200 is refused; with config(flip) (A4 about -14, A5 about -34) it is not; a line to
    a target that names the turn it would not end in is refused, naming the axis and both turns."""
    planner = _PLANNERS[SPEC_PATH]
    pose = pose_of((800.0, -200.0, 300.0, *DOWN))
    nearest, _ = planner.joint_target(pose, HOME)
    assert abs(nearest.main[3] - 166.0) < 1.0 and KIN.configuration(nearest.main) == 0
    line = pose_of((800.0, 200.0, 300.0, *DOWN))
    _, problem = planner.plan(MoveRequest(Motion.LIN, (line,), 250.0, 1000.0, 0.0, 1), nearest.axes, None, 0.005)
    assert problem is not None and "A4 would pass its limit 185 deg" in problem
    for config in (Config(wrist=1), Config(0, 0, 1, (0, 0, 0))):
        flipped, problem = planner.joint_target(Pose(pose.position, pose.orientation, config), HOME)
        assert problem is None and abs(flipped.main[3] + 14.0) < 1.0 and abs(flipped.main[4] + 34.0) < 1.0
        segment, problem = planner.plan(MoveRequest(Motion.LIN, (line,), 250.0, 1000.0, 0.0, 1), flipped.axes,
                                        None, 0.005)
        assert problem is None, problem
    end = segment.end
    assert turn_of(end[5]) == 1  # (A6 passes 180 on the way)
    named = Pose(line.position, line.orientation, Config(wrist=1, turns=(0, 0, 0)))
    _, problem = planner.plan(MoveRequest(Motion.LIN, (named,), 250.0, 1000.0, 0.0, 1), flipped.axes, None, 0.005)
    assert problem == (f"move lin would end with A6 in turn 1 ({end[5]:.1f} deg); its target names turn 0 "
                       "(config(flip, 0, 0, 0)): reach that turn with a ptp move")
    segment, problem = planner.plan(MoveRequest(Motion.LIN, (Pose(line.position, line.orientation,
                                                                  Config(wrist=1, turns=(0, 0, 1))),),
                                                250.0, 1000.0, 0.0, 1), flipped.axes, None, 0.005)
    assert problem is None and segment.end == end


@pytest.mark.parametrize("config, reason", [
    (Config(wrist=1, turns=(0, 0, 1)), "A6 would be 537.7 deg in turn 1 (180..540 deg), outside its limits -350..350"),
    (Config(turns=(1, 0, 0)), "A1 turn 1 means 180..540 deg, outside its limits -170..170"),
    (Config(shoulder=1), "no solution within the axis limits (A2 would be"),
    (Config(0, 1, 1), "no solution within the axis limits (A2 would be")])
def test_a_ptp_refusal_names_the_configuration_and_why(config, reason):
    pose = pose_of((800.0, -200.0, 300.0, *DOWN))
    target, problem = _PLANNERS[SPEC_PATH].joint_target(Pose(pose.position, pose.orientation, config), HOME)
    assert target is None
    assert problem.startswith(f"the target pose cannot be reached in {format_config(config)}: {reason}"), problem


def test_singular_in_the_configuration_named_is_refused():
    pose = KIN.forward_pose((0.0, 10.0, 20.0, 0.0, 0.0, 0.0))  # A5 at 0: the wrist singularity
    target, problem = _PLANNERS[SPEC_PATH].joint_target(Pose(pose.position, pose.orientation, Config(wrist=1)), HOME)
    assert target is None and "in config(flip): singular: wrist singularity" in problem


def test_a_frame_carries_a_targets_configuration_to_the_planner():
    """use base: the target composed with the base keeps the target's configuration."""
    base = pose_of((100.0, -50.0, 0.0, 0.0, 0.0, 20.0))
    world = pose_of((800.0, -200.0, 300.0, *DOWN))
    local = compose(call_builtin("inv", [base]), world)
    target = compose(base, Pose(local.position, local.orientation, Config(wrist=1)))
    joints, problem = _PLANNERS[SPEC_PATH].joint_target(target, HOME, Frames.default(SPEC))
    assert problem is None and KIN.configuration(joints.main) & WRIST_FLIP


# ---- irl pose --------------------------------------------------------------------------------------

def test_irl_pose_prints_the_literal_and_what_it_names(tmp_path):
    code, out, err = run_cli("pose", "--spec", SPEC_PATH, "-16.11", "44.885", "49.736", "-14.183", "-34.454", "177.738")
    assert code == 0 and err == ""
    literal, comment = out.splitlines()
    assert literal == pose_literal(KIN, (-16.11, 44.885, 49.736, -14.183, -34.454, 177.738)).text
    assert comment == "-- front, elbow up, wrist flipped; A1, A4, A6 in turns 0, 0, 0; tool default_tool, base world"
    # both lines are L-IRL: pasted into a program, the move reaches the joints
    path = tmp_path / "taught.irl"
    path.write_text(f'program taught; system_specification "{SPEC_PATH}";\nseq\n  move ptp\n    {literal}\n'
                    f"    {comment}\n  ;\nendseq\nendprogram;\n", encoding="utf-8")
    code, out, err = run_cli("run", path, "--json")
    assert code == 0, out + err
    final = json.loads(out)["final_position"]
    assert max(abs(a - b) for a, b in zip(final, (-16.11, 44.885, 49.736, -14.183, -34.454, 177.738))) < 0.05


def test_irl_pose_json_and_exact():
    joints = ("10", "20", "30", "182", "-40", "-300")
    code, out, err = run_cli("pose", "--spec", SPEC_PATH, *joints, "--json", "--exact")
    assert code == 0, err
    got = json.loads(out)
    q = tuple(map(float, joints))
    cid = KIN.configuration(q)
    assert got["config_id"] == cid and got["configuration"] == configuration_name(cid)
    assert got["turns"] == [0, 1, -1] and got["config"] == format_config(config_of(cid, q))
    assert got["joints"] == list(q) and got["tool"] == "default_tool" and got["base"] == "world"
    pose = compiled_constant(got["pose"])
    assert [pose.position.x, pose.position.y, pose.position.z] == got["position"]
    target, problem = _PLANNERS[SPEC_PATH].joint_target(pose, HOME)
    assert problem is None and max(abs(a - b) for a, b in zip(target.main, q)) < 1e-6


def test_irl_pose_with_a_tool_and_a_base():
    cell = PROGRAMS / "lola15_cell.spc"
    spec = load_spec(cell)
    joints = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)
    code, out, err = run_cli("pose", "--spec", cell, *joints, "--tool", "gripper", "--base", "Pallet_Station",
                             "--exact")
    assert code == 0, err
    literal, comment = out.splitlines()
    assert comment.endswith("tool gripper, base pallet_station")
    named = {(t, n): v for t, n, v in spec.named_frames}
    tool, base = named["tool", "gripper"], named["frame", "pallet_station"]
    pose = compiled_constant(literal, cell)
    planner = MovePlanner(spec.axes, spec.main_axes, "jerk", Kinematics(spec))
    target, problem = planner.joint_target(compose(pose_of(base), pose), HOME, Frames("pallet_station", base,
                                                                                        "gripper", tool))
    assert problem is None and max(abs(a - b) for a, b in zip(target.main, joints)) < 1e-6
    # without the tool, the same literal would put the flange there: another joint solution
    other, _ = planner.joint_target(compose(pose_of(base), pose), HOME)
    assert other is None or max(abs(a - b) for a, b in zip(other.main, joints)) > 1.0


@pytest.mark.parametrize("argv, status, message", [
    (["0", "0", "0", "0", "130", "0"], 1, "A5 = 130 deg is outside its limits -120..120"),
    (["0", "0", "0", "0", "0", "0"], 1, "at (or too near) a singularity; teach them as joint(...)"),
    (["0", "0", "0"], 2, "expected the six main axes' values A1 .. A6, got 3"),
    ([], 2, "give the six joint values A1 .. A6, or --endpoint E"),
    (["0", "10", "20", "0", "30", "0", "--tool", "griper"], 2, "has no [[tool]] of that name"),
    (["0", "10", "20", "0", "30", "0", "--endpoint", "tcp://127.0.0.1:9"], 2, "give the joint values or --endpoint"),
    (["0", "10", "20", "0", "30", "x"], 2, "invalid float value: 'x'")])
def test_irl_pose_exit_statuses(argv, status, message, monkeypatch):
    monkeypatch.delenv("IRL_ENDPOINT", raising=False)
    code, out, err = run_cli("pose", "--spec", SPEC_PATH, *argv)
    assert code == status and message in err and out == "", err


def test_irl_pose_refuses_a_robot_without_kinematics(tmp_path):
    text = SPEC_PATH.read_text(encoding="utf-8")
    spec = tmp_path / "gantry.spc"
    spec.write_text(re.sub(r"(?m)^dh = .*\n", "", text), encoding="utf-8")
    code, out, err = run_cli("pose", "--spec", spec, "0", "10", "20", "0", "30", "0")
    assert code == 1 and "this robot has no pose targets" in err


@pytest.mark.long
def test_irl_pose_takes_the_current_joints_from_a_server(server, tmp_path, monkeypatch):
    program = tmp_path / "there.irl"
    program.write_text(f'program there; system_specification "{SPEC_PATH}";\nseq\n'
                       "  move ptp joint(mainjoint(12, -25, 40, 100, -35, 250));\nendseq\nendprogram;\n",
                       encoding="utf-8")
    client = server.client()
    final = wait_end(client, submit(client, program), server)
    assert final["state"] == "completed", final
    position = client.request("status")["position"]
    code, out, err = run_cli("pose", "--spec", SPEC_PATH, "--endpoint", server.endpoint, "--json")
    assert code == 0, err
    got = json.loads(out)
    assert got["joints"] == position[:6]
    code, local, _ = run_cli("pose", "--spec", SPEC_PATH, *position[:6], "--json")
    assert json.loads(local) == got
    assert got["turns"][2] == 1  # (A6 at about 250 deg)
    monkeypatch.setenv("IRL_ENDPOINT", server.endpoint)
    code, out, _ = run_cli("pose", "--spec", SPEC_PATH)
    assert code == 0 and out.splitlines()[0] == got["pose"]
    other = PROGRAMS / "robots" / "abb_irb120.spc"
    code, out, err = run_cli("pose", "--spec", other, "--endpoint", server.endpoint)
    assert code == 1 and "drives another specification" in err
    code, out, err = run_cli("pose", "--spec", SPEC_PATH, "--endpoint", "tcp://127.0.0.1:9", "--timeout", "0.3")
    assert code == 2 and "no reply" in err


# ---- end to end ------------------------------------------------------------------------------------

def test_the_example_program_runs():
    code, out, err = run_cli("run", PROGRAMS / "configurations.irl")
    assert code == 0, out + err
    assert "program configurations on lola_15: completed" in out
    assert "configuration config(flip) kept" in out


@pytest.mark.parametrize("config, fault", [
    (", config(flip)", None), (", config(front, elbow_up, flip, 0, 0, 0)", None),
    ("", "line 5: move lin refused: the path leaves the axis limits"),
    (", config(noflip)", "line 5: move lin refused: the path leaves the axis limits"),
    (", config(back)", "line 4: the target pose cannot be reached in config(back)")])
def test_the_tool_down_line_with_and_without_the_wrist_flipped(config, fault, tmp_path):
    path = tmp_path / "line.irl"
    path.write_text(f'program line; system_specification "{SPEC_PATH}";\nseq\n'
                    "  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0));\n"
                    f"  move ptp pose(pos(800, -200, 300), rpy(180, 30, 180){config});\n"
                    "  move lin pose(pos(800, 200, 300), rpy(180, 30, 180));\nendseq\nendprogram;\n", encoding="utf-8")
    code, out, err = run_cli("run", path, "--json")
    summary = json.loads(out)
    if fault is None:
        assert code == 0 and summary["fault"] is None, summary["fault"]
    else:
        assert code == 1 and fault in summary["fault"], summary["fault"]
