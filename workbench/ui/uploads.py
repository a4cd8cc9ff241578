"""Uploads from the browser: limits per transfer, per client and per server, enforced before viser buffers a file,
and safe file names."""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import gc
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

MAX_UPLOAD_MB = 512  # one file
MAX_IN_FLIGHT_MB = 512  # every upload the server is receiving at once, all clients together
MAX_UPLOADS_PER_CLIENT = 2  # at once, from one page
# An upload must keep a minimum rate, or it gives its room to others when they need it: one that sent 1 MB and then
# 1 KB every 30 s held 510 MB of the server's room for ever, since a trickle reset a "nothing for 60 s" rule. 1 MB per
# 30 s is 270 kbit/s, slower than any link a person uploads a log over.
MIN_RATE_BYTES = 1 << 20  # at least this much (or the rest of the file) ...
RATE_WINDOW_S = 30.0  # ... in every window this long
UPLOAD_SUFFIXES = (".mcap", ".csv")


def safe_name(name: str) -> str:
    """A file name that cannot leave the folder it is written to: the last path part, plain characters only."""
    base = re.split(r"[\\/]", name)[-1]
    base = re.sub(r"[^A-Za-z0-9._-]+", "_", base).lstrip(".")
    return base[:120] or "upload"


def release_freed_memory() -> None:
    """Give freed heap back to the system: glibc keeps large freed blocks (an upload's 1 MB parts) in its arenas,
    and the server's RSS stayed where the uploads had taken it (measured: 2.55 GB 10 s after six clients left)."""
    name = ctypes.util.find_library("c")
    if name is None:
        return
    with contextlib.suppress(OSError, AttributeError):  # not glibc: nothing to trim
        ctypes.CDLL(name).malloc_trim(0)


@dataclass
class _Transfer:
    client_id: int
    name: str
    declared: int
    mark_time: float  # when it last met the rate: it has until mark_time + window to send the next MIN_RATE_BYTES
    mark_bytes: int  # what it had received then
    received: int = 0

    def slow(self, now: float, window_s: float, min_bytes: int) -> bool:
        """Whether it has fallen under the minimum rate: less than ``min_bytes`` (or what was left of its file)
        since its last mark, which is more than ``window_s`` ago."""
        due = min(min_bytes, self.declared - self.mark_bytes)
        return now - self.mark_time > window_s and self.received - self.mark_bytes < due


@dataclass
class UploadBudget:
    """What the whole server may be receiving at once: the bytes declared by every upload in flight, across all
    clients, and how many uploads each client has in flight. Shared by every client's handlers.

    Attributes:
        max_bytes: One upload's limit.
        max_in_flight: The declared bytes of every upload in flight together.
        per_client: Uploads in flight from one client.
        window_s: An upload that sent less than ``min_bytes`` (or the rest of its file) in this long is slow, and is
            dropped when another needs its room.
        min_bytes: See ``window_s``.
    """

    max_bytes: int = MAX_UPLOAD_MB << 20
    max_in_flight: int = MAX_IN_FLIGHT_MB << 20
    per_client: int = MAX_UPLOADS_PER_CLIENT
    window_s: float = RATE_WINDOW_S
    min_bytes: int = MIN_RATE_BYTES
    _transfers: dict[str, _Transfer] = field(default_factory=dict)
    _buffers: dict[int, dict] = field(default_factory=dict)  # client -> viser's buffers of its uploads
    _lock: threading.Lock = field(default_factory=threading.Lock)
    dropped_slow: int = 0  # uploads dropped under the minimum rate, for the tests and the log
    clock: Callable[[], float] = time.monotonic  # seconds; the tests' own clock

    def attach(self, client_id: int, buffers: dict) -> None:
        """Where viser buffers a client's uploads: a stalled one is dropped from there when its room is given."""
        with self._lock:
            self._buffers[client_id] = buffers

    def in_flight(self) -> int:
        """The declared bytes of the uploads now in flight."""
        with self._lock:
            return self._used()

    def reserve(self, transfer: str, client_id: int, name: str, declared: int) -> str | None:
        """Take room for an upload that starts; uploads under the minimum rate are dropped first if it needs their
        room.

        Returns:
            Why it is refused, or ``None``: it may go on.
        """
        shown = safe_name(name)
        if declared > self.max_bytes:
            return f"{shown}: {declared / 2**20:.1f} MB is over the {self.max_bytes >> 20} MB upload limit"
        with self._lock:
            now = self.clock()
            if self._count(client_id) >= self.per_client or self._used() + declared > self.max_in_flight:
                for k in [k for k, t in self._transfers.items() if t.slow(now, self.window_s, self.min_bytes)]:
                    self._buffers.get(self._transfers.pop(k).client_id, {}).pop(k, None)
                    self.dropped_slow += 1
            if (count := self._count(client_id)) >= self.per_client:
                return f"{shown}: this page is already sending {count} uploads; wait for one to finish"
            used = self._used()
            if used + declared > self.max_in_flight:
                return (
                    f"{shown}: the server is receiving {used / 2**20:.0f} MB of uploads already (at most "
                    f"{self.max_in_flight >> 20} MB at once); try again when they have finished"
                )
            self._transfers[transfer] = _Transfer(client_id, name, declared, now, 0)
            return None

    def _count(self, client_id: int) -> int:
        return sum(t.client_id == client_id for t in self._transfers.values())

    def _used(self) -> int:
        return sum(t.declared for t in self._transfers.values())

    def touch(self, transfer: str, size: int) -> bool:
        """A part of ``size`` bytes arrived; False when the transfer holds no room (refused, finished or dropped as
        too slow)."""
        with self._lock:
            held = self._transfers.get(transfer)
            if held is not None:
                held.received += size
                if held.received - held.mark_bytes >= min(self.min_bytes, held.declared - held.mark_bytes):
                    held.mark_time, held.mark_bytes = self.clock(), held.received  # it met the rate: a new window
            return held is not None

    def release(self, transfer: str) -> None:
        """The upload finished, was refused or dropped: its room goes back."""
        with self._lock:
            self._transfers.pop(transfer, None)

    def release_client(self, client_id: int) -> int:
        """The client left: the room of its uploads goes back. Returns how many it had in flight."""
        with self._lock:
            gone = [k for k, t in self._transfers.items() if t.client_id == client_id]
            for k in gone:
                del self._transfers[k]
            self._buffers.pop(client_id, None)
        release_freed_memory()  # what its finished uploads held is freed with its page too
        return len(gone)


def forget_upload(button) -> None:
    """Drop the file an upload button holds, once it is on disk or refused.

    viser keeps the last upload's bytes as the button's value until the next one, and a refused upload's bytes stay
    in a reference cycle (the error's traceback holds the frame that read them) until the collector runs: measured,
    350 MB still held by the server after the page that sent it had left, freed by ``gc.collect()``.
    """
    from viser import UploadedFile

    value = getattr(button, "_impl", None)
    if value is not None and isinstance(value.value, UploadedFile):
        value.value = UploadedFile(name=value.value.name, content=b"")
    gc.collect()
    release_freed_memory()


def limit_uploads(owner, budget: UploadBudget, refused: Callable[[int, str], None]) -> bool:
    """Hold every upload of one client to ``budget`` as its bytes arrive, before viser buffers them in memory.

    viser 1.1 holds a whole upload in memory before ``on_upload`` sees it, so a size check there comes after the
    harm, and it trusts the size a client declares: one that declared 1 KB and sent 1,200 parts of 1 MB grew the
    server by 1.2 GB. This wraps viser's handlers of the upload's start and parts (its internal handler registry):
    a start is refused when its declared size is over one upload's limit, when its client has ``per_client``
    uploads in flight, or when it would take the server's uploads in flight past ``max_in_flight`` (six clients
    sending 350 MB each grew the server by 2 GB while each was under the per-file limit); a part is refused when it
    would take the bytes received past the declared size. A refused transfer is dropped with what it had buffered,
    and its later parts are dropped as parts of an unknown transfer. ``owner`` is a viser client: each holds its
    uploads in its own GUI, so this runs for every client as it connects; ``budget`` is the server's, shared by all.
    Returns False, leaving the check after the upload as the only one, when this viser has no such registry.
    """
    from viser import _messages

    gui = owner.gui  # a client's own GUI: viser buffers an upload in the GUI of the client that sends it
    try:
        interface = gui._websock_interface
        uploads: dict = gui._current_file_upload_states
        start_handler, part_handler = gui._handle_file_transfer_start, gui._handle_file_transfer_part
        interface.unregister_handler(_messages.FileTransferStartUpload, start_handler)
        interface.unregister_handler(_messages.FileTransferPart, part_handler)
    except (AttributeError, AssertionError, ValueError):
        return False

    budget.attach(owner.client_id, uploads)

    def start(client_id: int, message: _messages.FileTransferStartUpload) -> None:
        why = budget.reserve(message.transfer_uuid, client_id, message.filename, message.size_bytes)
        if why is not None:
            refused(client_id, why)
            return
        start_handler(client_id, message)
        if message.transfer_uuid not in uploads:  # finished at once (an empty file) or not for an upload button
            budget.release(message.transfer_uuid)

    def part(client_id: int, message: _messages.FileTransferPart) -> None:
        transfer = message.transfer_uuid
        state = uploads.get(transfer)
        if state is None or state.get("client_id") != client_id:
            return  # unknown, refused, or another client's transfer: viser would drop it too
        if not budget.touch(transfer, len(message.content)):  # its room was given to others: it was too slow
            uploads.pop(transfer, None)
            return
        with state["lock"]:
            received = state["transferred_bytes"] + len(message.content)
            over = received > min(int(state["total_bytes"]), budget.max_bytes)
        if over:
            uploads.pop(transfer, None)
            budget.release(transfer)
            name = safe_name(str(state.get("filename", "upload")))
            refused(client_id, f"{name}: refused at {received / 2**20:.1f} MB, more than the browser declared")
            release_freed_memory()
            return
        part_handler(client_id, message)
        if transfer not in uploads:  # the last part: viser assembled the file and handed it on
            budget.release(transfer)

    interface.register_handler(_messages.FileTransferStartUpload, start)
    interface.register_handler(_messages.FileTransferPart, part)
    return True
