"""The supervisor's state machine as a diagram (``irl fsm``), built from the same table
the runtime steps, on a simulated robot that never runs."""
from __future__ import annotations


def supervisor_diagram(fmt: str = "mermaid") -> str:
    from compiler.spec import parse_spec

    from runtime.loop.system import RobotSystem, RunOptions

    spec = parse_spec(_minimal_spec(), "<diagram>")
    fsm = RobotSystem(spec, RunOptions()).supervisor.fsm
    return fsm.to_dot() if fmt == "dot" else fsm.to_mermaid()


def _minimal_spec() -> str:
    """One small axis, each limit the least its declared range accepts (compiler.params)."""
    import math

    from compiler import params

    axis = params.section_params("axis")
    limits = "\n".join(f"{key} = {float(axis[key].low)!r}" for key in ("max_velocity", "max_acceleration", "max_jerk"))
    # the coarsest encoder the resolution rule accepts at that acceleration, at the default gear
    gear = axis["gear_ratio"].default
    least = params.least_counts_per_unit(axis["max_acceleration"].low, params.spec_section("safety")["acceleration_factor"].default)
    limits += f"\ngear_ratio = {float(gear)!r}\nencoder_counts = {math.ceil(least * 360 / gear)}"
    return f"""
[robot]
name = "diagram"
[[axis]]
name = "A1"
kind = "revolute"
min = -180.0
max = 180.0
{limits}
"""
