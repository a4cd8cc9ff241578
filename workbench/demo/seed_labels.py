"""Seed labels from reference truth, so a demo (or an evaluation) starts with a few labelled segments."""

from __future__ import annotations

import numpy as np

from sessions import Segment, Session


def seed_labels(
    session: Session, fraction: float, *, seed: int = 0, segment_s: float = 3.0, author: str = "demo"
) -> list[Segment]:
    """Label about ``fraction`` of all time with stretches of ``segment_s`` taken from the reference truth.

    Stretches sit inside reference segments (1 s away from their edges), terrains taken in turn so every terrain
    with reference truth gets labels. These are deliberate labels (source "seed"), never silent ones.
    """
    if fraction <= 0:
        return []
    rng = np.random.default_rng(seed)
    logs = session.logs()
    total = sum(x.n_samples for x in logs)
    candidates: dict[str, list[tuple[int, int, int]]] = {}
    for log in logs:
        margin = int(log.rate_hz)
        for start, stop, terrain in session.reference(log.id):
            if stop - start > 2 * margin + int(segment_s * log.rate_hz) // 2:
                candidates.setdefault(terrain, []).append((log.id, start + margin, stop - margin))
    known = {t.name for t in session.terrains()}
    terrains = sorted(t for t in candidates if t in known)
    added: list[Segment] = []
    labelled, turn, tries = 0, 0, 0
    while labelled < fraction * total and terrains and tries < 10_000:
        tries += 1
        terrain = terrains[turn % len(terrains)]
        turn += 1
        log_id, lo, hi = candidates[terrain][int(rng.integers(len(candidates[terrain])))]
        rate = session.log(log_id).rate_hz
        length = min(int(segment_s * rate), hi - lo)
        start = int(rng.integers(lo, hi - length + 1))
        if any(s.log_id == log_id and s.start < start + length and start < s.stop for s in added):
            continue
        added.append(session.add_segment(log_id, start, start + length, terrain, author=author, source="seed"))
        labelled += length
    return added
