"""The Train tab: Retrain in the background (progress, live loss, time left, Cancel), model versions with their
metrics and confusion matrix, making an older version active, and the learning curve across versions."""

from __future__ import annotations

import html
from typing import TYPE_CHECKING

import numpy as np

import labeling
from sessions import COUNTED_KINDS, WorkbenchError
from training import estimate_headline, majority_words, recorded_family

from .plots import confusion_image, learning_curve_image

if TYPE_CHECKING:
    from .host import PanelHost


class TrainPanel:
    def __init__(self, host: PanelHost) -> None:
        self.host = host
        gui = host.client.gui
        self.retrain_button = gui.add_button(
            "Retrain (R)", icon="refresh", color="green", hint="Stage 2 on the labels; stage 1 too when logs were added"
        )
        self.retrain_button.on_click(lambda _: host.guard(self.retrain))
        self.stage1 = gui.add_checkbox(
            "Also retrain the predictor (stage 1)",
            False,
            hint="Slow: only needed after adding logs (done then on its own)",
        )
        self.progress = gui.add_progress_bar(0.0, visible=False)
        self.status = gui.add_html("")
        self.cancel_button = gui.add_button("Cancel", icon="x", color="red", visible=False)
        self.cancel_button.on_click(lambda _: host.guard(host.job.cancel))
        self.loss_plot = gui.add_uplot(
            (np.zeros(2), np.zeros(2)),
            ({"label": "epoch"}, {"label": "train loss", "stroke": "#2e7d32", "width": 1.5}),
            scales={"x": {"time": False}},
            height=110,
            visible=False,
            legend={"show": False},
        )
        with gui.add_folder("Model versions"):
            self.versions = gui.add_html("")
            self.version_pick = gui.add_dropdown("Version", ("(none)",))
            self.activate_button = gui.add_button("Make active", icon="player-play")
            self.activate_button.on_click(lambda _: host.guard(self.activate))
            self.confusion = gui.add_image(
                np.full((10, 10, 3), 255, np.uint8), label="Confusion (out of fold, same logs)", visible=False
            )
        with gui.add_folder("Learning curve"):
            self.curve = gui.add_image(np.full((10, 10, 3), 255, np.uint8), visible=False)
        self._drawn_versions: tuple = ()
        self.refresh("models")

    def retrain(self) -> None:
        job = self.host.job
        what = job.start(predictor=bool(self.stage1.value))
        self.host.notify(
            "Training started", f"{what}; keep labelling, the page refreshes when it is done", color="blue"
        )

    def activate(self) -> None:
        value = self.version_pick.value
        if not value.startswith("v"):
            raise WorkbenchError("no version chosen")
        vid = int(value[1:].split()[0])
        if self.host.job.running:
            raise WorkbenchError("a training run is going; wait for it or cancel it first")
        self.host.state.session.activate_model(vid)
        self.host.state.notify("models")
        self.host.state.refresh(scores=True)
        self.host.notify("Active", f"model v{vid} is active; highlights refresh")

    def refresh(self, event: str) -> None:
        job, state = self.host.job, self.host.state
        st = job.status
        running = st.state in ("running", "refining")
        self.retrain_button.disabled = st.state == "running"  # while refining, Retrain starts a newer quick one
        self.cancel_button.visible = running
        self.progress.visible = running
        if running:
            self.progress.value = round(100 * st.fraction, 1)
        eta = f", about {_duration(st.eta_s)} left" if running and st.eta_s is not None else ""
        loss = (
            f"<br>loss {st.loss:.4f}" + (f" (validation {st.val_loss:.4f})" if st.val_loss is not None else "")
            if st.loss is not None and running
            else ""
        )
        colour = {"failed": "#c62828", "cancelled": "#ef6c00", "done": "#2e7d32", "refining": "#1565c0"}.get(
            st.state, "#333"
        )
        text = (
            f"<b style='color:{colour}'>{html.escape(st.state)}</b>: {html.escape(st.message)}{eta}{loss}"
            if st.state != "idle"
            else "<span style='color:#666'>No training run yet in this server.</span>"
        )
        if state.busy:
            text += f"<br><i>{html.escape(state.busy)}…</i>"
        self.status.content = f"<div style='font-size:0.8em'>{text}</div>"
        if running and len(st.losses) >= 2:
            self.loss_plot.visible = True
            self.loss_plot.data = (np.arange(1, len(st.losses) + 1, dtype=np.float64), np.asarray(st.losses))
        elif not running:
            self.loss_plot.visible = False
        if event in ("models", "scores"):
            self._versions()

    def _versions(self) -> None:
        versions = self.host.state.session.model_versions()
        checks = [c for c in self.host.state.session.checks() if c.kind in COUNTED_KINDS]
        key = (tuple((v.id, v.active) for v in versions), len(checks))
        if key == self._drawn_versions:
            return
        self._drawn_versions = key
        rows = []
        for v in reversed(versions):
            m = v.metrics
            if v.stage == "classifier":
                held, estimate = m.get("held_out_logs"), m.get("estimate")
                if estimate:
                    balanced = estimate.get("balanced_accuracy")
                    baseline = majority_words(estimate)
                    figure = (
                        f"{estimate_headline(estimate) or 'accuracy not measurable'}, "
                        + (f"balanced {100 * balanced:.0f} %, " if balanced is not None else "")
                        + (f"{baseline}, " if baseline else "")
                        + f"{estimate['note']}, "
                    )
                else:  # a version from before the estimate, a quick fine-tune, the paper family
                    figure = (f"acc {100 * held['accuracy']:.1f} % on held-out logs, " if held else "") + (
                        f"acc {100 * m.get('accuracy', float('nan')):.1f} % (same logs), "
                    )
                tested = labeling.check_estimate([c.right for c in checks if c.classifier == v.id])
                what = (
                    f"{recorded_family(v.config)}: {figure}"
                    f"F1 {m.get('macro_f1', float('nan')):.2f}, "
                    f"{m.get('labelled_seconds', 0):.0f} s labelled"
                    + (", quick fine-tune" if v.config.get("new_labels") is not None else "")
                    + (f"; your checks of it: {tested.words()}" if tested is not None else "")
                )
            elif "copy_last_mse" in m:  # the default family's next-frame predictor: a fixed number of steps
                what = (
                    f"next-frame error {m.get('train_mse', float('nan')):.3f} against "
                    f"{m['copy_last_mse']:.3f} for copying the last frame"
                )
            else:
                what = f"val MSE {m.get('val_mse', float('nan')):.4f}, {m.get('epochs', '?')} epochs"
            act = " <b style='color:#2e7d32'>active</b>" if v.active else ""
            if "taught_from" in v.config:  # kept beside the active version for the export: what the robot gets
                source = int(v.config["taught_from"])
                act += f" <b style='color:#6a1b9a'>ships (taught by the session from v{source})</b>"
            rows.append(f"<tr><td>v{v.id}</td><td>{html.escape(v.stage)}</td><td>{html.escape(what)}{act}</td></tr>")
        self.versions.content = (
            "<table style='width:100%;font-size:0.75em'>" + "".join(rows) + "</table>"
            if rows
            else "<small>No models yet. Press Retrain.</small>"
        )
        opts = tuple(f"v{v.id} {v.stage}" + (" (active)" if v.active else "") for v in reversed(versions))
        with self.host.quiet():
            self.version_pick.options = opts or ("(none)",)
        active = next((v for v in versions if v.active and v.stage == "classifier"), None)
        if active is not None and active.metrics.get("confusion"):
            m = active.metrics
            self.confusion.image = confusion_image(
                m["confusion"], m.get("classes", []), title=f"v{active.id}: accuracy {100 * m['accuracy']:.1f} %"
            )
            self.confusion.visible = True
        points = [
            (
                v.metrics.get("labelled_seconds", 0.0),
                v.metrics.get("accuracy", 0.0),
                v.metrics.get("macro_f1", 0.0),
                v.id,
            )
            for v in versions
            if v.stage == "classifier"
        ]
        if points:
            self.curve.image = learning_curve_image(points)
            self.curve.visible = True


def _duration(seconds: float) -> str:
    m, s = divmod(round(seconds), 60)
    return f"{m} min {s:02d} s" if m else f"{s} s"
