"""The gate relays what viser sends, however large, and refuses what it must (tests/safety/test_security.py has
the refusals against a real workbench)."""

from __future__ import annotations

import threading

import msgspec
import pytest
from viser import _messages
from websockets.sync.client import connect
from websockets.sync.server import unix_serve

from sessions import WorkbenchError
from workbench.ui.gate import Gate
from workbench.ui.private_viser import SECRET_HEADER, InnerAddress

# a message viser reads (an upload's part): the gate passes only those
LABEL = msgspec.msgpack.encode(_messages.FileTransferPart("button", "transfer", 0, b"label").as_serializable_dict())


@pytest.fixture
def viser_stand_in(tmp_path):
    """A websocket server on a Unix socket that greets each connection with a 60 MB message and echoes the rest;
    it records the secret each connection showed."""
    big = bytes(60 << 20)
    address = InnerAddress(path=str(tmp_path / "viser.sock"), secret="the-secret")
    shown: list[str | None] = []

    def handler(ws) -> None:
        shown.append(ws.request.headers.get(SECRET_HEADER))
        ws.send(big)
        for message in ws:
            ws.send(message)

    server = unix_serve(handler, address.path, max_size=None)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield address, shown
    server.shutdown()


def test_messages_past_the_browser_limit_reach_the_browser(viser_stand_in) -> None:
    address, shown = viser_stand_in
    gate = Gate(host="127.0.0.1", port=0, token=None, inner=address)
    try:
        with connect(f"ws://127.0.0.1:{gate.port}", max_size=None, open_timeout=20) as ws:
            assert len(ws.recv(timeout=60)) == 60 << 20
            ws.send(b"garbage")  # not a message viser can read: dropped by the gate, never echoed
            ws.send(LABEL)
            assert ws.recv(timeout=20) == LABEL
        assert shown == ["the-secret"]  # the gate shows viser its secret
        assert gate.dropped.refused == 1
    finally:
        gate.stop()


def test_beyond_loopback_a_token_is_required() -> None:
    with pytest.raises(WorkbenchError, match="needs a token"):
        Gate(host="0.0.0.0", port=0, token=None)
