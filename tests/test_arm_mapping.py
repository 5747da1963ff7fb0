"""What a specification says of an arm beyond its DH rows (issue 27): the direction each
axis turns (``[[axis]] direction``), a coupled axis (``[[axis]] coupling``, FANUC's J3),
where the robot stands (``[kinematics] mounting``) and a tool given as a quaternion.

* Hypothesis over random directions, couplings and mountings: the forward kinematics
  against an independent NumPy product (theta = direction q + offset + factor q_j, the
  mounting in front); ``inverse(forward(q), near=q) == q``; every solution reproduces the
  pose; the Jacobian against finite differences.
* The specification's keys: accepted, defaulted, and refused with the key and the allowed
  values; the compiler's reach check in the world frame of a mounted robot.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from compiler.spec import SpecError, parse_spec
from runtime.motion.kinematics import Kinematics, KinematicsError
from test_kinematics import LOLA_ROWS, angle_diff, np_dh, np_rpy, pose_error

from conftest import SPEC, SPEC_PATH, run_cli, examples

LIMITS = [(ax.min, ax.max) for ax in SPEC.main_axes]
TOOL = (5.0, -10.0, 120.0, 10.0, 20.0, -30.0)


def np_forward(dirs, couplings, mounting, q):
    """The TCP as NumPy sees it: the mounting, then the DH links with the mapped angles."""
    t = np.eye(4)
    t[:3, :3] = np_rpy(*mounting[3:])
    t[:3, 3] = mounting[:3]
    for i, ((a, alpha, d, off), qi) in enumerate(zip(LOLA_ROWS, q)):
        theta = dirs[i] * qi + off
        if couplings[i] is not None:
            j, factor = couplings[i]
            theta += factor * q[j]
        t = t @ np_dh(a, math.radians(alpha), d, math.radians(theta))
    tool = np.eye(4)
    tool[:3, :3] = np_rpy(*TOOL[3:])
    tool[:3, 3] = TOOL[:3]
    return t @ tool


SIGNS = st.sampled_from((1, -1))
COUPLINGS = st.sampled_from([
    (None,) * 6,
    (None, None, (1, -1.0), None, None, None),  # FANUC: J3 from the horizontal
    (None, None, (1, 1.0), None, None, None),
    (None, (0, 0.5), (0, -0.25), None, None, None),
])
MOUNTINGS = st.sampled_from([
    (0.0,) * 6,
    (0.0, 0.0, 2500.0, 180.0, 0.0, 0.0),  # ceiling
    (1000.0, -500.0, 800.0, 0.0, 90.0, 0.0),  # wall
    (300.0, 200.0, 400.0, 12.0, -7.0, 33.0),  # a riser, tilted
])


def arm(dirs, couplings, mounting, limits=None):
    return Kinematics(LOLA_ROWS, tool=TOOL, limits=limits, directions=dirs, couplings=couplings,
                      mounting=mounting)


@settings(max_examples=examples(120), deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.filter_too_much])
@given(st.tuples(*[SIGNS] * 6), COUPLINGS, MOUNTINGS,
       st.tuples(*(st.floats(lo, hi, allow_nan=False) for lo, hi in LIMITS)))
def test_property_mapped_arm_forward_inverse_and_jacobian(dirs, couplings, mounting, q):
    kin = arm(dirs, couplings, mounting, LIMITS)
    reference = np_forward(dirs, couplings, mounting, q)
    position, rotation = pose_error(kin, q, reference)
    assert position < 1e-6 and rotation < 1e-9
    shoulder, elbow, wrist = kin.singularity_margins(q)
    assume(shoulder > 1.0 and elbow > 1e-2 and wrist > 1e-2)
    back = kin.inverse(kin.forward(q), near=q)
    assert max(angle_diff(a, b) for a, b in zip(back, q)) < 1e-8, (q, back)
    assert kin.configuration(back) == kin.configuration(q)
    for cid, joints in kin.solutions(kin.forward_matrix(q), near=q):
        assert kin.configuration(joints) == cid
        assert all(lo - 1e-9 <= v <= hi + 1e-9 for v, (lo, hi) in zip(joints, LIMITS))
        position, rotation = pose_error(kin, joints, reference)
        assert position < 1e-6 and rotation < 1e-9
    # the Jacobian: d(TCP)/dq of the joint values, in the world frame
    jac = np.array(kin.jacobian(q))
    h = 1e-6
    r0 = reference[:3, :3]
    for i in range(6):
        step = np.zeros(6)
        step[i] = h
        mp = np.array(kin.forward_matrix(tuple(np.array(q) + step)))
        mm = np.array(kin.forward_matrix(tuple(np.array(q) - step)))
        scale = 2.0 * math.radians(h)
        assert np.allclose(jac[:3, i], (mp[:3, 3] - mm[:3, 3]) / scale, atol=1e-3, rtol=1e-6)
        skew = (mp[:3, :3] - mm[:3, :3]) / scale @ r0.T
        assert np.allclose(jac[3:, i], (skew[2, 1], skew[0, 2], skew[1, 0]), atol=1e-6)


def test_a_negative_direction_mirrors_the_joint_value():
    plain = arm((1,) * 6, (None,) * 6, (0.0,) * 6)
    kuka = arm((-1, 1, 1, -1, 1, -1), (None,) * 6, (0.0,) * 6)
    q = (30.0, -20.0, 40.0, 50.0, 60.0, 70.0)
    mirrored = (-30.0, -20.0, 40.0, -50.0, 60.0, -70.0)
    assert kuka.forward(q) == pytest.approx(plain.forward(mirrored), abs=1e-9)
    # the limits bound the vendor's values: A1 = 175 is outside -170..170 whichever way it turns
    limited = arm((-1, 1, 1, 1, 1, 1), (None,) * 6, (0.0,) * 6, LIMITS)
    pose = plain.forward((-175.0, -20.0, 40.0, 50.0, 60.0, 70.0))
    with pytest.raises(KinematicsError, match="A1 would be 175"):
        limited.inverse(pose, configuration=plain.configuration((-175.0, -20.0, 40.0, 50.0, 60.0, 70.0)))


def test_the_mounting_moves_every_pose_into_the_world():
    floor = arm((1,) * 6, (None,) * 6, (0.0,) * 6)
    ceiling = arm((1,) * 6, (None,) * 6, (0.0, 0.0, 2500.0, 180.0, 0.0, 0.0))
    q = (10.0, -30.0, 20.0, 0.0, 45.0, 0.0)
    x, y, z = floor.forward(q)[:3]
    assert ceiling.forward(q)[:3] == pytest.approx((x, -y, 2500.0 - z), abs=1e-9)
    frames = ceiling.frames(q)
    assert frames[0][2][3] == pytest.approx(2500.0 - LOLA_ROWS[0][2])  # axis 2 hangs below the ceiling


# ---- the specification's keys ------------------------------------------------------------

BASE = SPEC_PATH.read_text()


def spec_with(axis_keys: dict | None = None, kinematics: str | None = None, tables: str = ""):
    """The Lola 15 with keys added to axis n's table ({n: 'key = value'}), a [kinematics]
    and more tables at the end (``tables``: [[tool]], [[frame]])."""
    text = BASE + tables
    parts = text.split("[[axis]]")
    for n, line in (axis_keys or {}).items():
        parts[n] = parts[n].replace('kind = "revolute"', f'kind = "revolute"\n{line}', 1)
    text = "[[axis]]".join(parts)
    if kinematics is not None:
        start = text.index("[kinematics]")
        end = text.index("\n\n", start)
        text = text[:start] + "[kinematics]\n" + kinematics + text[end:]
    return parse_spec(text, "arm.spc")


def test_the_new_keys_default_to_what_every_existing_specification_meant():
    assert [a.direction for a in SPEC.axes] == [1] * 6
    assert [a.coupling for a in SPEC.axes] == [None] * 6
    assert SPEC.mounting == (0.0,) * 6


def test_direction_coupling_mounting_and_a_quaternion_tool_are_read():
    spec = spec_with({1: "direction = -1", 3: 'coupling = { axis = "A2", factor = -1 }'},
                     'tool = { x = 0, y = 0, z = 100, qw = 0.7071068, qx = 0, qy = 0.7071068, qz = 0 }\n'
                     'mounting = { z = 2500, roll = 180 }')
    assert spec.axes[0].direction == -1
    assert spec.axes[2].coupling == (1, -1.0)
    assert spec.mounting == (0.0, 0.0, 2500.0, 180.0, 0.0, 0.0)
    assert spec.tool[:3] == (0.0, 0.0, 100.0)
    assert spec.tool[3:] == pytest.approx((0.0, 90.0, 0.0), abs=1e-5)
    kin = Kinematics(spec)
    assert kin.directions[0] == -1 and kin.mounting == spec.mounting


@pytest.mark.parametrize("axis_keys, kinematics, where, message", [
    ({1: "direction = 0"}, None, "axis[1].direction", "expected 1 or -1, got 0"),
    ({1: "direction = -1.5"}, None, "axis[1].direction", "expected 1 or -1"),
    ({1: 'direction = "-z"'}, None, "axis[1].direction", "expected 1 or -1"),
    ({5: 'coupling = { axis = "A4", factor = 1 }'}, None, "axis[5].coupling",
     "only axes 2 and 3 of the arm may be coupled"),
    ({3: 'coupling = { axis = "A4", factor = 1 }'}, None, "axis[3].coupling", "an earlier main axis (A1, A2)"),
    ({3: 'coupling = { axis = "A2", factor = 0 }'}, None, "axis[3].coupling", "not 0, got 0"),
    ({3: 'coupling = { axis = "A2" }'}, None, "axis[3].coupling", "a table {axis = NAME, factor = F}"),
    (None, "tool = { z = 100, qw = 0.9, qx = 0.1 }", "kinematics.tool", "got one of norm 0.905539"),
    (None, "tool = { z = 100, roll = 10, qw = 1 }", "kinematics.tool", "not both (got roll and qw)"),
    (None, "tool = { z = 100, q1 = 1 }", "kinematics.tool", "unknown key 'q1'"),
    (None, "tool = { z = nan }", "kinematics.tool.z", "expected a number (mm), got nan"),
    (None, "mounting = { z = 200000 }", "kinematics.mounting", "at most 100000 mm from its frame's, got 200000 mm"),
    (None, "mounting = 3", "kinematics.mounting", "expected a table {x, y, z}"),
    (None, "mountin = { z = 1 }", "kinematics.mountin", "did you mean 'mounting'"),
])
def test_bad_keys_are_refused_with_the_key_and_what_is_allowed(axis_keys, kinematics, where, message):
    with pytest.raises(SpecError) as info:
        spec_with(axis_keys, kinematics)
    assert f"arm.spc: {where}: " in str(info.value) and message in str(info.value), str(info.value)


def test_the_checker_measures_reach_from_where_the_robot_stands(tmp_path):
    text = BASE.replace("[kinematics]\n", "[kinematics]\nmounting = { z = 2500, roll = 180 }\n", 1)
    ceiling = tmp_path / "ceiling.spc"
    ceiling.write_text(text)
    program = tmp_path / "cell.irl"  # 300 mm below the ceiling, then 300 mm above the floor
    program.write_text("program cell;\nseq\n"
                       "move lin pose(pos(900, 0, 2200), rpy(180, 0, 0));\n"
                       "move lin pose(pos(900, 0, 300), rpy(180, 0, 0));\nendseq\nendprogram;\n")
    code, _, err = run_cli("check", program, "--spec", ceiling)
    assert code == 1 and "cell.irl:4" in err and "cell.irl:3" not in err, err
    assert "1653.9 mm from the shoulder" in err
    code, _, err = run_cli("check", program, "--spec", SPEC_PATH)
    assert code == 1 and "cell.irl:3" in err and "cell.irl:4" not in err, err
