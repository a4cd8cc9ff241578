"""The Label tab: mark a range (hotkeys or a two-handle slider), pick a terrain, save; snap proposal; the log's
segments (jump, relabel, delete); undo."""

from __future__ import annotations

import html
from typing import TYPE_CHECKING

from sessions import WorkbenchError

if TYPE_CHECKING:
    from .host import PanelHost

NONE_CHOSEN = "(choose a segment)"
NO_TERRAINS = "(no terrains yet)"
NO_TERRAINS_HINT = (  # a new session has none: they are the person's, not ours
    "<div style='font-size:0.85em;color:#b45309'><b>No terrains yet.</b> Type a name under <b>Terrains</b> below "
    "and press <b>Add terrain</b> (or import labels with <code>--create-terrains</code>).</div>"
)
KEYS_HELP = (
    "<div style='font-size:0.78em;color:#555;line-height:1.5'>"
    "<b>B</b>/<b>E</b> range start/end at cursor · <b>1–9</b> terrain · <b>Enter</b> save · <b>P</b> take snap · "
    "<b>Esc</b> clear · <b>U</b> or Ctrl+Z undo · <b>←/→</b> cursor · <b>↑/↓</b> zoom · <b>N</b> next suggestion · "
    "<b>A</b> accept guess · <b>X</b> skip · <b>J</b>/<b>K</b> model's next/previous stretch · <b>Y</b> accept it · "
    "<b>Shift+Y</b> label it as the terrain chosen · <b>R</b> retrain · <b>Space</b> play</div>"
)


class LabelPanel:
    def __init__(self, host: PanelHost) -> None:
        self.host = host
        gui = host.client.gui
        terrains = [t.name for t in host.state.terrains()]
        gui.add_html(KEYS_HELP)
        self.range = gui.add_multi_slider(
            "Range (s)",
            0.0,
            1.0,
            0.01,
            (0.0, 0.0),
            min_range=0.0,
            hint="Drag both handles, or press B and E at the cursor",
        )
        self.range.on_update(lambda _: host.guard(self._range_moved))
        self.terrain = gui.add_dropdown("Terrain", terrains or (NO_TERRAINS,), hint="Keys 1–9")
        self.no_terrains = gui.add_html(NO_TERRAINS_HINT, visible=not terrains)
        self.save_button = gui.add_button("Save label (Enter)", icon="device-floppy", color="green")
        self.save_button.on_click(lambda _: host.guard(self.save))
        self.snap_html = gui.add_html("")
        self.snap_button = gui.add_button("Take snap (P)", icon="magnet", visible=False)
        self.snap_button.on_click(lambda _: host.guard(self.take_snap))
        self._snap: tuple[int, int] | None = None
        with gui.add_folder("Segments of this log"):
            self.segments = gui.add_dropdown("Segment", ("(none)",))
            self.go_button = gui.add_button("Go to", icon="player-play")
            self.go_button.on_click(lambda _: host.guard(self.go_to))
            self.relabel_button = gui.add_button("Relabel as chosen terrain", icon="pencil")
            self.relabel_button.on_click(lambda _: host.guard(self.relabel))
            self.delete_button = gui.add_button("Delete", icon="trash", color="red")
            self.delete_button.on_click(lambda _: host.guard(self.delete))
            self.undo_button = gui.add_button("Undo my last change (U)", icon="arrow-back-up")
            self.undo_button.on_click(lambda _: host.guard(self.undo))
        self.summary = gui.add_html("")
        with gui.add_folder("Terrains", expand_by_default=not terrains):  # open where a new session starts
            self.terrain_name = gui.add_text("Name", "", hint="A new terrain, or the new name of the one chosen above")
            self.add_terrain_button = gui.add_button("Add terrain", icon="plus")
            self.add_terrain_button.on_click(lambda _: host.guard(lambda: self._terrains("add")))
            self.rename_terrain_button = gui.add_button("Rename chosen terrain", icon="pencil")
            self.rename_terrain_button.on_click(lambda _: host.guard(lambda: self._terrains("rename")))
            self.remove_terrain_button = gui.add_button("Remove chosen terrain", icon="trash", color="red")
            self.remove_terrain_button.on_click(lambda _: host.guard(lambda: self._terrains("remove")))
        self.refresh()

    def _terrains(self, action: str) -> None:
        """Add, rename or remove a terrain (a used one is refused by the session, with its reason shown)."""
        name, chosen = self.terrain_name.value.strip(), self.terrain.value
        if action == "add":
            self.host.state.change_terrains("add", name)
            self.host.notify("Terrain added", name, color="green")
        elif action == "rename":
            self.host.state.change_terrains("rename", chosen, name)
            self.host.notify("Terrain renamed", f"{chosen} → {name}; its labels follow", color="blue")
        else:
            self.host.state.change_terrains("remove", chosen)
            self.host.notify("Terrain removed", chosen, color="blue")
        with self.host.quiet():
            self.terrain_name.value = ""

    # -------------------------------------------------------------------------------------------- range
    def _set_range(self, start: int, stop: int) -> None:
        host = self.host
        log = host.log
        if log is None:
            return
        start, stop = max(0, min(start, log.n_samples)), max(0, min(stop, log.n_samples))
        host.selection = (min(start, stop), max(start, stop)) if start != stop else None
        with host.quiet():
            self.range.max = round(log.duration_s, 2)
            lo, hi = host.selection or (start, start)
            self.range.value = (round(lo / log.rate_hz, 2), round(hi / log.rate_hz, 2))
        self._propose_snap()
        host.redraw()

    def _range_moved(self) -> None:
        log = self.host.log
        if log is None:
            return
        lo, hi = self.range.value
        self._set_range(log.sample_at(lo), log.sample_at(hi))

    def mark_start(self) -> None:
        log = self.host.log
        if log is None:
            return
        a = log.sample_at(self.host.cursor_s)
        b = self.host.selection[1] if self.host.selection and self.host.selection[1] > a else a + round(log.rate_hz)
        self._set_range(a, b)

    def mark_end(self) -> None:
        log = self.host.log
        if log is None:
            return
        b = log.sample_at(self.host.cursor_s)
        a = self.host.selection[0] if self.host.selection and self.host.selection[0] < b else b - round(log.rate_hz)
        self._set_range(a, b)

    def select(self, start: int, stop: int, terrain: str | None = None) -> None:
        """Select a range of the current log (a suggestion, a segment) and optionally a terrain."""
        if terrain is not None:
            self.host.set_widget(self.terrain, terrain)
        self._set_range(start, stop)

    def clear(self) -> None:
        self.host.selection = None
        self._snap = None
        self.snap_html.content = ""
        self.snap_button.visible = False
        self.host.redraw()

    def pick_terrain(self, index: int) -> None:
        terrains = [t.name for t in self.host.state.terrains()]
        if index < len(terrains):
            self.host.set_widget(self.terrain, terrains[index])

    def _propose_snap(self) -> None:
        host, sel, log = self.host, self.host.selection, self.host.log
        self._snap = None
        if sel is None or log is None:
            self.snap_html.content, self.snap_button.visible = "", False
            return
        snap = host.state.snap(log.id, *sel)
        if not (snap.moved_start or snap.moved_stop) or (snap.start, snap.stop) == sel:
            self.snap_html.content = "<small style='color:#777'>No change point near the edges.</small>"
            self.snap_button.visible = False
            return
        self._snap = (snap.start, snap.stop)
        moves = []
        if snap.moved_start:
            moves.append(f"start {(snap.start - sel[0]) / log.rate_hz:+.2f} s")
        if snap.moved_stop:
            moves.append(f"end {(snap.stop - sel[1]) / log.rate_hz:+.2f} s")
        self.snap_html.content = (
            f"<small>Snap proposal: <b>{snap.start / log.rate_hz:.2f}–{snap.stop / log.rate_hz:.2f} s</b> "
            f"({', '.join(moves)}): the signal changes there.</small>"
        )
        self.snap_button.visible = True

    def take_snap(self) -> None:
        if self._snap is not None:
            self._set_range(*self._snap)

    # -------------------------------------------------------------------------------------------- saving
    def save(self, *, terrain: str | None = None, source: str = "manual") -> None:
        host, log, sel = self.host, self.host.log, self.host.selection
        if log is None or sel is None:
            raise WorkbenchError("mark a range first: B and E at the cursor, or drag the range handles")
        terrain = terrain or self.terrain.value
        if terrain == NO_TERRAINS:
            raise WorkbenchError("no terrains yet: type a name under Terrains below and press Add terrain")
        seg = host.state.add_label(log.id, sel[0], sel[1], terrain, author=host.author, source=source)
        host.notify("Saved", f"{(sel[1] - sel[0]) / log.rate_hz:.1f} s of {terrain} on {log.name} (segment {seg.id})")
        self.clear()

    def undo(self) -> None:
        kind = self.host.state.undo(author=self.host.author)
        self.host.notify("Undone", f"your last {kind}", color="blue")

    def _chosen_segment(self):
        value = self.segments.value
        if not value.startswith("#"):
            raise WorkbenchError("no segment chosen")
        return self.host.state.session.segment(int(value[1:].split()[0]))

    def go_to(self) -> None:
        seg = self._chosen_segment()
        log = self.host.state.log(seg.log_id)
        self.host.show(log, start_s=seg.start / log.rate_hz, stop_s=seg.stop / log.rate_hz)
        self.select(seg.start, seg.stop, seg.terrain)

    def relabel(self) -> None:
        seg = self._chosen_segment()
        self.host.state.change_label(seg.id, author=self.host.author, terrain=self.terrain.value)
        note = f"segment {seg.id}: {seg.terrain} → {self.terrain.value}; U undoes"
        self.host.notify("Relabelled", note, color="blue")

    def delete(self) -> None:
        seg = self._chosen_segment()
        self.host.state.delete_label(seg.id, author=self.host.author)
        self.host.notify("Deleted", f"segment {seg.id} ({seg.terrain}); U undoes", color="blue")

    def refresh(self) -> None:
        host, log = self.host, self.host.log
        state = host.state
        terrains = [t.name for t in state.terrains()]
        if tuple(terrains or (NO_TERRAINS,)) != tuple(self.terrain.options):
            self.terrain.options = terrains or (NO_TERRAINS,)
        self.no_terrains.visible = not terrains
        segs = state.session.segments(log.id) if log is not None else []
        opts = (
            tuple(f"#{s.id} {s.start / log.rate_hz:.1f}–{s.stop / log.rate_hz:.1f} s {s.terrain}" for s in segs)
            if log is not None
            else ()
        )
        with host.quiet():
            # Viser keeps the value when it is still listed, else falls on the first entry: "(choose a segment)", not
            # a segment Delete would then remove. A choice whose text changed (another person relabelled it) is
            # kept by its id. The value is read again after the options change, because the person may choose
            # while this runs: writing back what was read before would undo that choice.
            before = self.segments.value
            self.segments.options = (NONE_CHOSEN, *opts) if opts else ("(none)",)
            if self.segments.value == self.segments.options[0] and before.startswith("#"):
                same = [o for o in opts if o.startswith(before.split()[0] + " ")]
                if same:
                    self.segments.value = same[0]
        all_segs = state.session.segments()
        per = {}
        for s in all_segs:
            per[s.terrain] = per.get(s.terrain, 0) + s.length
        rate = log.rate_hz if log is not None else 100.0
        rows = "".join(
            f"<tr><td><span style='color:{html.escape(t.color, quote=True)}'>■</span> {html.escape(t.name)}</td>"
            f"<td style='text-align:right'>{per.get(t.name, 0) / rate:.1f} s</td></tr>"
            for t in state.terrains()
        )
        self.summary.content = (
            f"<div style='font-size:0.8em'><b>{len(all_segs)}</b> segments labelled in the session"
            f"<table style='width:100%'>{rows}</table></div>"
        )
