"""A page's own HTTP server on 127.0.0.1 (the pendant's: runtime.view.pendant), from the
standard library (``http.server.ThreadingHTTPServer``: a thread per connection, so a
request that waits on the robot holds up no other).

Everything is under a secret path, ``/KEY/`` (the URL ``irl view`` prints): a page or a
process that does not know it gets 404, whoever else may reach 127.0.0.1. Besides, a
request must name this server in ``Host`` (127.0.0.1 or localhost and the port: a web page
that rebinds its own name to 127.0.0.1 cannot talk to it), a ``POST`` must carry JSON
(``Content-Type: application/json``, which another site's page can send only after a CORS
preflight that this server never grants) from no other ``Origin``, and at most
:data:`MAX_BODY` bytes. Replies are JSON (the page itself apart), never cached. No input
gives a traceback: a route's :class:`RouteError` is the reply's ``error``, any other
failure an ``internal error`` reply with its type and text.
"""
from __future__ import annotations

import json
import socketserver
import sys
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qsl, urlsplit

#: The largest request body read (bytes); a larger one gets 413.
MAX_BODY = 64 * 1024
#: Ports tried from the one asked for (the next free one is taken).
PORT_TRIES = 100


class RouteError(Exception):
    """A request a route refuses: ``status`` (HTTP) and a message for the page."""

    def __init__(self, message: str, status: int = 400):
        super().__init__(message)
        self.message, self.status = message, status


class PageServer(ThreadingHTTPServer):
    """Serves ``page`` (HTML) at ``/KEY/``, and JSON routes under it: ``get[name](query)``
    and ``post[name](body)``, each returning a dict (the reply) or raising RouteError."""

    daemon_threads = True

    def __init__(self, host: str, port: int, key: str, page: bytes, get: dict, post: dict):
        self.key, self.page, self.get_routes, self.post_routes = key, page, get, post
        self.hosts: set[str] = set()
        last: OSError | None = None
        for candidate in range(port, min(port + PORT_TRIES, 65536)):
            try:
                super().__init__((host, candidate), _Handler)
            except OSError as exc:  # (taken: the next one)
                last = exc
                continue
            break
        else:
            raise last or OSError(f"no free port from {port}")
        bound = self.server_address[1]
        self.hosts = {f"{host}:{bound}", f"localhost:{bound}"}
        self.thread = threading.Thread(target=self.serve_forever, kwargs={"poll_interval": 0.2},
                                       name="view-pendant-http", daemon=True)

    def server_bind(self) -> None:
        # (not HTTPServer's: it asks the resolver for the host's full name, and a slow DNS
        # would stall the start)
        socketserver.TCPServer.server_bind(self)
        self.server_name, self.server_port = self.server_address[0], self.server_address[1]

    @property
    def port(self) -> int:
        return self.server_address[1]

    def start(self) -> None:
        self.thread.start()

    def close(self) -> None:
        self.shutdown()
        self.server_close()


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"  # (keep-alive: the page's requests reuse their connections)
    # (TCP_NODELAY: a reply's headers and body are two writes, and Nagle's algorithm held the
    # second back until the page's delayed acknowledgement of the first: 40 ms a request)
    disable_nagle_algorithm = True
    server_version = "irl-view"
    server: PageServer

    def log_message(self, format, *args) -> None:  # noqa: A002 (the base class's name)
        pass  # (no line per request on irl view's terminal)

    # ---- the methods -------------------------------------------------------------------------
    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        name, query = self._route()
        if name is None:
            return
        if name == "":
            self._send(200, self.server.page, "text/html; charset=utf-8")
            return
        route = self.server.get_routes.get(name)
        if route is None:
            self._error(404, "no such page")
            return
        self._answer(route, query)

    def do_POST(self) -> None:  # noqa: N802
        name, _query = self._route()
        if name is None:
            return
        route = self.server.post_routes.get(name)
        if route is None:
            self._error(404, "no such page")
            return
        origin = self.headers.get("Origin")
        if origin is not None and urlsplit(origin).netloc not in self.server.hosts:
            self._error(403, "requests from other pages are refused")
            return
        if (self.headers.get("Content-Type") or "").split(";")[0].strip().lower() != "application/json":
            self._error(415, "expected JSON (Content-Type: application/json)")
            return
        body = self._body()
        if body is not None:
            self._answer(route, body)

    def do_PUT(self) -> None:  # noqa: N802
        self._error(405, "only GET and POST")

    do_DELETE = do_PATCH = do_PUT  # noqa: N815

    # ---- the pieces --------------------------------------------------------------------------
    def _route(self) -> tuple[str | None, dict]:
        """The route's name under /KEY/ and the query (None: answered already)."""
        if (self.headers.get("Host") or "").lower() not in self.server.hosts:
            self._error(403, "this server answers only as 127.0.0.1 or localhost, its port")
            return None, {}
        parts = urlsplit(self.path)
        prefix = f"/{self.server.key}"
        if parts.path == prefix:  # (the URL without its slash: the page's relative requests need it)
            self._send(308, b"", "text/plain", {"Location": f"{prefix}/"})
            return None, {}
        if not parts.path.startswith(prefix + "/"):
            self._error(404, "no such page (the pendant's URL is the one irl view printed)")
            return None, {}
        return parts.path[len(prefix) + 1:], dict(parse_qsl(parts.query))

    def _body(self) -> dict | None:
        try:
            length = int(self.headers.get("Content-Length") or "0")
        except ValueError:
            length = -1
        if not 0 <= length <= MAX_BODY:
            self._error(413, f"a request body of at most {MAX_BODY} bytes")
            self.close_connection = True
            return None
        raw = self.rfile.read(length)
        try:
            body = json.loads(raw.decode("utf-8")) if raw else {}
        except (UnicodeDecodeError, ValueError):
            self._error(400, "the request is not JSON")
            return None
        if not isinstance(body, dict):
            self._error(400, "the request is not a JSON object")
            return None
        return body

    def _answer(self, route, args: dict) -> None:
        try:
            data = _encode(route(args))
        except RouteError as exc:
            self._error(exc.status, exc.message)
            return
        except Exception as exc:  # (a bug of ours: said, never a traceback; the server goes on)
            print(f"irl view: the pendant: internal error: {type(exc).__name__}: {exc}", file=sys.stderr)
            self._error(500, f"internal error: {type(exc).__name__}: {exc}")
            return
        self._send(200, data, "application/json")

    def _error(self, status: int, message: str) -> None:
        self._json(status, {"ok": False, "error": message})

    def _json(self, status: int, value: dict) -> None:
        self._send(status, _encode(value), "application/json")

    def _send(self, status: int, data: bytes, kind: str, headers: dict | None = None) -> None:
        try:
            self.send_response(status)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(data)))
            self.send_header("Cache-Control", "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            self.send_header("Referrer-Policy", "no-referrer")  # (the key is in the URL)
            for name, value in (headers or {}).items():
                self.send_header(name, value)
            self.end_headers()
            self.wfile.write(data)
        except OSError:  # (the page went away)
            self.close_connection = True


def _encode(value: dict) -> bytes:
    """JSON as a browser parses it (no NaN: ValueError)."""
    return json.dumps(value, allow_nan=False, default=str).encode()
