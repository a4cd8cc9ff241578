"""Names from the session (logs, terrains) as file names written beside it."""

from __future__ import annotations

import re

UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


def safe_file_name(name: str, *, empty: str = "_") -> str:
    """``name`` with every run of what a file system or a shell could misread (slashes, spaces, quotes) as ``_``,
    and no leading or trailing dot: ``"CONCRETE/imu 1"`` -> ``"CONCRETE_imu_1"``; ``empty`` when nothing is left."""
    return UNSAFE.sub("_", name).strip("._") or empty
