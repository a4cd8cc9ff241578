"""The session as a Label Studio ML backend: what each of the protocol's endpoints answers.

Label Studio asks ``/health`` and ``/setup`` when a project connects the backend, ``/predict`` for its tasks'
pre-annotations, and tells ``/webhook`` of annotations and of "Start training". The answers come from the state the
page shares (``workbench.ui.SharedState``: the scores, the model's stretches, the suggestion queue, labels with
their checks) and its training job, so a label made in Label Studio is made as the page makes one.

Decided where the protocol is silent: Label Studio adds labels to the session and never removes them. An annotation
updated or deleted there leaves the session's labels as they are (a region dropped in Label Studio is no reason to
lose a label that may have merged with the page's; remove it in the workbench); a region that would overlap another
terrain's label is refused for that region, the others kept. A region already labelled so is no change, so a
replayed event changes nothing.

A label made in Label Studio is a check of the model (test then train) as the page's are, of the version whose
pre-annotation the annotator saw: the backend remembers which version answered each task, and where a Retrain has
landed since, the label is kept without a check (the session no longer holds that version's answer to compare).
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import labeling
from sessions import LabelError, LogInfo, label_studio_frame, task_log

from ..cycle import names_now
from ..ui import JobStatus, SharedState
from .label_config import LabelConfig, name_key, parse_label_config

SOURCE = "label-studio"  # the labels' source, as the page's are "manual" or "accepted"
EVENTS = ("ANNOTATION_CREATED", "ANNOTATION_UPDATED", "ANNOTATION_DELETED", "START_TRAINING")
REMEMBERED_TASKS = 200_000  # tasks whose predicting version is kept (a few MB); the oldest forgotten first


@dataclass
class Backend:
    """The endpoints' answers, each ``(HTTP status, JSON body)``.

    Attributes:
        state: What the page's views share.
        start_training: Starts a Retrain in the background (``TrainJob.start``), returns what it said.
        job_status: The training job's status.
        create_terrains: A terrain Label Studio names that the session lacks is added (else that region is refused).
        wait_s: How long ``/predict`` waits for a scoring in progress before answering from what it has (Label
            Studio gives up after 100 s).
        say: Where a line about a refused task or region goes (the backend's terminal).
    """

    state: SharedState
    start_training: Callable[[], str]
    job_status: Callable[[], JobStatus]
    create_terrains: bool = False
    wait_s: float = 60.0
    say: Callable[[str], None] = print
    _configs: dict[str, LabelConfig] = field(default_factory=dict)
    _predicted: OrderedDict[str, str] = field(default_factory=OrderedDict)  # task id -> the version that answered
    _lock: threading.Lock = field(default_factory=threading.Lock)  # the server answers each request in a thread

    # ------------------------------------------------------------------------------------------- handshake
    def model_version(self) -> str:
        """The active classifier's version as Label Studio shows it (``v12``), ``none`` before one."""
        active = self.state.session.active_model("classifier")
        return "none" if active is None else f"v{active.id}"

    def health(self) -> tuple[int, dict]:
        return 200, {"status": "UP", "model_class": "TerrainWorkbench"}

    def setup(self, body: dict) -> tuple[int, dict]:
        """Keep the project's config; answer with the model version. Loads no model."""
        project = str(body.get("project", "")).split(".", 1)[0]
        try:
            self._configs[project] = parse_label_config(body.get("schema"))
        except ValueError as exc:
            return 400, {"error": str(exc)}
        return 200, {"model_version": self.model_version()}

    # ------------------------------------------------------------------------------------------- predict
    def predict(self, body: dict) -> tuple[int, dict]:
        """One prediction per task, in order: the model's stretches as regions with their confidence, and the
        task's score, lowest for the task whose log holds the queue's first suggestion ("sort by prediction score,
        ascending" is the workbench's order). A task the session cannot read gets an empty prediction and says why
        (``error``); the others are answered."""
        tasks = body.get("tasks")
        if not isinstance(tasks, list):
            return 400, {"error": "the request holds no list of tasks"}
        try:
            config = parse_label_config(body.get("label_config"))
        except ValueError as exc:
            return 400, {"error": str(exc)}
        project = str(body.get("project", "")).split(".", 1)[0]
        if not config.labels and project in self._configs:
            config = self._configs[project]
        state = self.state
        state.wait_idle(stop=lambda: False, deadline_s=self.wait_s)  # a scoring under way: its stretches, if in time
        scores, logs = state.scores, state.logs()
        version = self.model_version() if scores.classifier is None else f"v{scores.classifier}"  # what answers
        names = names_now(state.session, scores) if scores.classes else []
        first = _first_in_queue(state)
        results = []
        for i, task in enumerate(tasks, start=1):
            data = task.get("data") if isinstance(task, dict) else None
            log = task_log(data, logs)
            if log is None:
                why = (
                    f"task {i}{_task_id(task)}: names no log of this session (data.log, or a data file named after "
                    "one): `workbench ingest SESSION FILE` adds it, then Retrieve Predictions again"
                )
                self.say(f"label-studio: {why}")
                results.append({"result": [], "score": 1.0, "model_version": version, "error": why})
                continue
            regions = self._regions(log, names, config)
            score = first.get(log.id, 1.0)
            if isinstance(task, dict) and "id" in task:
                self._remember(str(task["id"]), version)
            results.append({"result": regions, "score": score, "model_version": version})
        return 200, {"results": results}

    def _remember(self, task_id: str, version: str) -> None:
        with self._lock:
            self._predicted[task_id] = version
            self._predicted.move_to_end(task_id)
            while len(self._predicted) > REMEMBERED_TASKS:
                self._predicted.popitem(last=False)

    def _regions(self, log: LogInfo, names: list[str], config: LabelConfig) -> list[dict]:
        """The model's stretches of ``log`` as ``timeserieslabels`` regions on the log's clock."""
        scale = 1e3 if config.dates else 1.0
        out = []
        for k, s in enumerate(self.state.stretches(log.id)):
            if not 0 <= s.terrain < len(names) or (label := config.label_for(names[s.terrain])) is None:
                continue  # a terrain the project does not offer
            out.append(
                {
                    "id": f"wb{log.id}-{k}",
                    "from_name": config.from_name,
                    "to_name": config.to_name,
                    "type": "timeserieslabels",
                    "value": {
                        "start": (log.t0 + s.start / log.rate_hz) * scale,
                        "end": (log.t0 + s.stop / log.rate_hz) * scale,
                        "instant": False,
                        "timeserieslabels": [label],
                    },
                    "score": round(float(s.confidence), 4) if math.isfinite(s.confidence) else 0.0,  # JSON has no NaN
                }
            )
        return out

    # ------------------------------------------------------------------------------------------- webhook
    def webhook(self, body: dict) -> tuple[int, dict]:
        """An annotation's regions become the session's labels; "Start training" starts a Retrain."""
        action = body.get("action")
        if action not in EVENTS:
            return 200, {"status": f"not an event the workbench acts on: {action!r}"}
        if action == "START_TRAINING":
            said = self.start_training()
            return 201, {"status": "ok", "result": said, "job": self.job_status().state}
        if action != "ANNOTATION_CREATED" and action != "ANNOTATION_UPDATED":
            return 201, {
                "status": "ok",
                "result": "kept: a deleted annotation removes no label of the session (remove it in the workbench)",
            }
        return self._annotation(body)

    def _annotation(self, body: dict) -> tuple[int, dict]:
        task, annotation = body.get("task"), body.get("annotation")
        if not isinstance(task, dict) or not isinstance(annotation, dict):
            return 400, {"error": "the event holds no task and annotation"}
        one = {
            "data": task.get("data") or {},
            "annotations": [annotation],
            **({"id": task["id"]} if "id" in task else {}),
        }
        state = self.state
        try:
            rows = label_studio_frame([one], state.logs(), path=Path("label-studio"))
        except LabelError as exc:
            self.say(f"label-studio: {exc}")
            return 422, {"error": str(exc)}
        log = task_log(one["data"], state.logs())
        assert log is not None or rows.empty  # the frame refused a task naming no log
        with self._lock:
            seen = self._predicted.get(str(task["id"])) if "id" in task else None
        now = state.scores.classifier
        check = seen is None or now is None or seen == f"v{now}"  # not predicted here: the version on screen
        added, same, refused = 0, 0, []
        for row in rows.itertuples(index=False):
            start, stop = round(row.start_s * log.rate_hz), min(round(row.end_s * log.rate_hz), log.n_samples)
            terrain = self._terrain(row.terrain)
            if terrain is None:
                refused.append(f"{row.at}: no terrain {row.terrain!r} in the session (start with --create-terrains)")
                continue
            if _covered(state, log.id, start, stop, terrain):
                same += 1  # a replayed event, or the same label made twice: nothing changes
                continue
            try:
                author = row.author or "label-studio"
                state.add_label(log.id, start, stop, terrain, author=author, source=SOURCE, check=check)
                added += 1
            except LabelError as exc:
                refused.append(f"{row.at}: {exc}")
        for line in refused:
            self.say(f"label-studio: {line}")
        words = f"{added} label(s) added, {same} already so" + (f", {len(refused)} refused" if refused else "")
        if added and not check:
            words += f" (not counted as a check of the model: {seen} predicted the task, the session now scores v{now})"
        return (201 if not refused else 207), {"status": "ok", "result": words, "refused": refused}

    def _terrain(self, name: str) -> str | None:
        """The session's terrain Label Studio's ``name`` is (case and spaces aside), added if allowed."""
        for t in self.state.terrains():
            if name_key(t.name) == name_key(name):
                return t.name
        if not self.create_terrains:
            return None
        self.state.change_terrains("add", name)
        return name


def _covered(state: SharedState, log_id: int, start: int, stop: int, terrain: str) -> bool:
    """Whether ``[start, stop)`` of the log is labelled ``terrain`` already, all of it."""
    mine = [(g.start, g.stop) for g in state.session.segments(log_id) if g.terrain == terrain]
    return not labeling.uncovered(start, stop, mine)


def _first_in_queue(state: SharedState) -> dict[int, float]:
    """Per log, a score in (0, 1) by where its first suggestion stands in the queue (the first: the lowest)."""
    queue = list(state.queue)
    out: dict[int, float] = {}
    for i, q in enumerate(queue):
        out.setdefault(q.log.id, round((i + 1) / (len(queue) + 1), 6))
    return out


def _task_id(task: object) -> str:
    return f" (id {task['id']})" if isinstance(task, dict) and "id" in task else ""
