"""The Retrain job: stage 2 (and stage 1 when needed) in a background thread, with progress, ETA and Cancel.

A Retrain after a few more labels runs in two phases. The quick one fine-tunes the active models on what is new, so
the highlights refresh in seconds. The refining one then trains stage 2 from scratch on every label, in the
background while the person keeps labelling, because the fine-tune gives up accuracy (QCAT-scale bench: 80.5 %
after the fine-tune, 84.7 % from scratch); when it finishes its models replace the quick ones. Pressing Retrain
during the refining phase stops it and starts a new quick one.
"""

from __future__ import annotations

import threading
import time
import traceback
from dataclasses import dataclass, field, replace

from sessions import WorkbenchError
from training import Cancelled, Progress, TrainConfig

from ..cycle import SessionScores, train_classifier, train_stage1, unseen_change
from ..retrain import RETRAIN
from ..user_errors import USER_ERRORS, one_line
from .state import SharedState
from .torch_lane import LANE


@dataclass(frozen=True)
class JobStatus:
    """What a view shows of the job: ``state`` is idle, running, refining, done, cancelled or failed.

    ``refining``: the quick models are active and stage 2 trains from scratch in the background; Retrain is allowed.
    """

    state: str = "idle"
    stages: tuple[str, ...] = ()
    stage: str = ""
    fraction: float = 0.0
    loss: float | None = None
    val_loss: float | None = None
    eta_s: float | None = None
    message: str = ""
    losses: tuple[float, ...] = field(default=())


def needs_predictor(state: SharedState) -> bool:
    """Stage 1 must (re)train: none yet, or logs were added since it trained."""
    version = state.session.active_model("predictor")
    if version is None:
        return True
    seen = version.config.get("logs")
    if seen is None:  # saved before versions recorded their logs
        return False
    from ..cycle import model_logs

    return bool({x.id for x in model_logs(state.session)} - set(seen))


class TrainJob:
    """At most one training run at a time for the whole server; every view watches the same status."""

    def __init__(
        self,
        state: SharedState,
        *,
        hidden: int = RETRAIN.hidden,
        predictor_config: TrainConfig = RETRAIN.predictor,
        classifier_config: TrainConfig = RETRAIN.classifier,
        warm_epochs: int | None = RETRAIN.warm_epochs,
        refine: bool = RETRAIN.refine,
    ) -> None:
        self.state = state
        self.hidden = hidden
        self.predictor_config, self.classifier_config = predictor_config, classifier_config
        self.warm_epochs = warm_epochs  # None: every retrain trains as long as a fresh one
        self.refine = refine  # after a quick fine-tune, train stage 2 from scratch in the background
        self.status = JobStatus()
        self._cancel = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()

    @property
    def running(self) -> bool:
        """A training run is going, quick or refining."""
        return self._thread is not None and self._thread.is_alive()

    def start(self, *, predictor: bool = False) -> str:
        """Start a retrain; returns what it will do, or raises when one runs or labels are missing."""
        with self._lock:
            if self.running and self.status.state in ("done", "refining"):  # "done": the quick phase, about to refine
                self._cancel.set()  # newer labels: stop the retrain from scratch; the new quick one comes first
                self._thread.join()  # type: ignore[union-attr]
            if self.running:
                raise WorkbenchError("a training run is already going; cancel it first")
            stages = ("predictor", "classifier") if predictor or needs_predictor(self.state) else ("classifier",)
            terrains = {s.terrain for s in self.state.session.segments()}
            if len(terrains) < 2 and stages == ("classifier",):
                raise WorkbenchError("label segments of at least two terrains before training the classifier")
            self._cancel.clear()
            self.status = JobStatus("running", stages, stages[0], message="starting")
            self._thread = threading.Thread(target=self._run, args=(stages, len(terrains) >= 2), daemon=True)
            self._thread.start()
        self.state.notify("job")
        return " + ".join(stages)

    def cancel(self) -> None:
        self._cancel.set()

    def join(self, timeout: float = 30.0) -> None:
        """Wait for a training run to end (after :meth:`cancel`, at its next poll)."""
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    def _progress(self, stages: tuple[str, ...], started: float):
        last = [0.0]

        def report(p: Progress) -> None:
            done = stages.index(p.stage) if p.stage in stages else 0
            fraction = (done + p.fraction) / len(stages)
            elapsed = time.monotonic() - started
            eta = elapsed / fraction * (1 - fraction) if fraction > 0.02 else None
            losses = self.status.losses
            prefix = "from scratch, " if self.status.state == "refining" else ""
            if p.step == p.steps:  # one point per epoch on the live loss plot
                losses = (*losses[-199:], p.train_loss)
            self.status = replace(
                self.status,
                stage=p.stage,
                fraction=fraction,
                loss=p.train_loss,
                val_loss=p.val_loss,
                eta_s=eta,
                losses=losses,
                message=f"{prefix}{p.stage}: fold {max(p.fold, 1)}/{p.folds}, epoch {p.epoch}",
            )
            now = time.monotonic()
            if now - last[0] > 0.5:  # views redraw at most twice a second
                last[0] = now
                self.state.notify("job")

        return report

    def _run(self, stages: tuple[str, ...], can_classify: bool) -> None:
        started = time.monotonic()
        progress = self._progress(stages, started)
        predictor_run = "predictor" in stages  # new features: the classifier starts afresh anyway
        quick = None  # the version a warm fine-tune saved: the refining phase follows it
        fell = None  # a line when the model that ships fell on runs it never saw
        hidden = self.hidden
        # a classifier's scores come next and the queue is ranked from them; a new stage 1 takes minutes, during
        # which the queue keeps following the person's labels
        self.state.hold_queue = stages == ("classifier",)
        try:
            if "predictor" in stages:
                LANE.run(
                    train_stage1,  # the family of the active classifier (the default family's before any)
                    self.state.session,
                    config=self.predictor_config,
                    hidden=self.hidden,
                    progress=progress,
                    cancel=self._cancel.is_set,
                )
                self.state.notify("models")
            if can_classify:
                p = self.state.session.active_model("predictor")
                hidden = int(p.config.get("hidden", self.hidden)) if p is not None else self.hidden
                warm_epochs = None if predictor_run else self.warm_epochs
                version = LANE.run(
                    train_classifier,
                    self.state.session,
                    config=self.classifier_config,
                    warm_epochs=warm_epochs,
                    hidden=hidden,
                    progress=progress,
                    cancel=self._cancel.is_set,
                    scores=self._known(),
                )
                if warm_epochs is not None and version.config.get("warm_start"):
                    quick = version
                fell = unseen_change(self.state.session, version)
            took = time.monotonic() - started
            self.status = replace(
                self.status,
                state="done",
                fraction=1.0,
                eta_s=0.0,
                message=f"done in {took:.0f} s; refreshing highlights" + (f"; {fell}" if fell else ""),
            )
        except Cancelled:
            self.status = replace(self.status, state="cancelled", message="cancelled; nothing was saved")
        except USER_ERRORS as exc:
            self.status = replace(self.status, state="failed", message=one_line(exc))
        except Exception as exc:
            traceback.print_exc()
            self.status = replace(self.status, state="failed", message=f"{type(exc).__name__}: {exc}")
        finally:
            self.state.hold_queue = False
        self.state.notify("models")
        self.state.notify("job")
        if self.status.state == "done":
            self.state.refresh(scores=True, first=self.state.viewed_logs())
            if quick is not None and self.refine:
                self._refine(quick.id, hidden)
        else:  # nothing new to score: the queue held back meanwhile is ranked now
            self.state.refresh(scores=False)

    def _known(self) -> SessionScores | None:
        """The scores the page shows (a classifier's, blended with the runs' label votes): what the session knows
        of its runs' unlabelled time, on which a fit from scratch judges the runs it holds out."""
        scores = self.state.scores
        return scores if scores.classifier is not None else None

    def _refine(self, quick: int, hidden: int) -> None:
        """Stage 2 from scratch on every label once the quick models' highlights are up; its models replace them."""
        self.status = replace(
            self.status,
            state="refining",
            fraction=0.0,
            eta_s=None,
            losses=(),
            message=f"quick model v{quick} is active; training from scratch once its highlights are drawn",
        )
        self.state.notify("job")
        # the rescore and the training would share 2 cores: the highlights a person waits for go first
        if not self.state.wait_idle(stop=self._cancel.is_set):
            self.status = replace(self.status, state="done", message=f"quick model v{quick} is active")
            self.state.notify("job")
            return
        started = time.monotonic()
        replaced = False
        try:
            version = LANE.run(
                train_classifier,
                self.state.session,
                config=self.classifier_config,
                warm_start=False,
                hidden=hidden,
                progress=self._progress(("classifier",), started),
                cancel=self._cancel.is_set,
                scores=self._known(),
            )
            took = time.monotonic() - started
            replaced = True
            fell = unseen_change(self.state.session, version)
            self.status = replace(
                self.status,
                state="done",
                fraction=1.0,
                eta_s=0.0,
                message=f"v{version.id}, trained from scratch in {took:.0f} s, replaced the quick v{quick}; "
                "refreshing highlights" + (f"; {fell}" if fell else ""),
            )
        except Cancelled:
            self.status = replace(
                self.status, state="done", message=f"quick model v{quick} is active; the retrain from scratch stopped"
            )
        except Exception as exc:
            if not isinstance(exc, USER_ERRORS):
                traceback.print_exc()
            self.status = replace(
                self.status,
                state="failed",
                message=f"the retrain from scratch failed ({one_line(exc)}); quick model v{quick} stays active",
            )
        self.state.notify("models")
        self.state.notify("job")
        if replaced:
            self.state.refresh(scores=True, first=self.state.viewed_logs())
