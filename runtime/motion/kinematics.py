"""Forward and inverse kinematics of a six-axis arm with a spherical wrist, in plain floats.

The arm is the one the system specification describes (``programs/lola15.spc``): six
revolute main axes, each with standard Denavit-Hartenberg parameters ``a`` (mm),
``alpha`` (deg), ``d`` (mm) and ``theta_offset`` (deg), and a tool centre point (TCP)
``[kinematics] tool = {x, y, z, roll, pitch, yaw}`` given in the flange frame::

    >>> from compiler.spec import load_spec
    >>> kin = Kinematics(load_spec("programs/lola15.spc"))
    >>> [round(v, 3) + 0.0 for v in kin.forward((0, 0, 0, 0, 30, 10))]
    [1116.195, 0.0, 1282.5, -163.26, -58.525, -19.425]
    >>> [round(v, 9) + 0.0 for v in kin.inverse(kin.forward((0, 0, 0, 0, 30, 10)))]
    [0.0, 0.0, 0.0, 0.0, 30.0, 10.0]
    >>> [(cid, [round(v, 3) + 0.0 for v in q]) for cid, q in kin.solutions(kin.forward((0, 0, 0, 0, 30, 10)))]
    [(0, [0.0, 0.0, 0.0, 0.0, 30.0, 10.0]), (4, [0.0, 0.0, 0.0, 180.0, -30.0, -170.0])]
    >>> try:
    ...     kin.inverse(kin.forward((0, 0, 0, 0, 0, 0)))
    ... except KinematicsError as exc:
    ...     print(exc)
    singular: wrist singularity (A5 at 0 deg)

(the zero position has A5 at 0: axes 4 and 6 in line, a wrist singularity).

Conventions
-----------
* **Units at the API**: lengths in mm, angles in degrees (joint values, roll/pitch/yaw).
* **DH (standard, "distal")**: link ``i`` is ``Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``
  with ``theta_i = direction_i q_i + theta_offset_i`` where ``q_i`` is the joint value
  (what ``joint(mainjoint(...))`` holds, what the axis limits bound) and ``direction_i``
  is 1 or -1 (``[[axis]] direction``: KUKA's A1 turns about -z). A coupled axis (2 or 3,
  ``[[axis]] coupling``) adds ``factor x q_j`` of an earlier axis ``j`` (FANUC's J3,
  measured from the horizontal: ``theta_3 = q_3 - q_2 + ...``). The flange is frame 6;
  the TCP is ``T_mount * T_06 * T_tool``, ``T_mount`` the robot's base in the world frame
  (``[kinematics] mounting``; the identity on the floor): poses given to and returned
  by every method are in the world frame.
* **Orientation (roll, pitch, yaw)**: ``R = Rz(yaw) Ry(pitch) Rx(roll)`` -- roll about x,
  pitch about y, yaw about z of the base (fixed axes, applied in that order; the same
  as intrinsic z-y'-x''). docs/language.md does not fix a convention; this is the one
  for ``rpy(roll, pitch, yaw)``, for poses and for the spec's tool. ``forward`` returns
  pitch in [-90, 90] and roll, yaw in [-180, 180]; at pitch = +-90 (gimbal lock) it
  returns yaw = 0 and puts the whole rotation about the vertical into roll.
  ``quat(w, x, y, z)`` is the usual unit quaternion (normalised here again).
* **Poses** given to :meth:`Kinematics.inverse` / :meth:`Kinematics.solutions` may be a
  6-sequence ``(x, y, z, roll, pitch, yaw)``, a :class:`compiler.values.Pose` (``Rpy`` or
  ``Quat`` orientation) or a 4x4 (or 3x4) homogeneous matrix as nested sequences.
* **Configurations**: eight closed-form solutions, numbered by a bit set (0..7)::

      SHOULDER_BACK = 1  the wrist centre lies behind axis 1: on the far side of axis 1
                         from link 1's x direction (x1 = (cos theta1, sin theta1, 0), the
                         direction of the shoulder offset a1); clear = "front"
      ELBOW_DOWN    = 2  the elbow (axis 3) lies below the line from axis 2 to the wrist
                         centre, in the arm's plane, "below" meaning: clockwise from that
                         line when seen with the base z axis up and, to the right, the
                         one of x1, -x1 that points towards the wrist centre (a world-
                         geometric notion: in the "back" configuration too, "up" is the
                         base's up); clear = "up"
      WRIST_FLIP    = 4  sin(theta5) < 0, theta5 = direction5 A5 + theta_offset5 (for
                         the Lola 15: A5 < 0); clear: sin(theta5) > 0

  The bits, and the words a program names them with (``front`` | ``back``, ``elbow_up`` |
  ``elbow_down``, ``noflip`` | ``flip``), are declared in :mod:`compiler.configs`.
  :meth:`Kinematics.configuration` gives the id of given joint values;
  :func:`configuration_name` a text ("back, elbow up, wrist flipped").
* **Choice**: :meth:`Kinematics.inverse` returns the solution nearest ``near`` (default:
  the axes' home positions) in the Euclidean joint-space distance (degrees), every
  angle taking the representation ``q + k 360`` that is nearest ``near`` among those
  within the axis limits (axis 6 of the Lola 15, -350..350, has two for most angles);
  with ``configuration=`` only that configuration. :meth:`Kinematics.inverse_config`
  takes what a pose target's ``config(...)`` names: some groups (the nearest solution of
  the configurations that have them) and the turns of A1, A4, A6 (each of these axes in
  its turn ``k``: ``-180 + 360 k <= q < 180 + 360 k``)::

      >>> from compiler.configs import Config
      >>> pose = kin.forward((0, 0, 0, 0, 30, 10))
      >>> [round(v, 9) + 0.0 for v in kin.inverse_config(pose, Config(wrist=1))]
      [0.0, 0.0, 0.0, 180.0, -30.0, -170.0]
      >>> [round(v, 9) + 0.0 for v in kin.inverse_config(pose, Config(turns=(0, 0, -1)))]
      [0.0, 0.0, 0.0, 0.0, 30.0, -350.0]

Singularities and tolerances (where the closed form has no unique answer)
---------------------------------------------------------------------------
* shoulder: the wrist centre within :data:`SHOULDER_TOL` (1e-6 mm) of axis 1 (of the
  cylinder of radius ``|d2 + d3|`` around it when there is a lateral shoulder offset):
  axis 1 is free. Every configuration is singular there.
* elbow: the wrist centre within :data:`ELBOW_TOL` (1e-6 mm) of the boundary of the
  arm's reach (arm stretched, or folded): the two elbow solutions coincide.
* wrist: ``|sin(theta5)| <`` :data:`WRIST_TOL` (1e-6): axes 4 and 6 aligned, only
  ``theta4 +- theta6`` is determined.

A singular configuration is still a candidate of :meth:`Kinematics.inverse` (with axis 1
or axis 4 taken from ``near``): if it is the nearest, ``inverse`` raises
:class:`KinematicsError` "singular: ..." rather than jump to a far configuration;
:meth:`Kinematics.solutions` leaves singular configurations out.

Errors: :class:`KinematicsError` (a ``ValueError``), whose text starts with
``unreachable:``, ``singular:`` or ``no solution within the axis limits``.

Geometry accepted (else ``ValueError`` naming the axis): six revolute main axes with DH
parameters; ``|alpha1| = 90``, ``alpha2 = 0`` (axes 2 and 3 parallel), ``|alpha3| = 90``,
``a2 != 0``; a spherical wrist: ``a4 = a5 = d5 = 0``, ``|alpha4| = |alpha5| = 90`` (axes
4, 5, 6 intersect at the wrist centre). ``d2 + d3`` (a lateral shoulder offset), ``a6``,
``alpha6`` and ``d6`` may be anything: the flange offset after the wrist is handled with
the tool. The Lola 15 qualifies as it is (its axis 2 ``theta_offset = -90`` is applied
like any other offset).

Accuracy: ``forward(inverse(pose))`` reproduces the pose to about 1e-12 mm and 1e-13 rad
in every configuration. The joint values themselves come back as well as the pose's
conditioning allows: 1e-11 deg typically, up to ~1e-9 deg with the elbow and the wrist
both within ~0.01 of a singularity (|sin| of the angles), more closer still.

Real time: :meth:`Kinematics.inverse` visits the branches nearest ``near`` first and
solves the wrist only for arm configurations not already farther from ``near`` than the
best solution found. With ``near`` at the current joints (the usual case) it takes about
10-18 us in CPython (p50; p99 under 30 us), with ``near`` far from the answer up to about
twice that; with ``configuration=`` about 6-13 us; :meth:`Kinematics.forward` about 5-10
us. Math-module scalar code, plain floats, no NumPy (see benchmarks/kinematics.py).
"""
from __future__ import annotations

from math import atan2, ceil, cos, inf, isfinite, pi, sin, sqrt
from typing import Sequence

from compiler.configs import ELBOW_DOWN, SHOULDER_BACK, TURN_AXES, WRIST_FLIP, Config, describe, in_turn, turn_of
from compiler.configs import turn_problem, turn_range
from compiler.geometry import normalise, rotation_to_rpy, rpy_to_matrix
from compiler.spec import DH, Spec
from compiler.values import Joint, Pose, Position, Quat, Rpy

__all__ = [
    "ELBOW_DOWN",
    "ELBOW_TOL",
    "Kinematics",
    "KinematicsError",
    "LIMIT_TOL",
    "SHOULDER_BACK",
    "SHOULDER_TOL",
    "WRIST_FLIP",
    "WRIST_TOL",
    "configuration_name",
    "cos_sin_deg",
    "matrix_to_rpy",
    "mul34",
    "rpy_to_matrix",
]


#: mm: the wrist centre this close to axis 1 (beyond a lateral shoulder offset) is singular
SHOULDER_TOL = 1e-6
#: mm: the wrist centre this close to the boundary of the arm's reach is singular
ELBOW_TOL = 1e-6
#: |sin(theta5)| below this is a wrist singularity
WRIST_TOL = 1e-6
#: deg: a joint value this far beyond a limit counts as on it (and is clamped to it)
LIMIT_TOL = 1e-9
#: deg: tolerance of the geometry checks on alpha (0 or +-90)
_ALPHA_TOL = 1e-9

#: deg: a named turn k seeds its axis at 360 k less this, so that the representation chosen
#: is in (-180 + 360 k - bias, 180 + 360 k - bias]: a value on the turn's lower boundary
#: (-180 + 360 k, in turn k) comes out there, not at the upper one (in turn k + 1)
_TURN_BIAS = 1e-9
_D2R = pi / 180.0
_R2D = 180.0 / pi
_OK, _SINGULAR, _LIMIT, _UNREACHABLE = 0, 1, 2, 3


class KinematicsError(ValueError):
    """No joint values for a pose: unreachable, singular or outside the axis limits."""


def configuration_name(configuration: int) -> str:
    """``"front, elbow up, wrist not flipped"`` ... for a configuration id 0..7
    (compiler.configs, where the groups and their words are declared)."""
    return describe(configuration)


def matrix_to_rpy(matrix) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in degrees of a 3x3 (or the rotation of a 4x4) matrix."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = (tuple(row[:3]) for row in matrix[:3])
    return rotation_to_rpy(r00, r01, r02, r10, r11, r12, r20, r21, r22)


def _quat_matrix(w, x, y, z) -> tuple:
    unit = normalise((w, x, y, z))
    if unit is None:
        raise KinematicsError(f"quat({w:g}, {x:g}, {y:g}, {z:g}) is not a rotation")
    w, x, y, z = unit
    s = 2.0
    return (1.0 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y),
            s * (x * y + w * z), 1.0 - s * (x * x + z * z), s * (y * z - w * x),
            s * (x * z - w * y), s * (y * z + w * x), 1.0 - s * (x * x + y * y))


# (_TURN) A joint value ``q`` turned by whole turns to its representation nearest ``n``:
# ``q += 360.0 * ((n - q + 180.0) // 360.0)``, written out where the inverse needs it (a
# call per axis would cost the inverse a twentieth of its time); outside the axis's
# limits, :func:`_fit` then looks for another turn within them.


def _fit(q: float, lo: float, hi: float, n: float, fails: list | None = None, axis: int = 0, cid: int = 0):
    """The representation ``q + k 360`` nearest ``n`` within ``lo..hi`` (``LIMIT_TOL``
    outside counts as on the limit and is clamped), or None when there is none: then, with
    ``fails``, the failure of configuration ``cid`` at axis ``axis`` (index) with the
    value ``q`` goes there."""
    r = q + 360.0 * round((n - q) / 360.0)
    if r > hi:
        if r <= hi + LIMIT_TOL:
            return hi
        r -= 360.0 * ceil((r - hi - LIMIT_TOL) / 360.0)  # the largest one <= hi + LIMIT_TOL
        if r >= lo:
            return hi if r > hi else r
        if r >= lo - LIMIT_TOL:
            return lo
    elif r < lo:
        if r >= lo - LIMIT_TOL:
            return lo
        r += 360.0 * ceil((lo - LIMIT_TOL - r) / 360.0)  # the smallest one >= lo - LIMIT_TOL
        if r <= hi:
            return lo if r < lo else r
        if r <= hi + LIMIT_TOL:
            return hi
    else:
        return r
    if fails is not None:
        fails.append((_LIMIT, (axis, q), cid))
    return None


def _sign90(alpha: float) -> float:
    """+1.0 / -1.0 for alpha = +-90 deg (mod 360), 0.0 otherwise."""
    a = (alpha + 180.0) % 360.0 - 180.0
    if abs(a - 90.0) <= _ALPHA_TOL:
        return 1.0
    if abs(a + 90.0) <= _ALPHA_TOL:
        return -1.0
    return 0.0


def cos_sin_deg(alpha_deg: float) -> tuple[float, float]:
    """cos and sin of an angle in degrees, exact for multiples of 90 (a DH row's alpha;
    the URDF's constant rotations, :mod:`runtime.motion.urdf`)."""
    a = alpha_deg % 360.0
    for m, cs in ((0.0, (1.0, 0.0)), (90.0, (0.0, 1.0)), (180.0, (-1.0, 0.0)), (270.0, (0.0, -1.0)),
                  (360.0, (1.0, 0.0))):
        if abs(a - m) <= _ALPHA_TOL:
            return cs
    return cos(alpha_deg * _D2R), sin(alpha_deg * _D2R)


class Kinematics:
    """Forward and inverse kinematics of one arm (see the module's documentation).

    ``Kinematics(spec)`` takes a :class:`compiler.spec.Spec` (its six main axes: DH
    parameters, limits, names, homes; its tool). ``Kinematics(rows, tool=..., limits=...,
    names=..., home=...)`` takes six DH rows instead: :class:`compiler.spec.DH` objects or
    ``(a, alpha, d[, theta_offset])`` tuples; ``limits`` is six ``(min, max)`` pairs
    (default: none), ``tool`` is ``(x, y, z, roll, pitch, yaw)`` (default: the flange).
    Raises ``ValueError`` naming the axis when the geometry is not a six-axis arm with a
    spherical wrist and parallel axes 2 and 3.
    """

    def __init__(self, source, tool: Sequence[float] | None = None,
                 limits: Sequence[tuple[float, float]] | None = None,
                 names: Sequence[str] | None = None, home: Sequence[float] | None = None,
                 directions: Sequence[int] | None = None, couplings: Sequence | None = None,
                 mounting: Sequence[float] | None = None):
        if isinstance(source, Spec):
            axes = source.main_axes
            if len(axes) != 6:
                raise ValueError(f"the kinematics needs six main axes, the specification has {len(axes)}")
            for axis in axes:
                if axis.kind != "revolute":
                    raise ValueError(f"axis {axis.name}: the arm's axes must be revolute, not {axis.kind}")
                if axis.dh is None:
                    raise ValueError(f"axis {axis.name}: no dh parameters (a, alpha, d)")
            rows = [(ax.dh.a, ax.dh.alpha, ax.dh.d, ax.dh.theta_offset) for ax in axes]
            tool = tuple(source.tool) if tool is None else tool
            limits = [(ax.min, ax.max) for ax in axes] if limits is None else limits
            names = [ax.name for ax in axes] if names is None else names
            home = [ax.home for ax in axes] if home is None else home
            directions = [ax.direction for ax in axes] if directions is None else directions
            couplings = [ax.coupling for ax in axes] if couplings is None else couplings
            mounting = source.mounting if mounting is None else mounting
        else:
            rows = []
            for row in source:
                if isinstance(row, DH):
                    rows.append((row.a, row.alpha, row.d, row.theta_offset))
                else:
                    row = tuple(float(v) for v in row)
                    rows.append(row + (0.0,) if len(row) == 3 else row)
            if len(rows) != 6:
                raise ValueError(f"the kinematics needs six DH rows, got {len(rows)}")
        names = tuple(names) if names is not None else tuple(f"A{i + 1}" for i in range(6))
        tool = tuple(float(v) for v in tool) if tool is not None else (0.0,) * 6
        limits = tuple((float(lo), float(hi)) for lo, hi in limits) if limits is not None else ((-inf, inf),) * 6
        home = tuple(float(v) for v in home) if home is not None else (0.0,) * 6
        if len(names) != 6 or len(tool) != 6 or len(limits) != 6 or len(home) != 6:
            raise ValueError("names, limits and home need six entries, tool six numbers")
        for name, row, (lo, hi) in zip(names, rows, limits):
            if len(row) != 4 or not all(isfinite(v) for v in row):
                raise ValueError(f"axis {name}: DH parameters must be finite numbers (a, alpha, d, theta_offset)")
            if not lo < hi:
                raise ValueError(f"axis {name}: the limits {lo:g}..{hi:g} are empty")
        self.names, self.tool, self.limits, self.home = names, tool, limits, home
        self.dh = tuple(tuple(float(v) for v in row) for row in rows)
        self._check_geometry()
        self._joint_map(directions, couplings)
        self.mounting = tuple(float(v) for v in mounting) if mounting is not None else (0.0,) * 6
        if len(self.mounting) != 6 or not all(isfinite(v) for v in self.mounting):
            raise ValueError("mounting needs six finite numbers (x, y, z, roll, pitch, yaw)")
        if self.mounting == (0.0,) * 6:
            self._mount = self._mount_t = None
        else:
            mr = rpy_to_matrix(*self.mounting[3:])
            self._mount = tuple(mr[i] + (self.mounting[i],) for i in range(3))
            self._mount_t = tuple(tuple(mr[j][i] for j in range(3)) for i in range(3))

        (a1, al1, d1, o1), (a2, al2, d2, o2), (a3, al3, d3, o3), \
            (a4, al4, d4, o4), (a5, al5, d5, o5), (a6, al6, d6, o6) = self.dh
        # forward: per link (theta_offset rad, cos alpha, sin alpha, a, d)
        self._links = tuple((off * _D2R, *cos_sin_deg(al), a, d) for a, al, d, off in self.dh)
        # the constant transform after Rz(theta6): Tz(d6) Tx(a6) Rx(alpha6) * tool
        ca6, sa6 = cos_sin_deg(al6)
        flange = ((1.0, 0.0, 0.0, a6), (0.0, ca6, -sa6, 0.0), (0.0, sa6, ca6, d6))
        x, y, z, roll, pitch, yaw = tool
        rt = rpy_to_matrix(roll, pitch, yaw)
        tool_m = tuple(rt[i] + ((x, y, z)[i],) for i in range(3))
        c = mul34(flange, tool_m)
        self._tool_m = tool_m
        self._tool_identity = tool == (0.0,) * 6
        self._tool_rot_identity = tool[3:] == (0.0,) * 3
        # the same with the kind of alpha: 0 for 0 deg, 1 for +90, 2 for -90, 3 otherwise
        self._fk_links = tuple(
            link + ({(1.0, 0.0): 0, (0.0, 1.0): 1, (0.0, -1.0): 2}.get((link[1], link[2]), 3),)
            for link in self._links)
        rc = tuple(tuple(c[i][j] for j in range(3)) for i in range(3))
        pc = (c[0][3], c[1][3], c[2][3])
        # W = R * Rc^T; wrist centre = p - R * (Rc^T pc)
        self._rct = tuple(rc[j][i] for i in range(3) for j in range(3))  # Rc^T, row-major
        self._c_rot_identity = rc == ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
        self._wc_off = tuple(sum(rc[k][i] * pc[k] for k in range(3)) for i in range(3))
        s1, s3, s4, s5 = _sign90(al1), _sign90(al3), _sign90(al4), _sign90(al5)
        l3 = sqrt(a3 * a3 + d4 * d4)
        rmax, rmin = abs(a2) + l3, abs(abs(a2) - l3)  # the arm's outer and inner reach from axis 2
        self._doff = d2 + d3
        sa2 = 1.0 if a2 > 0 else -1.0
        # sign of v = L3 sin(theta3 - phi) for (shoulder bit, elbow bit)
        vsign = tuple(tuple(-(1.0 if sb == 0 else -1.0) * s1 * sa2 * (1.0 if eb == 0 else -1.0)
                            for eb in (0, 1)) for sb in (0, 1))
        self._vsign = vsign
        self._l3 = l3
        self._phi = atan2(s3 * d4, a3)
        offs = (o1, o2, o3, o4, o5, o6)
        self._offs = offs
        # what each stage of the inverse needs, in one flat tuple: one unpack per call
        (lo1, hi1), (lo2, hi2), (lo3, hi3), (lo4, hi4), (lo5, hi5), (lo6, hi6) = limits
        dq1, dq2, dq3, dq4, dq5, dq6 = map(float, self.directions)
        self._ik_shoulder = (a1, d1, s1, self._doff * self._doff, s1 * self._doff, rmax, rmin, o1, lo1, hi1, dq1)
        self._ik_elbow = (a2, l3, self._phi, rmax, rmin, 1.0 / (2.0 * abs(a2) * l3), vsign, o2, o3, lo2, hi2,
                          lo3, hi3, dq2, dq3, *self._k)
        self._ik_wrist = (s1, s1 * s3, s3, s4, s5, -s4 * s5, o4, o5, o6, lo4, hi4, lo5, hi5, lo6, hi6, dq4, dq5, dq6)

    def _joint_map(self, directions, couplings) -> None:
        """The joint values' map to the DH angles: ``theta_i = direction_i q_i +
        theta_offset_i (+ factor q_j for a coupled axis i = 2, 3 and an earlier j)``."""
        dirs = tuple(directions) if directions is not None else (1,) * 6
        if len(dirs) != 6 or any(d not in (1, -1) for d in dirs):
            raise ValueError(f"directions must be six values 1 or -1, got {dirs}")
        k = {}
        for i, coupling in enumerate(couplings if couplings is not None else (None,) * 6):
            if coupling is None:
                continue
            j, factor = coupling
            if i not in (1, 2) or not 0 <= j < i or not isfinite(factor):
                raise ValueError(f"axis {self.names[i]}: only axes 2 and 3 may be coupled, to an earlier axis")
            k[i, j] = float(factor)
        self.directions = tuple(int(d) for d in dirs)
        self.couplings = tuple(couplings) if couplings is not None else (None,) * 6
        self._k = (k.get((1, 0), 0.0), k.get((2, 0), 0.0), k.get((2, 1), 0.0))  # k21, k31, k32
        self._plain = self.directions == (1,) * 6 and not k

    def with_tool(self, tool: Sequence[float]) -> "Kinematics":
        """The same arm with another tool (x, y, z, roll, pitch, yaw in the flange frame):
        what ``use tool`` plans with. Not for a tick (builds the tables, about 50 us)."""
        return Kinematics(self.dh, tool=tool, limits=self.limits, names=self.names, home=self.home,
                          directions=self.directions, couplings=self.couplings, mounting=self.mounting)

    def _angles(self, joints) -> tuple:
        """The DH angles less their offsets (deg) of joint values: the joint values
        themselves unless an axis turns the other way or is coupled."""
        q = _main(joints)
        if self._plain:
            return q
        d1, d2, d3, d4, d5, d6 = self.directions
        k21, k31, k32 = self._k
        q1, q2, q3, q4, q5, q6 = q
        return (d1 * q1, d2 * q2 + k21 * q1, d3 * q3 + k31 * q1 + k32 * q2, d4 * q4, d5 * q5, d6 * q6)

    def _mounted(self, m: tuple) -> tuple:
        """A flat 3x4 in the robot's base frame, in the world frame (the mounting's)."""
        if self._mount is None:
            return m
        (a00, a01, a02, ax), (a10, a11, a12, ay), (a20, a21, a22, az) = self._mount
        r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz = m
        return (a00 * r00 + a01 * r10 + a02 * r20, a00 * r01 + a01 * r11 + a02 * r21,
                a00 * r02 + a01 * r12 + a02 * r22, a00 * px + a01 * py + a02 * pz + ax,
                a10 * r00 + a11 * r10 + a12 * r20, a10 * r01 + a11 * r11 + a12 * r21,
                a10 * r02 + a11 * r12 + a12 * r22, a10 * px + a11 * py + a12 * pz + ay,
                a20 * r00 + a21 * r10 + a22 * r20, a20 * r01 + a21 * r11 + a22 * r21,
                a20 * r02 + a21 * r12 + a22 * r22, a20 * px + a21 * py + a22 * pz + az)

    def _unmounted(self, target: tuple) -> tuple:
        """A target ``(r00 .. r22, x, y, z)`` in the world frame, in the robot's base frame."""
        if self._mount_t is None:
            return target
        (b00, b01, b02), (b10, b11, b12), (b20, b21, b22) = self._mount_t
        r00, r01, r02, r10, r11, r12, r20, r21, r22, x, y, z = target
        mx, my, mz = self.mounting[:3]
        x, y, z = x - mx, y - my, z - mz
        return (b00 * r00 + b01 * r10 + b02 * r20, b00 * r01 + b01 * r11 + b02 * r21,
                b00 * r02 + b01 * r12 + b02 * r22,
                b10 * r00 + b11 * r10 + b12 * r20, b10 * r01 + b11 * r11 + b12 * r21,
                b10 * r02 + b11 * r12 + b12 * r22,
                b20 * r00 + b21 * r10 + b22 * r20, b20 * r01 + b21 * r11 + b22 * r21,
                b20 * r02 + b21 * r12 + b22 * r22,
                b00 * x + b01 * y + b02 * z, b10 * x + b11 * y + b12 * z, b20 * x + b21 * y + b22 * z)

    # ---- geometry --------------------------------------------------------------------
    def _check_geometry(self) -> None:
        n = self.names
        (a1, al1, d1, _), (a2, al2, d2, _), (a3, al3, d3, _), \
            (a4, al4, d4, _), (a5, al5, d5, _), _ = self.dh

        def need(ok: bool, i: int, what: str, value: float) -> None:
            if not ok:
                raise ValueError(f"axis {n[i]}: {what} for a six-axis arm with a spherical wrist "
                                 f"(closed-form inverse kinematics), got {value:g}")

        need(_sign90(al1) != 0.0, 0, "alpha must be +-90 deg (axis 2 perpendicular to axis 1)", al1)
        need(abs((al2 + 180.0) % 360.0 - 180.0) <= _ALPHA_TOL, 1,
             "alpha must be 0 deg (axes 2 and 3 parallel)", al2)
        need(a2 != 0.0, 1, "a (the upper arm) must not be 0 mm", a2)
        need(_sign90(al3) != 0.0, 2, "alpha must be +-90 deg (axis 4 perpendicular to axis 3)", al3)
        need(a4 == 0.0, 3, "a must be 0 mm (axes 4-6 intersecting)", a4)
        need(_sign90(al4) != 0.0, 3, "alpha must be +-90 deg (axis 5 perpendicular to axis 4)", al4)
        need(a5 == 0.0, 4, "a must be 0 mm (axes 4-6 intersecting)", a5)
        need(d5 == 0.0, 4, "d must be 0 mm (axes 4-6 intersecting)", d5)
        need(_sign90(al5) != 0.0, 4, "alpha must be +-90 deg (axis 6 perpendicular to axis 5)", al5)
        need(a3 != 0.0 or d4 != 0.0, 2, "a and axis 4's d must not both be 0 mm (no forearm)", a3)

    # ---- forward ---------------------------------------------------------------------
    def forward_matrix(self, joints: Sequence[float]) -> tuple:
        """The TCP in the base frame, a 4x4 homogeneous matrix (nested tuples, mm)."""
        r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz = self._chain(joints)
        return ((r00, r01, r02, px), (r10, r11, r12, py), (r20, r21, r22, pz), (0.0, 0.0, 0.0, 1.0))

    def forward(self, joints: Sequence[float]) -> tuple[float, float, float, float, float, float]:
        """The TCP pose ``(x, y, z, roll, pitch, yaw)`` (mm, deg) of joint values (deg)."""
        r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz = self._chain(joints)
        return (px, py, pz) + rotation_to_rpy(r00, r01, r02, r10, r11, r12, r20, r21, r22)

    def forward_pose(self, joints: Sequence[float]) -> Pose:
        """The TCP as an L-IRL ``pose(pos(...), rpy(...))`` value."""
        x, y, z, r, p, w = self.forward(joints)
        return Pose(Position(x, y, z), Rpy(r, p, w))

    def _chain(self, joints) -> tuple:
        """Flat 3x4 of the TCP: the DH product by columns (X, Y, Z, p), then the tool."""
        if self._mount is not None:
            return self._mounted(self._flange_tool(*self.flange_columns(joints)))
        return self._flange_tool(*self.flange_columns(joints))

    def flange_and_tcp(self, joints, tool: Sequence[float]) -> tuple[tuple, tuple]:
        """The flange's origin and the tool centre point (``tool``: its x, y, z in the
        flange) in the world frame, mm. Real-time safe (plain floats)."""
        x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2 = self.flange_columns(joints)
        tx, ty, tz = tool[0], tool[1], tool[2]
        t0 = p0 + x0 * tx + y0 * ty + z0 * tz
        t1 = p1 + x1 * tx + y1 * ty + z1 * tz
        t2 = p2 + x2 * tx + y2 * ty + z2 * tz
        m = self._mount
        if m is None:
            return (p0, p1, p2), (t0, t1, t2)
        (a00, a01, a02, ax), (a10, a11, a12, ay), (a20, a21, a22, az) = m
        return ((a00 * p0 + a01 * p1 + a02 * p2 + ax, a10 * p0 + a11 * p1 + a12 * p2 + ay,
                 a20 * p0 + a21 * p1 + a22 * p2 + az),
                (a00 * t0 + a01 * t1 + a02 * t2 + ax, a10 * t0 + a11 * t1 + a12 * t2 + ay,
                 a20 * t0 + a21 * t1 + a22 * t2 + az))

    def flange_columns(self, joints) -> tuple:
        """The flange in the robot's own base frame (no mount, no tool): its axes' columns
        X, Y, Z and its origin p, flat ``(x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2)``
        (mm). Real-time safe (plain floats): the T1 speed check runs it every 1 ms."""
        if isinstance(joints, Joint):
            joints = joints.main
        if not self._plain:
            joints = self._angles(joints)
        x0 = y1 = z2 = 1.0
        x1 = x2 = y0 = y2 = z0 = z1 = p0 = p1 = p2 = 0.0
        n = 0
        for (off, ca, sa, a, d, kind), q in zip(self._fk_links, joints):
            n += 1
            t = q * _D2R + off
            ct = cos(t)
            st = sin(t)
            if d:
                p0 += d * z0
                p1 += d * z1
                p2 += d * z2
            nx0 = ct * x0 + st * y0
            nx1 = ct * x1 + st * y1
            nx2 = ct * x2 + st * y2
            t0 = ct * y0 - st * x0
            t1 = ct * y1 - st * x1
            t2 = ct * y2 - st * x2
            x0, x1, x2 = nx0, nx1, nx2
            if kind == 1:  # alpha = +90: Y = Z, Z = -T
                y0, y1, y2, z0, z1, z2 = z0, z1, z2, -t0, -t1, -t2
            elif kind == 2:  # alpha = -90: Y = -Z, Z = T
                y0, y1, y2, z0, z1, z2 = -z0, -z1, -z2, t0, t1, t2
            elif kind == 0:  # alpha = 0
                y0, y1, y2 = t0, t1, t2
            else:
                y0 = ca * t0 + sa * z0
                y1 = ca * t1 + sa * z1
                y2 = ca * t2 + sa * z2
                z0 = ca * z0 - sa * t0
                z1 = ca * z1 - sa * t1
                z2 = ca * z2 - sa * t2
            if a:
                p0 += a * x0
                p1 += a * x1
                p2 += a * x2
        if n != 6:
            raise ValueError(f"expected six joint values, got {n}")
        return x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2

    def lever_arms(self, tool: Sequence[float] | None = None) -> tuple[float, ...]:
        """Per main axis, an upper bound (mm) on the distance of the flange and of the tool
        centre point (of ``tool``: x, y, z in the flange, mm; None: this arm's tool) from
        that axis's line, in any configuration: the lengths of the links after it, and
        the tool's. An axis turning at w rad/s moves neither point faster than w times it
        (what keeps homing under the T1 speed before the axes' positions are known)."""
        tx, ty, tz = (self._tool_m[0][3], self._tool_m[1][3], self._tool_m[2][3]) if tool is None else tool[:3]
        reach_tool = sqrt(tx * tx + ty * ty + tz * tz)
        arms = []
        for i in range(6):
            after = sum(abs(a) + abs(d) for (_o, _c, _s, a, d) in self._links[i:])
            arms.append(after + reach_tool)
        return tuple(arms)

    def _flange_tool(self, x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2) -> tuple:
        """The flat 3x4 of the TCP from the flange's columns X, Y, Z and origin p."""
        if self._tool_identity:
            return (x0, y0, z0, p0, x1, y1, z1, p1, x2, y2, z2, p2)
        (t00, t01, t02, tx), (t10, t11, t12, ty), (t20, t21, t22, tz) = self._tool_m
        if self._tool_rot_identity:
            return (x0, y0, z0, p0 + x0 * tx + y0 * ty + z0 * tz,
                    x1, y1, z1, p1 + x1 * tx + y1 * ty + z1 * tz,
                    x2, y2, z2, p2 + x2 * tx + y2 * ty + z2 * tz)
        return (x0 * t00 + y0 * t10 + z0 * t20, x0 * t01 + y0 * t11 + z0 * t21,
                x0 * t02 + y0 * t12 + z0 * t22, p0 + x0 * tx + y0 * ty + z0 * tz,
                x1 * t00 + y1 * t10 + z1 * t20, x1 * t01 + y1 * t11 + z1 * t21,
                x1 * t02 + y1 * t12 + z1 * t22, p1 + x1 * tx + y1 * ty + z1 * tz,
                x2 * t00 + y2 * t10 + z2 * t20, x2 * t01 + y2 * t11 + z2 * t21,
                x2 * t02 + y2 * t12 + z2 * t22, p2 + x2 * tx + y2 * ty + z2 * tz)

    def _base_frame(self) -> tuple:
        """The robot's base (the first DH frame) in the world frame, 3x4."""
        return self._mount or ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0))

    def frames(self, joints: Sequence[float]) -> list[tuple]:
        """The 4x4 matrices T_01 .. T_06 (flange) and the TCP, in the world frame (the
        base frame when the robot stands at the origin)."""
        out = []
        m = self._base_frame()
        for (off, ca, sa, a, d), q in zip(self._links, self._angles(joints)):
            t = q * _D2R + off
            ct, st = cos(t), sin(t)
            m = mul34(m, ((ct, -st * ca, st * sa, a * ct), (st, ct * ca, -ct * sa, a * st), (0.0, sa, ca, d)))
            out.append(m + ((0.0, 0.0, 0.0, 1.0),))
        out.append(mul34(m, self._tool_m) + ((0.0, 0.0, 0.0, 1.0),))
        return out

    def jacobian(self, joints: Sequence[float]) -> tuple:
        """The geometric Jacobian of the TCP in the world frame, 6x6 nested tuples: rows
        vx, vy, vz (mm per rad of joint motion), wx, wy, wz (rad per rad); column i is
        ``(z_{i-1} x (p_tcp - o_{i-1}), z_{i-1})`` times the axis's direction (plus a
        coupled axis's share). Multiply joint rates by pi/180 first when they are in deg/s."""
        fr = self.frames(joints)
        pe = (fr[6][0][3], fr[6][1][3], fr[6][2][3])
        cols = []
        prev = self._base_frame()
        for i in range(6):
            zx, zy, zz = prev[0][2], prev[1][2], prev[2][2]
            dx, dy, dz = pe[0] - prev[0][3], pe[1] - prev[1][3], pe[2] - prev[2][3]
            cols.append((zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx, zx, zy, zz))
            prev = fr[i]
        if not self._plain:  # d theta / d q: the directions, and the coupled axes' shares
            k21, k31, k32 = self._k
            mixed = [tuple(d * v for v in col) for d, col in zip(self.directions, cols)]
            mixed[0] = tuple(v + k21 * b + k31 * c for v, b, c in zip(mixed[0], cols[1], cols[2]))
            mixed[1] = tuple(v + k32 * c for v, c in zip(mixed[1], cols[2]))
            cols = mixed
        return tuple(tuple(col[r] for col in cols) for r in range(6))

    def singularity_margins(self, joints: Sequence[float]) -> tuple[float, float, float]:
        """How far joint values are from each singularity: ``(shoulder, elbow, wrist)`` =
        (the wrist centre's distance from axis 1 beyond a lateral shoulder offset, mm;
        ``|sin(theta3 - phi)|``, 0 with the arm stretched or folded; ``|sin(theta5)|``).
        The Jacobian's determinant is +- shoulder * a2 * L3 * elbow * wrist (mm^3), with
        L3 = sqrt(a3^2 + d4^2) the forearm from axis 3 to the wrist centre."""
        q = self._angles(joints)
        offs = self._offs
        t3 = q[2] * _D2R + offs[2] * _D2R
        t5 = q[4] * _D2R + offs[4] * _D2R
        x, _ = self._arm_plane(q)
        return abs(x), abs(sin(t3 - self._phi)), abs(sin(t5))

    def _arm_plane(self, q) -> tuple[float, float]:
        """(signed distance of the wrist centre from axis 1 along x1, v = L3 sin(theta3 - phi))."""
        a1, a2 = self.dh[0][0], self.dh[1][0]
        offs = self._offs
        t2 = (q[1] + offs[1]) * _D2R
        t3 = (q[2] + offs[2]) * _D2R
        u = self._l3 * cos(t3 - self._phi)
        v = self._l3 * sin(t3 - self._phi)
        return a1 + a2 * cos(t2) + cos(t2) * u - sin(t2) * v, v

    def configuration(self, joints: Sequence[float]) -> int:
        """The configuration id (SHOULDER_BACK | ELBOW_DOWN | WRIST_FLIP bits) of joint values."""
        q = self._angles(joints)
        x, v = self._arm_plane(q)
        sb = 1 if x < 0.0 else 0
        cid = sb
        if v * self._vsign[sb][0] < 0.0:
            cid |= ELBOW_DOWN
        if sin((q[4] + self._offs[4]) * _D2R) < 0.0:
            cid |= WRIST_FLIP
        return cid

    def configuration_and_margins(self, joints: Sequence[float]) -> tuple[int, tuple[float, float, float]]:
        """:meth:`configuration` and :meth:`singularity_margins` of joint values at once."""
        q = self._angles(joints)
        offs = self._offs
        x, v = self._arm_plane(q)
        sb = 1 if x < 0.0 else 0
        cid = sb
        if v * self._vsign[sb][0] < 0.0:
            cid |= ELBOW_DOWN
        s5 = sin((q[4] + offs[4]) * _D2R)
        if s5 < 0.0:
            cid |= WRIST_FLIP
        return cid, (abs(x), abs(sin((q[2] + offs[2]) * _D2R - self._phi)), abs(s5))

    # ---- inverse ---------------------------------------------------------------------
    def inverse(self, pose, near: Sequence[float] | None = None, configuration: int | None = None) -> tuple:
        """Joint values (deg) that put the TCP at ``pose``: the solution nearest ``near``
        (default: the home position), or of ``configuration`` only. Raises
        :class:`KinematicsError` (unreachable, singular, outside the axis limits)."""
        if configuration is not None and (type(configuration) is not int or not 0 <= configuration <= 7):
            raise ValueError(f"configuration must be an integer 0..7, got {configuration!r}")
        near = self.home if near is None else _main(near)
        target = _target(pose)
        if self._mount_t is not None:
            target = self._unmounted(target)
        sols, fails = self._candidates(target, near, configuration, True)
        if sols:
            best = sols[0]
            for c in sols:
                if c[4] < best[4]:
                    best = c
            if best[2] == _OK:
                return best[1]
            raise KinematicsError(best[3])
        raise KinematicsError(self._failure(fails))

    def inverse_config(self, pose, config: Config, near: Sequence[float] | None = None) -> tuple:
        """Joint values (deg) that put the TCP at ``pose`` in the configuration ``config``
        names (:class:`compiler.configs.Config`): of the solutions whose configuration has
        every group ``config`` names, the one nearest ``near`` (default: the home position)
        as :meth:`inverse` chooses; A1, A4 and A6 each in the turn ``config`` names (when it
        names turns), every other angle in its representation nearest ``near``. Raises
        :class:`KinematicsError` saying why there is none: a turn outside its axis's limits,
        the pose unreachable or singular in those configurations, an axis outside its
        limits. (Without a configuration, :meth:`inverse` is the fast path.)"""
        near = self.home if near is None else _main(near)
        problem = turn_problem(config, self.limits, self.names)
        if problem is not None:
            raise KinematicsError(problem)
        seed = list(near)  # a named turn: its axis's representation nearest the turn's middle
        for axis, k in zip(TURN_AXES, config.turns or ()):
            seed[axis] = 360.0 * k - _TURN_BIAS
        target = self._unmounted(_target(pose))
        sols: list = []
        fails: list = []
        for cid in range(8):
            if config.matches(cid):
                found, failed = self._candidates(target, tuple(seed), cid)
                sols += found
                fails += failed
        best = turned = None
        for _cid, q, status, message, _d in sols:
            wrong = [(axis, k) for axis, k in zip(TURN_AXES, config.turns or ()) if not in_turn(q[axis], k)]
            if wrong and status == _OK:  # the limits kept the axis out of its turn
                axis, k = wrong[0]
                turned = turned or (axis, k, q[axis] + 360.0 * (k - turn_of(q[axis])))
                continue
            d = sum((a - b) * (a - b) for a, b in zip(q, near))
            if best is None or d < best[0]:
                best = (d, status, q, message)
        if best is not None:
            if best[1] == _OK:
                return best[2]
            raise KinematicsError(best[3])
        if turned is not None:
            axis, k, value = turned
            lo, hi = self.limits[axis]
            start, end = turn_range(k)
            raise KinematicsError(f"{self.names[axis]} would be {value:.1f} deg in turn {k} ({start:g}..{end:g} "
                                  f"deg), outside its limits {lo:g}..{hi:g}")
        raise KinematicsError(self._failure(fails))

    def solutions(self, pose, near: Sequence[float] | None = None) -> list[tuple[int, tuple]]:
        """Every non-singular solution within the axis limits, as ``(configuration id,
        joints)`` sorted by id; each angle in its representation nearest ``near``
        (default: the home position). Empty when there is none (:meth:`inverse` says why)."""
        near = self.home if near is None else _main(near)
        out = [(c[0], c[1]) for c in self._candidates(self._unmounted(_target(pose)), near, None)[0] if c[2] == _OK]
        out.sort()
        return out

    def _failure(self, fails) -> str:
        """The message when no configuration is valid nor singular: a limit violation (the
        smallest one) if some configuration reaches the pose, else why none reaches it."""
        limits = []
        for status, info, cid in fails:
            if status == _LIMIT:
                i, value = info
                lo, hi = self.limits[i]
                if isfinite(lo) and isfinite(hi):
                    value += 360.0 * round(((lo + hi) / 2.0 - value) / 360.0)
                limits.append((max(lo - value, value - hi), i, value, cid))
        if limits:
            _, i, value, cid = min(limits)
            lo, hi = self.limits[i]
            return (f"no solution within the axis limits ({self.names[i]} would be {value:.1f} deg, "
                    f"limit {lo:g}..{hi:g}; nearest: configuration {cid}, {configuration_name(cid)})")
        kind, amount = min((info for _, info, _ in fails), key=lambda info: info[1])
        if kind == "far":
            return f"unreachable: the wrist centre is {amount:.1f} mm beyond the arm's reach"
        if kind == "near":
            return (f"unreachable: the wrist centre is {amount:.1f} mm inside the arm's inner reach "
                    f"(too close to axis 2)")
        return (f"unreachable: the wrist centre is {amount:.1f} mm closer to axis 1 than the lateral "
                f"shoulder offset ({abs(self._doff):g} mm) allows")

    def _candidates(self, target, near, want, prune: bool = False) -> tuple[list, list]:
        """The configurations (all, or only ``want``) of a target ``(r00 .. r22, x, y, z)``.

        Returns ``(sols, fails)``: ``sols`` holds ``(id, joints, status, message, squared
        distance to near)`` with status _OK or _SINGULAR (joints then a representative, axis
        1 or 4 taken from near); ``fails`` holds ``(status, info, id)`` of configurations
        that do not exist: _UNREACHABLE (info ("far" | "near" | "axis1", mm)) or _LIMIT
        (info (axis index, value in deg)).

        The closed form branches three times, once per stage: axis 1 of each shoulder
        branch (:meth:`_shoulders`), axes 2 and 3 of each elbow branch (:meth:`_elbows`),
        axes 4-6 of each wrist branch (:meth:`_wrists`); here, what they start from: the
        wrist centre and the rotation the wrist has to make.

        With ``prune`` (for :meth:`inverse`), branches are visited nearest ``near`` first
        (shoulder by axis 1, then elbow by axes 1-3) and a branch whose partial distance is
        already no better than the best solution so far is skipped: the nearest solution
        (valid or singular) is still among ``sols``, the others may be missing.
        """
        r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz = target
        cx, cy, cz = self._wc_off  # the wrist centre: the TCP less the constant offset after the wrist
        wx = px - (r00 * cx + r01 * cy + r02 * cz)
        wy = py - (r10 * cx + r11 * cy + r12 * cz)
        wz = pz - (r20 * cx + r21 * cy + r22 * cz)
        if not self._c_rot_identity:  # the rotation the wrist's axes make up with the arm's: W = R Rc^T
            c00, c01, c02, c10, c11, c12, c20, c21, c22 = self._rct
            target = (r00 * c00 + r01 * c10 + r02 * c20, r00 * c01 + r01 * c11 + r02 * c21,
                      r00 * c02 + r01 * c12 + r02 * c22,
                      r10 * c00 + r11 * c10 + r12 * c20, r10 * c01 + r11 * c11 + r12 * c21,
                      r10 * c02 + r11 * c12 + r12 * c22,
                      r20 * c00 + r21 * c10 + r22 * c20, r20 * c01 + r21 * c11 + r22 * c21,
                      r20 * c02 + r21 * c12 + r22 * c22, px, py, pz)
        sols: list = []
        fails: list = []
        shoulders = self._shoulders(wx, wy, wz, near, want, sols, fails)
        if prune and len(shoulders) == 2 and shoulders[1][0] < shoulders[0][0]:
            shoulders.reverse()
        best = inf  # the squared distance of the best solution so far, with prune; else inf
        for e1, sb, q1, cc, ss, rho2, x, zr, r, singular in shoulders:
            if e1 >= best:
                break
            elbows = self._elbows(e1, sb, q1, x, zr, r, near, want, fails)
            if not elbows:
                continue
            if prune and len(elbows) == 2 and elbows[1][0] < elbows[0][0]:
                elbows.reverse()
            best = self._wrists(target, q1, cc / rho2, ss / rho2, singular, elbows, near, want, prune, best, sols,
                                fails)
        return sols, fails

    def _shoulders(self, wx: float, wy: float, wz: float, near, want, sols: list, fails: list) -> list:
        """Axis 1 of each shoulder branch (front: the wrist centre ``(wx, wy, wz)`` at +rs
        along x1, back: at -rs) within its limits, as ``(squared distance of axis 1 to near,
        shoulder bit, q1, cos and sin theta1 times rho^2, rho^2, the wrist centre in the
        arm's plane from axis 2 (x, z, distance r), elbow_singular)``; the branches out of
        reach or out of the limits go to ``fails``. The wrist centre on axis 1 (a shoulder
        singularity) goes to ``sols`` as one singular representative."""
        a1, d1, s1, doff2, dlat, rmax, rmin, o1, lo1, hi1, dq1 = self._ik_shoulder
        n1 = near[0]
        shoulders: list = []
        first = 0 if want is None else want
        rho2 = wx * wx + wy * wy
        rs2 = rho2 - doff2
        if rs2 < 0.0:
            if sqrt(doff2) - sqrt(rho2) >= SHOULDER_TOL:
                fails.append((_UNREACHABLE, ("axis1", sqrt(doff2) - sqrt(rho2)), first))
                return shoulders
            rs2 = 0.0
        rs = sqrt(rs2)
        if rs < SHOULDER_TOL:
            msg = ("singular: shoulder singularity (wrist centre on axis 1)" if doff2 == 0.0 else
                   "singular: shoulder singularity (wrist centre on the cylinder of the lateral "
                   "shoulder offset around axis 1)")
            sols.append((first, tuple(near), _SINGULAR, msg, 0.0))
            return shoulders
        zr = s1 * (wz - d1)
        for sb in (0, 1) if want is None else (want & 1,):
            rb = rs if sb == 0 else -rs
            x = rb - a1
            r = sqrt(x * x + zr * zr)
            elbow_singular = None
            if r > rmax - ELBOW_TOL:
                if r >= rmax + ELBOW_TOL:
                    fails.append((_UNREACHABLE, ("far", r - rmax), sb if want is None else want))
                    continue
                elbow_singular = "singular: elbow singularity (arm stretched)"
            elif r < rmin + ELBOW_TOL:
                if r <= rmin - ELBOW_TOL:
                    fails.append((_UNREACHABLE, ("near", rmin - r), sb if want is None else want))
                    continue
                elbow_singular = "singular: elbow singularity (arm folded)"
            cc = rb * wx - dlat * wy
            ss = rb * wy + dlat * wx
            q1 = dq1 * (atan2(ss, cc) * _R2D - o1)  # the joint value of the DH angle
            q1 += 360.0 * ((n1 - q1 + 180.0) // 360.0)  # (_TURN)
            if not lo1 <= q1 <= hi1 and (q1 := _fit(q1, lo1, hi1, n1, fails, 0,
                                                     sb if want is None else want)) is None:
                continue
            e1 = q1 - n1
            shoulders.append((e1 * e1, sb, q1, cc, ss, rho2, x, zr, r, elbow_singular))
        return shoulders

    def _elbows(self, e1: float, sb: int, q1: float, x: float, zr: float, r: float, near, want,
                fails: list) -> list:
        """Axes 2 and 3 of each elbow branch of a shoulder branch (:meth:`_shoulders`: the
        squared distance ``e1`` of axis 1 to near, the shoulder bit ``sb``, axis 1 at
        ``q1``, the wrist centre in the arm's plane) within their limits, as ``(squared
        distance of axes 1-3 to near, configuration id so far, q2, q3, theta2 + theta3)``;
        the others go to ``fails``."""
        a2, l3, phi, rmax, rmin, inv2, vsign, o2, o3, lo2, hi2, lo3, hi3, dq2, dq3, k21, k31, k32 = self._ik_elbow
        n2 = near[1]
        n3 = near[2]
        # the law of cosines, k = cos(theta3 - phi), from the distances to the outer and
        # inner reach (no cancellation next to either)
        far = (rmax - r) * (rmax + r) * inv2
        near_ = (r - rmin) * (r + rmin) * inv2
        if far < 0.0:
            far = 0.0
        if near_ < 0.0:
            near_ = 0.0
        if a2 < 0.0:
            far, near_ = near_, far
        k = (near_ - far) * 0.5  # (1 + k) - (1 - k), halved
        sbeta = sqrt(far * near_)
        beta = atan2(sbeta, k)
        au = a2 + l3 * k
        lsb = l3 * sbeta
        base = atan2(zr, x)
        elbows: list = []
        vsigns = vsign[sb]
        for eb in (0, 1) if want is None else (want >> 1 & 1,):
            cid = sb | eb << 1 if want is None else want
            vs = vsigns[eb]
            t3 = phi + vs * beta
            t2 = base - atan2(vs * lsb, au)
            q2 = dq2 * (t2 * _R2D - o2 - k21 * q1)
            q2 += 360.0 * ((n2 - q2 + 180.0) // 360.0)  # (_TURN)
            if not lo2 <= q2 <= hi2 and (q2 := _fit(q2, lo2, hi2, n2, fails, 1, cid)) is None:
                continue
            q3 = dq3 * (t3 * _R2D - o3 - k31 * q1 - k32 * q2)
            q3 += 360.0 * ((n3 - q3 + 180.0) // 360.0)  # (_TURN)
            if not lo3 <= q3 <= hi3 and (q3 := _fit(q3, lo3, hi3, n3, fails, 2, cid)) is None:
                continue
            e2 = q2 - n2
            e3 = q3 - n3
            elbows.append((e1 + e2 * e2 + e3 * e3, sb | eb << 1, q2, q3, t2 + t3))
        return elbows

    def _wrists(self, w: tuple, q1: float, c1: float, sn1: float, elbow_singular: str | None, elbows: list, near,
                want, prune: bool, best: float, sols: list, fails: list) -> float:
        """Axes 4-6 of each wrist branch of each of ``elbows`` (:meth:`_elbows`) of the
        shoulder branch with axis 1 at ``q1`` (``c1``, ``sn1``: cos and sin of theta1;
        ``elbow_singular``: its message, if the elbow is singular), for the rotation ``w``
        the wrist makes up with the arm (``W = R Rc^T``, row-major, then the position): the
        solutions within the limits go to ``sols`` (a wrist-singular arm configuration: one
        representative, :meth:`_wrist_singular`), the others to ``fails``. Branches no
        nearer ``near`` than ``best`` are skipped; with ``prune``, ``best`` is the squared
        distance of the best solution so far (without, inf). Returns the new best."""
        s1, s13, s3, s4, s5, mtau, o4, o5, o6, lo4, hi4, lo5, hi5, lo6, hi6, dq4, dq5, dq6 = self._ik_wrist
        w00, w01, w02, w10, w11, w12, w20, w21, w22, _x, _y, _z = w
        n4 = near[3]
        n5 = near[4]
        n6 = near[5]
        # W seen from frame 1: h_j = c1 W0j + s1 W1j, g2 = s1 W02 - c1 W12
        h0 = c1 * w00 + sn1 * w10
        h1 = c1 * w01 + sn1 * w11
        h2 = c1 * w02 + sn1 * w12
        m12 = s13 * (sn1 * w02 - c1 * w12)
        # M = R03^T W is what the wrist has to turn (column 2 and row 2 of it)
        for e123, cid0, q2, q3, t23 in elbows:
            if e123 >= best:
                break
            c23 = cos(t23)
            s23 = sin(t23)
            m02 = c23 * h2 + s1 * s23 * w22
            m22 = s3 * s23 * h2 - s13 * c23 * w22
            c5 = mtau * m22
            sn5 = sqrt(m02 * m02 + m12 * m12)
            if sn5 < WRIST_TOL:
                self._wrist_singular(sols, fails, want, cid0, q1, q2, q3, e123, elbow_singular,
                                     c23 * h0 + s1 * s23 * w20, c23 * h1 + s1 * s23 * w21, m22, c5, near)
                if prune and sols and sols[-1][4] < best:
                    best = sols[-1][4]
                continue
            m20 = s3 * s23 * h0 - s13 * c23 * w20
            m21 = s3 * s23 * h1 - s13 * c23 * w21
            # the two wrist solutions: (t4, t5, t6) and (t4 + 180, -t5, t6 + 180) deg
            q4a = dq4 * (atan2(s5 * m12, s5 * m02) * _R2D - o4)
            t5a = atan2(sn5, c5) * _R2D
            q6a = dq6 * (atan2(-s4 * m21, s4 * m20) * _R2D - o6)
            q5a = dq5 * (t5a - o5)
            q5b = dq5 * (-t5a - o5)
            # axis 5's angular distance from near bounds each one's distance from below:
            # the nearer first, the other only if it can still be better
            d5a = (q5a - n5 + 180.0) % 360.0 - 180.0
            d5b = (q5b - n5 + 180.0) % 360.0 - 180.0
            d5a *= d5a
            d5b *= d5b
            for wb in ((0, 4) if d5a <= d5b else (4, 0)) if want is None else (want & 4,):
                if wb:
                    if e123 + d5b >= best:
                        continue
                    q4, q5, q6 = q4a + 180.0, q5b, q6a + 180.0
                else:
                    if e123 + d5a >= best:
                        continue
                    q4, q5, q6 = q4a, q5a, q6a
                cid = cid0 | wb
                q4 += 360.0 * ((n4 - q4 + 180.0) // 360.0)  # (_TURN)
                q5 += 360.0 * ((n5 - q5 + 180.0) // 360.0)
                q6 += 360.0 * ((n6 - q6 + 180.0) // 360.0)
                if ((not lo4 <= q4 <= hi4 and (q4 := _fit(q4, lo4, hi4, n4, fails, 3, cid)) is None)
                        or (not lo5 <= q5 <= hi5 and (q5 := _fit(q5, lo5, hi5, n5, fails, 4, cid)) is None)
                        or (not lo6 <= q6 <= hi6 and (q6 := _fit(q6, lo6, hi6, n6, fails, 5, cid)) is None)):
                    continue
                e4 = q4 - n4
                e5 = q5 - n5
                e6 = q6 - n6
                dist = e123 + e4 * e4 + e5 * e5 + e6 * e6
                sols.append((cid, (q1, q2, q3, q4, q5, q6), _SINGULAR if elbow_singular else _OK, elbow_singular,
                             dist))
                if prune and dist < best:
                    best = dist
        return best

    def _wrist_singular(self, sols, fails, want, cid0, q1, q2, q3, e123, elbow_singular,
                        m00, m01, m22, c5, near) -> None:
        """A wrist-singular arm configuration (axes 4 and 6 aligned): one representative
        for both wrist ids, axis 4 at ``near``, axis 6 from theta4 +- theta6."""
        o4, o5, o6 = self._offs[3:]
        (lo4, hi4), (lo5, hi5), (lo6, hi6) = self.limits[3:]
        n4, n5, n6 = near[3:]
        tau = self._ik_wrist[3] * self._ik_wrist[4]  # s4 s5
        d4, d5, d6 = self.directions[3:]
        t4 = (d4 * n4 + o4) * _D2R
        if m22 > 0.0:  # theta5 = 0 or 180 such that only theta4 + theta6 counts
            t6 = atan2(tau * m01, -tau * m00) - t4
        else:
            t6 = t4 - atan2(tau * m01, tau * m00)
        raw = (n4, d5 * (atan2(0.0, c5) * _R2D - o5), d6 * (t6 * _R2D - o6))
        fitted = [_fit(v, lo, hi, n) for v, lo, hi, n in zip(raw, (lo4, lo5, lo6), (hi4, hi5, hi6), (n4, n5, n6))]
        ids = [c for c in (cid0, cid0 | 4) if want is None or c == want]
        if None in fitted:
            i = fitted.index(None)
            fails.extend((_LIMIT, (3 + i, raw[i]), c) for c in ids)
            return
        q4, q5, q6 = fitted
        msg = f"wrist singularity ({self.names[4]} at {q5:g} deg)"
        msg = f"{elbow_singular}; {msg}" if elbow_singular else f"singular: {msg}"
        dist = e123 + (q4 - n4) ** 2 + (q5 - n5) ** 2 + (q6 - n6) ** 2
        sols.extend((c, (q1, q2, q3, q4, q5, q6), _SINGULAR, msg, dist) for c in ids)


def mul34(a, b) -> tuple:
    """Product of two 3x4 homogeneous matrices, nested tuples (the implicit last row 0 0 0
    1); a 4x4 ``a`` gives the same 3x4."""
    (b00, b01, b02, b03), (b10, b11, b12, b13), (b20, b21, b22, b23) = b[0], b[1], b[2]
    out = []
    for i in range(3):
        a0, a1, a2, a3 = a[i]
        out.append((a0 * b00 + a1 * b10 + a2 * b20 + 0.0, a0 * b01 + a1 * b11 + a2 * b21 + 0.0,
                    a0 * b02 + a1 * b12 + a2 * b22 + 0.0, a0 * b03 + a1 * b13 + a2 * b23 + a3))
    return tuple(out)


def _main(joints) -> tuple:
    if isinstance(joints, Joint):
        joints = joints.main
    joints = tuple(joints)
    if len(joints) != 6:
        raise ValueError(f"expected six joint values, got {len(joints)}")
    return joints


def _target(pose) -> tuple:
    """(r00 .. r22, x, y, z) of a pose: a 6-sequence (x, y, z, roll, pitch, yaw), a
    :class:`Pose` or a 3x4 / 4x4 matrix."""
    if isinstance(pose, Pose):
        p, o = pose.position, pose.orientation
        if isinstance(o, Quat):
            rot = _quat_matrix(o.w, o.x, o.y, o.z)
        else:
            rot = _flat(rpy_to_matrix(o.roll, o.pitch, o.yaw))
        x, y, z = p.x, p.y, p.z
    elif len(pose) == 6:
        x, y, z, roll, pitch, yaw = pose
        if not isfinite(x + y + z + roll + pitch + yaw):
            raise KinematicsError(f"the pose {tuple(pose)} is not finite")
        roll *= _D2R
        pitch *= _D2R
        yaw *= _D2R
        cr = cos(roll)
        sr = sin(roll)
        cp = cos(pitch)
        sp = sin(pitch)
        cy = cos(yaw)
        sy = sin(yaw)
        spcr = sp * cr
        spsr = sp * sr
        return (cy * cp, cy * spsr - sy * cr, cy * spcr + sy * sr,
                sy * cp, sy * spsr + cy * cr, sy * spcr - cy * sr,
                -sp, cp * sr, cp * cr, x, y, z)
    elif len(pose) in (3, 4) and len(pose[0]) == 4:
        rot = tuple(float(pose[i][j]) for i in range(3) for j in range(3))
        x, y, z = (float(pose[i][3]) for i in range(3))
        r = rot
        for i in range(3):
            for j in range(3):
                dot = r[i] * r[j] + r[3 + i] * r[3 + j] + r[6 + i] * r[6 + j]
                if abs(dot - (i == j)) > 1e-6:
                    raise KinematicsError("the pose's matrix is not a rotation (columns not orthonormal)")
        det = (r[0] * (r[4] * r[8] - r[5] * r[7]) - r[1] * (r[3] * r[8] - r[5] * r[6])
               + r[2] * (r[3] * r[7] - r[4] * r[6]))
        if det < 0.0:
            raise KinematicsError("the pose's matrix is a reflection, not a rotation")
    else:
        raise TypeError("a pose is (x, y, z, roll, pitch, yaw), a Pose or a 4x4 matrix")
    if not isfinite(x + y + z + sum(rot)):
        raise KinematicsError("the pose is not finite")
    return rot + (float(x), float(y), float(z))


def _flat(m) -> tuple:
    return m[0] + m[1] + m[2]
