"""Uploads from the browser: the size limit, enforced before viser buffers a file, and safe file names."""

from __future__ import annotations

import re
from collections.abc import Callable

MAX_UPLOAD_MB = 512
UPLOAD_SUFFIXES = (".mcap", ".csv")


def safe_name(name: str) -> str:
    """A file name that cannot leave the folder it is written to: the last path part, plain characters only."""
    base = re.split(r"[\\/]", name)[-1]
    base = re.sub(r"[^A-Za-z0-9._-]+", "_", base).lstrip(".")
    return base[:120] or "upload"


def limit_uploads(owner, max_bytes: int, refused: Callable[[int, str, int], None]) -> bool:
    """Hold every upload to ``max_bytes`` as its bytes arrive, before viser buffers them in memory.

    viser 1.1 holds a whole upload in memory before ``on_upload`` sees it, so a size check there comes after the
    harm, and it trusts the size a client declares: one that declared 1 KB and sent 1,200 parts of 1 MB grew the
    server by 1.2 GB. This wraps viser's handlers of the upload's start and parts (its internal handler registry):
    a start declaring more than ``max_bytes`` is refused, and so is the first part that would take the bytes
    received past the declared size or ``max_bytes``; the transfer is then dropped with what it had buffered, and
    its later parts are dropped as parts of an unknown transfer. ``owner`` is a viser client: each holds its uploads in
    its own GUI, so this runs for every client as it connects. Returns False, leaving the check
    after the upload as the only one, when this viser has no such registry.
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

    def start(client_id: int, message: _messages.FileTransferStartUpload) -> None:
        if message.size_bytes > max_bytes:
            refused(client_id, message.filename, message.size_bytes)
            return
        start_handler(client_id, message)

    def part(client_id: int, message: _messages.FileTransferPart) -> None:
        state = uploads.get(message.transfer_uuid)
        if state is None or state.get("client_id") != client_id:
            return  # unknown, refused, or another client's transfer: viser would drop it too
        with state["lock"]:
            received = state["transferred_bytes"] + len(message.content)
            over = received > min(int(state["total_bytes"]), max_bytes)
        if over:
            uploads.pop(message.transfer_uuid, None)  # and every part it buffered
            refused(client_id, str(state.get("filename", "upload")), received)
            return
        part_handler(client_id, message)

    interface.register_handler(_messages.FileTransferStartUpload, start)
    interface.register_handler(_messages.FileTransferPart, part)
    return True
