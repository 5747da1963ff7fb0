"""CURVE authentication for ``irl serve`` and its clients (ZeroMQ's CurveZMQ, through
pyzmq's own certificate files and authenticator).

A key directory, as ``irl keys DIR`` makes it::

    DIR/server.key          the server's public key      (clients need it)
    DIR/server.key_secret   the server's key pair        (only the server)
    DIR/client.key_secret   a client's key pair          (the client: --keys DIR)
    DIR/client.key          that client's public key
    DIR/authorized/*.key    the public keys of the clients the server accepts

With ``--keys DIR`` the server encrypts both sockets and accepts only the clients whose
public key is in ``DIR/authorized``; a client without one cannot connect, so it cannot
submit, control or watch. ``irl keys DIR --name NAME`` adds another client key pair
(``NAME.key_secret``) and authorizes it; give a client its own directory holding its
``client.key_secret`` (renamed) and the server's ``server.key``.
"""
from __future__ import annotations

import shutil
from pathlib import Path


class KeyError_(Exception):
    """A missing or unreadable key file (the message names it)."""


def make_keys(directory: str | Path, name: str | None = None) -> list[Path]:
    """Write key pairs into ``directory``; returns the files written."""
    import zmq.auth

    d = Path(directory)
    try:
        (d / "authorized").mkdir(parents=True, exist_ok=True)
        made = []
        names = ["server", "client"] if name is None else [name]
        for n in names:
            if not n.isidentifier():
                raise KeyError_(f"key name {n!r}: use letters, digits and '_' only")
            if (d / f"{n}.key_secret").exists():
                raise KeyError_(f"{d / (n + '.key_secret')} exists already: refusing to overwrite a key")
            public, secret = zmq.auth.create_certificates(d, n)
            made += [Path(public), Path(secret)]
            if n != "server":
                shutil.copy(public, d / "authorized" / f"{n}.key")
                made.append(d / "authorized" / f"{n}.key")
        return made
    except OSError as exc:
        raise KeyError_(f"cannot write keys in {d}: {exc.strerror or exc}") from None


def _load(path: Path, secret: bool) -> tuple[bytes, bytes | None]:
    import zmq.auth

    if not path.is_file():
        raise KeyError_(f"{path}: no such key file (make keys with 'irl keys {path.parent}')")
    try:
        public, private = zmq.auth.load_certificate(path)
    except (OSError, ValueError) as exc:
        raise KeyError_(f"{path}: not a key file ({exc})") from None
    if secret and private is None:
        raise KeyError_(f"{path}: holds no secret key")
    return public, private


def check_server_keys(directory: str | Path) -> None:
    d = Path(directory)
    _load(d / "server.key_secret", True)
    if not (d / "authorized").is_dir():
        raise KeyError_(f"{d / 'authorized'}: missing (the public keys of the clients to accept go there)")


def server_security(ctx, directory: str | Path, sockets):
    """Start the authenticator and make ``sockets`` CURVE servers; returns the
    authenticator (stop it when closing)."""
    from zmq.auth.thread import ThreadAuthenticator

    d = Path(directory)
    public, secret = _load(d / "server.key_secret", True)
    auth = ThreadAuthenticator(ctx)
    auth.start()
    auth.configure_curve(domain="*", location=str(d / "authorized"))
    for sock in sockets:
        sock.curve_secretkey = secret
        sock.curve_publickey = public
        sock.curve_server = True
    return auth


def client_security(sock, directory: str | Path) -> None:
    """Make ``sock`` a CURVE client with the key pair and server key in ``directory``."""
    d = Path(directory)
    public, secret = _load(d / "client.key_secret", True)
    server_public, _ = _load(d / "server.key", False)
    sock.curve_secretkey = secret
    sock.curve_publickey = public
    sock.curve_serverkey = server_public
