"""Blending (``approx``): do blended corners keep every limit, and what do they save?

Random programs on the Lola 15 (simulated clock, the whole runtime in process): each is a
tour of 4-6 moves (ptp between random joint targets; or lin/circ tours in a horizontal
plane in front of the robot with a ptp in between), run twice: with ``approx`` on every
move but the last, and without (every corner an exact stop: the reference, same run).
The trajectory generator's 5 ms setpoints are captured; their first, second and third
differences are compared with each axis's max_velocity, max_acceleration and max_jerk.

Figures (issue 5): the largest ratio of any sample of a blended stream to its limit
(goal: <= 1.0; for the Cartesian tours only the samples inside blends count, as a lin
move's own joint accelerations are bounded by its path limits, not by the axis limits);
the share of corners that blended; the Move Robot time with blending against without; the
time the blend check takes per corner (it runs off the loop on the wall clock).
Run: .venv/bin/python benchmarks/blending.py [--programs N] [--seed N]
"""
from __future__ import annotations

import argparse
import random
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.driver import compile_source  # noqa: E402
from compiler.spec import load_spec  # noqa: E402
from runtime.loop.component import DataPort  # noqa: E402
from runtime.motion import blend as blend_module  # noqa: E402
from runtime.loop.system import RobotSystem, RunOptions  # noqa: E402
from runtime.loop.components import trajectory as tg_module  # noqa: E402

SPEC = ROOT / "programs" / "lola15.spc"
PERIOD = 0.005
BOX = ((-90, 90), (-40, 40), (-30, 60), (-90, 90), (-20, 90), (-90, 90))


class _Spy(DataPort):
    __slots__ = ("rows", "windows", "tg")

    def write(self, value, stamp=0.0):
        DataPort.write(self, value, stamp)
        tg = self.tg
        if tg.vm is not None:
            segs = tg.motion._segments
            blending = len(segs) > 1 and segs[1].start is not None and tg.motion.t_move > segs[1].start
            self.rows.append(value[1])
            self.windows.append(blending)


def ptp_program(rng: random.Random, approx: bool) -> str:
    lines = []
    n = rng.randint(4, 6)
    for i in range(n):
        target = ", ".join(f"{rng.uniform(lo, hi):.2f}" for lo, hi in BOX)
        clause = f" speed_ptp := {rng.uniform(0.3, 1):.2f} acc_ptp := {rng.uniform(0.3, 1):.2f}"
        fraction = rng.uniform(0.3, 1)  # drawn either way: both runs get the same tour
        if approx and i < n - 1:
            clause += f" approx := {fraction:.2f}"
        lines.append(f"  move ptp joint(mainjoint({target})){clause};")
    return "\n".join(lines)


def cartesian_program(rng: random.Random, approx: bool) -> str:
    z = rng.uniform(400, 800)
    pts = [(rng.uniform(800, 1200), rng.uniform(-300, 300)) for _ in range(5)]
    tool = "rpy(180, 0, 180)"
    speed = rng.uniform(100, 400)
    distance = rng.uniform(10, 40)  # drawn either way: both runs get the same tour
    a = f" approx := {distance:.1f}" if approx else ""
    lines = [f"  move ptp pose(pos({pts[0][0]:.1f}, {pts[0][1]:.1f}, {z:.1f}), {tool})"
             + (" approx := 1" if approx else "") + ";"]
    for i, (x, y) in enumerate(pts[1:], 1):
        if i == 3:
            vx, vy = (x + pts[i - 1][0]) / 2 + 60, (y + pts[i - 1][1]) / 2 + 60
            lines.append(f"  move circ pose(pos({vx:.1f}, {vy:.1f}, {z:.1f}), {tool}), "
                         f"pose(pos({x:.1f}, {y:.1f}, {z:.1f}), {tool}) speed := {speed:.0f}{a};")
        else:
            lines.append(f"  move lin pose(pos({x:.1f}, {y:.1f}, {z:.1f}), {tool}) speed := {speed:.0f}{a};")
    lines.append("  move ptp joint(mainjoint(0, -30, 30, 0, 60, 0));")
    return "\n".join(lines)


def run(system: RobotSystem, body: str, name: str):
    source = f'program {name};\nsystem_specification "lola15.spc";\nseq\n{body}\nendseq\nendprogram;\n'
    result = compile_source(source, f"{name}.irl", SPEC)
    if not result.ok:
        return None
    tg = system.trajectory
    spy = _Spy("desi_pos")
    spy.rows, spy.windows, spy.tg = [], [], tg
    old = tg.desi_pos
    tg.desi_pos = system.servo.desi_pos = spy
    try:
        summary = system.run(result.program)
    finally:
        tg.desi_pos = system.servo.desi_pos = old
    move = [s for s in summary["states"] if s["name"] == "Move Robot"]
    return summary, np.asarray(spy.rows), np.asarray(spy.windows), move[0]["t_exit"] - move[0]["t_enter"]


def ratios(q: np.ndarray, mask: np.ndarray | None, limits) -> list[float]:
    out, d = [], q
    for k, lim in enumerate(limits, start=1):
        d = np.diff(d, axis=0)
        r = np.abs(d) / PERIOD ** k / lim
        if mask is not None:  # a difference counts if any of its samples is in a blend
            m = np.zeros(len(r), dtype=bool)
            for j in range(k + 1):
                m |= mask[j:len(mask) - k + j]
            r = r[m]
        out.append(float(r.max()) if r.size else 0.0)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--programs", type=int, default=20, help="random programs per kind (default 20)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rng = random.Random(args.seed)
    system = RobotSystem(load_spec(SPEC), RunOptions(seed=args.seed))
    limits = [np.array([getattr(a, k) for a in system.spec.axes], dtype=float)
              for k in ("max_velocity", "max_acceleration", "max_jerk")]

    check_ns = []
    real = blend_module.blend_offset

    def timed(*a, **k):
        t0 = time.perf_counter_ns()
        try:
            return real(*a, **k)
        finally:
            check_ns.append(time.perf_counter_ns() - t0)

    tg_module.blend_offset = timed
    print(f"{'kind':10s} {'progs':>5s} {'corners':>8s} {'blended':>8s} {'max v':>7s} {'max a':>7s} "
          f"{'max j':>7s} {'time':>7s} {'exact':>7s} {'ratio':>6s}")
    worst = 0.0
    for kind, make in (("ptp", ptp_program), ("lin/circ", cartesian_program)):
        corners = blended = done = 0
        t_blend = t_exact = 0.0
        worst_kind = [0.0, 0.0, 0.0]
        for i in range(args.programs):
            seed = rng.random()
            with_approx = run(system, make(random.Random(seed), True), f"b{i}")
            without = run(system, make(random.Random(seed), False), f"e{i}")
            if with_approx is None or without is None:
                continue
            summary, q, windows, t1 = with_approx
            summary0, _q0, _w0, t0 = without
            if summary["fault"] or summary0["fault"]:
                continue
            done += 1
            corners += len(summary["moves"]) - 1
            blended += sum(1 for m in summary["moves"] if m["blended"])
            t_blend, t_exact = t_blend + t1, t_exact + t0
            r = ratios(q, None if kind == "ptp" else windows, limits)
            worst_kind = [max(a, b) for a, b in zip(worst_kind, r)]
        worst = max(worst, *worst_kind)
        print(f"{kind:10s} {done:5d} {corners:8d} {blended:8d} {worst_kind[0]:7.4f} {worst_kind[1]:7.4f} "
              f"{worst_kind[2]:7.4f} {t_blend:6.2f}s {t_exact:6.2f}s {t_blend / max(t_exact, 1e-9):6.3f}")
    check_ns.sort()
    if check_ns:
        print(f"blend check per corner: p50 {check_ns[len(check_ns) // 2] / 1e6:.2f} ms, "
              f"max {check_ns[-1] / 1e6:.2f} ms ({len(check_ns)} corners; off the loop on the wall clock)")
    print(f"largest ratio of a blended sample to its limit: {worst:.6f} (goal <= 1.0: "
          f"{'met' if worst <= 1.0 + 1e-6 else 'NOT met'})")
    return 0 if worst <= 1.0 + 1e-6 else 1


if __name__ == "__main__":
    sys.exit(main())
