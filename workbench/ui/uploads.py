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


def limit_uploads(server, max_bytes: int, refused: Callable[[int, str, int], None]) -> bool:
    """Refuse an upload larger than ``max_bytes`` at its first message, before viser buffers its parts in memory.

    viser 1.1 holds a whole upload in memory before ``on_upload`` sees it, so a size check there comes after the
    harm. This wraps viser's handler of the upload's start message (its internal handler registry); the parts of a
    refused upload are then dropped as parts of an unknown transfer. Returns False, leaving the check after the
    upload as the only one, when this viser has no such registry.
    """
    from viser import _messages

    gui = server.gui
    try:
        interface, original = gui._websock_interface, gui._handle_file_transfer_start
        interface.unregister_handler(_messages.FileTransferStartUpload, original)
    except (AttributeError, AssertionError, ValueError):
        return False

    def start(client_id: int, message: _messages.FileTransferStartUpload) -> None:
        if message.size_bytes > max_bytes:
            refused(client_id, message.filename, message.size_bytes)
            return
        original(client_id, message)

    interface.register_handler(_messages.FileTransferStartUpload, start)
    return True
