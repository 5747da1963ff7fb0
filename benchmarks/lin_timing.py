"""How close to the time optimum are lin and circ moves? (issue 32)

For random Cartesian moves of the Lola 15, planned as the runtime plans them
(``plan_cartesian`` with the specification's axis limits), each move's planned duration
is compared, on the same joint path (the check's joint samples along the path, a cubic
spline through them), with

* **TOPP-RA** (``toppra``, the time-optimal path parameterisation by reachability
  analysis): every joint's velocity and acceleration limit (100 % of them), the
  programmed speed and acceleration along the path (a seventh "joint", the path
  parameter itself, limited to them); TOPP-RA knows no jerk limit;
* **the jerk-aware bound**: the largest of TOPP-RA's time, the programmed jerk-limited
  profile alone (speed, acc and jerk over the path's length, no joint limit) and each
  joint's rest-to-rest jerk-limited time over its net travel (ruckig, at 100 % of its
  limits). No jerk-limited timing of the path can be shorter than any of them.

Printed per kind of move (short lines, long lines, lines near the wrist singularity,
circs) and over all of them: the median, p90 and worst ratio to TOPP-RA, and the same to
the jerk-aware bound (goals: median to TOPP-RA <= 1.15, worst to the bound <= 1.25); then
the planning time of 500 mm lines (the fastest of 3 plans per move, p50/p99; goal p99
<= 20 ms) and, for reference in the same run, TOPP-RA's own time on the same paths.

Moves: a start within the axis limits (the main axes within +-150 deg) away from the
shoulder and elbow singularities, a random direction and tool tilt, speeds 100-1000
mm/s, accelerations 1000-10000 mm/s^2 (fast: the joints bind for much of the path);
"short" 10-80 mm, "long" 300-800 mm, "wrist" 50-400 mm starting with |sin A5| between
0.05 and 0.2, "circ" 50-500 mm through a via point off the chord. Moves the path check
refuses are counted, not timed. Deterministic for a seed.

Run: .venv/bin/python benchmarks/lin_timing.py [--moves N] [--seed N] [--show N]
(needs ``toppra`` and ``ruckig``: pip install -e '.[bench]')
"""
from __future__ import annotations

import argparse
import math
import random
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from _stats import percentile  # noqa: E402

from compiler.spec import load_spec  # noqa: E402
from runtime.motion.cartesian import CartesianInput, plan_cartesian  # noqa: E402
from runtime.motion.kinematics import Kinematics  # noqa: E402
from runtime.motion.paths import DEFAULT_JERK_FACTOR  # noqa: E402
from runtime.motion.pathtiming import nominal_profile  # noqa: E402

KINDS = ("short", "long", "wrist", "circ")
SPEEDS = (100.0, 250.0, 500.0, 1000.0)
ACCELERATIONS = (500.0, 1500.0, 5000.0)
LENGTHS = {"short": (10.0, 80.0), "long": (300.0, 800.0), "wrist": (50.0, 400.0), "circ": (50.0, 500.0)}
REPEATS = 3


def random_start(rng, kin, axes, near_wrist: bool):
    q0 = [rng.uniform(max(a.min, -150), min(a.max, 150)) for a in axes]
    if near_wrist:
        q0[4] = math.degrees(math.asin(rng.uniform(0.05, 0.2))) * rng.choice((-1, 1))
    margins = kin.singularity_margins(q0)
    if margins[0] < 50.0 or margins[1] < 0.2 or (not near_wrist and margins[2] < 0.2):
        return None
    return q0


def random_move(rng, kin, spec, kind: str):
    """(start joints, CartesianInput) of a random move of ``kind``, or None."""
    q0 = random_start(rng, kin, spec.main_axes, kind == "wrist")
    if q0 is None:
        return None
    x, y, z, r, p, w = kin.forward(q0)
    d = [rng.gauss(0, 1) for _ in range(3)]
    norm = math.sqrt(sum(c * c for c in d))
    d = [c / norm for c in d]
    length = rng.uniform(*LENGTHS[kind])
    tilt = (r + rng.uniform(-20, 20), p + rng.uniform(-20, 20), w + rng.uniform(-20, 20))
    end = tuple(c + length * dc for c, dc in zip((x, y, z), d)) + tilt
    speed, acc = rng.choice(SPEEDS), rng.choice(ACCELERATIONS)
    via = None
    if kind == "circ":
        other = [rng.gauss(0, 1) for _ in range(3)]
        dot = sum(a * b for a, b in zip(other, d))
        perp = [a - dot * b for a, b in zip(other, d)]
        pn = math.sqrt(sum(c * c for c in perp)) or 1.0
        sagitta = length * rng.uniform(0.1, 0.5)
        via = tuple(c + 0.5 * length * dc + sagitta * pc / pn for c, dc, pc in zip((x, y, z), d, perp)) + tilt
    return q0, CartesianInput(kin, q0, end, speed, acc, via=via, axis_limits=spec)


def toppra_time(s: np.ndarray, joints: np.ndarray, vmax, amax, speed: float, acc: float) -> float:
    """TOPP-RA's time over the joint path (a cubic spline through ``joints`` at ``s``)
    within the joints' velocity and acceleration limits and the path's speed and acc."""
    import toppra
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    toppra.setup_logging("ERROR")
    length = float(s[-1])
    u = s / length  # (the path on 0..1: TOPP-RA's solver is better conditioned so)
    way = np.hstack([joints, u[:, None]])  # (the path parameter: a seventh joint)
    path = toppra.SplineInterpolator(u, way)
    v = np.array(list(vmax) + [speed / length], dtype=float)
    a = np.array(list(amax) + [acc / length], dtype=float)
    constraints = [constraint.JointVelocityConstraint(np.vstack([-v, v]).T),
                   constraint.JointAccelerationConstraint(np.vstack([-a, a]).T)]
    for points in (len(s), 2 * len(s), len(s) // 2):  # (a grid it cannot solve on: another)
        grid = np.linspace(0.0, 1.0, min(max(points, 100), 2000))
        instance = algo.TOPPRA(constraints, path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
        trajectory = instance.compute_trajectory(0.0, 0.0)
        if trajectory is not None:
            return float(trajectory.duration)
    return math.nan


def ruckig_time(q0, q1, v: float, a: float, j: float) -> float:
    """One joint's rest-to-rest jerk-limited time over ``q1 - q0``."""
    from ruckig import InputParameter, Result, Ruckig, Trajectory

    otg = Ruckig(1)
    inp = InputParameter(1)
    inp.current_position, inp.target_position = [q0], [q1]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v], [a], [j]
    out = Trajectory(1)
    if otg.calculate(inp, out) not in (Result.Working, Result.Finished):
        return 0.0
    return out.duration


def stats(values) -> str:
    values = sorted(values)
    if not values:
        return "-"
    return f"median {percentile(values, 0.5):.3f}, p90 {percentile(values, 0.9):.3f}, worst {values[-1]:.3f}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=20, help="moves of each kind (refused ones not counted)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--show", type=int, default=5, help="the worst moves to list")
    args = ap.parse_args()
    spec = load_spec(ROOT / "programs" / "lola15.spc")
    kin = Kinematics(spec)
    axes = spec.main_axes
    vmax = [a.max_velocity for a in axes]
    amax = [a.max_acceleration for a in axes]
    jmax = [a.max_jerk for a in axes]
    rng = random.Random(args.seed)
    rows = []  # (kind, ours, toppra, bound, description)
    refused = unsolved = 0
    for kind in KINDS:
        done = 0
        while done < args.moves:
            drawn = random_move(rng, kin, spec, kind)
            if drawn is None:
                continue
            q0, inp = drawn
            _result, stream, _message = plan_cartesian(inp)
            if stream is None:
                refused += 1
                continue
            done += 1
            checked = stream.checked
            move = checked.move
            s = np.asarray(checked.fractions, dtype=float) * move.path.length
            joints = np.asarray(checked.joints, dtype=float)
            optimum = toppra_time(s, joints, vmax, amax, inp.speed, inp.acc)
            if math.isnan(optimum):
                unsolved += 1
                continue
            jerk = DEFAULT_JERK_FACTOR * inp.acc if inp.jerk is None else inp.jerk  # (the programmed one)
            programmed = nominal_profile(move.path.length, inp.speed, inp.acc, jerk).duration
            travel = max(ruckig_time(a, b, v, acc, j) for a, b, v, acc, j
                         in zip(joints[0], joints[-1], vmax, amax, jmax))
            bound = max(optimum, programmed, travel)
            rows.append((kind, stream.duration, optimum, bound,
                         f"{kind} {move.path.length:.0f} mm at {inp.speed:g} mm/s, {inp.acc:g} mm/s^2, "
                         f"A5 {q0[4]:+.1f} deg"))
    print(f"{len(rows)} random lin/circ moves of the {spec.name} ({refused} drawn moves refused by the path check, {unsolved} that TOPP-RA could not solve), "
          f"planned as irl plans them, against TOPP-RA (100 % of the joint limits) on the same joint path")
    for kind in KINDS + ("all",):
        mine = [r for r in rows if kind in ("all", r[0])]
        print(f"  {kind:>5} ({len(mine)}): to TOPP-RA {stats([r[1] / r[2] for r in mine])}; "
              f"to the jerk-aware bound {stats([r[1] / r[3] for r in mine])}")
    print(f"  the worst {args.show} to the jerk-aware bound:")
    for kind, ours, optimum, bound, what in sorted(rows, key=lambda r: -r[1] / r[3])[:args.show]:
        print(f"    {ours / bound:.3f} x the bound ({ours:.3f} s; TOPP-RA {optimum:.3f} s, bound {bound:.3f} s): {what}")

    # planning time: 500 mm lines
    ours_ns, toppra_ns = [], []
    while len(ours_ns) < 50:
        q0 = random_start(rng, kin, axes, False)
        if q0 is None:
            continue
        x, y, z, r, p, w = kin.forward(q0)
        d = [rng.gauss(0, 1) for _ in range(3)]
        norm = math.sqrt(sum(c * c for c in d))
        end = tuple(c + 500.0 * dc / norm for c, dc in zip((x, y, z), d)) + (r, p, w)
        inp = CartesianInput(kin, q0, end, 250.0, 1500.0, axis_limits=spec)
        best = None
        for _ in range(REPEATS):
            t0 = time.perf_counter_ns()
            _, stream, _message = plan_cartesian(inp)
            elapsed = time.perf_counter_ns() - t0
            best = elapsed if best is None else min(best, elapsed)
        if stream is None:
            continue
        ours_ns.append(best)
        checked = stream.checked
        s = np.asarray(checked.fractions, dtype=float) * checked.move.path.length
        t0 = time.perf_counter_ns()
        toppra_time(s, np.asarray(checked.joints, dtype=float), vmax, amax, 250.0, 1500.0)
        toppra_ns.append(time.perf_counter_ns() - t0)
    ours_ns.sort()
    toppra_ns.sort()
    print(f"planning a 500 mm lin (the fastest of {REPEATS}, {len(ours_ns)} lines): p50 "
          f"{percentile(ours_ns, 0.5) / 1e6:.1f} ms, p99 {percentile(ours_ns, 0.99) / 1e6:.1f} ms "
          f"(goal p99 <= 20 ms); TOPP-RA alone on the same joint paths: p50 {percentile(toppra_ns, 0.5) / 1e6:.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
