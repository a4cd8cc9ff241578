"""One browser's view: its own log, window, cursor and selection over the shared state; hotkeys; the traces panel.

Panels (label, suggestions, training, data, robot) live in their own modules and see this view only as a
:class:`~workbench.ui.host.PanelHost`; the tracks' arrays (``track_data``) and the legend (``legend``) are built
outside it.
"""

from __future__ import annotations

import contextlib
import html
import threading
import traceback
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TYPE_CHECKING

import numpy as np

from sessions import LogInfo

from ..user_errors import USER_ERRORS, one_line
from . import charts
from .decimate import decimate
from .legend import legend_html
from .map_view import MAP_TRACES_WIDTH, TRACES_WIDTH, MapView
from .status_bar import StatusBar
from .track_data import track_inputs

if TYPE_CHECKING:
    import viser

    from .jobs import TrainJob
    from .state import SharedState

WIDTHS_S = (2.0, 5.0, 10.0, 20.0, 30.0, 60.0, 120.0, 300.0, 600.0, 1800.0, 3600.0)
PIXELS = 1100  # chart width the server decimates for; about a laptop screen's traces panel
# A jump to a range (a suggestion, a saved label) shows at least this much: a 1 s suggestion alone is a couple of
# gait cycles, too little to tell whether it sits inside one terrain or across a change; 10 s keeps the piece about a
# tenth of the chart (110 px) while showing the stretch around it.
CONTEXT_S = 10.0


class ClientView:
    """Everything one browser sees; built when it connects, dropped when it leaves."""

    def __init__(
        self, client: viser.ClientHandle, state: SharedState, job: TrainJob, *, open_map: bool = False
    ) -> None:
        self.client, self.state, self.job = client, state, job
        self._open_map = open_map
        self.author = f"browser-{client.client_id}"
        self._lock = threading.RLock()
        # Set while the server moves widgets, so their callbacks do not echo. Per thread: viser runs those callbacks
        # synchronously in the thread that moved the widget, while another person's click runs in another thread
        # and must not be dropped (a view-wide flag lost clicks that came during a refresh).
        self._quiet = threading.local()
        # viser runs each key's callback on a pool thread as it arrives, so "2" then Shift+Y could run out of order
        # and label the stretch with the terrain chosen before (seen under load in the browser test): the keys are
        # handed, in the order they arrive, to one thread of the view's own
        self._keys = ThreadPoolExecutor(max_workers=1, thread_name_prefix="workbench-keys")
        # Widgets are live as soon as they are added, and a fast client acts before the view is whole (a label
        # saved mid-build met a view without its robot panel): callbacks take this lock, held until the end.
        with self._lock:
            self._build()

    def _build(self) -> None:
        from .camera_panel import CameraPanel
        from .panel_data import DataPanel
        from .panel_label import LabelPanel
        from .panel_review import ReviewPanel
        from .panel_suggest import SuggestPanel
        from .panel_train import TrainPanel
        from .robot import RobotView

        client, state = self.client, self.state
        logs = state.logs()
        self.log: LogInfo | None = logs[0] if logs else None
        if self.log is not None:
            state.set_viewed(self.author, self.log.id)
        self.width_s = 30.0
        self.start_s = 0.0
        self.cursor_s = 0.0
        self.selection: tuple[int, int] | None = None  # samples [start, stop) of the current log
        self.threshold = 0.95
        self.forces_by = "foot"
        self.pixels = PIXELS  # the benchmark raises it to send raw windows as its reference
        self._charts: list = []
        self._chart_key: tuple = ()

        gui = client.gui
        gui.configure_theme(
            titlebar_content=None,
            control_width="large",
            show_logo=False,
            show_share_button=False,
            brand_color=(46, 125, 50),
        )
        gui.main_panel.dock_right()
        gui.main_panel.set_width(420)
        self.traces_panel = gui.add_panel()
        self.traces_panel.dock_left()
        self.traces_panel.set_width(TRACES_WIDTH)
        self._traces_tab = self.traces_panel.add_tab("Traces", icon="chart-line")
        with self._traces_tab:
            self._build_traces()
        self.status_bar = StatusBar(
            self, retrain=lambda: self.train_panel.retrain(), export=lambda: self.data_panel.download_bundle()
        )
        tabs = gui.add_tab_group()
        # suggestions first: the page opens on "what to label next"
        suggest_tab = tabs.add_tab("Suggest", icon="bulb")
        with tabs.add_tab("Label", icon="tag"):
            self.label_panel = LabelPanel(self)
            self.review_panel = ReviewPanel(self)
        with suggest_tab:
            self.suggest_panel = SuggestPanel(self)
        with tabs.add_tab("Train", icon="brain"):
            self.train_panel = TrainPanel(self)
        with tabs.add_tab("Data", icon="database"):
            self.data_panel = DataPanel(self)
        self.robot = RobotView(self)
        self.map = MapView(self, robot_nodes=[self.robot.body, self.robot.forces, self.robot.ground])
        self.camera = CameraPanel(self)
        self._hotkeys()
        self.status_bar.refresh()
        self._unsubscribe = state.subscribe(self._on_event)
        self.redraw()
        if self._open_map and self.log is not None and self.map.has_positions(self.log):
            self.toggle_map()

    # ------------------------------------------------------------------------------------------- building
    def _build_traces(self) -> None:
        gui = self.client.gui
        logs = self.state.logs()
        self.log_dropdown = gui.add_dropdown(
            "Log", self._log_options(logs) or ("(no logs yet)",), hint="The log on screen"
        )
        self.log_dropdown.on_update(lambda _: self.guard(self._pick_log))
        self.cursor_slider = gui.add_slider(
            "Cursor (s)", 0.0, 1.0, 0.01, 0.0, hint="←/→ move the cursor; Shift+←/→ a whole window"
        )
        self.cursor_slider.on_update(lambda _: self.guard(lambda: self.move_cursor(self.cursor_slider.value)))
        self.zoom = gui.add_dropdown(
            "Window", [_fmt_width(w) for w in WIDTHS_S], initial_value=_fmt_width(30.0), hint="↑ zoom in, ↓ zoom out"
        )
        self.zoom.on_update(lambda _: self.guard(lambda: self.set_width(WIDTHS_S[self._zoom_index()])))
        self.map_button = gui.add_button("Map (M)", hint="The log's path coloured by terrain, in the 3D view")
        self.map_button.on_click(lambda _: self.guard(self.toggle_map))
        self.legend = gui.add_html("")
        self.tracks_chart = None
        self._chart_area_order = 100.0
        with gui.add_folder("Display", expand_by_default=False, order=10_000):
            self.threshold_slider = gui.add_slider(
                "Highlight above",
                0.5,
                0.99,
                0.01,
                self.threshold,
                hint="Rank of the score in the session: 0.9 = top 10 % of time",
            )
            self.threshold_slider.on_update(lambda _: self.guard(self._set_threshold))
            self.forces = gui.add_dropdown("Foot forces", ("by foot", "by axis"))
            self.forces.on_update(lambda _: self.guard(self._set_forces))

    def _log_options(self, logs: list[LogInfo]) -> tuple[str, ...]:
        return tuple(f"{x.id}: {x.name}" for x in logs)

    def guard(self, fn: Callable[[], None]) -> None:
        """Run a widget callback unless the server itself moved the widget; report errors in the page."""
        if getattr(self._quiet, "depth", 0):
            return
        try:
            with self._lock:
                fn()
        except USER_ERRORS as exc:
            self.notify("Not done", one_line(exc), color="red")
        except Exception as exc:
            traceback.print_exc()
            self.notify("Something went wrong", f"{type(exc).__name__}: {exc}", color="red")

    def notify(self, title: str, body: str, *, color: str = "green", seconds: float = 4.0) -> None:
        self.client.add_notification(title, body, auto_close_seconds=seconds, color=color)  # type: ignore[arg-type]

    @contextlib.contextmanager
    def quiet(self) -> Iterator[None]:
        """Widgets changed inside this block are moved by the server: their callbacks do not echo."""
        self._quiet.depth = getattr(self._quiet, "depth", 0) + 1  # blocks nest
        try:
            yield
        finally:
            self._quiet.depth -= 1

    def set_widget(self, handle, value) -> None:
        """Move a widget from the server without triggering its callback."""
        with self.quiet():
            handle.value = value

    def _hotkeys(self) -> None:
        gui = self.client.gui

        def bind(label: str, key: str, fn: Callable[[], None], *, modifier: str | None = None, desc: str = "") -> None:
            cmd = gui.add_command(label, description=desc or None, hotkey=key, modifier=modifier)  # type: ignore[arg-type]

            async def in_order(_) -> None:  # awaited on viser's event loop, one message after another
                with contextlib.suppress(RuntimeError):  # the view closed: its keys thread takes no more
                    self._keys.submit(self.guard, fn).add_done_callback(_raised)

            cmd.on_trigger(in_order)

        bind("Cursor left", "arrowleft", lambda: self.step(-0.05))
        bind("Cursor right", "arrowright", lambda: self.step(0.05))
        bind("Window left", "arrowleft", lambda: self.step(-1.0), modifier="shift")
        bind("Window right", "arrowright", lambda: self.step(1.0), modifier="shift")
        bind("Zoom in", "arrowup", lambda: self.zoom_by(-1))
        bind("Zoom out", "arrowdown", lambda: self.zoom_by(1))
        bind("Mark start at cursor", "B", self.label_panel.mark_start, desc="B: begin the range at the cursor")
        bind("Mark end at cursor", "E", self.label_panel.mark_end, desc="E: end the range at the cursor")
        bind("Save label", "enter", self.label_panel.save, desc="Enter: label the range with the chosen terrain")
        bind("Take snap", "P", self.label_panel.take_snap, desc="P: move the range edges to the change points")
        bind("Undo", "Z", self.label_panel.undo, modifier="cmd/ctrl", desc="Undo your last label action")
        bind("Undo (U)", "U", self.label_panel.undo)
        bind("Clear range", "escape", self.label_panel.clear)
        for k in range(1, 10):
            bind(f"Terrain {k}", str(k), lambda k=k: self.label_panel.pick_terrain(k - 1))
        bind("Next suggestion", "N", self.suggest_panel.next, desc="N: show the next suggested segment")
        bind("Accept guess", "A", self.suggest_panel.accept, desc="A: label the suggestion with the model's guess")
        bind("Skip suggestion", "X", self.suggest_panel.skip)
        bind(
            "Verify this version",
            "V",
            self.suggest_panel.verify,
            desc="V: uniform checks of the active version until the session's interval is ±5 points",
        )
        bind("Next stretch", "J", lambda: self.review_panel.step(1), desc="J: the model's next predicted stretch")
        bind("Previous stretch", "K", lambda: self.review_panel.step(-1), desc="K: the model's previous stretch")
        bind("Accept stretch", "Y", self.review_panel.accept, desc="Y: label the stretch as the model predicts")
        bind(
            "Label stretch as chosen terrain",
            "Y",
            self.review_panel.label_as_chosen,
            modifier="shift",
            desc="Shift+Y: label the stretch with the terrain chosen (1–9), correcting the model",
        )
        bind("Retrain", "R", self.train_panel.retrain, desc="R: retrain the classifier in the background")
        bind("Play / pause", "space", self.robot.toggle_play)
        bind("Map", "M", self.toggle_map, desc="M: the 3D view shows the log's path coloured by terrain, or the robot")

    # ------------------------------------------------------------------------------------------- moving
    def _pick_log(self) -> None:
        value = self.log_dropdown.value
        if ":" not in value:
            return
        self.show(self.state.log(int(value.split(":")[0])))

    def show(self, log: LogInfo, *, start_s: float | None = None, stop_s: float | None = None) -> None:
        """Show a log; with a range, centre it in a window of 2.5 times its length (at least ``CONTEXT_S``) and put
        the cursor on it."""
        changed = self.log is None or log.id != self.log.id
        self.log = log
        self.state.set_viewed(self.author, log.id)
        if changed:
            self.selection = None
            self.set_widget(self.log_dropdown, f"{log.id}: {log.name}")
            self.review_panel.refresh()
        if start_s is not None and stop_s is not None:
            span = stop_s - start_s
            self.width_s = next((w for w in WIDTHS_S if w >= max(2.5 * span, CONTEXT_S)), WIDTHS_S[-1])
            self.set_widget(self.zoom, _fmt_width(self.width_s))
            self.start_s = start_s + span / 2 - self.width_s / 2
            self.cursor_s = start_s
        elif changed:
            self.start_s, self.cursor_s = 0.0, 0.0
        self.redraw()

    def _zoom_index(self) -> int:
        return [_fmt_width(w) for w in WIDTHS_S].index(self.zoom.value)

    def set_width(self, width_s: float) -> None:
        centre = self.cursor_s
        self.width_s = width_s
        self.start_s = centre - width_s / 2
        self.redraw()

    def zoom_by(self, steps: int) -> None:
        i = int(np.clip(self._zoom_index() + steps, 0, len(WIDTHS_S) - 1))
        self.set_widget(self.zoom, _fmt_width(WIDTHS_S[i]))
        self.set_width(WIDTHS_S[i])

    def move_cursor(self, seconds: float) -> None:
        if self.log is None:
            return
        self.cursor_s = float(np.clip(seconds, 0.0, self.log.duration_s))
        # the window follows the cursor when it leaves it
        if self.cursor_s < self.start_s or self.cursor_s > self.start_s + self.width_s:
            self.start_s = self.cursor_s - self.width_s / 2
        self.redraw()

    def step(self, windows: float) -> None:
        if windows in (-1.0, 1.0):
            self.start_s += windows * self.width_s
            self.cursor_s += windows * self.width_s
            self.cursor_s = float(np.clip(self.cursor_s, 0.0, self.log.duration_s if self.log else 0.0))
            self.redraw()
        else:
            self.move_cursor(self.cursor_s + windows * self.width_s)

    def _set_threshold(self) -> None:
        self.threshold = float(self.threshold_slider.value)
        self.redraw()

    def _set_forces(self) -> None:
        self.forces_by = "axis" if self.forces.value == "by axis" else "foot"
        self._chart_key = ()
        self.redraw()

    @property
    def window(self) -> tuple[int, int]:
        """Visible samples ``[a, b)`` of the current log."""
        log = self.log
        assert log is not None
        width = min(self.width_s, log.duration_s)
        self.start_s = float(np.clip(self.start_s, 0.0, max(0.0, log.duration_s - width)))
        return log.sample_at(self.start_s), log.sample_at(self.start_s + width)

    # ------------------------------------------------------------------------------------------- drawing
    def _on_event(self, event: str) -> None:
        with self._lock:
            if event == "logs":
                logs = self.state.logs()
                opts = self._log_options(logs)
                with self.quiet():
                    self.log_dropdown.options = opts or ("(no logs yet)",)
                if self.log is None and logs:
                    self.show(logs[0])
                self.data_panel.refresh()
            if event in ("labels", "scores", "suggestions"):
                self.redraw()
            if event == "labels":
                self.label_panel.refresh()
            if event in ("labels", "scores"):
                self.review_panel.refresh()
            if event in ("suggestions", "scores", "labels"):
                self.suggest_panel.refresh()
            if event in ("job", "models", "scores"):
                self.train_panel.refresh(event)
            if event in ("labels", "models", "scores", "suggestions"):  # a new queue: the worker has change points
                self.data_panel.refresh()
            self.status_bar.refresh()

    def redraw(self) -> None:
        """Draw the window: traces decimated per pixel, tracks, cursor; the robot at the cursor."""
        with self._lock:
            log = self.log
            if log is None:
                self.legend.content = "<p>No logs yet: upload MCAP or CSV files in the Data tab.</p>"
                return
            a, b = self.window
            with self.quiet():
                self.cursor_slider.max = round(log.duration_s, 2)
                self.cursor_slider.value = round(min(self.cursor_s, log.duration_s), 2)
            try:
                samples = self.state.session.array(log.id)[a:b]
            except USER_ERRORS as exc:  # a log file changed under the session: say so where the traces would be
                self.legend.content = f"<p style='color:#c62828'>{html.escape(one_line(exc))}</p>"
                return
            dec = decimate(samples, a, rate_hz=log.rate_hz, pixels=self.pixels)
            groups = charts.channel_groups(log.channel_names, forces_by=self.forces_by)
            specs = [
                charts.trace_chart(dec, g, cursor_s=self.cursor_s, show_x=(i == len(groups) - 1))
                for i, g in enumerate(groups)
            ]
            tracks = charts.tracks_chart(self._track_inputs(log, dec.t), self._terrain_colors(), cursor_s=self.cursor_s)
            key = (log.channel_names, self.forces_by, len(tracks["series"]))
            with self.client.atomic():
                if key != self._chart_key:
                    self._rebuild_charts(tracks, specs)
                    self._chart_key = key
                else:
                    for handle, spec in zip([self.tracks_chart, *self._charts], [tracks, *specs], strict=True):
                        if handle.series != spec["series"]:  # a new series list rebuilds the chart: only if needed
                            handle.series = spec["series"]
                        handle.data = spec["data"]
                self.legend.content = legend_html(
                    log,
                    (a, b),
                    terrains=self.state.terrains(),
                    cursor_s=self.cursor_s,
                    selection=self.selection,
                    busy=self.state.busy,
                    problem=self.state.problem,
                )
            self.robot.update()
            self.map.update()
            self.camera.update()

    def toggle_map(self) -> None:
        """The 3D view shows the map (the traces panel narrower, so the map has room) or the robot again."""
        if self.log is not None and not self.map.shown and not self.map.has_positions(self.log):
            self.notify("No map", f"{self.log.name} has no positions (odometry, a pose, /tf, GNSS)", color="yellow")
            return
        shown = self.map.toggle()
        self.traces_panel.set_width(MAP_TRACES_WIDTH if shown else TRACES_WIDTH)
        self.map_button.label = "Robot (M)" if shown else "Map (M)"

    def _rebuild_charts(self, tracks: dict, specs: list[dict]) -> None:
        for h in [self.tracks_chart, *self._charts]:
            if h is not None:
                h.remove()
        with self._traces_tab:
            self.tracks_chart = self.client.gui.add_uplot(**tracks, order=self._chart_area_order)
            self._charts = [
                self.client.gui.add_uplot(**s, order=self._chart_area_order + 1 + i) for i, s in enumerate(specs)
            ]

    def _terrain_colors(self) -> list[tuple[str, str]]:
        return [(t.name, t.color) for t in self.state.terrains()]

    def _track_inputs(self, log: LogInfo, t: np.ndarray) -> charts.TrackInputs:
        """The tracks' arrays at the decimated times ``t`` (``(P,)``, s) of the window on screen."""
        queue = [q for q in self.suggest_panel.visible_queue() if q.log.id == log.id]
        cur = self.suggest_panel.current
        current = next(((q.start, q.stop) for q in queue if cur is not None and q.key == cur.key), None)
        return track_inputs(
            log,
            t,
            terrains=[x.name for x in self.state.terrains()],
            segments=self.state.session.segments(log.id),
            scores=self.state.scores,
            threshold=self.threshold,
            suggested=[(q.start, q.stop) for q in queue],
            current=current,
            selection=self.selection,
            stretches=self.state.stretches(log.id),
            review=self.review_panel.review_range(),
        )

    def close(self) -> None:
        self.state.set_viewed(self.author, None)
        self._unsubscribe()
        self.robot.close()
        self._keys.shutdown(wait=False, cancel_futures=True)


def _raised(done: Future) -> None:
    """A key's callback that raised past ``guard`` (which reports errors in the page) is printed, as viser's pool
    prints it."""
    if not done.cancelled() and done.exception() is not None:
        traceback.print_exception(done.exception())


def _fmt_width(seconds: float) -> str:
    return f"{seconds:g} s" if seconds < 60 else f"{seconds / 60:g} min"
