"""The check of a planned move against the world zones (compiler.zones) before it starts.

:func:`zone_problem` samples the move's joint trajectory so that the flange and the tool
centre point each move at most :data:`compiler.zones.STEP` mm between two samples (the
step adapts to how fast they move: about one sample per STEP mm of the faster one's path),
computes both points (forward kinematics, the world frame) and refuses the move where
either comes within :data:`compiler.zones.MARGIN` of a zone. The planner
(runtime.motion.moves) runs it on every move it plans, and on every blend (a blend that
would come too close is not made: the robot stops at the corner).

Not real-time: the planning worker's time (about 10 us per sample: 3 ms for a 600 mm move).
"""
from __future__ import annotations

import math

from compiler.zones import MARGIN, STEP, forbidden, run_problem, shown

__all__ = ["home_problem", "zone_problem"]

#: s: the first step, and the bounds of the adapted one.
_FIRST_STEP, _MIN_STEP, _MAX_STEP = 0.002, 1e-5, 0.05


def zone_problem(kinematics, trajectory, tool: tuple, zones, what: str = "the path") -> str | None:
    """Why the flange or the tool centre point (``tool``: its x, y, z in the flange) of
    ``trajectory`` (its first six axes: the arm's) comes within MARGIN of one of ``zones``,
    or None."""
    if not zones:
        return None
    duration = trajectory.duration
    position_at = trajectory.position_at

    def points(t: float) -> tuple:
        return kinematics.flange_and_tcp(position_at(t)[:6], tool)

    t, here = 0.0, points(0.0)
    said = _closest(here, zones, 0.0, duration, what)
    if said is not None:
        return said
    dt = min(_FIRST_STEP, duration) if duration > 0.0 else 0.0
    while t < duration:
        t_next = min(t + dt, duration)
        there = points(t_next)
        moved = max(math.dist(here[0], there[0]), math.dist(here[1], there[1]))
        if moved > STEP and dt > _MIN_STEP:
            dt *= 0.5
            continue
        said = _closest(there, zones, t_next, duration, what)
        if said is not None:
            return said
        t, here = t_next, there
        if moved < 0.5 * STEP:
            dt = min(dt * 1.5, _MAX_STEP)
    return None


def _closest(points: tuple, zones, t: float, duration: float, what: str) -> str | None:
    flange, tcp = points
    for zone in zones:
        for name, (x, y, z) in (("the tool centre point", tcp), ("the flange", flange)):
            depth = zone.depth(x, y, z)
            if depth > -MARGIN:
                at = f"{100.0 * t / duration:.0f} % of its time" if duration > 0.0 else "its start"
                how = (f"{depth:.1f} mm inside it" if depth > 0.0 else
                       f"{-depth:.1f} mm from it (a move keeps {MARGIN:g} mm away)")
                return (f"{what} enters zone '{zone.name}' ({zone.describe()}) at {at}: {name} would be at "
                        f"({shown(x)}, {shown(y)}, {shown(z)}), {how}")
    return None


def home_problem(kinematics, home: tuple, tool: tuple, zones) -> str | None:
    """Why the robot's home position (where homing leaves it, and every program starts)
    has the flange or the tool centre point within MARGIN of a zone (no move could leave
    it), or None."""
    if not zones or kinematics is None:
        return None
    said = _closest(kinematics.flange_and_tcp(tuple(home)[:6], tool), zones, 0.0, 0.0, "the home position")
    if said is None:
        return None
    return said.replace(" enters zone", " is in zone", 1).replace(" at its start", "", 1) + \
        ": every move from there would be refused (move the zone, or the axes' home)"


def start_problem(spec, kinematics, zones: tuple) -> tuple[str, str] | None:
    """Why a program with its own world ``zones`` (compiler.zones) cannot start on the robot of
    ``spec`` (its ``kinematics``, None when it has none): ``(the zone's name, what)``, or
    None. The runtime refuses such object code; ``irl check`` says so at the zone."""
    if not zones:
        return None
    problem = run_problem(spec, zones)
    if problem is not None:
        return zones[0].name, problem
    if kinematics is None:
        return zones[0].name, "world zones need the robot's kinematics ([kinematics] in its specification)"
    home, tool = tuple(axis.home for axis in spec.main_axes), tuple(spec.tool[:3])
    for zone in forbidden(zones):
        problem = home_problem(kinematics, home, tool, (zone,))
        if problem is not None:
            return zone.name, problem
    return None
