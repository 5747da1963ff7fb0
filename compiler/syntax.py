"""Source text -> AST, with precise syntax errors.

The AST is built *while* Lark's LALR parser reduces (an inline transformer): no parse
tree is ever materialised, which makes the whole parse cheaper than a bare tree parse.
Syntax errors become :class:`Diagnostic` s; after an error inside a statement the parser
resynchronises at the statement's ``;`` and goes on, so one run reports several.
"""
from __future__ import annotations

from lark import Token, Transformer
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken

from grammar import make_parser

from . import ast
from .clauses import NAMES as CLAUSE_NAMES
from .clauses import Motion
from .recovery import WORDS
from .records import END_WORD as RECORD_END, MAX_FIELDS, WORD as RECORD_WORD
from .zones import WORD as ZONE_WORD
from .diagnostics import CompileError, Diagnostic, did_you_mean
from .semantics import INT_MAX

#: Clause names that a move accepts (also used for "did you mean" on syntax errors).
CLAUSES = CLAUSE_NAMES

MAX_SYNTAX_ERRORS = 20

_INT_DIGITS = len(str(INT_MAX))  # an integer literal with more significant digits is out of range


class LongInteger(int):
    """The value of an integer literal with more significant digits than the largest
    integer: compares as ``INT_MAX + 1`` (so it is out of range wherever it is looked
    at) and keeps its ``digits`` for the checker's message. Its exact value is never
    computed: ``int()`` of more than 4,300 digits raises ValueError (and is quadratic)."""

    digits: str

    def __new__(cls, digits: str):
        self = super().__new__(cls, INT_MAX + 1)
        self.digits = digits
        return self


_Span = ast.Span
_new_tuple = tuple.__new__


def _span(tok: Token) -> ast.Span:
    return _new_tuple(_Span, (tok.line, tok.column, tok.end_line, tok.end_column))


def _stmts(items) -> tuple:
    return tuple(item for item in items if not isinstance(item, (Token, _Elsif, _Else)))


class _Elsif(tuple):
    """(cond, body) of an ``elsif`` branch, marked so ``if_stmt`` can tell it apart."""


class _Else(tuple):
    """The body of an ``else`` branch."""


class _Builder(Transformer):
    """One method per grammar rule or alias; each takes the rule's children (a list, the
    filtered tokens already gone) and returns an AST node. Plain list callbacks rather
    than ``v_args(inline=True)``, which costs three extra calls per reduction."""

    # -- program structure --
    def start(self, c):
        return c[0]

    def program(self, c):
        program_kw, name, *rest = c
        spec, decls, imports = _header(rest[:-2])
        body, end_kw = rest[-2], rest[-1]
        return ast.Program(name.value.lower(), spec[0], spec[1], decls, body,
                           _span(program_kw).to(_span(end_kw)), imports)

    def module(self, c):
        module_kw, name, *rest = c
        _spec, decls, imports = _header(rest[:-1])
        return ast.Module(name.value.lower(), imports, decls, _span(module_kw).to(_span(rest[-1])))

    def import_decl(self, c):
        kw, string = c
        return ast.Import(_unquote(string.value), _span(kw).to(_span(string)))

    def spec(self, c):
        kw, string = c
        return ("spec", _unquote(string.value), _span(string))

    def const_section(self, c):
        kw, *items = c
        return list(items)

    def const_item(self, c):
        name, value = c
        return ast.ConstDecl(name.value.lower(), value, _span(name).to(value.span))

    def var_section(self, c):
        kw, *items = c
        if items and isinstance(items[0], Token):  # var persistent ...
            word = items.pop(0)
            return [ast.replace(item, section=word.value.lower(), section_span=_span(word))
                    if isinstance(item, ast.VarDecl) else item for item in items]
        return list(items)

    def record_decl(self, c):
        word, name, *fields, end = c
        return ast.RecordDecl(name.value.lower(), tuple(fields), _span(word).to(_span(end)), _span(name),
                              word.value.lower(), _span(word), end.value.lower(), _span(end))

    def zone_decl(self, c):
        word, name, shape, signal, output = c
        end = output.span if output is not None else shape.span
        return ast.ZoneDecl(name.value.lower(), shape, output, _span(word).to(end), _span(name), word.value.lower(),
                            _span(word), signal.value.lower() if signal is not None else "",
                            _span(signal) if signal is not None else None)

    def record_field(self, c):
        *names, type_ = c
        return ast.RecordField(tuple(n.value.lower() for n in names), type_, _span(names[0]).to(type_.span),
                               tuple(_span(n) for n in names))

    def var_item(self, c):
        items = c
        names, type_, init = items[:-2], items[-2], items[-1]
        end = init.span if init is not None else type_.span
        return ast.VarDecl(tuple(n.value.lower() for n in names), type_, init,
                           _span(names[0]).to(end), tuple(_span(n) for n in names))

    def named_type(self, c):
        name, = c
        return ast.NamedType(name.value.lower(), _span(name))

    def array_type(self, c):
        kw, low, high, element = c
        return ast.ArrayType(low, high, element, _span(kw).to(element.span))

    def procedure(self, c):
        kw, name, *rest = c
        params = ()
        variables = []
        for item in rest[:-2]:
            if isinstance(item, list):
                variables.extend(item)
            else:
                params = item
        return ast.Procedure(name.value.lower(), params, tuple(variables), rest[-2],
                             _span(kw).to(_span(rest[-1])), _span(name))

    def function(self, c):
        kw, name, *rest = c
        params, result, variables = (), None, []
        for item in rest[:-2]:
            if isinstance(item, list):
                variables.extend(item)
            elif isinstance(item, tuple):
                params = item
            else:
                result = item
        return ast.Procedure(name.value.lower(), params, tuple(variables), rest[-2],
                             _span(kw).to(_span(rest[-1])), _span(name), result)

    def interrupt(self, c):
        kw, name, _when, cond, *rest = c
        options, variables = [], []
        for item in rest[:-2]:  # the options, then the var sections; then the block and endinterrupt
            if isinstance(item, list):
                variables.extend(item)
            else:
                options.append(item)
        head_end = options[-1][2] if options else cond.span
        spec = ast.InterruptSpec(cond, tuple(options), _span(kw).to(head_end))
        return ast.Procedure(name.value.lower(), (), tuple(variables), rest[-2], _span(kw).to(_span(rest[-1])),
                             _span(name), None, spec)

    def interrupt_option(self, c):
        word, *number = c
        value = number[0] if number else None
        span = _span(word).to(_span(number[0])) if number else _span(word)
        return (word.value.lower(), int(value) if value is not None and value.isdigit() else value, span)

    def interrupt_then(self, c):
        word, = c
        return ("then", word.value.lower(), _span(word))

    def params(self, c):
        groups = c
        return tuple(p for group in groups if group is not None for p in group)

    def param(self, c):
        items = list(c)
        by_ref = bool(items) and getattr(items[0], "type", None) == "VAR"
        names, type_ = items[1 if by_ref else 0:-1], items[-1]
        return [ast.Param(n.value.lower(), type_, _span(n), by_ref) for n in names]

    def block(self, c):
        seq_kw, *items = c
        return _stmts(items)  # (an error handler, the last item when there is one, is kept)

    def on_error(self, c):
        kw, word, *body = c
        body = _stmts(body)
        return ast.OnError(word.value.lower(), _span(word), body, _span(kw).to(body[-1].span if body else _span(word)))

    def word_stmt(self, c):
        name, *args = c
        args = tuple(a for a in args if a is not None)
        return ast.Word(name.value.lower(), args, _span(name).to(args[-1].span) if args else _span(name), _span(name))

    # -- statements --
    def assign(self, c):
        name, *path, value = c
        return ast.Assign(name.value.lower(), tuple(path), value, _span(name).to(value.span), _span(name))

    def member(self, c):
        name, = c
        return ast.Member(name.value.lower(), _span(name))

    def out_stmt(self, c):
        kw, index, value = c
        return ast.OutSet(index, value, _span(kw).to(value.span))

    def move(self, c):
        kw, kind, *rest = c
        targets = tuple(item for item in rest if not isinstance(item, ast.Clause))
        clauses = tuple(item for item in rest if isinstance(item, ast.Clause))
        return ast.Move(Motion(kind.value.lower()), targets, clauses, _span(kw).to(rest[-1].span))

    def clause(self, c):
        name, value = c
        return ast.Clause(name.value.lower(), value, _span(name).to(value.span), _span(name))

    def if_stmt(self, c):
        kw, cond, *rest = c
        branches = [(cond, _stmts(rest))]
        orelse = ()
        for item in rest:
            if isinstance(item, _Elsif):
                branches.append((item[0], item[1]))
            elif isinstance(item, _Else):
                orelse = tuple(item)
        return ast.If(tuple(branches), orelse, _span(kw).to(_span(rest[-1])))

    def elsif(self, c):
        kw, cond, *body = c
        return _Elsif((cond, _stmts(body)))

    def else_part(self, c):
        kw, *body = c
        return _Else(_stmts(body))

    def while_stmt(self, c):
        kw, cond, *rest = c
        return ast.While(cond, _stmts(rest), _span(kw).to(_span(rest[-1])))

    def repeat_stmt(self, c):
        kw, *rest = c
        cond = rest[-1]
        return ast.Repeat(_stmts(rest[:-1]), cond, _span(kw).to(cond.span))

    def for_stmt(self, c):
        kw, name, start, stop, step, *rest = c
        return ast.For(name.value.lower(), start, stop, step, _stmts(rest),
                       _span(kw).to(_span(rest[-1])), _span(name))

    def wait_time(self, c):
        kw, seconds, sec = c
        return ast.WaitTime(seconds, _span(kw).to(_span(sec)))

    def wait_for(self, c):
        kw, for_kw, cond, timeout, sec = c
        end = _span(sec) if sec is not None else cond.span
        return ast.WaitFor(cond, timeout, _span(kw).to(end))

    def call_stmt(self, c):
        kw, name, *args = c
        args = tuple(a for a in args if a is not None)
        end = args[-1].span if args else _span(name)
        return ast.CallProc(name.value.lower(), args, _span(kw).to(end), _span(name))

    def print_stmt(self, c):
        kw, *values = c
        return ast.Print(values, _span(kw).to(values[-1].span))

    def pause(self, c):
        kw, = c
        return ast.Pause(_span(kw))

    def halt(self, c):
        kw, = c
        return ast.Halt(_span(kw))

    def return_stmt(self, c):
        kw, value = c
        return ast.Return(value, _span(kw).to(value.span) if value is not None else _span(kw))

    def trigger_stmt(self, c):
        kw, _when, amount, unit, direction, reference, action = c
        return ast.Trigger(amount, unit.value.lower(), f"{direction.value.lower()} {reference.value.lower()}",
                           _span(unit).to(_span(reference)), action, _span(kw).to(action[-1].span))

    def trigger_out(self, c):
        _kw, index, value = c
        return ("out", index, value)

    def trigger_set(self, c):
        name, value = c
        return ("set", name.value.lower(), _span(name), value)

    def enable_stmt(self, c):
        kw, name = c
        return ast.Enable(name.value.lower(), kw.type == "ENABLE", _span(kw).to(_span(name)), _span(name))

    def use_stmt(self, c):
        kw, which, value = c
        return ast.Use(which.value.lower(), _span(which), value, _span(kw).to(value.span))

    # -- expressions --
    def binary(self, c):
        left, op, right = c
        return ast.Binary(op.value.lower(), left, right, left.span.to(right.span), _span(op))

    def unary(self, c):
        op, operand = c
        return ast.Unary(op.value.lower(), operand, _span(op).to(operand.span))

    def index(self, c):
        base, index = c
        return ast.Index(base, index, base.span.to(index.span))

    def field(self, c):
        base, name = c
        return ast.Field(base, name.value.lower(), base.span.to(_span(name)))

    def number(self, c):
        tok, = c
        text = tok.value
        if not text.isdigit():
            return ast.Number(float(text), _span(tok))  # float() takes any length (inf if too large)
        digits = text.lstrip("0") or "0"
        if len(digits) > _INT_DIGITS:  # never int() it: thousands of digits raise ValueError
            return ast.Number(LongInteger(digits), _span(tok))
        return ast.Number(int(digits), _span(tok))

    def string(self, c):
        tok, = c
        return ast.String(_unquote(tok.value), _span(tok))

    def true(self, c):
        tok, = c
        return ast.Bool(True, _span(tok))

    def false(self, c):
        tok, = c
        return ast.Bool(False, _span(tok))

    def ref(self, c):
        name, = c
        return ast.Ref(name.value.lower(), _span(name))

    def call(self, c):
        name, *args = c
        args = tuple(a for a in args if a is not None)
        span = _span(name)
        return ast.Call(name.value.lower(), args, span.to(args[-1].span) if args else span, span)

    def input(self, c):
        kw, index = c
        return ast.Input(index, _span(kw).to(index.span))

    def output(self, c):
        kw, index = c
        return ast.Output(index, _span(kw).to(index.span))


def _header(items) -> tuple[tuple, tuple, tuple]:
    """A program's or module's (system_specification (file, span), declarations, imports)
    from the children between its name and its body."""
    spec: tuple = (None, None)
    decls: list = []
    imports: list = []
    for item in items:
        if isinstance(item, tuple) and item and item[0] == "spec":
            spec = (item[1], item[2])
        elif isinstance(item, list):
            decls.extend(item)
        elif isinstance(item, (ast.Procedure, ast.RecordDecl, ast.ZoneDecl)):
            decls.append(item)
        elif isinstance(item, ast.Import):
            imports.append(item)
    return spec, tuple(decls), tuple(imports)


def _unquote(text: str) -> str:
    return text[1:-1].replace('\\"', '"').replace("\\\\", "\\")


_PARSER = None


def _parser():
    global _PARSER
    if _PARSER is None:
        _PARSER = make_parser(transformer=_Builder())
    return _PARSER


# ---- syntax errors --------------------------------------------------------------------

_REGEX_NAMES = {"NAME": "a name", "NUMBER": "a number", "STRING": "a string",
                "COMPARE": "a comparison", "ADD_OP": "'+' or '-'", "MUL_OP": "'*' or '/'",
                "$END": "end of file"}

#: Tokens that open or close a block: resynchronising across one would only cascade.
_STRUCTURE = {"PROGRAM", "ENDPROGRAM", "MODULE", "ENDMODULE", "SEQ", "ENDSEQ", "PROCEDURE", "ENDPROCEDURE", "FUNCTION",
              "ENDFUNCTION", "INTERRUPT", "ENDINTERRUPT", "IF",
              "ELSIF", "ELSE", "ENDIF", "WHILE", "ENDWHILE", "REPEAT", "UNTIL", "FOR",
              "ENDFOR", "THEN", "DO", "VAR", "CONST"}
_KEYWORD_TYPES = _STRUCTURE | {"MOVE", "WAIT", "OUT", "CALL", "PRINT", "PAUSE", "HALT", "RETURN", "ENDPROGRAM",
                                "IMPORT", "USE", "ENABLE", "DISABLE", "TRIGGER"}
_STMT_BOUNDARY = {"SEMICOLON", "SEQ", "THEN", "DO", "ELSE", "REPEAT"}


def _describe_terminal(name: str) -> str:
    if name in _REGEX_NAMES:
        return _REGEX_NAMES[name]
    for term in _parser().terminals:
        if term.name == name:
            value = term.pattern.value
            if term.pattern.type == "str":
                return f"'{value}'"
            return f"'{name.lower()}'"
    return name.lower()


def _expected_text(expected) -> str:
    names = sorted({_describe_terminal(n) for n in expected})
    if len(names) > 6:
        return "one of " + ", ".join(names[:6]) + ", ..."
    return names[0] if len(names) == 1 else "one of " + ", ".join(names)


_KEYWORDS: list[str] = []


def _keywords() -> list[str]:
    if not _KEYWORDS:
        _KEYWORDS.extend(t.pattern.value for t in _parser().terminals
                         if t.pattern.type == "str" and t.pattern.value.replace("_", "").isalpha())
    return _KEYWORDS


def _tokens(text: str) -> list[Token]:
    """All tokens of ``text``, lexing on past characters that are no token's."""
    for _ in range(MAX_SYNTAX_ERRORS):
        try:
            return list(_parser().lex(text))
        except UnexpectedCharacters as err:
            text = _blank(text, err.pos_in_stream, err.pos_in_stream + 1)
    return []


def _diag(file, span: ast.Span, message, hint=None) -> Diagnostic:
    return Diagnostic(file, span.line, span.col, span.end_line, span.end_col, "error", message, hint)


def _unexpected_character(err: UnexpectedCharacters, text: str, file: str):
    pos = err.pos_in_stream
    char = text[pos]
    span = ast.Span(err.line, err.column, err.line, err.column + 1)
    if char == "{" and "}" not in text[pos:]:
        return _diag(file, span, "unterminated comment: this '{' is never closed by '}'"), None
    if text.startswith("(*", pos) and "*)" not in text[pos:]:
        return _diag(file, span.to(ast.Span(err.line, err.column + 1, err.line, err.column + 2)),
                     "unterminated comment: this '(*' is never closed by '*)'"), None
    if char == '"':
        line_rest = text[pos + 1:].split("\n", 1)[0]
        if '"' not in line_rest.replace('\\"', ""):
            return (_diag(file, span, "unterminated string: a string must end on the line it starts",
                          'close it with "'), ("resync", pos))
        return (_diag(file, span, "invalid string", 'inside a string only \\" and \\\\ are escapes'),
                ("resync", pos))
    hint = "strings are written in double quotes" if char == "'" else None
    return _diag(file, span, f"unexpected character {char!r}", hint), ("resync", pos)


def _classify(err: UnexpectedInput, text: str, file: str, tokens: list[Token]):
    """A diagnostic for ``err`` and how to recover from it: ``None`` (stop), ``("resync",
    offset)`` (skip the statement around offset) or ``("patch", start, end, text)`` (a fix
    of the same length, which keeps every position, so parsing can go on as if mended)."""
    if isinstance(err, UnexpectedCharacters):
        return _unexpected_character(err, text, file)

    assert isinstance(err, UnexpectedToken)
    tok = err.token
    expected = set(err.expected)
    prev = None
    for candidate in tokens:
        if candidate.start_pos is not None and tok.start_pos is not None and candidate.start_pos >= tok.start_pos:
            break
        prev = candidate
    misspelled = _misspelled_word(tokens, tok)
    if misspelled is not None:  # ("endwhle;" is a word statement to the parser: the block stays open)
        return _misspelled_keyword(file, *misspelled)
    if tok.type == "$END":
        last = tokens[-1] if tokens else None
        line = last.end_line if last else 1
        col = last.end_column if last else 1
        return (_diag(file, ast.Span(line, col, line, col + 1),
                      f"unexpected end of file; expected {_expected_text(expected)}"), None)

    # "speed ptp := 0.1": two words that, joined by '_', make a clause or keyword.
    if prev is not None and prev.type == "NAME":
        joined = f"{prev.value}_{tok.value}".lower()
        if joined in CLAUSES or joined in _keywords():
            diag = _diag(file, _span(prev).to(_span(tok)), f"unexpected '{tok.value}' after '{prev.value}'",
                         f"did you mean '{joined}'?")
            if tok.start_pos - prev.end_pos == 1:
                return diag, ("patch", prev.end_pos, tok.start_pos, "_")
            return diag, ("resync", tok.start_pos)

    # "endseg" where "endseq" belongs: a misspelled keyword reads as a name, and the
    # parser only notices at the token after it.
    if prev is not None and prev.type == "NAME" and ("NAME" not in expected or _word_at_start(tokens, prev)):
        guess = did_you_mean(prev.value, _keywords(), cutoff=0.75)
        if guess and guess != prev.value.lower():
            return _misspelled_keyword(file, prev, guess)

    if tok.type in ("LSQB", "DOT") and prev is not None and prev.type == "NAME" and _after_trigger_do(tokens, prev):
        return (_diag(file, _span(tok), f"a trigger sets a global variable by its name: '{prev.value}{tok.value}...' "
                      "is an element or a field", "set a plain global in the trigger, and the element or field from "
                                                  "it after the move"), None)
    if tok.type == "NAME" and tok.value.lower() in (RECORD_WORD, ZONE_WORD) and {"VAR", "SEQ"} <= expected:
        what = "record types" if tok.value.lower() == RECORD_WORD else "world zones"
        return (_diag(file, _span(tok), f"{what} are declared at the program's or a module's level, not in a "
                      "procedure, function or interrupt", "move the declaration before the routine"), None)
    record = _open_record(tokens, tok)
    if record is not None:
        opener, fields = record
        name = tokens[tokens.index(opener) + 1].value
        if not fields and prev is not None and prev.value.lower() == RECORD_END:
            return (_diag(file, _span(opener).to(_span(prev)), f"record {name} has no fields: a record has 1 to "
                          f"{MAX_FIELDS} (a line NAME : TYPE; each)"), None)
        if tok.type != "NAME" or tok.value.lower() in _keywords():
            return (_diag(file, _span(tok), f"the record '{name}' at line "
                          f"{opener.line} is not closed: expected '{RECORD_END};' before '{tok.value}'",
                          f"add '{RECORD_END};' after its last field"), None)

    hint = None
    if tok.type == "NAME" and tok.value.lower() not in _keywords():
        words = [_describe_terminal(n).strip("'") for n in expected if n not in _REGEX_NAMES]
        guess = did_you_mean(tok.value, [w for w in words if w.replace("_", "").isalpha()], cutoff=0.7)
        if guess:
            hint = f"did you mean '{guess}'?"
    is_keyword = tok.type in _KEYWORD_TYPES or tok.value.upper() in _KEYWORD_TYPES
    if "SEMICOLON" in expected and prev is not None and (prev.end_line < tok.line or is_keyword or tok.type == "NAME"):
        span = ast.Span(prev.end_line, prev.end_column, prev.end_line, prev.end_column + 1)
        return _diag(file, span, f"expected ';' after '{prev.value}'", hint), ("resync", tok.start_pos)
    unclosed = _unclosed_block(tokens, tok) or _unclosed_routine(tokens, tok, expected)
    if unclosed is not None and tok.type not in _CLOSERS:
        opener, closer = unclosed
        return (_diag(file, _span(tok), f"the '{opener.value}' at line {opener.line} is not closed: expected "
                      f"'{closer}' before '{tok.value}'", f"add '{closer};' before it"), None)
    if unclosed is not None:
        opener, closer = unclosed
        return (_diag(file, _span(tok), f"'{tok.value}' ends a block, but the '{opener.value}' at line "
                      f"{opener.line} is not closed", f"add '{closer};' before it"), None)
    if "NAME" in expected and tok.value.lower() in _keywords():
        return (_diag(file, _span(tok), f"'{tok.value}' is a reserved word and cannot be used as a name",
                      "choose another name"), ("resync", tok.start_pos))

    return (_diag(file, _span(tok), f"unexpected '{tok.value}'; expected {_expected_text(expected)}", hint),
            ("resync", tok.start_pos))


def _after_trigger_do(tokens: list[Token], name: Token) -> bool:
    """Whether ``name`` is the first token after a trigger's ``do``."""
    i = next((k for k, t in enumerate(tokens) if t.start_pos == name.start_pos), None)
    if i is None or i == 0 or tokens[i - 1].type != "DO":
        return False
    for k in range(i - 2, -1, -1):
        if tokens[k].type in _STMT_BOUNDARY or tokens[k].type in _STRUCTURE:
            return False
        if tokens[k].type == "TRIGGER":
            return True
    return False


def _open_record(tokens: list[Token], tok: Token) -> tuple[Token, int] | None:
    """When ``tok`` comes inside a record's declaration not closed yet (``record NAME`` at a
    declaration's start, no ``endrecord;`` since): its ``record`` word and how many fields
    (``:``) came before ``tok``."""
    found, fields = None, 0
    for i, candidate in enumerate(tokens):
        if candidate.start_pos is None or tok.start_pos is None or candidate.start_pos >= tok.start_pos:
            break
        word = candidate.value.lower() if candidate.type == "NAME" else ""
        if word == RECORD_WORD and i + 1 < len(tokens) and tokens[i + 1].type == "NAME" and \
                (i == 0 or tokens[i - 1].type == "SEMICOLON"):
            found, fields = candidate, 0
        elif found is not None and word == RECORD_END and i + 1 < len(tokens) and tokens[i + 1].type == "SEMICOLON" \
                and tokens[i + 1].start_pos < tok.start_pos:
            found = None
        elif found is not None and candidate.type == "COLON":
            fields += 1
    return (found, fields) if found is not None else None


def _misspelled_keyword(file: str, word: Token, guess: str):
    """The diagnostic of name ``word`` where keyword ``guess`` belongs, and how to go on: mended
    in place when both are as long, else past its statement; a misspelled block keyword
    leaves the block open, and going on would cascade."""
    diag = _diag(file, _span(word), f"unexpected name '{word.value}'", f"did you mean '{guess}'?")
    if len(guess) == len(word.value):
        return diag, ("patch", word.start_pos, word.end_pos, guess)
    return diag, (None if guess.upper() in _STRUCTURE else ("resync", word.start_pos))


def _word_at_start(tokens: list[Token], name: Token) -> bool:
    """Whether ``name`` starts a statement and is not one of the handler's words (the
    parser reads it as the start of a word statement: ``endseg endprogram``)."""
    i = next((k for k, t in enumerate(tokens) if t.start_pos == name.start_pos), None)
    return i is not None and (i == 0 or tokens[i - 1].type in _STMT_BOUNDARY) and name.value.lower() not in WORDS


def _misspelled_word(tokens: list[Token], tok: Token) -> tuple[Token, str] | None:
    """The last misspelled keyword before ``tok`` that stands alone as a statement
    (``endwhle;``): the parser takes it for a word statement (compiler.recovery.WORDS), so
    it only notices later that a block is not closed. (The token and the keyword meant.)"""
    found = None
    for i, candidate in enumerate(tokens[:-1]):
        if candidate.start_pos is None or tok.start_pos is None or candidate.start_pos >= tok.start_pos:
            break
        if candidate.type == "NAME" and tokens[i + 1].type == "SEMICOLON" and \
                (i == 0 or tokens[i - 1].type in _STMT_BOUNDARY) and candidate.value.lower() not in WORDS:
            guess = did_you_mean(candidate.value, _keywords(), cutoff=0.75)
            if guess and guess != candidate.value.lower():
                found = (candidate, guess)
    return found


#: Each block's opening keyword and the one that closes it.
_BLOCKS = {"PROGRAM": "ENDPROGRAM", "MODULE": "ENDMODULE", "PROCEDURE": "ENDPROCEDURE", "FUNCTION": "ENDFUNCTION",
           "INTERRUPT": "ENDINTERRUPT", "SEQ": "ENDSEQ",
           "IF": "ENDIF",
           "WHILE": "ENDWHILE", "FOR": "ENDFOR", "REPEAT": "UNTIL"}
_CLOSERS = set(_BLOCKS.values())


def _unclosed_block(tokens: list[Token], tok: Token) -> tuple[Token, str] | None:
    """When ``tok`` closes a block other than the innermost open one (``endseq`` while a
    ``for`` is open): the innermost opener and the keyword that closes it."""
    if tok.type not in _CLOSERS:
        return None
    stack = _open_blocks(tokens, tok)
    if not stack or _BLOCKS[stack[-1].type] == tok.type:
        return None
    return stack[-1], _BLOCKS[stack[-1].type].lower()


def _open_blocks(tokens: list[Token], tok: Token) -> list[Token]:
    """The blocks open before ``tok``, outermost first (their opening tokens)."""
    stack: list[Token] = []
    for candidate in tokens:
        if candidate.start_pos is None or tok.start_pos is None or candidate.start_pos >= tok.start_pos:
            break
        if candidate.type in _BLOCKS:
            stack.append(candidate)
        elif candidate.type in _CLOSERS and stack and _BLOCKS[stack[-1].type] == candidate.type:
            stack.pop()
    return stack


def _unclosed_routine(tokens: list[Token], tok: Token, expected) -> tuple[Token, str] | None:
    """A procedure, function or program whose body has ended (its closing keyword is what
    the parser expects) but whose closing keyword is missing before ``tok``, a keyword that
    starts or ends another block: the opener and its closing keyword."""
    if tok.type not in _BLOCKS and tok.type not in _CLOSERS:
        return None
    stack = _open_blocks(tokens, tok)
    if not stack or stack[-1].type not in ("PROCEDURE", "FUNCTION", "INTERRUPT", "PROGRAM", "MODULE"):
        return None
    closer = _BLOCKS[stack[-1].type]
    return (stack[-1], closer.lower()) if closer in expected and tok.type != closer else None


def _resync_region(tokens: list[Token], offset: int) -> tuple[int, int] | None:
    """The [start, end) text range of the statement around ``offset``, if blanking it is safe."""
    start_index = 0
    for i, tok in enumerate(tokens):
        if tok.start_pos >= offset:
            break
        if tok.type in _STMT_BOUNDARY:
            start_index = i + 1
    end_index = None
    for i in range(start_index, len(tokens)):
        if tokens[i].start_pos >= offset and tokens[i].type == "SEMICOLON":
            end_index = i
            break
    if end_index is None or start_index >= len(tokens):
        return None
    if any(t.type in _STRUCTURE for t in tokens[start_index:end_index + 1]):
        return None
    return tokens[start_index].start_pos, tokens[end_index].end_pos


def _blank(text: str, start: int, end: int) -> str:
    middle = "".join(c if c == "\n" else " " for c in text[start:end])
    return text[:start] + middle + text[end:]


def parse_recovering(text: str, file: str = "<input>") -> tuple[ast.Program | None, list[Diagnostic]]:
    """Parse L-IRL source, going on after syntax errors.

    Returns (tree, diagnostics). The tree is None when a statement had to be skipped to
    go on; when every error could be mended in place (same length, so every position
    holds) the tree of the mended text comes back, and it can still be checked.
    """
    parser = _parser()
    try:
        return parser.parse(text), []
    except UnexpectedInput as first:
        err = first
    diagnostics: list[Diagnostic] = []
    mended_only = True
    tree = None
    while len(diagnostics) < MAX_SYNTAX_ERRORS:
        tokens = _tokens(text)
        diag, recovery = _classify(err, text, file, tokens)
        if not any((d.line, d.column) == (diag.line, diag.column) for d in diagnostics):
            diagnostics.append(diag)
        if recovery is None:
            mended_only = False
            break
        if recovery[0] == "patch":
            _, start, end, replacement = recovery
            text = text[:start] + replacement + text[end:]
        else:
            mended_only = False
            region = _resync_region(tokens, recovery[1])
            if region is None:
                break
            text = _blank(text, *region)
        try:
            tree = parser.parse(text)
            break
        except UnexpectedInput as again:
            err = again
    return (tree if mended_only else None), diagnostics


def parse(text: str, file: str = "<input>") -> ast.Program:
    """Parse L-IRL source; raises :class:`CompileError` with every syntax error found."""
    tree, diagnostics = parse_recovering(text, file)
    if diagnostics:
        raise CompileError(diagnostics)
    return tree
