"""PTP planner and trajectory sampling: time per call, and the paper's moves.

Over N random six-axis moves (limits of programs/lola15.spc, scaled by random speed_ptp
and acc_ptp in [0.05, 1]) it times, one call at a time with ``perf_counter_ns``:

  plan_ptp          once per move
  trajectory.sample every 5 ms tick of each move (positions and velocities, six axes)
  interpolator      push every 5 ms + sample every 1 ms (the first 100 moves)

Reference for speed, measured interleaved in the same run and in the same way: a bare
Python loop doing the same number of float multiplications as the code it stands for
(sample: 4 per axis in its worst phase, ``0.5 * a * t * t`` and ``a * t``; plan_ptp: 16
per axis, counted in profiles.py: minimum_duration 4, then the time-optimal profile 6 or
the given-duration profile 12). The ratio says how much the real code costs beyond
its bare arithmetic in the interpreter (branches, tuples, attribute and call overhead).

Then, for the paper's program (programs/test.irl: speed_ptp = acc_ptp = 0.1), each
move's planned duration against the analytic optimum max_i (|d_i|/v_i + v_i/a_i) (or
2 sqrt(|d_i|/a_i) for a triangular axis), computed here independently.

Run: .venv/bin/python benchmarks/ptp_planner.py [--moves N] [--seed S]
"""
from __future__ import annotations

import math
import random
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.spec import load_spec  # noqa: E402
from runtime.motion.interpolator import Interpolator  # noqa: E402
from runtime.motion.planner import PtpInput, Result, plan_ptp, scaled_limits  # noqa: E402
from _stats import LOLA15, arguments, timing_table  # noqa: E402

TICK = 0.005  # s, trajectory generator period
SERVO = 0.001  # s
MULS_PER_SAMPLE_AXIS = 4
MULS_PER_PLAN_AXIS = 16

PAPER_MOVES = [
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (45.0, 0.0, -45.0, 0.0, 0.0, 0.0),
    (-45.0, 45.0, 45.0, 0.0, 0.0, 0.0),
    (45.0, -45.0, 45.0, 0.0, 0.0, 0.0),
]


def bare_multiplications(n: int, x: float, y: float) -> float:
    """The reference: ``n`` float multiplications in a bare Python loop."""
    for _ in range(n):
        x = x * y
    return x



def analytic_optimum(start, target, v, a) -> float:
    best = 0.0
    for s, t, vi, ai in zip(start, target, v, a):
        d = abs(t - s)
        best = max(best, 2.0 * math.sqrt(d / ai) if d < vi * vi / ai else d / vi + vi / ai)
    return best


def main() -> int:
    ap = arguments(__doc__, moves=1000, seed=1)
    args = ap.parse_args()

    spec = load_spec(LOLA15)
    axes = spec.main_axes
    n_axes = len(axes)
    rng = random.Random(args.seed)
    pc = time.perf_counter_ns

    overhead = []
    for _ in range(10000):
        t0 = pc()
        overhead.append(pc() - t0)

    plan_ns, plan_ref_ns, sample_ns, sample_ref_ns = [], [], [], []
    push_ns, interp_ns = [], []
    errors = 0
    total_duration = 0.0
    muls_plan = MULS_PER_PLAN_AXIS * n_axes
    muls_sample = MULS_PER_SAMPLE_AXIS * n_axes
    for m in range(args.moves):
        start = tuple(rng.uniform(ax.min, ax.max) for ax in axes)
        target = tuple(rng.uniform(ax.min, ax.max) for ax in axes)
        v, a = scaled_limits([ax.max_velocity for ax in axes],
                             [ax.max_acceleration for ax in axes],
                             rng.uniform(0.05, 1.0), rng.uniform(0.05, 1.0))
        inp = PtpInput(start, target, v, a)
        t0 = pc()
        result, traj, message = plan_ptp(inp)
        t1 = pc()
        bare_multiplications(muls_plan, 1.0000001, 0.9999999)
        t2 = pc()
        plan_ns.append(t1 - t0)
        plan_ref_ns.append(t2 - t1)
        if result != Result.WORKING:
            errors += 1
            print(f"move {m}: {result.name}: {message}", file=sys.stderr)
            continue
        total_duration += traj.duration
        ticks = int(math.ceil(traj.duration / TICK)) + 1
        sample = traj.sample
        for k in range(ticks):
            t = k * TICK
            t0 = pc()
            sample(t)
            t1 = pc()
            bare_multiplications(muls_sample, t, 0.9999999)
            t2 = pc()
            sample_ns.append(t1 - t0)
            sample_ref_ns.append(t2 - t1)
        if m < 100:
            interp = Interpolator(start)
            for k in range(ticks + 1):
                setpoint = sample(k * TICK)
                t0 = pc()
                interp.push(k * TICK, *setpoint)
                push_ns.append(pc() - t0)
                if k:
                    for j in range(5):
                        t = (k - 1) * TICK + j * SERVO
                        t0 = pc()
                        interp.sample(t)
                        interp_ns.append(pc() - t0)

    print(f"{args.moves} random {n_axes}-axis moves ({spec.name} limits, speed_ptp and acc_ptp "
          f"in [0.05, 1]), {total_duration:.0f} s of motion, {errors} planning errors")
    table = timing_table(overhead, 34)

    def row(label, ns):
        return table(label, ns)[0]

    plan50 = row("plan_ptp", plan_ns)
    ref_plan50 = row(f"  reference: {muls_plan} multiplications", plan_ref_ns)
    sample50 = row("trajectory.sample (5 ms tick)", sample_ns)
    ref_sample50 = row(f"  reference: {muls_sample} multiplications", sample_ref_ns)
    row("interpolator.push (5 ms)", push_ns)
    row("interpolator.sample (1 ms)", interp_ns)
    print(f"ratio plan_ptp / reference (p50):          {plan50 / ref_plan50:6.2f}")
    print(f"ratio trajectory.sample / reference (p50): {sample50 / ref_sample50:6.2f}")
    print()

    v, a = scaled_limits([ax.max_velocity for ax in axes], [ax.max_acceleration for ax in axes],
                         0.1, 0.1)
    print(f"the paper's program (speed_ptp = acc_ptp = 0.1): "
          f"v = {', '.join(f'{x:g}' for x in v)} deg/s, "
          f"a = {', '.join(f'{x:g}' for x in a)} deg/s^2 (A1..A6)")
    for i in range(len(PAPER_MOVES) - 1):
        start, target = PAPER_MOVES[i], PAPER_MOVES[i + 1]
        result, traj, message = plan_ptp(PtpInput(start, target, v, a))
        if result < 0:
            print(f"move {i + 1}: {result.name}: {message}")
            continue
        optimum = analytic_optimum(start, target, v, a)
        print(f"move {i + 1}: {start} -> {target}: duration {traj.duration:.9f} s, analytic "
              f"optimum {optimum:.9f} s, difference {traj.duration - optimum:+.1e} s, "
              f"slowest axis A{traj.slowest_axis + 1}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
