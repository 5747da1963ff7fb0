"""The L-IRL abstract syntax tree: frozen dataclasses, each with a source span.

Names are stored lower-cased (L-IRL is case-insensitive). Nodes are built while parsing
(compiler/syntax.py) and never change afterwards; the checker keeps what it learns about
them in side tables keyed by ``id(node)``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Union


class Span(NamedTuple):
    """A region of the source: 1-based line and column; ``end_col`` is exclusive.

    A NamedTuple rather than a dataclass: it is immutable all the same, and a parse
    creates one per token, where a tuple is three times cheaper to build.
    """

    line: int
    col: int
    end_line: int
    end_col: int

    def to(self, other: "Span") -> "Span":
        """The span from the start of ``self`` to the end of ``other``."""
        return _new_span(Span, (self[0], self[1], other[2], other[3]))


_new_span = tuple.__new__  # builds a Span without the generated __new__'s extra call


# ---- expressions -------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Number:
    value: int | float
    span: Span


@dataclass(frozen=True, slots=True)
class String:
    value: str
    span: Span


@dataclass(frozen=True, slots=True)
class Bool:
    value: bool
    span: Span


@dataclass(frozen=True, slots=True)
class Ref:
    """A use of a name: a constant, a variable or a parameter."""

    name: str
    span: Span


@dataclass(frozen=True, slots=True)
class Call:
    """``name(args)``: a built-in function or a value constructor."""

    name: str
    args: tuple["Expr", ...]
    span: Span
    name_span: Span


@dataclass(frozen=True, slots=True)
class Index:
    """``base[index]``: an array element or (1-based) a joint's axis value."""

    base: "Expr"
    index: "Expr"
    span: Span


@dataclass(frozen=True, slots=True)
class Field:
    """``base.name``: ``x``, ``y``, ``z`` of a position or pose."""

    base: "Expr"
    name: str
    span: Span


@dataclass(frozen=True, slots=True)
class Unary:
    op: str  # "-", "+", "not"
    operand: "Expr"
    span: Span


@dataclass(frozen=True, slots=True)
class Binary:
    op: str  # + - * / div mod = <> < > <= >= and or
    left: "Expr"
    right: "Expr"
    span: Span
    op_span: Span


@dataclass(frozen=True, slots=True)
class Input:
    """``in[index]``: a digital input, bool."""

    index: "Expr"
    span: Span


Expr = Union[Number, String, Bool, Ref, Call, Index, Field, Unary, Binary, Input]


# ---- types ---------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class NamedType:
    name: str
    span: Span


@dataclass(frozen=True, slots=True)
class ArrayType:
    low: Expr
    high: Expr
    element: "TypeExpr"
    span: Span


TypeExpr = Union[NamedType, ArrayType]


# ---- statements ----------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Assign:
    """``name := value`` or ``name[i]...[k] := value`` (array elements, a joint's axis)."""

    name: str
    indices: tuple[Expr, ...]
    value: Expr
    span: Span
    name_span: Span


@dataclass(frozen=True, slots=True)
class OutSet:
    """``out[index] := value``: set a digital output."""

    index: Expr
    value: Expr
    span: Span


@dataclass(frozen=True, slots=True)
class Clause:
    name: str
    value: Expr
    span: Span
    name_span: Span


@dataclass(frozen=True, slots=True)
class Move:
    """``move ptp|lin|circ TARGET [, TARGET] {CLAUSE}``; circ has (via, end) targets."""

    kind: str
    targets: tuple[Expr, ...]
    clauses: tuple[Clause, ...]
    span: Span


@dataclass(frozen=True, slots=True)
class If:
    branches: tuple[tuple[Expr, tuple["Stmt", ...]], ...]  # if + elsif, in order
    orelse: tuple["Stmt", ...]
    span: Span


@dataclass(frozen=True, slots=True)
class While:
    cond: Expr
    body: tuple["Stmt", ...]
    span: Span


@dataclass(frozen=True, slots=True)
class Repeat:
    body: tuple["Stmt", ...]
    cond: Expr
    span: Span


@dataclass(frozen=True, slots=True)
class For:
    var: str
    start: Expr
    stop: Expr
    step: Expr | None
    body: tuple["Stmt", ...]
    span: Span
    var_span: Span


@dataclass(frozen=True, slots=True)
class WaitTime:
    """``wait seconds sec``: dwell with the robot standing still."""

    seconds: Expr
    span: Span


@dataclass(frozen=True, slots=True)
class WaitFor:
    """``wait for cond [timeout seconds sec]``."""

    cond: Expr
    timeout: Expr | None
    span: Span


@dataclass(frozen=True, slots=True)
class CallProc:
    name: str
    args: tuple[Expr, ...]
    span: Span
    name_span: Span


@dataclass(frozen=True, slots=True)
class Print:
    values: tuple[Expr, ...]
    span: Span


@dataclass(frozen=True, slots=True)
class Pause:
    span: Span


@dataclass(frozen=True, slots=True)
class Halt:
    span: Span


Stmt = Union[Assign, OutSet, Move, If, While, Repeat, For, WaitTime, WaitFor,
             CallProc, Print, Pause, Halt]


# ---- declarations and the program ----------------------------------------------------

@dataclass(frozen=True, slots=True)
class ConstDecl:
    name: str
    value: Expr
    span: Span


@dataclass(frozen=True, slots=True)
class VarDecl:
    """One ``a, b : TYPE [:= init]`` item; ``spans`` has one span per name."""

    names: tuple[str, ...]
    type: TypeExpr
    init: Expr | None
    span: Span
    spans: tuple[Span, ...]


@dataclass(frozen=True, slots=True)
class Param:
    name: str
    type: TypeExpr
    span: Span


@dataclass(frozen=True, slots=True)
class Procedure:
    name: str
    params: tuple[Param, ...]
    variables: tuple[VarDecl, ...]
    body: tuple[Stmt, ...]
    span: Span
    name_span: Span


Decl = Union[ConstDecl, VarDecl, Procedure]


@dataclass(frozen=True, slots=True)
class Program:
    name: str
    spec: str | None  # the system_specification file, as written
    spec_span: Span | None
    decls: tuple[Decl, ...]  # in source order (a constant may use earlier ones)
    body: tuple[Stmt, ...]
    span: Span
