"""Checked AST -> object code (:class:`compiler.objcode.Program`).

A single pass over the checked program, in the style of clox's compiler: every
expression leaves one value on the stack, every statement leaves the stack as it found
it, and constant expressions (folded by the checker) become one ``CONST``.
"""
from __future__ import annotations

from pathlib import Path

from . import ast
from .check import INTEGER, REAL, STRING, ArrayT, CheckedProgram, Symbol, type_name
from .frames import BY_KEYWORD as FRAME_BY_KEYWORD
from .frames import describe_name
from .triggers import PLACE_INDEX, UNIT_INDEX
from .clauses import CLAUSES as CLAUSE_TABLE
from .clauses import Motion
from .configs import CONTEXTUAL_NAME, WORDS as CONFIG_WORDS, Config, operand_of
from .objcode import BUILTIN_NAMES, FIELDS, OP, HandlerInfo, InterruptInfo, ProcInfo, Program, RecordInfo, zero_of
from .records import RecordT
from .robotstate import FUNCTIONS as STATE_FUNCTIONS, PROCEDURES as STATE_PROCEDURES
from .semantics import STRING_BUILTINS

_BINARY_OPS = {"+": OP.ADD, "-": OP.SUB, "*": OP.MUL, "/": OP.DIV, "div": OP.IDIV, "mod": OP.MOD,
               "=": OP.EQ, "<>": OP.NE, "<": OP.LT, "<=": OP.LE, ">": OP.GT, ">=": OP.GE,
               "and": OP.AND, "or": OP.OR}
_BUILTIN_INDEX = {name: i for i, name in enumerate(BUILTIN_NAMES)}
#: Each motion's instruction (the object code's MOVE_PTP, MOVE_LIN, MOVE_CIRC).
MOVE_OPS = {Motion.PTP: OP.MOVE_PTP, Motion.LIN: OP.MOVE_LIN, Motion.CIRC: OP.MOVE_CIRC}
_NO_VALUE = object()


class CodeGen:
    def __init__(self, checked: CheckedProgram):
        self.checked = checked
        self.types = checked.types
        self.values = checked.values
        self.symbols = checked.symbols
        self.code: list[tuple[int, ...]] = []
        self.lines: list[tuple[int, int, int]] = []
        self.constants: list = []
        self.constant_index: dict = {}
        self.globals = list(checked.globals)
        self.locals: list | None = None  # slots of the procedure being generated
        self.result = None  # the result type of the function being generated (None: not a function)
        self.refs: list[int] = []  # the 'var' parameters' slots of the procedure being generated
        self.line_files: list[int] = []  # per line entry: 0 the program's file, k its module k
        self.file_index = 0
        self.module_paths = list(checked.modules)  # module paths, in the order their code comes
        self._expr = {cls: getattr(self, "e_" + cls.__name__)
                      for cls in (ast.Ref, ast.Unary, ast.Binary, ast.Index, ast.Field, ast.Input, ast.Output,
                                  ast.Call)}
        self._stmt = {cls: getattr(self, "s_" + cls.__name__)
                      for cls in (ast.Assign, ast.OutSet, ast.Move, ast.If, ast.While, ast.Repeat, ast.For,
                                  ast.WaitTime, ast.WaitFor, ast.CallProc, ast.Print, ast.Pause, ast.Halt,
                                  ast.Return, ast.Use, ast.Enable, ast.Trigger, ast.Word)}
        self.handlers: list[HandlerInfo] = []  # the error handlers (compiler.recovery)
        self.statements: list[tuple[int, int]] | None = None  # of the body a handler protects, while generated
        self.records = {record.name: i for i, record in enumerate(checked.records)}  # -> its index in the table

    # -- emitting --
    def emit(self, op: int, *operands: int) -> int:
        self.code.append((op, *operands))
        return len(self.code) - 1

    def patch(self, at: int, target: int | None = None) -> None:
        """Point the jump at ``at`` to ``target`` (default: the next instruction emitted)."""
        self.code[at] = (self.code[at][0], len(self.code) if target is None else target)

    def mark(self, span: ast.Span) -> None:
        entry = (len(self.code), span.line, span.col)
        if self.lines and self.lines[-1][0] == entry[0]:
            self.lines[-1] = entry
            self.line_files[-1] = self.file_index
        elif not self.lines or self.lines[-1][1:] != entry[1:] or self.line_files[-1] != self.file_index:
            self.lines.append(entry)
            self.line_files.append(self.file_index)

    def in_file_of(self, node) -> None:
        """Code generated next comes from ``node``'s file (a module's, or the program's)."""
        path = self.checked.decl_files.get(id(node))
        self.file_index = 0 if path is None else 1 + self.module_paths.index(path)

    def constant(self, value) -> None:
        self.emit(OP.CONST, self.constant_slot(value))

    def constant_slot(self, value) -> int:
        """The index of ``value`` in the constant pool (added once)."""
        key = (type(value), value)
        index = self.constant_index.get(key)
        if index is None:
            index = self.constant_index[key] = len(self.constants)
            self.constants.append(value)
        return index

    def temp(self, name: str, type_: str) -> tuple[int, int, int]:
        """A hidden variable slot: (load op, store op, slot)."""
        slots = self.locals if self.locals is not None else self.globals
        slots.append((name, type_))
        if self.locals is not None:
            return OP.LOAD_LOCAL, OP.STORE_LOCAL, len(slots) - 1
        return OP.LOAD_GLOBAL, OP.STORE_GLOBAL, len(slots) - 1

    @staticmethod
    def load_op(symbol: Symbol) -> int:
        return OP.LOAD_LOCAL if symbol.kind == "local" else OP.LOAD_GLOBAL

    @staticmethod
    def store_op(symbol: Symbol) -> int:
        return OP.STORE_LOCAL if symbol.kind == "local" else OP.STORE_GLOBAL

    # -- expressions --
    def value(self, node: ast.Expr, want=None) -> None:
        """Push ``node``'s value, converted for a slot of type ``want``."""
        key = id(node)
        folded = self.values.get(key, _NO_VALUE)
        if folded is not _NO_VALUE:
            if want == REAL and type(folded) is int:
                folded = float(folded)
            self.constant(folded)
            return
        self._expr[type(node)](node)
        t = self.types[key]
        if want == REAL and t == INTEGER:
            self.emit(OP.TO_REAL)
        elif isinstance(t, (ArrayT, RecordT)) and isinstance(node, (ast.Ref, ast.Index, ast.Field)):
            self.emit(OP.COPY)  # arrays and records are values: a stored or passed one is a copy

    def e_Ref(self, node: ast.Ref) -> None:
        symbol = self.symbols[id(node)]
        self.emit(self.load_op(symbol), symbol.slot)

    def e_Unary(self, node: ast.Unary) -> None:
        self.value(node.operand)
        if node.op == "-":
            self.emit(OP.NEG)
        elif node.op == "not":
            self.emit(OP.NOT)

    def e_Binary(self, node: ast.Binary) -> None:
        self.value(node.left)
        self.value(node.right)
        self.emit(_BINARY_OPS[node.op])

    def e_Index(self, node: ast.Index) -> None:
        base_t = self.types[id(node.base)]
        self.e_raw(node.base)
        self.value(node.index)
        if isinstance(base_t, ArrayT):
            self.emit(OP.GET_ITEM, base_t.low)
        else:
            self.emit(OP.GET_AXIS)

    def e_raw(self, node: ast.Expr) -> None:
        """Push a value without copying it (to read from it, not to keep it)."""
        if id(node) in self.values:
            self.value(node)
        elif isinstance(node, ast.Ref):
            self.e_Ref(node)
        elif isinstance(node, ast.Index):
            self.e_Index(node)
        elif isinstance(node, ast.Field):
            self.e_Field(node)
        else:
            self.value(node)

    def e_Field(self, node: ast.Field) -> None:
        base_t = self.types[id(node.base)]
        if isinstance(base_t, RecordT):
            self.e_raw(node.base)
            self.emit(OP.GET_MEMBER, base_t.index(node.name))
            return
        self.value(node.base)
        self.emit(OP.GET_FIELD, FIELDS.index(node.name))

    def e_Input(self, node: ast.Input) -> None:
        self.value(node.index)
        self.emit(OP.IN_GET)

    def e_Output(self, node: ast.Output) -> None:
        self.value(node.index)
        self.emit(OP.OUT_GET)

    def e_Call(self, node: ast.Call) -> None:
        name = node.name
        symbol = self.symbols.get(id(node))
        if symbol is not None and symbol.kind == "func":
            for arg, param_t in zip(node.args, symbol.params):
                self.value(arg, param_t)
            self.emit(OP.CALL_FUNC, symbol.index)
        elif symbol is not None and symbol.kind == "record":  # part_t(v1, ..., vn)
            for arg, (_name, field_t) in zip(node.args, symbol.type.fields):
                self.value(arg, field_t)
            self.emit(OP.MAKE_RECORD, self.records[symbol.type.name])
        elif name in STATE_FUNCTIONS:
            self.state_routine(node, STATE_FUNCTIONS[name])
        elif name in _BUILTIN_INDEX:
            want = REAL if self.types[id(node)] == REAL else None
            wants = STRING_BUILTINS[name][0] if name in STRING_BUILTINS else [want] * len(node.args)
            for arg, wanted in zip(node.args, wants):
                self.value(arg, wanted)
            self.emit(OP.CALL_BUILTIN, _BUILTIN_INDEX[name], len(node.args))
        elif name == "joint":
            counts = []
            for part in node.args:  # mainjoint(...) [, addjoint(...)]
                for arg in part.args:
                    self.value(arg, REAL)
                counts.append(len(part.args))
            self.emit(OP.MAKE_JOINT, counts[0], counts[1] if len(counts) > 1 else 0)
        elif name in ("pos", "rpy", "quat"):
            for arg in node.args:
                self.value(arg, REAL)
            self.emit({"pos": OP.MAKE_POS, "rpy": OP.MAKE_RPY, "quat": OP.MAKE_QUAT}[name])
        elif name in ("pose", "frame", "tool"):
            for arg in node.args:
                self.value(arg)
            self.emit(OP.MAKE_POSE_CONFIG if len(node.args) == 3 else OP.MAKE_POSE)
        elif name == CONTEXTUAL_NAME:  # (its words are constant; its turns, if any, are not: else it was folded)
            words = [CONFIG_WORDS[a.name] for a in node.args if isinstance(a, ast.Ref) and a.name in CONFIG_WORDS]
            turns = node.args[len(words):]
            for arg in turns:
                self.value(arg)
            self.emit(OP.MAKE_CONFIG, operand_of(Config(**{g.field: v for g, v in words}), bool(turns)))
        else:  # pragma: no cover - the checker rejects everything else
            raise AssertionError(f"cannot generate a call of {name}")

    # -- statements --
    def stmts(self, body) -> None:
        dispatch = self._stmt
        statements = self.statements
        for stmt in body:
            start = len(self.code)
            self.mark(stmt.span)
            dispatch[type(stmt)](stmt)
            if statements is not None:
                statements.append((start, len(self.code)))

    def body(self, body, epilogue) -> None:
        """A routine's ``seq ... endseq`` body, then ``epilogue()`` (its end: END, RET, ...);
        with an error handler, the handler's code after it, ending the same way, and its
        entry in the handler table (what it protects, and the body's statements)."""
        main, handler = ast.split_handler(body)
        if handler is None:
            self.stmts(main)
            epilogue()
            return
        start, self.statements = len(self.code), []
        self.stmts(main)
        end, statements, self.statements = len(self.code), tuple(self.statements), None
        epilogue()
        entry = len(self.code)
        self.stmts(handler.body)
        epilogue()  # (its end leaves the routine as the body's does)
        self.handlers.append(HandlerInfo(start, end, entry, statements))

    def s_Word(self, node: ast.Word) -> None:
        """An error handler's word (compiler.recovery.WORDS)."""
        if node.name != "raise":
            self.emit(getattr(OP, node.name.upper()))  # RETRY, TRYNEXT
        elif not node.args:
            self.emit(OP.RERAISE)
        else:
            self.value(node.args[0], INTEGER)
            if len(node.args) > 1:
                self.value(node.args[1], STRING)
            else:
                self.constant("")
            self.emit(OP.RAISE)

    def s_Assign(self, node: ast.Assign) -> None:
        symbol = self.symbols[id(node)]
        self.assign(node, symbol)
        if symbol.persistent:  # (the runtime keeps its value: compiler.persistent)
            self.emit(OP.PERS_STORE, symbol.slot)

    def assign(self, node: ast.Assign, symbol: Symbol) -> None:
        path = node.path
        if not path:
            self.value(node.value, symbol.type)
            self.emit(self.store_op(symbol), symbol.slot)
            return
        # Walk down to the container of the last selector: arrays and records are
        # references in the VM, so changing a part of one changes the variable.
        types = self.path_types(symbol.type, path)
        container = types[-2]
        if isinstance(container, (ArrayT, RecordT)):
            self.load_path(symbol, path[:-1])
            self.store_into(container, path[-1], node.value)
        elif len(path) == 1:  # an axis of a joint variable
            self.emit(self.load_op(symbol), symbol.slot)
            self.value(path[0])
            self.value(node.value, REAL)
            self.emit(OP.SET_AXIS)
            self.emit(self.store_op(symbol), symbol.slot)
        else:  # an axis of a joint inside an array or a record: a[i].j[axis] := v
            holder, member = types[-3], isinstance(path[-2], ast.Member)
            self.load_path(symbol, path[:-2])
            if not member:
                self.value(path[-2])
            self.load_path(symbol, path[:-1])  # (the joint: a value, changed into a new one)
            self.value(path[-1])
            self.value(node.value, REAL)
            self.emit(OP.SET_AXIS)
            if member:
                self.emit(OP.SET_MEMBER, holder.index(path[-2].name))
            else:
                self.emit(OP.SET_ITEM, holder.low)

    def store_into(self, container, selector, value: ast.Expr) -> None:
        """The container on the stack: its element or field ``selector`` := ``value``."""
        if isinstance(container, RecordT):
            self.value(value, container.type_of(selector.name))
            self.emit(OP.SET_MEMBER, container.index(selector.name))
        else:
            self.value(selector)
            self.value(value, container.element)
            self.emit(OP.SET_ITEM, container.low)

    @staticmethod
    def path_types(t, path) -> list:
        """The types along an assignment's ``path``: the variable's, then each selector's."""
        types = [t]
        for selector in path:
            t = t.type_of(selector.name) if isinstance(selector, ast.Member) else \
                t.element if isinstance(t, ArrayT) else REAL
            types.append(t)
        return types

    def load_path(self, symbol: Symbol, path) -> None:
        """Push the (uncopied) array or record ``symbol[i].f...[k]``."""
        self.emit(self.load_op(symbol), symbol.slot)
        t = symbol.type
        for selector in path:
            if isinstance(selector, ast.Member):
                self.emit(OP.GET_MEMBER, t.index(selector.name))
                t = t.type_of(selector.name)
            else:
                self.value(selector)
                self.emit(OP.GET_ITEM, t.low)
                t = t.element

    def s_OutSet(self, node: ast.OutSet) -> None:
        self.value(node.index)
        self.value(node.value)
        self.emit(OP.OUT_SET)

    def s_Move(self, node: ast.Move) -> None:
        given = {c.name: c for c in node.clauses}
        search = "search" in given  # a search move starts and ends at rest (compiler.clauses)
        if search:
            self.emit(OP.SEARCH_BEGIN)
        for target in node.targets:
            self.value(target)
        mask = 0
        for clause in CLAUSE_TABLE:  # in bit order
            if clause.name in given:
                mask |= 1 << clause.bit
                self.value(given[clause.name].value, REAL if clause.stack_type == REAL else None)
        self.emit(MOVE_OPS[node.kind], mask)
        if search:
            self.emit(OP.SEARCH_END)

    def s_If(self, node: ast.If) -> None:
        to_end = []
        last = len(node.branches) - 1
        for i, (cond, body) in enumerate(node.branches):
            if i:
                self.mark(cond.span)
            self.value(cond)
            skip = self.emit(OP.JUMP_IF_FALSE, -1)
            self.stmts(body)
            if i < last or node.orelse:
                to_end.append(self.emit(OP.JUMP, -1))
            self.patch(skip)
        self.stmts(node.orelse)
        for at in to_end:
            self.patch(at)

    def s_While(self, node: ast.While) -> None:
        top = len(self.code)
        self.value(node.cond)
        exit_ = self.emit(OP.JUMP_IF_FALSE, -1)
        self.stmts(node.body)
        self.emit(OP.JUMP, top)
        self.patch(exit_)

    def s_Repeat(self, node: ast.Repeat) -> None:
        top = len(self.code)
        self.stmts(node.body)
        self.mark(node.cond.span)
        self.value(node.cond)
        self.emit(OP.JUMP_IF_FALSE, top)

    def s_For(self, node: ast.For) -> None:
        var = self.symbols[id(node)]
        step = self.values[id(node.step)] if node.step is not None else 1
        self.value(node.start)
        self.emit(self.store_op(var), var.slot)
        load_end, store_end, end_slot = self.temp(f"$end@{node.span.line}:{node.span.col}", INTEGER)
        self.value(node.stop)
        self.emit(store_end, end_slot)
        top = len(self.code)
        self.emit(self.load_op(var), var.slot)
        self.emit(load_end, end_slot)
        self.emit(OP.LE if step > 0 else OP.GE)
        exit_ = self.emit(OP.JUMP_IF_FALSE, -1)
        self.stmts(node.body)
        self.mark(node.span)
        self.emit(self.load_op(var), var.slot)
        self.constant(step)
        self.emit(OP.ADD)
        self.emit(self.store_op(var), var.slot)
        self.emit(OP.JUMP, top)
        self.patch(exit_)

    def s_WaitTime(self, node: ast.WaitTime) -> None:
        self.value(node.seconds, REAL)
        self.emit(OP.DWELL)

    def s_WaitFor(self, node: ast.WaitFor) -> None:
        if node.timeout is not None:
            self.value(node.timeout, REAL)
        self.emit(OP.WAIT_BEGIN, 1 if node.timeout is not None else 0)
        top = len(self.code)
        self.value(node.cond)
        self.emit(OP.WAIT_TEST, top)

    def s_CallProc(self, node: ast.CallProc) -> None:
        symbol = self.symbols.get(id(node))
        if symbol is None:  # (the checker found none of the program's: a built-in)
            self.state_routine(node, STATE_PROCEDURES[node.name])
            return
        indices: dict[int, list] = {}  # a 'var' argument's path: each index computed once, into a hidden slot
        for k, (arg, param_t) in enumerate(zip(node.args, symbol.params)):
            if k < len(symbol.refs) and symbol.refs[k] and not isinstance(arg, ast.Ref):
                indices[k] = self.fixed_path(arg)
                self.load_fixed(arg, indices[k])
                if isinstance(self.types[id(arg)], (ArrayT, RecordT)):
                    self.emit(OP.COPY)
            else:
                self.value(arg, param_t)
        self.emit(OP.CALL, symbol.index)
        for slot, (arg, by_ref) in enumerate(zip(node.args, symbol.refs)):  # 'var' parameters: their values back
            if not by_ref:
                continue
            variable = self.symbols[id(ast.reference_root(arg))]
            if slot not in indices:
                self.emit(OP.TAKE, symbol.index, slot)
                self.emit(self.store_op(variable), variable.slot)
            else:  # into the element or field the argument named (its indices as they were at the call)
                parts, fixed = ast.reference_parts(arg), indices[slot]
                self.load_fixed(parts[-1].base, fixed[:-1])
                last = parts[-1]
                if isinstance(last, ast.Field):
                    self.emit(OP.TAKE, symbol.index, slot)
                    self.emit(OP.SET_MEMBER, self.types[id(last.base)].index(last.name))
                else:
                    self.emit(fixed[-1][0], fixed[-1][1])
                    self.emit(OP.TAKE, symbol.index, slot)
                    self.emit(OP.SET_ITEM, self.types[id(last.base)].low)
            if variable.persistent:
                self.emit(OP.PERS_STORE, variable.slot)

    def fixed_path(self, arg: ast.Expr) -> list:
        """Each selector of a 'var' argument's path (``a[i].f[k]``): an index's value stored in
        a hidden slot now, as (load op, slot); None for a field."""
        fixed = []
        for part in ast.reference_parts(arg):
            if isinstance(part, ast.Field):
                fixed.append(None)
                continue
            load, store, slot = self.temp(f"$index@{part.span.line}:{part.span.col}", INTEGER)
            self.value(part.index)
            self.emit(store, slot)
            fixed.append((load, slot))
        return fixed

    def load_fixed(self, expr: ast.Expr, fixed: list) -> None:
        """Push (uncopied) what ``expr`` (a variable's path) names, its indices from ``fixed``."""
        self.e_Ref(ast.reference_root(expr))
        for part, index in zip(ast.reference_parts(expr), fixed):
            base_t = self.types[id(part.base)]
            if index is None:
                self.emit(OP.GET_MEMBER, base_t.index(part.name))
            else:
                self.emit(*index)
                self.emit(OP.GET_ITEM, base_t.low)

    def state_routine(self, node, routine) -> None:
        """A built-in routine of the robot's state: its arguments, then its instruction."""
        for arg, param_t in zip(node.args, routine.params):
            self.value(arg, param_t)
        self.emit(getattr(OP, routine.instruction))

    def s_Print(self, node: ast.Print) -> None:
        for value in node.values:
            self.value(value)
        self.emit(OP.PRINT, len(node.values))

    def s_Pause(self, node) -> None:
        self.emit(OP.PAUSE)

    def s_Halt(self, node) -> None:
        self.emit(OP.HALT)

    def s_Return(self, node: ast.Return) -> None:
        if node.value is None:
            self.keep_refs()
            self.emit(OP.RET)
            return
        self.value(node.value, self.result)
        self.emit(OP.RET_VALUE)

    def end_routine(self) -> None:
        """The end of the procedure or function being generated (see :meth:`generate`)."""
        if self.result is None:
            self.keep_refs()
        self.emit(OP.HALT if self.result is not None else OP.RET)

    def keep_refs(self) -> None:
        """Before a procedure returns: its 'var' parameters kept for the caller (KEEP)."""
        for slot in self.refs:
            self.emit(OP.KEEP, slot)

    def s_Trigger(self, node: ast.Trigger) -> None:
        place, unit = PLACE_INDEX[node.where], UNIT_INDEX[node.unit]
        self.value(node.amount, REAL)
        if node.action[0] == "out":
            self.value(node.action[1])
            self.value(node.action[2])
            self.emit(OP.TRIGGER_OUT, place, unit)
            return
        symbol = self.symbols[id(node)]
        self.value(node.action[3], symbol.type)
        self.emit(OP.TRIGGER_SET, place, unit, symbol.slot)

    def s_Enable(self, node: ast.Enable) -> None:
        scope = self.checked.procedures[self.symbols[id(node)].index]
        self.emit(OP.INT_ENABLE if node.on else OP.INT_DISABLE, scope.interrupt.index)

    def s_Use(self, node: ast.Use) -> None:
        self.value(node.value)
        name = self.constant_slot(describe_name(ast.expression_text(node.value)))
        self.emit(getattr(OP, FRAME_BY_KEYWORD[node.kind].instruction), name)

    # -- declarations --
    def default(self, t) -> None:
        if isinstance(t, ArrayT):
            self.default(t.element)
            self.emit(OP.MAKE_ARRAY, t.length)
            return
        if isinstance(t, RecordT):
            for _name, field_t in t.fields:
                self.default(field_t)
            self.emit(OP.MAKE_RECORD, self.records[t.name])
            return
        spec = self.checked.spec
        self.constant(zero_of(t, len(spec.main_axes), len(spec.additional_axes)))

    def init_vars(self, decls, lookup, zeros: bool = False) -> None:
        """Each variable of ``decls`` set to its initialiser (its zero value when it has
        none, or for all of them with ``zeros``)."""
        for decl in decls:
            self.in_file_of(decl)
            self.mark(decl.span)
            for name in decl.names:
                symbol = lookup(name)
                if decl.init is not None and not zeros:
                    self.value(decl.init, symbol.type)
                else:
                    self.default(symbol.type)
                self.emit(self.store_op(symbol), symbol.slot)
                if symbol.persistent and (not zeros or decl.init is None):  # the value the last run kept, if any
                    self.emit(OP.PERS_LOAD, symbol.slot)

    def generate(self, source_name: str) -> Program:
        checked = self.checked
        program = checked.program
        gvars = [d for d in program.decls if isinstance(d, ast.VarDecl)]
        lookup = checked.global_symbols.__getitem__
        if any(scope.result is not None for scope in checked.procedures):
            # a function called by an initialiser may read any global: every one holds its
            # zero value first, then the initialisers run in order
            self.init_vars(gvars, lookup, zeros=True)
            gvars = [d for d in gvars if d.init is not None]
        self.init_vars(gvars, lookup)
        self.file_index = 0
        end = program.span

        def end_program():
            self.mark(ast.Span(end.end_line, 1, end.end_line, end.end_col))
            self.emit(OP.END)
        self.body(program.body, end_program)
        procedures = []
        for scope in checked.procedures:
            self.locals = scope.slots
            self.refs = [slot for slot, by_ref in enumerate(scope.symbol.refs) if by_ref]
            entry = len(self.code)
            self.result = scope.result
            self.init_vars([v for v in scope.node.variables if isinstance(v, ast.VarDecl)], scope.names.__getitem__)
            self.in_file_of(scope.node)
            # a procedure returns at its end; a function never gets there (the checker saw a
            # return on every path): HALT keeps any jump to its end inside the code
            self.body(scope.node.body, self.end_routine)
            procedures.append(ProcInfo(scope.node.name, entry, len(scope.node.params), tuple(self.locals),
                                       type_name(scope.result) if scope.result is not None else ""))
            self.locals = self.result = None
            self.refs = []
        interrupts = []
        for scope in checked.interrupts:  # each condition: a function of its own, straight-line code
            self.in_file_of(scope.node)
            spec_node = scope.node.interrupt
            self.mark(spec_node.cond.span)
            entry = len(self.code)
            self.value(spec_node.cond)
            self.emit(OP.RET_VALUE)
            procedures.append(ProcInfo(f"{scope.node.name}.when", entry, 0, (), "bool"))
            decl = scope.interrupt
            interrupts.append(InterruptInfo(scope.node.name, len(procedures) - 1, scope.symbol.index, decl.priority,
                                            decl.stop, decl.then == "halt"))
        spec = checked.spec
        modules = tuple(checked.modules.values())
        return Program(program.name, source_name, spec.name, spec.hash, checked.robots,
                       tuple(self.constants), tuple(self.code), tuple(self.lines),
                       tuple(self.globals), tuple(procedures),
                       files=modules, line_files=tuple(self.line_files) if modules else (),
                       interrupts=tuple(interrupts), handlers=tuple(self.handlers),
                       persistent=tuple(s.slot for s in checked.global_symbols.values() if s.persistent),
                       records=tuple(RecordInfo(r.name, tuple((n, type_name(t)) for n, t in r.fields))
                                     for r in checked.records),
                       zones=tuple(checked.zones))


def generate(checked: CheckedProgram, source_file: str) -> Program:
    return CodeGen(checked).generate(Path(source_file).name)
