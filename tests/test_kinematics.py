"""Forward and inverse kinematics of the six-axis spherical-wrist arm (runtime.motion.kinematics).

* Forward kinematics against an independent NumPy product of standard DH matrices (all
  zeros, each axis at +-90 deg, random joints), one pose checked by hand.
* Inverse kinematics over many random reachable poses (random joints within the limits,
  away from singularities, FK as the pose): every solution of ``solutions()`` reproduces
  the pose (1e-6 mm, 1e-9 rad), the generating joints are among them with their
  configuration id, ``inverse(near=q)`` returns q. Without limits all eight
  configurations exist and are distinct. The same for a second, more general geometry
  (lateral shoulder offset, a6 != 0, alpha6 != 0, other alpha signs, a rotated tool).
* Within 1e-5.5 .. 1e-2 of a wrist or elbow singularity (outside the tolerances) every
  solution still reproduces the pose to 1e-6 mm and 1e-9 rad.
* The configuration bits mean what they say geometrically (front/back, elbow above or
  below the shoulder-wrist line, sign of A5), for the Lola 15 and the general geometry.
* The module's examples (doctest).
* Errors: unreachable (with the distance), singular (shoulder, elbow, wrist), outside
  the limits; geometry that is not a spherical-wrist arm is refused naming the axis.
* Hypothesis (derandomized): inverse(forward(q), near=q) == q within 1e-9 deg (mod 360)
  for joints whose elbow and wrist margins exceed JOINT_MARGIN (0.01).
* The Jacobian against finite differences, and its determinant against the margins.

NumPy is used here only, as the independent reference.
"""
from __future__ import annotations

import math
import random
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from compiler.spec import parse_spec
from compiler.values import Pose, Position, Quat, Rpy
from runtime.motion.kinematics import (
    ELBOW_DOWN,
    SHOULDER_BACK,
    WRIST_FLIP,
    Kinematics,
    KinematicsError,
    configuration_name,
    matrix_to_rpy,
    rpy_to_matrix,
)

from conftest import SPEC_PATH, SPEC, examples
KIN = Kinematics(SPEC)
POS_TOL = 1e-6  # mm (1e-9 m)
ROT_TOL = 1e-9  # rad
JOINT_TOL = 1e-9  # deg
# Joint values come back within JOINT_TOL when the elbow and wrist margins (|sin(theta3 -
# phi)|, |sin(theta5)|) exceed this; near two singularities at once the pose's rounding
# (1e-13 mm) is amplified: e.g. 2e-9 deg with the elbow folded to 0.0017 and A5 at 0.12 deg
# (the pose is still reproduced to 1e-12 mm).
JOINT_MARGIN = 1e-2

# A second geometry exercising what the Lola 15 does not: other alpha signs, a lateral
# shoulder offset (d2 + d3), a flange offset a6 with alpha6 = 30 deg, a rotated tool.
GENERAL_ROWS = [(150.0, 90.0, 400.0, 10.0), (500.0, 0.0, 60.0, 0.0), (-40.0, 90.0, 25.0, 30.0),
                (0.0, -90.0, 450.0, 0.0), (0.0, 90.0, 0.0, -20.0), (30.0, 30.0, 80.0, 5.0)]
GENERAL_TOOL = (10.0, -20.0, 120.0, 15.0, -30.0, 40.0)
GENERAL = Kinematics(GENERAL_ROWS, tool=GENERAL_TOOL)


# ---- the independent reference ---------------------------------------------------------

def np_dh(a, alpha, d, theta):
    """Standard DH: Rz(theta) Tz(d) Tx(a) Rx(alpha), angles in radians."""
    ct, st_, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st_ * ca, st_ * sa, a * ct],
                     [st_, ct * ca, -ct * sa, a * st_],
                     [0.0, sa, ca, d],
                     [0.0, 0.0, 0.0, 1.0]])


def np_rot(axis, angle):
    c, s = math.cos(angle), math.sin(angle)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], float)
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], float)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], float)


def np_rpy(roll, pitch, yaw):
    """R = Rz(yaw) Ry(pitch) Rx(roll), degrees."""
    return np_rot("z", math.radians(yaw)) @ np_rot("y", math.radians(pitch)) @ np_rot("x", math.radians(roll))


def np_forward(rows, tool, q):
    t = np.eye(4)
    for (a, alpha, d, off), qi in zip(rows, q):
        t = t @ np_dh(a, math.radians(alpha), d, math.radians(qi + off))
    tt = np.eye(4)
    tt[:3, :3] = np_rpy(*tool[3:])
    tt[:3, 3] = tool[:3]
    return t @ tt


LOLA_ROWS = [(ax.dh.a, ax.dh.alpha, ax.dh.d, ax.dh.theta_offset) for ax in SPEC.main_axes]


def rotation_error(r1, r2) -> float:
    """Angle (rad) of r1^T r2, robust for small angles."""
    diff = np.linalg.norm(np.asarray(r1, float) - np.asarray(r2, float))
    return 2.0 * math.asin(min(1.0, diff / (2.0 * math.sqrt(2.0))))


def pose_error(kin, joints, target_matrix) -> tuple[float, float]:
    m = np.array(kin.forward_matrix(joints))
    t = np.asarray(target_matrix, float)
    return float(np.linalg.norm(m[:3, 3] - t[:3, 3])), rotation_error(m[:3, :3], t[:3, :3])


def angle_diff(a, b) -> float:
    """|a - b| modulo 360, in deg."""
    return abs((a - b + 180.0) % 360.0 - 180.0)


def random_joints(kin, rng, limits=None, margin=1e-3):
    """Random joints within the limits, away from every singularity."""
    limits = limits or kin.limits
    while True:
        q = tuple(rng.uniform(lo, hi) for lo, hi in limits)
        shoulder, elbow, wrist = kin.singularity_margins(q)
        if shoulder > 1.0 and elbow > margin and wrist > margin:
            return q


# ---- forward -------------------------------------------------------------------------

def test_lola_geometry_is_accepted_as_is():
    assert [ax.dh.theta_offset for ax in SPEC.main_axes] == [0.0, -90.0, 0.0, 0.0, 0.0, 0.0]
    assert SPEC.tool == (0.0, 0.0, 100.0, 0.0, 0.0, 0.0)
    assert KIN.names == ("A1", "A2", "A3", "A4", "A5", "A6")
    assert KIN.limits[1] == (-135.0, 90.0)


def test_forward_at_zero_by_hand():
    # A1 at 0: the shoulder is a1 = 260 mm out, d1 = 675 mm up; A2 at 0 (theta2 = -90):
    # the upper arm (680) points up; A3 at 0: a3 = 35 mm further up, the forearm d4 = 670
    # forward, then d6 + tool = 215 mm forward: the TCP at x = 260 + 670 + 215, z = 675 +
    # 680 + 35, its z axis forward (+x), its x axis up, its y axis -y.
    m = KIN.forward_matrix((0, 0, 0, 0, 0, 0))
    assert np.allclose(np.array(m), [[0, 0, 1, 1145], [0, -1, 0, 0], [1, 0, 0, 1390], [0, 0, 0, 1]],
                       atol=1e-12)
    x, y, z, roll, pitch, yaw = KIN.forward((0, 0, 0, 0, 0, 0))
    assert (x, y, z) == pytest.approx((1145.0, 0.0, 1390.0), abs=1e-12)
    assert pitch == pytest.approx(-90.0)
    assert np.allclose(np_rpy(roll, pitch, yaw), np.array(m)[:3, :3], atol=1e-12)


KNOWN = [(0.0,) * 6] + [tuple(s * 90.0 if i == j else 0.0 for j in range(6)) for i in range(6) for s in (1, -1)]


@pytest.mark.parametrize("q", KNOWN, ids=lambda q: ",".join(f"{v:g}" for v in q))
def test_forward_known_poses_against_numpy(q):
    ref = np_forward(LOLA_ROWS, SPEC.tool, q)
    m = np.array(KIN.forward_matrix(q))
    assert m.shape == (4, 4)
    assert all(type(v) is float for row in KIN.forward_matrix(q) for v in row)
    assert np.max(np.abs(m - ref)) < 1e-9
    pose = KIN.forward(q)
    assert np.allclose(pose[:3], ref[:3, 3], atol=1e-9)
    assert rotation_error(np_rpy(*pose[3:]), ref[:3, :3]) < 1e-12


def test_forward_random_against_numpy():
    rng = random.Random(7)
    bare = Kinematics(LOLA_ROWS)  # no tool: the TCP is the flange
    for kin, rows, tool in ((KIN, LOLA_ROWS, SPEC.tool), (GENERAL, GENERAL_ROWS, GENERAL_TOOL),
                            (bare, LOLA_ROWS, (0.0,) * 6)):
        for _ in range(300):
            q = tuple(rng.uniform(-400.0, 400.0) for _ in range(6))
            ref = np_forward(rows, tool, q)
            assert np.max(np.abs(np.array(kin.forward_matrix(q)) - ref)) < 1e-9
            pose = kin.forward(q)
            assert rotation_error(np_rpy(*pose[3:]), ref[:3, :3]) < 1e-12
            assert -90.0 <= pose[4] <= 90.0 and -180.0 <= pose[3] <= 180.0 and -180.0 <= pose[5] <= 180.0
            if min(kin.singularity_margins(q)[1:]) > 1e-3 and kin.singularity_margins(q)[0] > 1.0:
                for _, joints in kin.solutions(pose, near=q):
                    dp, dr = pose_error(kin, joints, ref)
                    assert dp <= POS_TOL and dr <= ROT_TOL


def test_forward_accepts_joint_values_and_returns_a_pose():
    from compiler.values import Joint
    q = (10.0, -20.0, 30.0, 40.0, 50.0, 60.0)
    assert KIN.forward(Joint(q)) == KIN.forward(q)
    pose = KIN.forward_pose(q)
    assert isinstance(pose, Pose) and isinstance(pose.orientation, Rpy)
    assert KIN.inverse(pose, near=q) == pytest.approx(q, abs=JOINT_TOL)
    with pytest.raises(ValueError, match="six joint values"):
        KIN.forward((1.0, 2.0))


# ---- orientation convention ------------------------------------------------------------

def test_rpy_convention():
    # yaw alone is a rotation about z, pitch about y, roll about x
    assert np.allclose(rpy_to_matrix(0, 0, 90), [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    assert np.allclose(rpy_to_matrix(0, 90, 0), [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-15)
    assert np.allclose(rpy_to_matrix(90, 0, 0), [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-15)
    # composition R = Rz(yaw) Ry(pitch) Rx(roll)
    assert np.allclose(rpy_to_matrix(10, 20, 30), np_rpy(10, 20, 30), atol=1e-15)
    # the language reference's "down := rpy(180, 0, 180)": the tool's z axis points down
    assert np.allclose(np.array(rpy_to_matrix(180, 0, 180))[:, 2], [0, 0, -1], atol=1e-15)


def test_matrix_to_rpy_round_trip_and_gimbal_lock():
    rng = random.Random(3)
    for _ in range(500):
        rpy = (rng.uniform(-180, 180), rng.uniform(-90, 90), rng.uniform(-180, 180))
        back = matrix_to_rpy(rpy_to_matrix(*rpy))
        assert rotation_error(rpy_to_matrix(*back), rpy_to_matrix(*rpy)) < 1e-13
    for pitch in (90.0, -90.0, 90.0 - 1e-9, -90.0 + 1e-12):
        m = rpy_to_matrix(25.0, pitch, -70.0)
        back = matrix_to_rpy(m)
        assert rotation_error(rpy_to_matrix(*back), m) < 1e-13
    assert matrix_to_rpy(rpy_to_matrix(25.0, 90.0, -70.0))[2] == 0.0  # yaw 0 at the lock


# ---- inverse: random reachable poses -------------------------------------------------

def check_all_solutions(kin, q, expect_all_eight=False):
    target = kin.forward_matrix(q)
    pose = kin.forward(q)
    sols = kin.solutions(pose, near=q)
    ids = [cid for cid, _ in sols]
    assert ids == sorted(set(ids))
    if expect_all_eight:
        assert ids == list(range(8))
    for cid, joints in sols:
        dp, dr = pose_error(kin, joints, target)
        assert dp <= POS_TOL and dr <= ROT_TOL, (q, cid, joints, dp, dr)
        assert kin.configuration(joints) == cid
        for (lo, hi), v in zip(kin.limits, joints):
            assert lo <= v <= hi
        assert kin.inverse(pose, near=q, configuration=cid) == joints
    own = kin.configuration(q)
    assert own in ids
    back = kin.inverse(pose, near=q)
    # joint values are recovered as well as the pose's conditioning allows: 1e-9 deg
    # unless close to two singularities at once (see JOINT_MARGIN)
    tol = JOINT_TOL if min(kin.singularity_margins(q)[1:]) > JOINT_MARGIN else 1e-6
    assert max(angle_diff(a, b) for a, b in zip(dict(sols)[own], q)) < tol
    assert max(abs(a - b) for a, b in zip(back, q)) < tol, (q, back)
    return sols


def test_inverse_random_reachable_poses_all_configurations():
    rng = random.Random(11)
    counts = [0] * 9
    for _ in range(1500):
        q = random_joints(KIN, rng)
        counts[len(check_all_solutions(KIN, q))] += 1
    assert counts[0] == 0
    assert sum(counts[4:]) > 0  # several configurations are commonly within the limits


def test_inverse_without_limits_gives_eight_distinct_configurations():
    free = Kinematics(LOLA_ROWS, tool=SPEC.tool)
    rng = random.Random(12)
    for _ in range(500):
        q = random_joints(free, rng, limits=SPEC_LIMITS_WIDE, margin=1e-2)
        pose = free.forward(q)
        sols = free.solutions(pose, near=q)
        if len(sols) < 8:  # another configuration singular or beyond reach: allowed, rare
            assert all(pose_error(free, j, free.forward_matrix(q))[0] <= POS_TOL for _, j in sols)
            continue
        check_all_solutions(free, q, expect_all_eight=True)
        joints = [j for _, j in sols]
        for i in range(8):
            for j in range(i):
                assert max(angle_diff(a, b) for a, b in zip(joints[i], joints[j])) > 1e-6


SPEC_LIMITS_WIDE = [(-180.0, 180.0)] * 6


def test_inverse_general_geometry():
    rng = random.Random(13)
    eight = 0
    for _ in range(800):
        q = random_joints(GENERAL, rng, limits=SPEC_LIMITS_WIDE, margin=1e-2)
        sols = check_all_solutions(GENERAL, q)
        eight += len(sols) == 8
    assert eight > 400


def test_inverse_of_a_pose_in_every_form():
    q = (20.0, -30.0, 40.0, -50.0, 60.0, -70.0)
    x, y, z, roll, pitch, yaw = KIN.forward(q)
    m = KIN.forward_matrix(q)
    rot = np.array(m)[:3, :3]
    w = math.sqrt(max(0.0, 1.0 + np.trace(rot))) / 2.0
    quat = Quat(w, (rot[2, 1] - rot[1, 2]) / (4 * w), (rot[0, 2] - rot[2, 0]) / (4 * w),
                (rot[1, 0] - rot[0, 1]) / (4 * w))
    forms = [(x, y, z, roll, pitch, yaw), [x, y, z, roll, pitch, yaw], m, m[:3],
             Pose(Position(x, y, z), Rpy(roll, pitch, yaw)), Pose(Position(x, y, z), quat)]
    for form in forms:
        assert KIN.inverse(form, near=q) == pytest.approx(q, abs=1e-9)
    with pytest.raises(KinematicsError, match="not finite"):
        KIN.inverse((math.nan, 0, 0, 0, 0, 0))
    with pytest.raises(KinematicsError, match="not a rotation"):
        KIN.inverse(((1, 0, 0, 0), (0, 2, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)))
    with pytest.raises(KinematicsError, match="not a rotation"):
        KIN.inverse(Pose(Position(0, 0, 0), Quat(0.0, 0.0, 0.0, 0.0)))


def test_default_near_is_home_and_representations_follow_near():
    q = (20.0, -30.0, 40.0, -50.0, 60.0, -70.0)
    pose = KIN.forward(q)
    assert KIN.inverse(pose) == pytest.approx(q, abs=JOINT_TOL)  # the nearest to all-zero home
    # axis 6 (-350..350) has two representations of -70: near 300 picks 290
    far6 = KIN.inverse(pose, near=q[:5] + (300.0,))
    assert far6 == pytest.approx(q[:5] + (290.0,), abs=JOINT_TOL)
    # axis 4 (-185..185): -50 has no other representation within the limits; near 300 the
    # flipped wrist (130, -60, -250: A6 near its -70) is nearer; in q's own configuration A4 stays -50
    near4 = q[:3] + (300.0,) + q[4:]
    assert KIN.inverse(pose, near=near4) == pytest.approx((20.0, -30.0, 40.0, 130.0, -60.0, -250.0), abs=JOINT_TOL)
    assert KIN.inverse(pose, near=near4, configuration=KIN.configuration(q))[3] == pytest.approx(-50.0)


def test_representation_nearest_near_within_limits_brute_force():
    from runtime.motion.kinematics import _fit
    rng = random.Random(4)
    for _ in range(20000):
        lo = rng.uniform(-400.0, 100.0)
        hi = lo + rng.choice((rng.uniform(1.0, 800.0), 360.0, 1e-3))
        q, n = rng.uniform(-1000.0, 1000.0), rng.uniform(-500.0, 500.0)
        got = _fit(q, lo, hi, n)
        inside = [q + 360.0 * k for k in range(-10, 11) if lo - 1e-9 <= q + 360.0 * k <= hi + 1e-9]
        if not inside:
            assert got is None
            continue
        assert got is not None and lo <= got <= hi
        assert abs(got - n) <= min(abs(c - n) for c in inside) + 1e-9
        assert angle_diff(got, q) < 1e-9


def test_joint_exactly_at_a_limit_is_kept_within_it():
    q = (170.0, 90.0, -120.0, 185.0, 119.0, -350.0)
    pose = KIN.forward(q)
    back = KIN.inverse(pose, near=q)
    assert back == pytest.approx(q, abs=JOINT_TOL)
    for (lo, hi), v in zip(KIN.limits, back):
        assert lo <= v <= hi


def test_nearest_configuration_is_chosen():
    rng = random.Random(21)
    for _ in range(200):
        q = random_joints(KIN, rng)
        pose = KIN.forward(q)
        sols = KIN.solutions(pose)
        best = min(sols, key=lambda s: sum((a - b) ** 2 for a, b in zip(s[1], KIN.home)))
        assert KIN.inverse(pose) == best[1]
        for cid, joints in sols:  # near a solution, that solution
            assert KIN.inverse(pose, near=joints) == pytest.approx(joints, abs=JOINT_TOL)


def test_near_singularities_the_pose_is_still_reproduced():
    # within 1e-5.5 .. 1e-2 of a wrist or elbow singularity (outside the tolerances)
    rng = random.Random(17)
    phi = math.degrees(math.atan2(-670.0, 35.0))
    checked = 0
    for i in range(1500):
        q = [rng.uniform(lo, hi) for lo, hi in KIN.limits]
        eps = math.degrees(10.0 ** rng.uniform(-5.5, -2.0)) * rng.choice((-1.0, 1.0))
        if i % 3 == 0:
            q[4] = eps
        elif i % 3 == 1:
            q[2] = phi + eps
        else:
            q[2], q[4] = phi + 180.0 + eps, -eps
        q = tuple(q)
        if KIN.singularity_margins(q)[0] < 1.0 or not KIN.limits[2][0] <= q[2] <= KIN.limits[2][1]:
            continue
        target = KIN.forward_matrix(q)
        try:
            back = KIN.inverse(KIN.forward(q), near=q)
        except KinematicsError as exc:
            assert str(exc).startswith("singular:")  # rounded into the tolerance band
            continue
        checked += 1
        for _, joints in [(None, back)] + KIN.solutions(KIN.forward(q)):
            dp, dr = pose_error(KIN, joints, target)
            assert dp <= POS_TOL and dr <= ROT_TOL, (q, joints, dp, dr)
        # (the joints themselves only as well as the conditioning allows: up to ~1e-5 deg
        # here with both singularities within 1e-5.5)
    assert checked > 1000


def test_module_examples():
    import doctest

    import runtime.motion.kinematics as module
    assert doctest.testmod(module).failed == 0


# ---- configuration bits mean what the documentation says -----------------------------

@pytest.mark.parametrize("kin", [KIN, GENERAL], ids=["lola15", "general"])
def test_configuration_bits_are_geometric(kin):
    rng = random.Random(5)
    seen = set()
    offsets = [row[3] for row in kin.dh]
    for _ in range(400):
        q = random_joints(kin, rng, limits=KIN.limits, margin=1e-2)
        frames = [np.array(f) for f in kin.frames(q)]
        shoulder, elbow, wrist_centre = frames[0][:3, 3], frames[1][:3, 3], frames[3][:3, 3]
        x1 = frames[0][:3, 0]  # horizontal: axis 1 is the base z axis
        towards = float(np.dot(x1, wrist_centre))
        back = towards < 0.0
        h = x1 if towards > 0.0 else -x1

        def plane(v):
            return np.array([np.dot(v, h), v[2]])

        ws, es = plane(wrist_centre - shoulder), plane(elbow - shoulder)
        down = ws[0] * es[1] - ws[1] * es[0] < 0.0  # clockwise from the shoulder-wrist line
        flip = math.sin(math.radians(q[4] + offsets[4])) < 0.0
        cid = kin.configuration(q)
        assert cid == (SHOULDER_BACK if back else 0) | (ELBOW_DOWN if down else 0) | (WRIST_FLIP if flip else 0)
        seen.add(cid)
    assert len(seen) == 8
    assert configuration_name(0) == "front, elbow up, wrist not flipped"
    assert configuration_name(7) == "back, elbow down, wrist flipped"


def test_zero_position_is_front_elbow_up():
    assert KIN.configuration((0, 0, 0, 0, 30, 0)) == 0
    assert KIN.configuration((0, 0, 0, 0, -30, 0)) == WRIST_FLIP


# ---- errors ----------------------------------------------------------------------------

def test_unreachable_says_by_how_much():
    # tool pointing up (rpy 0): the wrist centre is 215 mm below the TCP
    x, y, z = 3000.0, 0.0, 500.0
    wc = np.array([x, y, z - 215.0])
    l3 = math.hypot(35.0, 670.0)
    excess = math.hypot(wc[0] - 260.0, wc[2] - 675.0) - (680.0 + l3)
    with pytest.raises(KinematicsError) as info:
        KIN.inverse((x, y, z, 0, 0, 0))
    assert str(info.value) == f"unreachable: the wrist centre is {excess:.1f} mm beyond the arm's reach"
    with pytest.raises(KinematicsError, match=r"^unreachable: the wrist centre is \d+\.\d mm beyond"):
        KIN.inverse((0.0, -2000.0, 2500.0, 10, 20, 30), configuration=5)
    assert KIN.solutions((x, y, z, 0, 0, 0)) == []


def test_unreachable_inside_the_inner_reach():
    # the Lola's inner reach: |a2 - L3| = 9.09 mm around axis 2; a wrist centre exactly
    # at axis 2 (of the front shoulder) is 9.09 mm inside it
    l3 = math.hypot(35.0, 670.0)
    with pytest.raises(KinematicsError) as info:
        KIN.inverse((260.0, 0.0, 675.0 + 215.0, 0, 0, 0), configuration=0)
    assert str(info.value) == (f"unreachable: the wrist centre is {abs(680.0 - l3):.1f} mm inside the arm's "
                               f"inner reach (too close to axis 2)")


def test_wrist_singularity():
    q = (10.0, 20.0, 30.0, 40.0, 0.0, 60.0)
    with pytest.raises(KinematicsError) as info:
        KIN.inverse(KIN.forward(q), near=q)
    assert str(info.value) == "singular: wrist singularity (A5 at 0 deg)"
    with pytest.raises(KinematicsError, match=r"^singular: wrist singularity \(A5 at 0 deg\)$"):
        KIN.inverse(KIN.forward((0.0,) * 6))  # the zero position itself
    # just outside the tolerance (|sin theta5| >= 1e-6) it solves, and reproduces the pose
    q = (10.0, 20.0, 30.0, 40.0, math.degrees(2e-6), 60.0)
    back = KIN.inverse(KIN.forward(q), near=q)
    dp, dr = pose_error(KIN, back, KIN.forward_matrix(q))
    assert dp <= POS_TOL and dr <= ROT_TOL
    # the singular configuration is left out of solutions(); others remain
    q = (10.0, 20.0, 30.0, 40.0, 0.0, 60.0)
    sols = KIN.solutions(KIN.forward(q))
    assert KIN.configuration(q) & 3 not in {cid & 3 for cid, _ in sols}
    for cid, joints in sols:
        assert pose_error(KIN, joints, KIN.forward_matrix(q))[0] <= POS_TOL


def test_shoulder_singularity():
    # tool pointing up: the wrist centre 215 mm below the TCP, right on axis 1
    with pytest.raises(KinematicsError) as info:
        KIN.inverse((0.0, 0.0, 1715.0, 0, 0, 0))
    assert str(info.value) == "singular: shoulder singularity (wrist centre on axis 1)"
    with pytest.raises(KinematicsError, match="shoulder singularity"):
        KIN.inverse((1e-7, -1e-7, 1715.0, 0, 0, 0), configuration=3)
    assert KIN.solutions((0.0, 0.0, 1715.0, 0, 0, 0)) == []
    # 1e-3 mm away it solves (axis 1 is then well defined)
    back = KIN.inverse((1e-3, 0.0, 1715.0, 0, 0, 0))
    dp, dr = pose_error(KIN, back, ((1, 0, 0, 1e-3), (0, 1, 0, 0), (0, 0, 1, 1715.0), (0, 0, 0, 1)))
    assert dp <= POS_TOL and dr <= ROT_TOL


def test_elbow_singularity_stretched_and_folded():
    phi = math.degrees(math.atan2(-670.0, 35.0))  # theta3 with the forearm in line with the upper arm
    q = (10.0, -20.0, phi, 30.0, 40.0, 50.0)
    assert KIN.singularity_margins(q)[1] < 1e-12
    with pytest.raises(KinematicsError) as info:
        KIN.inverse(KIN.forward(q), near=q)
    assert str(info.value) == "singular: elbow singularity (arm stretched)"
    q = (10.0, -20.0, phi + 180.0, 30.0, 40.0, 50.0)
    with pytest.raises(KinematicsError, match=r"^singular: elbow singularity \(arm folded\)$"):
        KIN.inverse(KIN.forward(q), near=q)


def test_outside_the_axis_limits():
    tight = Kinematics(LOLA_ROWS, tool=SPEC.tool, limits=[(-170, 170), (-10, 10), (-120, 156),
                                                          (-185, 185), (-120, 120), (-350, 350)])
    q = (10.0, 45.0, 30.0, 40.0, 50.0, 60.0)
    pose = tight.forward(q)
    with pytest.raises(KinematicsError) as info:
        tight.inverse(pose, configuration=KIN.configuration(q))
    assert str(info.value).startswith("no solution within the axis limits (A2 would be 45.0 deg, limit -10..10;")
    # all configurations: still an error; the message names the smallest violation
    with pytest.raises(KinematicsError, match=r"^no solution within the axis limits \(A\d would be -?\d+\.\d deg, "):
        tight.inverse(pose)
    # a pose reachable only behind the robot with A1 at 180 (limits +-170): A1 named
    behind = KIN.forward((180.0, 0.0, 0.0, 0.0, 30.0, 0.0))
    with pytest.raises(KinematicsError, match=r"A1 would be 180\.0 deg, limit -170\.\.170"):
        KIN.inverse(behind, configuration=0)
    with pytest.raises(ValueError, match="configuration must be an integer 0..7"):
        KIN.inverse(pose, configuration=8)


def test_geometry_that_is_not_a_spherical_wrist_arm_is_refused():
    def rows_with(i, **change):
        rows = [list(r) for r in LOLA_ROWS]
        for key, value in change.items():
            rows[i]["a alpha d".split().index(key)] = value
        return rows

    cases = [(rows_with(3, a=10.0), "axis A4: a must be 0 mm"),
             (rows_with(4, a=5.0), "axis A5: a must be 0 mm"),
             (rows_with(4, d=5.0), "axis A5: d must be 0 mm"),
             (rows_with(1, alpha=10.0), "axis A2: alpha must be 0 deg"),
             (rows_with(0, alpha=0.0), "axis A1: alpha must be +-90 deg"),
             (rows_with(2, alpha=45.0), "axis A3: alpha must be +-90 deg"),
             (rows_with(3, alpha=0.0), "axis A4: alpha must be +-90 deg"),
             (rows_with(4, alpha=180.0), "axis A5: alpha must be +-90 deg"),
             (rows_with(1, a=0.0), "axis A2: a (the upper arm) must not be 0 mm")]
    for rows, message in cases:
        with pytest.raises(ValueError, match=re.escape(message)):
            Kinematics(rows)
    with pytest.raises(ValueError, match="six DH rows"):
        Kinematics(LOLA_ROWS[:5])
    text = SPEC_PATH.read_text(encoding="utf-8")
    with pytest.raises(ValueError, match="axis A6: the arm's axes must be revolute"):
        Kinematics(parse_spec(text.replace('name = "A6"\nkind = "revolute"', 'name = "A6"\nkind = "prismatic"')
                                      .replace("gear_ratio = 60.0", "gear_ratio = 1.0")))
    with pytest.raises(ValueError, match="axis A4: a must be 0 mm"):
        Kinematics(parse_spec(text.replace("a = 0.0, alpha = 90.0, d = 670.0", "a = 1.0, alpha = 90.0, d = 670.0")))
    with pytest.raises(ValueError, match="axis A3: no dh parameters"):
        Kinematics(parse_spec(text.replace("dh = { a = 35.0, alpha = -90.0, d = 0.0 }\n", "")))


# ---- hypothesis --------------------------------------------------------------------------

JOINTS = st.tuples(*(st.floats(lo, hi, allow_nan=False) for lo, hi in KIN.limits))


@settings(max_examples=examples(400), deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.filter_too_much])
@given(JOINTS)
def test_property_inverse_of_forward_is_identity(q):
    shoulder, elbow, wrist = KIN.singularity_margins(q)
    assume(shoulder > 1.0 and elbow > JOINT_MARGIN and wrist > JOINT_MARGIN)
    back = KIN.inverse(KIN.forward(q), near=q)
    assert max(angle_diff(a, b) for a, b in zip(back, q)) < JOINT_TOL, (q, back)


# ---- Jacobian ------------------------------------------------------------------------------

def test_jacobian_against_finite_differences_and_margins():
    rng = random.Random(9)
    for kin in (KIN, GENERAL):
        for _ in range(30):
            q = np.array([rng.uniform(-150, 150) for _ in range(6)])
            jac = np.array(kin.jacobian(tuple(q)))
            assert jac.shape == (6, 6)
            h = 1e-6  # deg
            num = np.zeros((6, 6))
            r0 = np.array(kin.forward_matrix(tuple(q)))[:3, :3]
            for i in range(6):
                dq = np.zeros(6)
                dq[i] = h
                mp = np.array(kin.forward_matrix(tuple(q + dq)))
                mm = np.array(kin.forward_matrix(tuple(q - dq)))
                scale = 2.0 * math.radians(h)
                num[:3, i] = (mp[:3, 3] - mm[:3, 3]) / scale
                skew = (mp[:3, :3] - mm[:3, :3]) / scale @ r0.T  # dR/dq R^T = [w]x
                num[3:, i] = (skew[2, 1], skew[0, 2], skew[1, 0])
            assert np.allclose(jac[:3], num[:3], atol=1e-4, rtol=1e-6)
            assert np.allclose(jac[3:], num[3:], atol=1e-7)
    # |det J| = shoulder * a2 * L3 * elbow * wrist for the Lola 15
    l3 = math.hypot(35.0, 670.0)
    for _ in range(50):
        q = tuple(rng.uniform(lo, hi) for lo, hi in KIN.limits)
        shoulder, elbow, wrist = KIN.singularity_margins(q)
        det = abs(np.linalg.det(np.array(KIN.jacobian(q))))
        assert det == pytest.approx(shoulder * 680.0 * l3 * elbow * wrist, rel=1e-9, abs=1e-6)
