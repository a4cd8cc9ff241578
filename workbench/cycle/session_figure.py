"""How right the session is now: the active classifier's accuracy over the time nobody labelled, from the person's
uniform checks of that very version, corrected by its confidence there (``labeling.powered_accuracy``).

A check tests the model that was active when it was made (test then train): after a Retrain the older checks test
an older model, so the figure says "not checked since the last Retrain" until the person verifies the new one
(``workbench suggest --verify``, the page's Verify). Only spot checks count: they are drawn uniformly from the time
nobody labelled; a ranked suggestion is where the model was doubted (it would read low), a main answer where it was
sure (high). The time the figure speaks for is the time nobody labelled when the version was scored: the time still
unlabelled and the pieces its own checks labelled since.

The fit's own figures (held-out labelled time, its runs held out) describe other things: the labelled pieces, chosen
where the model was unsure, and the model that ships on a run it never saw. They are shown beside this one, named.
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Collection, Sequence
from dataclasses import dataclass, field

import numpy as np

import labeling
from sessions import Check, Session

from .scores import SessionScores

DEFAULT_WIDTH = 0.10  # the interval's width a verification aims for: ±5 points


@dataclass(frozen=True)
class SessionFigure:
    """The session's (or one run's) accuracy as far as the checks of the active classifier say.

    Attributes:
        version: The classifier judged (``None``: no classifier).
        figure: From this version's spot checks (``None``: none yet).
        earlier: The last earlier version with spot checks and what they said (``None``: none).
        confidence: The model's mean confidence over the time the figure speaks for (its own guess, not a test).
        steps: How many steps that time holds.
    """

    version: int | None
    figure: labeling.PoweredAccuracy | None
    earlier: tuple[int, labeling.CheckEstimate] | None = None
    confidence: float | None = None
    steps: int = 0

    def short(self) -> str:
        """``"≈ 97 % (93–99)"``, ``"not checked"``: a table's cell."""
        f = self.figure
        if f is None:
            return "not checked"
        return f"≈ {100 * f.accuracy:.0f} % ({100 * f.low:.0f}–{100 * f.high:.0f})"

    def words(self) -> str:
        """``"≈ 97 % (90 % interval 93–99 %, from 24 checks of this version)"``, or what stands instead."""
        f = self.figure
        if f is not None:
            return (
                f"≈ {100 * f.accuracy:.0f} % (90 % interval {100 * f.low:.0f}–{100 * f.high:.0f} %, from "
                f"{f.checks} check{'s' if f.checks != 1 else ''} of this version)"
            )
        if self.earlier is not None:
            v, e = self.earlier
            return f"not checked since the last Retrain (v{v}: right on {e.right} of {e.n} spot checks)"
        return "not checked yet"

    @property
    def width(self) -> float | None:
        """The interval's width (``None`` without one)."""
        return None if self.figure is None else self.figure.high - self.figure.low

    def plan(self, *, width: float = DEFAULT_WIDTH) -> int:
        """How many more uniform checks would bring the interval to ``width`` (0 when it is there already): at the
        estimate so far, else at the model's own mean confidence; each check counted as this version's checks
        counted so far (``effective / checks``)."""
        f = self.figure
        expected = f.accuracy if f is not None else (self.confidence if self.confidence is not None else 0.5)
        gain = f.effective / f.checks if f is not None and f.checks else 1.0
        need = labeling.checks_needed(expected, width, gain=gain)
        return max(0, need - (f.checks if f is not None else 0))

    def plan_words(self, *, width: float = DEFAULT_WIDTH) -> str:
        """``"26 checks would bring it to ±5 points"``, or that it is there already."""
        more = self.plan(width=width)
        half = f"±{100 * width / 2:g} points"
        if self.figure is not None and more == 0:
            return f"within {half} already"
        if more > labeling.MOST_CHECKS:
            return f"over {labeling.MOST_CHECKS} checks would be needed for {half}"
        again = " more" if self.figure is not None else ""
        return f"{more}{again} check{'s' if more != 1 else ''} would bring it to {half}"


@dataclass(frozen=True)
class SessionFigures:
    """The session's figure and each run's (``per_log``: every scored log, checked or not)."""

    session: SessionFigure
    per_log: dict[int, SessionFigure] = field(default_factory=dict)


class FigureTally:
    """The figures summed a log at a time, for a pass that never holds every log's scores (the export's).

    ``add`` each log's probabilities under ``version``; ``figures`` then gives the same as :func:`session_figures`
    over those logs. ``checks``: these instead of the session's (an evaluation's checks, never recorded).
    """

    def __init__(self, session: Session, version: int, *, checks: Sequence[Check] | None = None) -> None:
        self.version = version
        self.checks = list(session.checks() if checks is None else checks)
        self._mine = _spot(self.checks, version)
        self._spans: dict[int, list[tuple[int, int]]] = {}
        for g in session.segments():
            self._spans.setdefault(g.log_id, []).append((g.start, g.stop))
        self._parts: dict[int, tuple[labeling.Moments, list[float], list[float]]] = {}

    def add(self, log_id: int, probs: np.ndarray) -> None:
        """Take one log's ``(T, K)`` probabilities from the version judged."""
        top = np.asarray(probs).max(axis=1)  # (T,) the model's confidence
        keep = np.ones(len(top), bool)  # (T,) the time the figure speaks for
        for a, b in self._spans.get(log_id, ()):
            keep[a:b] = False
        here = [c for c in self._mine if c.log_id == log_id and c.stop <= len(top)]
        for c in here:
            keep[c.start : c.stop] = True  # labelled by this version's own checks: it was unlabelled then
        y = [c.agreement for c in here]  # the share of each piece named right
        f = [float(top[c.start : c.stop].mean()) for c in here]  # the model's confidence on each piece
        self._parts[log_id] = (labeling.Moments.of(top[keep]), y, f)

    def _one(self, ids: list[int]) -> SessionFigure:
        parts = [self._parts[i] for i in ids]
        g = labeling.Moments.pooled([p[0] for p in parts])
        y = np.array([v for p in parts for v in p[1]], np.float64)
        f = np.array([v for p in parts for v in p[2]], np.float64)
        figure = labeling.powered_accuracy(y, f, g) if len(y) else None
        past = _earlier([c for c in self.checks if c.log_id in ids], self.version)
        return SessionFigure(self.version, figure, past, g.mean if g.n else None, g.n)

    def figures(self) -> SessionFigures:
        """The session's figure over the logs added, and each one's."""
        ids = list(self._parts)
        return SessionFigures(self._one(ids), {i: self._one([i]) for i in ids})


# the last figures and what they were computed from (the scores held weakly: a rescoring frees the old ones)
_KEPT: list[tuple[weakref.ref[SessionScores], tuple, SessionFigures]] = []
_KEPT_LOCK = threading.Lock()


def _spot(checks: list[Check], version: int) -> list[Check]:
    return [c for c in checks if c.kind == "spot check" and c.classifier == version]


def _earlier(checks: list[Check], version: int) -> tuple[int, labeling.CheckEstimate] | None:
    older = [c for c in checks if c.kind == "spot check" and c.classifier != version]
    if not older:
        return None
    last = max(c.classifier for c in older)
    est = labeling.check_estimate([c.right for c in older if c.classifier == last])
    return None if est is None else (last, est)


def session_figures(
    session: Session, scores: SessionScores, *, log_ids: Collection[int] | None = None
) -> SessionFigures:
    """The active classifier's accuracy over the time nobody labelled, for the session (the logs ``log_ids``, when
    given) and per log, from its spot checks and its confidence (``labeling.powered_accuracy``).

    The figures are of ``scores``' classifier version. Kept per scores object, labels and checks: the status line
    asks twice a second.
    """
    version = scores.classifier
    if version is None:
        return SessionFigures(SessionFigure(None, None))
    segments = session.segments()
    checks = session.checks()
    key = (  # what the figures read: the labels' spans, the spot checks' answers (a check made again updates its row)
        version,
        None if log_ids is None else tuple(sorted(log_ids)),
        hash(tuple((g.id, g.log_id, g.start, g.stop) for g in segments)),
        tuple((c.id, c.agreement, c.classifier) for c in checks if c.kind == "spot check"),
    )
    with _KEPT_LOCK:
        kept = next((k for k in _KEPT if k[0]() is scores and k[1] == key), None)
    if kept is not None:
        return kept[2]
    tally = FigureTally(session, version)
    for i, s in scores.scores.items():
        if s.probs is not None and (log_ids is None or i in log_ids):
            tally.add(i, s.probs)
    got = tally.figures()
    with _KEPT_LOCK:
        _KEPT[:] = [(weakref.ref(scores), key, got)]
    return got
