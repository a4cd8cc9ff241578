"""What a classifier version records of the labels it trained on, and how a quick fine-tune reads it back.

A from-scratch fit of the default family holds out blocks of labelled time (``training.figures.blocking``): a long
segment is cut into pieces that may sit in different folds. The version keeps every piece and its fold
(``labels.pieces``) so that a fine-tune keeps fold model ``m`` off fold ``m``'s pieces, old and new, and its figures
stay out-of-fold.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

from sessions import Segment
from training import ClassifierFit, cut_blocks

Piece = tuple[int, int, int]  # (index into the segments used, start, stop)


def labels_record(fit: ClassifierFit, used: Sequence[Segment], segments: Sequence[tuple[int, int, int, int]]) -> dict:
    """The ``labels`` entry of a version's config: the segments' ids, their newest change, and every piece's fold
    (a family whose fit cuts nothing: one piece per segment)."""
    pieces = fit.pieces or [(i, s[1], s[2]) for i, s in enumerate(segments)]
    fold_of = [-1] * len(pieces)
    for f, val in enumerate(fit.folds):
        for j in val:
            fold_of[j] = f
    return {
        "ids": [s.id for s in used],
        "as_of": max((s.updated_at for s in used), default=""),
        "pieces": [[used[i].id, a, b, f] for (i, a, b), f in zip(pieces, fold_of, strict=True)],
    }


def new_labels(used: Sequence[Segment], seen: dict | None) -> list[int] | None:
    """Indices into ``used`` of segments a version trained on ``seen`` (its recorded ids and newest change) did not
    see: added or changed since. ``None`` (train on all) when the version recorded nothing."""
    if not seen:
        return None
    ids, as_of = set(seen.get("ids", ())), seen.get("as_of", "")
    return [i for i, s in enumerate(used) if s.id not in ids or s.updated_at > as_of]


def recorded_pieces(
    used: Sequence[Segment],
    segments: Sequence[tuple[int, int, int, int]],
    seen: dict,
    fresh: set[int],
    block: int,
) -> tuple[list[Piece], list[int]] | None:
    """The pieces a fine-tune reads and the fold each had (``-1``: none yet), or ``None`` when the record does not
    add up (a segment it saw whose pieces do not tile it, a piece of a segment it never listed).

    A segment the version saw keeps its recorded pieces and folds; a version from before blocked folds recorded one
    fold per segment (``folds``), read as one piece each. A new or changed segment is cut as a fit from scratch
    cuts it.
    """
    ids = seen.get("ids") or []
    recorded: dict[int, list[tuple[int, int, int]]] = {}
    if isinstance(seen.get("pieces"), list):
        for seg_id, a, b, f in seen["pieces"]:
            recorded.setdefault(seg_id, []).append((a, b, f))
    elif isinstance(seen.get("folds"), list) and len(seen["folds"]) == len(ids):
        by_id = {s.id: s for s in used}
        recorded = {
            i: [(by_id[i].start, by_id[i].stop, f)] for i, f in zip(ids, seen["folds"], strict=True) if i in by_id
        }
    else:
        return None
    if not set(recorded) <= set(ids):
        return None
    pieces, known = [], []
    for i, s in enumerate(used):
        if i not in fresh:
            mine = sorted(recorded.get(s.id, ()))
            tiles = bool(mine) and mine[0][0] == s.start and mine[-1][1] == s.stop
            if not tiles or any(x[1] != y[0] for x, y in itertools.pairwise(mine)):
                return None
            pieces += [(i, a, b) for a, b, _ in mine]
            known += [f for _, _, f in mine]
        else:
            for piece in cut_blocks([segments[i]], block):
                pieces.append((i, piece.start, piece.stop))
                known.append(-1)
    return pieces, known
