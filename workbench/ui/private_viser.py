"""viser where only the gate reaches it: a Unix socket in a private folder, and a secret on every request.

viser 1.1 binds a TCP port and answers whoever connects: a port on ``127.0.0.1`` is open to every web page in the
user's browser (a page may try ``ws://127.0.0.1:N`` for every N in seconds), so a second, unchecked port beside the
gate made the gate's checks worth nothing (measured: a foreign Origin with no token got the whole UI and could
upload). viser gives no option for its socket, so while a server starts, the one call it makes to
``websockets.asyncio.server.serve`` is answered by :func:`unix_serve` instead: no TCP port is opened at all. The
socket lies in a folder only this user may enter (``0700``), no browser can open a Unix socket, and every request on
it must also carry a per-process secret that only the gate adds (compared in constant time), so a local process of
another user, or one that found the path, still gets 403. viser's banner (which printed the inner address in a box,
``http://127.0.0.1:N``) is kept off the terminal the same way: the one ``rich.print`` it makes while starting.
"""

from __future__ import annotations

import http
import secrets
import shutil
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import websockets.asyncio.server as ws_server

SECRET_HEADER = "X-Workbench-Gate"
_STARTING = threading.Lock()  # one viser starts at a time: the patched ``serve`` belongs to that one


@dataclass(frozen=True)
class InnerAddress:
    """Where viser listens and what the gate must show it.

    Attributes:
        path: The Unix socket viser listens on.
        secret: The value of ``SECRET_HEADER`` every request must carry.
    """

    path: str
    secret: str


def _guarded(process_request: Any, secret: str) -> Any:
    """viser's request hook, behind the secret: a request without it never reaches viser's page or websocket."""
    expected = secret.encode()

    def check(connection: ws_server.ServerConnection, request: Any) -> Any:
        given = request.headers.get(SECRET_HEADER, "")
        if not secrets.compare_digest(given.encode(), expected):
            return connection.respond(http.HTTPStatus.FORBIDDEN, "403 Forbidden\n")
        return process_request(connection, request) if process_request is not None else None

    return check


def start_private_viser(**viser_options: Any) -> tuple[Any, InnerAddress]:
    """Start a ``viser.ViserServer`` on a private Unix socket instead of a TCP port.

    Args:
        **viser_options: Passed to ``viser.ViserServer`` (``host`` and ``port`` are not used: nothing is bound on
            TCP).

    Returns:
        The server, and the address the gate connects to.

    Raises:
        RuntimeError: viser did not start on the socket (a viser that no longer calls ``serve`` as 1.1 does): the
            caller must not go on with a server that may listen on TCP.
    """
    import rich
    import viser

    folder = Path(tempfile.mkdtemp(prefix="workbench-"))  # 0700: only this user may enter it
    address = InnerAddress(path=str(folder / "viser.sock"), secret=secrets.token_urlsafe(32))
    original = ws_server.serve
    bound: list[str] = []

    def serve_on_socket(handler: Any, host: Any = None, port: Any = None, **kwargs: Any) -> Any:
        kwargs["process_request"] = _guarded(kwargs.get("process_request"), address.secret)
        bound.append(address.path)
        return original(handler, unix=True, path=address.path, **kwargs)

    with _STARTING:
        ws_server.serve, banner = serve_on_socket, rich.print
        rich.print = lambda *args, **kwargs: None
        try:
            server = viser.ViserServer(**{**viser_options, "host": "127.0.0.1", "port": 0})
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        finally:
            ws_server.serve, rich.print = original, banner
    if not bound or not Path(address.path).exists():
        server.stop()
        shutil.rmtree(folder, ignore_errors=True)
        raise RuntimeError("viser did not start on the private socket; refusing to serve it on a TCP port")
    return server, address


def remove_private_socket(address: InnerAddress) -> None:
    """Remove the socket's folder once viser has stopped."""
    shutil.rmtree(Path(address.path).parent, ignore_errors=True)
