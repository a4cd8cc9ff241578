"""The gate relays what viser sends, however large, and refuses what it must (tests/safety/test_security.py has
the refusals against a real workbench)."""

from __future__ import annotations

import threading

import pytest
from websockets.sync.client import connect
from websockets.sync.server import serve

from sessions import WorkbenchError
from workbench.ui.gate import Gate


@pytest.fixture
def viser_stand_in():
    """A websocket server on loopback that greets each connection with a 60 MB message and echoes the rest."""
    big = bytes(60 << 20)

    def handler(ws) -> None:
        ws.send(big)
        for message in ws:
            ws.send(message)

    server = serve(handler, "127.0.0.1", 0, max_size=None)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server.socket.getsockname()[1]
    server.shutdown()


def test_messages_past_the_browser_limit_reach_the_browser(viser_stand_in: int) -> None:
    gate = Gate(host="127.0.0.1", port=0, token=None, inner_port=viser_stand_in)
    try:
        with connect(f"ws://127.0.0.1:{gate.port}", max_size=None, open_timeout=20) as ws:
            assert len(ws.recv(timeout=60)) == 60 << 20
            ws.send(b"label")
            assert ws.recv(timeout=20) == b"label"
    finally:
        gate.stop()


def test_beyond_loopback_a_token_is_required() -> None:
    with pytest.raises(WorkbenchError, match="needs a token"):
        Gate(host="0.0.0.0", port=0, token=None)
