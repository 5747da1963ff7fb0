"""Helpers shared by the benchmark scripts (not a benchmark itself)."""
from __future__ import annotations

import argparse
import socket
from pathlib import Path

#: the paper's robot, the one the benchmarks measure unless they say otherwise
LOLA15 = Path(__file__).resolve().parent.parent / "programs" / "lola15.spc"


def percentile(values, q: float):
    """The value at quantile ``q`` (0..1) of ``values``: the nearest rank, no interpolation."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def percentiles(ns) -> tuple[float, float]:
    """(p50, p99) in microseconds of durations in nanoseconds."""
    return percentile(ns, 0.5) / 1000.0, percentile(ns, 0.99) / 1000.0


def free_port() -> int:
    """A TCP port on loopback that nothing listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def arguments(doc: str, **counts: int) -> argparse.ArgumentParser:
    """A benchmark's command line: its docstring's first line as the description, and an
    ``--NAME N`` option for each count (``arguments(__doc__, moves=1000, seed=1)``)."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    for name, default in counts.items():
        parser.add_argument(f"--{name}", type=int, default=default)
    return parser


def timing_table(overhead_ns, width: int):
    """Print the timer's own overhead and a table's head; returns ``row(label, ns)``, which
    prints one row of durations in nanoseconds and returns their (p50, p99) in us."""
    o50, o99 = percentiles(overhead_ns)
    print(f"timer overhead (perf_counter_ns pair): p50 {o50:.3f} us, p99 {o99:.3f} us "
          f"(included in every figure below)")
    print(f"{'':{width}s} {'p50 us':>8s} {'p99 us':>8s} {'calls':>9s}")

    def row(label: str, ns) -> tuple[float, float]:
        p50, p99 = percentiles(ns)
        print(f"{label:{width}s} {p50:8.2f} {p99:8.2f} {len(ns):9d}")
        return p50, p99

    return row
