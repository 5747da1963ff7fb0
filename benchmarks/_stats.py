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
