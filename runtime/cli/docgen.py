"""The documentation's generated tables: ``python -m runtime.cli.docgen --write`` (or ``--check``).

Each table lives between ``<!-- generated: NAME -->`` and ``<!-- end generated -->`` in a
page of ``docs/``, and is rendered from its one declaration: the parameters from
:mod:`compiler.params`, the move clauses and the specification's ``[defaults]`` from
:mod:`compiler.clauses`, the stop categories from :data:`runtime.loop.components.safety.CATEGORIES`, the simulated
cell's rules from :data:`runtime.hardware.sim.cell.RULES`, the fieldbus file's fields from
:data:`runtime.hardware.fieldbus.FIELDS`, the telemetry sample's fields from
:data:`runtime.wire.protocol.SAMPLE_FIELDS`, pose arithmetic from :data:`compiler.semantics.GEOMETRY`, the bounds of frames and tools from
:data:`compiler.frames.FRAME_KINDS`, the configuration's words from :data:`compiler.configs.GROUPS`, a
recording's topics and the events' kinds from :data:`runtime.recording.TOPICS` and :data:`runtime.recording.EVENTS`,
the errors a handler takes and its words from :mod:`compiler.recovery`.
A test fails while a page is stale. Not real-time; imports nothing the loop needs.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parents[2] / "docs"

_BLOCK = re.compile(r"(<!-- generated: (?P<name>[a-z_]+) -->\n)(?P<body>.*?)(<!-- end generated -->)", re.S)


def tables() -> dict[str, str]:
    from compiler import clauses, configs, frames, recovery, semantics, triggers, zones
    from compiler.params import COMPONENTS, markdown

    from runtime import recording
    from runtime.hardware import fieldbus
    from runtime.wire import protocol
    from runtime.loop.components.safety import categories_markdown
    from runtime.hardware.sim import cell

    return {"params": markdown(), "config": markdown(COMPONENTS), "categories": categories_markdown(),
            "clauses": clauses.markdown(), "defaults": clauses.defaults_markdown(), "cell": cell.markdown(),
            "fieldbus": fieldbus.markdown(), "sample": protocol.sample_markdown(),
            "geometry": semantics.geometry_markdown(), "frames": frames.markdown(),
            "triggers": triggers.markdown(), "configurations": configs.markdown(),
            "recording": recording.topics_markdown(), "events": recording.events_markdown(),
            "errors": recovery.markdown(), "zones": zones.markdown()}


def render(text: str) -> str:
    """``text`` with every generated block rendered anew."""
    rendered = tables()

    def block(match: re.Match) -> str:
        name = match.group("name")
        if name not in rendered:
            raise KeyError(f"no generated table {name!r} (known: {', '.join(rendered)})")
        return match.group(1) + rendered[name] + match.group(4)
    return _BLOCK.sub(block, text)


def pages() -> list[Path]:
    return sorted(p for p in DOCS.glob("*.md") if "<!-- generated:" in p.read_text(encoding="utf-8"))


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    write = args == ["--write"]
    if args not in (["--write"], ["--check"]):
        print("usage: python -m runtime.cli.docgen --write | --check", file=sys.stderr)
        return 2
    stale = []
    for page in pages():
        text = page.read_text(encoding="utf-8")
        new = render(text)
        if new != text:
            stale.append(page)
            if write:
                page.write_text(new, encoding="utf-8")
    for page in stale:
        print(f"{'wrote' if write else 'stale'}: {page.relative_to(DOCS.parent)}")
    return 1 if stale and not write else 0


if __name__ == "__main__":
    sys.exit(main())
