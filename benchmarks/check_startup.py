"""End-to-end start-up of `irl check --no-motion programs/test.irl` against `python -c pass`.

Both are run as fresh processes, interleaved, in the same run; the figure is the ratio
of the medians. Goal (issues 2, 26; 29: --no-motion keeps it): <= 8x. Start-up as a user meets it at every run after
the first: Lark's parser tables and Python's bytecode come from their caches (the first,
unmeasured run writes them; a PYTHONDONTWRITEBYTECODE in the environment is left out, or
each run would compile every module of the compiler from source again). It also lists
what the check imported of what it does not need (runtime.cli.main.NOT_FOR_CHECKING).
Run: .venv/bin/python benchmarks/check_startup.py [--runs N]
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IRL = Path(sys.executable).with_name("irl")


ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def timed(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=ENV)
    elapsed = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed: {done.stderr.decode()[:500]}")
    return elapsed


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=21)
    args = ap.parse_args()
    check = [str(IRL), "check", "--no-motion", "programs/test.irl"]
    bare = [sys.executable, "-c", "pass"]
    timed(check)  # let Lark write its table cache, and Python its bytecode, if this is the first run
    ours, base = [], []
    for _ in range(args.runs):
        base.append(timed(bare))
        ours.append(timed(check))

    probe = subprocess.run(
        [sys.executable, "-c",
         "import sys; from runtime.cli.main import NOT_FOR_CHECKING, main; main(['check', '--no-motion', 'programs/test.irl']);"
         "heavy = sorted(m for m in sys.modules if any(m == n or m.startswith(n + '.') for n in NOT_FOR_CHECKING));"
         "print('heavy modules imported:', heavy or 'none', file=sys.stderr)"],
        cwd=ROOT, capture_output=True, text=True)
    b, o = statistics.median(base), statistics.median(ours)
    print(f"python -c pass:                 median {b * 1000:6.1f} ms (min {min(base) * 1000:.1f})")
    print(f"irl check --no-motion test.irl: median {o * 1000:6.1f} ms (min {min(ours) * 1000:.1f})")
    print(f"ratio: {o / b:.2f}x  (goal <= 8x)")
    print(probe.stderr.strip().splitlines()[-1])
    return 0


if __name__ == "__main__":
    sys.exit(main())
