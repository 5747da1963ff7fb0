"""Record types (docs/language.md, "Records"; RAPID's RECORD, KRL's STRUC): a type with named
fields, declared once at a program's or a module's level::

    record part_t
      name : string;
      height, width : real;
      seat : pose;
    endrecord;

One declaration: the words (contextual: the parser reads them as names, so a variable
called ``record`` keeps working), the checker's type of a record and its limits. The
checker, the code generator, the object code's record table (compiler.objcode), the VM's
values (compiler.values.Record) and the manual read it.

A record is a value, as an array is: assigning or passing one copies it; its fields are
read ``part.height`` and assigned ``part.height := 12.5``; ``part_t("A", 12.5, 20.0, p)``
makes one (its fields' values in declaration order).
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["END_WORD", "MAX_FIELDS", "RecordT", "WORD"]

#: The word that starts a record's declaration, and the one that ends it.
WORD, END_WORD = "record", "endrecord"
#: The most fields a record type may have (the object code's operand of GET_MEMBER and
#: SET_MEMBER is a field's index).
MAX_FIELDS = 255


@dataclass(frozen=True)
class RecordT:
    """A record type as the checker knows it: its name and its fields, ``(name, type)`` in
    declaration order (a field's type is a checker type: a name, an array, a record)."""

    name: str
    fields: tuple[tuple[str, object], ...]

    def __str__(self) -> str:
        return self.name

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _t in self.fields)

    def index(self, name: str) -> int:
        """The index of field ``name`` (-1: no such field)."""
        for i, (field, _t) in enumerate(self.fields):
            if field == name:
                return i
        return -1

    def type_of(self, name: str):
        """The type of field ``name`` (which the record has)."""
        return self.fields[self.index(name)][1]

    def layout(self) -> str:
        """The type with its fields, as the manual and a message write it:
        ``part_t(name: string; height: real)``."""
        return f"{self.name}({'; '.join(f'{n}: {t}' for n, t in self.fields)})"
