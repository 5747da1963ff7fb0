"""The supervisor's state machine as a diagram (``irl fsm``), built from the same table
the runtime steps, on a simulated robot that never runs."""
from __future__ import annotations


def supervisor_diagram(fmt: str = "mermaid") -> str:
    from compiler.spec import parse_spec

    from .system import RobotSystem, RunOptions

    spec = parse_spec(_MINIMAL_SPEC, "<diagram>")
    fsm = RobotSystem(spec, RunOptions()).supervisor.fsm
    return fsm.to_dot() if fmt == "dot" else fsm.to_mermaid()


_MINIMAL_SPEC = """
[robot]
name = "diagram"
[[axis]]
name = "A1"
kind = "revolute"
min = -10.0
max = 10.0
max_velocity = 1.0
max_acceleration = 1.0
max_jerk = 1.0
"""
