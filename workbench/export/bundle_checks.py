"""The person's checks carried in an exported bundle (``checks.json``), so ``classify`` can set them beside its own
expectation on files far from the session.

The counts are the session's at export: right of how many, over spot checks (the fair sample of the unlabelled
time), over the checks of suggestions and manual labels, and over all. ``classify`` reads them back as Wilson
estimates; a file whose expected accuracy lies outside the spot checks' interval by 10 points or more is warned of.
Per run (``runs``: the session's log names), its counted checks too: ``classify`` of a file of that name says them
beside what it expects there (a run the person found the model mostly wrong on must not read 80 % alone).
The file is optional (bundles exported before it have none); a damaged one is named in one line and left out.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import labeling

from ..cycle import ChecksSummary

CHECKS_FILE = "checks.json"
MAX_CHECKS_BYTES = 4 << 20  # three pairs of counts and one per run checked (a fleet's 10,000 runs: 0.5 MB)
KINDS = ("spot", "suggested", "all")


def write_checks(folder: Path, checks: ChecksSummary, *, names: Mapping[int, str] | None = None) -> Path | None:
    """Write ``checks``'s counts to ``folder/checks.json``, each checked log's under its name in ``names`` (log id
    to name); nothing when the person made no check."""
    counts: dict = {k: [e.right, e.n] for k in KINDS if (e := getattr(checks, k)) is not None}
    if not counts:
        return None
    runs = {names[i]: [e.right, e.n] for i, e in checks.per_log.items() if names and i in names}
    path = folder / CHECKS_FILE
    path.write_text(json.dumps({"schema": 1, **counts, **({"runs": runs} if runs else {})}) + "\n")
    return path


def _estimate(pair, what: str) -> labeling.CheckEstimate:
    right, n = (int(x) for x in pair)
    if not 0 <= right <= n or n == 0:
        raise ValueError(f"{what}: right on {right} of {n}")
    return labeling.CheckEstimate(right, n, *labeling.wilson(right, n))


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
        estimates = {kind: _estimate(raw[kind], kind) for kind in KINDS if raw.get(kind) is not None}
        runs = {str(name): _estimate(pair, str(name)) for name, pair in (raw.get("runs") or {}).items()}
    except (OSError, ValueError, TypeError, AttributeError, RecursionError, OverflowError) as exc:
        return None, f"{path}: damaged ({type(exc).__name__}: {str(exc)[:200]}); your checks are left out"
    if not estimates:
        return None, None
    return ChecksSummary(estimates.get("spot"), estimates.get("suggested"), estimates.get("all"), per_run=runs), None
