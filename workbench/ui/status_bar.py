"""The line above the tabs: which model is active, how much is labelled, what the server is doing, and the two
things a person comes back to after labelling (Retrain, Export), so neither has to be found in a tab first."""

from __future__ import annotations

import html
from collections.abc import Callable
from typing import TYPE_CHECKING

from training import HELD_OUT, estimate_headline, missed_terrains, missed_words, recorded_family, runs_low, unseen_words

from ..cycle import ChecksSummary, checks_summary, estimate_disagrees
from ..expectations import card_accuracy

if TYPE_CHECKING:
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
        model = (
            f"<b>{html.escape(recorded_family(classifier.config))} v{classifier.id}</b>"
            + figure_html(classifier.metrics)
            + checks_html(checks_summary(session), classifier.metrics)
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


def figure_html(m: dict) -> str:
    """The active classifier's estimate, saying which it is; a same-run figure carries its caution, in full on hover
    (the person deciding whether to label more reads it here); then what the model that ships is expected to score
    on a run it never saw, named apart from the session's figures."""
    return _estimate_html(m) + unseen_html(m)


def unseen_html(m: dict) -> str:
    """``" · shipped, on a new run: ≈ 72 % (61–80 %)"``, the whole of it on hover; empty without the figure."""
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
    return f" · <span title='{title}'>shipped, on a new run: ≈ {100 * got['accuracy']:.0f} %{span}{low}</span>"


def _estimate_html(m: dict) -> str:
    estimate = m.get("estimate")
    if estimate:
        words = estimate_headline(estimate)
        if words is None:
            return " · <span style='color:#b26a00'>accuracy not measurable yet</span>"
        missed = missed_words(missed_terrains(estimate)).removeprefix("the model ")  # the line names the model
        misses = f" · <b style='color:{MISSED}'>{html.escape(missed)}</b>" if missed else ""
        if estimate["kind"] == HELD_OUT:
            return f" · {html.escape(words)}{misses}"
        return (
            f" · <span title='{html.escape(estimate['note'], quote=True)}'>{html.escape(words)} "
            f"<b style='color:#b26a00'>(new runs may score lower)</b></span>{misses}"
        )
    held = m.get("held_out_logs") or {}  # a version from before the estimate, or the paper family's
    acc, where = held.get("accuracy"), "on held-out logs"
    if acc is None and m.get("out_of_fold"):  # a quick fine-tune measures no held-out logs; its refit will
        acc, where = m.get("accuracy"), "out of fold"
    return f" · {100 * acc:.0f} % {where}" if acc is not None and acc == acc else ""


def checks_html(summary: ChecksSummary, m: dict) -> str:
    """What the person's own checks say (test then train: ``cycle.checks_summary``), and a warning when the card's
    figure lies outside the spot checks' 95 % interval by 10 points or more: the spot checks are the fair sample (a
    ranked suggestion is where the model is doubted, so those checks run low by design)."""
    if summary.all is None:
        return ""
    est, spot = summary.all, summary.spot
    text = f"your checks: right on {est.right} of {est.n}"
    text += f", spot checks {spot.right} of {spot.n}" if spot else ""
    card = card_accuracy(m)
    if spot is not None and card is not None and estimate_disagrees(card, spot):
        return (
            f" · <b style='color:{MISSED}' title='the model was right on {spot.right} of your {spot.n} spot "
            f"checks (95 % interval {100 * spot.low:.0f}–{100 * spot.high:.0f} %), its estimate says "
            f"{100 * card:.0f} %'>{html.escape(text)}: not what the estimate says</b>"
        )
    title = html.escape(
        "spot checks are drawn at random from the unlabelled time: the fair sample; the suggestions' checks are where "
        "the model was doubted and run low",
        quote=True,
    )
    return f" · <span title='{title}'>{html.escape(text)}</span>"


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
