"""The arm as URDF (runtime/motion/urdf.py, ``irl urdf``).

* The URDF read back by another library (yourdfpy, its own XML parser; the forward
  kinematics by the URDF's rules in NumPy, and yourdfpy's own) moves as our kinematics:
  the flange, the default tool's TCP, a named tool and a named frame at random joint
  values within the limits (hypothesis), to 1e-6 mm and 1e-9 in rotation, for the Lola
  15, every shipped real arm and an arm with a mounting, axes turning the other way and
  two couplings.
* ``link_frames`` composed from ``world`` gives ``Kinematics.frames`` (every DH frame,
  the flange, the TCP), and it names the URDF's joints, parents before children.
* Names: the axes name the joints, a collision is refused, the robot's name is escaped.
* ``irl urdf``: to standard output or a file; a specification whose arm the kinematics
  cannot take is exit 1 with the reason, a missing file exit 2.
"""
from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET
from functools import cache

import numpy as np
import pytest
import yourdfpy
from hypothesis import given, settings
from hypothesis import strategies as st

from compiler.spec import parse_spec
from runtime.motion.kinematics import Kinematics
from runtime.motion.urdf import EFFORT, joint_positions, link_frames, urdf_joints, urdf_text, world_frames
from test_arm_mapping import spec_with

from conftest import PROGRAMS, SPEC_PATH, run_cli

#: A named tool and a named frame, added to every specification tested.
NAMED = """
[[tool]]
name = "probe"
x = 12.5
y = -30.0
z = 80.0
roll = 10.0
pitch = -20.0
yaw = 35.0

[[frame]]
name = "fixture"
x = 400.0
y = -250.0
z = 120.0
roll = 5.0
yaw = -60.0
"""
PROBE = (12.5, -30.0, 80.0, 10.0, -20.0, 35.0)
FIXTURE = (400.0, -250.0, 120.0, 5.0, 0.0, -60.0)

SHIPPED = [SPEC_PATH, *sorted((PROGRAMS / "robots").glob("*.spc"))]


@cache
def arm(name: str):
    """(spec, Kinematics, the URDF loaded by yourdfpy) of a shipped specification (its file
    name) with NAMED added, or of "mapped": the Lola 15 mounted on a tilted riser, A1 and
    A4 turning the other way, A2 coupled to A1 and A3 to A2 (FANUC's J3)."""
    if name == "mapped":
        spec = spec_with({1: "direction = -1", 2: 'coupling = { axis = "A1", factor = 0.5 }',
                          3: 'coupling = { axis = "A2", factor = -1 }', 4: "direction = -1"},
                         "tool = { x = 5, y = -10, z = 120, roll = 10, pitch = 20, yaw = -30 }\n"
                         "mounting = { x = 300, y = 200, z = 400, roll = 12, pitch = -7, yaw = 33 }", NAMED)
    else:
        path = next(p for p in SHIPPED if p.name == name)
        spec = parse_spec(path.read_text() + NAMED, str(path))
    text = urdf_text(spec)
    return spec, Kinematics(spec), yourdfpy.URDF.load(io.StringIO(text), load_meshes=False)


NAMES = [p.name for p in SHIPPED] + ["mapped"]


def rpy(values) -> np.ndarray:
    """The 4x4 of (x, y, z, roll, pitch, yaw) (mm, deg), Rz Ry Rx, by NumPy."""
    x, y, z, roll, pitch, yaw = values
    r, p, w = np.radians([roll, pitch, yaw])
    rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    rz = np.array([[np.cos(w), -np.sin(w), 0], [np.sin(w), np.cos(w), 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx
    m[:3, 3] = (x, y, z)
    return m


def assert_same(urdf_m, ours, what: str) -> None:
    """A yourdfpy transform (m) against ours (mm): 1e-6 mm, 1e-9 in rotation."""
    ours = np.asarray(ours, dtype=float)[:3]
    position = np.abs(np.asarray(urdf_m)[:3, 3] * 1000.0 - ours[:, 3]).max()
    rotation = np.abs(np.asarray(urdf_m)[:3, :3] - ours[:, :3]).max()
    assert position < 1e-6 and rotation < 1e-9, f"{what}: {position:.3g} mm, {rotation:.3g}"


def urdf_forward(model, positions: dict) -> dict:
    """Every link in the world frame (4x4, m) at the axes' positions (rad, by joint name),
    from the joints as yourdfpy parsed them (origin, axis, type, mimic), by the URDF's rules
    (a mimic joint at multiplier x its joint + offset), in NumPy. (Not yourdfpy's
    ``get_transform``: its scene graph (trimesh) takes a joint's transform within 1e-8 of
    the identity for the identity, 1e-8 rad at a joint near 0.)"""
    world = {model.base_link: np.eye(4)}
    for joint in model.robot.joints:  # (the file lists parents first)
        turn = np.eye(4)
        if joint.type != "fixed":
            q = positions[joint.name] if joint.mimic is None else \
                joint.mimic.multiplier * positions[joint.mimic.joint] + joint.mimic.offset
            k = np.asarray(joint.axis, dtype=float)
            cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            turn[:3, :3] = np.cos(q) * np.eye(3) + np.sin(q) * cross + (1 - np.cos(q)) * np.outer(k, k)
        world[joint.child] = world[joint.parent] @ joint.origin @ turn
    return world


FRACTIONS = st.tuples(*[st.floats(0.0, 1.0)] * 6)


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=12, deadline=None)
@given(fractions=FRACTIONS)
def test_the_urdf_moves_as_our_kinematics(name, fractions):
    spec, kin, model = arm(name)
    q = [lo + f * (hi - lo) for f, (lo, hi) in zip(fractions, kin.limits)]
    links = urdf_forward(model, {axis: math.radians(v) for axis, v in zip(kin.names, q)})  # the axes alone
    frames = kin.frames(q)
    assert_same(links["flange"], frames[5], "flange")
    assert_same(links["tcp"], frames[6], "tcp")
    assert_same(links["tool_probe"], kin.with_tool(PROBE).frames(q)[6], "tool_probe")
    assert_same(links["frame_fixture"], rpy(FIXTURE), "frame_fixture")


@pytest.mark.parametrize("name", ["mapped", "yaskawa_gp8.spc"])
def test_yourdfpy_itself_moves_the_urdf_as_our_kinematics(name):
    """yourdfpy's own forward kinematics (its mimic joints included), at joint values no
    joint's transform of which is near the identity (see urdf_forward)."""
    spec, kin, model = arm(name)
    for q in ((10.0, -20.0, 30.0, 40.0, 50.0, 60.0), (-35.5, 12.25, -47.0, 150.0, -80.0, -200.0)):
        model.update_cfg({axis: math.radians(v) for axis, v in zip(kin.names, q)})
        assert_same(model.get_transform("flange", "world"), kin.frames(q)[5], f"flange at {q}")
        assert_same(model.get_transform("tool_probe", "world"), kin.with_tool(PROBE).frames(q)[6], f"probe at {q}")


def dh(a, alpha, d) -> np.ndarray:
    """Tz(d) Tx(a) Rx(alpha), by NumPy."""
    ca, sa = np.cos(np.radians(alpha)), np.sin(np.radians(alpha))
    return np.array([[1, 0, 0, a], [0, ca, -sa, 0], [0, sa, ca, d], [0, 0, 0, 1]], dtype=float)


@pytest.mark.parametrize("name", ["lola15.spc", "mapped"])
def test_link_frames_compose_to_the_kinematics_frames(name):
    """Every DH frame i is link i + 1's frame moved along its row (Tz(d) Tx(a) Rx(alpha)),
    the flange T_06, the TCP the tool's; the transforms are plain floats, 3x4, in the
    URDF's joint order (parents first)."""
    spec, kin, model = arm(name)
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = [float(rng.uniform(lo, hi)) for lo, hi in kin.limits]
        listed = link_frames(kin, q, spec.named_frames)
        assert [(p, c) for p, c, _m in listed] == [(j.parent, j.child) for j in model.robot.joints]
        for _p, _c, m in listed:
            assert len(m) == 3 and all(len(row) == 4 and all(type(v) is float for v in row) for row in m)
        world = world_frames(kin, q, spec.named_frames)
        frames = kin.frames(q)
        for i, (a, alpha, d, _off) in enumerate(kin.dh):
            link = np.vstack([np.array(world[f"link_{i + 1}"]), [0, 0, 0, 1]])
            assert np.abs(link @ dh(a, alpha, d) - np.array(frames[i])).max() < 1e-9, f"frame {i + 1}"
        assert np.abs(np.array(world["flange"]) - np.array(frames[5])[:3]).max() < 1e-9
        assert np.abs(np.array(world["tcp"]) - np.array(frames[6])[:3]).max() < 1e-9
        assert np.abs(np.array(world["base_link"]) - rpy(kin.mounting)[:3]).max() < 1e-12


def test_a_coupled_axis_is_a_mimic_joint_and_its_share_is_its_position():
    spec, kin, model = arm("mapped")
    joints = {j.name: j for j in model.robot.joints}
    assert model.actuated_joint_names == ["A1", "A2", "A3", "A4", "A5", "A6"]
    assert (joints["A3_from_A2"].mimic.joint, joints["A3_from_A2"].mimic.multiplier) == ("A2", -1.0)
    assert (joints["A2_from_A1"].mimic.joint, joints["A2_from_A1"].mimic.multiplier) == ("A1", 0.5)
    assert (joints["A3"].parent, joints["A3"].child, joints["A3_from_A2"].child) == ("link_2", "link_3_uncoupled",
                                                                                     "link_3")
    assert list(joints["A1"].axis) == [0, 0, -1] and list(joints["A2"].axis) == [0, 0, 1]
    q = (10.0, -20.0, 30.0, 40.0, 50.0, 60.0)
    positions = joint_positions(kin, q)
    assert positions == pytest.approx({"A1": math.radians(10), "A2": math.radians(-20), "A2_from_A1": math.radians(5),
                                       "A3": math.radians(30), "A3_from_A2": math.radians(20), "A4": math.radians(40),
                                       "A5": math.radians(50), "A6": math.radians(60)}, abs=1e-15)


def test_limits_and_the_shipped_names():
    spec, kin, model = arm("kuka_kr6_r900_sixx.spc")
    links = [link.name for link in model.robot.links]
    assert links == ["world", "base_link", "link_1", "link_2", "link_3", "link_4", "link_5", "link_6", "flange",
                     "tcp", "frame_fixture", "tool_probe"]
    assert model.base_link == "world"
    for axis in spec.main_axes:
        joint = model.joint_map[axis.name]
        assert joint.type == "revolute"
        assert (joint.limit.lower, joint.limit.upper) == pytest.approx((math.radians(axis.min), math.radians(axis.max)))
        assert joint.limit.velocity == pytest.approx(math.radians(axis.max_velocity))
        assert joint.limit.effort == EFFORT
    assert model.validate()


def test_a_name_the_urdf_would_take_twice_is_refused_and_the_robot_name_escaped():
    clash = parse_spec(SPEC_PATH.read_text().replace('name = "A6"', 'name = "link_6-flange"'), "clash.spc")
    with pytest.raises(ValueError, match="two joints named 'link_6-flange'"):
        urdf_text(clash)
    odd = parse_spec(SPEC_PATH.read_text().replace('name = "lola_15"', 'name = "Lola <15> & \\"co\\""'), "odd.spc")
    assert ET.fromstring(urdf_text(odd)).get("name") == 'Lola <15> & "co"'
    control = parse_spec(SPEC_PATH.read_text().replace('name = "A2"', 'name = "A\\u00012"'), "control.spc")
    with pytest.raises(ValueError, match="printable"):
        urdf_text(control)


def test_the_table_is_built_once_per_arm():
    spec, kin, _model = arm("lola15.spc")
    assert urdf_joints(kin, spec.named_frames) is urdf_joints(kin, spec.named_frames)
    with pytest.raises(ValueError, match="six joint values"):
        link_frames(kin, (0.0,) * 5)


# ---- irl urdf ------------------------------------------------------------------------------

def test_irl_urdf_writes_the_file_or_standard_output(tmp_path):
    out = tmp_path / "lola.urdf"
    code, stdout, stderr = run_cli("urdf", SPEC_PATH, "-o", out)
    assert (code, stderr) == (0, "") and f"-> {out}" in stdout
    code, printed, stderr = run_cli("urdf", SPEC_PATH)
    assert (code, stderr) == (0, "")
    assert out.read_text(encoding="utf-8") == printed == urdf_text(parse_spec(SPEC_PATH.read_text(), str(SPEC_PATH)))
    assert yourdfpy.URDF.load(str(out), load_meshes=False).actuated_joint_names == [f"A{i}" for i in range(1, 7)]


@pytest.mark.parametrize("changes, message", [
    ([('name = "A6"', 'name = "A6"\ngroup = "additional"')],
     "no URDF of this arm: the kinematics needs six main axes, the specification has 5"),
    ([('kind = "revolute"\nmin = -350.0', 'kind = "prismatic"\nmin = -350.0'), ("gear_ratio = 60.0", "gear_ratio = 1.0")],
     "no URDF of this arm: axis A6: the arm's axes must be revolute"),
    ([("dh = { a = 0.0, alpha = -90.0, d = 0.0 }", "")], "no URDF of this arm: axis A5: no dh parameters"),
    ([("dh = { a = 0.0, alpha = -90.0, d = 0.0 }", "dh = { a = 10.0, alpha = -90.0, d = 0.0 }")],
     "no URDF of this arm: axis A5: a must be 0 mm"),
    ([('name = "A6"', 'name = "world-base_link"')], "no URDF of this arm: the URDF would have two joints named"),
    ([('name = "lola_15"', "")], "robot.name: missing"),
])
def test_irl_urdf_refuses_an_arm_it_cannot_describe(tmp_path, changes, message):
    text = SPEC_PATH.read_text()
    for old, new in changes:
        assert text.count(old) == 1
        text = text.replace(old, new)
    bad = tmp_path / "bad.spc"
    bad.write_text(text, encoding="utf-8")
    code, stdout, stderr = run_cli("urdf", bad, "-o", tmp_path / "bad.urdf")
    assert (code, stdout) == (1, "")
    assert stderr.startswith("irl urdf: ") and message in stderr and "Traceback" not in stderr, stderr
    assert not (tmp_path / "bad.urdf").exists()


def test_irl_urdf_without_the_file_is_a_usage_error(tmp_path):
    code, stdout, stderr = run_cli("urdf", tmp_path / "none.spc")
    assert (code, stdout) == (2, "") and "no such file" in stderr
