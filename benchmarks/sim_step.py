"""Per-tick cost of the simulated robot: SimRobot.step + read + AlphaBeta.update for the
Lola 15's 6 axes, i.e. the sense/estimate/act work of one 1 ms tick, counts converted to
positions as the Robot Interface does.

Two figures, both measured in the same run:

  per tick:  each tick timed with perf_counter_ns: median and p99 in microseconds (the
             timer's own cost, measured on an empty body, is shown beside it)
  ratio:     total time of the tick loop / total time of a bare Python loop of the same
             iteration count (the same loop skeleton, fetching the command, no work)

Run: .venv/bin/python benchmarks/sim_step.py [--ticks N]
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.spec import load_spec  # noqa: E402
from runtime.hardware.sim import AlphaBeta, SimRobot  # noqa: E402
from _stats import percentile  # noqa: E402

DT = 0.001


def setup():
    spec = load_spec(ROOT / "programs" / "lola15.spc")
    robot = SimRobot(spec, seed=1)
    robot.release_brakes()
    n = robot.n_axes
    for _ in range(60):
        robot.step(DT, (0.0,) * n)
    # a slow sine on every axis (amplitude 20 deg): the axes stay clear of their stops,
    # the encoders count and index pulses come and go
    commands = [tuple(20.0 * 2 * math.pi * 0.5 * math.cos(2 * math.pi * 0.5 * k * DT + i) for i in range(n))
                for k in range(2000)]
    estimator = AlphaBeta(n, DT)
    inverse_cpu = tuple(1.0 / a.counts_per_unit for a in spec.axes)
    estimator.reset((0.0,) * n)
    return robot, estimator, commands, inverse_cpu


def tick_loop(robot, estimator, commands, inverse_cpu, ticks: int) -> float:
    step, read, update = robot.step, robot.read, estimator.update
    m = len(commands)
    r = range(len(inverse_cpu))
    t0 = time.perf_counter()
    for k in range(ticks):
        step(DT, commands[k % m])
        counts = read()[0]
        update([counts[i] * inverse_cpu[i] for i in r])
    return time.perf_counter() - t0


def bare_loop(commands, ticks: int) -> float:
    m = len(commands)
    t0 = time.perf_counter()
    for k in range(ticks):
        commands[k % m]
    return time.perf_counter() - t0


def timed_ticks(robot, estimator, commands, inverse_cpu, ticks: int) -> tuple[list[int], list[int]]:
    step, read, update = robot.step, robot.read, estimator.update
    clock = time.perf_counter_ns
    m = len(commands)
    r = range(len(inverse_cpu))
    work = [0] * ticks
    empty = [0] * ticks
    for k in range(ticks):
        t0 = clock()
        step(DT, commands[k % m])
        counts = read()[0]
        update([counts[i] * inverse_cpu[i] for i in r])
        t1 = clock()
        commands[k % m]
        t2 = clock()
        work[k] = t1 - t0
        empty[k] = t2 - t1
    return work, empty



def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=100_000)
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds for the ratio")
    args = parser.parse_args()

    robot, estimator, commands, inverse_cpu = setup()
    work, empty = timed_ticks(robot, estimator, commands, inverse_cpu, args.ticks)
    ticks_s, bare_s = [], []
    for _ in range(args.rounds):
        ticks_s.append(tick_loop(robot, estimator, commands, inverse_cpu, args.ticks))
        bare_s.append(bare_loop(commands, args.ticks))
    tick_total, bare_total = statistics.median(ticks_s), statistics.median(bare_s)

    print(f"6 axes, {args.ticks} ticks of {DT * 1000:g} ms (step + read + counts->positions + AlphaBeta.update)")
    print(f"  per tick: median {statistics.median(work) / 1000:.2f} us, p99 {percentile(work, 0.99) / 1000:.2f} us,"
          f" max {max(work) / 1000:.1f} us   (timer on an empty body: median {statistics.median(empty) / 1000:.2f} us)")
    print(f"  loop totals (median of {args.rounds}): ticks {tick_total * 1e6 / args.ticks:.2f} us/tick,"
          f" bare loop {bare_total * 1e9 / args.ticks:.1f} ns/iteration, ratio {tick_total / bare_total:.0f}x")
    print(f"  share of the 1 ms tick: {tick_total / args.ticks / DT * 100:.1f} %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
