"""Helpers shared by the benchmark scripts (not a benchmark itself)."""
from __future__ import annotations

import socket


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
