"""Do lin and circ moves keep every joint's limits? (issue 14: the baseline and the goal)

For random Cartesian moves of the Lola 15, planned as the runtime plans them
(``plan_cartesian`` with the specification's axis limits), this prints:

* the largest ratio of any joint's velocity, acceleration and jerk to its limit, over
  - the 5 ms setpoints the trajectory generator gives the servo (velocities as sampled,
    accelerations and jerks as differences of consecutive samples),
  - the 1 ms references the servo's interpolator makes of them, as a drive sees them:
    first, second and third differences of successive references over 1 ms; with the
    setpoints as the generator writes them for lin and circ (positions, velocities and
    accelerations: the stream's central differences over +-0.1 ms), and with the same
    derivatives taken from the path afresh at every setpoint, beside the path itself
    sampled every 1 ms;
  goal: at most 1.0 everywhere;
* how much slower than the programmed speed the moves are: each move's duration against
  the same path at constant programmed speed (``length / speed``: the reference, computed
  in the same run), median and largest ratio;
* what slowing down only where the joints need it gains: each move's duration against
  the same path slowed down as a whole (the planner before it, :func:`uniform_duration`,
  computed in the same run): median, percentiles, smallest and largest ratio (goal: never
  slower, to 1 %: the planner compares the timings by their predicted ratios, the
  reference measures its own by inverse kinematics);
* planning time per move (``perf_counter_ns`` around one call, the fastest of REPEATS
  calls per move: what the code costs, without the host's stalls, which on a shared
  2-core machine reach tens of ms) for 500 mm lines: p50 and p99, goal p99 <= 20 ms (off
  the loop), against a jerk-limited PTP plan of the same start and end joints measured
  the same way in the same run;
* for comparison, PTP moves between random joints at the axes' full limits (jerk-limited,
  "auto", and trapezoidal): the same ratios of their 5 ms setpoints and of the 1 ms
  references without and with the setpoints' accelerations.

Moves: a start within the axis limits (the main axes within +-150 deg), a random direction,
50-500 mm, a random tool tilt, speeds 100-1000 mm/s, accelerations 500-5000 mm/s^2. Half
of them start with the wrist near its singularity (``|sin A5|`` between 0.05 and 0.2),
half away from every singularity. A circ passes through a via point off the chord. Moves
that the path check refuses (out of reach, through a singularity) are counted, not timed.
Deterministic for a seed.

Run: .venv/bin/python benchmarks/lin_limits.py [--moves N] [--ptp-moves N] [--seed N]
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
from runtime.motion.cartesian import (  # noqa: E402
    JOINT_LIMIT_SHARE,
    RETIMINGS,
    CartesianInput,
    _retimed,
    _scale,
    joint_limit_scale,
    plan_cartesian,
    setpoint_ratios,
)
from runtime.motion.pathcheck import MIN_SAMPLES, check_path  # noqa: E402
from runtime.motion.paths import CartesianMove  # noqa: E402
from runtime.motion.interpolator import Interpolator  # noqa: E402
from runtime.motion.jerk import plan_ptp_jerk  # noqa: E402
from runtime.motion.kinematics import Kinematics  # noqa: E402
from runtime.motion.planner import PtpInput, plan_ptp  # noqa: E402

PERIOD = 0.005  # the trajectory generator's
REPEATS = 3  # plans per move for the planning time (the fastest counts)
TICK = 0.001  # the servo's
PERIOD_TICKS = 5
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


def note_differences(ratios: Ratios, positions, dt: float, name: str) -> None:
    """The first, second and third differences of ``positions`` over ``dt`` (what a drive
    sees of references every ``dt``)."""
    values = positions
    for order in range(3):
        values = derivative(values, dt)
        for v in values:
            ratios.note(order, v, name)


def exact_derivatives(stream, t: float, e: float = 1e-4):
    """Velocities and accelerations of a lin/circ joint stream's main axes at ``t``: central
    differences of its positions over +-0.1 ms (less near the ends); zero outside the move."""
    if not 0.0 < t < stream.duration:
        zeros = (0.0,) * 6
        return zeros, zeros
    e = min(e, 0.5 * t, 0.5 * (stream.duration - t))
    before, now, after = (stream.position_at(x)[:6] for x in (t - e, t, t + e))
    return (tuple((c - a) / (2 * e) for a, c in zip(before, after)),
            tuple((a - 2 * b + c) / (e * e) for a, b, c in zip(before, now, after)))


def references(q0, setpoints, limits=None) -> list:
    """The 1 ms references of ``setpoints`` (every 5 ms: ``(t, positions, velocities[,
    accelerations])``), as the servo takes them: one setpoint period behind."""
    interp = Interpolator(tuple(q0), limits)
    out = []
    k = 0
    for setpoint in setpoints:
        interp.push(*setpoint)
        t = setpoint[0]
        while k * TICK < t + PERIOD - 1e-12:
            out.append(interp.sample(k * TICK - PERIOD))
            k += 1
    return out


def measure(stream, q0, name: str, setpoints: Ratios, plain: Ratios, exact: Ratios, path: Ratios,
            limits) -> None:
    """Sample ``stream`` as the trajectory generator and the servo do; note the ratios."""
    steps = int(math.ceil(stream.duration / PERIOD)) + 2
    velocities5, now, wired = [], [], []
    for n in range(steps + 1):
        t = n * PERIOD
        positions, velocities = stream.sample(t)
        velocities5.append(velocities)
        now.append((t, positions[:6], velocities[:6], stream.accelerations_at(t)[:6]))  # as the runtime
        v, a = exact_derivatives(stream, t)
        wired.append((t, stream.position_at(t)[:6] if 0.0 < t < stream.duration else positions[:6], v, a))
    accelerations = derivative(velocities5, PERIOD)
    for order, values in enumerate((velocities5, accelerations, derivative(accelerations, PERIOD))):
        for v in values:
            setpoints.note(order, v, name)
    note_differences(plain, references(q0, now, limits), TICK, name)
    note_differences(exact, references(q0, wired, limits), TICK, name)
    own = [stream.position_at(k * TICK)[:6] for k in range(-PERIOD_TICKS, int(stream.duration / TICK) + 2 * PERIOD_TICKS)]
    note_differences(path, own, TICK, name)


def measure_ptp(rng, spec, moves: int) -> list[tuple[str, Ratios]]:
    """Random PTP moves of the robot at its axes' full limits, jerk-limited and trapezoidal:
    the ratios of their 5 ms setpoints and of the 1 ms references without and with the
    setpoints' accelerations."""
    axes = spec.axes
    limits = ([a.max_velocity for a in axes], [a.max_acceleration for a in axes], [a.max_jerk for a in axes])
    figures = []
    for profile in ("jerk-limited", "trapezoidal"):
        setpoints, plain, exact = Ratios(limits), Ratios(limits), Ratios(limits)
        for m in range(moves):
            q0 = [rng.uniform(a.min, a.max) for a in axes]
            q1 = [rng.uniform(a.min, a.max) for a in axes] if m % 2 else [x + rng.uniform(-10, 10) for x in q0]
            if profile == "jerk-limited":
                _, trajectory, _ = plan_ptp_jerk(PtpInput(tuple(q0), tuple(q1), tuple(limits[0]), tuple(limits[1]),
                                                          max_jerk=tuple(limits[2])))
            else:
                _, trajectory, _ = plan_ptp(PtpInput(tuple(q0), tuple(q1), tuple(limits[0]), tuple(limits[1])))
            name = f"{profile} move {m + 1}"
            steps = int(math.ceil(trajectory.duration / PERIOD)) + 2
            samples = [(n * PERIOD, *trajectory.sample(n * PERIOD)) for n in range(steps + 1)]
            velocities5 = [s[2] for s in samples]
            accelerations = derivative(velocities5, PERIOD)
            for order, values in enumerate((velocities5, accelerations, derivative(accelerations, PERIOD))):
                for v in values:
                    setpoints.note(order, v, name)
            note_differences(plain, references(q0, samples), TICK, name)
            wired = [s + (trajectory.sample_accelerations(s[0]),) for s in samples]
            note_differences(exact, references(q0, wired, limits), TICK, name)
        figures.append((f"{moves} {profile} PTP moves", [("5 ms setpoints", setpoints),
                                                          ("1 ms, setpoints without accelerations", plain),
                                                          ("1 ms, with accelerations", exact)]))
    return figures


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


def uniform_duration(stream, limits) -> float:
    """The duration of the same path slowed down uniformly (the planner before the local
    slowdown, the reference): the programmed double-S profile run k times slower, k the
    one factor that keeps every joint within JOINT_LIMIT_SHARE of its limits at samples as
    fine as the setpoints, then slower again until the 1 ms setpoints keep every limit."""
    checked = stream.checked
    move = CartesianMove(checked.move.path, checked.move.speed, checked.move.acc, checked.move.jerk)
    fine = check_path(move, checked.kinematics, checked.start_joints, SPEC_AXES[0],
                      check_velocity=False, min_samples=max(MIN_SAMPLES, math.ceil(move.duration / PERIOD)))
    k = joint_limit_scale(fine, limits)
    for _ in range(RETIMINGS):
        if k < 1.0:
            move = CartesianMove(move.path, move.speed * k, move.acc * k * k, move.jerk * k ** 3)
            fine = _retimed(fine, move, k)
        ratios = setpoint_ratios(fine, limits, TICK)
        if max(ratios) <= 1.0:
            break
        k = _scale(ratios, JOINT_LIMIT_SHARE)
    return move.duration


SPEC_AXES: list = []


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=300, help="moves planned (refused ones not counted)")
    ap.add_argument("--ptp-moves", type=int, default=200, help="PTP moves of each profile for comparison")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    spec = load_spec(ROOT / "programs" / "lola15.spc")
    SPEC_AXES.append(spec)
    kin = Kinematics(spec)
    axes = spec.main_axes
    limits = ([a.max_velocity for a in axes], [a.max_acceleration for a in axes], [a.max_jerk for a in axes])
    setpoints, plain, exact, itself = Ratios(limits), Ratios(limits), Ratios(limits), Ratios(limits)
    rng = random.Random(args.seed)
    planned = refused = 0
    slowdowns: list[float] = []
    against_uniform: list[float] = []
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
        against_uniform.append(stream.duration / uniform_duration(stream, limits))
        name = f"move {planned} ({kind}, {speed:g} mm/s, {move[-1]:g} mm/s^2{', near the wrist singularity' if near_wrist else ''})"
        measure(stream, q0, name, setpoints, plain, exact, itself, limits)

    # planning time: 500 mm lines, against a jerk-limited PTP between the same joints
    lin_ns, ptp_ns = [], []
    while len(lin_ns) < 100:
        q0 = random_start(rng, kin, axes)
        if q0 is None:
            continue
        x, y, z, r, p, w = kin.forward(q0)
        direction, norm = random_direction(rng)
        end = tuple(c + 500.0 * d / norm for c, d in zip((x, y, z), direction)) + (r, p, w)
        best = None
        for _ in range(REPEATS):  # each move's fastest of REPEATS plans: the code's cost, not the host's stalls
            t0 = time.perf_counter_ns()
            _, stream, _message = plan_cartesian(CartesianInput(kin, q0, end, 250.0, 1500.0, axis_limits=spec))
            t1 = time.perf_counter_ns()
            if stream is None:
                break
            best = t1 - t0 if best is None else min(best, t1 - t0)
        if stream is None:
            continue
        lin_ns.append(best)
        target = stream.target_position
        best = None
        for _ in range(REPEATS):
            t0 = time.perf_counter_ns()
            plan_ptp_jerk(PtpInput(tuple(q0), target[:6], *limits[:2], max_jerk=limits[2]))
            elapsed = time.perf_counter_ns() - t0
            best = elapsed if best is None else min(best, elapsed)
        ptp_ns.append(best)

    print(f"{planned} random lin/circ moves of the {spec.name} ({near} starting near the wrist singularity; "
          f"{refused} drawn moves refused by the path check)")
    report([("5 ms setpoints", setpoints), ("1 ms references (the runtime's setpoints)", plain),
            ("1 ms, exact velocities and accelerations", exact), ("the path itself, every 1 ms (reference)", itself)])
    print(f"  duration against the same path at the programmed speed (reference): median "
          f"{percentile(slowdowns, 0.5):.2f}x, largest {max(slowdowns):.2f}x")
    faster = sum(1 for r in against_uniform if r < 0.99)
    print(f"  duration against the same path slowed down as a whole (the previous planner, reference): median "
          f"{percentile(against_uniform, 0.5):.3f}x, 25th percentile {percentile(against_uniform, 0.25):.3f}x, "
          f"10th {percentile(against_uniform, 0.1):.3f}x, smallest {min(against_uniform):.3f}x, largest "
          f"{max(against_uniform):.3f}x (goal: never slower, to 1 %: {'met' if max(against_uniform) <= 1.01 else 'MISSED'}); "
          f"{faster} of {len(against_uniform)} moves faster by more than 1 %")
    lin50, lin99 = percentile(lin_ns, 0.5) / 1e6, percentile(lin_ns, 0.99) / 1e6
    ptp50 = percentile(ptp_ns, 0.5) / 1e6
    print(f"  planning a 500 mm lin: p50 {lin50:.2f} ms, p99 {lin99:.2f} ms (goal p99 <= 20 ms: "
          f"{'met' if lin99 <= 20.0 else 'MISSED'}); a jerk-limited PTP between the same joints "
          f"(reference): p50 {ptp50:.3f} ms ({lin50 / ptp50:.0f}x)")
    for title, rows in measure_ptp(rng, spec, args.ptp_moves):
        print(f"{title} of the {spec.name} at the axes' full limits (for comparison)")
        report(rows, trapezoid=title.endswith("trapezoidal PTP moves"))
    return 0


def report(rows, trapezoid: bool = False) -> None:
    for title, ratios in rows:
        figures = ", ".join(f"{name} {ratios.worst[i]:.{2 if ratios.worst[i] > 2 else 6}f}"
                            for i, name in enumerate(("velocity", "acceleration", "jerk")))
        kept = ratios.worst[:2] if trapezoid else ratios.worst  # a trapezoid has no jerk limit
        met = "met" if max(kept) <= 1.0 + 1e-6 else "MISSED"
        print(f"  {title:42s} largest ratio to the joint limits: {figures}  (goal <= 1.0{' but the jerk' if trapezoid else ''}: {met})")
        for i, name in enumerate(("velocity", "acceleration", "jerk")):
            print(f"      {name:12s} at {ratios.where[i]}")


if __name__ == "__main__":
    sys.exit(main())
