"""The tool centre point of the arm's joint values, with any tool and base: one cache of
the arm's kinematics per tool, for every part of the runtime that shows or uses the tool
(the report, the recording, the server's snapshot, the views, the trajectory generator's
own state of the robot and the simulated cell's sensors)."""
from __future__ import annotations

from compiler.frames import IDENTITY, pose_of, values_of
from compiler.semantics import compose, inverse

__all__ = ["TcpOf", "tcp_of"]


class TcpOf:
    """The tool centre point of joint values with a move's tool, in the world frame or in
    its base (:class:`~runtime.motion.moves.Frames`). The report's writer, the server, the
    views and the trajectory generator call it; the arm with each tool is built once (the
    latest 16 kept: another tool's tables take about 50 us, once), so that a tick may too."""

    def __init__(self, kinematics):
        self.kinematics = kinematics
        self._tools: dict = {}

    def arm(self, tool: tuple):
        """The arm with ``tool`` (the specification's: the kinematics themselves)."""
        k = self.kinematics
        if tool == k.tool:
            return k
        arm = self._tools.get(tool)
        if arm is None:
            if len(self._tools) >= 16:
                self._tools.pop(next(iter(self._tools)))
            arm = self._tools[tool] = k.with_tool(tool)
        return arm

    def world(self, joints, frames) -> tuple:
        """x, y, z, roll, pitch, yaw of the TCP in the world frame (the spec's tool: None)."""
        return self.arm(self.kinematics.tool if frames is None else frames.tool).forward(joints)

    def world_matrix(self, joints, frames) -> tuple:
        """The same as a 4x4 homogeneous matrix (nested tuples, mm)."""
        return self.arm(self.kinematics.tool if frames is None else frames.tool).forward_matrix(joints)

    def in_base(self, joints, frames, world: tuple | None = None) -> tuple:
        """The same in the move's base (``world``: :meth:`world` of the same joints and
        frames, when the caller has it already)."""
        if world is None:
            world = self.world(joints, frames)
        if frames is None or frames.base == IDENTITY:
            return world
        return values_of(compose(inverse(pose_of(frames.base)), pose_of(world)))


def tcp_of(spec) -> TcpOf | None:
    """Not real-time: the TCP of the specification's arm, or None when its kinematics are
    not usable (no DH data, not a six-axis arm with a spherical wrist)."""
    from runtime.motion.kinematics import Kinematics

    try:
        return TcpOf(Kinematics(spec))
    except ValueError:
        return None
