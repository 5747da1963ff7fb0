"""The arm as URDF: the specification's arm as a Unified Robot Description Format file for
3D viewers and ROS tools (:func:`urdf_text`), and its links' transforms at given joint
values (:func:`link_frames`, :func:`world_frames`, :func:`joint_positions`) for a live view
and recordings.

One declaration: :func:`urdf_joints` builds the table of the URDF's joints (each one's
parent and child link, its constant origin, what turns it) from a
:class:`~runtime.motion.kinematics.Kinematics`; the URDF's text, its link geometry and the
transforms are all read from it, so the file and the transforms cannot disagree, and
composing the transforms from ``world`` gives what ``Kinematics.frames`` gives.

The links (names fixed; the joints that turn the arm are named after its axes)::

    world           the cell's world frame, the root
    base_link       the robot's base (DH frame 0), at [kinematics] mounting in the world:
                    fixed joint world-base_link
    link_1..link_6  link i is DH frame i-1 turned by theta_i about its z axis (the axis of
                    joint i): it moves with axis i. Revolute joint <axis i's name> (A1, ..)
                    from link i-1 (base_link for i = 1), origin Tz(d) Tx(a) Rx(alpha) of
                    row i-1 (none for i = 1) then Rz(theta_offset_i), axis (0, 0,
                    direction_i): the joint's position is the joint value, in rad
    link_i_uncoupled  only for a coupled axis i (theta_i += factor x q_j): joint <A_i>
                    turns this link, and a continuous joint <A_i>_from_<A_j> (URDF
                    <mimic joint="A_j" multiplier="factor"/>) turns link_i from it about
                    the same axis
    flange          DH frame 6 (Kinematics.frames' T_06): fixed joint link_6-flange,
                    Tz(d6) Tx(a6) Rx(alpha6)
    tcp             the specification's tool ([kinematics] tool) on the flange: the TCP
                    (Kinematics.frames' last)
    tool_<name>     each [[tool]], on the flange
    frame_<name>    each [[frame]], in the world

Units: the URDF is in m and rad (its convention); the transforms here are in mm, as
everything else in ``irl``. A transform is a 3x4 matrix as nested tuples, ``((r00, r01,
r02, x), (r10, r11, r12, y), (r20, r21, r22, z))``: the child's frame in its parent's
(:func:`link_frames`) or in the world (:func:`world_frames`), the rotation's columns the
frame's axes. URDF's ``rpy`` is this codebase's roll, pitch, yaw: ``Rz(yaw) Ry(pitch)
Rx(roll)``.

The URDF's limits are the axes' ``min``, ``max`` (rad) and ``max_velocity`` (rad/s);
``effort`` is :data:`EFFORT`: URDF requires it, the specification gives no torques. No
inertias and no collision geometry: a kinematic model with simple visual geometry
(cylinders along each link's d and a, a cylinder at each joint along its axis; sized from
the arm's lengths), not a model for a dynamics simulator. The additional axes (a track, a
turntable) are not in it.

Real time: :func:`link_frames` takes about 7 us for the arm, 17 us with four named frames,
:func:`world_frames` about 40 us (plain floats; the table is built once per Kinematics and
named frames, then cached).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from math import cos, pi, sin, sqrt

from compiler.geometry import rotation_to_rpy, rpy_to_matrix
from compiler.spec import Spec
from runtime.motion.kinematics import Kinematics, cos_sin_deg, mul34

__all__ = ["EFFORT", "IDENTITY", "UrdfJoint", "joint_positions", "link_frames", "urdf_joints", "urdf_text",
           "world_frames"]

#: N m: every revolute joint's ``<limit effort>``. URDF requires the attribute and the
#: specification gives no torques: 0 says none is known (viewers, kinematics and motion
#: planners ignore it; a dynamics simulator needs real values, and inertias too).
EFFORT = 0.0

#: The identity as a 3x4.
IDENTITY = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0))

_D2R = pi / 180.0


@dataclass(frozen=True)
class UrdfJoint:
    """One joint of the URDF: ``name``; ``parent`` and ``child`` links; ``origin``, the
    child's frame in the parent's at position 0 (3x4, mm); ``axis``: 0 for a fixed joint,
    else the sign of z in the child's frame it turns about; ``source``, the index of the
    main axis whose joint value turns it (-1: fixed) and ``factor``: its position is
    ``factor x`` that joint value (1 for the axis's own joint; a coupling's factor for a
    ``mimic`` joint, which names the joint it mimics); ``role``: ``mount``, ``axis``,
    ``coupling``, ``flange``, ``tcp``, ``tool`` or ``frame``."""

    name: str
    parent: str
    child: str
    origin: tuple
    axis: int
    source: int
    factor: float
    mimic: str | None
    role: str


def _frame(values) -> tuple:
    """The 3x4 of ``(x, y, z, roll, pitch, yaw)`` (mm, deg)."""
    rot = rpy_to_matrix(*values[3:])
    return tuple(tuple(rot[i]) + (float(values[i]),) for i in range(3))


def _dh_origin(row: tuple | None, theta_offset: float) -> tuple:
    """``Tz(d) Tx(a) Rx(alpha)`` of a DH row ``(a, alpha, d, theta_offset)`` (none: the
    identity), then ``Rz(theta_offset)``: where joint i's child link is at position 0."""
    a, alpha, d = (0.0, 0.0, 0.0) if row is None else row[:3]
    ca, sa = cos_sin_deg(alpha)
    ct, st = cos_sin_deg(theta_offset)
    return ((ct, -st, 0.0, a), (ca * st, ca * ct, -sa, 0.0), (sa * st, sa * ct, ca, d))


def _check_name(name: str, what: str) -> str:
    if not name.isprintable():
        raise ValueError(f"{what} {name!r}: a URDF name must be printable (no control characters)")
    return name


@lru_cache(maxsize=32)
def urdf_joints(kinematics: Kinematics, named_frames: tuple = ()) -> tuple[UrdfJoint, ...]:
    """The URDF's joints of an arm, parents before children (the module's documentation
    lists them), with the specification's ``[[tool]]`` and ``[[frame]]`` tables given as
    :attr:`compiler.spec.Spec.named_frames` (a tuple). Raises ``ValueError`` when two
    joints would have one name (an axis named like another joint) or an axis's name is
    not printable. Cached by the Kinematics object and the named frames."""
    names = [_check_name(name, "axis") for name in kinematics.names]
    rows = [UrdfJoint("world-base_link", "world", "base_link", _frame(kinematics.mounting), 0, -1, 1.0, None,
                      "mount")]
    parent, previous = "base_link", None
    for i, (row, name, direction, coupling) in enumerate(zip(kinematics.dh, names, kinematics.directions,
                                                             kinematics.couplings)):
        link = f"link_{i + 1}"
        own = link if coupling is None else f"{link}_uncoupled"
        rows.append(UrdfJoint(name, parent, own, _dh_origin(previous, row[3]), direction, i, 1.0, None, "axis"))
        if coupling is not None:
            j, factor = coupling
            rows.append(UrdfJoint(f"{name}_from_{names[j]}", own, link, IDENTITY, 1, j, float(factor), names[j],
                                  "coupling"))
        parent, previous = link, row
    rows.append(UrdfJoint("link_6-flange", "link_6", "flange", _dh_origin(previous, 0.0), 0, -1, 1.0, None, "flange"))
    rows.append(UrdfJoint("flange-tcp", "flange", "tcp", _frame(kinematics.tool), 0, -1, 1.0, None, "tcp"))
    for kind, name, values in named_frames:
        parent, child = ("flange", f"tool_{name}") if kind == "tool" else ("world", f"frame_{name}")
        rows.append(UrdfJoint(f"{parent}-{child}", parent, child, _frame(values), 0, -1, 1.0, None, kind))
    taken = [r.name for r in rows]  # (the links' names are the module's and the tables' own: distinct)
    twice = sorted({n for n in taken if taken.count(n) > 1})
    if twice:
        raise ValueError(f"the URDF would have two joints named {twice[0]!r}: rename the axis that takes that name")
    return tuple(rows)


# ---- the transforms ----------------------------------------------------------------------

def _six(joints) -> tuple:
    q = tuple(joints)
    if len(q) != 6:
        raise ValueError(f"expected six joint values (the main axes), got {len(q)}")
    return q


def link_frames(kinematics: Kinematics, joints, named_frames: tuple = ()) -> list[tuple[str, str, tuple]]:
    """``(parent, child, transform)`` of every joint of the URDF (:func:`urdf_joints`,
    parents before children) at the joint values ``joints`` (the six main axes, deg): the
    child link's frame in its parent's, a 3x4 of nested tuples in mm. Composed from
    ``world`` they give ``Kinematics.frames(joints)``: ``flange`` its T_06, ``tcp`` its TCP
    (:func:`world_frames`). Plain floats, for a tick or a recording's writer."""
    q = _six(joints)
    out = []
    for row in urdf_joints(kinematics, named_frames):
        m = row.origin
        if row.axis:
            t = row.axis * row.factor * q[row.source] * _D2R
            c, s = cos(t), sin(t)
            (r00, r01, r02, x), (r10, r11, r12, y), (r20, r21, r22, z) = m
            m = ((r00 * c + r01 * s, r01 * c - r00 * s, r02, x), (r10 * c + r11 * s, r11 * c - r10 * s, r12, y),
                 (r20 * c + r21 * s, r21 * c - r20 * s, r22, z))
        out.append((row.parent, row.child, m))
    return out


def world_frames(kinematics: Kinematics, joints, named_frames: tuple = ()) -> dict[str, tuple]:
    """Every link of the URDF in the world frame (``world`` included: the identity), 3x4
    in mm, at the joint values ``joints``: :func:`link_frames` composed."""
    frames = {"world": IDENTITY}
    for parent, child, m in link_frames(kinematics, joints, named_frames):
        frames[child] = mul34(frames[parent], m)
    return frames


def joint_positions(kinematics: Kinematics, joints) -> dict[str, float]:
    """The position (rad) of every joint of the URDF that moves, by name, at the joint
    values ``joints`` (deg): each axis's joint its joint value, each coupling's (mimic)
    joint the coupled share. A viewer that follows ``<mimic>`` needs only the axes'."""
    q = _six(joints)
    return {row.name: row.factor * q[row.source] * _D2R for row in urdf_joints(kinematics) if row.axis}


# ---- the URDF's text ---------------------------------------------------------------------

#: The URDF's materials: name -> RGBA.
MATERIALS = {"irl_body": (0.95, 0.55, 0.15, 1.0), "irl_joint": (0.22, 0.23, 0.25, 1.0),
             "irl_tool": (0.72, 0.74, 0.78, 1.0)}


def _num(v: float) -> str:
    """A float as URDF text: every digit (the shortest text that reads back the same)."""
    return repr(float(v) + 0.0)


def _xyz_rpy(m: tuple) -> tuple[str, str]:
    """A 3x4 (mm) as URDF's origin: ``xyz`` (m) and ``rpy`` (rad)."""
    (r00, r01, r02, x), (r10, r11, r12, y), (r20, r21, r22, z) = m
    rpy = rotation_to_rpy(r00, r01, r02, r10, r11, r12, r20, r21, r22)
    return " ".join(_num(v / 1000.0) for v in (x, y, z)), " ".join(_num(v * _D2R) for v in rpy)


def _cylinder(start: tuple, end: tuple, radius: float, material: str) -> tuple | None:
    """A cylinder from point ``start`` to ``end`` (mm, in its link's frame) as a visual
    ``(material, origin 3x4, radius, length)``; None when they coincide."""
    d = [e - s for s, e in zip(start, end)]
    length = sqrt(sum(v * v for v in d))
    if length < 1e-9:
        return None
    z = [v / length for v in d]
    helper = (1.0, 0.0, 0.0) if abs(z[2]) > 0.9 else (0.0, 0.0, 1.0)  # x: it, less its part along z
    along = sum(h * v for h, v in zip(helper, z))
    x = [h - along * v for h, v in zip(helper, z)]
    n = sqrt(sum(v * v for v in x))
    x = [v / n for v in x]
    y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]]
    middle = [(s + e) / 2.0 for s, e in zip(start, end)]
    return material, tuple((x[i], y[i], z[i], middle[i]) for i in range(3)), radius, length


def _visuals(table: tuple[UrdfJoint, ...], kinematics: Kinematics) -> dict[str, list]:
    """Each link's simple geometry, from the joints' table: a base plate; at each axis a
    cylinder along it; from each link's joint to the next one a cylinder along z (d) and
    one across (a); a flange plate, the tool to the TCP and a ball there. Radii from the
    arm's length (the sum of its DH lengths), thinner towards the wrist."""
    size = sum(abs(a) + abs(d) for a, _alpha, d, _off in kinematics.dh)
    r = max(0.035 * size, 1.0)
    visuals: dict[str, list] = {"base_link": [_cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 0.5 * r), 1.4 * r, "irl_joint")]}
    radius = {}
    for row in table:
        if row.role == "axis":
            ri = r * (1.0 - 0.1 * row.source)
            radius[f"link_{row.source + 1}"] = ri
            visuals[f"link_{row.source + 1}"] = [_cylinder((0.0, 0.0, -1.1 * ri), (0.0, 0.0, 1.1 * ri), ri,
                                                           "irl_joint")]
    for row in table:
        if row.role in ("axis", "flange") and row.parent in radius:  # from this link's joint to the next one
            x, y, z = (row.origin[i][3] for i in range(3))
            ri = 0.7 * radius[row.parent]
            visuals[row.parent] += [_cylinder((0.0, 0.0, 0.0), (0.0, 0.0, z), ri, "irl_body"),
                                    _cylinder((0.0, 0.0, z), (x, y, z), ri, "irl_body")]
    r6 = radius["link_6"]
    tcp = next(row for row in table if row.role == "tcp")
    visuals["flange"] = [_cylinder((0.0, 0.0, -0.1 * r6), (0.0, 0.0, 0.0), 0.8 * r6, "irl_tool"),
                         _cylinder((0.0, 0.0, 0.0), tuple(tcp.origin[i][3] for i in range(3)), 0.25 * r6, "irl_tool")]
    visuals["tcp"] = [("irl_tool", IDENTITY, 0.35 * r6, None)]  # (a sphere: no length)
    return {link: [v for v in shapes if v is not None] for link, shapes in visuals.items()}


def urdf_text(spec: Spec) -> str:
    """The URDF of the specification's arm (the module's documentation: links, joints,
    units, limits, geometry): robot name the specification's ``[robot] name``. Raises
    ``ValueError`` (naming the axis) when the specification's kinematics cannot be used:
    not six revolute main axes with DH parameters, a geometry the kinematics does not
    take, or names the URDF cannot carry."""
    import xml.etree.ElementTree as ET

    kinematics = Kinematics(spec)
    table = urdf_joints(kinematics, tuple(spec.named_frames))
    robot = ET.Element("robot", name=_check_name(spec.name, "robot"))
    robot.append(ET.Comment(f" generated by irl urdf (specification hash {spec.hash[:16]}): m, rad; link i is "
                            "DH frame i-1 turned by theta_i; flange = DH frame 6, tcp = the tool centre point "))
    for name, rgba in MATERIALS.items():
        ET.SubElement(ET.SubElement(robot, "material", name=name), "color", rgba=" ".join(map(_num, rgba)))
    visuals = _visuals(table, kinematics)
    for link in ["world"] + [row.child for row in table]:
        element = ET.SubElement(robot, "link", name=link)
        for material, origin, radius, length in visuals.get(link, ()):
            visual = ET.SubElement(element, "visual")
            xyz, rpy = _xyz_rpy(origin)
            ET.SubElement(visual, "origin", xyz=xyz, rpy=rpy)
            shape = ET.SubElement(visual, "geometry")
            if length is None:
                ET.SubElement(shape, "sphere", radius=_num(radius / 1000.0))
            else:
                ET.SubElement(shape, "cylinder", radius=_num(radius / 1000.0), length=_num(length / 1000.0))
            ET.SubElement(visual, "material", name=material)
    axes = spec.main_axes
    for row in table:
        kind = "fixed" if not row.axis else "continuous" if row.mimic else "revolute"
        joint = ET.SubElement(robot, "joint", name=row.name, type=kind)
        ET.SubElement(joint, "parent", link=row.parent)
        ET.SubElement(joint, "child", link=row.child)
        xyz, rpy = _xyz_rpy(row.origin)
        ET.SubElement(joint, "origin", xyz=xyz, rpy=rpy)
        if row.axis:
            ET.SubElement(joint, "axis", xyz=f"0 0 {row.axis}")
        if row.mimic:
            ET.SubElement(joint, "mimic", joint=row.mimic, multiplier=_num(row.factor), offset="0")
        elif row.axis:
            axis = axes[row.source]
            ET.SubElement(joint, "limit", lower=_num(axis.min * _D2R), upper=_num(axis.max * _D2R),
                          effort=_num(EFFORT), velocity=_num(axis.max_velocity * _D2R))
    ET.indent(robot, "  ")
    return "<?xml version=\"1.0\"?>\n" + ET.tostring(robot, encoding="unicode") + "\n"
