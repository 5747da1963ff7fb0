"""The VM's speed on a tight arithmetic loop against a plain Python while-loop doing the
same arithmetic, measured in the same run (interleaved, so the ratio holds on a noisy
machine). Both VM dispatch loops are measured:

  inline: the frequent instructions inline in an if-chain, the rest via the table (default)
  table:  every instruction through the handler table (a list indexed by opcode)

The VM runs as it does on the robot: step() with the default budget of 200 instructions,
called again and again (here back to back, on the robot once per 5 ms cycle).

Goal (issue: VM): under 1 us per simple instruction.
Run: .venv/bin/python benchmarks/vm_speed.py [--iterations N] [--rounds N] [--budget N]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.driver import compile_source  # noqa: E402
from runtime.loop.vm import VM, VMStatus  # noqa: E402

PROGRAM = """\
program speed;
system_specification "lola15.spc";
var i, s, t : integer;
    x : real;
seq
  s := 0;
  x := 0.0;
  for i := 1 to {n} do
    t := i * 3 - s;
    s := s + t - i;
    if s > 1000 then
      s := s - 1000;
    endif;
    x := x + 0.5 * i;
  endfor;
  print s, " ", x;
endseq
endprogram;
"""


def python_loop(n: int) -> tuple[int, float]:
    """The same arithmetic as PROGRAM, in plain Python."""
    s = 0
    x = 0.0
    i = 1
    while i <= n:
        t = i * 3 - s
        s = s + t - i
        if s > 1000:
            s = s - 1000
        x = x + 0.5 * i
        i = i + 1
    return s, x


class _Host:
    """A host that is never waited for (the loop does no motion)."""

    def __init__(self):
        self.printed: list[str] = []

    def now(self) -> float:
        return 0.0

    def move(self, kind, targets, clauses, line):
        return None

    def motion_done(self) -> bool:
        return True

    def read_input(self, n: int) -> bool:
        return False

    def write_output(self, n: int, value: bool) -> None:
        pass

    def log(self, text: str, line: int) -> None:
        self.printed.append(text)


def run_vm(program, dispatch: str, budget: int) -> tuple[float, int, str]:
    """(seconds, instructions executed, what the program printed)."""
    host = _Host()
    vm = VM(program, host, budget, dispatch=dispatch)
    step = vm.step
    t0 = time.perf_counter()
    while step() < VMStatus.DONE:
        pass
    elapsed = time.perf_counter() - t0
    if vm.status != VMStatus.DONE:
        raise SystemExit(f"the benchmark program failed: {vm.error}")
    return elapsed, vm.instructions, host.printed[-1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, default=100_000, help="loop iterations (default 100000)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--budget", type=int, default=200, help="instructions per step (default 200)")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "speed.irl"
        (Path(tmp) / "lola15.spc").write_text((ROOT / "programs" / "lola15.spc").read_text())
        result = compile_source(PROGRAM.format(n=args.iterations), str(src))
        if not result.ok:
            raise SystemExit(f"benchmark program does not compile: {result.diagnostics[:3]}")
    program = result.program

    s, x = python_loop(args.iterations)
    _, count, printed = run_vm(program, "inline", args.budget)  # warm up, and check the result
    if printed.split()[0] != str(s) or float(printed.split()[1]) != x:
        raise SystemExit(f"the VM computed {printed!r}, Python {s} {x!r}")
    times: dict[str, list[float]] = {"python": [], "inline": [], "table": []}
    for _ in range(args.rounds):
        t0 = time.perf_counter()
        python_loop(args.iterations)
        times["python"].append(time.perf_counter() - t0)
        for dispatch in ("inline", "table"):
            elapsed, executed, _ = run_vm(program, dispatch, args.budget)
            assert executed == count
            times[dispatch].append(elapsed)

    best = {k: min(v) for k, v in times.items()}
    median = {k: statistics.median(v) for k, v in times.items()}
    per_iter = count / args.iterations
    print(f"program: {args.iterations} loop iterations, {count} VM instructions "
          f"({per_iter:.1f} per iteration), budget {args.budget} per step, best of {args.rounds}")
    print(f"  plain Python while-loop: {best['python'] * 1e3:8.2f} ms   "
          f"({args.iterations / best['python'] / 1e6:6.2f} M iterations/s)")
    for dispatch in ("inline", "table"):
        t = best[dispatch]
        print(f"  VM, {dispatch + ' dispatch:':17s} {t * 1e3:8.2f} ms   ({count / t / 1e6:6.2f} M instructions/s, "
              f"{t / count * 1e9:5.0f} ns/instruction, median {median[dispatch] / count * 1e9:5.0f})")
    print(f"  ratio VM (inline) / Python: {best['inline'] / best['python']:.1f}x   "
          f"table / inline: {best['table'] / best['inline']:.2f}x")
    goal = best["inline"] / count < 1e-6
    print(f"  goal < 1 us per instruction: {'met' if goal else 'NOT met'}")
    return 0 if goal else 1


if __name__ == "__main__":
    sys.exit(main())
