"""Where irl listens and keeps its state, by default: each written once, for the server, its
clients and the command line.
"""
from __future__ import annotations

import os
from pathlib import Path

#: ``irl serve``'s request and telemetry endpoints, and its clients' (loopback only: a
#: server reachable from other machines is a choice, docs/protocol.md)
DEFAULT_ENDPOINT = "tcp://127.0.0.1:5555"
DEFAULT_TELEMETRY = "tcp://127.0.0.1:5556"


def default_state_dir() -> Path:
    """Where irl keeps its state (calibration, reports, a control token):
    ``$XDG_STATE_HOME/irl``, else ``~/.local/state/irl``."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / "irl"
