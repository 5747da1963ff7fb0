"""`irl check` (the motion check) against `irl run` of the same program, on every shipped program.

Both are whole commands, run as fresh processes, in pairs in the same run: `irl check P.irl`
and `irl run P.irl` (each with `--cell-scenario P.cell.toml` where the program has one).
The figures per program are the medians of the pairs' ratios, of the wall time and of the
processes' CPU time (goal, issue 29: <= 0.5, the check at most half the wall time of the
run; the CPU time is the steadier figure on a shared machine); the summary gives the worst
and the median ratio,
and checks that the cycle time the check prints is the run's time in Move Robot (within a
5 ms tick per move: the run of a program without a scenario waits for its inputs, which the
check assumes come at once, so there the two differ by the waits; those are marked).
Lark's tables and Python's bytecode come from their caches (a first, unmeasured run of
each command writes them).
Run: .venv/bin/python benchmarks/check_vs_run.py [--runs N] [--only NAME]
"""
from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from _stats import arguments  # noqa: E402

IRL = Path(sys.executable).with_name("irl")
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def timed(cmd: list[str]) -> tuple[float, float, str]:
    """(wall seconds, CPU seconds of the process, its output)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=ENV)
    elapsed = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({done.returncode}): {done.stderr[-800:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return elapsed, cpu, done.stdout


def programs(only: str | None) -> list[Path]:
    found = sorted((ROOT / "programs").glob("*.irl")) + sorted((ROOT / "programs" / "robots").glob("*.irl"))
    # cycle_control polls its inputs for ever without a cell: irl run would take its hour
    return [p for p in found if p.stem != "cycle_control" and (only is None or p.stem == only)]


def main() -> int:
    ap = arguments(__doc__, runs=3)
    ap.add_argument("--only", metavar="NAME", help="one program (its name without .irl)")
    args = ap.parse_args()
    walls, cpus = [], []
    print(f"{'program':24s} {'check s':>8s} {'run s':>8s} {'wall':>6s} {'cpu':>6s}  cycle time: check / run")
    for path in programs(args.only):
        scenario = path.with_suffix(".cell.toml")
        extra = ["--cell-scenario", str(scenario)] if scenario.exists() else []
        check = [str(IRL), "check", "--json", str(path), *extra]
        run = [str(IRL), "run", "--json", str(path), *extra]
        timed(check)  # (the caches)
        pairs = []
        for _ in range(args.runs):  # interleaved: each pair's ratio, under the same load
            c_wall, c_cpu, out_check = timed(check)
            r_wall, r_cpu, out_run = timed(run)
            pairs.append((c_wall, r_wall, c_wall / r_wall, c_cpu / r_cpu))
        c, r = statistics.median(p[0] for p in pairs), statistics.median(p[1] for p in pairs)
        wall, cpu = statistics.median(p[2] for p in pairs), statistics.median(p[3] for p in pairs)
        walls.append(wall)
        cpus.append(cpu)
        cycle = json.loads(out_check)["motion"]["cycle_time"]
        summary = json.loads(out_run)
        [move] = [s for s in summary["states"] if s["name"] == "Move Robot"]
        in_move = move["t_exit"] - move["t_enter"]
        n = len(summary["moves"])
        agree = "ok" if abs(cycle - in_move) <= 0.005 * max(n, 1) else (
            "waits assumed at once (no scenario)" if not extra else "DIFFERS")
        print(f"{path.stem:24s} {c:8.2f} {r:8.2f} {wall:6.2f} {cpu:6.2f}  {cycle:8.3f} / {in_move:8.3f} s "
              f"({n} moves: {agree})")
    print(f"check / run, the median of each program's pairs: wall worst {max(walls):.2f}, median "
          f"{statistics.median(walls):.2f}; CPU worst {max(cpus):.2f}, median {statistics.median(cpus):.2f}  "
          f"(goal <= 0.5)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
