"""Reviewing the model's stretches: step through what the model predicts (J next, K previous) and accept a stretch
with one key (Y) instead of drawing it. An accepted stretch is saved as labels with source ``accepted`` over its
unlabelled time only (a person's labels are never overwritten), as one action that U undoes."""

from __future__ import annotations

import html
from typing import TYPE_CHECKING

import labeling
from sessions import WorkbenchError

if TYPE_CHECKING:
    from .host import PanelHost

MIN_PIECE_S = 0.2  # slivers between existing labels shorter than this are left unlabelled


class ReviewPanel:
    """The "Model's stretches" folder of the Label tab; ``current`` is drawn as a bar over the model track."""

    def __init__(self, host: PanelHost) -> None:
        self.host = host
        gui = host.client.gui
        with gui.add_folder("Model's stretches (J / K / Y)"):
            self.info = gui.add_html("")
            self.prev_button = gui.add_button("Previous (K)", icon="chevron-left")
            self.prev_button.on_click(lambda _: host.guard(lambda: self.step(-1)))
            self.next_button = gui.add_button("Next (J)", icon="chevron-right")
            self.next_button.on_click(lambda _: host.guard(lambda: self.step(1)))
            self.accept_button = gui.add_button("Accept (Y)", icon="check", color="green")
            self.accept_button.on_click(lambda _: host.guard(self.accept))
        self.current: tuple[int, labeling.PredictedStretch] | None = None  # (log id, stretch)
        self.refresh()

    def review_range(self) -> tuple[int, int] | None:
        """``[start, stop)`` of the stretch under review when it lies in the log on screen."""
        log = self.host.log
        if self.current is None or log is None or self.current[0] != log.id:
            return None
        return self.current[1].start, self.current[1].stop

    def _open_time(self, stretch: labeling.PredictedStretch, covered: list[tuple[int, int]] | None = None) -> int:
        """Samples of ``stretch`` nobody labelled (``covered``: the log's labelled ranges, read when not given)."""
        log = self.host.log
        assert log is not None
        if covered is None:
            covered = [(s.start, s.stop) for s in self.host.state.session.segments(log.id)]
        pieces = labeling.uncovered(stretch.start, stretch.stop, covered, min_len=round(MIN_PIECE_S * log.rate_hz))
        return sum(b - a for a, b in pieces)

    def step(self, direction: int) -> None:
        """Show the next (``1``) or previous (``-1``) stretch of the log on screen that still has unlabelled time."""
        log = self.host.log
        if log is None:
            raise WorkbenchError("no log on screen")
        stretches = self.host.state.stretches(log.id)
        if not stretches:
            raise WorkbenchError("the model has no predictions for this log yet: train a classifier (Retrain)")
        here = self.review_range()
        at = here[0] if here is not None else log.sample_at(self.host.cursor_s) - (1 if direction > 0 else 0)
        order = stretches if direction > 0 else stretches[::-1]
        ahead = [x for x in order if (x.start > at if direction > 0 else x.start < at)]
        covered = [(s.start, s.stop) for s in self.host.state.session.segments(log.id)]  # once, not per stretch
        found = next((x for x in ahead if self._open_time(x, covered) > 0), None)
        if found is None:
            self.host.notify(
                "No more",
                f"no stretch with unlabelled time {'after' if direction > 0 else 'before'} this one in this log",
                color="blue",
            )
            return
        self.current = (log.id, found)
        self.host.show(log, start_s=found.start / log.rate_hz, stop_s=found.stop / log.rate_hz)
        self.refresh()

    def accept(self) -> None:
        """Label the unlabelled time of the stretch under review with the model's terrain, then show the next."""
        self._label_stretch(None)

    def label_as_chosen(self) -> None:
        """Label the unlabelled time of the stretch under review with the terrain chosen (1–9 or the dropdown), then
        show the next: the correction of a whole stretch in one key, where the model named the wrong terrain."""
        chosen = self.host.label_panel.terrain.value
        if chosen not in {t.name for t in self.host.state.terrains()}:
            raise WorkbenchError("no terrain chosen: press 1–9 (or pick one under Label) first")
        self._label_stretch(chosen)

    def _label_stretch(self, chosen: str | None) -> None:
        log = self.host.log
        here = self.review_range()
        if log is None or here is None or self.current is None:
            raise WorkbenchError("no stretch under review: press J to show the model's next stretch")
        stretch = self.current[1]
        classes = self.host.state.scores.classes
        if stretch.terrain >= len(classes):
            raise WorkbenchError("the model changed since this stretch was shown; press J again")
        terrain = chosen or classes[stretch.terrain]
        covered = [(s.start, s.stop) for s in self.host.state.session.segments(log.id)]
        pieces = labeling.uncovered(*here, covered, min_len=round(MIN_PIECE_S * log.rate_hz))
        if not pieces:
            raise WorkbenchError("this stretch is labelled already; press J for the next one")
        # the person's own terrain is a check of the model's stretch (counted); accepting the model's is not
        source = "accepted" if chosen is None else "manual"
        self.host.state.add_labels(log.id, pieces, terrain, author=self.host.author, source=source)
        seconds = sum(b - a for a, b in pieces) / log.rate_hz
        title = "Accepted" if chosen is None else ("Labelled" if chosen == classes[stretch.terrain] else "Corrected")
        self.host.notify(title, f"{terrain}, {seconds:.1f} s in {len(pieces)} piece(s); U undoes")
        self.step(1)

    def refresh(self) -> None:
        """Say which stretch is under review (and forget it when the log on screen or the model changed)."""
        log = self.host.log
        stretches = self.host.state.stretches(log.id) if log is not None else []
        if self.current is not None and (log is None or self.current[1] not in stretches):
            self.current = None
        if self.current is None:
            text = (
                f"{len(stretches)} stretches predicted in this log. <b>J</b> shows the next one from the cursor, "
                "<b>Y</b> accepts it (its unlabelled time only) and moves on, <b>Shift+Y</b> labels it with the "
                "terrain chosen instead, <b>U</b> undoes."
                if stretches
                else "No predictions yet: they appear once a classifier is trained."
            )
        else:
            s = self.current[1]
            classes = self.host.state.scores.classes
            name = classes[s.terrain] if s.terrain < len(classes) else "?"
            assert log is not None
            n = stretches.index(s) + 1
            open_s = self._open_time(s) / log.rate_hz
            text = (
                f"Stretch {n} of {len(stretches)}: <b>{html.escape(name)}</b> "
                f"{s.start / log.rate_hz:.1f}–{s.stop / log.rate_hz:.1f} s, confidence {s.confidence:.2f}; "
                f"{open_s:.1f} s unlabelled"
            )
        self.info.content = f"<div style='font-size:0.8em;line-height:1.5'>{text}</div>"
