"""Build: pure Python, plus runtime/kernels.py compiled with mypyc when that works.

The package metadata is in pyproject.toml. This file only adds the optional compiled
module ``runtime._kernels_c``: a copy of ``runtime/kernels.py`` stamped with the source's
SHA-256 (so ``runtime/accel.py`` can tell a stale build), compiled by mypyc. Floating-point
contraction is switched off so the compiled loops round exactly as the interpreter does.
If mypyc or the C compiler fails, the install goes on without the compiled module (the
runtime then runs the source; same results, slower) and says so.
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent
SOURCE = ROOT / "runtime" / "kernels.py"
STAMPED = ROOT / "runtime" / "_kernels_c.py"  # generated for mypyc, removed again


def warn(message: str) -> None:
    print(f"irl build: {message}; the runtime will run runtime/kernels.py as Python (same results, slower)",
          file=sys.stderr)


#: setuptools commands that build extensions (metadata-only runs skip the compilation)
BUILD_COMMANDS = {"build", "build_ext", "bdist_wheel", "editable_wheel", "develop", "install"}


def compiled_extensions() -> list:
    if os.environ.get("IRL_NO_COMPILE") or not BUILD_COMMANDS.intersection(sys.argv[1:]):
        return []
    try:
        from mypyc.build import mypycify
    except ImportError:
        warn("mypyc is not available")
        return []
    text = SOURCE.read_text(encoding="utf-8")
    digest = hashlib.sha256(SOURCE.read_bytes()).hexdigest()
    STAMPED.write_text(text + f"\n\nSOURCE_SHA256 = {digest!r}\n", encoding="utf-8")
    try:
        os.chdir(ROOT)  # mypycify takes paths relative to the project
        extensions = mypycify([str(STAMPED.relative_to(ROOT))], opt_level="3", debug_level="0")
    except (Exception, SystemExit) as exc:  # mypyc exits with SystemExit on type errors
        warn(f"mypyc could not compile runtime/kernels.py ({exc!r})")
        return []
    finally:
        STAMPED.unlink(missing_ok=True)
    for extension in extensions:
        extension.extra_compile_args = list(extension.extra_compile_args or []) + ["-ffp-contract=off"]
    return extensions


class OptionalBuildExt(build_ext):
    """build_ext that warns instead of failing when the C compiler is missing or fails."""

    def run(self) -> None:
        try:
            super().run()
        except Exception as exc:  # noqa: BLE001 - any compiler failure leaves the Python source in use
            warn(f"the compiled kernels were not built ({exc})")

    def build_extension(self, ext) -> None:
        try:
            super().build_extension(ext)
        except Exception as exc:  # noqa: BLE001
            warn(f"{ext.name} was not built ({exc})")


setup(ext_modules=compiled_extensions(), cmdclass={"build_ext": OptionalBuildExt})
