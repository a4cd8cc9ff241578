"""No way around the gate (issue 52, item 1): ``workbench serve --token`` listens on one TCP port, the gate's.

The process is started as a user starts it, in a child; its sockets are read from ``/proc`` (every TCP port it
listens on, every Unix socket it holds). Each TCP port other than the gate's must refuse a websocket from a foreign
Origin with no token and serve no page; viser's own Unix socket must refuse a request without the gate's secret; the
banner names no inner address. Before the fix, viser's own port on 127.0.0.1 gave the whole UI to such a websocket.
``make stress`` also sweeps loopback's whole ephemeral range as a web page in the browser would.
"""

from __future__ import annotations

import http.client
import os
import socket
import time
from pathlib import Path

import pytest
from websockets.exceptions import InvalidHandshake, InvalidStatus
from websockets.sync.client import connect, unix_connect

VISER = f"viser-v{__import__('viser').__version__}"


def _socket_inodes(pid: int) -> set[int]:
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue  # closed meanwhile
        if target.startswith("socket:["):
            inodes.add(int(target[8:-1]))
    return inodes


def listening_tcp_ports(pid: int) -> set[int]:
    """Every TCP port (v4 and v6) the process listens on, read from ``/proc/net/tcp*``."""
    inodes, ports = _socket_inodes(pid), set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if not Path(table).exists():
            continue
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == "0A" and int(fields[9]) in inodes:  # 0A: LISTEN
                ports.add(int(fields[1].rsplit(":", 1)[1], 16))
    return ports


def unix_socket_paths(pid: int) -> set[str]:
    """The paths of the Unix sockets the process holds (listening or not), read from ``/proc/net/unix``."""
    inodes, paths = _socket_inodes(pid), set()
    for line in Path("/proc/net/unix").read_text().splitlines()[1:]:
        fields = line.split()
        if len(fields) >= 8 and int(fields[6]) in inodes and fields[7].startswith("/"):
            paths.add(fields[7])
    return paths


def _page_status(port: int, **headers: str) -> int | None:
    """The status of ``GET /``, or None when the port does not speak HTTP."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    try:
        conn.request("GET", "/", headers=headers)
        reply = conn.getresponse()
        reply.read()
        return reply.status
    except (OSError, http.client.HTTPException):
        return None
    finally:
        conn.close()


def _foreign_websocket_refused(port: int) -> bool:
    try:
        ws = connect(f"ws://127.0.0.1:{port}", subprotocols=[VISER], origin="http://evil.example", open_timeout=5)
    except (InvalidHandshake, OSError, TimeoutError):
        return True
    with ws:
        try:
            ws.recv(timeout=2)  # viser talks at once to a client it accepted
        except Exception:
            return True
    return False


def test_only_the_gate_listens_and_viser_refuses_without_the_secret(served, promise) -> None:
    proc, port, banner = served
    deadline = time.monotonic() + 20
    while not (unix := unix_socket_paths(proc.pid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    ports = listening_tcp_ports(proc.pid)
    assert port in ports
    others = ports - {port}
    for other in others:  # none today; each must still be shut to a page on the web
        assert _foreign_websocket_refused(other), f"port {other} accepted a foreign websocket"
        assert _page_status(other, Host="evil.example") != 200, f"port {other} served a page"
    assert others == set(), f"the serve process listens on more than the gate's port: {sorted(ports)}"
    # the gate itself, as before: a foreign Origin and no token are refused
    with pytest.raises(InvalidStatus, match="403"):
        connect(f"ws://127.0.0.1:{port}", subprotocols=[VISER], origin="http://evil.example", open_timeout=20)
    assert _page_status(port) == 403
    # viser's own socket: private folder, and a request without the gate's secret gets no page and no websocket
    (inner,) = [p for p in unix if p.endswith("viser.sock")]
    assert os.stat(Path(inner).parent).st_mode & 0o077 == 0, "the socket's folder is open to other users"
    with pytest.raises(InvalidStatus, match="403"):
        unix_connect(inner, uri="ws://localhost/", subprotocols=[VISER], open_timeout=20)
    with socket.socket(socket.AF_UNIX) as raw:
        raw.connect(inner)
        raw.sendall(b"GET / HTTP/1.1\r\nHost: localhost\r\n\r\n")
        assert raw.recv(64).startswith(b"HTTP/1.1 403")
    assert inner not in banner and str(Path(inner).parent) not in banner
    promise(f"ports (nothing but the gate reaches viser): the serve process listens on TCP {sorted(ports)} only")


@pytest.mark.slow
def test_no_port_in_the_ephemeral_range_gives_a_foreign_page_the_ui(served, promise) -> None:
    """What a web page in the user's browser can do: try every ephemeral port on loopback for viser."""
    _, port, _ = served
    low, high = (int(x) for x in Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split())
    answered, t0 = [], time.monotonic()
    for candidate in range(low, high + 1):
        with socket.socket() as probe:
            probe.settimeout(0.2)
            if probe.connect_ex(("127.0.0.1", candidate)) != 0:
                continue
        answered.append(candidate)
    opened = [p for p in answered if p != port and not _foreign_websocket_refused(p)]
    assert opened == [], f"ports that gave a foreign page a viser websocket: {opened}"
    promise(
        f"ports, full sweep: {high - low + 1:,} loopback ports tried in {time.monotonic() - t0:.0f} s, "
        f"{len(answered)} answered, none gave a foreign page the UI (the gate's {port} refused it)"
    )
