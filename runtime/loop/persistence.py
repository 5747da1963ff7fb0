"""The persistent variables' store (compiler.persistent; docs/runtime.md, "Persistent
variables"): ``persistent.json`` in the state directory, beside ``calibration.json``.

It holds, per program (by its name), each persistent variable's declared type and its value
as plain data (an array as ``["array", [items]]``, the other values as the object code's
constants are written). A value is taken back only for a variable of the same name and
declared type (the VM then checks its shape: an array's lengths, a joint's axes).

Real time: :meth:`PersistentStore.kept` and :meth:`PersistentStore.keep` (the VM's
``PERS_LOAD`` and ``PERS_STORE``, through the trajectory generator) never wait, never touch
a file and never convert: the store holds the values as the VM does (read and converted
when it is loaded, before the loop runs), a change is a copy of the value (an array's:
one C-level copy per level, at most compiler.persistent.MAX_ELEMENTS elements) put in
:attr:`latest`, and it wakes a writer thread, which converts and writes the whole store
atomically (a temporary file, fsync, rename: a kill -9 leaves the last store written,
never a torn one) as soon as it can, the changes of a busy program together. The
operator's changes (:meth:`set`, :meth:`reset`) and :meth:`load` are not real-time.
"""
from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

from compiler.persistent import FILE, FORMAT, MAX_FILE_BYTES
from compiler.values import Joint, Record, copy_value, from_plain, to_plain

__all__ = ["PersistentStore", "fitted", "plain_of", "shown_plain", "value_of"]


def plain_of(value):
    """A value of the language as the store writes it (an array: ``["array", [items]]``; a
    record: ``["record", type name, {field: item, ...}]``)."""
    if type(value) is list:
        return ["array", [plain_of(item) for item in value]]
    if type(value) is Record:
        return ["record", value.type_name, {name: plain_of(item) for name, item in zip(value.field_names, value)}]
    return to_plain(value)


def value_of(plain):
    """The inverse of :func:`plain_of`; ValueError on anything malformed."""
    if isinstance(plain, list) and len(plain) == 2 and plain[0] == "array" and isinstance(plain[1], list):
        return [value_of(item) for item in plain[1]]
    if isinstance(plain, list) and len(plain) == 3 and plain[0] == "record" and isinstance(plain[1], str) \
            and isinstance(plain[2], dict) and all(isinstance(name, str) for name in plain[2]):
        return Record(plain[1], tuple(plain[2]), [value_of(item) for item in plain[2].values()])
    return from_plain(plain)


def fitted(value, like):
    """``value`` as it goes into a variable that holds ``like`` (of the same type and shape:
    an array of the same lengths, a record of the same type and fields, a joint of the same
    axes; an integer where a real is becomes a real, at every level), or None when it does
    not fit there."""
    if type(like) is list:
        if type(value) is not list or len(value) != len(like):
            return None
        items = [fitted(v, w) for v, w in zip(value, like)]
        return None if any(item is None for item in items) else items
    if type(like) is Record:
        if type(value) is not Record or value.type_name != like.type_name or value.field_names != like.field_names:
            return None
        items = [fitted(v, w) for v, w in zip(value, like)]
        return None if any(item is None for item in items) else Record(like.type_name, like.field_names, items)
    if type(like) is float:
        return float(value) if type(value) in (float, int) else None
    if isinstance(like, Joint):
        fits = isinstance(value, Joint) and len(value.main) == len(like.main) and len(value.add) == len(like.add)
        return value if fits else None
    return value if type(value) is type(like) else None


def shown_plain(plain) -> str:
    """A kept value as a program would print it (or, malformed, as it is)."""
    from compiler.values import format_value

    try:
        value = value_of(plain)
    except (ValueError, TypeError, RecursionError):
        return repr(plain)[:200]
    if type(value) is list:
        return "[" + ", ".join(shown_plain(plain_of(item)) for item in value) + "]"
    return format_value(value)


class PersistentStore:
    """The store of one runtime (``directory``: its state directory; None: values are kept
    for the run only). ``values`` holds what was loaded or written: (program, name) ->
    (type, value); ``latest`` the changes since (the loop's). ``why`` says what
    :meth:`load` found; ``error`` the last write that failed."""

    def __init__(self, directory: str | Path | None):
        self.path = Path(directory) / FILE if directory else None
        self.values: dict[tuple[str, str], tuple[str, object]] = {}
        self.latest: dict[tuple[str, str], tuple[str, object]] = {}
        self.why = "no state directory: persistent variables are kept for the run only"
        self.error: str | None = None
        self._wake = threading.Event()
        self._writer: threading.Thread | None = None
        self._lock = threading.Lock()  # (the writer and the operator's changes: never the loop)

    # ---- not real-time ----
    def load(self) -> None:
        """Read the store (what is wrong with it is said in ``why``; a store that cannot be
        read counts as empty, and is not written over until a value changes; an entry that
        is no value of the language is left out)."""
        if self.path is None:
            return
        try:
            with open(self.path, "rb") as f:
                raw = f.read(MAX_FILE_BYTES + 1)
        except FileNotFoundError:
            self.why = f"no persistent values yet in {self.path.parent}"
            return
        except OSError as exc:
            self.why = f"cannot read {self.path}: {exc.strerror or exc}"
            return
        if len(raw) > MAX_FILE_BYTES:
            self.why = f"{self.path} is larger than {MAX_FILE_BYTES} bytes: not read"
            return
        try:
            data = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError):
            self.why = f"{self.path} is not a store of persistent values (not JSON): not read"
            return
        programs = data.get("programs") if isinstance(data, dict) and data.get("format") == FORMAT else None
        if not isinstance(programs, dict):
            self.why = f"{self.path} is not a store of persistent values of format {FORMAT}: not read"
            return
        values, bad = {}, 0
        for program, names in programs.items():
            for name, entry in (names.items() if isinstance(names, dict) else ()):
                try:
                    if not (isinstance(entry, list) and len(entry) == 2 and isinstance(entry[0], str)):
                        raise ValueError("not [type, value]")
                    values[(str(program), str(name))] = (entry[0], value_of(entry[1]))
                except (ValueError, TypeError, RecursionError):
                    bad += 1
        self.values = values
        self.why = f"{len(values)} persistent value{'s' if len(values) != 1 else ''} in {self.path}" + (
            f" ({bad} malformed, left out)" if bad else "")

    def start(self) -> None:
        """Start the writer thread (once, before the loop runs)."""
        if self.path is not None and self._writer is None:
            self._writer = threading.Thread(target=self._write_loop, name="irl-persistent-writer", daemon=True)
            self._writer.start()

    def flush(self, timeout: float = 10.0) -> bool:
        """Wait until every change is written (or ``timeout``); whether it is."""
        deadline = time.monotonic() + timeout
        while self._writer is not None and (self._wake.is_set() or self._pending()) and time.monotonic() < deadline:
            time.sleep(0.002)
        return not self._pending()

    def entries(self) -> dict[str, dict[str, list]]:
        """Every kept value as plain data: program -> name -> [type, plain] (a copy)."""
        merged: dict[str, dict[str, list]] = {}
        for (program, name), (type_, value) in (self.values | dict(self.latest)).items():
            merged.setdefault(program, {})[name] = [type_, plain_of(value)]
        return merged

    def set(self, program: str, name: str, type_: str, value) -> None:
        """The operator's value for ``program``'s ``name`` (checked by the caller), kept as a
        program's change is."""
        self.latest[(program, name)] = (type_, copy_value(value))
        self._wake.set()

    def reset(self, program: str, name: str | None = None) -> int:
        """Forget ``program``'s kept values (one, or all): its next run starts from the
        initial values. Returns how many were forgotten; written at once."""
        with self._lock:
            known = {key for key in self.values | dict(self.latest) if key[0] == program}
            gone = {key for key in known if name is None or key[1] == name}
            for key in gone:
                self.latest.pop(key, None)
            values = {key: entry for key, entry in self.values.items() if key not in gone}
            if gone and self.path is not None:
                self._write(values)
            self.values = values
        return len(gone)

    # ---- real-time ----
    def kept(self, program: str, name: str, type_: str):
        """The value kept of ``program``'s ``name`` declared ``type_`` (the VM's own copy), or None."""
        entry = self.latest.get((program, name)) or self.values.get((program, name))
        if entry is None or entry[0] != type_:
            return None
        return copy_value(entry[1])

    def keep(self, program: str, name: str, type_: str, value) -> None:
        """Keep ``value`` of ``program``'s ``name``: written soon by the writer."""
        self.latest[(program, name)] = (type_, copy_value(value))
        self._wake.set()

    # ---- the writer ----
    def _pending(self) -> bool:
        return any(self.values.get(key) is not entry for key, entry in dict(self.latest).items())

    def _write_loop(self) -> None:
        while True:  # never dies: a write that fails is said in ``error``
            self._wake.wait()
            self._wake.clear()  # (before taking the changes: one made meanwhile wakes it again)
            try:
                with self._lock:
                    values = self.values | dict(self.latest)  # (one C call each: atomic against the loop)
                    if any(self.values.get(key) is not entry for key, entry in values.items()):
                        self._write(values)
                        self.values = values
            except OSError as exc:
                self.error = f"cannot keep the persistent values in {self.path}: {exc.strerror or exc}"
            except Exception:  # noqa: BLE001
                self.error = f"the persistent values could not be kept in {self.path} (an internal error of its writer)"

    def _write(self, values: dict) -> None:
        programs: dict[str, dict[str, list]] = {}
        for (program, name), (type_, value) in values.items():
            programs.setdefault(program, {})[name] = [type_, plain_of(value)]
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump({"format": FORMAT, "programs": programs}, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.path)
