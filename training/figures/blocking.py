"""Folds over labelled time that hold out contiguous blocks, with a guard gap no model input crosses.

Folds over whole segments break in the commonest way people record terrain: labels as whole runs, one run per
terrain. A fold then holds out a terrain's only segment, and its model cannot know that terrain (a card said 17 % for
a model that scored 65-78 % on new runs). Here every segment longer than two blocks is cut into blocks first; each
terrain's pieces, in time order, are dealt to the folds in contiguous runs (fold ``i * k // n`` of ``n`` pieces), so
every fold holds about ``1/k`` of every terrain and a fold's held-out time is one stretch per log where it can be.
A fold's training pieces are trimmed by ``guard`` samples around its held-out pieces of the same log: with ``guard``
at least the model's input span, no training step reads an input a held-out step reads.

Figures from these folds are same-run figures: the held-out blocks share their run's surface, speed and mounting
with the training blocks. Held-out logs measure new runs (:func:`log_folds`: folds holding out whole recordings,
the fits' extra figure); the estimate says which one it reports.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..fitting import Segment


@dataclass(frozen=True)
class Block:
    """A block of one labelled segment (a whole segment when it is short).

    Attributes:
        segment: Index of its segment in the list the folds were drawn from.
        log: Log index.
        start: First sample.
        stop: One past the last sample.
        label: Class index.
    """

    segment: int
    log: int
    start: int
    stop: int
    label: int

    @property
    def as_segment(self) -> Segment:
        """``(log, start, stop, class)``, as the fits read segments."""
        return self.log, self.start, self.stop, self.label


def cut_blocks(segments: Sequence[Segment], block: int) -> list[Block]:
    """Every segment as pieces: one of at least two ``block`` lengths is cut into ``length // block`` equal blocks
    (the remainder spread over them); a shorter one stays whole."""
    if block < 1:
        raise ValueError(f"block must be at least 1 sample, got {block}")
    pieces = []
    for i, (log, start, stop, label) in enumerate(segments):
        n = (stop - start) // block if stop - start >= 2 * block else 1
        edges = np.linspace(start, stop, n + 1).round().astype(np.int64)
        pieces += [Block(i, log, int(a), int(b), label) for a, b in itertools.pairwise(edges)]
    return pieces


def deal_blocks(pieces: Sequence[Block], k: int) -> list[int]:
    """The fold of each piece: a terrain's ``n`` pieces in time order (log, then start) go to folds ``i * k // n``,
    turned by the offset that leaves the folds most even (a terrain with fewer pieces than folds starts at the
    emptiest); folds left empty are dropped, so the result numbers ``0 .. k' - 1``."""
    folds = [0] * len(pieces)
    by_label: dict[int, list[int]] = {}
    for j, p in enumerate(pieces):
        by_label.setdefault(p.label, []).append(j)
    size = np.zeros(k, np.int64)
    for label in sorted(by_label, key=lambda c: (-len(by_label[c]), c)):
        members = sorted(by_label[label], key=lambda j: (pieces[j].log, pieces[j].start))
        base = np.arange(len(members)) * k // len(members)
        offset = min(range(k), key=lambda o: (int(size[(base + o) % k].sum()), o))
        for j, f in zip(members, (base + offset) % k, strict=True):
            folds[j] = int(f)
            size[f] += 1
    used = {f: i for i, f in enumerate(sorted(set(folds)))}
    return [used[f] for f in folds]


@dataclass(frozen=True)
class BlockedFolds:
    """Pieces of labelled time, the fold of each, and the guard between a fold's held-out and training time.

    Attributes:
        pieces: The segments cut into blocks.
        fold_of: Fold of each piece.
        k: Number of folds.
        guard: Samples of training time dropped either side of a held-out piece of the same log.
    """

    pieces: tuple[Block, ...]
    fold_of: tuple[int, ...]
    k: int
    guard: int

    def held_out(self, fold: int) -> list[int]:
        """Indices of the pieces fold ``fold`` holds out."""
        return [j for j, f in enumerate(self.fold_of) if f == fold]

    def training(self, fold: int) -> list[Segment]:
        """Fold ``fold``'s training time: the other folds' pieces, less ``guard`` samples around each held-out piece
        of the same log (a piece may split in two or vanish)."""
        cuts: dict[int, list[tuple[int, int]]] = {}
        for j in self.held_out(fold):
            p = self.pieces[j]
            cuts.setdefault(p.log, []).append((p.start - self.guard, p.stop + self.guard))
        out = []
        for p, f in zip(self.pieces, self.fold_of, strict=True):
            if f == fold:
                continue
            spans = [(p.start, p.stop)]
            for a, b in cuts.get(p.log, ()):
                spans = [piece for s, e in spans for piece in ((s, min(e, a)), (max(s, b), e)) if piece[1] > piece[0]]
            out += [(p.log, s, e, p.label) for s, e in spans]
        return out


def blocked_folds(segments: Sequence[Segment], k: int, *, block: int, guard: int) -> BlockedFolds:
    """Folds of contiguous blocks of labelled time.

    Args:
        segments: Labelled stretches ``(log index, start, stop, class index)``.
        k: Folds (fewer when there are fewer pieces).
        block: Samples per block; segments shorter than two blocks stay whole.
        guard: Samples of training time dropped around each held-out piece: at least the model's input span.

    Returns:
        The pieces and their folds.
    """
    pieces = cut_blocks(segments, block)
    folds = deal_blocks(pieces, max(1, min(k, len(pieces))))
    return BlockedFolds(tuple(pieces), tuple(folds), max(folds) + 1, guard)


LOG_FOLD_DRAWS = 20  # shuffles of the folds over logs tried; the one that measures the most labelled time is kept


def log_folds(segments: Sequence[Segment], k: int, groups: Sequence[int]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Folds over segments that hold out whole recordings (``groups[log]``, at most ``k`` folds), terrains spread
    over them as evenly as whole recordings allow; none when fewer than two are labelled or a fold's training part
    would hold one terrain only.

    scikit-learn's stratified group folds can hold out every recording of a terrain at once (six logs, two per
    terrain, three folds: each fold held out one terrain's pair, and nothing was measured), so ``LOG_FOLD_DRAWS`` of
    its shuffles and as many dealings of each terrain's recordings to the folds in turn are tried, and the one whose
    held-out segments' terrains stay most in training, by labelled time, is kept.
    """
    # imported where used: scikit-learn and SciPy add 2 s to every CLI start, and classify, export and serve never fit
    from sklearn.model_selection import GroupKFold, StratifiedGroupKFold

    logs = np.asarray([groups[s[0]] for s in segments])
    n_logs = len(np.unique(logs))
    if n_logs < 2:
        return []
    labels = np.asarray([s[3] for s in segments])
    length = np.asarray([s[2] - s[1] for s in segments])

    def measured(folds: list[tuple[np.ndarray, np.ndarray]]) -> int:
        return sum(int(length[va][np.isin(labels[va], labels[tr])].sum()) for tr, va in folds)

    def dealt(seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """Recordings ordered by their main terrain (shuffled within it) and dealt to the folds in turn: a
        terrain's recordings land in different folds."""
        rng = np.random.default_rng(seed)
        ids = np.unique(logs)
        main = [np.bincount(labels[logs == g], weights=length[logs == g]).argmax() for g in ids]
        order = ids[np.lexsort((rng.random(len(ids)), main))]
        fold_of = {int(g): i % min(k, n_logs) for i, g in enumerate(order)}
        which = np.asarray([fold_of[int(g)] for g in logs])
        return [(np.flatnonzero(which != f), np.flatnonzero(which == f)) for f in range(min(k, n_logs))]

    candidates = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "least populated class has only N members"
        for draw in range(LOG_FOLD_DRAWS):
            try:
                splitter = StratifiedGroupKFold(min(k, n_logs), shuffle=True, random_state=draw)
                candidates.append(list(splitter.split(logs, labels, groups=logs)))
            except ValueError:  # every terrain has fewer segments than folds: whole logs, unstratified
                candidates.append(list(GroupKFold(min(k, n_logs)).split(logs, groups=logs)))
            candidates.append(dealt(draw))
    best: list[tuple[np.ndarray, np.ndarray]] = []
    for folds in candidates:
        if any(len(set(labels[tr].tolist())) < 2 for tr, _ in folds):
            continue
        if not best or measured(folds) > measured(best):
            best = folds
    return best
