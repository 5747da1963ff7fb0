"""Machine instructions per 1 ms tick of the paper's program, counted by valgrind.

Wall-clock speed on a shared machine moves by 1.5x within minutes; instruction counts do
not: the same code, inputs and environment give the same count, whatever else runs. This
counts the whole run of programs/test.irl (all phases, simulated clock) minus the same
process's set-up, divided by the ticks; the reference, counted the same way in the same
run, is the bare 6-axis float loop of benchmarks/sim_speed.py. Hash seeds and BLAS threads
are pinned (both change counts from run to run otherwise). IRL_KERNELS=python in the
environment counts the per-axis loops as Python source instead of the compiled build.
The safety supervisor's cost per tick is the difference from the same run with its update
replaced by a bare pass-through of the servo's command (what the drives need at least).
Needs valgrind (Debian's package). Run: .venv/bin/python benchmarks/instructions.py
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import sys
sys.path[:0] = [{root!r}, {root!r} + "/benchmarks"]  # (sim_speed imports _stats beside it)
from compiler.driver import compile_file
from runtime.loop.system import RobotSystem, RunOptions
from benchmarks.sim_speed import bare_loop
from runtime import accel
mode, ticks = sys.argv[1], int(sys.argv[2])
result = compile_file({program!r})
system = RobotSystem(result.spec, RunOptions(seed=0))
if mode == "unguarded":  # the safety's checks replaced by a bare pass-through (for its cost only)
    out_vel, drive_cmd = system.ports["out_vel"], system.ports["drive_cmd"]
    zeros = (0.0,) * len(result.spec.axes)
    def passing(now, out_vel=out_vel, drive_cmd=drive_cmd, zeros=zeros):
        drive_cmd.write(out_vel.value or zeros, now)
    for task in system.executive.tasks:
        if task.name == "safety":
            task.run = passing
    mode = "run"
if mode == "run":
    summary = system.run(result.program)
    print("TICKS", summary["ticks"], "FAULT", summary["fault"])
    print("KERNELS", accel.DESCRIPTION)
elif mode == "bare":
    bare_loop(ticks)
"""


def count(mode: str, ticks: int = 0) -> tuple[int, str]:
    """Instructions of one child process (``mode``: "none", "run" or "bare") and its output."""
    code = _CHILD.format(root=str(ROOT), program=str(ROOT / "programs" / "test.irl"))
    env = dict(os.environ, PYTHONHASHSEED="0", OPENBLAS_NUM_THREADS="1")
    done = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
                           sys.executable, "-c", code, mode, str(ticks)],
                          capture_output=True, text=True, env=env, check=False)
    found = re.search(r"Collected : (\d+)", done.stderr)
    if done.returncode != 0 or not found:
        raise SystemExit(f"valgrind run ({mode}) failed:\n{done.stderr[-2000:]}")
    return int(found.group(1)), done.stdout


def main() -> int:
    if shutil.which("valgrind") is None:
        print("valgrind is not installed (apt-get install valgrind): nothing to count", file=sys.stderr)
        return 2
    setup, _ = count("none")
    total, out = count("run")
    found = re.search(r"TICKS (\d+) FAULT (.*)", out)
    if not found or found.group(2) != "None":
        raise SystemExit(f"the run did not complete: {out.strip()}")
    ticks = int(found.group(1))
    bare, _ = count("bare", ticks)
    unguarded, out_unguarded = count("unguarded")
    per_tick = (total - setup) / ticks
    bare_per_tick = (bare - setup) / ticks
    found = re.search(r"TICKS (\d+) FAULT (.*)", out_unguarded)
    unguarded_ticks = int(found.group(1)) if found else ticks
    kernels = re.search(r"KERNELS (.*)", out)
    print(f"per-axis kernels: {kernels.group(1) if kernels else '?'}")
    print(f"paper's program, all phases: {ticks} ticks")
    print(f"instructions per 1 ms tick, everything: {per_tick:,.0f}")
    print(f"reference, bare 6-axis float loop: {bare_per_tick:,.0f} per tick (ratio {per_tick / bare_per_tick:.0f}x)")
    guard = per_tick - (unguarded - setup) / unguarded_ticks
    print(f"the safety supervisor's checks: {guard:,.0f} per tick ({100 * guard / per_tick:.1f} % of the tick; "
          "against a bare pass-through of the command)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
