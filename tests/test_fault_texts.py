"""Issue 26: no fault text is a Python exception's message ("tuple index out of range"
means nothing at a robot). This searches the runtime's and compiler's source for every
handler that catches any exception (``except Exception``, ``BaseException``, a bare
``except``) and uses the exception it caught: the exception may only go to a function
that says it in the robot's terms (tests/test_vm.py and tests/test_fieldbus.py check
those with exceptions of every kind), or to one of the few places listed here, none of
which makes a fault text. Narrower handlers (``except OSError``, ``except EvalError``)
catch the project's own messages or the system's (``strerror``)."""
from __future__ import annotations

import ast
from pathlib import Path

from conftest import ROOT

#: Functions that turn any exception into a text in the robot's terms.
TRANSLATORS = {"_describe", "_why", "_failed"}  # (_failed: the VM's dispatch loops' end, through _describe)

#: (file, function) -> why the exception's text may be used there (never a fault text).
ALLOWED = {
    ("runtime/cli/main.py", "main"): "the command line's last guard: a bug report on stderr, exit 70",
    ("runtime/server/server.py", "_handle"): "a server bug: the client's 'internal' error reply (and the log)",
    ("runtime/view/pagehttp.py", "_answer"): "a pendant bug: the page's 'internal error' reply and a line on irl "
                                             "view's stderr",
    ("runtime/loop/robotloop.py", "command"): "a loop bug: the server's 'internal' error reply",
    ("runtime/loop/system.py", "_poll"): "the print thread keeps the exception object to raise it again in the caller",
    ("runtime/loop/robotloop.py", "child"): "the loop process could not start: irl serve says so and exits 2",
    ("runtime/wire/protocol.py", "_decode"): "a request that is not msgpack: the kind of decoding error in the reply",
    ("runtime/wire/protocol.py", "decode_reply"): "a reply that is not msgpack: the kind of decoding error",
    ("compiler/objcode.py", "decode"): "object code that is not msgpack: the kind of decoding error",
}


def _broad(handler: ast.ExceptHandler) -> bool:
    kinds = handler.type
    if kinds is None:
        return True
    names = kinds.elts if isinstance(kinds, ast.Tuple) else [kinds]
    return any(isinstance(n, ast.Name) and n.id in ("Exception", "BaseException") for n in names)


def _uses(handler: ast.ExceptHandler) -> list[int]:
    """Lines where the caught exception is used other than by a translator."""
    name = handler.name
    translated = set()
    for node in ast.walk(handler):
        if isinstance(node, ast.Call) and isinstance(node.func, (ast.Name, ast.Attribute)):
            called = node.func.id if isinstance(node.func, ast.Name) else node.func.attr
            if called in TRANSLATORS:
                translated.update(id(a) for a in node.args)
    return [node.lineno for node in ast.walk(handler)
            if isinstance(node, ast.Name) and node.id == name and isinstance(node.ctx, ast.Load)
            and id(node) not in translated]


def _handlers(path: Path):
    """(the enclosing function's name, handler) of every broad handler that names its exception."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    functions, handlers = [], []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            functions.append((node.lineno, node.end_lineno, node.name))
        elif isinstance(node, ast.ExceptHandler) and node.name and _broad(node):
            handlers.append(node)
    for handler in handlers:  # the innermost function around it
        around = [f for f in functions if f[0] <= handler.lineno <= f[1]]
        yield (max(around)[2] if around else ""), handler


def test_no_handler_of_any_exception_makes_its_message_a_text_outside_the_listed_places():
    found, allowed_seen = [], set()
    for path in sorted([*ROOT.glob("runtime/**/*.py"), *ROOT.glob("compiler/**/*.py")]):
        rel = path.relative_to(ROOT).as_posix()
        for function, handler in _handlers(path):
            lines = _uses(handler)
            if not lines:
                continue
            if (rel, function) in ALLOWED:
                allowed_seen.add((rel, function))
                continue
            found.append(f"{rel}:{lines[0]} in {function}()")
    assert not found, "an exception's own text may become a fault text here:\n" + "\n".join(found)
    assert allowed_seen == set(ALLOWED), f"listed but no longer there: {set(ALLOWED) - allowed_seen}"


def test_the_search_finds_a_handler_that_puts_the_message_in_a_fault():
    """The search is not blind: the fault that issue 26 found, written the old way."""
    source = ("def op_in_get(self):\n    try:\n        x = self.read()\n    except Exception as exc:\n"
              "        self.fault = f'interrupt curtain: {exc}'\n")
    (function, handler), = [(f.name, h) for f in ast.walk(ast.parse(source)) if isinstance(f, ast.FunctionDef)
                            for h in ast.walk(f) if isinstance(h, ast.ExceptHandler)]
    assert _broad(handler) and _uses(handler) == [5]
    translated = source.replace("f'interrupt curtain: {exc}'", "_describe(exc, 3)")
    handler = next(h for h in ast.walk(ast.parse(translated)) if isinstance(h, ast.ExceptHandler))
    assert _uses(handler) == []
