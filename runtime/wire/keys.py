"""CURVE authentication for ``irl serve`` and its clients (ZeroMQ's CurveZMQ, through
pyzmq's own certificate files; the server's ZAP handler, runtime.server.connections, accepts
the authorized keys).

A key directory, as ``irl keys DIR`` makes it::

    DIR/server.key          the server's public key      (clients need it)         0644
    DIR/server.key_secret   the server's key pair        (only the server)         0600
    DIR/client.key_secret   a client's key pair          (the client: --keys DIR)  0600
    DIR/client.key          that client's public key                               0644
    DIR/authorized/*.key    the public keys of the clients the server accepts      0644

DIR and DIR/authorized are made 0700 when ``irl keys`` creates them. A key directory (or
its ``authorized/``) that others may write to, and a secret key file that others may read,
are refused wherever they are used (``irl keys``, ``irl serve --keys``, a client's
``--keys``), with the ``chmod`` that fixes them.

With ``--keys DIR`` the server encrypts both sockets and accepts only the clients whose
public key is in ``DIR/authorized``; a client without one cannot connect, so it cannot
submit, control or watch. ``irl keys DIR --name NAME`` adds another client key pair
(``NAME.key_secret``) and authorizes it; give a client its own directory holding its
``client.key_secret`` (renamed) and the server's ``server.key``.
"""
from __future__ import annotations

import datetime
import os
import shutil
from pathlib import Path


class KeyError_(Exception):
    """A missing or unreadable key file (the message names it)."""


#: File modes: a secret key is the owner's alone; a directory ``make_keys`` creates too.
SECRET_MODE, PUBLIC_MODE, DIRECTORY_MODE = 0o600, 0o644, 0o700


def make_keys(directory: str | Path, name: str | None = None) -> list[Path]:
    """Write key pairs into ``directory``; returns the files written.

    Secret key files are created with mode 0600 (by ``os.open``: never readable by
    others, not even for a moment); the directory and its ``authorized/`` are created
    0700 when they do not exist yet (an existing directory keeps its mode)."""
    import zmq

    d = Path(directory)
    try:
        names = ["server", "client"] if name is None else [name]
        for n in names:
            if not n.isidentifier():
                raise KeyError_(f"key name {n!r}: use letters, digits and '_' only")
        if not d.is_dir():
            d.parent.mkdir(parents=True, exist_ok=True)
            d.mkdir(mode=DIRECTORY_MODE, exist_ok=True)
        _check_directory(d)
        (d / "authorized").mkdir(mode=DIRECTORY_MODE, exist_ok=True)
        _check_directory(d / "authorized")
        for n in names:
            if (d / f"{n}.key_secret").exists():
                raise KeyError_(f"{d / (n + '.key_secret')} exists already: refusing to overwrite a key")
        made = []
        for n in names:
            public, secret = zmq.curve_keypair()
            secret_path, public_path = d / f"{n}.key_secret", d / f"{n}.key"
            _write_key_file(secret_path, _certificate(public, secret), SECRET_MODE)
            _write_key_file(public_path, _certificate(public, None), PUBLIC_MODE)
            made += [public_path, secret_path]
            if n != "server":
                shutil.copy(public_path, d / "authorized" / f"{n}.key")
                made.append(d / "authorized" / f"{n}.key")
        return made
    except OSError as exc:
        raise KeyError_(f"cannot write keys in {d}: {exc.strerror or exc}") from None


def _certificate(public: bytes, secret: bytes | None) -> str:
    """A key file in ZeroMQ's certificate format (what ``zmq.auth.load_certificate`` reads)."""
    now = datetime.datetime.now().isoformat(sep=" ", timespec="seconds")
    if secret is None:
        banner = "#   ZeroMQ CURVE Public Certificate (made by irl keys)\n#   Give it to the other side.\n"
    else:
        banner = ("#   ZeroMQ CURVE **Secret** Certificate (made by irl keys)\n"
                  "#   DO NOT PROVIDE THIS FILE TO OTHER USERS nor change its permissions.\n")
    text = f"#   Generated on {now}\n{banner}\nmetadata\ncurve\n    public-key = \"{public.decode('ascii')}\"\n"
    if secret is not None:
        text += f"    secret-key = \"{secret.decode('ascii')}\"\n"
    return text


def _write_key_file(path: Path, text: str, mode: int) -> None:
    """Write ``text`` to ``path``, created with ``mode`` from the start (the umask can only
    take bits away). A secret key file must not exist yet (O_EXCL: never overwritten,
    never opened through a link someone else put there)."""
    flags = os.O_WRONLY | os.O_CREAT | (os.O_EXCL if mode == SECRET_MODE else os.O_TRUNC)
    fd = os.open(path, flags, mode)
    try:
        with os.fdopen(fd, "w", encoding="ascii") as f:
            fd = -1
            f.write(text)
    except BaseException:
        if fd >= 0:
            os.close(fd)
        path.unlink(missing_ok=True)
        raise


def _mode(path: Path) -> int:
    return path.stat().st_mode & 0o777


def _check_directory(d: Path) -> None:
    """A key directory (or its ``authorized/``) that others may write to is refused: they
    could replace a key, or authorize a client of their own."""
    if os.name == "posix" and d.is_dir() and _mode(d) & 0o022:
        raise KeyError_(f"{d}: writable by others (mode {_mode(d):04o}): anyone could replace or add a key; "
                        f"'chmod go-w {d}' (irl keys makes it 0700)")


def _load(path: Path, secret: bool) -> tuple[bytes, bytes | None]:
    import zmq.auth

    if not path.is_file():
        raise KeyError_(f"{path}: no such key file (make keys with 'irl keys {path.parent}')")
    _check_directory(path.parent)
    if secret and os.name == "posix" and _mode(path) & 0o077:
        raise KeyError_(f"{path}: a secret key readable by others (mode {_mode(path):04o}): 'chmod 600 {path}' "
                        "(and make new keys if others may have read it)")
    try:
        public, private = zmq.auth.load_certificate(path)
    except (OSError, ValueError) as exc:
        raise KeyError_(f"{path}: not a key file ({exc})") from None
    if secret and private is None:
        raise KeyError_(f"{path}: holds no secret key")
    return public, private


def check_server_keys(directory: str | Path) -> tuple[bytes, bytes]:
    """The server's key pair from ``directory``, once its files and ``authorized/`` pass
    every check (KeyError_ naming what does not)."""
    d = Path(directory)
    public, secret = _load(d / "server.key_secret", True)
    if not (d / "authorized").is_dir():
        raise KeyError_(f"{d / 'authorized'}: missing (the public keys of the clients to accept go there)")
    _check_directory(d / "authorized")
    return public, secret


def server_security(directory: str | Path, sockets) -> frozenset[bytes]:
    """Make ``sockets`` CURVE servers with the server's key pair in ``directory``; returns
    the public keys (z85) of ``directory/authorized``, the clients to accept (the
    server's ZAP handler, runtime.server.connections, checks each connection against them)."""
    import zmq.auth

    d = Path(directory)
    public, secret = check_server_keys(d)
    try:
        authorized = frozenset(zmq.auth.load_certificates(d / "authorized"))
    except (OSError, ValueError) as exc:
        raise KeyError_(f"{d / 'authorized'}: cannot read its public keys ({exc})") from None
    for sock in sockets:
        sock.curve_secretkey = secret
        sock.curve_publickey = public
        sock.curve_server = True
    return authorized


def client_security(sock, directory: str | Path) -> None:
    """Make ``sock`` a CURVE client with the key pair and server key in ``directory``."""
    d = Path(directory)
    public, secret = _load(d / "client.key_secret", True)
    server_public, _ = _load(d / "server.key", False)
    sock.curve_secretkey = secret
    sock.curve_publickey = public
    sock.curve_serverkey = server_public
