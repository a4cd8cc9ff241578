"""The server's front door: only the page this server serves may use it.

viser 1.1 accepts any websocket and serves any page that asks, and browsers let every web page open a websocket to
``127.0.0.1:8080``: a page on the web could drive the workbench of a person labelling in another tab (measured: it
downloaded every label). viser gives no hook for a check, so the gate stands in front of it: viser serves on a
private Unix socket that only the gate can use (``private_viser``: no TCP port, a secret on every request), and the
gate listens on the address a person opens, answers a request only when

- its ``Host`` names the address served (on loopback: ``127.0.0.1``, ``localhost`` or ``[::1]`` with the port), which
  turns away DNS rebinding;
- its ``Origin``, when a browser sends one, is that same address, which turns away other sites' pages;
- it carries the token, when the server has one (always beyond loopback, as Jupyter does): ``?token=`` in the URL
  the server prints, then a cookie the gate sets on that first visit;

and passes it on to viser: plain HTTP requests are fetched from viser and returned, websockets are relayed message
by message. Anything else gets 403 and one line saying why.
"""

from __future__ import annotations

import asyncio
import contextlib
import http
import http.client
import logging
import secrets
import socket
import threading
import time
from http.cookies import SimpleCookie
from urllib.parse import parse_qs, urlsplit

from websockets.asyncio.client import unix_connect
from websockets.asyncio.server import ServerConnection, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from sessions import WorkbenchError

from .private_viser import SECRET_HEADER, InnerAddress

LOOPBACK = ("127.0.0.1", "localhost", "::1")
MIN_TOKEN_CHARS = 16  # a token anyone could guess or type by mistake is no token: an empty one opened the server
MAKE_TOKEN = 'python -c "import secrets; print(secrets.token_urlsafe(24))"'
MAX_MESSAGE = 50 << 20  # viser's own limit for one websocket message
# what a browser must not do with the page: frame it into another site, or guess types
_PAGE_HEADERS = {"Content-Security-Policy": "frame-ancestors 'none'", "X-Content-Type-Options": "nosniff"}


class _NoHandshakeNoise(logging.Filter):
    """A connection that opens and closes without a request (a port check, a scanner) is no error of ours."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "opening handshake failed" not in record.getMessage()


_LOG = logging.getLogger("workbench.gate")
_LOG.addFilter(_NoHandshakeNoise())
REFUSAL_LINE_EVERY_S = 10.0  # one line on the serve terminal per this many seconds of refused messages, at most


def viser_message_error(message: str | bytes) -> str | None:
    """Why a message from a browser is not one viser can read (``None``: it is), decoded as viser decodes it.

    viser printed a ``msgspec.DecodeError`` traceback on the serve terminal for every garbage message, and stopped
    reading that page's messages: the gate drops such a message instead, before viser sees it.
    """
    from viser import _messages

    if not isinstance(message, bytes):
        return "a text message (viser reads binary ones)"
    try:
        _messages.Message.deserialize(message)
    except Exception as exc:  # whatever viser's decoding raises on it: msgspec's, KeyError, TypeError, ...
        text = "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in str(exc)[:120])  # no control character
        return f"{type(exc).__name__}: {text}"
    return None


class RefusalLog:
    """One line per refused message on the serve terminal, at most one per ``every_s`` seconds, with a count of those
    not printed: a page sending garbage in a loop cannot flood the terminal."""

    def __init__(self, every_s: float = REFUSAL_LINE_EVERY_S) -> None:
        self.every_s, self.refused, self._quiet, self._last = every_s, 0, 0, float("-inf")

    def refuse(self, why: str) -> None:
        self.refused += 1
        now = time.monotonic()
        if now - self._last < self.every_s:
            self._quiet += 1
            return
        more = f" ({self._quiet} more since the last line)" if self._quiet else ""
        _LOG.warning("gate: dropped a websocket message viser cannot read: %s%s", why, more)
        self._last, self._quiet = now, 0


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a bind address or name) serves this machine only."""
    return host in LOOPBACK or host.startswith("127.")


def new_token() -> str:
    """A token for the URL: 32 random bytes, URL-safe (as Jupyter's)."""
    return secrets.token_urlsafe(32)


def check_token(token: str | None, *, host: str) -> None:
    """Refuse a token too short to guard anything, and no token beyond loopback.

    ``--token "$(cat ~/.workbench-token)"`` with the file missing passes an empty string: served, it let any request
    with an empty cookie in, from any host.

    Raises:
        WorkbenchError: One line: what to pass and how to make a token.
    """
    if token is None:
        if not is_loopback(host):
            raise WorkbenchError(f"serving on {host} needs a token: anyone who can reach the port could use it")
        return
    if len(token) < MIN_TOKEN_CHARS or not token.isprintable() or token != token.strip():
        raise WorkbenchError(
            f"--token of {len(token)} character(s): a token is at least {MIN_TOKEN_CHARS} printable characters "
            f"without spaces at its ends (leave --token out for a new random one, or make one with {MAKE_TOKEN})"
        )


class _UnixHTTPConnection(http.client.HTTPConnection):
    """HTTP to viser's Unix socket (``http.client`` speaks TCP only)."""

    def __init__(self, path: str, *, timeout: float) -> None:
        super().__init__("workbench.inner", timeout=timeout)
        self._path = path

    def connect(self) -> None:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(self.timeout)
        try:
            sock.connect(self._path)
        except OSError:
            sock.close()
            raise
        self.sock = sock


class Gate:
    """Listen on ``host:port`` and pass allowed requests to viser on its private socket.

    Args:
        host: Address to listen on.
        port: Port to listen on; 0 asks the system for any free one. A taken port is an error, never replaced.
        inner: viser's private socket and secret (set it once viser is up: the gate binds first, so a taken port is
            refused before anything else starts).
        token: Required of every request when set (``?token=`` or the cookie the gate sets); ``None`` only on
            loopback.

    Raises:
        WorkbenchError: The port is taken, or a token is missing beyond loopback.
    """

    def __init__(self, *, host: str, port: int, token: str | None, inner: InnerAddress | None = None) -> None:
        check_token(token, host=host)
        self.host, self.inner, self.token = host, inner, token
        self.port = port
        self.cookie = f"workbench-token-{port}"
        self.refused = 0  # requests answered 403, for the tests and the log
        self.dropped = RefusalLog()  # websocket messages viser could not read
        self._stop: asyncio.Event | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="workbench-gate", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._error is not None:
            raise self._error

    # ------------------------------------------------------------------------------------------ checks
    def _allowed_hosts(self) -> set[str] | None:
        """``Host`` headers accepted; ``None``: any (beyond loopback, where the token is what is checked)."""
        if not is_loopback(self.host):
            return None
        return {f"{name}:{self.port}" for name in ("127.0.0.1", "localhost", "[::1]")}

    def _why_refused(self, request: Request) -> str | None:
        hosts, origins = request.headers.get_all("Host"), request.headers.get_all("Origin")
        if len(hosts) != 1 or len(origins) > 1:
            return "a request needs exactly one Host and at most one Origin"
        host = hosts[0]
        allowed = self._allowed_hosts()
        if allowed is not None and host not in allowed:
            return f"Host {host!r} is not the address this workbench serves"
        origin = origins[0] if origins else None
        if origin is not None and origin not in (f"http://{host}", f"https://{host}"):
            return f"a page from {origin} may not use this workbench"
        if self.token is not None and not self._has_token(request):
            return "this workbench needs its token: open the URL it printed when it started"
        return None

    def _query_token(self, request: Request) -> str | None:
        values = parse_qs(urlsplit(request.path).query).get("token")
        return values[0] if values else None

    def _has_token(self, request: Request) -> bool:
        """Whether the request presents the token: an empty or missing one never does, whatever the secret."""
        if not self.token:  # never compared against an empty secret (check_token refuses one at start)
            return False
        given = self._query_token(request)
        if given is None:
            cookie = SimpleCookie()
            with contextlib.suppress(Exception):
                cookie.load(request.headers.get("Cookie", ""))
            given = cookie[self.cookie].value if self.cookie in cookie else None
        if not given:
            return False
        return secrets.compare_digest(given.encode(), self.token.encode())

    # ------------------------------------------------------------------------------------------ serving
    async def _process_request(self, connection: ServerConnection, request: Request) -> Response | None:
        why = self._why_refused(request)
        if why is not None:
            self.refused += 1
            return connection.respond(http.HTTPStatus.FORBIDDEN, f"403 Forbidden: {why}\n")
        if request.headers.get("Upgrade", "").lower() == "websocket":
            return None  # the handshake goes on; _relay takes the connection
        if self.token is not None and self._query_token(request) is not None:
            # the token moves from the URL into a cookie, and the address bar loses it; always to this server's root:
            # the path as sent (``/\evil.example/``) is read by browsers as another site (an open redirect)
            headers = Headers(Location="/")
            headers["Set-Cookie"] = f"{self.cookie}={self.token}; Path=/; HttpOnly; SameSite=Strict"
            return Response(http.HTTPStatus.SEE_OTHER, "See Other", headers, b"")
        return await asyncio.to_thread(self._fetch, request)

    def _fetch(self, request: Request) -> Response:
        """The same request of viser: static files of the page."""
        if self.inner is None:
            return Response(http.HTTPStatus.SERVICE_UNAVAILABLE, "Service Unavailable", Headers(), b"starting\n")
        conn = _UnixHTTPConnection(self.inner.path, timeout=30)
        try:
            forward = {k: v for k in ("Accept-Encoding", "Accept") if (v := request.headers.get(k)) is not None}
            forward[SECRET_HEADER] = self.inner.secret
            conn.request("GET", request.path, headers=forward)
            reply = conn.getresponse()
            body = reply.read()
            headers = Headers(
                (k, v) for k, v in reply.getheaders() if k.lower() in ("content-type", "content-encoding")
            )
            headers["Content-Length"] = str(len(body))
            for k, v in _PAGE_HEADERS.items():
                headers[k] = v
            return Response(reply.status, reply.reason, headers, body)
        except OSError as exc:
            return Response(http.HTTPStatus.BAD_GATEWAY, "Bad Gateway", Headers(), f"{exc}\n".encode())
        finally:
            conn.close()

    async def _relay(self, outer: ServerConnection) -> None:
        """Pass every message both ways between the browser and viser until either side closes."""
        sub, address = outer.subprotocol, self.inner
        if address is None:
            await outer.close(1013, "starting")
            return
        try:
            async with unix_connect(
                address.path,
                uri="ws://workbench.inner/",
                additional_headers={SECRET_HEADER: address.secret},
                subprotocols=[sub] if sub else None,
                max_size=None,  # viser's own messages to a browser have no limit (a raw window can be 60 MB)
                compression=None,
                open_timeout=30,
            ) as inner:

                async def pump(source, sink, *, check: bool) -> None:
                    async for message in source:
                        if check and (why := viser_message_error(message)) is not None:
                            self.dropped.refuse(why)
                            continue
                        await sink.send(message)

                tasks = [
                    asyncio.create_task(pump(outer, inner, check=True)),
                    asyncio.create_task(pump(inner, outer, check=False)),
                ]
                done, pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
                for task in pending:
                    task.cancel()
                for task in done:  # a side that closed, cleanly or not, ends the relay: nothing to report
                    if not task.cancelled():
                        task.exception()
                await asyncio.gather(*pending, return_exceptions=True)
        except (ConnectionClosed, OSError):
            pass

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        except BaseException as exc:  # reported to the constructor when it happens before the gate is up
            if not self._ready.is_set():
                self._error = exc
                self._ready.set()
        finally:
            loop.close()

    async def _serve(self) -> None:
        self._stop = asyncio.Event()
        try:
            server = await serve(
                self._relay,
                self.host,
                self.port,
                process_request=self._process_request,
                max_size=MAX_MESSAGE,
                compression=None,
                select_subprotocol=lambda _, offered: next((p for p in offered if p.startswith("viser-v")), None),
                logger=_LOG,
            )
        except OSError as exc:
            raise WorkbenchError(
                f"cannot serve on {self.host}:{self.port} ({exc.strerror or exc}): the port is taken or not allowed; "
                "choose another with --port, or --port 0 for any free one"
            ) from None
        async with server:
            if self.port == 0:
                self.port = server.sockets[0].getsockname()[1]
                self.cookie = f"workbench-token-{self.port}"
            self._ready.set()
            await self._stop.wait()

    def stop(self) -> None:
        """Stop listening and close every connection."""
        if self._loop is not None and self._stop is not None and self._loop.is_running():
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(10)
