"""Do lin and circ moves keep every joint's limits? (issue 14: the baseline and the goal)

For random Cartesian moves of the Lola 15, planned as the runtime plans them
(``plan_cartesian`` with the specification's axis limits), this prints:

* the largest ratio of any joint's velocity, acceleration and jerk to its limit, over
  - the 5 ms setpoints the trajectory generator gives the servo (velocities as sampled,
    accelerations and jerks as differences of consecutive samples), and
  - the 1 ms references the servo's interpolator makes of them (the velocity it feeds
    forward, its differences);
  goal: at most 1.0 everywhere;
* how much slower than the programmed speed the moves are: each move's duration against
  the same path at constant programmed speed (``length / speed``: the reference, computed
  in the same run), median and largest ratio;
* planning time per move (``perf_counter_ns`` around one call) for 500 mm lines: p50 and
  p99, goal p99 <= 20 ms (off the loop), against a jerk-limited PTP plan of the same
  start and end joints measured in the same run.

Moves: a start within the axis limits (the main axes within +-150 deg), a random direction,
50-500 mm, a random tool tilt, speeds 100-1000 mm/s, accelerations 500-5000 mm/s^2. Half
of them start with the wrist near its singularity (``|sin A5|`` between 0.05 and 0.2),
half away from every singularity. A circ passes through a via point off the chord. Moves
that the path check refuses (out of reach, through a singularity) are counted, not timed.
Deterministic for a seed.

Run: .venv/bin/python benchmarks/lin_limits.py [--moves N] [--seed N]
"""
from __future__ import annotations

import argparse
import math
import random
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from _stats import percentile  # noqa: E402

from compiler.spec import load_spec  # noqa: E402
from runtime.motion.cartesian import CartesianInput, plan_cartesian  # noqa: E402
from runtime.motion.interpolator import Interpolator  # noqa: E402
from runtime.motion.jerk import plan_ptp_jerk  # noqa: E402
from runtime.motion.kinematics import Kinematics  # noqa: E402
from runtime.motion.planner import PtpInput  # noqa: E402

PERIOD = 0.005  # the trajectory generator's
TICK = 0.001  # the servo's
SPEEDS = (100.0, 250.0, 500.0, 1000.0)
ACCELERATIONS = (500.0, 1500.0, 5000.0)


class Ratios:
    """The largest ratio of each derivative to its limit, and where it was."""

    def __init__(self, limits):
        self.limits = limits  # (velocity, acceleration, jerk) per axis
        self.worst = [0.0, 0.0, 0.0]
        self.where = [None, None, None]

    def note(self, order: int, values, move: str) -> None:
        for i, value in enumerate(values):
            ratio = abs(value) / self.limits[order][i]
            if ratio > self.worst[order]:
                self.worst[order], self.where[order] = ratio, (move, f"A{i + 1}")


def derivative(samples, dt: float):
    return [tuple((b - a) / dt for a, b in zip(p, q)) for p, q in zip(samples, samples[1:])]


def measure(stream, q0, name: str, setpoints: Ratios, references: Ratios) -> None:
    """Sample ``stream`` as the trajectory generator and the servo do; note the ratios."""
    steps = int(math.ceil(stream.duration / PERIOD)) + 2
    interp = Interpolator(tuple(q0))
    velocities5, velocities1 = [], []
    k = 0
    for n in range(steps + 1):
        t = n * PERIOD
        positions, velocities = stream.sample(t)
        velocities5.append(velocities)
        interp.push(t, positions, velocities)
        while k * TICK < t + PERIOD - 1e-12:  # the servo samples one setpoint period behind
            velocities1.append(interp.sample_velocity(k * TICK - PERIOD))
            k += 1
    for ratios, series, dt in ((setpoints, velocities5, PERIOD), (references, velocities1, TICK)):
        accelerations = derivative(series, dt)
        for order, values in enumerate((series, accelerations, derivative(accelerations, dt))):
            for v in values:
                ratios.note(order, v, name)


def random_start(rng, kin, axes, near_wrist: bool = False):
    """Random start joints within the limits (the main axes within +-150 deg), away from
    the shoulder and elbow singularities, the wrist near its own (``near_wrist``) or away
    from it; None if the draw is unusable."""
    q0 = [rng.uniform(max(a.min, -150), min(a.max, 150)) for a in axes]
    if near_wrist:
        q0[4] = math.degrees(math.asin(rng.uniform(0.05, 0.2))) * rng.choice((-1, 1))
        if not axes[4].min < q0[4] < axes[4].max:
            return None
    margins = kin.singularity_margins(q0)
    if margins[0] < 50.0 or margins[1] < 0.2 or (not near_wrist and margins[2] < 0.2):
        return None
    return q0


def random_direction(rng) -> tuple[list[float], float]:
    """A random direction (not normalised) and its length."""
    direction = [rng.gauss(0, 1) for _ in range(3)]
    return direction, math.sqrt(sum(c * c for c in direction))


def random_move(rng, kin, spec, near_wrist: bool):
    """(start joints, kind, arguments) of a random move, or None if the draw is unusable."""
    q0 = random_start(rng, kin, spec.main_axes, near_wrist)
    if q0 is None:
        return None
    x, y, z, r, p, w = kin.forward(q0)
    direction, norm = random_direction(rng)
    length = rng.uniform(50, 500)
    tilt = (r + rng.uniform(-20, 20), p + rng.uniform(-20, 20), w + rng.uniform(-20, 20))
    end = tuple(c + length * d / norm for c, d in zip((x, y, z), direction)) + tilt
    speed, acc = rng.choice(SPEEDS), rng.choice(ACCELERATIONS)
    if rng.random() < 0.5:
        return q0, "lin", (end, speed, acc)
    # circ: the via point off the middle of the chord, perpendicular to it
    other = [rng.gauss(0, 1) for _ in range(3)]
    d = [c / norm for c in direction]
    dot = sum(a * b for a, b in zip(other, d))
    perpendicular = [a - dot * b for a, b in zip(other, d)]
    pn = math.sqrt(sum(c * c for c in perpendicular)) or 1.0
    sagitta = length * rng.uniform(0.1, 0.5)
    via = tuple(c + 0.5 * length * dd + sagitta * pc / pn for c, dd, pc in zip((x, y, z), d, perpendicular))
    return q0, "circ", (via + tilt, end, speed, acc)


def plan(kin, spec, q0, kind, args):
    if kind == "lin":
        end, speed, acc = args
        return plan_cartesian(CartesianInput(kin, q0, end, speed, acc, axis_limits=spec))[1:]
    via, end, speed, acc = args
    return plan_cartesian(CartesianInput(kin, q0, end, speed, acc, via=via, axis_limits=spec))[1:]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=300, help="moves planned (refused ones not counted)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    spec = load_spec(ROOT / "programs" / "lola15.spc")
    kin = Kinematics(spec)
    axes = spec.main_axes
    limits = ([a.max_velocity for a in axes], [a.max_acceleration for a in axes], [a.max_jerk for a in axes])
    setpoints, references = Ratios(limits), Ratios(limits)
    rng = random.Random(args.seed)
    planned = refused = 0
    slowdowns: list[float] = []
    near = 0
    while planned < args.moves:
        near_wrist = planned % 2 == 0
        drawn = random_move(rng, kin, spec, near_wrist)
        if drawn is None:
            continue
        q0, kind, move = drawn
        stream, _message = plan(kin, spec, q0, kind, move)
        if stream is None:
            refused += 1
            continue
        planned += 1
        near += near_wrist
        speed = move[-2]
        path = stream.checked.move.path
        slowdowns.append(stream.duration / (path.length / speed))
        name = f"move {planned} ({kind}, {speed:g} mm/s, {move[-1]:g} mm/s^2{', near the wrist singularity' if near_wrist else ''})"
        measure(stream, q0, name, setpoints, references)

    # planning time: 500 mm lines, against a jerk-limited PTP between the same joints
    lin_ns, ptp_ns = [], []
    while len(lin_ns) < 100:
        q0 = random_start(rng, kin, axes)
        if q0 is None:
            continue
        x, y, z, r, p, w = kin.forward(q0)
        direction, norm = random_direction(rng)
        end = tuple(c + 500.0 * d / norm for c, d in zip((x, y, z), direction)) + (r, p, w)
        t0 = time.perf_counter_ns()
        _, stream, _message = plan_cartesian(CartesianInput(kin, q0, end, 250.0, 1500.0, axis_limits=spec))
        t1 = time.perf_counter_ns()
        if stream is None:
            continue
        lin_ns.append(t1 - t0)
        target = stream.target_position
        t0 = time.perf_counter_ns()
        plan_ptp_jerk(PtpInput(tuple(q0), target[:6], *limits[:2], max_jerk=limits[2]))
        ptp_ns.append(time.perf_counter_ns() - t0)

    print(f"{planned} random lin/circ moves of the {spec.name} ({near} starting near the wrist singularity; "
          f"{refused} drawn moves refused by the path check)")
    for title, ratios in (("5 ms setpoints", setpoints), ("1 ms references", references)):
        figures = ", ".join(f"{name} {ratios.worst[i]:.2f}" for i, name in enumerate(("velocity", "acceleration",
                                                                                      "jerk")))
        met = "met" if max(ratios.worst) <= 1.0 + 1e-6 else "MISSED"
        print(f"  {title:16s} largest ratio to the joint limits: {figures}  (goal <= 1.0: {met})")
        for i, name in enumerate(("velocity", "acceleration", "jerk")):
            print(f"      {name:12s} at {ratios.where[i]}")
    print(f"  duration against the same path at the programmed speed (reference): median "
          f"{percentile(slowdowns, 0.5):.2f}x, largest {max(slowdowns):.2f}x")
    lin50, lin99 = percentile(lin_ns, 0.5) / 1e6, percentile(lin_ns, 0.99) / 1e6
    ptp50 = percentile(ptp_ns, 0.5) / 1e6
    print(f"  planning a 500 mm lin: p50 {lin50:.2f} ms, p99 {lin99:.2f} ms (goal p99 <= 20 ms: "
          f"{'met' if lin99 <= 20.0 else 'MISSED'}); a jerk-limited PTP between the same joints "
          f"(reference): p50 {ptp50:.3f} ms ({lin50 / ptp50:.0f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
