"""Test-suite settings.

Hypothesis runs derandomized by default (profile "ci"): the examples searched are the same
on every run, so a property test that passes in CI passes again, and a counter-example, once
found, is found every time. To search new examples locally:
``IRL_HYPOTHESIS_PROFILE=explore .venv/bin/python -m pytest tests/...``.
"""
from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None, deadline=None)
settings.register_profile("explore", deadline=None)
settings.load_profile(os.environ.get("IRL_HYPOTHESIS_PROFILE", "ci"))
