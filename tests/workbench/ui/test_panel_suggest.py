"""The Suggest tab keeps the suggestion a person looks at when the shared queue is recomputed under it."""

from __future__ import annotations

import base64
from dataclasses import dataclass, field
from types import SimpleNamespace

from sessions import LogInfo, SessionError
from workbench.ui.panel_suggest import SuggestPanel
from workbench.ui.state import Queued


class _Widget(SimpleNamespace):
    def on_click(self, fn) -> None:
        self.click = fn

    def on_update(self, fn) -> None:
        self.update = fn


class _Gui:
    def add_html(self, content: str) -> _Widget:
        return _Widget(content=content)

    def add_button(self, label: str, *, disabled: bool = False, **_) -> _Widget:
        return _Widget(label=label, disabled=disabled)

    def add_dropdown(self, label: str, options, *, initial_value: str, **_) -> _Widget:
        return _Widget(label=label, value=initial_value)


@dataclass
class _Labeller:
    saved: list[tuple[int, int, str, str]] = field(default_factory=list)
    selection: tuple[int, int] | None = None

    def select(self, start: int, stop: int, terrain: str | None = None) -> None:
        self.selection = (start, stop)

    def save(self, *, terrain: str, source: str) -> None:
        assert self.selection is not None
        self.saved.append((*self.selection, terrain, source))


@dataclass
class _Host:
    state: SimpleNamespace
    label_panel: _Labeller = field(default_factory=_Labeller)
    client: SimpleNamespace = field(default_factory=lambda: SimpleNamespace(gui=_Gui()))
    log: LogInfo | None = None

    def guard(self, fn) -> None:
        fn()

    def set_widget(self, handle, value) -> None:
        handle.value = value

    def show(self, log: LogInfo, *, start_s: float | None = None, stop_s: float | None = None) -> None:
        self.log = log


LOG = LogInfo(
    id=1,
    name="walk_000",
    source_path="walk_000.mcap",
    format="mcap",
    file="",
    n_samples=10_000,
    rate_hz=100.0,
    t0=0.0,
    channels=(),
)


def _queued(start: int, guess: str, reason: str = "unsure") -> Queued:
    return Queued(
        key=(1, start, start + 100), log=LOG, start=start, stop=start + 100, reason=reason, guess=guess, score=1.0
    )


class _Session:
    """Cameras of the logs: none unless given; a thumbnail is its request, so a test can see what was asked."""

    def __init__(self, cameras: dict[int, list] | None = None, broken: bool = False) -> None:
        self._cameras, self.broken, self.asked = cameras or {}, broken, []

    def cameras(self, log_id: int) -> list:
        return self._cameras.get(log_id, [])

    def camera_thumbnail(self, log_id: int, seconds: float) -> bytes:
        if self.broken:
            raise SessionError("s: log 1's camera index does not match its frames; the session was changed")
        self.asked.append((log_id, seconds))
        return b"\xff\xd8 jpeg " + str(seconds).encode()


def _panel(queue: list[Queued], session: _Session | None = None) -> tuple[SuggestPanel, _Host]:
    state = SimpleNamespace(
        queue=queue,
        strategy="combined",
        busy=None,
        scored=True,
        problem=None,
        session=session or _Session(),
        scores=SimpleNamespace(classifier=None),  # no classifier: no verification plan to say
    )
    host = _Host(state=state)
    return SuggestPanel(host), host


def test_a_suggestion_on_screen_survives_a_new_queue_and_is_accepted() -> None:
    panel, host = _panel([_queued(500, "grass"), _queued(900, "sand")])
    panel.next()
    assert panel.current.key == (1, 500, 600) and not panel.accept_button.disabled
    host.state.queue = [_queued(2000, "gravel")]  # a rescoring ranked other stretches
    panel.refresh()
    assert panel.current.key == (1, 500, 600) and not panel.accept_button.disabled
    assert "no longer ranked" in panel.info.content
    panel.accept()
    assert host.label_panel.saved == [(500, 600, "grass", "suggestion")]
    assert panel.current.key == (1, 2000, 2100)  # the next one of the new queue


def test_a_suggestion_still_ranked_takes_its_new_guess() -> None:
    panel, host = _panel([_queued(500, "grass")])
    panel.next()
    host.state.queue = [_queued(500, "sand", reason="models disagree")]
    panel.refresh()
    assert panel.current.guess == "sand" and "models disagree" in panel.info.content
    assert "no longer ranked" not in panel.info.content


def test_the_table_shows_each_suggestions_camera_frame_when_its_log_has_a_camera() -> None:
    panel, _ = _panel([_queued(500, "grass")])
    assert "<img" not in panel.table.content and "view" not in panel.table.content  # no camera: no column
    session = _Session({1: ["/camera"]})
    panel, _ = _panel([_queued(500, "grass"), _queued(900, "sand")], session)
    assert session.asked == [(1, 5.5), (1, 9.5)]  # the frame at each suggestion's middle
    assert panel.table.content.count("<img class='wb-thumb'") == 2 and "<th>view</th>" in panel.table.content
    shown = base64.b64encode(b"\xff\xd8 jpeg 5.5").decode()
    assert f"src='data:image/jpeg;base64,{shown}'" in panel.table.content


def test_a_damaged_camera_shows_no_picture_and_keeps_the_table() -> None:
    panel, _ = _panel([_queued(500, "grass")], _Session({1: ["/camera"]}, broken=True))
    assert "<img" not in panel.table.content and "grass" in panel.table.content
