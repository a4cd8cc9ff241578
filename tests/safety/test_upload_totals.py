"""Limits per server, not per transfer (issue 52, item 2), against ``workbench serve --token`` in a child process.

Before: the 512 MB cap held each transfer, so six pages sending 350 MB each grew the server from 0.53 to 2.61 GB,
with no notification, and 10 s after they left it still held 2.55 GB. Now every upload's declared size counts
against one total for the whole server, a page may send two at once, a refusal is one notification, and an upload
cut off by its page leaving gives its memory back (the server's RSS, read from ``/proc``, within 100 MB of where it
started). ``make test`` sends 2 x 120 MB; ``make stress`` the issue's six pages of 350 MB.
"""

from __future__ import annotations

import os
import threading
import time
import uuid
from pathlib import Path

import msgspec
import pytest
from viser import _messages

from tests.safety.conftest import SERVE_TOKEN
from tests.safety.viser_client import ViserClient
from workbench.ui import MAX_UPLOAD_MB
from workbench.ui.uploads import MAX_IN_FLIGHT_MB, MAX_UPLOADS_PER_CLIENT

BUTTON = f"Upload MCAP / CSV (≤ {MAX_UPLOAD_MB} MB)"
CHUNK = os.urandom(1 << 20)


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError(f"no VmRSS for {pid}")


class Page:
    """One browser page of the served workbench, sending uploads as viser's client does."""

    def __init__(self, port: int) -> None:
        self.client = ViserClient(f"http://127.0.0.1:{port}/?token={SERVE_TOKEN}")
        self.button = self.client.wait_widget(BUTTON, timeout=60)

    def _send(self, message: _messages.Message) -> None:
        self.client.ws.send(msgspec.msgpack.encode(message.as_serializable_dict()))

    def start(self, name: str, megabytes: int) -> str:
        transfer = uuid.uuid4().hex
        self._send(_messages.FileTransferStartUpload(self.button, transfer, name, "", megabytes, megabytes << 20))
        return transfer

    def send(self, transfer: str, first: int, count: int) -> None:
        for i in range(first, first + count):
            self._send(_messages.FileTransferPart(self.button, transfer, i, CHUNK))

    def refusal(self, timeout: float = 30.0) -> str:
        note = self.client.wait_for(
            lambda m: m["type"] == "NotificationShowMessage" and m["props"]["title"] == "Not done", timeout=timeout
        )
        return note["props"]["body"]

    def no_refusal(self, seconds: float = 1.5) -> bool:
        try:
            self.refusal(timeout=seconds)
        except TimeoutError:
            return True
        return False

    def close(self) -> None:
        self.client.close()


class Peak:
    """The server's highest RSS while the block runs, sampled every 20 ms."""

    def __init__(self, pid: int) -> None:
        self.pid, self.mb, self._stop = pid, 0.0, threading.Event()

    def __enter__(self) -> Peak:
        def sample() -> None:
            while not self._stop.wait(0.02):
                self.mb = max(self.mb, rss_mb(self.pid))

        self._thread = threading.Thread(target=sample, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def settled_rss(pid: int, near: float, *, within: float, timeout: float = 15.0) -> float:
    """The server's RSS once it is within ``within`` MB of ``near`` (or after ``timeout``)."""
    deadline = time.monotonic() + timeout
    while (now := rss_mb(pid)) > near + within and time.monotonic() < deadline:
        time.sleep(0.2)
    return now


def test_uploads_share_one_total_and_a_page_that_leaves_gives_its_memory_back(served, detail) -> None:
    proc, port, _ = served
    pages = [Page(port) for _ in range(3)]
    try:
        time.sleep(1.0)
        before = rss_mb(proc.pid)
        a, b, c = pages
        # a page may send two at once; the third is refused in one notification
        first = [a.start(f"a{i}.mcap", 120) for i in range(MAX_UPLOADS_PER_CLIENT)]
        a.start("a-third.mcap", 1)
        assert f"already sending {MAX_UPLOADS_PER_CLIENT} uploads" in a.refusal()
        # 240 MB in flight: a page asking for 300 MB more is over the server's total, though under the per-file limit
        assert MAX_IN_FLIGHT_MB < 240 + 300 and MAX_UPLOAD_MB > 300
        b.start("b.mcap", 300)
        why = b.refusal()
        assert "b.mcap" in why and "receiving 240 MB of uploads already" in why, why
        # the first page sends 100 MB of each of its two, then leaves halfway: its buffers are dropped
        with Peak(proc.pid) as peak:
            for transfer in first:
                a.send(transfer, 0, 100)
            time.sleep(2.0)  # the parts reach the server
            grown = rss_mb(proc.pid) - before
        assert grown > 150, f"the server grew by {grown:.0f} MB for 200 MB of parts: the parts did not arrive"
        a.close()
        after = settled_rss(proc.pid, before, within=100)
        assert after - before < 100, f"{after - before:.0f} MB still held after the page left (from {before:.0f})"
        # its room is back: the same 300 MB is now taken
        c.start("c.mcap", 300)
        assert c.no_refusal()
        detail(
            f"upload totals: {MAX_UPLOADS_PER_CLIENT} per page, {MAX_IN_FLIGHT_MB} MB in flight; 2 x 100 MB sent "
            f"then the page left: the server peaked at +{peak.mb - before:.0f} MB and came back to "
            f"{after - before:+.0f} MB of where it started"
        )
    finally:
        for page in pages:
            page.close()


@pytest.mark.slow
def test_six_pages_of_350_mb_at_once(served, detail) -> None:
    """The issue's measurement: six pages each sending a 350 MB file at once."""
    proc, port, _ = served
    pages = [Page(port) for _ in range(6)]
    try:
        time.sleep(1.0)
        before = rss_mb(proc.pid)
        transfers = [page.start(f"p{i}.mcap", 350) for i, page in enumerate(pages)]
        refused = [i for i, page in enumerate(pages) if not page.no_refusal(3.0)]
        assert len(refused) == 5, f"pages refused: {refused}"
        (taken,) = set(range(6)) - set(refused)
        with Peak(proc.pid) as peak:
            threads = [
                threading.Thread(target=page.send, args=(transfer, 0, 350))
                for page, transfer in zip(pages, transfers, strict=True)
            ]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            time.sleep(3.0)
        # the one taken has all its bytes: viser assembled it and the session refused random bytes as a log
        body = pages[taken].refusal(timeout=60)
        assert "p" in body, body
        for page in pages:
            page.close()
        after = settled_rss(proc.pid, before, within=100, timeout=20)
        grew = peak.mb - before
        assert grew < MAX_IN_FLIGHT_MB * 2.5, f"the server grew by {grew:.0f} MB"
        assert after - before < 100, f"{after - before:.0f} MB still held after the pages left"
        detail(
            f"six pages x 350 MB at once: 5 refused in one notification each, the server peaked at +{grew:.0f} MB "
            f"(was +2,080 MB) and came back to {after - before:+.0f} MB of where it started"
        )
    finally:
        for page in pages:
            page.close()
