"""The shipped specifications of real arms (programs/robots/*.spc) against their published chains.

For each arm, the kinematic chain of its ROS-Industrial URDF is written below as the file
gives it (each joint's origin xyz and rpy, its axis and its <limit>; the fixed joints on to
tool0; the vendor's base frame), with a forward kinematics of its own: NumPy, a homogeneous
4x4 per origin (``Rz(yaw) Ry(pitch) Rx(roll)``, then the translation, as URDF defines it) and
the joint's rotation about its axis -- not our Denavit-Hartenberg kinematics, and not the
specification's numbers. The URDF's joint values are the controller's (ROS-Industrial's
drivers pass them through), so agreeing with the URDF means a joint target means the same
pose as on the real robot. Checked:

* ``Kinematics(spec)`` gives the URDF's tool0 (position to 1e-6 mm, rotation to 1e-9) for
  joint values anywhere within the axis limits, and frame 6, the flange that ``use tool``
  tools are measured from, is that tool0 too; its inverse of a URDF pose gives joints whose
  URDF pose is that pose;
* no axis of a specification goes beyond the URDF's <limit> (range and speed);
* a short program (ptp moves, one to a pose, a straight line) runs on the simulated robot,
  and the report's tool centre point, at rest after every move, is within 0.01 mm of the
  URDF's tool0 of the measured joints, and at the end of the move of its commanded target.
"""
from __future__ import annotations

import csv
import functools
import re
import shlex
import math
from dataclasses import dataclass
from math import pi, radians

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from compiler.driver import compile_file
from compiler.spec import load_spec
from runtime.motion.kinematics import Kinematics
from runtime.loop.system import RobotSystem, RunOptions

from conftest import PROGRAMS, ROOT, run_cli, examples

ROBOTS = PROGRAMS / "robots"


@dataclass(frozen=True)
class Joint:
    """One revolute <joint> of a URDF: origin (m, rad), axis, <limit> (rad, rad/s)."""

    name: str
    xyz: tuple
    rpy: tuple
    axis: tuple
    lower: float
    upper: float
    velocity: float


@dataclass(frozen=True)
class Arm:
    name: str  # programs/robots/NAME.spc and NAME.irl
    joints: tuple  # the six revolute joints, base_link to the last link
    tool0: tuple  # the fixed joints from the last link to tool0: ((xyz, rpy), ...)
    base: tuple  # the vendor's base frame ("base") in base_link: (xyz, rpy)


IDENTITY = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

ARMS = (
    # github.com/ros-industrial/abb_experimental, abb_irb120_support/urdf/irb120_3_58_macro.xacro
    # (commit 0ae97e1); base_link-base is the identity.
    Arm("abb_irb120", (
        Joint("joint_1", (0, 0, 0), (0, 0, 0), (0, 0, 1), -2.87979, 2.87979, 4.36332),
        Joint("joint_2", (0, 0, 0.29), (0, 0, 0), (0, 1, 0), -1.91986, 1.91986, 4.36332),
        Joint("joint_3", (0, 0, 0.27), (0, 0, 0), (0, 1, 0), -1.91986, 1.22173, 4.36332),
        Joint("joint_4", (0, 0, 0.07), (0, 0, 0), (1, 0, 0), -2.79253, 2.79253, 5.58505),
        Joint("joint_5", (0.302, 0, 0), (0, 0, 0), (0, 1, 0), -2.094395, 2.094395, 5.58505),
        Joint("joint_6", (0.072, 0, 0), (0, 0, 0), (1, 0, 0), -6.98132, 6.98132, 7.33038),
    ), (((0, 0, 0), (0, 0, 0)),  # joint_6-flange
        ((0, 0, 0), (0, radians(90), 0))),  # link_6-tool0 (from the flange)
        IDENTITY),
    # github.com/ros-industrial/kuka_experimental, kuka_kr6_support/urdf/kr6r900sixx_macro.xacro
    # (commit 652600d); base_link-base ($ROBROOT) is the identity.
    Arm("kuka_kr6_r900_sixx", (
        Joint("joint_a1", (0, 0, 0.400), (0, 0, 0), (0, 0, -1), -radians(170), radians(170), radians(360)),
        Joint("joint_a2", (0.025, 0, 0), (0, 0, 0), (0, 1, 0), -radians(190), radians(45), radians(300)),
        Joint("joint_a3", (0.455, 0, 0), (0, 0, 0), (0, 1, 0), -radians(120), radians(156), radians(360)),
        Joint("joint_a4", (0, 0, 0.035), (0, 0, 0), (-1, 0, 0), -radians(185), radians(185), radians(381)),
        Joint("joint_a5", (0.420, 0, 0), (0, 0, 0), (0, 1, 0), -radians(120), radians(120), radians(388)),
        Joint("joint_a6", (0.080, 0, 0), (0, 0, 0), (-1, 0, 0), -radians(350), radians(350), radians(615)),
    ), (((0, 0, 0), (0, 0, 0)),  # joint_a6-flange
        ((0, 0, 0), (0, radians(90), 0))),  # flange-tool0
        IDENTITY),
    # github.com/ros-industrial/staubli_experimental, staubli_tx2_60_support/urdf/tx2_60_macro.xacro
    # (commit f3c3ae1); base_link-base (Staubli's world frame) is 0.375 up.
    Arm("staubli_tx2_60", (
        Joint("joint_1", (0, 0, 0.375), (0, 0, 0), (0, 0, 1), radians(-180), radians(180), radians(435)),
        Joint("joint_2", (0, 0, 0), (0, 0, 0), (0, 1, 0), radians(-127.5), radians(127.5), radians(385)),
        Joint("joint_3", (0, 0.02, 0.29), (0, 0, 0), (0, 1, 0), radians(-152.5), radians(152.5), radians(500)),
        Joint("joint_4", (0, 0, 0), (0, 0, 0), (0, 0, 1), radians(-270.0), radians(270.0), radians(995)),
        Joint("joint_5", (0, 0, 0.31), (0, 0, 0), (0, 1, 0), radians(-121.0), radians(132.5), radians(1065)),
        Joint("joint_6", (0, 0, 0.07), (0, 0, 0), (0, 0, 1), radians(-270.0), radians(270.0), radians(1445)),
    ), (((0, 0, 0), (0, radians(-90.0), 0)),  # joint_6-flange
        ((0, 0, 0), (0, radians(90.0), 0))),  # flange-tool0
        ((0, 0, 0.375), (0, 0, 0))),
    # github.com/ros-industrial/motoman, motoman_gp8_support/urdf/gp8_macro.xacro (commit
    # 3a9f58e); base_link-base (Yaskawa's robot frame) is 0.330 up. The file writes tool0's
    # rpy as "3.1415926 -1.570796 0": pi and -pi/2 rounded to 7 digits (3e-7 rad off), taken
    # here as what they stand for.
    Arm("yaskawa_gp8", (
        Joint("joint_1_s", (0, 0, 0.330), (0, 0, 0), (0, 0, 1), -2.9670, 2.9670, 7.9412),
        Joint("joint_2_l", (0.040, 0, 0), (0, 0, 0), (0, 1, 0), -1.1344, 2.5307, 6.7495),
        Joint("joint_3_u", (0, 0, 0.345), (0, 0, 0), (0, -1, 0), -1.2217, 3.3161, 9.0757),
        Joint("joint_4_r", (0.340, 0, 0.040), (0, 0, 0), (-1, 0, 0), -3.3161, 3.3161, 9.5993),
        Joint("joint_5_b", (0, 0, 0), (0, 0, 0), (0, -1, 0), -2.3561, 2.3561, 9.5993),
        Joint("joint_6_t", (0, 0, 0), (0, 0, 0), (-1, 0, 0), -6.2944, 6.2944, 17.4845),
    ), (((0.080, 0, 0), (pi, -pi / 2, 0)),),  # joint_6_t-tool0
        ((0, 0, 0.330), (0, 0, 0))),
)
IDS = [arm.name for arm in ARMS]


# ---- the URDF's forward kinematics (NumPy; nothing of ours) ------------------------------------

def _rotation(axis, angle: float) -> np.ndarray:
    """Rodrigues: the rotation by ``angle`` (rad) about the unit vector ``axis``."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * cross @ cross


def _origin(xyz, rpy) -> np.ndarray:
    """A URDF <origin>: translation xyz (m, here in mm) and fixed-axis rpy, R = Rz Ry Rx."""
    roll, pitch, yaw = rpy
    h = np.eye(4)
    h[:3, :3] = _rotation((0, 0, 1), yaw) @ _rotation((0, 1, 0), pitch) @ _rotation((1, 0, 0), roll)
    h[:3, 3] = np.asarray(xyz, dtype=float) * 1000.0
    return h


def urdf_tool0(arm: Arm, joints_deg) -> np.ndarray:
    """tool0 in the vendor's base frame (4x4, mm) for joint values in degrees."""
    h = np.eye(4)
    for joint, q in zip(arm.joints, joints_deg):
        turn = np.eye(4)
        turn[:3, :3] = _rotation(joint.axis, radians(q))
        h = h @ _origin(joint.xyz, joint.rpy) @ turn
    for xyz, rpy in arm.tool0:
        h = h @ _origin(xyz, rpy)
    return np.linalg.inv(_origin(*arm.base)) @ h


def _matrix(rows) -> np.ndarray:
    return np.array([list(row) for row in rows], dtype=float)


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """docs: a pose's rpy(roll, pitch, yaw) in degrees is Rz(yaw) Ry(pitch) Rx(roll)."""
    return _origin((0, 0, 0), (radians(roll), radians(pitch), radians(yaw)))[:3, :3]


def _angle(r1: np.ndarray, r2: np.ndarray) -> float:
    """The angle (rad) of the rotation from r1 to r2."""
    return math.acos(max(-1.0, min(1.0, (np.trace(r1.T @ r2) - 1.0) / 2.0)))


@functools.cache
def spec_of(name: str):
    return load_spec(ROBOTS / f"{name}.spc")


@functools.cache
def kinematics_of(name: str) -> Kinematics:
    return Kinematics(spec_of(name))


def joints_within_limits(spec) -> st.SearchStrategy:
    return st.tuples(*(st.floats(axis.min, axis.max, allow_nan=False) for axis in spec.main_axes))


# ---- the kinematics -----------------------------------------------------------------------------

@pytest.mark.parametrize("arm", ARMS, ids=IDS)
@settings(max_examples=examples(300))
@given(data=st.data())
def test_the_specification_is_the_urdf_chain(arm, data):
    """Forward kinematics of joint values anywhere within the limits: the TCP (the default
    tool) and frame 6 (the flange, that every tool is given in) are the URDF's tool0."""
    q = data.draw(joints_within_limits(spec_of(arm.name)), label="joints")
    expected = urdf_tool0(arm, q)
    kin = kinematics_of(arm.name)
    for got in (_matrix(kin.forward_matrix(q)), _matrix(kin.frames(q)[5])):
        assert np.abs(got[:3, 3] - expected[:3, 3]).max() <= 1e-6, (got, expected)
        assert np.abs(got[:3, :3] - expected[:3, :3]).max() <= 1e-9, (got, expected)


@pytest.mark.parametrize("arm", ARMS, ids=IDS)
@settings(max_examples=examples(100))
@given(data=st.data())
def test_the_inverse_of_a_urdf_pose_is_that_pose(arm, data):
    """Our inverse kinematics of the URDF's tool0 at joint values within the limits (away
    from the singularities): joints whose URDF tool0 is that pose."""
    kin = kinematics_of(arm.name)
    q = data.draw(joints_within_limits(spec_of(arm.name)), label="joints")
    assume(min(kin.singularity_margins(q)) > 1e-3)
    pose = urdf_tool0(arm, q)
    solution = kin.inverse(pose.tolist(), near=q)
    back = urdf_tool0(arm, solution)
    assert np.abs(back[:3, 3] - pose[:3, 3]).max() <= 1e-6
    assert np.abs(back[:3, :3] - pose[:3, :3]).max() <= 1e-9


@pytest.mark.parametrize("arm", ARMS, ids=IDS)
def test_no_axis_goes_beyond_the_urdf_limits(arm):
    """The range and speed of every axis lie within the URDF's <limit> (the data sheet's;
    up to 0.006 deg beyond it: the URDF's radians cut to four decimals, 1e-4 rad). The
    default tool is the flange (frame 6 is tool0: a tool measured on the real robot is a
    [[tool]] as it is)."""
    spec = spec_of(arm.name)
    rounding = math.degrees(1e-4)
    assert len(spec.main_axes) == len(arm.joints) == 6
    for axis, joint in zip(spec.main_axes, arm.joints):
        assert math.degrees(joint.lower) - rounding <= axis.min < axis.max <= math.degrees(joint.upper) + rounding, \
            axis.name
        assert axis.max_velocity <= math.degrees(joint.velocity) + rounding, axis.name
        assert axis.min <= axis.home <= axis.max
    assert spec.tool == (0.0,) * 6


def test_a_kuka_joint_target_turns_as_on_the_robot():
    """KUKA's A1, A4 and A6 turn about the URDF's -z (-x): A1 = +30 from home turns the arm
    clockwise seen from above (y < 0), as on the real robot; A2 = +30 lowers the upper arm."""
    kin = kinematics_of("kuka_kr6_r900_sixx")
    home = (0.0, -90.0, 90.0, 0.0, 0.0, 0.0)
    x, y, z = kin.forward(home)[:3]
    assert y == pytest.approx(0.0, abs=1e-9) and x > 0
    assert kin.forward((30.0, -90.0, 90.0, 0.0, 0.0, 0.0))[1] < -100.0
    assert kin.forward((0.0, -60.0, 90.0, 0.0, 0.0, 0.0))[2] < z - 100.0


# ---- a program on the simulated robot -----------------------------------------------------------

TCP = ("tcp_x", "tcp_y", "tcp_z", "tcp_roll", "tcp_pitch", "tcp_yaw")


def _rests(path) -> list[dict]:
    """The report's row at rest after each move: the last row of each move's dwell (Move
    Robot, the move's number, no move under way), and for the last move the report's last
    row (Stop Robot, brakes applied)."""
    with open(path, encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    last: dict[int, dict] = {}
    for row in rows:
        if row["state"] == "Move Robot" and row["line"] == "0" and row["move"] != "0":
            last[int(row["move"])] = row
    final = rows[-1]
    assert final["state"] == "Stop Robot"
    last[int(final["move"])] = final
    return [last[n] for n in sorted(last)]


@pytest.mark.parametrize("arm", ARMS, ids=IDS)
def test_a_program_runs_and_the_tcp_is_the_urdf_tool0(arm, tmp_path):
    """programs/robots/NAME.irl on the simulated robot (simulated clock) completes. At rest
    after each move, the report's TCP is the URDF's tool0 of the measured joints within
    0.01 mm and 1e-6 rad (it is their forward kinematics; the report writes joints to 1e-6
    deg), and the measured joints are the move's commanded target within one encoder count
    (the arm rests on the count nearest it: at these arms' reach up to about 0.01 mm). At
    the final rest, home, the TCP is the URDF's tool0 of the commanded target within 0.01 mm."""
    result = compile_file(ROBOTS / f"{arm.name}.irl")
    assert result.ok, [d.message for d in result.diagnostics]
    system = RobotSystem(result.spec, RunOptions(report=tmp_path / "report.csv"))
    system.report.columns = [*system.report.columns, "move"]
    summary = system.run(result.program)
    assert summary["fault"] is None, summary["fault"]
    axes = result.spec.main_axes
    moves = summary["moves"]
    rests = _rests(tmp_path / "report.csv")
    assert len(rests) == len(moves) >= 5
    assert moves[-1]["target"] == [axis.home for axis in axes]
    for number, (row, move) in enumerate(zip(rests, moves), 1):
        where = f"move {number} (line {move['line']})"
        measured = [float(row[f"sens_pos_{axis.name}"]) for axis in axes]
        tcp = [float(row[key]) for key in TCP]
        expected = urdf_tool0(arm, measured)
        assert math.dist(tcp[:3], expected[:3, 3]) <= 0.01, (where, measured, tcp, expected)
        assert _angle(_rpy_matrix(*tcp[3:]), expected[:3, :3]) <= 1e-6, (where, measured, tcp, expected)
        for axis, q, target in zip(axes, measured, move["target"]):
            assert abs(q - target) * axis.counts_per_unit <= 1.0 + 1e-3, (where, axis.name, q, target)
    target = urdf_tool0(arm, moves[-1]["target"])
    assert math.dist(tcp[:3], target[:3, 3]) <= 0.01, (tcp, target)
    assert _angle(_rpy_matrix(*tcp[3:]), target[:3, :3]) <= 1e-6, (tcp, target)


# ---- docs/robots.md ------------------------------------------------------------------------------

def _doc_commands() -> list[list[str]]:
    """The ``irl`` commands of docs/robots.md's shell blocks, as argument lists."""
    text = (ROOT / "docs" / "robots.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```sh\n(.*?)```", text, re.S)
    return [shlex.split(line)[1:] for block in blocks for line in block.splitlines()
            if line.startswith(".venv/bin/irl ")]


def test_the_commands_in_docs_robots_md_run(tmp_path):
    """Every ``irl`` command docs/robots.md shows succeeds (in-process; its files under a
    temporary directory instead of out/), and every shipped arm is in its table."""
    commands = _doc_commands()
    assert len(commands) >= 4
    for argv in commands:
        argv = [str(tmp_path / a[len("out/"):]) if a.startswith("out/") else
                str(ROOT / a) if a.startswith("programs/") else a for a in argv]
        code, out, err = run_cli(*argv)
        assert code == 0, (argv, out, err)
    text = (ROOT / "docs" / "robots.md").read_text(encoding="utf-8")
    shipped = sorted(path.stem for path in ROBOTS.glob("*.spc"))
    assert shipped == sorted(arm.name for arm in ARMS)
    for name in shipped:
        assert f"| `{name}.spc` |" in text, name
        assert (ROBOTS / f"{name}.irl").exists(), name


# ---- the sequence on the shipped Staubli --------------------------------------------------

STAUBLI_SEQUENCE = """program staubli;
seq
  move ptp joint(mainjoint(0,0,90,0,45,0));
  move ptp joint(mainjoint(0,0,90,180,45,0)) speed_ptp := 1 acc_ptp := 1;
  wait 0.5 sec;
endseq
endprogram;
"""


@pytest.mark.parametrize("encoder_counts", [4096, 65536])
def test_the_staubli_full_acceleration_wrist_move_and_dwell_complete(encoder_counts, tmp_path):
    """Issue 27: a legal full-acceleration ptp of J4 then a dwell on the TX2-60 ended in a
    false category-0 stop ("J4 moved 11 encoder counts while the robot must be at rest");
    with the shipped encoders and with encoders 16 times finer (the tolerance in counts is
    then 16 times smaller an angle) it completes, the arm where the program left it."""
    text = (ROBOTS / "staubli_tx2_60.spc").read_text(encoding="utf-8")
    text = re.sub(r"(?m)^encoder_counts = 4096", f"encoder_counts = {encoder_counts}", text)
    spec_path = tmp_path / "staubli.spc"
    spec_path.write_text(text, encoding="utf-8")
    program = tmp_path / "staubli.irl"
    program.write_text(STAUBLI_SEQUENCE, encoding="utf-8")
    code, out, err = run_cli("run", program, "--spec", spec_path)
    assert code == 0 and "completed" in out, out + err
    assert "final position: 0.000, 0.000, 90.000, 180.000, 45.000, 0.000" in out, out
