"""State every browser shares: the session, the active models' scores, change points, the suggestion queue and the
training job. Views subscribe to its events and redraw; nothing here knows about viser.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable, Collection
from dataclasses import dataclass, replace

import numpy as np

import labeling
from sessions import LogInfo, Segment, Session, Terrain, WorkbenchError

from ..cycle import (
    QUEUE_MODES,
    SESSION_POLICY,
    VERIFY,
    SessionScores,
    compute_scores,
    keep_answers,
    keep_change_points,
    kept_change_points,
    log_change_points,
    queue_key,
    record_check,
    score_and_store,
    store_queue,
    stored_queue,
    stored_scores,
    suggest_for_session,
    verification_queue,
)
from ..user_errors import USER_ERRORS, one_line
from .events import Event, Events, Listener
from .torch_lane import LANE


@dataclass(frozen=True)
class Queued:
    """One suggestion of the shared queue, located by log id and seconds."""

    key: tuple[int, int, int]  # (log id, start, stop): stable across recomputations
    log: LogInfo
    start: int
    stop: int
    reason: str
    guess: str | None
    score: float
    kind: str = "suggestion"  # or "spot check" (labeling.Suggestion.kind)

    @property
    def seconds(self) -> tuple[float, float]:
        return self.start / self.log.rate_hz, self.stop / self.log.rate_hz


# The model track and its review show stretches, not steps: probabilities smoothed over a second, and runs shorter
# than two seconds merged into a neighbour (the model's frames flicker at 0.2 s; a person judges stretches).
STRETCH_WINDOW_S = 1.0
STRETCH_MIN_S = 2.0
SNAP_CONTEXT_S = 10  # seconds of signal either side of a range that its snap looks at before the log's are known


class SharedState:
    """The session and what is derived from it, safe to use from viser's callback threads and the job thread."""

    def __init__(self, session: Session, *, on_error: Callable[[str], None] | None = None) -> None:
        self.session = session
        self._lock = threading.RLock()
        self._logs: list[LogInfo] = session.logs()
        self._terrains: list[Terrain] = session.terrains()
        self.scores = SessionScores()
        self.scored = False  # the first scoring has finished
        self._change_points: dict[tuple[int, int | None], np.ndarray] = {}
        self.queue: list[Queued] = []
        self.strategy: str = "combined"  # shared: everyone works from one queue (a ranking, or "verify")
        self._dirty = threading.Event()
        self._scores_wanted = True
        self._first: set[int] = set()  # logs to score before the rest (on screen when a retrain finished)
        self._viewed: dict[str, int] = {}  # view -> the log it shows
        self._stop = threading.Event()
        self._on_error = on_error or (lambda msg: print(msg, flush=True))
        self.busy = ""  # what the worker is doing, for the status line
        # a Retrain's quick phase is training: a queue ranked now would be ranked again from its scores in seconds,
        # and would take a core from it (100 h of logs: 24 s of ranking beside the fine-tune)
        self.hold_queue = False
        self.problem = ""  # why the last refresh failed (one line), shown in every page until one succeeds
        self._stretches: tuple[SessionScores, dict[int, list[labeling.PredictedStretch]]] = (self.scores, {})
        self._queue_of: tuple[SessionScores, str] | None = None  # what the queue was ranked from: (scores, key)
        self._events = Events(on_error=self._on_error)
        self._worker = threading.Thread(target=self._work, name="workbench-refresh", daemon=True)
        self._dirty.set()
        self._worker.start()

    # --------------------------------------------------------------------------------------------- events
    def subscribe(self, fn: Listener) -> Callable[[], None]:
        """Call ``fn(event)`` for every event from now on; returns what unsubscribes it."""
        return self._events.subscribe(fn)

    def notify(self, event: Event) -> None:
        """Tell every view that ``event`` happened; returns at once (``events.Events.notify``)."""
        self._events.notify(event)

    def flush(self, *, timeout: float = 30.0) -> bool:
        """Wait until every event notified so far has been delivered; False on timeout."""
        return self._events.flush(timeout=timeout)

    def request_stop(self) -> None:
        """Ask the refresh worker to stop at its next poll (between two groups of logs) and the views to be sent
        nothing more: a page whose connection is closing is not written to."""
        self._stop.set()
        self._dirty.set()
        self._events.stop()

    def stop(self, *, timeout: float = 30.0) -> None:
        """Stop the refresh worker, waiting for a scoring in progress so the session can close under it."""
        self.request_stop()
        if self._worker is not threading.current_thread():
            self._worker.join(timeout)
        self._events.stop(wait=timeout)

    # ----------------------------------------------------------------------------------------------- data
    def logs(self) -> list[LogInfo]:
        with self._lock:
            return list(self._logs)

    def log(self, log_id: int) -> LogInfo:
        for x in self.logs():
            if x.id == log_id:
                return x
        raise WorkbenchError(f"no log {log_id} in {self.session.path}")

    def terrains(self) -> list[Terrain]:
        with self._lock:
            return list(self._terrains)

    def logs_changed(self) -> None:
        """Logs were added (upload, CLI ingest): reload the catalog and rescore."""
        with self._lock:
            self._logs = self.session.logs()
            self._terrains = self.session.terrains()
        self.notify("logs")
        self.refresh(scores=True)

    def change_terrains(self, action: str, name: str, new: str = "") -> None:
        """Add (``name``), rename (``name`` to ``new``) or remove (``name``, refused while labels use it) a terrain;
        every view hears of it as a label change."""
        if action == "add":
            self.session.add_terrain(name)
        elif action == "rename":
            self.session.rename_terrain(name, new)
        elif action == "remove":
            self.session.remove_terrain(name)
        else:
            raise ValueError(f"unknown terrain action {action!r}")
        with self._lock:
            self._terrains = self.session.terrains()
        self._labels_changed()

    # --------------------------------------------------------------------------------------------- labels
    def add_label(
        self, log_id: int, start: int, stop: int, terrain: str, *, author: str, source: str, check: bool = True
    ) -> Segment:
        """Commit a label (it is saved when this returns); every view hears of it. The part of it that was
        unlabelled is first a check of the model on screen (test then train: ``cycle.record_check``): a suggestion's
        or spot check's when the range is one of the queue's, a manual one otherwise. ``check=False`` keeps no
        check (the person saw another version's answer than the one on screen)."""
        scores = self.scores
        fresh = labeling.uncovered(start, stop, [(g.start, g.stop) for g in self.session.segments(log_id)])
        seg = self.session.add_segment(log_id, start, stop, terrain, author=author, source=source)
        if check:
            self._check(scores, log_id, fresh, terrain, kind=self._queued_kind(log_id, start, stop), author=author)
        self._labels_changed()
        return seg

    def _queued_kind(self, log_id: int, start: int, stop: int) -> str:
        """``"suggestion"`` or ``"spot check"`` when ``[start, stop)`` overlaps one of the queue's; else manual."""
        with self._lock:
            queue = list(self.queue)
        hit = next((q for q in queue if q.log.id == log_id and q.start < stop and start < q.stop), None)
        return "manual" if hit is None else hit.kind

    def _check(
        self, scores: SessionScores, log_id: int, pieces: list[tuple[int, int]], terrain: str, *, kind: str, author: str
    ) -> None:
        """Keep the checks of a label just saved; one that cannot be kept (a full disk) costs the estimate a check,
        never the label."""
        for a, b in pieces:
            try:
                record_check(self.session, scores, log_id, a, b, terrain, kind=kind, author=author)
            except USER_ERRORS as exc:
                self._on_error(f"a check of the model was not kept: {one_line(exc)}")

    def add_labels(
        self, log_id: int, ranges: list[tuple[int, int]], terrain: str, *, author: str, source: str
    ) -> list[Segment]:
        """Commit several ranges of one terrain as one action (one undo reverts them); every view hears of it."""
        scores = self.scores
        taken = [(g.start, g.stop) for g in self.session.segments(log_id)]
        fresh = [p for a, b in ranges for p in labeling.uncovered(a, b, taken)]
        segs = self.session.add_segments(log_id, ranges, terrain, author=author, source=source)
        # the model's own stretch accepted: kept as a "stretch" check, which no estimate counts
        self._check(scores, log_id, fresh, terrain, kind="stretch" if source == "accepted" else "manual", author=author)
        self._labels_changed()
        return segs

    def stretches(self, log_id: int) -> list[labeling.PredictedStretch]:
        """The model's predicted stretches of a log (none before a classifier), computed once per scoring."""
        scores = self.scores
        with self._lock:
            if self._stretches[0] is not scores:
                self._stretches = (scores, {})
            found = self._stretches[1].get(log_id)
        if found is not None:
            return found
        s = scores.scores.get(log_id)
        if s is None or s.probs is None:
            return []
        rate = self.log(log_id).rate_hz
        found = labeling.predicted_stretches(
            s.probs, window=max(1, round(STRETCH_WINDOW_S * rate)), min_len=max(1, round(STRETCH_MIN_S * rate))
        )
        with self._lock:
            if self._stretches[0] is scores:
                self._stretches[1][log_id] = found
        return found

    def change_label(self, segment_id: int, *, author: str, **changes: object) -> Segment:
        seg = self.session.change_segment(segment_id, author=author, **changes)  # type: ignore[arg-type]
        self._labels_changed()
        return seg

    def delete_label(self, segment_id: int, *, author: str) -> Segment:
        seg = self.session.delete_segment(segment_id, author=author)
        self._labels_changed()
        return seg

    def undo(self, *, author: str) -> str:
        entry = self.session.undo(author=author)
        self._labels_changed()
        return entry.kind

    def _labels_changed(self) -> None:
        self.notify("labels")
        self.refresh(scores=False)

    # ------------------------------------------------------------------------------------ derived, refreshed
    def refresh(self, *, scores: bool, first: Collection[int] = ()) -> None:
        """Recompute the suggestion queue (and the scores first when ``scores``) in the background.

        Args:
            scores: Rescore the logs (new models) before the queue.
            first: Logs to rescore and show before the others: the ones on screen, so their highlights refresh
                in a fraction of a full rescore.
        """
        if scores:
            with self._lock:
                self._first |= set(first)
            self._scores_wanted = True
        self._dirty.set()

    def set_viewed(self, view: str, log_id: int | None) -> None:
        """Which log a view shows (``None``: it left); those logs are rescored first after a retrain."""
        with self._lock:
            if log_id is None:
                self._viewed.pop(view, None)
            else:
                self._viewed[view] = log_id

    def wait_idle(self, *, stop: Callable[[], bool], poll_s: float = 0.2, deadline_s: float | None = None) -> bool:
        """Block until no rescore or queue update is pending or running; False when ``stop()`` said to give up or
        ``deadline_s`` passed."""
        quiet = 0
        end = None if deadline_s is None else time.monotonic() + deadline_s
        while quiet < 2:  # twice in a row: the worker clears its flag a moment before it says it is busy
            if stop() or self._stop.is_set() or (end is not None and time.monotonic() > end):
                return False
            time.sleep(poll_s)
            quiet = quiet + 1 if not (self.busy or self._dirty.is_set()) else 0
        return True

    def viewed_logs(self) -> set[int]:
        with self._lock:
            return set(self._viewed.values())

    def set_strategy(self, strategy: str) -> None:
        """Rank the shared queue with another strategy (``labeling.STRATEGIES``), or make it the verification checks
        (``"verify"``); every view hears of it."""
        if strategy not in QUEUE_MODES:
            raise WorkbenchError(f"unknown strategy {strategy!r}; choose from {', '.join(QUEUE_MODES)}")
        with self._lock:
            if (strategy == VERIFY) != (self.strategy == VERIFY):
                self.queue = []  # ranked suggestions are no checks, nor checks suggestions: none shown meanwhile
            self.strategy = strategy
        self.refresh(scores=False)

    def change_points(self, log_id: int) -> np.ndarray:
        """Change points of a log (computed once per log and predictor version)."""
        key = (log_id, self.scores.predictor)
        with self._lock:
            cps = self._change_points.get(key)
        if cps is None:
            log = self.log(log_id)
            s = self.scores.scores.get(log_id)
            predictor = self.scores.predictor if s is not None else None  # found over that predictor's surprise
            cps = None if predictor is None else kept_change_points(self.session, predictor, log)
            if cps is None:
                rows = self.session.rows(log_id)[:]  # read, not mapped: a map stayed resident (3.1 GiB at 102 h)
                cps = log_change_points(rows, None if s is None else s.surprise, rate_hz=log.rate_hz)
                if predictor is not None:
                    self._keep(keep_change_points, self.session, predictor, log, cps)
            with self._lock:
                self._change_points[key] = cps
        return cps

    def known_change_points(self, log_id: int) -> np.ndarray | None:
        """A log's change points if the worker has found them for the current predictor, else ``None`` (never
        computed here: a page's redraw must not wait for a pass over a log)."""
        with self._lock:
            return self._change_points.get((log_id, self.scores.predictor))

    def snap(self, log_id: int, start: int, stop: int) -> labeling.Snap:
        """Edges of a rough range moved to change points within 1 s (a proposal, not applied).

        Uses the log's change points when the worker has them; otherwise finds them in a window around the range
        only. A person's range selection must not wait for a pass over the whole log (an 800 s log under a retrain
        left a Save unanswered for 20 s; an hour-long one would take minutes).
        """
        log = self.log(log_id)
        radius = round(1.0 * log.rate_hz)
        with self._lock:
            cps = self._change_points.get((log_id, self.scores.predictor))
        if cps is None:
            a = max(0, start - SNAP_CONTEXT_S * round(log.rate_hz))
            b = min(log.n_samples, stop + SNAP_CONTEXT_S * round(log.rate_hz))
            s = self.scores.scores.get(log_id)
            surprise = None if s is None else s.surprise[a:b]
            cps = a + log_change_points(self.session.samples(log_id, a, b), surprise, rate_hz=log.rate_hz)
        return labeling.snap_range(start, stop, cps, radius=radius)

    def _restore(self) -> None:
        """Draw the last scoring and queue kept in the session at once; score again only when they are stale."""
        try:
            stored = LANE.run(stored_scores, self.session)
        except Exception as exc:  # a cache that cannot be read is recomputed, never a reason not to start
            self._on_error(f"stored scores not used ({type(exc).__name__}: {exc}); scoring the logs again")
            return
        if stored is None:
            return
        self.scores = stored.scores
        self.scored = True
        self._scores_wanted = not stored.complete
        key = queue_key(self.session, self.strategy, self.terrains())
        rows = stored_queue(self.session, stored.scores, key=key)
        if rows is not None:
            logs = {x.id: x for x in self.logs()}
            queue = [Queued((r[0], r[1], r[2]), logs[r[0]], *r[1:7]) for r in rows if r[0] in logs]
            with self._lock:
                self.queue = queue
            self._queue_of = (stored.scores, key)
        self.notify("scores")
        self.notify("suggestions")

    def _work(self) -> None:
        self._restore()
        while not self._stop.is_set():
            self._dirty.wait()
            if self._stop.is_set():
                return
            self._dirty.clear()
            try:
                if self._scores_wanted:
                    self._scores_wanted = False
                    with self._lock:
                        first, self._first = self._first, set()
                    self.busy = "scoring logs"
                    self.notify("job")
                    if first and len(first) < len(self._logs):
                        self.scores = LANE.run(compute_scores, self.session, log_ids=first)
                        self.notify("scores")
                    scores = score_and_store(  # a group of logs at a time through the lane, kept as they come
                        self.session,
                        score=compute_scores,  # looked up here, so a test can stand in for it
                        run=LANE.run,
                        stop=lambda: self._stop.is_set() or self._scores_wanted,
                        on_error=self._on_error,
                    )
                    if scores is None:  # stopped, or other models became active meanwhile: theirs are wanted
                        self._scores_wanted = not self._stop.is_set()
                        self._dirty.set()
                        continue
                    self.scores = scores
                    self.scored = True
                    self._keep(keep_answers, self.session, scores)  # what the next Retrain changed is told from it
                    self.notify("scores")
                key = queue_key(self.session, self.strategy, self.terrains())
                if self._queue_of is None or self._queue_of[0] is not self.scores or self._queue_of[1] != key:
                    self.busy = "updating suggestions"
                    queue = None if self.hold_queue else self._compute_queue()
                    if queue is None:  # new models: their scores first, then the queue (the job refreshes it)
                        if self._scores_wanted:
                            self._dirty.set()
                        continue
                    with self._lock:
                        self.queue = queue
                    self._queue_of = (self.scores, key)
                    rows = [(q.log.id, q.start, q.stop, q.reason, q.guess, q.score, q.kind) for q in queue]
                    self._keep(store_queue, self.session, self.scores, rows, key=key)
                self._find_change_points()
                self.notify("suggestions")
            except USER_ERRORS as exc:
                if self._stop.is_set():  # the lane stopped under the work ("the server is stopping"): nothing to say
                    return
                # a damaged model or session: one line in every page and in the server's output, no traceback
                self.problem = one_line(exc)
                self._on_error(f"refresh failed: {self.problem}")
                self.notify("scores")
            except Exception as exc:
                self.problem = f"internal error while scoring: {type(exc).__name__}: {exc}"
                self._on_error(f"refresh failed: {type(exc).__name__}: {exc}\n{traceback.format_exc()}")
                self.notify("scores")
            else:
                self.problem = ""
            finally:
                self.scored = True
                self.busy = ""
                self.notify("job")

    def _keep(self, store: Callable[..., object], *args: object, **kwargs: object) -> None:
        """Store for the next start; a full disk costs the next start its head start, nothing more."""
        try:
            store(*args, **kwargs)
        except OSError as exc:
            self._on_error(f"could not keep the scores for the next start: {exc}")

    def _find_change_points(self) -> None:
        """Change points of every scored log, for the Data tab's figure by stretches: a queue kept from the last
        start was ranked without them, and the page never computes them itself."""
        for log in self.logs():
            if self._stop.is_set() or self._dirty.is_set():
                return  # newer work first; the next pass goes on
            if log.id in self.scores.scores and self.known_change_points(log.id) is None:
                self.busy = "finding change points"
                self.change_points(log.id)

    def _compute_queue(self) -> list[Queued] | None:
        """The suggestion queue ranked from the current scores; ``None`` when new scores are wanted first, a Retrain's
        quick phase trains (``hold_queue``) or the server stops: each makes this ranking worthless."""

        def newer() -> bool:
            return self._scores_wanted or self.hold_queue or self._stop.is_set()

        scores = self.scores
        if scores.predictor is None:
            return []
        logs = [x for x in self.logs() if x.id in scores.scores]
        cps = {}
        for x in logs:
            if newer():
                return None  # new models' scores first (the log in view after a Retrain); the queue follows them
            cps[x.id] = self.change_points(x.id)
        out = []
        try:
            if self.strategy == VERIFY:
                ranked = verification_queue(self.session, scores, logs=logs)
            else:
                strategy: labeling.Strategy = self.strategy  # type: ignore[assignment]
                policy = replace(SESSION_POLICY, strategy=strategy)
                ranked = suggest_for_session(self.session, scores, cps, logs=logs, policy=policy, stop=newer)
        except labeling.Interrupted:
            return None
        for log, s in ranked:
            guess = None if s.guess is None or s.guess >= len(scores.classes) else scores.classes[s.guess]
            out.append(Queued((log.id, s.start, s.stop), log, s.start, s.stop, s.reason, guess, s.score, s.kind))
        return out
