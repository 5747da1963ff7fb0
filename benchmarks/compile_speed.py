"""Full compile of a 10,000-line program against Lark's own bare LALR parse of it.

Both are measured in the same run, interleaved, so the ratio holds on a noisy machine:

  bare parse:   Lark LALR, no positions, no transformer, builds a parse tree
  full compile: parse with positions building the AST (inline transformer), check
                against the specification, code generation, encoding to bytes

Goal (issue 2): ratio full / bare <= 1.0.
Run: .venv/bin/python benchmarks/compile_speed.py [--lines N] [--rounds N]
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
sys.path.insert(0, str(ROOT / "benchmarks"))

from _programs import large_program  # noqa: E402
from lark import Lark  # noqa: E402

from compiler.driver import compile_source  # noqa: E402
from compiler.objcode import encode  # noqa: E402
from grammar import grammar_text  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=10_000)
    ap.add_argument("--rounds", type=int, default=7)
    args = ap.parse_args()

    text = large_program(args.lines)
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "big.irl"
        src.write_text(text)
        (Path(tmp) / "lola15.spc").write_text((ROOT / "programs" / "lola15.spc").read_text())
        bare = Lark(grammar_text(), parser="lalr", maybe_placeholders=True)

        def full() -> int:
            result = compile_source(text, str(src))
            if not result.ok:
                raise SystemExit(f"generated program does not compile: {result.diagnostics[:3]}")
            return len(encode(result.program))

        size = full()  # warm up: parser tables, imports
        bare.parse(text)
        bare_times, full_times = [], []
        for _ in range(args.rounds):
            t0 = time.perf_counter()
            bare.parse(text)
            t1 = time.perf_counter()
            full()
            t2 = time.perf_counter()
            bare_times.append(t1 - t0)
            full_times.append(t2 - t1)

    b, f = statistics.median(bare_times), statistics.median(full_times)
    print(f"program: {text.count(chr(10))} lines, {len(text)} characters, object code {size} bytes")
    print(f"bare Lark LALR parse (tree, no positions): median {b * 1000:8.1f} ms  (min {min(bare_times) * 1000:.1f})")
    print(f"full compile (parse+AST, check, codegen, encode): median {f * 1000:8.1f} ms  (min {min(full_times) * 1000:.1f})")
    print(f"ratio full / bare: {f / b:.2f}  (goal <= 1.00)  lines/s: {args.lines / f:,.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
