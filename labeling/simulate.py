"""Label-efficiency simulation: an oracle answers each suggestion from the reference truth, the classifier retrains
after every batch, and accuracy on held-out data is recorded against labelled time.

The model is not here (``labeling`` has no torch): the caller passes a ``learner`` that retrains on the labels so far
and returns the pool's scores and the held-out accuracy.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .queue_policy import Evidence, QueuePolicy, Strategy
from .suggest import suggest
from .tracks import LogScores

Labelled = tuple[int, int, int, int]  # (log, start, stop, class)


@dataclass(frozen=True)
class Round:
    """What the learner reports after training on the labels so far."""

    scores: list[LogScores]  # per pool log
    accuracy: float  # on held-out data; NaN when nothing is trained yet
    macro_f1: float = float("nan")
    recall: np.ndarray | None = None  # (K,) each class's measured recall (NaN: unmeasured): the missed terrains


Learner = Callable[[Sequence[Labelled]], Round]


@dataclass(frozen=True)
class CurvePoint:
    labelled_samples: int
    accuracy: float
    macro_f1: float


def oracle(span: tuple[int, int, int], truth: Sequence[np.ndarray]) -> list[Labelled]:
    """Label ``(log, start, stop)`` from the truth as a careful person would: one label per terrain run inside it.

    Samples with unknown truth (``-1``) are left unlabelled.
    """
    log, a, b = span
    y = truth[log][a:b]
    edges = np.flatnonzero(np.diff(y)) + 1
    bounds = [0, *edges.tolist(), len(y)]
    return [(log, a + s, a + e, int(y[s])) for s, e in itertools.pairwise(bounds) if y[s] >= 0]


def stretch_oracle(span: tuple[int, int, int], truth: Sequence[np.ndarray], stretch: tuple[int, int]) -> list[Labelled]:
    """Label as a person who checks the model's stretch around a suggestion does (a range, or ``Y``): the suggested
    piece as :func:`oracle` labels it, then on from its edges across the stretch ``[start, stop)`` for as long as the
    truth stays the terrain at that edge. Time the stretch holds of another terrain stays unlabelled.
    """
    log, a, b = span
    y = truth[log]
    lo, hi = min(stretch[0], a), max(stretch[1], b)
    out = oracle(span, truth)
    if not out:
        return out
    first, last = out[0], out[-1]
    other = np.flatnonzero(y[lo : first[1]] != first[3])  # where the truth before the piece is another terrain
    left = lo + int(other[-1]) + 1 if len(other) else lo
    other = np.flatnonzero(y[last[2] : hi] != last[3])
    right = last[2] + int(other[0]) if len(other) else hi
    if len(out) == 1:
        return [(log, left, right, first[3])]
    return [(log, left, first[2], first[3]), *out[1:-1], (log, last[1], right, last[3])]


def simulate(
    learner: Learner,
    truth: Sequence[np.ndarray],
    *,
    strategy: Strategy,
    rounds: int,
    batch: int,
    classes: Sequence[str],
    change_points: Sequence[np.ndarray] | None = None,
    max_len: int = 500,
    min_len: int = 100,
    embeddings: Sequence[np.ndarray] | None = None,
    seed: int = 0,
    log: Callable[[str], None] | None = None,
) -> list[CurvePoint]:
    """Label ``batch`` suggestions per round for ``rounds`` rounds; the curve has one point per trained round.

    Args:
        learner: Retrains on the labels and reports scores and held-out accuracy.
        truth: Per pool log, ``(T,)`` class index per sample (``-1`` unknown).
        strategy: Which suggestion strategy picks the segments.
        rounds: Rounds of labelling (each followed by a retrain).
        batch: Suggestions labelled per round.
        classes: Class names.
        change_points: Per pool log, change points where candidates are cut.
        max_len: Longest suggestion, samples.
        min_len: Shortest suggestion, samples.
        embeddings: Per pool log, ``(T, D)`` features for the diversity of ``combined``.
        seed: Seed of the random strategy (varied per round).
        log: Where progress lines go.
    """
    labels: list[Labelled] = []
    spans: list[tuple[int, int, int]] = []
    state = learner(labels)
    curve = []
    for r in range(rounds):
        counts = np.bincount([c for *_, c in labels], [b - a for _, a, b, _ in labels], minlength=len(classes))
        picks = suggest(
            state.scores,
            Evidence(
                labelled=spans,
                label_counts=counts,
                change_points=change_points,
                classes=classes,
                embeddings=embeddings,
                recall=state.recall,
            ),
            policy=QueuePolicy(strategy=strategy, max_len=max_len, min_len=min_len, seed=seed * 1000 + r),
            n=batch,
        )
        if not picks:
            break
        for p in picks:
            spans.append((p.log, p.start, p.stop))
            labels += oracle((p.log, p.start, p.stop), truth)
        state = learner(labels)
        done = sum(b - a for _, a, b in spans)
        curve.append(CurvePoint(done, state.accuracy, state.macro_f1))
        if log:
            log(f"{strategy} seed {seed} round {r + 1}: {done} samples labelled, accuracy {state.accuracy:.2%}")
    return curve


def time_to_reach(curve: Sequence[CurvePoint], accuracy: float) -> float:
    """Labelled samples at which ``curve`` first reaches ``accuracy`` (linear between points); ``inf`` if never."""
    prev_x, prev_y = 0.0, -np.inf
    for p in curve:
        if p.accuracy >= accuracy:
            if not np.isfinite(prev_y) or p.accuracy == prev_y:
                return float(p.labelled_samples)
            return prev_x + (accuracy - prev_y) / (p.accuracy - prev_y) * (p.labelled_samples - prev_x)
        prev_x, prev_y = float(p.labelled_samples), p.accuracy
    return float("inf")


def mean_curve(curves: Sequence[Sequence[CurvePoint]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean labelled samples, mean and std of accuracy per round over seeds (rounds all seeds reached)."""
    n = min(len(c) for c in curves)
    x = np.array([[c[i].labelled_samples for i in range(n)] for c in curves], np.float64)
    y = np.array([[c[i].accuracy for i in range(n)] for c in curves], np.float64)
    return x.mean(0), y.mean(0), y.std(0)


def savings(curves: dict[str, Sequence[Sequence[CurvePoint]]], *, method: str, reference: str = "random") -> dict:
    """How much labelled time ``method`` needs to match ``reference`` at each of its rounds (seed means).

    Returns:
        ``{"rounds": [(reference samples, reference accuracy, method samples, ratio)], "final_ratio": ...}`` where the
        ratio is method time over reference time to reach the same accuracy (0.5: half as much labelling).
    """
    rx, ry, _ = mean_curve(curves[reference])
    mx, my, _ = mean_curve(curves[method])
    pts = [CurvePoint(int(x), float(y), float("nan")) for x, y in zip(mx, my, strict=True)]
    rows = []
    for x, y in zip(rx, ry, strict=True):
        t = time_to_reach(pts, float(y))
        rows.append((float(x), float(y), t, t / x))
    return {"rounds": rows, "final_ratio": rows[-1][3] if rows else float("nan")}


def bootstrap_final_ratio(
    curves: dict[str, Sequence[Sequence[CurvePoint]]],
    *,
    method: str,
    reference: str = "random",
    draws: int = 2000,
    seed: int = 0,
) -> np.ndarray:
    """``(draws,)`` final ratios of :func:`savings` over seeds resampled with replacement (``inf``: never reached).

    Seeds are resampled in pairs: seed ``i`` of ``method`` goes with seed ``i`` of ``reference``, because a seed fixes
    what both strategies share (pool, held-out data, fold). With a handful of seeds and single fits that swing by
    several points, the mean ratio alone says little; its spread says how far to trust it.
    """
    n = min(len(curves[method]), len(curves[reference]))
    rng = np.random.default_rng(seed)
    out = np.empty(draws)
    for d in range(draws):
        idx = rng.integers(0, n, n)
        pick = {k: [curves[k][i] for i in idx] for k in (reference, method)}
        out[d] = savings(pick, method=method, reference=reference)["final_ratio"]
    return out


def table(curves: dict[str, Sequence[Sequence[CurvePoint]]], *, total_samples: int, rate_hz: float) -> str:
    """Markdown: labelled time (s and % of all time) and mean ± std accuracy per round, one column per strategy."""
    names = list(curves)
    means = {k: mean_curve(v) for k, v in curves.items()}
    rounds = min(len(m[0]) for m in means.values())
    head = "| round | " + " | ".join(f"{k}: labelled s (%) | {k}: accuracy (%)" for k in names) + " |"
    lines = [head, "| --- |" + " --- | --- |" * len(names)]
    for r in range(rounds):
        cells = []
        for k in names:
            x, y, sd = means[k]
            share = 100 * x[r] / total_samples
            cells.append(f"{x[r] / rate_hz:.0f} ({share:.2f}) | {100 * y[r]:.2f} ± {100 * sd[r]:.2f}")
        lines.append(f"| {r + 1} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
