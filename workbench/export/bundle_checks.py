"""The person's checks carried in an exported bundle (``checks.json``), so ``classify`` can set them beside its own
expectation on files far from the session (issue 65, item 4).

The counts are the session's at export: right of how many, over spot checks (the fair sample of the unlabelled
time), over the checks of suggestions and manual labels, and over all. ``classify`` reads them back as Wilson
estimates; a file whose expected accuracy lies outside the spot checks' interval by 10 points or more is warned of.
The file is optional (bundles exported before it have none); a damaged one is named in one line and left out.
"""

from __future__ import annotations

import json
from pathlib import Path

import labeling

from ..cycle import ChecksSummary

CHECKS_FILE = "checks.json"
MAX_CHECKS_BYTES = 64 << 10  # three pairs of counts: anything larger is not ours
KINDS = ("spot", "suggested", "all")


def write_checks(folder: Path, checks: ChecksSummary) -> Path | None:
    """Write ``checks``'s counts to ``folder/checks.json``; nothing when the person made no check."""
    counts = {k: [e.right, e.n] for k in KINDS if (e := getattr(checks, k)) is not None}
    if not counts:
        return None
    path = folder / CHECKS_FILE
    path.write_text(json.dumps({"schema": 1, **counts}) + "\n")
    return path


def read_checks(folder: Path) -> tuple[ChecksSummary | None, str | None]:
    """The checks a bundle carries, and a line saying why a damaged file was left out (``None`` when fine).

    Returns ``(None, None)`` for a bundle without the file.
    """
    path = folder / CHECKS_FILE
    try:
        if not path.exists():
            return None, None
        if not path.is_file():
            return None, f"{path}: not a regular file; your checks are left out"
        if path.stat().st_size > MAX_CHECKS_BYTES:
            return None, f"{path}: over {MAX_CHECKS_BYTES:,} bytes; your checks are left out"
        raw = json.loads(path.read_text())
        estimates = {}
        for kind in KINDS:
            pair = raw.get(kind)
            if pair is None:
                continue
            right, n = (int(x) for x in pair)
            if not 0 <= right <= n or n == 0:
                raise ValueError(f"{kind}: right on {right} of {n}")
            estimates[kind] = labeling.CheckEstimate(right, n, *labeling.wilson(right, n))
    except (OSError, ValueError, TypeError, AttributeError, RecursionError, OverflowError) as exc:
        return None, f"{path}: damaged ({type(exc).__name__}: {str(exc)[:200]}); your checks are left out"
    if not estimates:
        return None, None
    return ChecksSummary(estimates.get("spot"), estimates.get("suggested"), estimates.get("all")), None
