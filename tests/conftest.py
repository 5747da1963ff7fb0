"""Test-suite settings.

Hypothesis runs derandomized by default (profile "ci"): the examples searched are the same
on every run, so a property test that passes in CI passes again, and a counter-example, once
found, is found every time. To search new examples locally:
``IRL_HYPOTHESIS_PROFILE=explore .venv/bin/python -m pytest tests/...``.

The README's test command runs the tests in parallel (pytest-xdist, ``-n auto --dist
worksteal``: two workers per core, see pytest_xdist_auto_num_workers; a worker that runs
out of tests takes half of another's queue). Tests marked ``long`` (the few that take seconds of CPU or of the wall clock each;
``long(first=True)``: the longest, a worker to itself) are put at the heads of the
workers' first shares, so that each worker starts on its long tests and the short ones fill in around them,
instead of one long test starting last on an otherwise idle machine, or all of them on one
worker.
"""
from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None, deadline=None)
settings.register_profile("explore", deadline=None)
settings.load_profile(os.environ.get("IRL_HYPOTHESIS_PROFILE", "ci"))


def pytest_xdist_auto_num_workers(config):
    """``-n auto``: two workers per core this process may run on. A fifth of the suite's
    time is spent waiting on the wall clock (servers, the fieldbus, real-time runs) with
    a core idle; a second worker per core keeps it busy."""
    return 2 * len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 2 * (os.cpu_count() or 1)


def pytest_collection_modifyitems(config, items):
    """The ``long`` tests dealt in turn to the heads of the shares that xdist's worksteal
    scheduler first gives each worker (contiguous: worker i gets len(pending) //
    (workers - i) of the tests left): the ``first=True`` ones to workers of their own, the
    others to the rest; the other tests in their files' order. Without xdist: the long
    tests first."""
    workers = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))

    def rank(item) -> int:
        mark = item.get_closest_marker("long")
        return 2 if mark is None else 0 if mark.kwargs.get("first") else 1

    ranked = sorted(items, key=rank)  # (stable)
    longs = [item for item in ranked if rank(item) < 2]
    rest = ranked[len(longs):]
    firsts = [item for item in longs if rank(item) == 0]
    shares: list[list] = [[] for _ in range(workers)]
    for k, item in enumerate(firsts):
        shares[k % workers].append(item)
    others = list(range(len(firsts), workers)) or list(range(workers))  # (the workers with no first one)
    for k, item in enumerate(longs[len(firsts):]):
        shares[others[k % len(others)]].append(item)
    left = len(items)
    for i, share in enumerate(shares):
        size = left // (workers - i)
        take = max(0, size - len(share))
        share.extend(rest[:take])
        rest = rest[take:]
        left -= len(share)
    items[:] = [item for share in shares for item in share] + rest
