"""Decompression that stops past a limit: zstd, lz4 and bz2 read a block at a time, never to whatever the data holds.

The readers' libraries decompress a chunk or a message whole (``zstandard.decompress`` allocates the size a frame
declares; lz4 and bz2 return all that comes out), so a few kilobytes of zeros can ask for gigabytes. These return at
most ``limit + 1`` bytes: one more than the limit says the data did not stop.
"""

from __future__ import annotations

import io

from ..limits import MiB

READ_BLOCK = 1 * MiB


class DecodedTooLarge(ValueError):
    """Data that decodes to more than its limit; ``limit`` and the ``what`` it was say which."""

    def __init__(self, what: str, limit: int) -> None:
        super().__init__(f"{what} decodes to more than {limit:,} bytes")
        self.what, self.limit = what, limit


def decompress(data: bytes, compression: str, limit: int) -> bytes:
    """``data`` decompressed (``zstd``, ``lz4``, ``bz2``; ``""`` or ``none``: as it is), at most ``limit + 1`` bytes."""
    if compression in ("", "none"):
        return data
    if compression == "zstd":
        import zstandard

        out = bytearray()
        with zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data), read_across_frames=True) as reader:
            while len(out) <= limit:
                block = reader.read(min(READ_BLOCK, limit + 1 - len(out)))
                if not block:
                    break
                out += block
        return bytes(out)
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=limit + 1)
    if compression == "bz2":
        import bz2

        return bz2.BZ2Decompressor().decompress(data, max_length=limit + 1)
    raise ValueError(f"compression {compression!r} is not supported (zstd, lz4, bz2 or none are)")


def decompress_within(data: bytes, compression: str, limit: int, what: str) -> bytes:
    """As :func:`decompress`, raising :class:`DecodedTooLarge` past ``limit``."""
    out = decompress(data, compression, limit)
    if len(out) > limit:
        raise DecodedTooLarge(what, limit)
    return out
