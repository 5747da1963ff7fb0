"""Jerk-limited PTP planner (runtime.motion.jerk) against Ruckig: durations and speed.

Over N random six-axis moves (seeded; start and target uniform in [-180, 180] deg on
every axis; limits of programs/lola15.spc -- velocity, acceleration and jerk -- each
scaled per move by its own random fraction in [0.05, 1], like speed_ptp / acc_ptp),
in the same run:

* durations: ``plan_ptp_jerk`` with ``synchronization="time"`` and with the default
  ``"line"`` (a straight line in joint space) against Ruckig (``Ruckig(6, 0.005)``,
  ``Trajectory``, ``InputParameter`` with zero boundary velocities and accelerations,
  default synchronisation ``Time``): the largest difference and whether every move is
  within one 5 ms tick. ``"time"`` should agree to rounding; ``"line"`` can only be
  longer (it is the fastest *straight-line* move), by how much is printed;
* planning time per move (``perf_counter_ns`` around the one call): p50 / p99, goal
  p99 <= 50 us; Ruckig's ``calculate`` (input already filled in) timed the same way.
  Twice: the moves planned one after the other (the figure held against the goal), and
  each move planned again right before its ticks are sampled ("in the tick loop":
  instruction and data caches cold from the previous move's sampling, as in the
  runtime, where a plan follows hundreds of ticks -- two to three times slower, for
  Ruckig's C++ as for our Python);
* sampling time per 5 ms tick of each planned move (positions and velocities of six
  axes): p50 / p99, goal p50 <= 2 us; Ruckig's ``Trajectory.at_time``.

The garbage collector is off while timing, as in ``RobotSystem.run``. The figures are
wall-clock percentiles on whatever else the machine runs: p99 is sensitive to load.

With ``--independent`` each axis draws its own fractions (limits less alike across the
axes: the straight line costs more time).

If Ruckig is not installed (``pip install ruckig``; a benchmark-only dependency) the
script says so and prints our figures only.

Run: .venv/bin/python benchmarks/planner.py [--moves N] [--seed S] [--independent]
"""
from __future__ import annotations

import gc
import math
import random
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.spec import load_spec  # noqa: E402
from runtime.motion.jerk import minimum_duration, plan_ptp_jerk  # noqa: E402
from runtime.motion.planner import PtpInput  # noqa: E402
from runtime.motion.planner import Result  # noqa: E402
from _stats import LOLA15, arguments, percentiles  # noqa: E402

try:
    import ruckig
except ImportError:  # pragma: no cover - depends on the environment
    ruckig = None

TICK = 0.005  # s, trajectory generator period
MODES = ("line", "time", "auto")  # "auto": the runtime's default (line when it is free)
GOAL_PLAN_P99_US = 50.0
GOAL_SAMPLE_P50_US = 2.0



def ptp_input(move, mode: str) -> PtpInput:
    start, target, v, a, j = move
    return PtpInput(start, target, v, a, max_jerk=j, synchronization=mode)


def main() -> int:
    ap = arguments(__doc__, moves=1000, seed=1)
    ap.add_argument("--independent", action="store_true",
                    help="draw the limit fractions per axis instead of per move")
    args = ap.parse_args()

    spec = load_spec(LOLA15)
    axes = spec.main_axes
    n = len(axes)
    rng = random.Random(args.seed)
    pc = time.perf_counter_ns

    if ruckig is None:
        print("ruckig is not installed (pip install ruckig): our figures only")
    else:
        otg = ruckig.Ruckig(n, TICK)
        r_inp = ruckig.InputParameter(n)
        r_traj = ruckig.Trajectory(n)
        r_inp.current_velocity = [0.0] * n
        r_inp.current_acceleration = [0.0] * n
        r_inp.target_velocity = [0.0] * n
        r_inp.target_acceleration = [0.0] * n

    gc.collect()
    gc.freeze()
    gc.disable()  # as RobotSystem.run does for a run
    overhead = []
    for _ in range(10000):
        t0 = pc()
        overhead.append(pc() - t0)

    moves = []
    for _ in range(args.moves):
        start = tuple(rng.uniform(-180.0, 180.0) for _ in range(n))
        target = tuple(rng.uniform(-180.0, 180.0) for _ in range(n))
        if args.independent:
            fv = [rng.uniform(0.05, 1.0) for _ in range(n)]
            fa = [rng.uniform(0.05, 1.0) for _ in range(n)]
            fj = [rng.uniform(0.05, 1.0) for _ in range(n)]
        else:
            fv = [rng.uniform(0.05, 1.0)] * n
            fa = [rng.uniform(0.05, 1.0)] * n
            fj = [rng.uniform(0.05, 1.0)] * n
        v = tuple(ax.max_velocity * f for ax, f in zip(axes, fv))
        a = tuple(ax.max_acceleration * f for ax, f in zip(axes, fa))
        j = tuple(ax.max_jerk * f for ax, f in zip(axes, fj))
        moves.append((start, target, v, a, j))

    def fill_ruckig(move):
        start, target, v, a, j = move
        r_inp.current_position = list(start)
        r_inp.target_position = list(target)
        r_inp.max_velocity = list(v)
        r_inp.max_acceleration = list(a)
        r_inp.max_jerk = list(j)

    # 1. planning, the moves one after the other (each call timed on its own)
    plan = {"line": [], "time": [], "auto": [], "ruckig": []}
    durations = {"line": [], "time": [], "auto": [], "ruckig": []}
    errors = 0
    for m, move in enumerate(moves):
        for mode in MODES:
            inp = ptp_input(move, mode)  # (as ruckig's input is filled outside its timing)
            t0 = pc()
            result, traj, message = plan_ptp_jerk(inp)
            plan[mode].append(pc() - t0)
            if result != Result.WORKING:
                errors += 1
                print(f"move {m} ({mode}): {result.name}: {message}", file=sys.stderr)
            durations[mode].append(traj.duration if traj else math.nan)
        if ruckig is not None:
            fill_ruckig(move)
            t0 = pc()
            r_result = otg.calculate(r_inp, r_traj)
            plan["ruckig"].append(pc() - t0)
            if r_result != ruckig.Result.Working:
                errors += 1
                print(f"move {m} (ruckig): {r_result}", file=sys.stderr)
            durations["ruckig"].append(r_traj.duration)

    # 2. sampling every 5 ms tick of each move; each move planned again just before its
    # ticks ("in the tick loop": caches cold from the previous move's sampling)
    sample = {"line": [], "time": [], "auto": [], "ruckig": []}
    plan_cold = {"line": [], "time": [], "auto": [], "ruckig": []}
    total = 0.0
    for move in moves:
        for mode in MODES:
            inp = ptp_input(move, mode)
            t0 = pc()
            result, traj, message = plan_ptp_jerk(inp)
            plan_cold[mode].append(pc() - t0)
            if result != Result.WORKING:
                continue
            if mode == "line":
                total += traj.duration
            f = traj.sample
            out = sample[mode]
            for k in range(int(math.ceil(traj.duration / TICK)) + 1):
                t = k * TICK
                t0 = pc()
                f(t)
                out.append(pc() - t0)
        if ruckig is not None:
            fill_ruckig(move)
            t0 = pc()
            otg.calculate(r_inp, r_traj)
            plan_cold["ruckig"].append(pc() - t0)
            f = r_traj.at_time
            out = sample["ruckig"]
            for k in range(int(math.ceil(r_traj.duration / TICK)) + 1):
                t = k * TICK
                t0 = pc()
                f(t)
                out.append(pc() - t0)

    line_extra = sorted(
        dl - max(minimum_duration(q - p, vi, ai, ji) for p, q, vi, ai, ji in zip(*move))
        for dl, move in zip(durations["line"], moves))
    diff_time = [x - y for x, y in zip(durations["time"], durations["ruckig"])]
    diff_line = [x - y for x, y in zip(durations["line"], durations["ruckig"])]
    diff_auto = [x - y for x, y in zip(durations["auto"], durations["ruckig"])]

    o50, o99 = percentiles(overhead)
    limits = "per-axis" if args.independent else "per-move"
    print(f"{args.moves} random {n}-axis moves, start/target in [-180, 180] deg, {spec.name} "
          f"limits (v, a, j) times {limits} fractions in [0.05, 1]; "
          f"{total:.0f} s of motion; {errors} planning errors")
    print(f"Python {sys.version.split()[0]}; ruckig "
          f"{getattr(ruckig, '__version__', 'installed') if ruckig else 'not installed'}")
    print(f"timer overhead (perf_counter_ns pair): p50 {o50:.3f} us, p99 {o99:.3f} us "
          f"(included in every figure below)")
    print()
    print("durations")
    if ruckig is not None and diff_time:
        worst_time = max(diff_time, key=abs)
        print(f"  'time' - ruckig:   largest |difference| {abs(worst_time):.3e} s; every move "
              f"within one {TICK * 1000:g} ms tick: "
              f"{'yes' if all(abs(x) <= TICK for x in diff_time) else 'NO'}")
        worst_line = max(diff_line, key=abs)
        within = sum(1 for x in diff_line if abs(x) <= TICK)
        print(f"  'line' - ruckig:   largest |difference| {abs(worst_line):.3e} s "
              f"(smallest {min(diff_line):+.3e} s); within one tick: {within} of "
              f"{len(diff_line)} moves "
              f"({'every move' if within == len(diff_line) else 'not every move'})")
        worst_auto = max(diff_auto, key=abs)
        print(f"  'auto' - ruckig:   largest |difference| {abs(worst_auto):.3e} s; every move within one tick: "
              f"{'yes' if all(abs(x) <= TICK for x in diff_auto) else 'NO'} (the runtime's default)")
    s = line_extra
    print(f"  'line' - max_i T_min,i (straight line's extra time): median {s[len(s) // 2]:.3e} s,"
          f" largest {s[-1]:.3e} s, moves above 1 us: {sum(1 for x in s if x > 1e-6)}")
    print()
    print(f"{'time per call':34s} {'p50 us':>8s} {'p99 us':>8s} {'calls':>9s}  goal")

    def row(label, ns, goal=""):
        if not ns:
            return
        p50, p99 = percentiles(ns)
        print(f"{label:34s} {p50:8.2f} {p99:8.2f} {len(ns):9d}  {goal}")

    for mode in MODES:
        p99 = percentiles(plan[mode])[1]
        row(f"plan_ptp_jerk '{mode}'", plan[mode],
            f"p99 <= {GOAL_PLAN_P99_US:g}: {'met' if p99 <= GOAL_PLAN_P99_US else 'MISSED'}")
    row("ruckig Ruckig.calculate", plan["ruckig"])
    for mode in MODES:
        row(f"  in the tick loop: '{mode}'", plan_cold[mode])
    row("  in the tick loop: ruckig", plan_cold["ruckig"])
    for mode in MODES:
        p50 = percentiles(sample[mode])[0]
        row(f"trajectory.sample '{mode}' (tick)", sample[mode],
            f"p50 <= {GOAL_SAMPLE_P50_US:g}: {'met' if p50 <= GOAL_SAMPLE_P50_US else 'MISSED'}")
    row("ruckig Trajectory.at_time (tick)", sample["ruckig"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
