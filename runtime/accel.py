"""Which implementation of :mod:`runtime.kernels` the 1 ms loop runs.

The build compiles ``runtime/kernels.py`` with mypyc into ``runtime._kernels_c`` (see
``setup.py``), stamping the compiled module with the SHA-256 of the source it was built
from. At import this module takes:

* the compiled module, if it exists and was built from the source as it is now;
* the source module otherwise: no compiled build (no C compiler when installing), a
  stale one (``kernels.py`` edited since the last ``pip install -e .``; a warning says
  so), or ``IRL_KERNELS=python`` in the environment (to compare, or to debug the loops).

Both give bit-identical results; only the speed differs. :data:`DESCRIPTION` says which
runs and why (``irl run`` and the benchmarks print it).
"""
from __future__ import annotations

import hashlib
import os
import warnings
from pathlib import Path
from types import ModuleType

from runtime import kernels as source

#: The environment variable that chooses: "python" forces the source; unset (or "auto"):
#: the compiled module when it is usable.
ENV = "IRL_KERNELS"


def source_digest(path: Path | None = None) -> str:
    """SHA-256 (hex) of the kernels' source file, as the build stamps it."""
    return hashlib.sha256((path or Path(source.__file__)).read_bytes()).hexdigest()


def _compiled_module() -> ModuleType | None:
    try:
        from runtime import _kernels_c
    except ImportError:
        return None
    return _kernels_c


def select(choice: str, compiled: ModuleType | None, digest: str) -> tuple[ModuleType, str]:
    """The kernels to use and a one-line description, for ``choice`` (the environment
    variable's value), the compiled module (or None) and the source's digest now."""
    if choice == "python":
        return source, f"python ({ENV}=python)"
    if choice not in ("", "auto"):
        warnings.warn(f"irl: {ENV}={choice!r} is not 'python' or 'auto'; taken as 'auto'", stacklevel=2)
    if compiled is not None and str(getattr(compiled, "__file__", "")).endswith(".py"):
        compiled = None  # the build's stamped copy, left by an interrupted build: not compiled
    if compiled is None:
        return source, "python (no compiled build; reinstall with a C compiler: pip install -e .)"
    if getattr(compiled, "SOURCE_SHA256", None) != digest:
        warnings.warn("irl: the compiled kernels are stale (runtime/kernels.py changed since the build; "
                      "rebuild: pip install -e .); running the Python source (slower, same results)", stacklevel=2)
        return source, "python (stale compiled build: runtime/kernels.py changed since; pip install -e .)"
    return compiled, "compiled (mypyc)"


kernels, DESCRIPTION = select(os.environ.get(ENV, "").strip().lower(), _compiled_module(), source_digest())
COMPILED = kernels is not source
