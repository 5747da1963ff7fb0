"""Interrupts, declared once: the options of ``interrupt NAME when COND OPTIONS;``, the
priorities, what a condition may be made of (in the source and in the object code), and
what a handler may not do.

Read by the checker (``compiler.check``: options, condition, handler), the code generator
(``compiler.codegen``), the object code's decoder and verifier (``compiler.objcode``:
the interrupt table and the condition's code) and the VM (``runtime.loop.vm``). Imports
nothing from Lark, NumPy or ZeroMQ.
"""
from __future__ import annotations

__all__ = ["ACTIONS", "CONDITION_OPS", "DEFAULT_PRIORITY", "DEFAULT_THEN", "MAX_CONDITION_CODE", "PRIORITY",
           "THEN", "CONDITION_TEXT"]

#: What happens to the motion when an interrupt fires (exactly one must be given).
ACTIONS = {
    "stop": "the robot stops on its path at once (a controlled stop, as for a pause), while the handler runs",
    "continue": "the robot goes on with the moves already handed over while the handler runs",
}

#: What happens after the handler (``then WORD``; the first is the default).
THEN = {
    "resume": "the program goes on where it was; after stop, the interrupted move continues from where the robot "
              "stopped, once it is at rest",
    "halt": "the program ends when the handler does (the robot stops on its path; the moves not yet made are "
            "dropped)",
}
DEFAULT_THEN = "resume"

#: ``priority N``: the allowed range (1 is the highest) and the default.
PRIORITY = (1, 100)
DEFAULT_PRIORITY = 50

#: The instructions a condition's code may hold (straight-line, so it takes a bounded time
#: every 5 ms), and its longest length in instructions.
CONDITION_OPS = ("CONST", "LOAD_GLOBAL", "IN_GET", "NOT", "AND", "OR", "RET_VALUE")
MAX_CONDITION_CODE = 256

#: What a condition may use, as messages say it.
CONDITION_TEXT = "in[N] (N a constant), global bool variables and constants, true, false, not, and, or"
