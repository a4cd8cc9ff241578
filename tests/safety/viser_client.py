"""A client that speaks viser's websocket protocol as the browser does, to drive the workbench without a browser.

Server frames are ``[8 B inner size][8 B compressed size][zstd msgpack {"messages": [...]}][binary buffers]``; the
client sends one msgpack-encoded message per frame (viser 1.1, ``viser/infra/_infra.py``). Messages are kept as the
plain dicts they decode to: ``{"type": "GuiButtonMessage", "uuid": ..., "props": {"label": ...}}``.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

import msgspec
import viser
import zstandard
from viser import _messages
from websockets.sync.client import connect


class ViserClient:
    """One connection. ``widgets`` maps a GUI label to its uuid (this client's own panel); ``wait_for`` reads frames
    until a message matches."""

    def __init__(self, url: str, *, timeout: float = 20.0) -> None:
        self.ws = connect(
            url.replace("http://", "ws://"),
            subprotocols=[f"viser-v{viser.__version__}"],
            max_size=None,
            open_timeout=timeout,
        )
        self._unzip = zstandard.ZstdDecompressor()
        self.widgets: dict[str, str] = {}
        self.props: dict[str, dict] = {}  # uuid -> latest props
        self._inbox: deque[dict] = deque()  # received, not yet read
        self.recent: deque[str] = deque(maxlen=40)  # what came lately, for the message of a timeout
        # viser counts a client as connected (and builds its panel) at its first camera message, as a browser sends
        camera = _messages.ViewerCameraMessage(
            (1.0, 0.0, 0.0, 0.0), (3.0, 3.0, 3.0), 1.0, 0.01, 100.0, 800, 1200, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)
        )
        self._send(camera)

    def close(self) -> None:
        self.ws.close()

    def _messages(self, raw: bytes) -> list[dict]:
        inner, size = int.from_bytes(raw[:8], "little"), int.from_bytes(raw[8:16], "little")
        return msgspec.msgpack.decode(self._unzip.decompress(raw[16 : 16 + size], max_output_size=inner))["messages"]

    def _track(self, m: dict) -> None:
        if m["type"] == "NotificationShowMessage":
            self.recent.append(f"{time.strftime('%H:%M:%S')} notification {m['props']['title']}: {m['props']['body']}")
        elif m["type"] == "GuiUpdateMessage" and self.props.get(m["uuid"], {}).get("label"):
            self.recent.append(f"{time.strftime('%H:%M:%S')} update {self._name(m['uuid'])}: {str(m['updates'])[:60]}")
        props = m.get("props")
        if m["type"].startswith("Gui") and isinstance(props, dict) and "uuid" in m:
            self.props[m["uuid"]] = dict(props)
            if "label" in props:
                self.widgets[props["label"]] = m["uuid"]
        elif m["type"] == "GuiUpdateMessage" and m["uuid"] in self.props:
            self.props[m["uuid"]].update(m["updates"])

    def wait_for(self, match: Callable[[dict], bool], *, timeout: float = 20.0) -> dict:
        """Read until a message satisfies ``match``; raises ``TimeoutError`` (or the connection's error).

        The messages after the match in the same frame stay in the inbox for the next call: a frame carries many
        (a whole panel, or an update and a notification), and dropping the rest lost widgets and answers.
        """
        deadline = time.monotonic() + timeout
        while True:
            if not self._inbox:
                left = deadline - time.monotonic()
                try:
                    if left <= 0:
                        raise TimeoutError
                    raw = self.ws.recv(timeout=left)
                except TimeoutError:
                    lately = " | ".join(self.recent)
                    raise TimeoutError(f"no matching message within {timeout:.0f} s; lately: {lately}") from None
                self._inbox.extend(self._messages(raw))
            m = self._inbox.popleft()
            self._track(m)
            if match(m):
                return m

    def _name(self, uuid: str) -> str:
        return str(self.props.get(uuid, {}).get("label", uuid))

    def wait_until(self, condition: Callable[[], bool], *, timeout: float = 20.0) -> None:
        """Read messages until ``condition()`` (on what this client has been told so far) holds."""
        if not condition():
            self.wait_for(lambda m: condition(), timeout=timeout)

    def wait_widget(self, label: str, *, timeout: float = 30.0) -> str:
        """The uuid of the widget labelled ``label`` once the server has sent it."""
        if label not in self.widgets:
            self.wait_for(lambda m: label in self.widgets, timeout=timeout)
        return self.widgets[label]

    def send_update(self, uuid: str, **updates: object) -> None:
        """What the browser sends when a person moves a widget (a button click is ``value=True``)."""
        self._send(_messages.GuiUpdateMessage(uuid, dict(updates)))

    def _send(self, message: _messages.Message) -> None:
        self.ws.send(msgspec.msgpack.encode(message.as_serializable_dict()))

    def label(self, start_s: float, stop_s: float, *, sent: Callable[[], None] | None = None) -> tuple[str, str]:
        """Label ``[start_s, stop_s]`` with the chosen terrain as a person does: move the range, press Save.

        Waits for the server to take the range (its snap note changes) before pressing Save, as a person would see
        the range before saving; ``sent`` is called just before Save is pressed. Returns the notification's title
        and body ("Saved", "... (segment N)").
        """
        span = self.wait_widget("Range (s)")
        self.send_update(span, value=(round(start_s, 2), round(stop_s, 2)))
        self.wait_for(
            lambda m: (
                m["type"] == "GuiUpdateMessage"
                and any(k in str(m["updates"].get("content", "")) for k in ("Snap proposal", "No change point"))
            )
        )
        if sent is not None:
            sent()
        return self.click("Save label (Enter)", ("Saved",))

    def click(self, button: str, done: tuple[str, ...], **before: object) -> tuple[str, str]:
        """Set widgets (label -> value), press ``button``, and return the title and body of the notification
        that answers it: one titled in ``done``, or an error ("Not done", "Something went wrong")."""
        for label, value in before.items():
            self.send_update(self.wait_widget(label), value=value)
        self.send_update(self.wait_widget(button), value=True)
        titles = (*done, "Not done", "Something went wrong")
        note = self.wait_for(lambda m: m["type"] == "NotificationShowMessage" and m["props"]["title"] in titles)
        return note["props"]["title"], note["props"]["body"]
