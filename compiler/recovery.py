"""Error recovery (docs/language.md, "Error handlers"): the errors a program can handle,
and the words of an error handler, as RAPID's ERROR handlers (ERRNO, RETRY, TRYNEXT,
RAISE) do it.

A ``seq ... endseq`` body (of the program, a procedure, a function or an interrupt) may end
with a handler, ``when error do STATEMENTS``: an error that a statement of the body raises,
directly or in a routine it calls that does not handle it, runs the handler once the robot
has ended every move before the error (at rest). There ``retry;`` runs the statement that
raised it again, ``trynext;`` goes on after it, ``raise;`` passes the error on to the caller,
and ``return`` or the handler's end leaves the routine (the program's: ends it).
``raise N;`` or ``raise N, "message";`` raises a program's own error, anywhere.

One declaration each: :data:`ERRORS` (the errors by name and number, what raises them and
the RAPID errors they stand for) and :data:`WORDS` (the handler's statements). The
checker, the code generator, the VM and the manual read them. The words are contextual:
they are statements only as a whole statement (``retry;``), so a program's variable called
``retry`` or ``error`` keeps working.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ERRORS", "BY_NAME", "BY_NUMBER", "USER_ERRORS", "WORDS", "HANDLER_WORD", "ErrorKind", "Word",
           "error_kind"]

#: The word after ``when`` that starts a handler (``when error do``).
HANDLER_WORD = "error"


@dataclass(frozen=True)
class ErrorKind:
    """An error a handler can take: its name (``error_name()``), its number
    (``error_number()``), what raises it, and the RAPID errors it stands for."""

    name: str
    number: int
    raised_by: str
    rapid: str


ERRORS: tuple[ErrorKind, ...] = (
    ErrorKind("move", 1, "a move the runtime refuses: a target out of reach or past a limit, a path that cannot be "
                         "planned, a clause out of range; the moves after it are dropped, the robot ends the moves "
                         "before it", "ERR_ROBLIMIT, ERR_OUTSIDE_REACH, ERR_PATH_STOP"),
    ErrorKind("timeout", 2, "a 'wait for ... timeout' whose time-out passes (with no handler to take it, the program "
                            "goes on, as timed_out() tells)", "ERR_WAIT_MAXTIME"),
    ErrorKind("arithmetic", 3, "a division by zero, an integer overflow, a result that is not a finite number",
              "ERR_DIVZERO, ERR_OVERFLOW"),
    ErrorKind("value", 4, "a value an operation cannot take: an array index out of range, a string that is no "
                          "number, a zero quaternion, a pose the arm cannot compute, too deep a recursion",
              "ERR_ILLDIM, ERR_STRTOOLONG, ERR_ARGVALERR"),
    ErrorKind("io", 5, "a digital input, output, pulse or group, or an analog input or output, of a number the "
                       "robot does not have (or its PLC does not map); an analog reading outside its input's range "
                       "(the sensor's fault)",
              "ERR_NORUNUNIT, ERR_SIG_NOT_VALID"),
    ErrorKind("search", 6, "a search move (move lin ... search := N) whose input did not become true before the "
                           "move reached its target, or was true already when it began", "ERR_WHLSEARCH, "
                           "ERR_SIGSUPSEARCH"),
    ErrorKind("user", 0, "raise N: the program's own error N (error_number() is N)", "RAISE with BookErrNo"),
)
BY_NAME = {kind.name: kind for kind in ERRORS}
BY_NUMBER = {kind.number: kind for kind in ERRORS if kind.number}

#: The numbers a program's own errors may have (``raise N``).
USER_ERRORS = (100, 9999)


def error_kind(number: int) -> ErrorKind:
    """The kind of error ``number`` (a program's own for a number of :data:`USER_ERRORS`)."""
    return BY_NUMBER.get(number, BY_NAME["user"])


@dataclass(frozen=True)
class Word:
    """A statement of an error handler: its word, the values it takes (``raise``: a number
    and a message, both optional), whether it belongs inside a handler only, the
    instruction it compiles to, and what it does."""

    name: str
    handler_only: bool
    instruction: str
    doc: str
    rapid: str


WORDS: dict[str, Word] = {w.name: w for w in (
    Word("retry", True, "RETRY", "run the statement that raised the error again (its expressions evaluated anew)",
         "RETRY"),
    Word("trynext", True, "TRYNEXT", "go on with the statement after the one that raised the error", "TRYNEXT"),
    Word("raise", False, "RAISE",
         "without a value, in a handler: pass the error on to the caller's handler (none: the program ends with "
         "it); 'raise N;' or 'raise N, \"message\";': raise the program's own error N "
         f"({USER_ERRORS[0]}..{USER_ERRORS[1]})", "RAISE"),
)}


def markdown() -> str:
    """The manual's tables (docs/language.md, "Error handlers"): the errors, and the words."""
    lines = ["| error_name() | error_number() | raised by | RAPID |", "|---|---|---|---|"]
    for kind in ERRORS:
        number = f"{USER_ERRORS[0]}..{USER_ERRORS[1]}" if kind.name == "user" else str(kind.number)
        lines.append(f"| `\"{kind.name}\"` | {number} | {kind.raised_by} | {kind.rapid} |")
    lines += ["", "| statement | where | what it does | RAPID |", "|---|---|---|---|"]
    for word in WORDS.values():
        spelled = "`raise;` / `raise N;` / `raise N, \"message\";`" if word.name == "raise" else f"`{word.name};`"
        where = "in a handler" if word.handler_only else "`raise;` in a handler, `raise N` anywhere"
        lines.append(f"| {spelled} | {where} | {word.doc} | `{word.rapid}` |")
    return "\n".join(lines) + "\n"
