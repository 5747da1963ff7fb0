"""The L-IRL grammar (``lirl.lark``) and a tiny loader for it.

The grammar is data; this module only finds it and builds a Lark LALR parser whose
tables are cached on disk (Lark's own cache, keyed by the grammar's hash), so a command
like ``irl check`` does not rebuild them at every start.
"""
from __future__ import annotations

import re
from functools import cache
from pathlib import Path

GRAMMAR_PATH = Path(__file__).with_name("lirl.lark")


def grammar_text() -> str:
    return GRAMMAR_PATH.read_text(encoding="utf-8")


@cache
def keywords() -> frozenset[str]:
    """The reserved words of L-IRL (every case-insensitive literal of the grammar)."""
    return frozenset(re.findall(r'"([a-z_]+)"i', grammar_text()))


def make_parser(transformer=None, **options):
    """A Lark LALR parser for L-IRL; ``transformer`` builds the result while parsing.

    Lark's basic lexer, not the contextual one: the grammar needs no context to lex, the
    contextual lexer compiles one scanner per parser state at every start (~50 ms), and
    it would let a keyword pass as a name wherever the keyword cannot stand.
    """
    from lark import Lark

    options.setdefault("lexer", "basic")  # one scanner to build at start-up; keywords always reserved
    return Lark(grammar_text(), parser="lalr", transformer=transformer,
                maybe_placeholders=True, cache=True, **options)
