"""Persistent variables (docs/language.md, "Persistent variables"; RAPID's PERS, KRL's data
lists): a ``var persistent`` section of global variables whose values the runtime keeps
across program runs and restarts, beside the calibration.

One declaration: the section's word (contextual: only right after ``var``, so a variable
called ``persistent`` keeps working), the store's file and its bounds. The checker, the code generator, the VM's host
(runtime.loop.persistence) and the manual read it.
"""
from __future__ import annotations

__all__ = ["FILE", "FORMAT", "MAX_ELEMENTS", "MAX_FILE_BYTES", "SECTION"]

#: The word after ``var`` that makes its section's variables persistent.
SECTION = "persistent"
#: The store, in the runtime's state directory (beside calibration.json).
FILE = "persistent.json"
#: Its format (a file of another is not read).
FORMAT = 1
#: The largest store read or written (its values: at most this much JSON).
MAX_FILE_BYTES = 16 * 1024 * 1024
#: The most elements a persistent variable may hold (an array, all levels together): a
#: change is copied in the control cycle, and the store is written while the loop runs.
MAX_ELEMENTS = 10_000
