"""Semantic checks: names, types, clauses and limits against the system specification.

The checker walks the AST once, reporting *every* error of the file, and records what
code generation needs in side tables keyed by ``id(node)``: each expression's type, its
value when it is a compile-time constant (folded with :mod:`compiler.semantics`, the
same code the VM runs), and what each name refers to.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from grammar import keywords

from . import ast
from .diagnostics import Diagnostic, did_you_mean
from .frames import BY_KEYWORD as FRAME_BY_KEYWORD
from .frames import BY_TYPE as FRAME_BY_TYPE
from .frames import FRAME_KINDS, describe_name, pose_of, values_of
from .frames import problem as frame_problem
from .interrupts import ACTIONS, CONDITION_TEXT, DEFAULT_PRIORITY, DEFAULT_THEN, PRIORITY, THEN
from .triggers import PLACE_INDEX as TRIGGER_PLACE_INDEX
from .triggers import PLACES as TRIGGER_PLACES
from .triggers import SET_TYPES as TRIGGER_SET_TYPES
from .triggers import UNIT_INDEX as TRIGGER_UNIT_INDEX
from .triggers import UNITS as TRIGGER_UNITS
from .triggers import problem as trigger_problem
from .clauses import BY_NAME as CLAUSE_BY_NAME
from .clauses import CLAUSES as CLAUSE_TABLE
from .clauses import NAMES as CLAUSES
from .clauses import Clause, Motion
from . import zones as world_zones
from .zones import MARGIN as ZONE_MARGIN
from .zones import forbidden as forbidden_zones
from .configs import CONTEXTUAL_NAME, GROUPS as CONFIG_GROUPS, TURN_AXES, WORDS as CONFIG_WORDS, Config
from .configs import turn_problem as config_turn_problem
from .objcode import BUILTINS, FIELDS, MAX_ARRAY_ELEMENTS, MAX_COUNT, MAX_STRING_LENGTH
from .persistent import MAX_ELEMENTS as PERSISTENT_ELEMENTS, SECTION as PERSISTENT
from .records import END_WORD as RECORD_END, MAX_FIELDS as RECORD_FIELDS, WORD as RECORD_WORD, RecordT
from .recovery import HANDLER_WORD, USER_ERRORS, WORDS as HANDLER_WORDS
from .robotstate import CLOCKS, ERROR_ROUTINES, FUNCTIONS as STATE_FUNCTIONS, PROCEDURES as STATE_PROCEDURES
from .robotstate import group_problem, group_value_problem
from .semantics import (GEOMETRIC_BUILTINS, GEOMETRY, STRING_BUILTINS, INT_MAX, INT_MIN, EvalError, binary, call_builtin,
                        compose, geometric_result, make_joint, make_pos, make_pose, make_quat, make_rpy, unary)
from .spec import Spec
from .values import AddJoint, Joint, MainJoint, Pose

# ---- types ---------------------------------------------------------------------------------

INTEGER, REAL, BOOL, STRING = "integer", "real", "bool", "string"
JOINT, POSITION, ORIENTATION, POSE = "joint", "position", "orientation", "pose"
FRAME, TOOL = "frame", "tool"  # poses with a role (compiler.frames): a frame in the world, a TCP on the flange
CONFIG = "config"  # the arm's configuration a pose target names (compiler.configs)
POSE_LIKE = (POSE, FRAME, TOOL)
MAINJOINT, ADDJOINT = "mainjoint(...)", "addjoint(...)"
ERROR = "<error>"  # the type of an expression already reported: suppresses follow-on errors

NAMED_TYPES = (INTEGER, REAL, BOOL, STRING, JOINT, POSITION, ORIENTATION, POSE, FRAME, TOOL, CONFIG)
NUMERIC = (INTEGER, REAL)
#: The types a move's target may have, per motion (a circ move's via pose too).
MOVE_TARGETS: dict[Motion, tuple[str, ...]] = {Motion.PTP: (JOINT, POSE), Motion.LIN: (POSE,), Motion.CIRC: (POSE,)}
MAX_ARRAY_LENGTH = MAX_ARRAY_ELEMENTS  # the object-code contract's limit


@dataclass(frozen=True)
class ArrayT:
    low: int
    high: int
    element: object

    def __str__(self) -> str:
        return f"array[{self.low}..{self.high}] of {self.element}"

    @property
    def length(self) -> int:
        return self.high - self.low + 1


def elements(t) -> int:
    """How many values a variable of type ``t`` holds, all levels together (an array's
    elements times each one's, a record's fields' summed; 1 for any other type)."""
    if isinstance(t, ArrayT):
        return t.length * elements(t.element)
    if isinstance(t, RecordT):
        return sum(elements(ft) for _n, ft in t.fields)
    return 1


GEOMETRIC_KINDS = (POSITION, POSE, ORIENTATION)
# a symbol's kind, as messages say it
_KIND_WORDS = {"const": "constant", "proc": "procedure", "func": "function", "interrupt": "interrupt",
               "record": "record type", "global": "variable", "local": "variable", "zone": "world zone"}


def _kind(t) -> str:
    """A checker type as compiler.semantics' operator tables name it (a frame or a tool
    is a pose there)."""
    return "number" if t in NUMERIC else POSE if t in POSE_LIKE else str(t)


def type_name(t) -> str:
    return str(t)


def a(t) -> str:
    """The type's name with its article: "an integer", "a pose"."""
    name = type_name(t)
    return ("an " if name[:1] in "aeiou" else "a ") + name


def assignable(target, value) -> bool:
    """Whether a value of type ``value`` may be stored where ``target`` is expected: the
    same type, an integer where a real is, a pose where a frame or tool is (and a frame or
    a tool where a pose is), but not a frame where a tool is or the other way round."""
    return target == value or (target == REAL and value == INTEGER) or ERROR in (target, value) or \
        (target in POSE_LIKE and value in POSE_LIKE and POSE in (target, value))


def _literal_text(value: int) -> str:
    """An out-of-range integer literal as a message shows it: in full up to 40 digits,
    else its first and last digits and how many there are (a literal too long to convert
    is a :class:`~compiler.syntax.LongInteger` that keeps its digits)."""
    digits = getattr(value, "digits", None)
    if digits is None:
        return str(value)  # at most 19 digits: the parser converted it
    if len(digits) <= 40:
        return digits
    return f"{digits[:10]}...{digits[-10:]} ({len(digits)} digits)"


# ---- symbols -------------------------------------------------------------------------------

@dataclass
class Symbol:
    kind: str  # "const", "global", "local", "proc", "func"
    name: str
    type: object
    span: ast.Span
    slot: int = -1
    value: object = None
    params: tuple = ()  # for procedures and functions: parameter types
    refs: tuple = ()  # for procedures: which parameters are 'var' (by reference), one bool each
    index: int = -1  # for procedures and functions: index in the procedure table
    file: str = ""  # the file it is declared in
    predeclared: bool = False  # by the language or the specification (world, default_tool, [[tool]] ...)
    persistent: bool = False  # a global of a 'var persistent' section (compiler.persistent)


@dataclass
class ProcScope:
    node: ast.Procedure
    symbol: Symbol
    names: dict[str, Symbol] = field(default_factory=dict)
    slots: list[tuple[str, str]] = field(default_factory=list)
    result: object = None  # a function's result type (None: a procedure)
    interrupt: "InterruptDecl | None" = None  # an interrupt's handler: its options, resolved


@dataclass
class InterruptDecl:
    """An interrupt's options as the checker resolved them (compiler.interrupts)."""

    index: int  # in the object code's interrupt table
    priority: int = DEFAULT_PRIORITY
    stop: bool = True
    then: str = DEFAULT_THEN


def always_returns(body) -> bool:
    """Whether every path through ``body`` ends in a ``return`` (an ``if`` with an ``else``
    whose every branch does; a ``repeat``, whose body runs at least once, whose body does)."""
    for stmt in body:
        if isinstance(stmt, ast.Return) or isinstance(stmt, ast.Word) and stmt.name in HANDLER_WORDS:
            return True  # (retry, trynext and raise never go on to the next statement either)
        if isinstance(stmt, ast.If) and always_returns(stmt.orelse) and \
                all(always_returns(branch) for _cond, branch in stmt.branches):
            return True
        if isinstance(stmt, ast.Repeat) and always_returns(stmt.body):
            return True
    return False


@dataclass
class Declared:
    """What a program declares beside its variables and routines: its record types
    (compiler.records) and its own world zones (compiler.zones), in declaration order; while
    the record types are checked, those not declared yet (by name) and the one whose fields
    are being checked."""

    records: list = field(default_factory=list)  # RecordT
    zones: list = field(default_factory=list)  # compiler.zones.Zone
    later: dict = field(default_factory=dict)  # name -> its ast.RecordDecl
    declaring: str | None = None
    zone_lines: dict = field(default_factory=dict)  # a zone's name -> (its file, its line)


@dataclass
class CheckedProgram:
    """The AST plus everything the checker learned; input to code generation."""

    program: ast.Program
    spec: Spec
    types: dict[int, object]
    values: dict[int, object]
    symbols: dict[int, Symbol]
    globals: list[tuple[str, str]]  # (name, type) per global slot
    global_symbols: dict[str, Symbol]
    procedures: list[ProcScope]
    robots: tuple[str, ...]
    decl_files: dict = field(default_factory=dict)  # id(declaration) -> the module file it is in
    modules: dict = field(default_factory=dict)  # module path -> its name in the object code, in order
    interrupts: list = field(default_factory=list)  # the interrupts' ProcScopes, in table order
    records: list = field(default_factory=list)  # the record types (compiler.records), in declaration order
    zones: list = field(default_factory=list)  # the program's world zones (compiler.zones), in declaration order


_NO_VALUE = object()


class Checker:
    def __init__(self, program: ast.Program, spec: Spec, file: str, decl_files: dict | None = None,
                 sees: dict | None = None):
        self.program, self.spec, self.file = program, spec, file
        self.main_file = file
        self.decl_files = decl_files or {}  # id(declaration) -> its module's file (the others: file)
        self.sees = sees or {}  # module file -> the module files its code may use (it imports)
        self.hidden: Symbol | None = None  # the last name lookup found in a file this one cannot see
        # declarations in source order: the modules' (in the order they come), then the program's
        ranks: dict[str, int] = {}
        for decl in program.decls:
            ranks.setdefault(self.decl_files.get(id(decl), file), len(ranks))
        ranks.setdefault(file, len(ranks))
        self.file_rank = ranks
        self.diagnostics: list[Diagnostic] = []
        self.types: dict[int, object] = {}
        self.values: dict[int, object] = {}
        self.symbols: dict[int, Symbol] = {}
        self.globals: dict[str, Symbol] = {}
        self.global_slots: list[tuple[str, str]] = []
        self.procs: list[ProcScope] = []
        self.scope: ProcScope | None = None
        self.loop_vars: list[str] = []
        self.robots: list[str] = []
        self._expr = {cls: getattr(self, "e_" + cls.__name__) for cls in _EXPR_CLASSES}
        self._stmt = {cls: getattr(self, "s_" + cls.__name__) for cls in _STMT_CLASSES}
        # the active base and tool where known: keyword -> (name, pose), or None (not known here)
        self.active: dict[str, tuple | None] = {}
        self._reach: dict[int, float] = {}  # the arm's reach with a tool (by the tool's value object)
        self._changes: dict[int, tuple] = {}  # (memo of _uses)
        self.proc_changes: frozenset = frozenset()  # what some procedure may make active
        self.interrupts: list[ProcScope] = []  # in the order of the object code's interrupt table
        self.moving: dict[str, str] = {}  # procedures a handler may not call: name -> what they do
        self.all_changes: frozenset = frozenset()  # what some statement of the program may make active
        self.in_handler = False  # checking an error handler's statements (compiler.recovery)
        self.declared = Declared()  # its record types and world zones

    # -- reporting --
    def error(self, span: ast.Span, message: str, hint: str | None = None, file: str | None = None) -> None:
        self.diagnostics.append(Diagnostic(file or self.file, span.line, span.col, span.end_line, span.end_col,
                                           "error", message, hint))

    def warning(self, span: ast.Span, message: str, hint: str | None = None) -> None:
        """Something that compiles and runs, but likely not as meant (the program is still made)."""
        self.diagnostics.append(Diagnostic(self.file, span.line, span.col, span.end_line, span.end_col,
                                           "warning", message, hint))

    # -- names --
    def lookup(self, name: str) -> Symbol | None:
        if self.scope is not None and name in self.scope.names:
            return self.scope.names[name]
        symbol = self.globals.get(name)
        if symbol is not None and not self.can_see(symbol.file):
            self.hidden = symbol
            return None
        return symbol

    def can_see(self, file: str) -> bool:
        """Whether the code being checked may use a name declared in ``file``: the program
        sees every module; a module, itself and the modules it imports (directly or not)."""
        return self.file == self.main_file or not file or file == self.file or file in self.sees.get(self.file, ())

    def hidden_hint(self, name: str) -> tuple[str, str] | None:
        """(message, hint) when ``name`` is declared, but in a file this code cannot see."""
        hidden, self.hidden = self.hidden, None
        if hidden is None or hidden.name != name:
            return None
        return (f"'{name}' is declared in {hidden.file}, which {self.file} does not import",
                "a module sees its own declarations and those of the modules it imports: import it")

    def visible_names(self) -> list[str]:
        names = list(self.globals)
        if self.scope is not None:
            names += list(self.scope.names)
        return names

    def unknown(self, span: ast.Span, name: str, what: str = "name") -> None:
        hidden = self.hidden_hint(name)
        if hidden is not None:
            self.error(span, *hidden)
            return
        guess = did_you_mean(name, self.visible_names())
        self.error(span, f"undeclared {what} '{name}'", f"did you mean '{guess}'?" if guess else None)

    def declare(self, table: dict[str, Symbol], symbol: Symbol) -> bool:
        if symbol.name in keywords():
            self.error(symbol.span, f"'{symbol.name}' is a reserved word and cannot be declared",
                       "choose another name")
            return False
        previous = table.get(symbol.name)  # a local may shadow a global: tables are per scope
        if previous is None and table is not self.globals:
            previous = self.globals.get(symbol.name)
            previous = previous if previous is not None and previous.predeclared else None
        symbol.file = self.file
        if previous is not None and previous.predeclared:
            where = "the language" if previous.file == "" else f"the system specification ({previous.file})"
            self.error(symbol.span, f"'{symbol.name}' is predeclared by {where}: {a(previous.type)}",
                       "choose another name")
            return False
        if previous is not None:
            # (procedures and functions are declared first: the error goes to the later one in the source)
            first, later = sorted((previous, symbol), key=self.source_order)
            where = f" of {first.file}" if first.file != later.file else ""
            self.error(later.span, f"'{symbol.name}' is already declared",
                       f"the first declaration is at line {first.span.line}{where}", file=later.file)
            return False
        table[symbol.name] = symbol
        return True

    def source_order(self, symbol: Symbol) -> tuple:
        return (self.file_rank.get(symbol.file, len(self.file_rank)), symbol.span.line, symbol.span.col)

    # -- types --
    def resolve_type(self, node: ast.TypeExpr):
        if isinstance(node, ast.NamedType):
            if node.name in NAMED_TYPES:
                return node.name
            symbol = self.lookup(node.name)
            if symbol is not None and symbol.kind == "record":
                return symbol.type
            if symbol is not None:
                self.error(node.span, f"'{node.name}' is {a(_KIND_WORDS.get(symbol.kind, symbol.kind))}, not a type")
                return ERROR
            hidden = self.hidden_hint(node.name)
            if hidden is not None:
                self.error(node.span, *hidden)
                return ERROR
            later, declaring = self.declared.later.get(node.name), self.declared.declaring
            if later is not None and declaring is not None:
                itself = later.name == declaring
                self.error(node.span, f"record {declaring} cannot hold itself" if itself
                           else f"record type '{node.name}' is declared after record {declaring} (line "
                                f"{later.name_span.line})",
                           "a record's fields have the record types declared before it (an array of them too); a "
                           "record that holds itself would never end" if itself else
                           f"declare {node.name} first: a record's fields have the record types declared before it")
                return ERROR
            records = tuple(r.name for r in self.declared.records)
            guess = did_you_mean(node.name, NAMED_TYPES + records + ("array",))
            self.error(node.span, f"unknown type '{node.name}'",
                       f"did you mean '{guess}'?" if guess else
                       f"types are {', '.join(NAMED_TYPES + records)}, array, or a record type of the program "
                       f"(record NAME ... endrecord;)")
            return ERROR
        low = self.const_int(node.low, "an array's lower bound")
        high = self.const_int(node.high, "an array's upper bound")
        element = self.resolve_type(node.element)
        if ERROR in (low, high, element):
            return ERROR
        if high < low:
            self.error(node.span, f"array bounds {low}..{high} are empty", "the upper bound must be >= the lower")
            return ERROR
        if not -(2 ** 31) <= low <= high < 2 ** 31:
            self.error(node.span, f"array bounds {low}..{high} must lie within the 32-bit integer range")
            return ERROR
        length = (high - low + 1) * elements(element)
        if length > MAX_ARRAY_LENGTH:
            self.error(node.span, f"array of {length} elements is too large (limit {MAX_ARRAY_LENGTH})")
            return ERROR
        return ArrayT(low, high, element)

    def const_int(self, expr: ast.Expr, what: str):
        t = self.expr(expr)
        if t == ERROR:
            return ERROR
        value = self.values.get(id(expr), _NO_VALUE)
        if t != INTEGER or value is _NO_VALUE:
            self.error(expr.span, f"{what} must be an integer known at compile time")
            return ERROR
        return value

    def expect(self, expr: ast.Expr, wanted, what: str):
        """Check ``expr`` and that its type fits ``wanted`` (a type or a tuple of types)."""
        t = self.expr(expr)
        if t == ERROR or t == wanted:
            return t
        options = wanted if isinstance(wanted, tuple) else (wanted,)
        if t not in options and not any(assignable(w, t) for w in options):
            self.error(expr.span, f"{what} must be {' or '.join(map(type_name, options))}, not {type_name(t)}")
            return ERROR
        return t

    def fold(self, node, fn, *args) -> bool:
        """Record ``fn(*args)`` as ``node``'s constant value; False (reported) if it fails."""
        try:
            value = fn(*args)
        except EvalError as exc:
            self.error(node.span, str(exc))
            return False
        except (OverflowError, ValueError) as exc:
            self.error(node.span, f"cannot compute this constant: {exc}")
            return False
        if isinstance(value, int) and not isinstance(value, bool) and not INT_MIN <= value <= INT_MAX:
            self.error(node.span, f"integer overflow: {value:.3g} is outside the integer range (64-bit)")
            return False
        self.values[id(node)] = value
        return True

    def value_of(self, expr: ast.Expr):
        return self.values.get(id(expr), _NO_VALUE)

    # ---- expressions ----
    def expr(self, node: ast.Expr):
        t = self._expr[type(node)](node)
        self.types[id(node)] = t
        return t

    def e_Number(self, node: ast.Number):
        value = node.value
        if isinstance(value, int):
            if value > INT_MAX:
                digits = len(getattr(value, "digits", ""))
                self.error(node.span, f"the integer {_literal_text(value)} is too large: integers are 64-bit, "
                                      f"from {INT_MIN} to {INT_MAX}",
                           "write it as a real (with a decimal point) if you need a larger number"
                           if digits <= 308 else None)  # 309 digits and more are beyond a real too (1.8e308)
                return ERROR
            self.values[id(node)] = value
            return INTEGER
        if value == float("inf"):
            self.error(node.span, "this number is too large for a real (the largest is about 1.8e308)")
            return ERROR
        self.values[id(node)] = value
        return REAL

    def e_String(self, node: ast.String):
        if len(node.value) > MAX_STRING_LENGTH:
            self.error(node.span, f"a string of {len(node.value)} characters is too long (at most "
                                  f"{MAX_STRING_LENGTH})")
            return ERROR
        self.values[id(node)] = node.value
        return STRING

    def e_Bool(self, node: ast.Bool):
        self.values[id(node)] = node.value
        return BOOL

    def e_Ref(self, node: ast.Ref):
        symbol = self.lookup(node.name)
        if symbol is None:
            if node.name in BUILTINS or node.name in CONSTRUCTORS:
                self.error(node.span, f"'{node.name}' is a function: it needs arguments in parentheses")
            else:
                self.unknown(node.span, node.name)
            return ERROR
        if symbol.kind == "proc":
            self.error(node.span, f"'{node.name}' is a procedure, not a value",
                       f"call it as a statement: call {node.name}(...);")
            return ERROR
        if symbol.kind == "zone":
            self.error(node.span, f"'{node.name}' is a world zone, not a value",
                       "a zone is declared for the whole program: the planner and the safety supervisor keep the "
                       "robot out of it")
            return ERROR
        if symbol.kind == "record":
            self.error(node.span, f"'{node.name}' is a record type, not a value",
                       f"make one with its fields' values: {node.name}({', '.join(symbol.type.names)})")
            return ERROR
        if symbol.kind == "interrupt":
            self.error(node.span, f"'{node.name}' is an interrupt, not a value",
                       f"switch it with 'enable {node.name};' and 'disable {node.name};'")
            return ERROR
        if symbol.kind == "func":
            self.error(node.span, f"'{node.name}' is a function: call it with its arguments in parentheses",
                       f"write {node.name}({', '.join(type_name(t) for t in symbol.params)})")
            return ERROR
        self.symbols[id(node)] = symbol
        if symbol.kind == "const" and symbol.value is not _NO_VALUE:
            self.values[id(node)] = symbol.value
        return symbol.type

    def e_Unary(self, node: ast.Unary):
        if node.op == "not":
            t = self.expect(node.operand, BOOL, "the operand of 'not'")
            result = BOOL
        else:
            t = result = self.expr(node.operand)
            if t not in NUMERIC + (ERROR,) and not (t == POSITION and node.op == "-"):
                self.error(node.operand.span, f"the operand of unary '{node.op}' must be integer or real"
                                              + (" (or a position, for '-')" if node.op == "-" else "")
                                              + f", not {type_name(t)}")
                t = ERROR
        if t == ERROR:
            return ERROR
        value = self.value_of(node.operand)
        if value is not _NO_VALUE and not self.fold(node, unary, node.op, value):
            return ERROR
        return result

    def e_Binary(self, node: ast.Binary):
        op = node.op
        lt, rt = self.expr(node.left), self.expr(node.right)
        if ERROR in (lt, rt):
            return ERROR
        result = self.binary_type(node, op, lt, rt)
        if result == ERROR:
            return ERROR
        left, right = self.value_of(node.left), self.value_of(node.right)
        if left is not _NO_VALUE and right is not _NO_VALUE and not self.fold(node, binary, op, left, right):
            return ERROR
        return result

    def binary_type(self, node: ast.Binary, op: str, lt, rt):
        pair = f"{type_name(lt)} {op} {type_name(rt)}"
        if op in ("and", "or"):
            if lt == BOOL and rt == BOOL:
                return BOOL
            self.error(node.op_span, f"'{op}' needs two bool operands, not {pair}")
            return ERROR
        if op in ("div", "mod"):
            if lt == INTEGER and rt == INTEGER:
                return INTEGER
            self.error(node.op_span, f"'{op}' needs two integers, not {pair}",
                       "use '/' for real division" if op == "div" else None)
            return ERROR
        if op in ("=", "<>"):
            if lt == rt or (lt in NUMERIC and rt in NUMERIC) or (lt in POSE_LIKE and rt in POSE_LIKE):
                if isinstance(lt, (ArrayT, RecordT)):
                    self.error(node.op_span, f"{'arrays' if isinstance(lt, ArrayT) else 'records'} cannot be "
                                             "compared", "compare their elements or fields")
                    return ERROR
                return BOOL
            self.error(node.op_span, f"cannot compare {pair}")
            return ERROR
        if op in ("<", "<=", ">", ">="):
            if (lt in NUMERIC and rt in NUMERIC) or (lt == STRING and rt == STRING):
                return BOOL
            self.error(node.op_span, f"'{op}' needs two numbers or two strings, not {pair}")
            return ERROR
        if lt in NUMERIC and rt in NUMERIC:
            if op == "/":
                return REAL
            return INTEGER if lt == rt == INTEGER else REAL
        if op == "+" and lt == STRING and rt == STRING:
            return STRING
        geometric = GEOMETRY.get((op, _kind(lt), _kind(rt)))
        if geometric is not None:
            return geometric[0]
        if _kind(lt) in GEOMETRIC_KINDS or _kind(rt) in GEOMETRIC_KINDS:
            allowed = ", ".join(f"{left} {op} {right}" for o, left, right in GEOMETRY if o == op)
            hint = f"with positions, poses and orientations '{op}' takes: {allowed}" if allowed else \
                "see 'Pose arithmetic' in docs/language.md"
            if op == "+" and lt == rt and lt in (POSE, ORIENTATION):
                hint += f"; to compose two {lt}s, use '*' (the right one given in the frame of the left one)"
            self.error(node.op_span, f"'{op}' is not defined for {pair}", hint)
            return ERROR
        self.error(node.op_span, f"'{op}' needs two numbers, not {pair}")
        return ERROR

    def element_type(self, container, index: ast.Expr, container_span: ast.Span, what: str):
        """The type of ``container[index]``, checking the index; ERROR when it cannot be indexed."""
        index_t = self.expect(index, INTEGER, "an index")
        if ERROR in (container, index_t):
            return ERROR
        i = self.value_of(index)
        if isinstance(container, ArrayT):
            if i is not _NO_VALUE and not container.low <= i <= container.high:
                self.error(index.span, f"index {i} is outside the array bounds {container.low}..{container.high}")
            return container.element
        if container == JOINT:
            n = len(self.spec.axes)
            if i is not _NO_VALUE and not 1 <= i <= n:
                self.error(index.span, f"axis {i} does not exist: {self.spec.name} has axes 1..{n}")
            return REAL
        self.error(container_span, f"{what} is {a(container)} and cannot be indexed", "only arrays and joints can")
        return ERROR

    def e_Index(self, node: ast.Index):
        base = self.expr(node.base)
        t = self.element_type(base, node.index, node.base.span, "this")
        if t == REAL and base == JOINT:
            j, i = self.value_of(node.base), self.value_of(node.index)
            if j is not _NO_VALUE and i is not _NO_VALUE and 1 <= i <= len(j.axes):
                self.values[id(node)] = j.axes[i - 1]
        return t

    def e_Field(self, node: ast.Field):
        base = self.expr(node.base)
        if base == ERROR:
            return ERROR
        if isinstance(base, RecordT):
            return self.member_type(base, node.name, node.span)
        if base not in (POSITION, POSE):
            self.error(node.span, f"{a(base)} has no field '{node.name}'",
                       "fields x, y, z belong to positions and poses")
            return ERROR
        if node.name not in ("x", "y", "z"):
            guess = did_you_mean(node.name, ("x", "y", "z"))
            self.error(node.span, f"{a(base)} has no field '{node.name}'",
                       f"did you mean '{guess}'?" if guess else "its fields are x, y, z")
            return ERROR
        value = self.value_of(node.base)
        if value is not _NO_VALUE:
            position = value.position if isinstance(value, Pose) else value
            self.values[id(node)] = getattr(position, node.name)
        return REAL

    def member_type(self, record, name: str, span: ast.Span):
        """The type of field ``name`` of a value of type ``record`` (ERROR, reported, when it has none)."""
        if record == ERROR:
            return ERROR
        if record in (POSITION, POSE) and name in FIELDS:
            self.error(span, f"{a(record)}'s {', '.join(FIELDS)} are read, not assigned",
                       "build a new one: pos(...), or pose(pos(...), ...)")
            return ERROR
        if not isinstance(record, RecordT):
            self.error(span, f"{a(record)} has no field '{name}'", "only records have fields to assign")
            return ERROR
        if name not in record.names:
            guess = did_you_mean(name, record.names)
            self.error(span, f"record {record.name} has no field '{name}'",
                       f"did you mean '{guess}'?" if guess else f"its fields are {', '.join(record.names)}")
            return ERROR
        return record.type_of(name)

    def record_value(self, node: ast.Call, symbol: Symbol):
        """``part_t(v1, ..., vn)``: a record made of its fields' values, in declaration order."""
        record: RecordT = symbol.type
        self.symbols[id(node)] = symbol
        if len(node.args) != len(record.fields):
            self.error(node.span, f"record {record.name} has {len(record.fields)} field"
                                  f"{'s' if len(record.fields) != 1 else ''}: give a value for each, in order: "
                                  f"{node.name}({', '.join(record.names)})")
            for arg in node.args:
                self.expr(arg)
            return ERROR
        for arg, (name, t) in zip(node.args, record.fields):
            value = self.expr(arg)
            if ERROR not in (t, value) and not assignable(t, value):
                self.error(arg.span, f"field '{name}' of {record.name} is {a(t)}, not {a(value)}")
        return record

    def e_Input(self, node: ast.Input):
        if self.expect(node.index, INTEGER, "an input number") != ERROR:
            self.check_io_index(node.index, self.spec.inputs, "input")
        return BOOL

    def e_Output(self, node: ast.Output):
        if self.expect(node.index, INTEGER, "an output number") != ERROR:
            self.check_io_index(node.index, self.spec.outputs, "output")
        return BOOL

    def check_io_index(self, index: ast.Expr, count: int, what: str, kind: str = "digital") -> None:
        i = self.value_of(index)
        if i is not _NO_VALUE and not 1 <= i <= count:
            named = f"{kind} {what}s" if kind != "digital" else f"{what}s"  # ("has outputs 1..16", as always)
            has = f"has {named} 1..{count}" if count else f"has no {named}"
            self.error(index.span, f"{kind} {what} {i} does not exist: {self.spec.name} {has}",
                       f"the specification declares them ([[analog_{what}]] tables)" if kind == "analog" else None)

    def e_Call(self, node: ast.Call):
        name = node.name
        if name in CONSTRUCTORS and (name != CONTEXTUAL_NAME or self.lookup(name) is None):
            self.hidden = None  # (a 'config' declared where this code cannot see it: the constructor here)
            return CONSTRUCTORS[name](self, node)
        symbol = self.lookup(name)
        if symbol is not None and symbol.kind == "record":
            return self.record_value(node, symbol)
        if name in BUILTINS and not (name in STRING_BUILTINS and symbol is not None and symbol.kind == "func"):
            return self.builtin(node)  # (a string function's name: a program's own function of it first)
        if name in STATE_FUNCTIONS and (symbol is None or symbol.kind != "func"):  # (a routine of its own first)
            return self.state_routine(node, STATE_FUNCTIONS[name])
        if symbol is not None and symbol.kind == "func":
            self.symbols[id(node)] = symbol
            self.arguments(node, symbol, "function")
            return symbol.type
        if symbol is not None and symbol.kind == "proc" or symbol is None and name in STATE_PROCEDURES:
            self.error(node.name_span, f"procedure '{name}' has no value", f"call it as a statement: call {name}(...);")
        elif symbol is not None:
            self.error(node.name_span, f"'{name}' is {a(symbol.type)}, not a function")
        elif (hidden := self.hidden_hint(name)) is not None:
            self.error(node.name_span, *hidden)
        else:
            guess = did_you_mean(name, list(BUILTINS) + list(CONSTRUCTORS))
            self.error(node.name_span, f"unknown function '{name}'", f"did you mean '{guess}'?" if guess else None)
        for arg in node.args:
            self.expr(arg)
        return ERROR

    def state_routine(self, node, routine):
        """A built-in routine of the robot's state (compiler.robotstate): its arguments
        (a clock's number within 1..CLOCKS when it is a constant); its result type."""
        if not self.arity(node, len(routine.params)) or not self.typed_arguments(node, routine.params):
            return ERROR
        values = [self.value_of(arg) for arg in node.args]
        if routine.number == "clock" and values[0] is not _NO_VALUE and not 1 <= values[0] <= CLOCKS:
            self.error(node.args[0].span, f"clock {values[0]} does not exist: a program has clocks 1..{CLOCKS}")
            return ERROR
        if routine.number == "analog input":
            self.check_io_index(node.args[0], len(self.spec.analog_inputs), "input", "analog")
        if routine.number == "analog output":
            channels = self.spec.analog_outputs
            self.check_io_index(node.args[0], len(channels), "output", "analog")
            if len(values) > 1 and values[0] is not _NO_VALUE and values[1] is not _NO_VALUE \
                    and 1 <= values[0] <= len(channels):
                problem = channels[values[0] - 1].problem(values[0], values[1], "output")
                if problem is not None:
                    self.error(node.args[1].span, problem)
                    return ERROR
        if routine.number in ("input group", "output group"):
            what = routine.number.split()[0]
            first, bits = values[0], values[1]
            if bits is not _NO_VALUE and first is _NO_VALUE:
                first = 1  # (the group's size alone: checked against the first input)
            if first is not _NO_VALUE and bits is not _NO_VALUE:
                problem = group_problem(first, bits, self.spec.inputs if what == "input" else self.spec.outputs,
                                        what)
                if problem is not None:
                    self.error(node.span, problem)
                    return ERROR
                if what == "output" and values[2] is not _NO_VALUE:
                    problem = group_value_problem(values[2], bits)
                    if problem is not None:
                        self.error(node.args[2].span, problem)
                        return ERROR
        if routine.number == "output":
            self.check_io_index(node.args[0], self.spec.outputs, "output")
            if values[1] is not _NO_VALUE and not values[1] > 0:
                self.error(node.args[1].span, f"a pulse of {values[1]} s: it must last more than 0 s")
                return ERROR
        return routine.result or None

    def typed_arguments(self, node, params: tuple) -> bool:
        """Check a built-in's arguments against its parameters' types (one message each,
        naming the argument by its place); whether all fit."""
        fit = True
        for i, (arg, wanted) in enumerate(zip(node.args, params)):
            what = f"the {('first', 'second', 'third')[i]} argument" if len(params) > 1 else "the argument"
            fit = self.expect(arg, wanted, f"{what} of {node.name}") != ERROR and fit
        return fit

    def arity(self, node: ast.Call, count: int) -> bool:
        if len(node.args) != count:
            self.error(node.span, f"{node.name} takes {count} argument{'s' if count != 1 else ''}, "
                                  f"not {len(node.args)}")
            for arg in node.args:
                self.expr(arg)
            return False
        return True

    def builtin(self, node: ast.Call):
        name = node.name
        if not self.arity(node, BUILTINS[name]):
            return ERROR
        if name in GEOMETRIC_BUILTINS:
            return self.geometric_builtin(node)
        if name in STRING_BUILTINS:
            return self.string_builtin(node)
        types = [self.expect(arg, NUMERIC, f"the argument of {name}") for arg in node.args]
        if ERROR in types:
            return ERROR
        if name in ("round", "trunc"):
            result = INTEGER
        elif name in ("abs", "min", "max"):
            result = INTEGER if all(t == INTEGER for t in types) else REAL
        else:
            result = REAL
        values = [self.value_of(arg) for arg in node.args]
        if _NO_VALUE not in values:
            if result == REAL:
                values = [float(v) for v in values]
            if not self.fold(node, call_builtin, name, values):
                return ERROR
        return result

    def string_builtin(self, node: ast.Call):
        """``str_len``, ``str_part``, ``str_find``, ``num_to_str``, ``str_to_num``: typed by
        STRING_BUILTINS, computed here when every argument is a constant."""
        name = node.name
        params, result = STRING_BUILTINS[name]
        if not self.typed_arguments(node, params):
            return ERROR
        values = [self.value_of(arg) for arg in node.args]
        if _NO_VALUE not in values:
            values = [float(v) if wanted == REAL else v for v, wanted in zip(values, params)]
            if not self.fold(node, call_builtin, name, values):
                return ERROR
        return result

    def geometric_builtin(self, node: ast.Call):
        """``inv``, ``distance``, ``tool_offset``: typed by GEOMETRIC_BUILTINS."""
        name = node.name
        types = [self.expr(arg) for arg in node.args]
        if ERROR in types:
            return ERROR
        result = geometric_result(name, tuple(_kind(t) for t in types))
        if result is None:
            forms = " or ".join(f"{name}({', '.join(w.replace('|', ' or ') for w in wanted)})"
                                for wanted, _r in GEOMETRIC_BUILTINS[name])
            self.error(node.span, f"{name} is not defined for {', '.join(map(a, types))}", f"it takes {forms}")
            return ERROR
        values = [self.value_of(arg) for arg in node.args]
        if _NO_VALUE not in values and not self.fold(node, call_builtin, name, values):
            return ERROR
        return result

    def numbers(self, node: ast.Call, count: int | None, what: str):
        """Check numeric arguments; returns their constant values or None."""
        if count is not None and not self.arity(node, count):
            return ERROR
        ok = all([self.expect(arg, NUMERIC, f"{what}") != ERROR for arg in node.args])
        if not ok:
            return ERROR
        values = [self.value_of(arg) for arg in node.args]
        return None if _NO_VALUE in values else values

    def c_part(self, node: ast.Call):
        """``mainjoint``/``addjoint`` anywhere but as an argument of ``joint``."""
        for arg in node.args:
            self.expr(arg)
        self.error(node.span, f"{node.name}(...) is only meaningful as an argument of joint(...)",
                   f"write joint({node.name}(...))" if node.name == "mainjoint" else
                   "write joint(mainjoint(...), addjoint(...))")
        return ERROR

    def joint_part(self, node: ast.Expr, group: str):
        """Check an argument of ``joint``: ``mainjoint(...)`` or ``addjoint(...)``."""
        if isinstance(node, ast.Call) and node.name in ("mainjoint", "addjoint"):
            t = self.c_mainjoint(node, "main" if node.name == "mainjoint" else "additional")
            self.types[id(node)] = t
            return t
        return self.expr(node)

    def c_mainjoint(self, node: ast.Call, group: str = "main"):
        axes = self.spec.main_axes if group == "main" else self.spec.additional_axes
        values = self.numbers(node, None, f"an axis value of {node.name}")
        if values == ERROR:
            return ERROR
        if len(node.args) != len(axes):
            names = ", ".join(a.name for a in axes) or "none"
            self.error(node.span, f"{node.name} has {len(node.args)} value{'s' if len(node.args) != 1 else ''} "
                                  f"but {self.spec.name} has {len(axes)} {group} axes ({names})")
            return ERROR
        if values is not None:
            cls = MainJoint if group == "main" else AddJoint
            self.values[id(node)] = cls(tuple(float(v) for v in values))
        return MAINJOINT if group == "main" else ADDJOINT

    def c_joint(self, node: ast.Call):
        if not 1 <= len(node.args) <= 2:
            self.error(node.span, "joint takes mainjoint(...) and, for additional axes, addjoint(...)",
                       "write joint(mainjoint(a1, ..., an))")
            for arg in node.args:
                self.expr(arg)
            return ERROR
        first = self.joint_part(node.args[0], "main")
        ok = first != ERROR
        if ok and first != MAINJOINT:
            self.error(node.args[0].span, f"the first argument of joint must be mainjoint(...), not {type_name(first)}",
                       "write joint(mainjoint(a1, ..., an))")
            ok = False
        add_value = AddJoint(())
        if len(node.args) == 2:
            second = self.joint_part(node.args[1], "additional")
            if second not in (ADDJOINT, ERROR):
                self.error(node.args[1].span, f"the second argument of joint must be addjoint(...), "
                                              f"not {type_name(second)}")
                ok = False
            ok = ok and second != ERROR
            add_value = self.value_of(node.args[1])
        elif self.spec.additional_axes:
            self.error(node.span, f"{self.spec.name} has additional axes: joint needs addjoint(...) too")
            ok = False
        if not ok:
            return ERROR
        main_value = self.value_of(node.args[0])
        if main_value is not _NO_VALUE and add_value is not _NO_VALUE:
            self.values[id(node)] = make_joint(main_value.values, add_value.values)
        return JOINT

    def numeric_constructor(self, node: ast.Call, count: int, what: str, make, result):
        """``pos``, ``rpy``, ``quat``: ``count`` numbers in, folded when all are constant."""
        values = self.numbers(node, count, what)
        if values == ERROR:
            return ERROR
        if values is not None and not self.fold(node, make, *(float(v) for v in values)):
            return ERROR
        return result

    def c_pos(self, node: ast.Call):
        return self.numeric_constructor(node, 3, "a coordinate of pos (mm)", make_pos, POSITION)

    def c_rpy(self, node: ast.Call):
        return self.numeric_constructor(node, 3, "an angle of rpy (deg)", make_rpy, ORIENTATION)

    def c_quat(self, node: ast.Call):
        return self.numeric_constructor(node, 4, "a component of quat", make_quat, ORIENTATION)

    def c_pose(self, node: ast.Call):
        """``pose(P, O [, C])``, and ``frame(P, O)`` and ``tool(P, O)``: the same value,
        typed; only a pose names the arm's configuration (compiler.configs)."""
        if node.name != POSE and len(node.args) == 3:
            self.error(node.args[2].span, f"a {node.name} has no configuration: {node.name} takes a position and an "
                                          "orientation", "frames and tools are not reached by the arm: only a pose "
                                                         "target names a configuration")
            for arg in node.args:
                self.expr(arg)
            return ERROR
        if node.name == POSE and len(node.args) == 3:
            c = self.expect(node.args[2], CONFIG, "the third argument of pose (its configuration)")
        elif node.name == POSE and len(node.args) != 2:
            self.error(node.span, f"pose takes 2 or 3 arguments (a position, an orientation and optionally a "
                                  f"configuration), not {len(node.args)}")
            for arg in node.args:
                self.expr(arg)
            return ERROR
        elif not self.arity(node, 2):
            return ERROR
        else:
            c = None
        p = self.expect(node.args[0], POSITION, f"the first argument of {node.name}")
        o = self.expect(node.args[1], ORIENTATION, f"the second argument of {node.name}")
        if ERROR in (p, o, c):
            return ERROR
        values = [self.value_of(arg) for arg in node.args]
        if _NO_VALUE not in values:
            self.values[id(node)] = make_pose(*values)
        return node.name

    def c_config(self, node: ast.Call):
        """``config(WORDS..., [T1, T4, T6])`` (compiler.configs): the words first, each
        group at most once; a name that is a word is the word whatever the program declares
        (the words mean something only here); then none or three integer turns."""
        named: dict[str, tuple[int, str]] = {}
        turns: list[ast.Expr] = []
        ok = True
        for arg in node.args:
            word = arg.name if isinstance(arg, ast.Ref) else None
            if word in CONFIG_WORDS:
                ok = self.config_word(arg, word, named, turns) and ok
                continue
            if word is not None and not turns and self.lookup(word) is None and self.hidden is None:
                guess = did_you_mean(word, list(CONFIG_WORDS))
                words = ", ".join(w for g in CONFIG_GROUPS for w in g.words)
                self.error(arg.span, f"unknown configuration word '{word}'",
                           f"did you mean '{guess}'?" if guess else f"the words are {words}; then three turn numbers "
                                                                     "(A1, A4, A6)")
                ok = False
                continue
            turns.append(arg)
        for turn in turns:
            t = self.expr(turn)
            if t not in (INTEGER, ERROR):
                self.error(turn.span, f"a turn number must be an integer, not {type_name(t)}",
                           "turn k of an axis means -180 + 360 k <= its value < 180 + 360 k")
            ok = ok and t == INTEGER
        if len(turns) not in (0, len(TURN_AXES)):
            self.error(turns[0].span.to(turns[-1].span), f"config takes three turn numbers (A1, A4, A6) or none, "
                                                         f"not {len(turns)}")
            ok = False
        if not ok:
            return ERROR
        values = [self.value_of(turn) for turn in turns]
        if _NO_VALUE not in values:
            self.values[id(node)] = Config(**{f: v for f, (v, _w) in named.items()},
                                           turns=tuple(values) if values else None)
        return CONFIG

    def config_word(self, arg: ast.Ref, word: str, named: dict, turns: list) -> bool:
        """One word of ``config(...)``: before the turns, its group not given yet."""
        group, value = CONFIG_WORDS[word]
        if turns:
            self.error(arg.span, f"'{word}' comes after the turn numbers: config's words come first",
                       "write config(WORDS..., T1, T4, T6)")
            return False
        if group.field in named:
            first = named[group.field][1]
            self.error(arg.span, f"'{word}' is given twice" if first == word else
                                 f"'{word}': {group.what} is already given ('{first}')",
                       f"config names {group.what} once: {' or '.join(group.words)}")
            return False
        named[group.field] = (value, word)
        return True

    # ---- statements ----
    def stmts(self, body) -> None:
        dispatch = self._stmt
        function = self.scope is not None and self.scope.result is not None
        handler = self.scope is not None and self.scope.interrupt is not None
        for k, stmt in enumerate(body):
            if type(stmt) is ast.Trigger:
                self.trigger_belongs(stmt, body[k + 1:])
            if function and type(stmt) in _NOT_IN_FUNCTIONS:
                self.error(stmt.span, f"a function computes a value: '{_NOT_IN_FUNCTIONS[type(stmt)]}' is not "
                                      f"allowed in function '{self.scope.node.name}'",
                           "move, wait, set outputs, print, pause, halt and call procedures in a procedure")
            elif handler and type(stmt) in _NOT_IN_HANDLERS:
                self.error(stmt.span, f"'{_NOT_IN_HANDLERS[type(stmt)]}' is not allowed in interrupt "
                                      f"'{self.scope.node.name}'",
                           "a handler runs beside the motion or its stop: it may not move, pause or use a frame "
                           "or tool (end with 'then halt' and move in the program)")
            changes = self.frame_changes(stmt) if type(stmt) in _COMPOUND else ()
            for keyword in changes:  # inside: not known (a loop's second pass, a later branch)
                self.active[keyword] = None
            dispatch[type(stmt)](stmt)
            for keyword in changes:
                self.active[keyword] = None

    # ---- the active base and tool (for the reach of constant targets) ----
    def frame_changes(self, stmt) -> frozenset:
        """The kinds (``base``, ``tool``) that ``stmt`` may make active: its ``use``
        statements, and those of every procedure when it calls one."""
        uses, calls = _uses(stmt, self._changes)
        return uses | self.proc_changes if calls else uses

    def start_frames(self, known: bool) -> None:
        """The active base and tool at the start of the main program (``known``) or of a
        routine (known only where the program never changes them)."""
        for kind in FRAME_KINDS:
            changed = kind.keyword in self.all_changes
            self.active[kind.keyword] = (kind.default, self.globals[kind.default].value) \
                if known or not changed else None

    def predeclare(self) -> None:
        """``world``, ``default_tool`` and the specification's ``[[frame]]`` and ``[[tool]]``
        (compiler.frames): constants every file sees."""
        none = ast.Span(0, 0, 0, 0)
        defaults = {"frame": (0.0,) * 6, "tool": tuple(self.spec.tool)}
        for kind in FRAME_KINDS:
            self.globals[kind.default] = Symbol("const", kind.default, kind.type, none,
                                                value=pose_of(defaults[kind.type]), predeclared=True)
        for type_, name, values in self.spec.named_frames:
            self.globals[name] = Symbol("const", name, type_, none, value=pose_of(values),
                                        file=self.spec.file.rsplit("/", 1)[-1] or self.spec.file, predeclared=True)

    def s_Use(self, node: ast.Use):
        kind = FRAME_BY_KEYWORD.get(node.kind)
        if kind is None:
            typed = FRAME_BY_TYPE.get(node.kind)  # 'use frame': the type's name, not the statement's
            guess = typed.keyword if typed is not None else did_you_mean(node.kind, list(FRAME_BY_KEYWORD), cutoff=0.5)
            self.error(node.kind_span, f"'use {node.kind}': expected 'use base FRAME;' or 'use tool TOOL;'",
                       f"did you mean 'use {guess}'?" if guess else None)
            self.expr(node.value)
            return
        self.active[kind.keyword] = None
        t = self.expr(node.value)
        if t == ERROR:
            return
        if t not in (kind.type, POSE):
            other = FRAME_BY_TYPE.get(t)
            self.error(node.value.span, f"'use {kind.keyword}' needs {a(kind.type)} (or a pose), not {a(t)}",
                       f"{a(t)} is made active with 'use {other.keyword}'" if other is not None else None)
            return
        value = self.value_of(node.value)
        if value is _NO_VALUE:
            return
        problem = frame_problem(kind, values_of(value))
        if problem is not None:
            self.error(node.value.span, problem)
            return
        self.active[kind.keyword] = (describe_name(ast.expression_text(node.value)), value)

    def variable(self, name: str, span: ast.Span, node) -> Symbol | None:
        symbol = self.lookup(name)
        if symbol is None:
            self.unknown(span, name, "variable")
            return None
        if symbol.kind == "const":
            self.error(span, f"'{name}' is a constant and cannot be assigned")
            return None
        if symbol.kind in ("proc", "func", "record", "interrupt", "zone"):
            self.error(span, f"'{name}' is a {_KIND_WORDS[symbol.kind]} and cannot be assigned",
                       "a function's result is given with 'return VALUE;'" if symbol.kind == "func" else None)
            return None
        self.symbols[id(node)] = symbol
        return symbol

    def s_Assign(self, node: ast.Assign):
        symbol = self.variable(node.name, node.name_span, node)
        if symbol is not None and node.name in self.loop_vars:
            self.error(node.name_span, f"'{node.name}' is the variable of an enclosing for loop",
                       "a for loop's variable cannot be assigned inside the loop")
        target = symbol.type if symbol is not None else ERROR
        path = node.path
        for k, selector in enumerate(path):
            if isinstance(selector, ast.Member):
                target = self.member_type(target, selector.name, selector.span)
                continue
            if target == JOINT and k < len(path) - 1:
                self.error(selector.span, "a joint's axis value is a real and cannot be indexed")
                target = ERROR
            target = self.element_type(target, selector, node.name_span, f"'{node.name}'")
        value = self.expr(node.value)
        if ERROR not in (target, value) and not assignable(target, value):
            last = path[-1] if path else None
            self.error(node.value.span, f"cannot assign {a(value)} to '{node.name}', which is {a(target)}"
                       if last is None else f"cannot assign {a(value)} to field '{last.name}', which is {a(target)}"
                       if isinstance(last, ast.Member) else
                       f"cannot assign {a(value)} to an element of type {type_name(target)}")

    def s_OutSet(self, node: ast.OutSet):
        if self.expect(node.index, INTEGER, "an output number") != ERROR:
            self.check_io_index(node.index, self.spec.outputs, "output")
        self.expect(node.value, BOOL, "a digital output's value")

    def s_Move(self, node: ast.Move):
        wanted = MOVE_TARGETS[node.kind]
        names = ["the via pose", "the end pose"] if node.kind == Motion.CIRC else ["the target"]
        if len(node.targets) != len(names):
            self.error(node.span, "move circ takes two poses: via, end" if node.kind == Motion.CIRC
                       else f"move {node.kind} takes one target, not {len(node.targets)}")
            for target in node.targets:
                self.expr(target)
        else:
            for target, what in zip(node.targets, names):
                t = self.expect(target, wanted, f"{what} of move {node.kind}")
                value = self.value_of(target)
                if t == JOINT and value is not _NO_VALUE:
                    self.check_joint_limits(target, value)
                elif t in POSE_LIKE and value is not _NO_VALUE:
                    self.check_reach(target, value)
                    self.check_turns(target, value)
        self.clauses(node)

    def check_turns(self, target: ast.Expr, value: Pose) -> None:
        """The turns a constant pose target names, each with a value within its axis's
        limits (compiler.configs; the rest is found when the move runs)."""
        axes = self.spec.main_axes
        if value.config is None or len(axes) <= max(TURN_AXES):
            return
        problem = config_turn_problem(value.config, [(a.min, a.max) for a in axes], [a.name for a in axes])
        if problem is not None:
            self.error(target.span, f"the target's configuration cannot be reached: {problem}")

    def check_joint_limits(self, target: ast.Expr, value: Joint) -> None:
        for axis, v in zip(self.spec.axes, value.axes):
            problem = axis.target_problem(v)
            if problem is not None:
                self.error(target.span, problem)

    def check_reach(self, target: ast.Expr, value: Pose) -> None:
        """A constant pose target within the arm's reach, in the active base with the
        active tool where both are known here (else it is checked when the move runs)."""
        base, tool = self.active["base"], self.active["tool"]
        if base is None or tool is None:
            return
        p = (value if base[0] == "world" else compose(base[1], value)).position  # (world: the identity)
        distance = self.spec.shoulder_distance(p.x, p.y, p.z)
        reach = self._reach.get(id(tool[1]))
        if reach is None:
            reach = self._reach[id(tool[1])] = self.spec.arm_reach(values_of(tool[1]))
        frames = [f"{kind} '{name}'" for kind, (name, _v), default in
                  (("base", base, "world"), ("tool", tool, "default_tool")) if name != default]
        where = f" (in {' with '.join(frames)})" if frames else ""
        if reach > 0 and distance > reach:
            self.error(target.span, f"pose out of reach{where}: its position is {distance:.1f} mm from the "
                                    f"shoulder, but {self.spec.name}'s arm reaches at most {reach:.1f} mm")
        # (the tool centre point: the flange's path when it runs)
        for zone in forbidden_zones(self.spec.zones + tuple(self.declared.zones)):
            if zone.depth(p.x, p.y, p.z) > -ZONE_MARGIN:
                self.error(target.span, f"the target{where} is in zone '{zone.name}' ({zone.describe()}), or within "
                                        f"{ZONE_MARGIN:g} mm of it: no move goes there",
                           "zone '{}' is declared at {}:{}: the tool and the flange never go there".format(
                               zone.name, *self.declared.zone_lines[zone.name]) if zone in self.declared.zones else
                           "the specification's [[zone]] tables are where the tool and the flange never go")

    def clauses(self, node: ast.Move) -> None:
        """The move's clauses against the clause table (compiler.clauses): known, given
        once, applying to the motion, of the right type and, when constant, in range;
        and the specification's defaults of those it leaves out in range for it."""
        seen: dict[str, ast.Clause] = {}
        kind = node.kind
        for clause in node.clauses:
            name = clause.name
            entry = CLAUSE_BY_NAME.get(name)
            if entry is None:
                guess = did_you_mean(name, CLAUSES)
                hint = f"did you mean '{guess}'?" if guess else f"clauses are {', '.join(CLAUSES)}"
                if clause.span.line > node.span.line and not guess:
                    hint = f"is a ';' missing at the end of line {clause.span.line - 1}?"
                self.error(clause.name_span, f"unknown clause '{name}'", hint)
                self.expr(clause.value)
                continue
            if name in seen:
                self.error(clause.name_span, f"clause '{name}' is given twice",
                           f"the first is at line {seen[name].span.line}, column {seen[name].span.col}")
            seen[name] = clause
            applies = kind in entry.motions
            if not applies:
                problem = entry.wrong_motion(kind)
                self.error(clause.name_span, problem.message, problem.hint)
            if entry.type == "robot":
                self.act_rob(clause, entry, kind)
                continue
            if applies and entry.excludes:
                problem = entry.excluded([c.name for c in node.clauses])
                if problem is not None:
                    self.error(clause.name_span, problem.message, problem.hint)
            wanted = INTEGER if entry.stack_type == INTEGER else NUMERIC
            if self.expect(clause.value, wanted, f"clause '{name}'") == ERROR or not applies:
                continue
            v = self.value_of(clause.value)
            if v is _NO_VALUE:
                continue
            _, problem = entry.check(kind, v, self.spec)
            if problem is not None:
                self.error(clause.value.span, problem.message, problem.hint)
        for entry in CLAUSE_TABLE:  # a default the motion does not take (approx = 5 mm for a ptp move)
            if entry.name not in seen and kind in entry.motions and entry.type == "real":
                _, problem = entry.check(kind, entry.default_value(self.spec), self.spec, default=True)
                if problem is not None:
                    self.error(node.span, problem.message, problem.hint)
        if "act_rob" not in seen and self.spec.name not in self.robots:
            self.robots.append(self.spec.name)

    def act_rob(self, clause: ast.Clause, entry: Clause, kind: str) -> None:
        if self.expect(clause.value, STRING, f"clause '{entry.name}'") == ERROR:
            return
        robot = self.value_of(clause.value)
        if robot is _NO_VALUE:
            self.error(clause.value.span, f"{entry.name} must be a robot's name known at compile time")
            return
        _, problem = entry.check(kind, robot, self.spec)
        if problem is not None:
            self.error(clause.value.span, problem.message, problem.hint)
            return
        if robot not in self.robots:
            self.robots.append(robot)

    def s_If(self, node: ast.If):
        for cond, body in node.branches:
            self.expect(cond, BOOL, "a condition")
            self.stmts(body)
        self.stmts(node.orelse)

    def s_While(self, node: ast.While):
        self.expect(node.cond, BOOL, "a condition")
        self.stmts(node.body)

    def s_Repeat(self, node: ast.Repeat):
        self.stmts(node.body)
        self.expect(node.cond, BOOL, "a condition")

    def s_For(self, node: ast.For):
        symbol = self.lookup(node.var)
        if symbol is None:
            self.error(node.var_span, f"undeclared loop variable '{node.var}'",
                       f"declare it: var {node.var} : integer;")
        elif symbol.kind in ("const", "proc", "func", "record", "interrupt", "zone"):
            self.error(node.var_span, f"'{node.var}' is a {_KIND_WORDS[symbol.kind]} and cannot be a loop variable")
        elif symbol.type not in (INTEGER, ERROR):
            self.error(node.var_span, f"the loop variable '{node.var}' must be an integer, "
                                      f"not {type_name(symbol.type)}")
        else:
            self.symbols[id(node)] = symbol
        if node.var in self.loop_vars:
            self.error(node.var_span, f"'{node.var}' is already the variable of an enclosing for loop")
        if symbol is not None and symbol.persistent:
            self.error(node.var_span, f"the persistent variable '{node.var}' cannot be a loop variable",
                       "count with a plain variable, and keep the count in the persistent one")
        self.expect(node.start, INTEGER, "a for loop's start")
        self.expect(node.stop, INTEGER, "a for loop's end")
        if node.step is not None:
            step = self.const_int(node.step, "a for loop's step")
            if step == 0:
                self.error(node.step.span, "a for loop's step must not be 0")
        self.loop_vars.append(node.var)
        self.stmts(node.body)
        self.loop_vars.pop()

    def s_WaitTime(self, node: ast.WaitTime):
        if self.expect(node.seconds, NUMERIC, "a wait time (seconds)") != ERROR:
            v = self.value_of(node.seconds)
            if v is not _NO_VALUE and v < 0:
                self.error(node.seconds.span, f"a wait time of {v:g} s is negative")

    def s_WaitFor(self, node: ast.WaitFor):
        self.expect(node.cond, BOOL, "the condition of 'wait for'")
        if node.timeout is not None and self.expect(node.timeout, NUMERIC, "a time-out (seconds)") != ERROR:
            v = self.value_of(node.timeout)
            if v is not _NO_VALUE and v <= 0:
                self.error(node.timeout.span, f"a time-out of {v:g} s must be positive")

    def s_CallProc(self, node: ast.CallProc):
        symbol = self.lookup(node.name)
        if node.name in STATE_PROCEDURES and (symbol is None or symbol.kind != "proc"):  # (its own first)
            self.state_routine(node, STATE_PROCEDURES[node.name])
            return
        if symbol is None or symbol.kind != "proc":
            hidden = self.hidden_hint(node.name) if symbol is None else None
            if symbol is None and node.name in STATE_FUNCTIONS:
                self.error(node.name_span, f"'{node.name}' is a function: use its value",
                           f"for example: x := {node.name}({'1' if STATE_FUNCTIONS[node.name].params else ''});")
            elif hidden is not None:
                self.error(node.name_span, *hidden)
            elif symbol is None:
                procs = [s.name for s in self.globals.values() if s.kind == "proc"]
                guess = did_you_mean(node.name, procs)
                self.error(node.name_span, f"undeclared procedure '{node.name}'",
                           f"did you mean '{guess}'?" if guess else None)
            elif symbol.kind == "func":
                self.error(node.name_span, f"'{node.name}' is a function: use its value",
                           f"for example: x := {node.name}(...);")
            elif symbol.kind == "interrupt":
                self.error(node.name_span, f"'{node.name}' is an interrupt: it runs when its condition becomes true",
                           f"switch it on with 'enable {node.name};'")
            else:
                self.error(node.name_span, f"'{node.name}' is not a procedure")
            for arg in node.args:
                self.expr(arg)
            return
        self.symbols[id(node)] = symbol
        self.arguments(node, symbol, "procedure")
        handler = self.scope.interrupt if self.scope is not None else None
        if handler is not None and symbol.name in self.moving:
            self.error(node.name_span, f"an interrupt's handler may not call '{node.name}': it "
                                       f"{self.moving[symbol.name]}",
                       "a handler runs beside the motion or its stop: it may not move, pause or use a frame or tool")

    def trigger_belongs(self, node: ast.Trigger, after) -> None:
        """A trigger belongs to the next move: the statements after it are triggers, then
        a move; a distance is for a lin or circ move."""
        move = next((s for s in after if type(s) is not ast.Trigger), None)
        if type(move) is not ast.Move:
            self.error(node.span, "a trigger belongs to the next move: the statement after it must be a move (or "
                                  "another trigger)", "put the trigger right before its move")
            return
        k = TRIGGER_UNIT_INDEX.get(node.unit)
        unit = TRIGGER_UNITS[k] if k is not None else None
        if unit is not None and move.kind not in unit.motions:
            self.error(node.words_span, f"a trigger in {unit.name} is for {' and '.join(unit.motions)} moves: the "
                                        f"move at line {move.span.line} is a {move.kind} move",
                       "give a ptp move's trigger in ms")

    def s_Trigger(self, node: ast.Trigger):
        place, unit = TRIGGER_PLACE_INDEX.get(node.where), TRIGGER_UNIT_INDEX.get(node.unit)
        if unit is None:
            guess = did_you_mean(node.unit, [u.name for u in TRIGGER_UNITS], cutoff=0.3)
            self.error(node.words_span, f"unknown trigger unit '{node.unit}': expected "
                                        f"{' or '.join(u.name for u in TRIGGER_UNITS)}",
                       f"did you mean '{guess}'?" if guess else None)
        elif place is None:
            words = [p.words for p in TRIGGER_PLACES]
            guess = did_you_mean(node.where, words, cutoff=0.5)
            self.error(node.words_span, f"'{node.where}': a trigger is counted {', '.join(words)}",
                       "a trigger cannot fire before its move starts: give it to the move before, counted from "
                       "that move's end" if node.where == "before start" else
                       f"did you mean '{guess}'?" if guess else None)
        if self.expect(node.amount, NUMERIC, "a trigger's amount") != ERROR and None not in (place, unit):
            value = self.value_of(node.amount)
            problem = trigger_problem(place, unit, value if value is not _NO_VALUE else 0)
            if problem is not None:
                self.error(node.amount.span if "amount" in problem else node.words_span, problem)
        if node.action[0] == "out":
            _kind, index, value = node.action
            if self.expect(index, INTEGER, "an output number") != ERROR:
                self.check_io_index(index, self.spec.outputs, "output")
            self.expect(value, BOOL, "a digital output's value")
            return
        _kind, name, span, value = node.action
        symbol = self.lookup(name)
        vt = self.expr(value)
        if symbol is None:
            self.unknown(span, name, "variable")
        elif symbol.persistent:
            self.error(span, f"a trigger cannot set the persistent variable '{name}'",
                       "the program's statements keep it: set a plain global in the trigger, and the persistent "
                       "one from it")
        elif symbol.kind != "global" or symbol.type not in TRIGGER_SET_TYPES:
            local = symbol.kind == "local"
            what = "a local variable" if local else a(symbol.type) if symbol.kind == "global" else \
                a(_KIND_WORDS.get(symbol.kind, symbol.kind))
            self.error(span, f"a trigger sets a global variable of type {', '.join(TRIGGER_SET_TYPES)}: '{name}' "
                             f"is {what}",
                       "the trigger fires later, when the robot is there: a local may be gone by then" if local
                       else None)
        else:
            self.symbols[id(node)] = symbol
            if vt != ERROR and not assignable(symbol.type, vt):
                self.error(value.span, f"cannot assign {a(vt)} to '{name}', which is {a(symbol.type)}")

    def s_Enable(self, node: ast.Enable):
        symbol = self.lookup(node.name)
        if symbol is None or symbol.kind != "interrupt":
            names = [s.name for s in self.globals.values() if s.kind == "interrupt"]
            guess = did_you_mean(node.name, names)
            kind = _KIND_WORDS.get(symbol.kind, "variable") if symbol is not None else ""
            what = f"'{node.name}' is {a(kind)}, not an interrupt" if symbol is not None \
                else f"undeclared interrupt '{node.name}'"
            self.error(node.name_span, what, f"did you mean '{guess}'?" if guess else None)
            return
        self.symbols[id(node)] = symbol

    def arguments(self, node, symbol: Symbol, what: str) -> None:
        """Check a call's arguments against the procedure's or function's parameters."""
        if len(node.args) != len(symbol.params):
            self.error(node.span, f"{what} '{node.name}' takes {len(symbol.params)} argument"
                                  f"{'s' if len(symbol.params) != 1 else ''}, not {len(node.args)}")
            for arg in node.args:
                self.expr(arg)
            return
        for i, (arg, param_t) in enumerate(zip(node.args, symbol.params), 1):
            if i <= len(symbol.refs) and symbol.refs[i - 1]:
                self.reference(node, i, arg, param_t)
                continue
            t = self.expr(arg)
            if t != ERROR and not assignable(param_t, t):
                self.error(arg.span, f"argument {i} of '{node.name}' must be {type_name(param_t)}, "
                                     f"not {type_name(t)}")

    def reference(self, node, i: int, arg: ast.Expr, param_t) -> None:
        """Argument ``i`` of a call, for a 'var' parameter: a variable, or an element or a
        field of one (``slots[k].part``: arrays' elements and records' fields only), of exactly
        the parameter's type, which takes the parameter's value when the procedure returns."""
        t = self.expr(arg)
        root = ast.reference_root(arg)
        if root is None or any(isinstance(part, ast.Index) and not isinstance(self.types.get(id(part.base)), ArrayT)
                               or isinstance(part, ast.Field) and not isinstance(self.types.get(id(part.base)),
                                                                                 RecordT)
                               for part in ast.reference_parts(arg)):
            axis = any(isinstance(part, ast.Index) and self.types.get(id(part.base)) == JOINT
                       for part in ast.reference_parts(arg))
            self.error(arg.span, f"argument {i} of '{node.name}' is a 'var' parameter: pass a variable, by its name, "
                                 "or an element or a field of one" + (" (an array's element or a record's field; not "
                                                                      "an axis of a joint)" if axis else ""),
                       "pass the whole joint, or a real variable and put it back with j[k] := x" if axis else
                       "the procedure puts its value back there")
            return
        whole, arg = arg, root
        symbol = self.symbols.get(id(arg))
        if symbol is None or symbol.kind not in ("global", "local"):
            if symbol is not None:
                self.error(arg.span, f"argument {i} of '{node.name}' is a 'var' parameter: '{arg.name}' is "
                                     f"{a(_KIND_WORDS.get(symbol.kind, symbol.kind))}, not a variable")
            return
        if arg.name in self.loop_vars:
            self.error(arg.span, f"'{arg.name}' is the variable of an enclosing for loop",
                       "a for loop's variable cannot be passed to a 'var' parameter")
        elif t != ERROR and t != param_t:
            self.error(whole.span, f"argument {i} of '{node.name}' is a 'var' parameter of type "
                                 f"{type_name(param_t)}: pass a variable of that type, not {a(t)}")

    def s_Print(self, node: ast.Print):
        if len(node.values) > MAX_COUNT:
            self.error(node.span, f"print takes at most {MAX_COUNT} values")
        for value in node.values:
            self.expr(value)

    def s_Pause(self, node):
        pass

    def s_Halt(self, node):
        pass

    # ---- error handlers (compiler.recovery) ----
    def s_OnError(self, node: ast.OnError):
        if node.word != HANDLER_WORD:
            self.error(node.word_span, f"'when {node.word} do' is no handler: an error handler starts with "
                                       f"'when {HANDLER_WORD} do'",
                       "the statements after it run when a statement of the body raises an error")
        outer, self.in_handler = self.in_handler, True
        self.stmts(node.body)
        self.in_handler = outer
        assigned = _assigned(node.body)
        for retry in _unguarded_retries(node.body, assigned):
            self.warning(retry.span, "this 'retry' has no bound: if the error comes again, the statement is "
                                     "retried for ever",
                         "count the tries and retry only below a limit: tries := tries + 1; "
                         "if tries < 3 then retry; endif;")

    def s_Word(self, node: ast.Word):
        word = HANDLER_WORDS.get(node.name)
        if word is None:
            self.unknown_statement(node)
            return
        reraise = node.name == "raise" and not node.args
        if (word.handler_only or reraise) and not self.in_handler:
            self.error(node.name_span, f"'{node.name};' belongs in an error handler: there is no error here to "
                                       f"{'pass on' if reraise else 'go on from'}",
                       f"end the seq ... endseq body with 'when {HANDLER_WORD} do', then the statements that "
                       f"handle its errors" + ("; raise the program's own error with 'raise NUMBER;'" if reraise
                                               else ""))
        if node.name == "trynext" and self.scope is not None and self.scope.result is not None:
            self.error(node.name_span, f"'trynext' is not allowed in function '{self.scope.node.name}': it could "
                                       "reach the function's end without a value",
                       "return a value, retry, or raise the error on")
        if node.name != "raise":
            if node.args:
                self.error(node.args[0].span, f"'{node.name}' takes no value")
                for arg in node.args:
                    self.expr(arg)
            return
        if len(node.args) > 2:
            self.error(node.args[2].span, "'raise' takes an error number and a message at most: "
                                          "raise NUMBER, \"message\";")
        if node.args and self.expect(node.args[0], INTEGER, "an error's number") != ERROR:
            number = self.value_of(node.args[0])
            if number is not _NO_VALUE and not USER_ERRORS[0] <= number <= USER_ERRORS[1]:
                self.error(node.args[0].span, f"error {number}: a program's own errors are numbered "
                                              f"{USER_ERRORS[0]}..{USER_ERRORS[1]}",
                           "the numbers below are the runtime's own errors (error_number())")
        if len(node.args) > 1:
            self.expect(node.args[1], STRING, "an error's message")
        for arg in node.args[2:]:
            self.expr(arg)

    def unknown_statement(self, node: ast.Word):
        """A name standing alone as a statement that is no word of a handler."""
        symbol = self.lookup(node.name)
        if symbol is not None and symbol.kind == "proc":
            self.error(node.name_span, f"'{node.name}' is a procedure: call it with 'call {node.name}(...);'")
        elif symbol is not None and symbol.kind in ("global", "local"):
            self.error(node.name_span, f"'{node.name}' is a variable, not a statement",
                       f"assign it with '{node.name} := VALUE;'")
        else:
            words = sorted(set(keywords()) | set(HANDLER_WORDS))
            guess = did_you_mean(node.name, words, cutoff=0.7)
            self.error(node.name_span, f"'{node.name}' is not a statement",
                       f"did you mean '{guess}'?" if guess else
                       "a statement starts with a keyword (move, if, call, ...), a variable to assign, or one of an "
                       f"error handler's words ({', '.join(HANDLER_WORDS)})")
        for arg in node.args:
            self.expr(arg)

    def s_Return(self, node: ast.Return):
        scope = self.scope
        if scope is None:
            self.error(node.span, "'return' outside a procedure or function", "to end the program, write 'halt;'")
            if node.value is not None:
                self.expr(node.value)
            return
        if scope.result is None:
            if node.value is not None:
                self.expr(node.value)
                self.error(node.value.span, f"procedure '{scope.node.name}' has no result: write 'return;'",
                           "a procedure that computes a value is a function: function NAME(...) : TYPE;")
            return
        if node.value is None:
            self.error(node.span, f"function '{scope.node.name}' must return {a(scope.result)}: "
                                  "write 'return VALUE;'")
            return
        t = self.expr(node.value)
        if ERROR not in (t, scope.result) and not assignable(scope.result, t):
            self.error(node.value.span, f"function '{scope.node.name}' returns {a(scope.result)}, not {a(t)}")

    # ---- declarations ----
    def const_decl(self, decl: ast.ConstDecl) -> None:
        t = self.expr(decl.value)
        value = self.value_of(decl.value)
        if t != ERROR and value is _NO_VALUE:
            self.error(decl.value.span, f"the value of constant '{decl.name}' must be known at compile time",
                       "a record is no constant: declare a variable with it as its initial value"
                       if isinstance(t, RecordT) else None)
        if t in (MAINJOINT, ADDJOINT):
            self.error(decl.value.span, f"{t} is only meaningful inside joint(...)")
            t = ERROR
        self.declare(self.globals, Symbol("const", decl.name, t, decl.span, value=value))

    def record_decl(self, decl: ast.RecordDecl) -> None:
        """A record type (compiler.records): its words, its fields (each named once, of a type
        known here), its size; then its name, declared."""
        for word, span, wanted in ((decl.word, decl.word_span, RECORD_WORD), (decl.end_word, decl.end_span,
                                                                               RECORD_END)):
            if word != wanted:
                self.error(span, f"unexpected name '{word}': a record type is declared 'record NAME FIELDS "
                                 f"endrecord;'", f"did you mean '{wanted}'?")
        fields: list[tuple[str, object]] = []
        seen: dict[str, ast.Span] = {}
        self.declared.declaring = decl.name
        for item in decl.fields:
            t = self.resolve_type(item.type)
            for name, span in zip(item.names, item.spans):
                if name in seen:
                    self.error(span, f"record {decl.name} has a field '{name}' already",
                               f"the first is at line {seen[name].line}")
                elif name in keywords():
                    self.error(span, f"'{name}' is a reserved word and cannot be a field's name", "choose another name")
                else:
                    seen[name] = span
                    fields.append((name, t))
        self.declared.declaring = None
        record = RecordT(decl.name, tuple(fields))
        if decl.name in NAMED_TYPES or decl.name in CONSTRUCTORS or decl.name in BUILTINS \
                or decl.name in STATE_FUNCTIONS:
            self.error(decl.name_span, f"'{decl.name}' is a {'type' if decl.name in NAMED_TYPES else 'function'} of "
                                       "the language and cannot name a record type", "choose another name")
            return
        if len(fields) > RECORD_FIELDS:
            self.error(decl.name_span, f"record {decl.name} has {len(fields)} fields (at most {RECORD_FIELDS})")
        elif elements(record) > MAX_ARRAY_LENGTH:
            self.error(decl.name_span, f"record {decl.name} holds {elements(record)} values (at most "
                                       f"{MAX_ARRAY_LENGTH}, all its fields' elements together)")
        if self.declare(self.globals, Symbol("record", decl.name, record, decl.name_span)):
            self.declared.records.append(record)

    def zone_decl(self, decl: ast.ZoneDecl) -> None:
        """A world zone of the program (compiler.zones): its words, its shape (a constructor
        with constant arguments, each checked as the specification's keys are), a signal
        zone's output; then its name, declared."""
        if decl.word != world_zones.WORD:
            self.error(decl.word_span, f"unexpected name '{decl.word}': a world zone is declared 'zone NAME := "
                                       f"box(LOW, HIGH);' or '... := cylinder(FOOT, RADIUS, HEIGHT);'",
                       f"did you mean '{world_zones.WORD}'?")
            return
        zone = self.zone_shape(decl)
        output = 0
        if decl.signal_span is not None:
            if decl.signal_word != world_zones.SIGNAL_WORD:
                self.error(decl.signal_span, f"unexpected name '{decl.signal_word}' after the zone's shape",
                           f"a signal zone ends with '{world_zones.SIGNAL_WORD} N': output N is true while the tool "
                           "centre point is inside")
            elif self.expect(decl.output, INTEGER, "a signal zone's output") != ERROR:
                output = self.value_of(decl.output)
                if output is _NO_VALUE:
                    self.error(decl.output.span, "a signal zone's output must be an integer known at compile time")
                    zone = None
                else:
                    self.check_io_index(decl.output, self.spec.outputs, "output")
                    zone = zone if 1 <= output <= self.spec.outputs else None
        if not self.declare(self.globals, Symbol("zone", decl.name, "zone", decl.name_span)) or zone is None:
            return
        zone = world_zones.zone_of(decl.name, *zone, "signal" if output else "forbidden", output)
        problem = world_zones.run_problem(self.spec, tuple(self.declared.zones) + (zone,))
        if problem is not None:
            self.error(decl.name_span, problem)
            return
        self.declared.zones.append(zone)
        self.declared.zone_lines[zone.name] = (self.file, decl.name_span.line)

    def zone_shape(self, decl: ast.ZoneDecl):
        """(shape, its keys' values) of a zone's declaration, or None (reported)."""
        shape = decl.shape
        if not isinstance(shape, ast.Call) or shape.name not in world_zones.CONSTRUCTORS:
            for part in shape.args if isinstance(shape, ast.Call) else (shape,):
                self.expr(part)
            self.error(shape.span, "a zone's shape is " + " or ".join(
                f"{name}({params})" for name, (params, _doc) in world_zones.CONSTRUCTORS.items()))
            return None
        params, doc = world_zones.CONSTRUCTORS[shape.name]
        wanted = (POSITION, POSITION) if shape.name == "box" else (POSITION, NUMERIC, NUMERIC)
        if not self.arity(shape, len(wanted)):
            return None
        args = []
        for arg, t in zip(shape.args, wanted):
            if self.expect(arg, t, f"an argument of {shape.name}({params})") == ERROR:
                return None
            value = self.value_of(arg)
            if value is _NO_VALUE:
                self.error(arg.span, f"a zone's {shape.name}({params}) needs values known at compile time",
                           f"{params}: {doc}")
                return None
            args.append((value.x, value.y, value.z) if t == POSITION else value)
        problem = world_zones.shape_problem(shape.name, tuple(args))
        if problem is not None:
            self.error(shape.span, f"zone '{decl.name}': {problem}", f"{shape.name}({params}): {doc}")
            return None
        return shape.name, world_zones.values_of(shape.name, tuple(args))

    def var_decl(self, decl: ast.VarDecl, table: dict, slots: list, kind: str) -> None:
        t = self.resolve_type(decl.type)
        if decl.init is not None:
            vt = self.expr(decl.init)
            if ERROR not in (t, vt) and not assignable(t, vt):
                self.error(decl.init.span, f"cannot initialise {a(t)} with {a(vt)}")
        if decl.section and decl.section != PERSISTENT:
            guess = did_you_mean(decl.section, [PERSISTENT], cutoff=0.6)
            self.error(decl.section_span, f"'var {decl.section}': the only word a var section takes is "
                                          f"'{PERSISTENT}'",
                       f"did you mean '{guess}'?" if guess else f"var {PERSISTENT} declares variables whose values "
                                                                "the runtime keeps across runs")
        elif decl.section and kind != "global":
            self.error(decl.section_span, f"a {PERSISTENT} variable is global: declare it in the program's (or a "
                                          f"module's) var {PERSISTENT} section",
                       "a routine's variables live while it runs")
        elif decl.section and elements(t) > PERSISTENT_ELEMENTS:
            self.error(decl.type.span, f"a {PERSISTENT} variable holds at most {PERSISTENT_ELEMENTS} elements, "
                                       f"not {elements(t)}",
                       "the runtime copies it at every change and writes it while the robot moves: keep large "
                       "data in plain variables")
        for name, span in zip(decl.names, decl.spans):
            symbol = Symbol(kind, name, t, span, slot=len(slots),
                            persistent=decl.section == PERSISTENT and kind == "global")
            if self.declare(table, symbol):
                slots.append((name, type_name(t)))

    def check(self) -> CheckedProgram:
        program = self.program
        self.predeclare()
        bodies = [d.body for d in program.decls if isinstance(d, ast.Procedure)]
        self.proc_changes = frozenset().union(*(_uses(s, self._changes)[0] for body in bodies for s in body))
        self.all_changes = self.proc_changes.union(*(_uses(s, self._changes)[0] for s in program.body))
        self.declared.later = {d.name: d for d in program.decls if isinstance(d, ast.RecordDecl)}
        for decl in program.decls:  # record types first (each before its use), then procedures, so a
            if isinstance(decl, ast.RecordDecl):  # call may come before the procedure's declaration
                self.file = self.decl_files.get(id(decl), self.main_file)
                self.record_decl(decl)
                self.declared.later.pop(decl.name, None)
        for decl in program.decls:
            if isinstance(decl, ast.Procedure):
                self.file = self.decl_files.get(id(decl), self.main_file)
                self.declare_procedure(decl)
        for decl in program.decls:
            self.file = self.decl_files.get(id(decl), self.main_file)
            if isinstance(decl, ast.ConstDecl):
                self.const_decl(decl)
            elif isinstance(decl, ast.ZoneDecl):
                self.zone_decl(decl)
            elif isinstance(decl, ast.VarDecl):
                self.var_decl(decl, self.globals, self.global_slots, "global")
        self.moving = _moving_procedures(self.procs)
        for scope in self.interrupts:  # conditions: in the global scope (checked every 5 ms, anywhere)
            self.file = self.decl_files.get(id(scope.node), self.main_file)
            self.interrupt_condition(scope.node.interrupt.cond)
        for scope in self.procs:
            self.scope = scope
            self.file = self.decl_files.get(id(scope.node), self.main_file)
            for var in scope.node.variables:
                if isinstance(var, (ast.RecordDecl, ast.ZoneDecl)):
                    self.error(var.name_span, f"{'record type' if isinstance(var, ast.RecordDecl) else 'zone'} "
                                              f"'{var.name}' is declared inside "
                                              f"{_KIND_WORDS.get(scope.symbol.kind, 'a routine')} "
                                              f"'{scope.node.name}'",
                               "declare record types and zones at the program's or a module's level, beside its "
                               "variables")
                    continue
                self.var_decl(var, scope.names, scope.slots, "local")
            self.start_frames(known=False)
            self.stmts(scope.node.body)
            main, handler = ast.split_handler(scope.node.body)
            if scope.result is not None and not always_returns(main):
                self.error(scope.node.name_span, f"function '{scope.node.name}' can reach its end without "
                                                 "'return'", "every path through a function must end in "
                                                             "'return VALUE;'")
            elif scope.result is not None and handler is not None and not always_returns(handler.body):
                self.error(handler.word_span, f"the error handler of function '{scope.node.name}' can reach its "
                                              "end without 'return'",
                           "end every path through it with 'return VALUE;', 'retry;' or 'raise;'")
            self.scope = None
        self.file = self.main_file
        self.start_frames(known=True)
        self.stmts(program.body)
        if not self.robots:
            self.robots.append(self.spec.name)
        return CheckedProgram(program, self.spec, self.types, self.values, self.symbols,
                              self.global_slots, self.globals, self.procs, tuple(self.robots), self.decl_files,
                              interrupts=self.interrupts, records=self.declared.records,
                              zones=self.declared.zones)

    def interrupt_options(self, node: ast.Procedure, index: int) -> InterruptDecl:
        """``priority N``, ``stop`` or ``continue``, ``then resume`` or ``then halt``
        (compiler.interrupts): each known, given once; stop or continue given."""
        decl = InterruptDecl(index)
        seen: dict[str, ast.Span] = {}
        action = None
        unknown = False
        for word, value, span in node.interrupt.options:
            group = "then" if word == "then" else "action" if word in ACTIONS else word
            if group not in ("then", "action", "priority"):
                guess = did_you_mean(word, ["priority", *ACTIONS])
                self.error(span, f"unknown interrupt option '{word}': expected priority N, "
                                 f"{' or '.join(ACTIONS)}, then {' or '.join(THEN)}",
                           f"did you mean '{guess}'?" if guess else None)
                unknown = True
                continue
            if group in seen:
                self.error(span, f"'{node.name}' gives {'stop or continue' if group == 'action' else group} twice",
                           f"the first is at column {seen[group].col}")
                continue
            seen[group] = span
            if group == "then":
                if value not in THEN:
                    guess = did_you_mean(str(value), list(THEN))
                    self.error(span, f"'then {value}': expected then {' or then '.join(THEN)}",
                               f"did you mean 'then {guess}'?" if guess else None)
                else:
                    decl.then = value
            elif group == "action":
                if value is not None:
                    self.error(span, f"'{word}' takes no number")
                action = word
            else:
                low, high = PRIORITY
                if not isinstance(value, int) or not low <= value <= high:
                    self.error(span, f"an interrupt's priority must be a whole number {low}..{high} ({low} the "
                                     f"highest), not {value if value is not None else 'missing'}")
                else:
                    decl.priority = value
        if action is None and not unknown:
            self.error(node.interrupt.span, f"interrupt '{node.name}' must say what the robot does when it fires: "
                                            f"'stop' or 'continue'", "for example: ... when in[5] stop;")
        decl.stop = action != "continue"
        return decl

    def interrupt_condition(self, cond: ast.Expr) -> None:
        """A bool expression of inputs and global bool variables only (compiler.interrupts)."""
        if self.expect(cond, BOOL, "an interrupt's condition") == ERROR:
            return
        bad = _not_a_condition(cond, self)
        if bad is not None:
            self.error(bad.span, f"an interrupt's condition may use only {CONDITION_TEXT}, not "
                                 f"'{ast.expression_text(bad)}'",
                       "compute it in the program into a global bool variable, and test that")

    def declare_procedure(self, node: ast.Procedure) -> None:
        """A procedure, or a function (a procedure with a result type)."""
        result = None
        if node.result is not None:
            result = self.resolve_type(node.result)
            if node.name in BUILTINS and node.name not in STRING_BUILTINS or \
                    (node.name in CONSTRUCTORS and node.name != CONTEXTUAL_NAME):  # (string functions came later)
                self.error(node.name_span, f"'{node.name}' is a built-in function: a function needs another name")
                return
        kind = "func" if node.result is not None else "interrupt" if node.interrupt is not None else "proc"
        symbol = Symbol(kind, node.name, result if node.result is not None else _KIND_WORDS[kind], node.name_span,
                        index=len(self.procs))
        if not self.declare(self.globals, symbol):
            return
        scope = ProcScope(node, symbol, result=result)
        if node.interrupt is not None:
            scope.interrupt = self.interrupt_options(node, len(self.interrupts))
            self.interrupts.append(scope)
        params = []
        for param in node.params:
            t = self.resolve_type(param.type)
            params.append(t)
            if param.by_ref and node.result is not None:
                self.error(param.span, f"a function's parameter cannot be 'var': '{node.name}' computes a value",
                           "make it a procedure, or return the value")
            p = Symbol("local", param.name, t, param.span, slot=len(scope.slots))
            if self.declare(scope.names, p):
                scope.slots.append((param.name, type_name(t)))
        symbol.params = tuple(params)
        symbol.refs = tuple(param.by_ref and node.result is None for param in node.params)
        self.procs.append(scope)


_EXPR_CLASSES = (ast.Number, ast.String, ast.Bool, ast.Ref, ast.Call, ast.Index, ast.Field, ast.Unary,
                 ast.Binary, ast.Input, ast.Output)
_STMT_CLASSES = (ast.Assign, ast.OutSet, ast.Move, ast.If, ast.While, ast.Repeat, ast.For, ast.WaitTime,
                 ast.WaitFor, ast.CallProc, ast.Print, ast.Pause, ast.Halt, ast.Return, ast.Use, ast.Enable,
                 ast.Trigger, ast.Word, ast.OnError)
#: Statements a function may not hold (it computes a value; it does not act): the keyword.
_NOT_IN_FUNCTIONS = {ast.Move: "move", ast.WaitTime: "wait", ast.WaitFor: "wait for", ast.OutSet: "out[...] :=",
                     ast.CallProc: "call", ast.Print: "print", ast.Pause: "pause", ast.Halt: "halt",
                     ast.Use: "use", ast.Enable: "enable", ast.Trigger: "trigger"}
#: Statements an interrupt's handler may not hold (it runs beside the motion or its stop).
_NOT_IN_HANDLERS = {ast.Move: "move", ast.Pause: "pause", ast.Use: "use", ast.Trigger: "trigger"}
_COMPOUND = (ast.If, ast.While, ast.Repeat, ast.For, ast.CallProc)  # statements that hold (or call) others


def _uses(stmt, memo: dict) -> tuple[frozenset, bool]:
    """The kinds of ``use`` inside ``stmt`` (itself included), and whether it calls a
    procedure (memoized in ``memo`` by node)."""
    found = memo.get(id(stmt))
    if found is None:
        if isinstance(stmt, ast.Use):
            found = (frozenset((stmt.kind,)), False)
        else:
            inner = [_uses(s, memo) for s in _children(stmt)]
            found = (frozenset().union(*(u for u, _c in inner)),
                     isinstance(stmt, ast.CallProc) or any(c for _u, c in inner))
        memo[id(stmt)] = found
    return found


def _not_a_condition(node, checker):
    """The first part of ``node`` an interrupt's condition may not hold, or None."""
    if isinstance(node, ast.Bool):
        return None
    if isinstance(node, ast.Ref):
        symbol = checker.symbols.get(id(node))
        return None if symbol is not None and symbol.kind in ("global", "const") else node
    if isinstance(node, ast.Input):
        return None if id(node.index) in checker.values else node
    if isinstance(node, ast.Unary) and node.op == "not":
        return _not_a_condition(node.operand, checker)
    if isinstance(node, ast.Binary) and node.op in ("and", "or"):
        return _not_a_condition(node.left, checker) or _not_a_condition(node.right, checker)
    return node


def _moving_procedures(procs) -> dict[str, str]:
    """The procedures that move, pause or use a frame or tool, directly or through the
    procedures they call: name -> what (for the message)."""
    direct: dict[str, str] = {}
    calls: dict[str, set] = {}
    for scope in procs:
        name = scope.node.name
        calls[name] = set()
        stack = list(scope.node.body)
        while stack:
            stmt = stack.pop()
            if type(stmt) in _NOT_IN_HANDLERS and name not in direct:
                direct[name] = f"has '{_NOT_IN_HANDLERS[type(stmt)]}' at line {stmt.span.line}"
            if isinstance(stmt, ast.CallProc):
                calls[name].add(stmt.name)
            stack.extend(_children(stmt))
    moving = dict(direct)
    changed = True
    while changed:
        changed = False
        for name, called in calls.items():
            if name not in moving:
                via = next((c for c in sorted(called) if c in moving), None)
                if via is not None:
                    moving[name] = f"calls '{via}', which {moving[via]}"
                    changed = True
    return moving


def _children(stmt) -> tuple:
    """The statements directly inside ``stmt``."""
    if isinstance(stmt, ast.If):
        return tuple(s for _cond, body in stmt.branches for s in body) + tuple(stmt.orelse)
    if isinstance(stmt, (ast.While, ast.Repeat, ast.For, ast.OnError)):
        return tuple(stmt.body)
    return ()


def _assigned(body) -> frozenset:
    """The names the statements of ``body`` assign (a for loop's variable too)."""
    names, stack = set(), list(body)
    while stack:
        stmt = stack.pop()
        if isinstance(stmt, ast.Assign):
            names.add(stmt.name)
        elif isinstance(stmt, ast.For):
            names.add(stmt.var)
        elif isinstance(stmt, ast.CallProc):
            names.update(root.name for root in map(ast.reference_root, stmt.args)
                         if root is not None)  # (a 'var' parameter may change it)
        stack.extend(_children(stmt))
    return frozenset(names)


def _reads(expr, names: frozenset) -> bool:
    """Whether ``expr`` reads one of ``names``, or calls a function other than what a
    handler reads of its error (a clock, the program's own: they may bound a retry)."""
    stack = [expr]
    while stack:
        e = stack.pop()
        if isinstance(e, ast.Ref) and e.name in names:
            return True
        if isinstance(e, ast.Call) and e.name not in ERROR_ROUTINES:
            return True
        stack.extend(ast.operands(e))
    return False


def _unguarded_retries(body, assigned: frozenset, guarded: bool = False) -> list:
    """The ``retry`` statements of a handler's ``body`` not under a condition that reads
    what the handler changes (a count of the tries) or a function (a clock)."""
    found = []
    for stmt in body:
        if isinstance(stmt, ast.Word) and stmt.name == "retry" and not guarded:
            found.append(stmt)
        elif isinstance(stmt, ast.If):
            for cond, branch in stmt.branches:
                guarded_here = guarded or _reads(cond, assigned)
                found += _unguarded_retries(branch, assigned, guarded_here)
            found += _unguarded_retries(stmt.orelse, assigned, guarded or any(_reads(c, assigned)
                                                                               for c, _b in stmt.branches))
        elif isinstance(stmt, (ast.While, ast.Repeat)):
            found += _unguarded_retries(stmt.body, assigned, guarded or _reads(stmt.cond, assigned))
        elif isinstance(stmt, ast.For):
            found += _unguarded_retries(stmt.body, assigned, guarded)
    return found

CONSTRUCTORS = {
    "joint": Checker.c_joint,
    "mainjoint": Checker.c_part,
    "addjoint": Checker.c_part,
    "pos": Checker.c_pos,
    "rpy": Checker.c_rpy,
    "quat": Checker.c_quat,
    "pose": Checker.c_pose,
    "frame": Checker.c_pose,
    "tool": Checker.c_pose,
    CONTEXTUAL_NAME: Checker.c_config,  # (a declaration of that name shadows it: compiler.configs)
}


def check(program: ast.Program, spec: Spec, file: str, decl_files: dict | None = None,
          sees: dict | None = None) -> tuple[CheckedProgram, list[Diagnostic]]:
    """Check ``program`` against ``spec``; returns the result and every error found."""
    checker = Checker(program, spec, file, decl_files, sees)
    checked = checker.check()
    return checked, checker.diagnostics
