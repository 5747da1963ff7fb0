r"""The parser of the runtime's text scripting interface.

Operators type short commands, as in the OROCOS task browser, to list the components,
read and write their properties and call their operations. ``parse`` turns one line of
text into a command object; carrying it out is the caller's business. The parser is a
small tokenizer and a recursive-descent parser of our own: text is never handed to
Python to evaluate.

Grammar (spaces and tabs are allowed between any two tokens)::

    command := "components"                               list the components
             | "help" [NAME]                               usage, or one component
             | target [index]                              read a property (one element)
             | target [index] "=" value                    write a property (one element)
             | target "(" [value ("," value)*] ")"         call an operation
    target  := NAME "." NAME                               component.member, e.g. servo.kp
    index   := "[" digits "]"                              e.g. io.in[3]
    NAME    := [A-Za-z_][A-Za-z0-9_]*
    value   := number | string | "true" | "false"
    number  := ["+" | "-"] (digits ["." [digits]] | "." digits) [("e" | "E") ["+" | "-"] digits]
    string  := '"' chars '"' | "'" chars "'"              escapes \\ \" \' \n \t \r

"components" and "help" are commands only when no "." follows, so a component may be
called ``help``. A number without fraction and exponent is an int, any other a float,
which must be finite (``nan`` and ``inf`` are NAMEs, not values). A command is one line
(no line breaks, also not inside strings: write \n) of at most 10,000 characters.

For any text ``parse`` returns a command or raises ScriptError, and nothing else; the
error says what is wrong and at which 1-based column. ``format_value`` is the inverse of
value parsing, for display.
"""
from __future__ import annotations

import numbers
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import NamedTuple

from runtime.wire.protocol import ProtocolError

MAX_LENGTH = 10_000
_MAX_DIGITS = 4300  # Python's default limit for int(str); we keep it whatever the interpreter's setting

Value = bool | int | float | str

HELP_TEXT = r"""Commands, one per line:
  components                       list the components
  help [component]                 this text, or what a component offers
  component.property               read a property, e.g. servo.kp
  component.property = value       write a property, e.g. trajectory.budget = 500
  component.property[n] (= value)  one element, e.g. io.in[3] = true (simulation only)
  component.operation(value, ...)  call an operation, e.g. trajectory.configure() (while no program runs)
Values: numbers (3, -2, 2.5, 1e-3), true, false, and strings in double or single quotes
with the escapes \\ \" \' \n \t \r.
"""


class ScriptError(ValueError):
    """A command that does not parse: what is wrong (``message``) and where (``column``, 1-based)."""

    def __init__(self, message: str, column: int) -> None:
        super().__init__(f"column {column}: {message}")
        self.message = message
        self.column = column

    def __reduce__(self):  # keeps the exception picklable despite its two-argument constructor
        return (type(self), (self.message, self.column))


@dataclass(frozen=True)
class Components:
    """``components``: list the components."""


@dataclass(frozen=True)
class Help:
    """``help`` or ``help servo``."""

    component: str | None = None


@dataclass(frozen=True)
class GetProperty:
    """``servo.kp``, or one element: ``io.in[3]``."""

    component: str
    name: str
    index: int | None = None


@dataclass(frozen=True)
class SetProperty:
    """``servo.kp = 2.5``, or one element: ``io.in[3] = true``."""

    component: str
    name: str
    value: Value
    index: int | None = None


@dataclass(frozen=True)
class CallOperation:
    """``fsm.request_state("Calibrate Offsets")``."""

    component: str
    name: str
    args: tuple[Value, ...]


Command = Components | Help | GetProperty | SetProperty | CallOperation


# ---- tokenizer ---------------------------------------------------------------------------

class _Token(NamedTuple):
    kind: str  # "name", "number", "string", "punct" or "end"
    text: str  # the source text of the token
    value: object  # the number or the string's contents
    column: int


_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_WORD = re.compile(r"[A-Za-z0-9_.]*")  # what may not follow a number directly
_PUNCT = ".=(),[]"
_ESCAPES = {"\\": "\\", '"': '"', "'": "'", "n": "\n", "t": "\t", "r": "\r"}
_ONE_LINE = "a command must be on one line"


def _show(text: str) -> str:
    """``text`` quoted for an error message, shortened if long."""
    if len(text) > 20:
        text = text[:20] + "..."
    return f"'{text}'" if text.isprintable() and "'" not in text else repr(text)


def _number(text: str, start: int, end: int) -> int | float:
    lexeme, column = text[start:end], start + 1
    if any(c in lexeme for c in ".eE"):
        value = float(lexeme)
        if value in (float("inf"), float("-inf")):
            raise ScriptError(f"number out of range: {_show(lexeme)}", column)
        return value
    if len(lexeme.lstrip("+-")) > _MAX_DIGITS:
        raise ScriptError(f"integer has too many digits (at most {_MAX_DIGITS})", column)
    try:
        return int(lexeme)
    except ValueError:  # the interpreter's own digit limit may be lower than ours
        raise ScriptError("integer has too many digits", column) from None


def _string(text: str, start: int) -> tuple[str, int]:
    """The contents of the string whose opening quote is at ``start``, and the index after it."""
    quote, parts, i = text[start], [], start + 1
    while i < len(text):
        char = text[i]
        if char == quote:
            return "".join(parts), i + 1
        if char in "\r\n":
            raise ScriptError(_ONE_LINE, i + 1)
        if char == "\\" and i + 1 < len(text):
            escape = text[i + 1]
            if escape not in _ESCAPES:
                raise ScriptError(f"unknown escape {_show(char + escape)} (use \\\\ \\\" \\' \\n \\t \\r)", i + 1)
            parts.append(_ESCAPES[escape])
            i += 2
            continue
        parts.append(char)
        i += 1
    raise ScriptError("unterminated string", start + 1)


def _tokenize(text: str) -> Iterator[_Token]:
    """The tokens of ``text``, lazily (so the leftmost error is reported), then an "end" token."""
    i = 0
    while i < len(text):
        char, column = text[i], i + 1
        if char in " \t":
            i += 1
        elif char in "\r\n":
            raise ScriptError(_ONE_LINE, column)
        elif char in "\"'":
            value, end = _string(text, i)
            yield _Token("string", text[i:end], value, column)
            i = end
        elif (match := _NUMBER.match(text, i)) is not None:
            end = match.end()
            trailing = _WORD.match(text, end).end()
            if trailing > end:
                raise ScriptError(f"malformed number {_show(text[i:trailing])}", column)
            yield _Token("number", text[i:end], _number(text, i, end), column)
            i = end
        elif (match := _NAME.match(text, i)) is not None:
            yield _Token("name", match.group(), None, column)
            i = match.end()
        elif char in _PUNCT:
            yield _Token("punct", char, None, column)
            i += 1
        else:
            raise ScriptError(f"unexpected character {_show(char)}", column)
    yield _Token("end", "", None, len(text) + 1)


# ---- parser ------------------------------------------------------------------------------

_TARGET = "expected 'component.member', e.g. servo.kp"


class _Parser:
    def __init__(self, tokens: Iterator[_Token]) -> None:
        self.tokens = tokens
        self.ahead: list[_Token] = []  # tokens read but not yet taken; the last may be "end"

    def peek(self, ahead: int = 0) -> _Token:
        while len(self.ahead) <= ahead:
            if self.ahead and self.ahead[-1].kind == "end":
                return self.ahead[-1]
            self.ahead.append(next(self.tokens))
        return self.ahead[ahead]

    def take(self) -> _Token:
        token = self.peek()
        if token.kind != "end":
            self.ahead.pop(0)
        return token

    def at(self, punct: str, ahead: int = 0) -> bool:
        token = self.peek(ahead)
        return token.kind == "punct" and token.text == punct

    def expect(self, kind: str, text: str | None, message: str) -> _Token:
        token = self.peek()
        if token.kind != kind or (text is not None and token.text != text):
            raise ScriptError(message, token.column)
        return self.take()

    def command(self) -> Command:
        first = self.peek()
        if first.kind == "end":
            raise ScriptError("empty command (type 'help' for the forms)", first.column)
        if first.kind == "name" and first.text == "components" and not self.at(".", 1):
            self.take()
            result: Command = Components()
        elif first.kind == "name" and first.text == "help" and not self.at(".", 1):
            self.take()
            if self.peek().kind == "name":
                result = Help(self.take().text)
            elif self.peek().kind == "end":
                result = Help(None)
            else:
                raise ScriptError("expected a component name after 'help'", self.peek().column)
        else:
            result = self.target_command()
        extra = self.peek()
        if extra.kind != "end":
            raise ScriptError(f"unexpected text after the command: {_show(extra.text)}", extra.column)
        return result

    def target_command(self) -> Command:
        component = self.expect("name", None, _TARGET).text
        self.expect("punct", ".", _TARGET)
        name = self.expect("name", None, _TARGET).text
        index = None
        if self.at("["):
            self.take()
            token = self.peek()
            if token.kind != "number" or not isinstance(token.value, int) or token.value < 0 \
                    or not token.text.isdigit():
                raise ScriptError("expected an element number (digits) after '['", token.column)
            index = self.take().value
            self.expect("punct", "]", "expected ']' after the element number")
        if self.at("="):
            self.take()
            return SetProperty(component, name, self.value("expected a value after '='"), index)
        if self.at("("):
            if index is not None:
                raise ScriptError("an operation cannot be indexed", self.peek().column)
            self.take()
            return CallOperation(component, name, self.arguments())
        return GetProperty(component, name, index)

    def arguments(self) -> tuple[Value, ...]:
        if self.at(")"):
            self.take()
            return ()
        args = [self.value("expected a value or ')'")]
        while not self.at(")"):
            self.expect("punct", ",", "expected ',' or ')'")
            args.append(self.value("expected a value after ','"))
        self.take()
        return tuple(args)

    def value(self, message: str) -> Value:
        token = self.peek()
        if token.kind in ("number", "string"):
            self.take()
            return token.value  # type: ignore[return-value]
        if token.kind == "name" and token.text in ("true", "false"):
            self.take()
            return token.text == "true"
        raise ScriptError(message, token.column)


def parse(text: str) -> Command:
    """The command in one line of ``text``; raises ScriptError (only) if it does not parse."""
    if len(text) > MAX_LENGTH:
        raise ScriptError("command too long", MAX_LENGTH + 1)
    return _Parser(_tokenize(text)).command()


# ---- display -----------------------------------------------------------------------------

_QUOTED = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t", "\r": "\\r"}


def format_value(value: object) -> str:
    """``value`` as the scripting language writes it: ``parse`` reads back ints, finite floats, bools and strings."""
    return _format(value, set())


def _format(value: object, open_lists: set[int]) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        try:
            return repr(int(value))
        except ValueError:  # too many digits to print
            return f"<integer of {int(value).bit_length()} bits>"
    if isinstance(value, float):
        return float.__repr__(value)
    if isinstance(value, str):
        return '"' + "".join(_QUOTED.get(c, c) for c in value) + '"'
    if isinstance(value, (tuple, list)):
        if id(value) in open_lists:  # a list that contains itself
            return "[...]"
        open_lists.add(id(value))
        try:
            return "[" + ", ".join(_format(item, open_lists) for item in value) + "]"
        finally:
            open_lists.discard(id(value))
    return repr(value)


# ---- what both processes of irl serve need: the server's own target, the parse as a reply, an operation's run
def parse_call(text: str):
    """The parsed command of a ``call`` request, or ProtocolError (``script_error``)."""
    try:
        return parse(text)
    except ScriptError as exc:
        raise ProtocolError("script_error", f"{exc} in {text[:80]!r}") from None


class ServerTarget:
    """The server itself (``server``): its configuration. Its operations run in the
    server (they queue work; they never touch the robot directly: runtime/server/
    scripting_service.py); the loop reads the values the server sent with the command
    (``front``)."""

    name = "server"
    PROPERTIES: dict = {}
    READ_ONLY = {"configuration": "the configuration in force", "configurations": "those of the file",
                 "override": "speed override (percent)"}
    OPERATIONS = ("reconfigure",)
    IMMEDIATE = True
    lifecycle = None

    def __init__(self, front: dict, reconfigure=None):
        self.configuration = front.get("configuration")
        self.configurations = list(front.get("configurations") or [])
        self.override = front.get("override", 100.0)
        self._reconfigure = reconfigure

    def reconfigure(self, name: str) -> str:
        """Queue a Robot Reconfiguration with the named configuration."""
        if not isinstance(name, str):
            raise TypeError("reconfigure() takes the configuration's name, a string")
        if self._reconfigure is None:
            raise ValueError("reconfigure() runs in the server, not in the loop")
        result = self._reconfigure(name)
        return f"reconfiguration to {result['requested']!r} queued as {result['program']}"


def check_operation(target, command: CallOperation) -> None:
    """Refuse (``script_error``) an operation the target does not declare."""
    if command.name not in target.OPERATIONS:
        raise ProtocolError("script_error", f"{command.component} has no operation {command.name!r} "
                                            f"(operations: {', '.join(target.OPERATIONS)})")


def run_operation(where: str, operation, args: tuple, plain=lambda value: value) -> dict:
    """Call a declared operation (``where``: ``component.name``; ``operation``: the
    target's bound method, :func:`check_operation` passed) and say what it returned
    (``plain``: the value as msgpack carries it); its errors as the reply's."""
    try:
        value = plain(operation(*args))
    except TypeError as exc:
        raise ProtocolError("script_error", f"{where}: {exc}") from None
    except (ValueError, KeyError, IndexError) as exc:
        raise ProtocolError("refused", f"{where}: {exc}") from None
    return {"output": f"{where}(...) -> {format_value(value)}" if value is not None else f"{where}: done",
            "value": value}
