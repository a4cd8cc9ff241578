"""What reaches a terminal from a file is text, never a command to it.

A log, topic or terrain name comes from someone else's file: ``\\x1b]0;owned\\x07`` set the terminal's title,
``\\x1b[2J`` cleared the screen, and a newline printed a fake ``ingested 5 log(s)`` line. :func:`shown` writes every
character a terminal would act on as its escape (``\\x1b``, ``\\n``, ``\\u202e``), as ``repr`` does; the CLI prints
names through it, and :class:`EscapingStream` guards the rest of what it writes to standard output.
"""

from __future__ import annotations

import unicodedata
from typing import TextIO

_KEEP_IN_STREAM = "\n\t"  # the CLI's own line breaks and tables


def _escape(ch: str) -> str:
    code = ord(ch)
    if ch == "\n":
        return "\\n"
    if ch == "\t":
        return "\\t"
    if ch == "\r":
        return "\\r"
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def _acts(ch: str) -> bool:
    """Whether a terminal would act on ``ch`` rather than show it: controls, and format characters (bidi overrides
    reorder what follows them)."""
    return unicodedata.category(ch) in ("Cc", "Cf", "Zl", "Zp")


def shown(text: object) -> str:
    """``text`` with every character a terminal acts on (newlines included) written as its escape: one line."""
    s = str(text)
    if s.isprintable():
        return s
    return "".join(_escape(ch) if _acts(ch) else ch for ch in s)


class EscapingStream:
    """A text stream that writes every control character but newline and tab as its escape."""

    def __init__(self, inner: TextIO) -> None:
        self._inner = inner

    def write(self, text: str) -> int:
        if not text.isprintable():
            text = "".join(_escape(ch) if _acts(ch) and ch not in _KEEP_IN_STREAM else ch for ch in text)
        return self._inner.write(text)

    def __getattr__(self, name: str) -> object:
        return getattr(self._inner, name)
