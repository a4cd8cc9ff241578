"""How much a reader decodes, stated once with the reasons: each reader checks before it allocates.

A log's size on disk says little about what it decodes to (a 52 KB MCAP chunk can declare 1.6 GB of zeros), so every
limit counts decoded bytes or declared pixels, and a refusal names the limit, the file and the place. The UI's upload
limit (``workbench.ui.MAX_UPLOAD_MB``) counts the bytes sent; what an upload decodes to meets these limits after.
"""

from __future__ import annotations

MiB = 1 << 20

MAX_CHUNK_BYTES = 128 * MiB
"""Decoded size of one MCAP chunk (declared, and what comes out). Writers use 1–4 MiB chunks (the mcap library's
default is 1 MiB, rosbag2's 4 MiB); a chunk holds at least one whole message, and the largest message a camera topic
may have is below. Bounded, a chunk costs at most its decoded bytes and the messages cut from them: under 1 GB of
memory with the rest of an ingest."""

MAX_SENSOR_MESSAGE_BYTES = 1 * MiB
"""One message of a topic read as sensor channels. A ``sensor_msgs/Imu`` is about 330 bytes, a ``WrenchStamped``
about 90, a custom state message with a hundred wrenches some 10 KB: a megabyte is thousands of times what such a
schema holds, and decoding more would only spend memory on a frame id or an array no channel reads."""

MAX_IMAGE_MESSAGE_BYTES = MAX_CHUNK_BYTES
"""One camera message: an 8K frame of raw rgba8 (7680 x 4320 x 4) is 133 MB. A larger one skips that frame."""

MAX_FRAME_PIXELS = 40_000_000
"""Declared pixels of one camera frame, checked from its header before it is decoded (any format Pillow opens). An
8K frame has 33.2 million; Pillow's own guard starts at 89 million and raises an error no reader expects. A frame over
it is skipped and counted, never the log."""

MAX_CSV_LINE_BYTES = 1 * MiB
"""One line of a sensor CSV: a row is a few hundred bytes, so a longer "line" is not one (a file of one 2 GB line is
refused at its first megabyte, not read whole)."""

MAX_STORED_FRAME_BYTES = 16 * MiB
"""One camera frame as the session keeps it (a JPEG of at most 640 px): a larger size in a frames index is damage or
tampering, and the index is refused before a frame is read."""

MAX_LABEL_FILE_BYTES = 256 * MiB
"""A label file (CSV, Parquet, JSON) on disk, and a Parquet file's decoded row groups. A label is a row of a few
dozen bytes: 256 MiB is millions of segments."""

MAX_LABEL_ROWS = 5_000_000
"""Rows of one label file, from a Parquet file's metadata before any row is decoded. Five million one-second
segments are eight weeks of logs labelled end to end; importing 100,000 rows takes about 3 s."""

MAX_LABEL_NESTING = 2
"""Depth of a JSON label file: a list of records of plain values (``[{"log": ..., "start_s": ...}]``) is two. The
parser itself gives up past Python's recursion limit, with an error no reader expects."""

MAX_RATE_HZ = 100_000.0
"""Rate of a log's time base (``--rate``, ``rate_hz``): force plates and motor currents are sampled at a few kHz at
most, and a grid at 1e7 Hz held a gigabyte for 30 s of a 100 Hz log before anything was written."""

MAX_GRID_GROWTH = 64
"""Grid rows per sample of the fastest stream: upsampling a 50 Hz IMU to 1 kHz is 20. A grid larger than this is a
stamp that jumped (a 30 s CSV whose last row says 1e9 s asked for 1e11 rows: a 40 GB file) or a rate far past the
sensors'. It is refused before anything is allocated, whatever ``--allow-gaps`` says."""

MIN_GRID_ROWS = 1_000_000
"""A grid of up to this many rows is never refused by ``MAX_GRID_GROWTH``: a short file may be resampled freely."""

MAX_MAPPING_CHANNELS = 10_000
"""Channels (and CSV column names) one mapping file may declare: a robot's richest state message has hundreds."""

MAX_MAPPING_BYTES = 16 * MiB
"""A mapping file on disk: channels are a few lines each."""

MAX_NAME_CHARS = 300
"""A terrain's, a log's or an author's name, wherever it comes from (a label file of any format, Label Studio, the
command line, the page's terrain field). A file name is at most 255 bytes on the usual file systems and a log is
named by its file's stem (``_trialN`` added for a trial of a multi-trial CSV); a terrain is a word or two. A label
file with a 50 MB terrain name imported with exit 0 and put that name in every table and page."""

MAX_LABEL_LINE_BYTES = 64 * 1024
"""One row of a label CSV: its names are at most ``MAX_NAME_CHARS`` each, its numbers a few dozen bytes; a longer
row is refused, naming it, before pandas reads the file (which gave "straddling object straddles two block
boundaries" for one of 50 MB)."""


def name_refusal(name: str, what: str, *, one_line: bool = True) -> str | None:
    """Why ``name`` may not be a ``what``'s name (``"terrain"``, ``"log"``...), or ``None`` when it may. With
    ``one_line``, a control character (a newline, an escape) is refused too: a terrain name is shown on one line of a
    terminal, a table and a page, and one holding a newline printed a fake line of output."""
    if len(name) > MAX_NAME_CHARS:
        return f"a {what} name of {len(name):,} characters; a name is at most {MAX_NAME_CHARS}"
    if one_line and (bad := next((ch for ch in name if ord(ch) < 0x20 or 0x7F <= ord(ch) < 0xA0), None)):
        return f"a {what} name holding the control character {bad!r}; a name is one line of text"
    return None
