"""`workbench label-studio`: the session as a Label Studio ML backend, driven over HTTP as Label Studio drives it
(the protocol's JSON: /health, /setup, /predict, /webhook)."""

from __future__ import annotations

import base64
import json
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from sessions import Session
from workbench.cli import main
from workbench.label_studio import MAX_BODY, serve_label_studio

from ..cycle.test_default_family import trained_demo_session

pytestmark = pytest.mark.usefixtures("fast_window_fits")
CONFIG = """<View>
  <TimeSeriesLabels name="surface" toName="signals">
    <Label value="Concrete"/><Label value="Grass"/><Label value="Gravel"/><Label value="Mulch"/>
    <Label value="Dirt"/><Label value="Sand"/>
  </TimeSeriesLabels>
  <TimeSeries name="signals" valueType="url" value="$csv" timeColumn="time"><Channel column="imu/a.x"/></TimeSeries>
</View>"""


def _call(url: str, path: str, body: object = None, *, auth: tuple[str, str] | None = None, raw: bytes | None = None):
    """``(status, JSON)`` of a GET (no body) or a POST."""
    data = raw if raw is not None else None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(url + path, data=data, method="GET" if data is None else "POST")
    request.add_header("Content-Type", "application/json")
    if auth is not None:
        request.add_header("Authorization", "Basic " + base64.b64encode(f"{auth[0]}:{auth[1]}".encode()).decode())
    try:
        with urllib.request.urlopen(request, timeout=120) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read() or b"{}")


class Backend:
    """``serve_label_studio`` in a thread on a free port (the test's thread stays free to call it)."""

    def __init__(self, session: Session, **options) -> None:
        self.ready, self.stop, self.lines = threading.Event(), threading.Event(), []
        self.port = _free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.thread = threading.Thread(
            target=serve_label_studio,
            args=(session,),
            kwargs={
                "host": "127.0.0.1",
                "port": self.port,
                "auth": None,
                "ready": self.ready,
                "stop": self.stop,
                **options,
            },
            daemon=True,
        )
        self.thread.start()
        assert self.ready.wait(60)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(60)


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Session:
    s = trained_demo_session(tmp_path_factory.mktemp("ls"), seed=11, label_seed=3)
    yield s
    s.close()


@pytest.fixture(scope="module")
def backend(session: Session):
    b = Backend(session, create_terrains=False)
    yield b
    b.close()


def _tasks(session: Session, tmp_path: Path) -> list[dict]:
    """The session's logs as Label Studio tasks, as `labels export --format label-studio` writes them."""
    out = tmp_path / "ls.json"
    assert main(["labels", "export", str(session.path), "--out", str(out), "--format", "label-studio"]) == 0
    return [{"id": 100 + i, "data": t["data"]} for i, t in enumerate(json.loads(out.read_text()))]


def test_health_and_setup_answer_with_the_active_version(backend: Backend, session: Session) -> None:
    assert _call(backend.url, "/health") == (200, {"status": "UP", "model_class": "TerrainWorkbench"})
    status, body = _call(backend.url, "/setup", {"project": "3.1700000000", "schema": CONFIG})
    assert status == 200 and body == {"model_version": f"v{session.active_model('classifier').id}"}


def test_predict_answers_every_task_in_order_with_the_models_stretches(backend, session, tmp_path) -> None:
    tasks = _tasks(session, tmp_path)
    broken = {"id": 7, "data": {"csv": "/data/upload/1/somewhere-else.csv"}}
    status, body = _call(backend.url, "/predict", {"tasks": [tasks[0], broken, tasks[1]], "label_config": CONFIG})
    assert status == 200 and len(body["results"]) == 3
    version = f"v{session.active_model('classifier').id}"
    first, refused, second = body["results"]
    assert refused["result"] == [] and "task 2 (id 7): names no log of this session" in refused["error"]
    assert "`workbench ingest SESSION FILE` adds it" in refused["error"]  # what to do about it
    for prediction, log in ((first, session.logs()[0]), (second, session.logs()[1])):
        assert prediction["model_version"] == version and prediction["result"]
        regions = prediction["result"]
        assert {(r["from_name"], r["to_name"], r["type"]) for r in regions} == {
            ("surface", "signals", "timeserieslabels")
        }
        assert all(r["value"]["timeserieslabels"][0] in CONFIG for r in regions)  # the project's spelling
        assert all(0 < r["score"] <= 1 for r in regions)
        starts = [r["value"]["start"] for r in regions]
        assert starts == sorted(starts) and starts[0] == pytest.approx(log.t0)  # the log's clock, from its start
        assert regions[-1]["value"]["end"] == pytest.approx(log.t0 + log.n_samples / log.rate_hz)
    # ascending scores follow the queue: the log of the first suggestion comes first (the page's queue, as
    # `workbench suggest` writes it)
    import pandas as pd

    assert main(["suggest", str(session.path), "--out", str(tmp_path / "next.csv")]) == 0
    queue_first = pd.read_csv(tmp_path / "next.csv")["log"].iloc[0]
    lowest = min((first, second), key=lambda p: p["score"])
    assert (tasks[0] if lowest is first else tasks[1])["data"]["log"] == queue_first


def test_an_annotation_becomes_labels_once_and_a_deleted_one_removes_none(backend, session, tmp_path) -> None:
    tasks = _tasks(session, tmp_path)
    log = session.logs()[1]
    free = _free_span(session, log.id, 3.0)
    region = {
        "id": "r1",
        "from_name": "surface",
        "to_name": "signals",
        "type": "timeserieslabels",
        "value": {"start": log.t0 + free, "end": log.t0 + free + 3.0, "instant": False, "timeserieslabels": ["Sand"]},
    }
    event = {
        "action": "ANNOTATION_CREATED",
        "task": tasks[1],
        "annotation": {"id": 55, "completed_by": {"id": 2, "email": "ana@field.team"}, "result": [region]},
        "project": {"id": 3, "label_config": CONFIG},
    }
    before = len(session.segments())
    status, body = _call(backend.url, "/webhook", event)
    assert status == 201 and body["result"] == "1 label(s) added, 0 already so", body
    added = [g for g in session.segments(log.id) if g.author == "ana@field.team"]
    assert len(added) == 1 and added[0].terrain == "sand" and added[0].source == "label-studio"
    assert added[0].stop - added[0].start == pytest.approx(3.0 * log.rate_hz, abs=1)
    # replayed: nothing changes
    assert _call(backend.url, "/webhook", event)[1]["result"] == "0 label(s) added, 1 already so"
    assert len(session.segments()) == before + 1
    # deleted in Label Studio: the session keeps its label
    status, body = _call(backend.url, "/webhook", {**event, "action": "ANNOTATION_DELETED"})
    assert status == 201 and "removes no label" in body["result"] and len(session.segments()) == before + 1
    # a region over another terrain's label, and a terrain the session lacks: refused, each in a line; others kept
    other = dict(region, id="r2", value={**region["value"], "timeserieslabels": ["Grass"]})
    unknown = dict(region, id="r3", value={**region["value"], "timeserieslabels": ["Lava"]})
    status, body = _call(backend.url, "/webhook", {**event, "annotation": {"id": 56, "result": [other, unknown]}})
    assert status == 207 and len(body["refused"]) == 2 and "lava" in body["refused"][1].lower()
    assert len(session.segments()) == before + 1
    # an event naming no log of the session: a clear answer, nothing changed
    status, body = _call(backend.url, "/webhook", {**event, "task": {"id": 9, "data": {"csv": "x/other.csv"}}})
    assert status == 422 and "names no log of this session" in body["error"]
    assert len(session.segments()) == before + 1


def _free_span(session: Session, log_id: int, length: float) -> float:
    log = session.log(log_id)
    taken = sorted((g.start / log.rate_hz, g.stop / log.rate_hz) for g in session.segments(log_id))
    t = 1.0
    for a, b in taken:
        if t + length <= a:
            break
        t = max(t, b + 0.5)
    assert t + length < log.n_samples / log.rate_hz
    return float(round(t, 2))


def test_start_training_retrains_and_a_label_is_a_check_of_the_version_that_predicted_it(
    backend, session, tmp_path
) -> None:
    tasks, log = _tasks(session, tmp_path), session.logs()[0]
    old = f"v{session.active_model('classifier').id}"
    body = {"tasks": [{**tasks[0], "id": 500}], "label_config": CONFIG}
    assert _call(backend.url, "/predict", body)[1]["results"][0]["model_version"] == old
    before = {v.id for v in session.model_versions("classifier")}
    status, said = _call(backend.url, "/webhook", {"action": "START_TRAINING", "project": {"id": 3}})
    assert status == 201 and said["status"] == "ok"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not ({v.id for v in session.model_versions("classifier")} - before):
        time.sleep(0.5)
    (new,) = {v.id for v in session.model_versions("classifier")} - before  # a new version
    body = {"tasks": [{**tasks[0], "id": 501}], "label_config": CONFIG}
    while time.monotonic() < deadline and _call(backend.url, "/predict", body)[1]["results"][0]["model_version"] != (
        f"v{new}"
    ):
        time.sleep(0.5)  # the new version rescored: task 501 is answered by it

    def annotate(task_id: int) -> dict:
        free = _free_span(session, log.id, 2.0)
        value = {"start": log.t0 + free, "end": log.t0 + free + 2.0, "instant": False, "timeserieslabels": ["Sand"]}
        region = {"from_name": "surface", "to_name": "signals", "type": "timeserieslabels", "value": value}
        task = {**tasks[0], "id": task_id}
        event = {"action": "ANNOTATION_CREATED", "task": task, "annotation": {"result": [region]}}
        status, answer = _call(backend.url, "/webhook", event)
        assert status == 201 and answer["result"].startswith("1 label(s) added"), answer
        return answer

    checks = len(session.checks())
    # predicted by the version before the Retrain: the label kept, no check (its answer is not the session's now)
    assert f"{old} predicted the task, the session now scores v{new}" in annotate(500)["result"]
    assert len(session.checks()) == checks
    # predicted by the version scoring now: a check of it
    assert "not counted" not in annotate(501)["result"]
    assert len(session.checks()) == checks + 1 and session.checks()[-1].classifier == new


def test_bad_requests_get_one_clear_answer(backend) -> None:
    assert _call(backend.url, "/predict", raw=b"{not json")[0] == 400
    assert _call(backend.url, "/predict", [1, 2])[0] == 400
    assert _call(backend.url, "/predict", {"tasks": "x"}) == (400, {"error": "the request holds no list of tasks"})
    assert _call(backend.url, "/nowhere", {})[0] == 404
    request = urllib.request.Request(backend.url + "/predict", data=b"{}", method="POST")
    request.add_header("Content-Length", str(MAX_BODY + 1))
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(request, timeout=30)
    assert refused.value.code == 413
    # a web page in the person's browser posting to the port, or a rebound DNS name: refused before any work
    for header, value in (("Origin", "https://evil.example"), ("Host", "evil.example:9090")):
        request = urllib.request.Request(backend.url + "/webhook", data=b'{"action": "START_TRAINING"}', method="POST")
        request.add_header(header, value)
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(request, timeout=30)
        assert refused.value.code == 403
    assert _call(backend.url, "/health")[0] == 200  # still serving


def test_beyond_loopback_needs_basic_auth_and_checks_it(session: Session, capsys) -> None:
    from workbench.label_studio import Backend as Answers
    from workbench.label_studio import BackendServer

    assert main(["label-studio", str(session.path), "--host", "0.0.0.0"]) == 2
    assert "needs basic auth" in capsys.readouterr().err
    for short in ("", "short"):  # an empty $BASIC_AUTH_PASS guards nothing
        assert main(["label-studio", str(session.path), "--user", "studio", "--password", short]) == 2
        assert "at least 16 printable characters" in capsys.readouterr().err
    answers = Answers(state=None, start_training=lambda: "", job_status=lambda: None)  # /health reads no state
    server = BackendServer(answers, host="127.0.0.1", port=0, auth=("studio", "s3cret-pass"))
    server.start()
    try:
        assert _call(server.url, "/health")[0] == 401
        assert _call(server.url, "/health", auth=("studio", "wrong"))[0] == 401
        assert _call(server.url, "/health", auth=("studio", "s3cret-pass"))[0] == 200
    finally:
        server.stop()


def test_a_log_ingested_elsewhere_meanwhile_is_answered_once_scored(backend, session, tmp_path) -> None:
    from workbench.demo import generate_demo_logs

    (made,) = generate_demo_logs(tmp_path / "new", n_logs=1, minutes=0.5, seed=99)
    log_file = made.rename(made.with_name("later_walk.mcap"))
    task = {"id": 900, "data": {"log": "later_walk"}}
    status, body = _call(backend.url, "/predict", {"tasks": [task], "label_config": CONFIG})
    assert status == 200 and "names no log of this session" in body["results"][0]["error"]
    assert main(["ingest", str(session.path), str(log_file)]) == 0  # a terminal's ingest, the backend running
    deadline, answer = time.monotonic() + 120, {}
    while time.monotonic() < deadline:
        answer = _call(backend.url, "/predict", {"tasks": [task], "label_config": CONFIG})[1]["results"][0]
        if answer["result"]:
            break
        time.sleep(0.5)
    assert answer["result"] and "error" not in answer, answer  # the new log followed, scored and answered
