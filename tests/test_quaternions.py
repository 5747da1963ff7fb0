"""Quaternions across the whole float range (issue 26, fault 8): ``quat(1e308, 1e308, 1e308,
1e308)`` passed ``irl check`` and was refused at run time as "quat(0, 0, 0, 0) is not a
rotation" (the sum of squares overflowed to infinity, every component divided by it to 0);
``quat(1e300, 0, 0, 0)`` in ``use tool`` gave "roll = nan". Every place that normalises a
quaternion (compiler.geometry.normalise: the compiler's constant folding and the VM through
compiler.semantics.make_quat, roll/pitch/yaw of a quaternion for frames and tools, the
runtime's rotation matrices and slerp, the kinematics) scales by the largest component first.
The reference here is exact decimal arithmetic, independent of the code under test."""
from __future__ import annotations

import math
from decimal import Decimal, localcontext

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from compiler import frames, geometry, semantics
from compiler.semantics import EvalError
from compiler.values import Pose, Position, Quat
from runtime.motion import kinematics, rotation
from runtime.loop.vm import VMStatus

from test_vm import compile_text, program_text, raw_program, run

from compiler.objcode import OP

#: Any finite float, subnormals and the largest included.
component = st.floats(allow_nan=False, allow_infinity=False)
quaternions = st.tuples(component, component, component, component).filter(any)


def exact_unit(q) -> tuple[float, ...]:
    """q / |q| in 60-digit decimal arithmetic (no overflow, no underflow), rounded to floats."""
    with localcontext() as ctx:
        ctx.prec = 60
        d = [Decimal(c) for c in q]
        norm = sum(c * c for c in d).sqrt()
        return tuple(float(c / norm) for c in d)


def close(a, b, tol=4e-16) -> bool:
    return all(abs(x - y) <= tol for x, y in zip(a, b))


@given(q=quaternions)
@example(q=(1e308, 1e308, 1e308, 1e308))
@example(q=(1e300, 0.0, 0.0, 0.0))
@example(q=(2194575610302935.0, 0.0, 2194575610302932.0, 2192.0))  # next to gimbal lock
@example(q=(-1.7976931348623157e308, 5e-324, 0.0, 1.7976931348623157e308))
@example(q=(5e-324, 0.0, 0.0, 0.0))
@example(q=(3e-320, -3e-320, 1e-310, 0.0))
def test_a_quaternion_of_any_size_is_the_rotation_it_means(q):
    expected = exact_unit(q)
    assert close(geometry.normalise(q), expected), (q, geometry.normalise(q), expected)
    made = semantics.make_quat(*q)  # the compiler's constant folding and the VM's MAKE_QUAT
    assert close((made.w, made.x, made.y, made.z), expected)
    # the same rotation wherever it is used: roll/pitch/yaw (frames and tools), the unit
    # quaternion with w >= 0 (pose arithmetic), the matrices (Cartesian paths, kinematics)
    # (compared as rotations: next to pitch +-90 deg, roll and yaw swap what they hold)
    assert rotation.quat_angle(geometry.rpy_to_quat(*geometry.quat_to_rpy(q)), expected) == pytest.approx(0, abs=1e-6)
    unit = geometry.unit(q)
    assert close(unit, expected if expected[0] >= 0.0 else tuple(-c for c in expected))
    reference = rotation.quat_to_matrix(expected)
    assert close([v for row in rotation.quat_to_matrix(q) for v in row], [v for row in reference for v in row], 2e-15)
    assert close(kinematics._quat_matrix(*q), [v for row in reference for v in row], 2e-15)
    assert rotation.quat_angle(q, expected) == pytest.approx(0.0, abs=1e-6)
    rpy = frames.values_of(Pose(Position(0.0, 0.0, 0.0), Quat(*q)))[3:]  # use base, use tool
    assert rotation.quat_angle(geometry.rpy_to_quat(*rpy), expected) == pytest.approx(0, abs=1e-6)


def test_a_zero_quaternion_is_still_refused_everywhere():
    zero = (0.0, 0.0, 0.0, 0.0)
    with pytest.raises(EvalError, match=r"quat\(0, 0, 0, 0\) is not a rotation"):
        semantics.make_quat(*zero)
    for convert in (geometry.quat_to_rpy, rotation.quat_to_matrix, rotation._unit):
        with pytest.raises(ValueError, match="is not a rotation"):
            convert(zero)
    with pytest.raises(kinematics.KinematicsError, match="is not a rotation"):
        kinematics._quat_matrix(*zero)
    assert geometry.normalise(zero) is None and geometry.normalise((math.inf, 0.0, 0.0, 0.0)) is None
    assert geometry.normalise((math.nan, 1.0, 0.0, 0.0)) is None


def test_huge_quaternions_in_a_program_are_the_rotations_they_mean(tmp_path):
    """Folded at compile time and built at run time alike: the identity and a quarter turn
    about z, however large their components; a tool turned by one is accepted."""
    body = ("  o := quat(1e308, 0, 0, 0);\n  print o;\n  o := quat(w, w, w, w);\n  print o;\n"
            "  print quat(1e308, 1e308, 1e308, 1e308);\n"
            "  use tool tool(pos(0, 0, 100), quat(1e300, 0, 0, 0));\n"
            "  use tool tool(pos(0, 0, 100), quat(w, 0, 0, w));\n  print \"ok\";\n")
    program = compile_text(tmp_path, program_text(body, "var\n  o : orientation;\n  w : real := 1e308;\n"))
    machine, host = run(program)
    assert machine.status == VMStatus.DONE, machine.error
    half = "quat(0.5, 0.5, 0.5, 0.5)"
    tool = frames.BY_TYPE["tool"]
    assert [frames.problem(tool, frames.values_of(value)) for _k, _n, value in host.frames] == [None, None]
    assert frames.values_of(host.frames[1][2])[3:] == pytest.approx((0.0, 0.0, 90.0))
    assert host.texts == ["quat(1, 0, 0, 0)", half, half, "ok"], host.texts


def test_the_vm_normalises_a_huge_quaternion_from_object_code():
    program = raw_program([(OP.CONST, 0), (OP.CONST, 1), (OP.CONST, 1), (OP.CONST, 0), (OP.MAKE_QUAT,), (OP.PRINT, 1),
                           (OP.END,)], (1.7976931348623157e308, 0.0))
    machine, host = run(program)
    assert machine.status == VMStatus.DONE, machine.error
    s = repr(semantics.make_quat(1.0, 0.0, 0.0, 1.0).w)  # the same bits as the quaternion of ordinary size
    assert host.texts == [f"quat({s}, 0, 0, {s})"], host.texts
