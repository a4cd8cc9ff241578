"""MCAP chunks decoded with their size bounded, and a file's messages read linearly through them.

The mcap library decompresses a chunk to whatever its record declares (zstd allocates the declared size, lz4
whatever comes out) before anything can check it. Here the declared size is checked first, and the decompression
(``bounded_decode``) stops one byte past it, so neither a lying header nor a lying frame costs more than the limit.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

from ..errors import IngestError
from ..limits import MAX_CHUNK_BYTES
from .bounded_decode import decompress


def chunk_records(chunk, *, path: Path, where: str, limit: int = MAX_CHUNK_BYTES) -> list:
    """The records of one chunk (schemas, channels, messages), its decoded size checked before and while decoding.

    Raises:
        IngestError: The chunk declares more than ``limit`` decoded bytes, or decodes to other than it declares.
    """
    from mcap.stream_reader import breakup_chunk

    declared = int(chunk.uncompressed_size)
    if declared > limit:
        raise IngestError(
            path,
            f"an MCAP chunk declares {declared:,} decoded bytes, over the limit of {limit:,} "
            "(sessions/limits.py: MAX_CHUNK_BYTES)",
            where=where,
        )
    try:
        data = decompress(chunk.data, chunk.compression, declared)
    except ValueError:
        raise
    except Exception as exc:  # the decompressor's own errors: damaged data
        raise IngestError(path, f"truncated or corrupt MCAP chunk: {exc}", where=where) from None
    if len(data) != declared:
        more = "more" if len(data) > declared else "fewer"
        raise IngestError(path, f"an MCAP chunk decodes to {more} bytes than the {declared:,} it declares", where=where)
    return breakup_chunk(dataclasses.replace(chunk, compression="", data=data), validate_crc=True)


def linear_messages(raw: IO[bytes], path: Path, on_message: Callable[[object, object, object], None]) -> None:
    """Every message of an MCAP read front to back (no index needed), chunks decoded through
    :func:`chunk_records`: ``on_message(schema, channel, message)``."""
    from mcap.records import Channel, Chunk, Message, Schema
    from mcap.stream_reader import StreamReader

    schemas: dict[int, object] = {}
    channels: dict[int, object] = {}

    def records() -> Iterator[object]:
        for record in StreamReader(raw, skip_magic=False, emit_chunks=True, validate_crcs=True).records:
            if isinstance(record, Chunk):
                yield from chunk_records(record, path=path, where=f"chunk ending at byte {raw.tell()}")
            else:
                yield record

    for record in records():
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            channels[record.id] = record
        elif isinstance(record, Message):
            channel = channels.get(record.channel_id)
            if channel is None:
                raise IngestError(path, f"a message of channel {record.channel_id}, which no record defines")
            on_message(schemas.get(channel.schema_id), channel, record)
