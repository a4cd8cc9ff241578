"""The line above the tabs: which model is active, how much is labelled, what the server is doing, and the two
things a person comes back to after labelling (Retrain, Export), so neither has to be found in a tab first."""

from __future__ import annotations

import html
from collections.abc import Callable
from typing import TYPE_CHECKING

from training import HELD_OUT, estimate_headline, missed_terrains, missed_words, recorded_family, runs_low, unseen_words

from ..cycle import SessionFigure, checks_summary, kept_taught, session_figures

if TYPE_CHECKING:
    from sessions import ModelVersion

    from .host import PanelHost

RETRAIN = "Retrain"
EXPORT = "Export"
MISSED = "#c62828"  # what the model misses or is expected to miss: a terrain, a log


def status_html(host: PanelHost) -> str:
    """The status line: active classifier (or predictor) with its held-out accuracy, labels, what runs."""
    state, job = host.state, host.job
    session = state.session
    classifier = session.active_model("classifier")
    predictor = session.active_model("predictor")
    if classifier is not None:
        scores = state.scores
        figure = session_figures(session, scores).session if scores.classifier == classifier.id else None
        model = (
            f"<b>{html.escape(recorded_family(classifier.config))} v{classifier.id}</b>"
            + session_html(figure, checks=_checked_words(session))
            + figure_html(classifier.metrics, taught=kept_taught(session))
        )
    elif predictor is not None:
        model = f"<b>stage 1 v{predictor.id}</b> · no classifier yet"
    else:
        model = "<b>no model yet</b>"
    segments = session.segments()
    rates = {x.id: x.rate_hz for x in state.logs()}
    seconds = sum(s.length / rates.get(s.log_id, 1.0) for s in segments)
    terrains = len({s.terrain for s in segments})
    labels = f"{len(segments)} labels · {seconds:.0f} s · {terrains} terrains"
    st = job.status
    if st.state in ("running", "refining"):
        doing = f"training {100 * st.fraction:.0f} %"
    elif state.busy:
        doing = state.busy
    elif st.state in ("failed", "cancelled"):
        doing = f"last training {st.state}"
    else:
        doing = ""
    doing_html = f" · <i style='color:#1565c0'>{html.escape(doing)}…</i>" if doing else ""
    return f"<div style='font-size:0.8em;line-height:1.5'>{model}<br>{labels}{doing_html}</div>"


def figure_html(m: dict, *, taught: ModelVersion | None = None) -> str:
    """The fit's own figures, each named: what the model that ships is expected to score on a run it never saw (the
    ``taught`` version's, the one the export ships, once one is kept), then its figure on the labelled pieces (held
    out), which describes where the labels were placed, not the session."""
    if taught is not None and taught.metrics.get("unseen_runs"):
        return unseen_html(taught.metrics, taught=taught.id) + _estimate_html(m)
    return unseen_html(m) + _estimate_html(m)


def _checked_words(session) -> str:
    every = checks_summary(session).all
    return "" if every is None else f"; all your checks, of every version: right on {every.right} of {every.n}"


def session_html(figure: SessionFigure | None, *, checks: str = "") -> str:
    """``" · the session: ≈ 97 % (90 % interval 93–99 %, from 24 checks of this version)"``, or ``"not checked
    since the last Retrain"`` in amber; on hover what it is and how many checks Verify would take to narrow it."""
    if figure is None:
        return " · the session: <i>scoring…</i>"
    what = (
        "the share of the time nobody labelled that this version names right: from your spot checks of it (pieces "
        "drawn at random there), corrected by its confidence over all that time. A check tests the version that was "
        "active when it was made; after a Retrain, Verify (Suggest tab) asks for fresh ones: "
        f"{figure.plan_words()}{checks}"
    )
    text = html.escape(figure.words())
    if figure.figure is None:
        text = f"<b style='color:#b26a00'>{text}</b>"
    return f" · <span title='{html.escape(what, quote=True)}'>the session: {text}</span>"


def unseen_html(m: dict, *, taught: int | None = None) -> str:
    """``" · shipped, on a new run: ≈ 72 % (61–80 %)"`` (``taught``: "shipped (taught v12), ..."), the whole of it on
    hover; empty without the figure."""
    got = m.get("unseen_runs") or {}
    words = unseen_words(got)
    if words is None:
        return ""
    span = "" if got.get("low") is None else f" ({100 * got['low']:.0f}–{100 * got['high']:.0f} %)"
    title = html.escape(
        f"the model that ships, on a run it never saw: {words}. Each held-out run scored by a model fitted without "
        "it, on its labels and the terrain the session's scores are sure of: what the exported bundle is expected "
        "to do on the robot's next run, not the session's own accuracy",
        quote=True,
    )
    low = " <b style='color:#b26a00'>(runs low: few runs)</b>" if runs_low(got) else ""
    which = "shipped" if taught is None else f"shipped (taught v{taught})"
    return f" · <span title='{title}'>{which}, on a new run: ≈ {100 * got['accuracy']:.0f} %{span}{low}</span>"


LABELLED = (
    "the fit's figure on the labelled pieces, each predicted by a model fitted without it: it describes where the "
    "labels are, and suggestions place them where the model was unsure, so after a few rounds it runs far below the "
    "session's accuracy"
)


def _estimate_html(m: dict) -> str:
    """The fit's figure on the labelled pieces, in grey: never the session's headline (a loop that labels the hard
    places drives it down while the session's accuracy rises); the terrains it misses named on hover."""
    estimate = m.get("estimate")
    if estimate:
        words = estimate_headline(estimate)
        if words is None:
            return ""
        missed = missed_words(missed_terrains(estimate)).removeprefix("the model ")  # the line names the model
        caution = "" if estimate["kind"] == HELD_OUT else f"; {estimate['note']} (new runs may score lower)"
        title = html.escape(f"{LABELLED}{caution}" + (f"; on those pieces it {missed}" if missed else ""), quote=True)
        return f" · <span style='color:#666' title='{title}'>labelled pieces: {html.escape(words)}</span>"
    held = m.get("held_out_logs") or {}  # a version from before the estimate, or the paper family's
    acc, where = held.get("accuracy"), "on held-out logs"
    if acc is None and m.get("out_of_fold"):  # a quick fine-tune measures no held-out logs; its refit will
        acc, where = m.get("accuracy"), "out of fold"
    if acc is None or acc != acc:
        return ""
    title = html.escape(LABELLED, quote=True)
    return f" · <span style='color:#666' title='{title}'>labelled pieces: {100 * acc:.0f} % {where}</span>"


class StatusBar:
    """The status line and its Retrain / Export buttons; redrawn on label, model, job and score events."""

    def __init__(self, host: PanelHost, *, retrain: Callable[[], None], export: Callable[[], None]) -> None:
        self.host = host
        gui = host.client.gui
        self.line = gui.add_html("")
        self.buttons = gui.add_button_group(
            "Model",
            (RETRAIN, EXPORT),
            hint="Retrain (key R): stage 2 on the labels, in the background. "
            "Export: the model bundle (PyTorch, ONNX, card) as a zip",
        )
        actions = {RETRAIN: retrain, EXPORT: export}
        self.buttons.on_click(lambda event: host.guard(actions[event.target.value]))
        self._drawn = ""

    def refresh(self) -> None:
        content = status_html(self.host)
        if content != self._drawn:  # job progress arrives twice a second: send only what changed
            self._drawn = content
            self.line.content = content
