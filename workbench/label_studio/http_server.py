"""The ML backend's HTTP side: the protocol's few JSON endpoints on the standard library's threading server.

Loopback by default, as the page. Beyond it Label Studio's basic auth is required (it sends what its ML backend
settings or ``BASIC_AUTH_USER``/``BASIC_AUTH_PASS`` hold) and checked in constant time on every request. Label
Studio calls from its server, never from a browser, so a request that carries an ``Origin`` (a web page in the
user's browser posting to the port: a label made by a foreign site) is refused, and on loopback so is one whose
``Host`` is not this machine's (a rebound DNS name). A body past :data:`MAX_BODY` or one that is not a JSON object is
refused in one line before anything reads it.
"""

from __future__ import annotations

import base64
import hmac
import json
import threading
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from ..ui.gate import is_loopback
from .backend import Backend

MAX_BODY = 32 << 20  # bytes: a /predict of 100 tasks with their data and the config is well under a megabyte


def _handler(backend: Backend, auth: tuple[str, str] | None, *, loopback: bool) -> type[BaseHTTPRequestHandler]:
    expected = None if auth is None else base64.b64encode(f"{auth[0]}:{auth[1]}".encode()).decode()

    class Handler(BaseHTTPRequestHandler):
        server_version = "TerrainWorkbench"
        protocol_version = "HTTP/1.1"

        def log_message(self, format: str, *args: object) -> None:
            pass  # one line per refused task or region is said by the backend; requests are not logged

        def _send(self, status: int, body: dict) -> None:
            data = json.dumps(body).encode()
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            if status == 401:
                self.send_header("WWW-Authenticate", 'Basic realm="terrain workbench"')
            self.end_headers()
            self.wfile.write(data)

        def _allowed(self) -> bool:
            if self.headers.get("Origin") is not None:
                self._send(403, {"error": "a request from a web page (it names an Origin): only Label Studio's server"})
                return False
            host = (self.headers.get("Host") or "").rsplit(":", 1)[0].strip("[]")
            if loopback and not is_loopback(host) and host != "localhost":
                self._send(403, {"error": f"Host {host[:80]!r} is not this machine's: a loopback backend"})
                return False
            if expected is None:
                return True
            given = self.headers.get("Authorization", "")
            ok = given.startswith("Basic ") and hmac.compare_digest(given[6:].strip().encode(), expected.encode())
            if not ok:
                self._send(401, {"error": "basic auth required: the user and password the backend was started with"})
            return ok

        def do_GET(self) -> None:
            if not self._allowed():
                return
            if self.path.split("?")[0] in ("/", "/health"):
                self._send(*backend.health())
            elif self.path.split("?")[0] == "/metrics":
                self._send(200, {})
            else:
                self._send(404, {"error": f"no endpoint {self.path[:80]!r}"})

        def do_POST(self) -> None:
            if not self._allowed():
                return
            routes: dict[str, Callable[[dict], tuple[int, dict]]] = {
                "/setup": backend.setup,
                "/predict": backend.predict,
                "/webhook": backend.webhook,
                "/train": lambda body: backend.webhook({**body, "action": "START_TRAINING"}),
            }
            route = routes.get(self.path.split("?")[0])
            if route is None:
                self._send(404, {"error": f"no endpoint {self.path[:80]!r}"})
                return
            try:
                length = int(self.headers.get("Content-Length", "0"))
            except ValueError:
                length = -1
            if not 0 <= length <= MAX_BODY:
                self.close_connection = True
                self._send(413, {"error": f"a request body of {length} bytes: at most {MAX_BODY >> 20} MB"})
                return
            try:
                body = json.loads(self.rfile.read(length) or b"{}")
            except (ValueError, UnicodeDecodeError) as exc:
                self._send(400, {"error": f"the body is not JSON ({str(exc)[:120]})"})
                return
            if not isinstance(body, dict):
                self._send(400, {"error": "the body is not a JSON object"})
                return
            try:
                self._send(*route(body))
            except Exception as exc:  # one request's fault: it gets the line, the server goes on
                backend.say(f"label-studio: {self.path}: {type(exc).__name__}: {exc}")
                self._send(500, {"error": f"{type(exc).__name__}: {str(exc)[:300]}"})

    return Handler


class BackendServer:
    """The backend on ``host:port`` in a thread of its own (the caller's thread serves the torch work)."""

    def __init__(self, backend: Backend, *, host: str, port: int, auth: tuple[str, str] | None) -> None:
        self.httpd = ThreadingHTTPServer((host, port), _handler(backend, auth, loopback=is_loopback(host)))
        self.httpd.daemon_threads = True
        self.url = f"http://{host}:{self.httpd.server_address[1]}"
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="label-studio-backend", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
