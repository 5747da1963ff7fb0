"""Pose arithmetic (issue 17, item 2): composition and inverse of poses and orientations,
offsets in the base frame and in the tool frame, distance; one definition
(compiler.semantics.GEOMETRY) for the checker, the constant folding and the VM."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler import semantics
from compiler.semantics import EvalError, compose, distance, inverse, tool_offset, transform
from compiler.values import Pose, Position, Quat, Rpy

from test_vm import DISPATCHES, printed, raw_program, run

from conftest import ROOT, examples

coordinate = st.floats(-2000, 2000, allow_nan=False)
angle = st.floats(-180, 180, allow_nan=False)
positions = st.builds(Position, coordinate, coordinate, coordinate)
rpys = st.builds(Rpy, angle, st.floats(-89.9, 89.9), angle)
quats = st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: sum(c * c for c in q) > 1e-3).map(
    lambda q: semantics.make_quat(*q))
orientations = st.one_of(rpys, quats)
poses = st.builds(Pose, positions, orientations)


def matrix(pose: Pose) -> np.ndarray:
    """The 4x4 homogeneous matrix of a pose, by NumPy (independent of compiler.geometry)."""
    o = pose.orientation
    if isinstance(o, Rpy):
        r, p, y = np.radians([o.roll, o.pitch, o.yaw])
        rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
        ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
        rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
        rot = rz @ ry @ rx
    else:
        w, x, y, z = o.w, o.x, o.y, o.z
        rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = [pose.position.x, pose.position.y, pose.position.z]
    return m


def close(a: Pose, m: np.ndarray, tol: float = 1e-9) -> bool:
    got = matrix(a)
    return np.abs(got[:3, 3] - m[:3, 3]).max() <= tol * max(1.0, np.abs(m[:3, 3]).max()) and \
        np.abs(got[:3, :3] - m[:3, :3]).max() <= tol


@settings(max_examples=examples(300), deadline=None)
@given(poses)
def test_a_pose_composed_with_its_inverse_is_the_identity(a):
    for identity in (compose(a, inverse(a)), compose(inverse(a), a)):
        assert close(identity, np.eye(4)), identity
    assert type(inverse(a).orientation) is type(a.orientation)  # rpy stays rpy, quat stays quat


@settings(max_examples=examples(300), deadline=None)
@given(poses, poses, positions)
def test_composition_and_offsets_are_the_homogeneous_matrices(frame, target, offset):
    """A target written in a shifted (turned) frame is the matrix product, as computed by
    hand; offsets along the base frame and along the tool's own axes likewise."""
    assert close(compose(frame, target), matrix(frame) @ matrix(target))
    point = matrix(frame) @ np.array([offset.x, offset.y, offset.z, 1.0])
    got = transform(frame, offset)
    assert np.allclose([got.x, got.y, got.z], point[:3], rtol=0, atol=1e-9 * max(1.0, np.abs(point).max()))
    shifted = semantics.binary("+", target, offset)
    assert shifted.orientation == target.orientation
    assert (shifted.position.x, shifted.position.y, shifted.position.z) == pytest.approx(
        (target.position.x + offset.x, target.position.y + offset.y, target.position.z + offset.z), abs=1e-9)
    along_tool = matrix(target) @ np.array([[1, 0, 0, offset.x], [0, 1, 0, offset.y], [0, 0, 1, offset.z],
                                            [0, 0, 0, 1.0]])
    assert close(tool_offset(target, offset), along_tool)
    assert distance(frame, target) == pytest.approx(float(np.linalg.norm(matrix(frame)[:3, 3] -
                                                                         matrix(target)[:3, 3])), abs=1e-9)


GEOMETRIC_VALUES = st.one_of(positions, poses, orientations, st.integers(-5, 5), st.floats(-10, 10))


@settings(max_examples=examples(300), deadline=None)
@given(op=st.sampled_from(["+", "-", "*", "/"]), a=GEOMETRIC_VALUES, b=GEOMETRIC_VALUES)
def test_the_vm_computes_exactly_semantics_on_geometric_values(op, a, b):
    """Both dispatch loops (and their inline fast paths, which try the Python operator
    first) give semantics.binary's value or its error, for every pair, defined or not."""
    from compiler.objcode import OP

    opcode = {"+": OP.ADD, "-": OP.SUB, "*": OP.MUL, "/": OP.DIV}[op]
    program = raw_program([(OP.CONST, 0), (OP.CONST, 1), (opcode,), (OP.STORE_GLOBAL, 0), (OP.END,)], (a, b))
    try:
        expected, error = semantics.binary(op, a, b), None
    except (EvalError, TypeError) as exc:  # (numbers alone: the numeric rules, tested in test_vm)
        expected, error = None, exc
    for d in DISPATCHES:
        machine, _ = run(program, dispatch=d)
        if error is None:
            assert machine.status.name == "DONE", machine.error
            assert machine.globals[0] == expected
        else:
            assert machine.status.name == "ERROR"
            if isinstance(error, EvalError):
                assert machine.error.message == str(error)


def test_folded_and_computed_pose_arithmetic_agree(tmp_path):
    """Each expression once with constants (folded by the compiler) and once with
    variables (the VM): the same text printed."""
    decls = "var f, t : pose;\n    p : position;\n    o : orientation;\n    k : real;\n"
    setup = ("f := pose(pos(600, 200, 300), rpy(10, 20, 30)); t := pose(pos(100, 50, 0), rpy(180, 0, 0)); "
             "p := pos(1, 2, 3); o := quat(1, 0, 0, 1); k := 2.5;")
    F, T = "pose(pos(600, 200, 300), rpy(10, 20, 30))", "pose(pos(100, 50, 0), rpy(180, 0, 0))"
    pairs = [(f"{F} * {T}", "f * t"), (f"inv({F})", "inv(f)"), (f"{F} * pos(1, 2, 3)", "f * p"),
             (f"{T} + pos(1, 2, 3)", "t + p"), (f"{T} - pos(1, 2, 3)", "t - p"),
             ("pos(1, 2, 3) * 2.5", "p * k"), ("2.5 * pos(1, 2, 3)", "k * p"), ("pos(1, 2, 3) / 2.5", "p / k"),
             ("-pos(1, 2, 3)", "-p"), ("pos(1, 2, 3) - pos(1, 2, 3)", "p - p"),
             (f"tool_offset({T}, pos(1, 2, 3))", "tool_offset(t, p)"), (f"distance({F}, {T})", "distance(f, t)"),
             ("quat(1, 0, 0, 1) * rpy(0, 0, 10)", "o * rpy(0, 0, 10)"), ("inv(quat(1, 0, 0, 1))", "inv(o)")]
    body = [f"  {setup}"]
    for folded, computed in pairs:
        body += [f"  print {folded};", f"  print {computed};"]
    out = printed(tmp_path, "\n".join(body), decls)
    for k, (folded, _computed) in enumerate(pairs):
        assert out[2 * k] == out[2 * k + 1], folded
    assert out[16] == "pos(-1, -2, -3)" and out[18] == "pos(0, 0, 0)"


def test_object_code_that_gives_a_geometric_builtin_a_number_stops_with_an_error():
    """The verifier does not type the stack: CALL_BUILTIN inv on an integer (hand-made
    object code) is a run-time error at its line, never a crash."""
    from compiler.objcode import BUILTIN_NAMES, OP

    program = raw_program([(OP.CONST, 0), (OP.CALL_BUILTIN, BUILTIN_NAMES.index("inv"), 1), (OP.STORE_GLOBAL, 0),
                           (OP.END,)], (3,))
    for d in DISPATCHES:
        machine, _ = run(program, dispatch=d)
        assert machine.status.name == "ERROR" and machine.error.message == "inv(number) is not defined"


def test_a_lin_move_in_a_turned_frame_reaches_the_hand_computed_world_pose(tmp_path):
    """On the simulated robot: the tool ends where the matrix product says (to the servo's
    accuracy)."""
    from compiler.driver import compile_source
    from compiler.spec import load_spec
    from runtime.motion.kinematics import Kinematics
    from runtime.loop.system import RobotSystem, RunOptions

    frame = Pose(Position(650, -180, 250), Rpy(0, 0, 10))
    local = Pose(Position(150, 120, 0), Rpy(180, 30, 180))
    source = (f'program frame;\nsystem_specification "{ROOT / "programs" / "lola15.spc"}";\nvar f, t : pose;\nseq\n'
              f"  f := {frame};\n  t := {local};\n  move ptp f * t speed_ptp := 0.5;\n"
              "  move lin f * tool_offset(t, pos(0, 0, -100)) speed := 300;\n  move lin f * t speed := 300;\n"
              "endseq\nendprogram;\n")
    result = compile_source(source, str(tmp_path / "frame.irl"))
    assert result.ok, result.diagnostics
    spec = load_spec(ROOT / "programs" / "lola15.spc")
    summary = RobotSystem(spec, RunOptions(state_dir=tmp_path / "state")).run(result.program)
    assert summary["fault"] is None, summary["fault"]
    reached = Kinematics(spec).forward(summary["final_position"][:6])
    want = matrix(frame) @ matrix(local)
    assert np.abs(np.array(reached[:3]) - want[:3, 3]).max() < 0.05, (reached, want[:3, 3])
    got = matrix(Pose(Position(*reached[:3]), Rpy(*reached[3:6])))
    assert np.abs(got[:3, :3] - want[:3, :3]).max() < 1e-3
    assert math.isclose(distance(Pose(Position(*reached[:3]), Rpy(0, 0, 0)), compose(frame, local)), 0.0,
                        abs_tol=0.05)


def test_quat_results_are_unit_with_w_not_negative():
    q = inverse(Quat(0.0, 0.0, 0.0, 1.0))
    assert isinstance(q, Quat) and q.w >= 0 and math.isclose(q.w ** 2 + q.x ** 2 + q.y ** 2 + q.z ** 2, 1.0)


@pytest.mark.parametrize("a, op, b", [("x", "*", 10 ** 12), (10 ** 12, "*", "x"), ([0], "*", 10 ** 12),
                                      ([0] * 1000, "+", [0] * 1000), ("a", "-", "b"), (True, "*", "x")])
def test_hand_made_object_code_cannot_repeat_strings_or_arrays(a, op, b):
    """The verifier does not type the stack, so object code (not the compiler's) may ask
    for a string times 10^12: an error at once, nothing allocated."""
    from compiler.objcode import OP

    opcode = {"+": OP.ADD, "-": OP.SUB, "*": OP.MUL}[op]
    program = raw_program([(OP.CONST, 0), (OP.CONST, 1), (opcode,), (OP.STORE_GLOBAL, 0), (OP.END,)], (a, b))
    for d in DISPATCHES:
        machine, _ = run(program, dispatch=d)
        assert machine.status.name == "ERROR" and "is not defined for" in machine.error.message, machine.error


#: A value of each kind the geometric operators take, as L-IRL writes it.
LITERALS = {"position": ["pos(1, 2, 3)"], "pose": ["pose(pos(1, 2, 3), rpy(0, 0, 10))"],
            "orientation": ["rpy(0, 0, 10)", "quat(1, 0, 0, 0)"], "number": ["2", "2.5"]}


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(["+", "-", "*", "/"]), st.sampled_from(sorted(LITERALS)), st.sampled_from(sorted(LITERALS)),
       st.integers(0, 1), st.integers(0, 1))
def test_a_pair_no_form_defines_is_an_error_that_lists_every_form_of_the_operator(op, left, right, i, j):
    """docs/language.md: anything but the table's forms "is a compile-time error that lists
    the forms of the operator" (orientation + orientation too, which also says to use '*')."""
    from compiler.driver import compile_source

    if "number" == left == right or (op, left, right) in semantics.GEOMETRY:
        return
    a, b = LITERALS[left][i % len(LITERALS[left])], LITERALS[right][j % len(LITERALS[right])]
    source = (f'program p;\nsystem_specification "{ROOT / "programs" / "lola15.spc"}";\nseq\n'
              f'  print {a} {op} {b};\nendseq\nendprogram;\n')
    errors = compile_source(source, "p.irl", generate_code=False).diagnostics
    assert len(errors) == 1 and errors[0].line == 4 and f"'{op}' is not defined for" in errors[0].message, errors
    hint = errors[0].hint or ""
    forms = [f"{l} {o} {r}" for o, l, r in semantics.GEOMETRY if o == op]
    assert forms and all(form in hint for form in forms), (a, op, b, hint)
