"""The Suggest tab: the shared queue of segments to label next, with reasons and the model's guess; next, accept,
skip (skips are this browser's own)."""

from __future__ import annotations

import base64
import html
from typing import TYPE_CHECKING

from sessions import WorkbenchError

from ..cycle import QUEUE_MODES, VERIFY, AnswerChange, answer_change, session_figures
from ..user_errors import USER_ERRORS

if TYPE_CHECKING:
    from .host import PanelHost
    from .state import Queued


TABLE_ROWS = 12
THUMB_SHOWN_PX = 56  # the thumbnails are twice this wide: sharp on a high-density screen


class SuggestPanel:
    def __init__(self, host: PanelHost) -> None:
        self.host = host
        gui = host.client.gui
        self.current: Queued | None = None
        self._skipped: set[tuple[int, int, int]] = set()
        self._change: tuple[object, AnswerChange | None] | None = None
        self.info = gui.add_html("")
        self.next_button = gui.add_button("Next suggestion (N)", icon="arrow-right", color="teal")
        self.next_button.on_click(lambda _: host.guard(self.next))
        self.accept_button = gui.add_button("Accept guess (A)", icon="check", color="green", disabled=True)
        self.accept_button.on_click(lambda _: host.guard(self.accept))
        self.skip_button = gui.add_button("Skip (X)", icon="player-skip-forward", disabled=True)
        self.skip_button.on_click(lambda _: host.guard(self.skip))
        self.verify_button = gui.add_button("Verify this version (V)", icon="checklist")
        self.verify_button.on_click(lambda _: host.guard(self.verify))
        self.table = gui.add_html("")
        self.strategy = gui.add_dropdown(
            "Rank by",
            QUEUE_MODES,
            initial_value=host.state.strategy,
            hint="How the shared queue is ranked (for everyone): combined mixes uncertainty, disagreement, surprise "
            "and diversity; the others use one score alone; random is the baseline; verify: uniform checks of this "
            "version, as many as bring the session's interval to ±5 points",
        )
        self.strategy.on_update(lambda _: host.guard(lambda: host.state.set_strategy(self.strategy.value)))
        self.refresh()

    def verify(self) -> None:
        """Make the shared queue the verification checks of the active version (V): uniform pieces of the time
        nobody labelled, stratified by log, as many as bring the session's 90 % interval to ±5 points."""
        state = self.host.state
        if state.scores.classifier is None:
            raise WorkbenchError("nothing to verify before a classifier exists: label two terrains and Retrain (R)")
        self.current = None  # the ranked suggestion on screen is not one of the checks
        state.set_strategy(VERIFY)
        self.refresh()

    def verify_words(self) -> str:
        """What a verification would take: ``"the session: not checked since the last Retrain; 26 checks would
        bring it to ±5 points"``; empty before a classifier has scored the logs."""
        scores = self.host.state.scores
        if scores.classifier is None:
            return ""
        session = self.host.state.session
        figure = session_figures(session, scores).session
        if self._change is None or self._change[0] is not scores:  # read once per scoring: it reads the cache
            self._change = (scores, answer_change(session, scores))
        change = self._change[1]
        moved = f". {change.words()[:1].upper()}{change.words()[1:]}" if change is not None else ""
        return f"the session: {figure.words()}; {figure.plan_words()}{moved}"

    def visible_queue(self) -> list[Queued]:
        return [q for q in self.host.state.queue if q.key not in self._skipped]

    def next(self) -> None:
        queue = self.visible_queue()
        if not queue:
            raise WorkbenchError(self._empty_reason())
        keys = [q.key for q in queue]
        i = (keys.index(self.current.key) + 1) % len(queue) if self.current and self.current.key in keys else 0
        self._show(queue[i])

    def _show(self, q: Queued) -> None:
        self.current = q
        a, b = q.seconds
        self.host.show(q.log, start_s=a, stop_s=b)
        self.host.label_panel.select(q.start, q.stop, q.guess)
        self.refresh()

    def accept(self) -> None:
        q = self.current
        if q is None:
            raise WorkbenchError("no suggestion on screen: press N first")
        if q.guess is None:
            raise WorkbenchError("no guess yet (no classifier): choose the terrain (1–9) and press Enter")
        self.host.label_panel.select(q.start, q.stop)
        if self.host.log is None or self.host.log.id != q.log.id:
            self.host.show(q.log)
            self.host.label_panel.select(q.start, q.stop)
        self.host.label_panel.save(terrain=q.guess, source="suggestion")
        self._advance(q)

    def skip(self) -> None:
        q = self.current
        if q is None:
            raise WorkbenchError("no suggestion on screen: press N first")
        self._skipped.add(q.key)
        self._advance(q)

    def _advance(self, done: Queued) -> None:
        rest = [q for q in self.visible_queue() if q.key != done.key]
        self.current = None
        if rest:
            self._show(rest[0])
        else:
            self.refresh()

    def _empty_reason(self) -> str:
        state = self.host.state
        if state.busy or not state.scored:
            return f"suggestions are being computed ({state.busy or 'starting'}); they appear here in a moment"
        if state.problem:
            return f"no suggestions: {state.problem}"
        if state.scores.predictor is None:
            return "no suggestions before a predictor exists: press Retrain (R) to train it on all logs"
        if state.strategy == VERIFY:
            return (
                f"nothing left to verify ({self.verify_words()}); choose a ranking under Rank by to label on, "
                "or skip fewer"
            )
        return "no suggestions left (everything worth labelling is labelled, or all were skipped)"

    def refresh(self) -> None:
        if self.strategy.value != self.host.state.strategy:  # another browser changed it
            self.host.set_widget(self.strategy, self.host.state.strategy)
        queue = self.visible_queue()
        ranked = {q.key: q for q in queue}
        # A rescoring (after a retrain, another browser's label) recomputes the queue while a person looks at one
        # suggestion: it stays on screen and A or X still act on it. Dropping it made an A pressed a moment after N
        # find nothing to accept; a stretch still ranked takes its new reason and guess.
        stale = self.current is not None and self.current.key not in ranked
        if self.current is not None and not stale:
            self.current = ranked[self.current.key]
        has = self.current is not None
        self.accept_button.disabled = not (has and self.current.guess is not None)
        self.skip_button.disabled = not has
        if has:
            q = self.current
            a, b = q.seconds
            guess = f"model's guess: <b>{html.escape(q.guess)}</b>" if q.guess else "no guess yet"
            self.info.content = (
                f"<div style='font-size:0.85em;padding:4px;border-left:3px solid #00897b'>"
                f"<b>{html.escape(q.log.name)}</b> {a:.1f}–{b:.1f} s<br>{html.escape(q.reason)}<br>{guess}"
                + ("<br><small style='color:#b26a00'>no longer ranked after the last scoring</small>" if stale else "")
                + "</div>"
            )
        else:
            self.info.content = f"<small style='color:#666'>{html.escape(self._hint(queue))}</small>"
        plan = self.verify_words()
        if plan:
            mode = "<b>verifying</b>: " if self.host.state.strategy == VERIFY else ""
            self.info.content += (
                f"<div style='font-size:0.8em;color:#555;padding:2px 4px'>{mode}{html.escape(plan)}</div>"
            )
        shown = queue[:TABLE_ROWS]
        pictures = self._thumbnails(shown)
        rows = []
        for rank, q in enumerate(shown):
            a, b = q.seconds
            mark = "background:#e0f2f1;" if self.current is not None and q.key == self.current.key else ""
            picture = ""
            if pictures:
                jpeg = pictures.get(q.key)
                picture = (
                    f"<td><img class='wb-thumb' src='data:image/jpeg;base64,{base64.b64encode(jpeg).decode()}' "
                    f"style='width:{THUMB_SHOWN_PX}px;display:block;border-radius:3px' alt='camera frame'></td>"
                    if jpeg
                    else "<td style='color:#999;text-align:center'>–</td>"
                )
            rows.append(
                f"<tr style='{mark}'><td>{rank + 1}</td>{picture}<td>{html.escape(q.log.name)}</td>"
                f"<td style='text-align:right'>{a:.1f}–{b:.1f}</td><td>{html.escape(q.reason)}</td>"
                f"<td>{html.escape(q.guess or '–')}</td></tr>"
            )
        view = "<th>view</th>" if pictures else ""
        self.table.content = (
            "<table style='width:100%;font-size:0.75em;border-collapse:collapse'><tr style='color:#666'>"
            f"<th>#</th>{view}<th>log</th><th>s</th><th>why</th><th>guess</th></tr>" + "".join(rows) + "</table>"
            if rows
            else ""
        )

    def _thumbnails(self, queue: list[Queued]) -> dict[tuple[int, int, int], bytes | None]:
        """The camera frame at the middle of each suggestion, small, for logs that recorded one; empty when no log
        of the table has a camera (no column then). A damaged camera shows no picture, not an error."""
        session = self.host.state.session
        cameras: dict[int, bool] = {}
        out: dict[tuple[int, int, int], bytes | None] = {}
        for q in queue:
            try:
                if q.log.id not in cameras:
                    cameras[q.log.id] = bool(session.cameras(q.log.id))
                if cameras[q.log.id]:
                    a, b = q.seconds
                    out[q.key] = session.camera_thumbnail(q.log.id, (a + b) / 2)
            except USER_ERRORS:
                out[q.key] = None
        return out

    def _hint(self, queue: list[Queued]) -> str:
        if queue and self.host.state.strategy == VERIFY:
            return (
                f"{len(queue)} verification checks: uniform pieces of the time nobody labelled. Label each with the "
                "terrain you see (N for the first); each tests this version before it trains anything."
            )
        if queue:
            return f"{len(queue)} segments suggested. Press N to see the first."
        try:
            return self._empty_reason()
        except Exception:
            return ""
