"""The supervisor's state machine as a diagram (``irl fsm``), built from the same table
the runtime steps, on a simulated robot that never runs."""
from __future__ import annotations


def supervisor_diagram(fmt: str = "mermaid") -> str:
    from compiler.spec import parse_spec

    from .system import RobotSystem, RunOptions

    spec = parse_spec(_minimal_spec(), "<diagram>")
    fsm = RobotSystem(spec, RunOptions()).supervisor.fsm
    return fsm.to_dot() if fmt == "dot" else fsm.to_mermaid()


def _minimal_spec() -> str:
    """One small axis, each limit the least its declared range accepts (compiler.params)."""
    from compiler import params

    axis = params.section_params("axis")
    limits = "\n".join(f"{key} = {float(axis[key].low)!r}" for key in ("max_velocity", "max_acceleration", "max_jerk"))
    return f"""
[robot]
name = "diagram"
[[axis]]
name = "A1"
kind = "revolute"
min = -10.0
max = 10.0
{limits}
"""
