"""`workbench label-studio` against a real Label Studio (1.23.2, in a virtual environment of its own outside the
project's): a project with the export's TimeSeries config connects the backend, imports the tasks, shows the
predictions with their scores, its list sorted by them in the workbench's order; an annotation made there lands in
the session; "Start training" makes a new version.

Slow (Label Studio's first start migrates its database: about a minute): `make stress` runs it. The environment is
``$WORKBENCH_LABEL_STUDIO_VENV`` if set, else made once under ``~/.cache/workbench-label-studio`` (`pip install
label-studio==1.23.2`); the test skips, saying why, where that cannot be done.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main
from workbench.label_studio import serve_label_studio

from ..cycle.test_default_family import trained_demo_session
from .test_backend import _free_span

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("fast_window_fits")]
VERSION = "1.23.2"
TOKEN = "0123456789abcdef0123456789abcdef01234567"


def _venv() -> Path:
    folder = Path(os.environ.get("WORKBENCH_LABEL_STUDIO_VENV", Path.home() / ".cache" / "workbench-label-studio"))
    exe = folder / "bin" / "label-studio"
    if exe.exists():
        return folder
    try:
        subprocess.run([sys.executable, "-m", "venv", str(folder)], check=True, capture_output=True, timeout=120)
        subprocess.run(
            [str(folder / "bin" / "pip"), "install", "-q", f"label-studio=={VERSION}"],
            check=True,
            capture_output=True,
            timeout=900,
        )
    except (subprocess.SubprocessError, OSError) as exc:
        pytest.skip(f"Label Studio {VERSION} could not be installed in {folder}: {str(exc)[:200]}")
    return folder


def _port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Studio:
    """A Label Studio server on loopback, its API through the user's token."""

    def __init__(self, venv: Path, data: Path) -> None:
        self.port = _port()
        self.url = f"http://127.0.0.1:{self.port}"
        # a backend on the same machine: Label Studio blocks loopback URLs unless told it may reach them
        env = {**os.environ, "ML_BLOCK_LOCAL_IP": "false", "SSRF_PROTECTION_ENABLED": "false"}
        self.log = (data / "studio.log").open("w")
        args = ["--data-dir", str(data)]
        self.proc = subprocess.Popen(
            [str(venv / "bin" / "label-studio"), "start", "--no-browser", "--port", str(self.port), *args,
             "--username", "me@field.team", "--password", "pass-123456", "--user-token", TOKEN],
            stdout=self.log, stderr=subprocess.STDOUT, env=env,
        )  # fmt: skip
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            try:
                urllib.request.urlopen(self.url + "/health", timeout=3)
                break
            except OSError:
                if self.proc.poll() is not None:
                    pytest.fail(f"Label Studio exited: {(data / 'studio.log').read_text()[-2000:]}")
                time.sleep(2)
        # 1.23 turns the legacy user token off for a new organisation: on, for this test's API calls
        enable = "from jwt_auth.models import JWTSettings; JWTSettings.objects.update(legacy_api_tokens_enabled=True)"
        subprocess.run([str(venv / "bin" / "label-studio"), "shell", *args], input=enable, text=True, env=env,
                       capture_output=True, timeout=300, check=True)  # fmt: skip

    def api(self, method: str, path: str, body: object = None):
        data = None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(self.url + path, data=data, method=method)
        request.add_header("Authorization", f"Token {TOKEN}")
        request.add_header("Content-Type", "application/json")
        try:
            with urllib.request.urlopen(request, timeout=120) as r:
                text = r.read()
                return r.status, json.loads(text) if text else None
        except urllib.error.HTTPError as exc:
            return exc.code, exc.read()[:500]

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self.log.close()


def test_a_real_label_studio_connects_shows_predictions_and_its_annotation_lands_in_the_session(tmp_path) -> None:
    venv = _venv()
    s = trained_demo_session(tmp_path / "w", seed=11, label_seed=3)
    assert main(["labels", "export", str(s.path), "--out", str(tmp_path / "ls.json"), "--format", "label-studio"]) == 0
    assert main(["suggest", str(s.path), "--out", str(tmp_path / "next.csv")]) == 0
    queue_first = pd.read_csv(tmp_path / "next.csv")["log"].iloc[0]
    # the log of the queue's first suggestion imported last: Label Studio's id order puts it last, the score's first
    tasks = sorted(
        ({"data": t["data"]} for t in json.loads((tmp_path / "ls.json").read_text())),
        key=lambda t: t["data"]["log"] == queue_first,
    )
    assert tasks[-1]["data"]["log"] == queue_first and len(tasks) > 1
    config = (tmp_path / "ls-files" / "labeling-config.xml").read_text()
    ready, stop, port = threading.Event(), threading.Event(), _port()
    backend = threading.Thread(
        target=serve_label_studio,
        args=(s,),
        kwargs={"host": "127.0.0.1", "port": port, "auth": None, "ready": ready, "stop": stop},
        daemon=True,
    )
    backend.start()
    assert ready.wait(60)
    (tmp_path / "studio").mkdir()
    studio = Studio(venv, tmp_path / "studio")
    try:
        status, project = studio.api("POST", "/api/projects", {"title": "terrain", "label_config": config})
        assert status == 201, project
        pid, active = project["id"], s.active_model("classifier").id
        status, ml = studio.api("POST", "/api/ml", {"project": pid, "url": f"http://127.0.0.1:{port}", "title": "wb"})
        assert status == 201 and ml["state"] == "CO" and ml["model_version"] == f"v{active}", ml  # connected
        assert studio.api("POST", f"/api/projects/{pid}/import", tasks)[0] == 201
        status, said = studio.api(
            "POST",
            f"/api/dm/actions?id=retrieve_tasks_predictions&project={pid}",
            {"selectedItems": {"all": True, "excluded": []}},
        )
        assert status == 200, said
        found = studio.api("GET", f"/api/tasks?project={pid}&fields=all")[1]["tasks"]
        assert len(found) == len(tasks)
        for task in found:
            (prediction,) = task["predictions"]
            assert prediction["model_version"] == f"v{active}" and prediction["result"]
            assert 0 < prediction["score"] <= 1
            assert {r["type"] for r in prediction["result"]} == {"timeserieslabels"}
        # Label Studio's list sorted by "Prediction score", ascending, as a click on the column's head makes it (a
        # view of the project ordered so): the task of the queue's first suggestion first, the scores rising. Label
        # Studio sorts by the scores of the project's chosen model version only (Settings: the predictions to use;
        # none chosen, every task's is null and the list stays in id order): the workbench's version chosen
        assert studio.api("PATCH", f"/api/projects/{pid}", {"model_version": f"v{active}"})[0] == 200
        status, view = studio.api(
            "POST", "/api/dm/views", {"project": pid, "data": {"ordering": ["tasks:predictions_score"]}}
        )
        assert status == 201, view
        listed = studio.api("GET", f"/api/tasks?project={pid}&view={view['id']}&fields=all")[1]["tasks"]
        scores = [t["predictions"][0]["score"] for t in listed]
        assert scores == sorted(scores) and len(set(scores)) > 1, scores
        assert listed[0]["data"]["log"] == queue_first, (listed[0]["data"], queue_first)
        assert [t["id"] for t in listed] != sorted(t["id"] for t in listed)  # not the list's own (id) order
        print("Label Studio's order:", [(t["data"]["log"], t["predictions"][0]["score"]) for t in listed])
        # an annotation made in Label Studio: 3 s of one of the session's terrains where the second walk has none
        terrain = s.terrains()[-1].name
        task = next(t for t in found if t["data"]["log"] == s.logs()[1].name)
        log = s.logs()[1]
        free = _free_span(s, log.id, 3.0)
        start = (log.t0 + free) * 1000.0  # ms on the log's clock: the export's date axis
        region = {
            "from_name": "terrain",
            "to_name": "ts",
            "type": "timeserieslabels",
            "value": {"start": start, "end": start + 3000.0, "instant": False, "timeserieslabels": [terrain]},
        }
        before = len(s.segments())
        status, made = studio.api("POST", f"/api/tasks/{task['id']}/annotations", {"result": [region]})
        assert status == 201, made
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and len(s.segments()) == before:
            time.sleep(0.5)
        (new,) = [g for g in s.segments() if g.source == "label-studio"]
        assert new.log_id == log.id and new.terrain == terrain and new.author.startswith("label-studio user")
        assert abs(new.start - free * log.rate_hz) <= 1 and abs(new.stop - new.start - 3.0 * log.rate_hz) <= 1
        # "Start training"
        versions = {v.id for v in s.model_versions("classifier")}
        assert studio.api("POST", f"/api/ml/{ml['id']}/train", {})[0] == 200
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and not {v.id for v in s.model_versions("classifier")} - versions:
            time.sleep(1)
        assert {v.id for v in s.model_versions("classifier")} - versions
    finally:
        studio.stop()
        stop.set()
        backend.join(60)
        s.close()
