"""`workbench label-studio` answering Label Studio's "Retrieve predictions" for 100 tasks of 10 minutes each.

Label Studio gives an ML backend 100 s to answer a ``/predict`` (``ML_TIMEOUT_PREDICT``) and sends the project's
tasks in one request. The session: 100 IMU CSVs of 10 minutes (6 channels at 50 Hz, quadruped-shaped:
``speed_common.write_imu_logs``), 5 % of the time labelled in 5 s pieces, trained by `workbench train` (the
default family); the tasks as `workbench labels export --format label-studio` writes them (each names its log).
Writing, ingesting, labelling and training are set-up, timed but not part of the figures.

The backend runs as a person starts it (`workbench label-studio SESSION --port P`, a process of its own), and the
bench calls it over HTTP as Label Studio does:

- the first ``/predict`` of the 100 tasks after the backend started, where nothing has scored the session yet (a
  session just trained: the backend scores every log before it answers, as the page does on its first start);
- the same ``/predict`` again (the scores kept: what every later "Retrieve predictions" costs);
- the reference, in a fresh interpreter: reading the session's stored scores alone (``stored_scores``, what the
  answer is made from once the session is scored), and, for the first call, `workbench classify` of the 100 logs'
  CSVs with the session's active models exported as they are (`export --untaught`: the models the backend scores
  with, on the same steps, start-up included).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

from speed_common import Row, fmt_s, free_port, parse_args, record, wait_answering, write_imu_logs

LIMIT_S = 100.0  # Label Studio's ML_TIMEOUT_PREDICT


def _workbench(*args: str) -> float:
    """Seconds of one `workbench ...` in a process of its own."""
    exe = str(Path(sys.executable).with_name("workbench"))
    t = time.perf_counter()
    out = subprocess.run([exe, *args], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"workbench {' '.join(args)} failed:\n{out.stdout[-2000:]}\n{out.stderr[-2000:]}")
    return time.perf_counter() - t


def _post(url: str, body: dict, *, timeout: float = 600.0) -> tuple[float, dict]:
    data = json.dumps(body).encode()
    request = urllib.request.Request(url, data=data, method="POST", headers={"Content-Type": "application/json"})
    t = time.perf_counter()
    with urllib.request.urlopen(request, timeout=timeout) as r:
        answer = json.loads(r.read())
    return time.perf_counter() - t, answer


def set_up(folder: Path, *, n_logs: int, minutes: float) -> tuple[Path, list[dict], str, list[Path]]:
    from sessions import Session
    from workbench.demo import seed_labels

    t = time.perf_counter()
    files, reference = write_imu_logs(folder / "logs", n_logs=n_logs, minutes=(minutes, minutes))
    with Session.create(folder / "session") as s:
        s.ingest(files)
        s.import_reference(reference, create_terrains=True)
        seed_labels(s, 0.05, seed=0, segment_s=5.0)
    print(f"set-up: {n_logs} logs of {minutes:g} min written, ingested, labelled in {time.perf_counter() - t:.0f} s")
    print(f"set-up: workbench train {_workbench('train', str(folder / 'session')):.0f} s", flush=True)
    out = folder / "ls.json"
    _workbench("labels", "export", str(folder / "session"), "--out", str(out), "--format", "label-studio")
    tasks = [{"id": i + 1, "data": t["data"]} for i, t in enumerate(json.loads(out.read_text()))]
    config = (folder / "ls-files" / "labeling-config.xml").read_text()
    return folder / "session", tasks, config, files


def read_stored(session: Path) -> float:
    """Seconds to read the session's stored scores, every log's arrays touched, in a fresh interpreter (its imports
    not counted: the backend has them)."""
    code = (
        "import sys, time; from sessions import Session; from workbench.cycle import stored_scores\n"
        "t = time.perf_counter()\n"
        "with Session.open(sys.argv[1]) as s:\n"
        "    kept = stored_scores(s)\n"
        "    assert kept is not None and kept.complete, 'no stored scores'\n"
        "    n = sum(float(v.probs.sum() > 0) for v in kept.scores.scores.values())\n"
        "print(time.perf_counter() - t, n)"
    )
    out = subprocess.run([sys.executable, "-c", code, str(session)], capture_output=True, text=True, check=True)
    return float(out.stdout.split()[0])


def main() -> None:
    args = parse_args(__doc__)
    n_logs, minutes = (10, 2.0) if args.quick else (100, 10.0)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        session, tasks, config, files = set_up(folder, n_logs=n_logs, minutes=minutes)
        port = free_port()
        url = f"http://127.0.0.1:{port}"
        exe = str(Path(sys.executable).with_name("workbench"))
        t = time.perf_counter()
        proc = subprocess.Popen(
            [exe, "label-studio", str(session), "--port", str(port)],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        try:
            wait_answering(proc, url + "/health", name="workbench label-studio")
            started = time.perf_counter() - t
            _post(url + "/setup", {"project": "1.0", "schema": config})
            body = {"tasks": tasks, "label_config": config, "project": "1.0"}
            cold, first = _post(url + "/predict", body)
            warm, again = _post(url + "/predict", body)
        finally:
            proc.terminate()
            proc.wait(60)
        print(f"backend up in {started:.1f} s; first /predict {cold:.1f} s, again {warm:.2f} s", flush=True)
        answered = [r for r in again["results"] if r["result"]]
        first_answered = sum(1 for r in first["results"] if r["result"])
        regions = sum(len(r["result"]) for r in again["results"])
        stored = min(read_stored(session) for _ in range(3))
        _workbench("export", str(session), "--out", str(folder / "bundle"), "--untaught")  # the models scoring
        bundle, out = str(folder / "bundle" / "bundle"), str(folder / "c.parquet")
        classify_s = _workbench("classify", bundle, *map(str, files), "--out", out)
    shape = f"{len(tasks)} tasks of {minutes:g} min (6-channel 50 Hz IMU CSVs, {n_logs * minutes / 60:.1f} h)"
    check = f"{first_answered} of {len(tasks)} answered with regions first, {len(answered)} again; {regions:,} regions"
    record(
        "label_studio",
        [
            Row(
                f"label-studio /predict, {shape}, the first call after the backend started (it scores the session)",
                fmt_s(cold),
                f"workbench classify of the same {n_logs} CSVs: {fmt_s(classify_s)}",
                f"{cold / classify_s:.2f}× classify",
                f"≤ {LIMIT_S:.0f} s (Label Studio's limit)",
                bool(cold <= LIMIT_S and first_answered == len(tasks)),
                check,
            ),
            Row(
                f"label-studio /predict, {shape}, again (the session scored)",
                fmt_s(warm),
                f"reading the stored scores alone (every log's arrays, imports aside): {fmt_s(stored)}",
                f"{warm / stored:.2f}× the read",
                f"≤ {LIMIT_S:.0f} s (Label Studio's limit)",
                bool(warm <= LIMIT_S and len(answered) == len(tasks)),
                f"backend answering /health {started:.1f} s after it was started",
            ),
        ],
        device=args.device,
    )


if __name__ == "__main__":
    main()
