"""The L-IRL abstract syntax tree: frozen dataclasses, each with a source span.

Names are stored lower-cased (L-IRL is case-insensitive). Nodes are built while parsing
(compiler/syntax.py) and never change afterwards; the checker keeps what it learns about
them in side tables keyed by ``id(node)``.
"""
from __future__ import annotations

from dataclasses import FrozenInstanceError
from typing import NamedTuple, Union


def node(cls):
    """A frozen record class with slots, made from ``cls``'s annotated fields (with their
    defaults): what ``dataclass(frozen=True, slots=True)`` makes (an ``__init__`` with the
    fields in order, ``__eq__`` and ``__hash__`` by value, ``__repr__``, ``__match_args__``,
    assignment raising ``FrozenInstanceError``), built directly. A dataclass with slots
    is made twice, and the AST's classes cost every ``irl`` command 30 ms of start-up that
    way. The ``__init__`` stores each field through its slot's descriptor (a frozen
    dataclass's goes through ``object.__setattr__``, twice as slow: a parse builds one node
    per reduction)."""
    names = tuple(cls.__dict__.get("__annotations__", {}))
    defaults = {n: cls.__dict__[n] for n in names if n in cls.__dict__}
    namespace = {k: v for k, v in cls.__dict__.items() if k not in names and k not in ("__dict__", "__weakref__")}
    namespace.update(__slots__=names, __match_args__=names, __setattr__=_frozen, __delattr__=_frozen,
                     __eq__=_equal, __hash__=_hash, __repr__=_repr)
    made = type(cls.__name__, cls.__bases__, namespace)
    scope = {f"_set_{n}": getattr(made, n).__set__ for n in names}
    scope.update({f"_default_{n}": v for n, v in defaults.items()})
    params = ", ".join(f"{n}=_default_{n}" if n in defaults else n for n in names)
    body = "".join(f"    _set_{n}(self, {n})\n" for n in names) or "    pass\n"
    exec(f"def __init__(self, {params}):\n{body}", scope)  # noqa: S102 - the class's own field names only
    init = scope["__init__"]
    init.__qualname__ = f"{made.__qualname__}.__init__"
    made.__init__ = init
    return made


def _values(self) -> tuple:
    return tuple([getattr(self, n) for n in self.__slots__])


def _frozen(self, name, value=None):
    raise FrozenInstanceError(f"cannot assign to field {name!r}")


def _equal(self, other):
    if other.__class__ is not self.__class__:
        return NotImplemented
    return _values(self) == _values(other)


def _hash(self) -> int:
    return hash((self.__class__.__name__,) + _values(self))


def _repr(self) -> str:
    return f"{self.__class__.__qualname__}({', '.join(f'{n}={getattr(self, n)!r}' for n in self.__slots__)})"


def replace(record, **changes):
    """A copy of a node with ``changes`` (field name: new value), as ``dataclasses.replace``."""
    return record.__class__(**{n: changes.pop(n, getattr(record, n)) for n in record.__slots__}, **changes)


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

@node
class Number:
    value: int | float
    span: Span


@node
class String:
    value: str
    span: Span


@node
class Bool:
    value: bool
    span: Span


@node
class Ref:
    """A use of a name: a constant, a variable or a parameter."""

    name: str
    span: Span


@node
class Call:
    """``name(args)``: a built-in function or a value constructor."""

    name: str
    args: tuple["Expr", ...]
    span: Span
    name_span: Span


@node
class Index:
    """``base[index]``: an array element or (1-based) a joint's axis value."""

    base: "Expr"
    index: "Expr"
    span: Span


@node
class Field:
    """``base.name``: ``x``, ``y``, ``z`` of a position or pose."""

    base: "Expr"
    name: str
    span: Span


@node
class Unary:
    op: str  # "-", "+", "not"
    operand: "Expr"
    span: Span


@node
class Binary:
    op: str  # + - * / div mod = <> < > <= >= and or
    left: "Expr"
    right: "Expr"
    span: Span
    op_span: Span


@node
class Input:
    """``in[index]``: a digital input, bool."""

    index: "Expr"
    span: Span


@node
class Output:
    """``out[index]`` read in an expression: the digital output as last set, bool."""

    index: "Expr"
    span: Span


Expr = Union[Number, String, Bool, Ref, Call, Index, Field, Unary, Binary, Input, Output]


def operands(expr) -> tuple:
    """The expressions directly inside ``expr`` (none for a literal or a name)."""
    kind = type(expr)
    if kind is Call:
        return tuple(expr.args)
    if kind is Binary:
        return (expr.left, expr.right)
    if kind is Unary:
        return (expr.operand,)
    if kind is Index:
        return (expr.base, expr.index)
    if kind is Field:
        return (expr.base,)
    if kind in (Input, Output):
        return (expr.index,)
    return ()


def expression_text(expr) -> str:
    """An expression written out again (names in lower case, numbers as the parser read
    them, a binary operand that is itself binary in parentheses): what reports call a
    frame or tool made active by ``use`` (``gripper``, ``pallet * shift``)."""
    if isinstance(expr, Ref):
        return expr.name
    if isinstance(expr, Number):
        return f"{expr.value:g}" if isinstance(expr.value, float) else str(expr.value)
    if isinstance(expr, String):
        return '"' + expr.value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(expr, Bool):
        return "true" if expr.value else "false"
    if isinstance(expr, Call):
        return f"{expr.name}({', '.join(expression_text(arg) for arg in expr.args)})"
    if isinstance(expr, Index):
        return f"{expression_text(expr.base)}[{expression_text(expr.index)}]"
    if isinstance(expr, Field):
        return f"{expression_text(expr.base)}.{expr.name}"
    if isinstance(expr, Input):
        return f"in[{expression_text(expr.index)}]"
    if isinstance(expr, Unary):
        space = " " if expr.op == "not" else ""
        return f"{expr.op}{space}{_operand_text(expr.operand)}"
    if isinstance(expr, Binary):
        return f"{_operand_text(expr.left)} {expr.op} {_operand_text(expr.right)}"
    return "?"


def reference_parts(expr) -> list:
    """The selectors of ``a[i].f[k]`` (its Index and Field nodes), outermost (``a[i]``) first."""
    parts = []
    while isinstance(expr, (Index, Field)):
        parts.append(expr)
        expr = expr.base
    return parts[::-1]


def reference_root(expr) -> "Ref | None":
    """The variable ``a`` of ``a``, ``a[i]``, ``a.f[k]``, ...; None when ``expr`` is no such path."""
    while isinstance(expr, (Index, Field)):
        expr = expr.base
    return expr if isinstance(expr, Ref) else None


def _operand_text(expr) -> str:
    text = expression_text(expr)
    return f"({text})" if isinstance(expr, Binary) else text


# ---- types ---------------------------------------------------------------------------

@node
class NamedType:
    name: str
    span: Span


@node
class ArrayType:
    low: Expr
    high: Expr
    element: "TypeExpr"
    span: Span


TypeExpr = Union[NamedType, ArrayType]


# ---- statements ----------------------------------------------------------------------

@node
class Member:
    """``.name`` in an assignment's target: a field of a record (compiler.records)."""

    name: str
    span: Span


@node
class Assign:
    """``name := value``, or into a part of the variable: ``name[i].f[k] := value``
    (array elements, a record's fields, a joint's axis). ``path``: its selectors, an
    expression for each index, a :class:`Member` for each field."""

    name: str
    path: "tuple[Expr | Member, ...]"
    value: Expr
    span: Span
    name_span: Span


@node
class OutSet:
    """``out[index] := value``: set a digital output."""

    index: Expr
    value: Expr
    span: Span


@node
class Clause:
    name: str
    value: Expr
    span: Span
    name_span: Span


@node
class Move:
    """``move ptp|lin|circ TARGET [, TARGET] {CLAUSE}``; circ has (via, end) targets."""

    kind: str  # a compiler.clauses.Motion
    targets: tuple[Expr, ...]
    clauses: tuple[Clause, ...]
    span: Span


@node
class If:
    branches: tuple[tuple[Expr, tuple["Stmt", ...]], ...]  # if + elsif, in order
    orelse: tuple["Stmt", ...]
    span: Span


@node
class While:
    cond: Expr
    body: tuple["Stmt", ...]
    span: Span


@node
class Repeat:
    body: tuple["Stmt", ...]
    cond: Expr
    span: Span


@node
class For:
    var: str
    start: Expr
    stop: Expr
    step: Expr | None
    body: tuple["Stmt", ...]
    span: Span
    var_span: Span


@node
class WaitTime:
    """``wait seconds sec``: dwell with the robot standing still."""

    seconds: Expr
    span: Span


@node
class WaitFor:
    """``wait for cond [timeout seconds sec]``."""

    cond: Expr
    timeout: Expr | None
    span: Span


@node
class CallProc:
    name: str
    args: tuple[Expr, ...]
    span: Span
    name_span: Span


@node
class Print:
    values: tuple[Expr, ...]
    span: Span


@node
class Pause:
    span: Span


@node
class Halt:
    span: Span


@node
class Return:
    value: Expr | None  # None: 'return;' (a procedure)
    span: Span


@node
class Enable:
    """``enable NAME;`` (``on``) or ``disable NAME;``: an interrupt."""

    name: str
    on: bool
    span: Span
    name_span: Span


@node
class Trigger:
    """``trigger when AMOUNT UNIT DIRECTION REFERENCE do ACTION;`` (compiler.triggers):
    the words as written (in lower case); ``action`` is ``("out", index, value)`` or
    ``("set", name, name_span, value)``."""

    amount: Expr
    unit: str
    where: str  # "after start", "before end", ...
    words_span: Span
    action: tuple
    span: Span


@node
class Use:
    kind: str  # "base" or "tool" (compiler.frames.BY_KEYWORD), as written, in lower case
    kind_span: Span
    value: Expr
    span: Span


@node
class Word:
    """A contextual word as a whole statement (compiler.recovery.WORDS: ``retry;``,
    ``trynext;``, ``raise;``, ``raise N, "message";``), as written; the checker knows the words."""

    name: str
    args: tuple[Expr, ...]
    span: Span
    name_span: Span


@node
class OnError:
    """``when error do STATEMENTS``: the error handler a ``seq ... endseq`` body ends with
    (compiler.recovery); the last item of the body's statements (:func:`split_handler`)."""

    word: str  # as written after 'when' (the checker wants compiler.recovery.HANDLER_WORD)
    word_span: Span
    body: tuple["Stmt", ...]
    span: Span


Stmt = Union[Assign, OutSet, Move, If, While, Repeat, For, WaitTime, WaitFor,
             CallProc, Print, Pause, Halt, Return, Use, Enable, Trigger, Word, OnError]


def split_handler(body: tuple) -> tuple[tuple, "OnError | None"]:
    """A routine's body as (its statements, its error handler or None)."""
    if body and type(body[-1]) is OnError:
        return body[:-1], body[-1]
    return body, None


# ---- declarations and the program ----------------------------------------------------

@node
class ConstDecl:
    name: str
    value: Expr
    span: Span


@node
class VarDecl:
    """One ``a, b : TYPE [:= init]`` item; ``spans`` has one span per name."""

    names: tuple[str, ...]
    type: TypeExpr
    init: Expr | None
    span: Span
    spans: tuple[Span, ...]
    #: of a ``persistent`` section (RAPID's PERS): the section's word as written ("" for ``var``)
    section: str = ""
    section_span: Span | None = None


@node
class Param:
    name: str
    type: TypeExpr
    span: Span
    by_ref: bool = False  # 'var': the caller's variable takes the parameter's value when the procedure returns


@node
class Procedure:
    name: str
    params: tuple[Param, ...]
    variables: tuple[VarDecl, ...]
    body: tuple[Stmt, ...]
    span: Span
    name_span: Span
    result: TypeExpr | None = None  # a function's result type; None: a procedure
    interrupt: "InterruptSpec | None" = None  # an interrupt's handler: when it runs


@node
class InterruptSpec:
    """``interrupt NAME when COND OPTIONS;``: the condition, and the options as written
    (``(word, number or None, span)``: ``priority 1``, ``stop``, ``continue``; ``then`` gives
    ``("then", word, span)``), read by the checker."""

    cond: Expr
    options: tuple
    span: Span


@node
class RecordField:
    """One ``a, b : TYPE;`` line of a record's declaration."""

    names: tuple[str, ...]
    type: TypeExpr
    span: Span
    spans: tuple[Span, ...]


@node
class RecordDecl:
    """``record NAME FIELDS endrecord;`` (compiler.records). Its first and last words are
    names to the parser (not reserved): as written, checked by the checker."""

    name: str
    fields: tuple[RecordField, ...]
    span: Span
    name_span: Span
    word: str
    word_span: Span
    end_word: str
    end_span: Span


@node
class ZoneDecl:
    """``zone NAME := SHAPE [signal N];`` (compiler.zones): a world zone of the program. Its
    words are names to the parser (not reserved), checked by the checker; ``output`` is the
    signal zone's output (None: a forbidden zone)."""

    name: str
    shape: Expr
    output: "Expr | None"
    span: Span
    name_span: Span
    word: str
    word_span: Span
    signal_word: str
    signal_span: "Span | None"


Decl = Union[ConstDecl, VarDecl, Procedure, RecordDecl, ZoneDecl]


@node
class Import:
    path: str  # the module's file, as written (relative to the importing file's folder)
    span: Span


@node
class Module:
    """A file of declarations (constants, variables, procedures, functions) that programs
    and other modules import."""

    name: str
    imports: tuple[Import, ...]
    decls: tuple["Decl", ...]
    span: Span


@node
class Program:
    name: str
    spec: str | None  # the system_specification file, as written
    spec_span: Span | None
    decls: tuple[Decl, ...]  # in source order (a constant may use earlier ones)
    body: tuple[Stmt, ...]
    span: Span
    imports: tuple[Import, ...] = ()
