"""Arrays to the paper family's training batches: pieces of long logs, padded batches with masks."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..normalizer import Normalizer, Rows


@dataclass(frozen=True)
class Piece:
    """Samples ``[start, stop)`` of sequence ``seq``; ``loss_from`` marks where the loss starts (after context)."""

    seq: int
    start: int
    stop: int
    loss_from: int
    label: int = -1

    @property
    def length(self) -> int:
        return self.stop - self.start


def cut_pieces(lengths: Sequence[int], piece: int) -> list[Piece]:
    """Cut sequences of the given lengths into consecutive pieces of at most ``piece`` samples."""
    out = []
    for seq, n in enumerate(lengths):
        for start in range(0, n, piece):
            stop = min(n, start + piece)
            if stop - start >= 2:
                out.append(Piece(seq, start, stop, start))
    return out


def stage1_batch(
    arrays: Sequence[Rows], pieces: Sequence[Piece], length: int, normalizer: Normalizer | None = None
) -> tuple[np.ndarray, ...]:
    """Inputs, next-sample targets and target mask for stage 1.

    Args:
        arrays: One ``(T, C)`` log each; anything sliced by rows (an array, a memory map, ``sessions.FileRows``).
            Only the rows of ``pieces`` are read.
        pieces: What goes into the batch.
        length: Padded length ``L``.
        normalizer: Applied to the rows read (None: the arrays are normalised already).

    Returns:
        ``x (B, L, C)``, ``y (B, L, C)`` with ``y[:, t] = x[:, t + 1]`` (continuing past the piece into its log),
        ``mask (B, L)`` true where a target exists.
    """
    c = arrays[0].shape[1]
    x = np.zeros((len(pieces), length, c), np.float32)
    y = np.zeros((len(pieces), length, c), np.float32)
    mask = np.zeros((len(pieces), length), bool)
    for i, p in enumerate(pieces):
        a = arrays[p.seq]
        rows = np.asarray(a[p.start : min(p.stop + 1, len(a))], np.float32)  # the piece and the sample after it
        if normalizer is not None:
            rows = normalizer(rows)
        n = p.length
        x[i, :n] = rows[:n]
        m = len(rows) - 1  # the log's last sample has no next one
        y[i, :m] = rows[1:]
        mask[i, :m] = True
    return x, y, mask


def labelled_pieces(segments: Sequence[tuple[int, int, int, int]], *, piece: int, context: int) -> list[Piece]:
    """Pieces for stage 2 from labelled segments ``(seq, start, stop, label)``.

    Each piece covers at most ``piece`` labelled samples and starts up to ``context`` samples earlier, so the
    classifier's state is warmed on whatever came before (no loss there), as it is on a whole log.
    """
    out = []
    for seq, start, stop, label in segments:
        for a in range(start, stop, piece):
            b = min(stop, a + piece)
            out.append(Piece(seq, max(0, a - context), b, a, label))
    return out


def stage2_batch(features: Sequence[np.ndarray], pieces: Sequence[Piece]) -> tuple[np.ndarray, ...]:
    """Features, per-step labels and loss mask for stage 2: ``f (B, L, F)``, ``labels (B, L)``, ``mask (B, L)``."""
    length = max(p.length for p in pieces)
    f_dim = features[0].shape[1]
    f = np.zeros((len(pieces), length, f_dim), np.float32)
    labels = np.full((len(pieces), length), -1, np.int64)
    mask = np.zeros((len(pieces), length), bool)
    for i, p in enumerate(pieces):
        f[i, : p.length] = features[p.seq][p.start : p.stop]
        a = p.loss_from - p.start
        labels[i, a : p.length] = p.label
        mask[i, a : p.length] = True
    return f, labels, mask


def neighbour_pairs(
    lengths: Sequence[int],
    *,
    window: int,
    gap: int,
    stride: int,
    boundaries: Sequence[np.ndarray] | None = None,
) -> list[tuple[Piece, Piece]]:
    """Pairs of unlabelled windows ``gap`` samples apart in one log, with no boundary between them.

    Terrain changes seldom within a few seconds, so the classifier should say the same at the last step of both
    windows (``fit_classifier``'s consistency term). A boundary (a change point) between those two steps drops the
    pair: across it the terrain may differ. A boundary earlier in the windows does not: what they compare is their
    last steps, and a classifier has to see past an old change anyway. (Requiring the whole span free left 12 pairs
    in 12 demo walks, whose signal change points come every 2.75 s; with this rule and a pair every 100 samples
    they hold 722, 2.1 % of them across a true terrain change.)

    Args:
        lengths: Samples in each log.
        window: Samples in each window.
        gap: Start of the second window minus start of the first.
        stride: Samples between the starts of consecutive pairs.
        boundaries: Per log, sorted sample indices where the terrain may change (None: none known).

    Returns:
        ``(first, second)`` pieces, unlabelled, in log order.
    """
    if window < 1 or gap < 1 or stride < 1:
        raise ValueError(f"window, gap and stride must be positive, got {window}, {gap}, {stride}")
    out = []
    for seq, n in enumerate(lengths):
        starts = np.arange(0, n - gap - window + 1, stride)  # (P,)
        if boundaries is not None and len(starts):
            b = np.sort(np.asarray(boundaries[seq], np.int64))
            # b starts a new stretch: it splits the pair when first's last step < b <= second's last step
            first = np.searchsorted(b, starts + window - 1, side="right")
            last = np.searchsorted(b, starts + gap + window - 1, side="right")
            starts = starts[last == first]
        out += [
            (Piece(seq, int(s), int(s) + window, int(s)), Piece(seq, int(s) + gap, int(s) + gap + window, int(s) + gap))
            for s in starts
        ]
    return out
