"""How straight is a lin move at the servo? Deviation of the 1 ms commanded path from the line.

For random lin moves of the Lola 15 (start: random joints within the limits, away from
singularities; target: a random point 50-400 mm away with the start's orientation), the
trajectory generator's 5 ms joint setpoints (JointStream) go through the servo's
interpolator (cubic Hermite to 1 ms, as in the runtime), and every 1 ms reference is taken
back through the forward kinematics: its distance from the straight line is the deviation
the servo is asked to follow. Goal (issue 5): at most 0.01 mm at every 1 ms sample.
Reference measured in the same run: the deviation of the 5 ms setpoints themselves (exact
inverse kinematics of points on the line: rounding only).
Run: .venv/bin/python benchmarks/lin_accuracy.py [--moves N] [--seed N]
"""
from __future__ import annotations

import argparse
import math
import random
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.spec import load_spec  # noqa: E402
from runtime.motion.cartesian import CartesianInput, plan_cartesian  # noqa: E402
from runtime.motion.interpolator import Interpolator  # noqa: E402
from runtime.motion.kinematics import Kinematics  # noqa: E402

PERIOD = 0.005  # the trajectory generator's
TICK = 0.001  # the servo's


def off_line(p, a, b) -> float:
    d = [y - x for x, y in zip(a, b)]
    u = sum((pi - ai) * di for pi, ai, di in zip(p, a, d)) / sum(di * di for di in d)
    u = min(max(u, 0.0), 1.0)
    return math.dist(p, [ai + u * di for ai, di in zip(a, d)])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--speed", type=float, default=250.0, help="mm/s (the specification's default)")
    args = ap.parse_args()
    spec = load_spec(ROOT / "programs" / "lola15.spc")
    axes = spec.main_axes
    limits = ([a.max_velocity for a in axes], [a.max_acceleration for a in axes], [a.max_jerk for a in axes])
    kin = Kinematics(spec)
    rng = random.Random(args.seed)
    worst_ref = worst_set = 0.0
    planned = refused = samples = 0
    while planned < args.moves:
        q0 = tuple(rng.uniform(max(a.min, -150), min(a.max, 150)) for a in spec.main_axes)
        if min(kin.singularity_margins(q0)[1:]) < 0.2:
            continue
        x, y, z, r, p, w = kin.forward(q0)
        direction = [rng.gauss(0, 1) for _ in range(3)]
        norm = math.sqrt(sum(c * c for c in direction))
        length = rng.uniform(50, 400)
        end = tuple(c + length * d / norm for c, d in zip((x, y, z), direction))
        _, stream, _message = plan_cartesian(CartesianInput(kin, q0, end + (r, p, w), args.speed, 1000.0,
                                                             axis_limits=spec))
        if stream is None:
            refused += 1
            continue
        planned += 1
        start = (x, y, z)
        interp = Interpolator(q0, limits)  # as the servo makes them (runtime/loop/components/servo.py)
        t, k = 0.0, 0
        steps = int(math.ceil(stream.duration / PERIOD)) + 2
        for n in range(steps + 1):
            t = n * PERIOD
            positions, velocities = stream.sample(t)
            worst_set = max(worst_set, off_line(kin.forward(positions)[:3], start, end))
            interp.push(t, positions, velocities, stream.accelerations_at(t))  # as the generator writes it
            # the servo ticks until the next setpoint, sampling one setpoint period behind
            # (runtime/motion/interpolator.py): references between this setpoint and the last
            while k * TICK < t + PERIOD - 1e-12:
                reference = interp.sample(k * TICK - PERIOD)
                worst_ref = max(worst_ref, off_line(kin.forward(reference)[:3], start, end))
                samples += 1
                k += 1
    print(f"{planned} random lin moves of the {spec.name} at {args.speed:g} mm/s, 50-400 mm "
          f"({refused} drawn moves refused by the path check), {samples} references at 1 ms")
    print(f"  5 ms setpoints (exact IK of the line):         max deviation {worst_set:.3e} mm")
    print(f"  1 ms servo references (joint space):           max deviation {worst_ref:.3e} mm  "
          f"(goal <= 0.01 mm: {'met' if worst_ref <= 0.01 else 'MISSED'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
