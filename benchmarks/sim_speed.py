"""Simulated-clock speed of the paper's program through all phases.

Figures: simulated seconds per wall second (goal >= 100: issue 13 keeps it there with the safety supervisor in the tick; issue 3 asked 50), and the cost of one 1 ms tick
with every component in it (goal <= 20 us), with each task's mean execution time from
the executive's own statistics. Reference measured in the same run: a bare Python loop
doing one float multiply-add per axis per tick for the same number of ticks.
The per-axis loops run compiled when the build made them (runtime/accel.py says which;
the first line printed too); IRL_KERNELS=python in the environment measures the source.
Run: .venv/bin/python benchmarks/sim_speed.py [--runs N] [--seed N]
"""
from __future__ import annotations

import gc
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.driver import compile_file  # noqa: E402
from runtime import accel  # noqa: E402
from runtime.loop.system import RobotSystem, RunOptions  # noqa: E402
from _stats import arguments  # noqa: E402


def bare_loop(ticks: int, n: int = 6) -> float:
    x = [0.0] * n
    t0 = time.perf_counter()
    for _ in range(ticks):
        for i in range(n):
            x[i] = x[i] * 0.999 + 0.001
    return time.perf_counter() - t0


def main() -> int:
    ap = arguments(__doc__, runs=5, seed=0)
    args = ap.parse_args()
    result = compile_file(ROOT / "programs" / "test.irl")
    print(f"per-axis kernels: {accel.DESCRIPTION}")
    speeds, per_tick, bare = [], [], []
    tasks = None
    for run in range(args.runs):
        system = RobotSystem(result.spec, RunOptions(seed=args.seed))
        gc.collect()
        summary = system.run(result.program)
        if summary["fault"]:
            raise SystemExit(f"the run faulted: {summary['fault']}")
        speeds.append(summary["sim_time"] / summary["wall_time"])
        per_tick.append(summary["wall_time"] / summary["ticks"])
        bare.append(bare_loop(summary["ticks"]) / summary["ticks"])
        tasks = summary["deadlines"]
        # the host's speed varies (a shared machine): each run beside its own reference
        print(f"run {run + 1}: {speeds[-1]:.1f}x, {per_tick[-1] * 1e6:.1f} us per tick, "
              f"bare loop {bare[-1] * 1e6:.2f} us (ratio {per_tick[-1] / bare[-1]:.0f}x)")
    print(f"paper's program, all phases: {summary['sim_time']:.3f} s simulated, {summary['ticks']} ticks")
    print(f"speed: median {statistics.median(speeds):.1f}x, best {max(speeds):.1f}x real time  (goal >= 100x)")
    print(f"one 1 ms tick, everything: median {statistics.median(per_tick) * 1e6:.1f} us, "
          f"best {min(per_tick) * 1e6:.1f} us  (goal <= 20 us)")
    print(f"reference, bare 6-axis float loop: {statistics.median(bare) * 1e6:.2f} us per tick "
          f"(ratio {statistics.median(per_tick) / statistics.median(bare):.0f}x)")
    print("per task (last run): mean execution time per run, runs")
    for name, s in tasks.items():
        print(f"  {name:16s} {s['exec_mean_us']:7.2f} us  x {s['runs']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
