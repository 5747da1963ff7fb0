"""The cost of one FSM step against a bare Python function call, measured in the same run.

The machine is a 5-state table FSM (automatic mode) in a ring S0 -> S1 -> ... -> S4 -> S0
plus an event row per state (never posted), each state with a run and a handle program,
every row guarded; the guards hold once every 10 steps, so most steps run the sub-machine
check, the run program, two guards and the handle program, and one step in ten fires a
transition (transition program, exit, entry, history record).

The reference is a call of a bare Python function that does nothing, made as many times
as ``step()`` is, in the same loop shape. Rounds alternate between the two so the ratio
holds on a noisy machine. The issue's reference figure for a table FSM step (compiled
code) is about 0.2 us.

Run: .venv/bin/python benchmarks/fsm_step.py [--calls N] [--rounds N]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from runtime.loop.fsm import FSM, State, Transition  # noqa: E402

N_STATES = 5


def table_machine() -> FSM:
    count = [0]

    def run() -> None:
        count[0] += 1

    def handle() -> None:
        return None

    def every_tenth() -> bool:
        return count[0] % 10 == 0

    def never() -> bool:
        return False

    def program() -> None:
        return None

    names = [f"S{i}" for i in range(N_STATES)]
    states = [State(n, entry=program, run=run, handle=handle, exit=program) for n in names]
    states.append(State("Final"))
    rows = []
    for i, n in enumerate(names):
        rows.append(Transition(n, "Final", guard=never, event="abort"))
        rows.append(Transition(n, names[(i + 1) % N_STATES], guard=every_tenth, program=program))
    m = FSM("bench", states, rows, "S0", "Final")
    m.start()
    return m


def bare() -> None:
    return None


def time_calls(fn, calls: int) -> float:
    """Seconds per call of ``fn`` over ``calls`` calls."""
    loop = range(calls)
    t0 = time.perf_counter()
    for _ in loop:
        fn()
    return (time.perf_counter() - t0) / calls


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=200_000)
    ap.add_argument("--rounds", type=int, default=9)
    args = ap.parse_args()

    m = table_machine()
    step = m.step
    time_calls(step, 10_000)  # warm up
    time_calls(bare, 10_000)
    steps, calls = [], []
    for _ in range(args.rounds):
        m.history.clear()     # the history grows by one record per transition
        steps.append(time_calls(step, args.calls))
        calls.append(time_calls(bare, args.calls))
    step_us = statistics.median(steps) * 1e6
    call_us = statistics.median(calls) * 1e6
    print(f"FSM step ({N_STATES}-state table, automatic): median {step_us:.3f} us per step "
          f"({args.rounds} rounds x {args.calls} steps)")
    print(f"bare Python function call:            median {call_us:.3f} us per call")
    print(f"ratio step / call: {step_us / call_us:.1f}   (issue's reference for a table FSM step: ~0.2 us)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
