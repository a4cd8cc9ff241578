"""The Data tab: the session's logs, uploading MCAP/CSV logs from the browser, downloading label files and the
model bundle through the browser."""

from __future__ import annotations

import html
import io
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import labeling
from sessions import IngestError, Session, WorkbenchError

from ..cycle import SessionFigure, checks_summary, session_figures
from ..expectations import FileExpectation, file_expectation
from .charts import DRIFT
from .status_bar import MISSED
from .uploads import MAX_UPLOAD_MB, UPLOAD_SUFFIXES, forget_upload, safe_name

if TYPE_CHECKING:
    from .host import PanelHost

_STYLE = (
    "<style>.wb-table{border-collapse:collapse;width:100%;font-size:0.8em;white-space:nowrap}"
    ".wb-table th,.wb-table td{padding:3px 5px;border-bottom:1px solid #e0e0e0;text-align:left}"
    ".wb-table th{color:#666;font-weight:500;white-space:normal;vertical-align:bottom}"
    ".wb-table td.n,.wb-table th.n{text-align:right;font-variant-numeric:tabular-nums}</style>"
)


def _duration(seconds: float) -> str:
    m, s = divmod(round(seconds), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def logs_table_html(
    session: Session,
    drifted: Mapping[int, float | None] | None = None,
    expected: Mapping[int, FileExpectation | None] | None = None,
    checks: Mapping[int, labeling.CheckEstimate] | None = None,
    held_out: Mapping[str, float] | None = None,
    figures: Mapping[int, SessionFigure] | None = None,
) -> str:
    """An HTML table of the session's logs (name, format, duration, rate, channels, labelled time and, once the
    model gives a drift score, the share of each log unlike anything labelled and the accuracy expected at its
    drift, in red when 10 points or more below the card's figure, as ``classify`` warns).

    Args:
        session: The session.
        drifted: Per log id, the share of its time with a drift score above 1 (``None``: not scored).
        expected: Per log id, its expectation (:func:`workbench.expectations.file_expectation`).
        checks: Per log id, what the person's checks there say (``cycle.checks_summary``): right on X of N, the 95 %
            interval on hover.
        held_out: Per log name, what the model that ships scored on it when a fit without it held it out (the
            active classifier's ``unseen_runs``): a run it never saw, not the session's figure for the log.
        figures: Per log id, how right the active version is on the log's time nobody labelled, from its spot
            checks there (``cycle.session_figures``): "≈ 97 % (93–99)" or "not checked".
    """
    logs = session.logs()
    if not logs:
        return _STYLE + "<p>No logs yet. Ingest some with <code>workbench ingest SESSION FILE...</code></p>"
    labelled: dict[int, int] = {}
    for seg in session.segments():
        labelled[seg.log_id] = labelled.get(seg.log_id, 0) + seg.length
    rows = []
    drift_column = bool(drifted) and any(v is not None for v in drifted.values())
    expect_column = bool(expected) and any(e is not None and e.figure is not None for e in expected.values())
    for log in logs:
        lab = labelled.get(log.id, 0) / max(log.n_samples, 1)
        title = html.escape(f"{log.format}: {log.source_path}", quote=True)
        cell = ""
        if drift_column:
            share = drifted.get(log.id)  # type: ignore[union-attr]
            strong = share is not None and share > 0.5
            text = "–" if share is None else f"{share:.0%}"
            cell = f"<td class='n'>{f'<b style=color:{DRIFT}>{text}</b>' if strong else text}</td>"
        if figures:
            cell += _figure_cell(figures.get(log.id))
        if expect_column:
            cell += _expected_cell(expected.get(log.id))  # type: ignore[union-attr]
        if checks:
            cell += _checks_cell(checks.get(log.id))
        if held_out:
            share = held_out.get(log.name)
            cell += f"<td class='n'>{'–' if share is None else f'{share:.0%}'}</td>"
        rows.append(
            f"<tr><td class='n'>{log.id}</td><td title='{title}'>{html.escape(log.name)}</td>"
            f"<td class='n'>{_duration(log.duration_s)}</td><td class='n'>{log.rate_hz:g}</td>"
            f"<td class='n'>{log.n_channels}</td><td class='n'>{len(log.gaps)}</td><td class='n'>{lab:.0%}</td>"
            f"{cell}</tr>"
        )
    head = (
        "<th class='n' title='share of the log whose drift score is above 1: unlike anything labelled'>"
        "unlike labelled</th>"
        if drift_column
        else ""
    )
    if figures:
        head += (
            "<th class='n' title='how right this version is on the log&#39;s time nobody labelled: from your spot "
            "checks of it there (drawn at random), corrected by its confidence; 90 % interval. Not checked: no spot "
            "check of this version in the log since the last Retrain (Verify, in the Suggest tab, asks for them)'>"
            "this version</th>"
        )
    if expect_column:
        card = next((e.card for e in expected.values() if e is not None and e.card is not None), None)  # type: ignore[union-attr]
        red = [] if card is None else [f"10 points or more below the card&#39;s {card:.0%}"]
        below = "; red: " + ", or ".join([*red, "contradicted by your checks of this model in the log"])
        head += (
            "<th class='n' title='accuracy expected on the log: how often the model&#39;s members name the same "
            "terrain there, else its expected accuracy at its drift, else the share of its steps predicted as their "
            "stretch&#39;s most predicted terrain (stretches between change points; each on hover)"
            f"{below}; the model&#39;s own guess, not a test'>its guess</th>"
        )
    if checks:
        head += (
            "<th class='n' title='your checks in the log: how often the model named your terrain before your "
            "label there trained it (95 % interval on hover); suggestions are where the model was doubted, so "
            "these run low'>✓</th>"
        )
    if held_out:
        head += (
            "<th class='n' title='the model that ships, on this log as a run it never saw: a fit without any "
            "label or stretch of it, scored on its labels and the terrain the session is sure of there (the status "
            "line&#39;s &quot;shipped, on a new run&quot; over all such runs); not the session&#39;s own accuracy "
            "for the log'>held out</th>"
        )
    total = sum(log.duration_s for log in logs)
    return (
        _STYLE
        + f"<p><b>{len(logs)}</b> logs, {_duration(total)} in all</p>"
        + "<table class='wb-table'><tr><th class='n'>#</th><th>log</th><th class='n'>length</th>"
        + "<th class='n'>Hz</th><th class='n'>channels</th><th class='n'>gaps</th><th class='n'>labelled</th>"
        + head
        + "</tr>"
        + "".join(rows)
        + "</table>"
    )


def _expected_cell(e: FileExpectation | None) -> str:
    if e is None or e.figure is None:
        return "<td class='n'>–</td>"
    text = f"{e.figure:.0%}"
    both = html.escape(" ".join(filter(None, [e.figures(), e.warning() if e.checks_disagree else None])), quote=True)
    strong = e.below_card or e.disagrees or e.checks_disagree
    return f"<td class='n' title='{both}'>{f'<b style=color:{MISSED}>{text}</b>' if strong else text}</td>"


def _figure_cell(f: SessionFigure | None) -> str:
    if f is None:
        return "<td class='n'>–</td>"
    title = html.escape(f"{f.words()}; {f.plan_words()}", quote=True)
    text = html.escape(f.short())
    return f"<td class='n' title='{title}'>{text if f.figure is not None else f'<i>{text}</i>'}</td>"


def _checks_cell(est: labeling.CheckEstimate | None) -> str:
    if est is None:
        return "<td class='n'>–</td>"
    return f"<td class='n' title='{html.escape(est.words(), quote=True)}'>{est.right}/{est.n}</td>"


class DataPanel:
    def __init__(self, host: PanelHost) -> None:
        self.host = host
        gui = host.client.gui
        self.logs = gui.add_html("")
        self.upload = gui.add_upload_button(f"Upload MCAP / CSV (≤ {MAX_UPLOAD_MB} MB)", icon="upload")
        self.upload.on_upload(lambda _: host.guard(self._take_upload))
        with gui.add_folder("Download"):
            for fmt in ("csv", "parquet", "json"):
                b = gui.add_button(f"Labels ({fmt.upper()})", icon="download")
                b.on_click(lambda _, fmt=fmt: host.guard(lambda: self.download_labels(fmt)))
            self.bundle_button = gui.add_button(
                "Model bundle, taught by the session (zip: PyTorch, ONNX, card)", icon="package"
            )
            self.bundle_button.on_click(lambda _: host.guard(self.download_bundle))
        self.refresh()

    def refresh(self) -> None:
        scores = self.host.state.scores.scores
        session = self.host.state.session
        drifted = {i: labeling.drifted_share(s.drift) for i, s in scores.items()}
        classifier = session.active_model("classifier")
        metrics = classifier.metrics if classifier is not None else {}
        logs = session.logs()
        names, rates = {x.id: x.name for x in logs}, {x.id: x.rate_hz for x in logs}
        state = self.host.state
        checks = checks_summary(session).per_log
        # a figure is the active model's: only the checks of that model can contradict it (each earlier check was
        # of a model that has since learned from it)
        fresh = {} if classifier is None else checks_summary(session, classifier=classifier.id).per_log
        spans: dict[int, list[tuple[int, int]]] = {}
        for g in session.segments():
            spans.setdefault(g.log_id, []).append((g.start, g.stop))
        expected = {
            i: file_expectation(
                names.get(i, str(i)),
                s.drift,
                metrics,
                predicted=None if s.probs is None else s.probs.argmax(1),
                change_points=state.known_change_points(i),  # the worker's; none computed here, on the UI's thread
                rate_hz=rates.get(i),
                checks=fresh.get(i),
                members=s.agreement,
                labelled=spans.get(i, ()),
            )
            for i, s in scores.items()
        }
        held_out = (metrics.get("unseen_runs") or {}).get("per_run")
        now = session_figures(session, state.scores).per_log if state.scores.classifier is not None else None
        self.logs.content = logs_table_html(session, drifted, expected, checks, held_out, now)

    def _take_upload(self) -> None:
        refused: str | None = None
        try:
            self._uploaded()
        except WorkbenchError as exc:
            refused = str(exc)  # not the error itself: its traceback holds the frame that holds the upload's bytes
        finally:
            forget_upload(self.upload)  # its bytes are on disk (or refused): the server keeps no copy
        if refused is not None:
            raise WorkbenchError(refused)

    def _uploaded(self) -> None:
        f = self.upload.value
        name = safe_name(f.name)
        if not name.lower().endswith(UPLOAD_SUFFIXES):
            raise WorkbenchError(f"{name}: not an MCAP or CSV file (expected {', '.join(UPLOAD_SUFFIXES)})")
        if len(f.content) > MAX_UPLOAD_MB * 2**20:
            raise WorkbenchError(
                f"{name}: {len(f.content) / 2**20:.0f} MB is over the {MAX_UPLOAD_MB} MB limit; "
                "ingest it with `workbench ingest` instead"
            )
        session = self.host.state.session
        folder = session.path / "uploads"
        folder.mkdir(exist_ok=True)
        path = folder / name
        n = 1
        while path.exists():
            path = folder / f"{Path(name).stem}-{n}{Path(name).suffix}"
            n += 1
        tmp = path.with_name(path.name + ".part")
        tmp.write_bytes(f.content)
        tmp.replace(path)
        before = {x.id for x in session.logs()}
        try:
            logs = session.ingest([path])
        except IngestError as exc:
            path.unlink(missing_ok=True)
            raise WorkbenchError(str(exc)) from None
        added = [x for x in logs if x.id not in before]
        if not added:
            path.unlink(missing_ok=True)
            self.host.notify("Already here", f"{name} is already in the session", color="blue")
            return
        self.host.notify("Ingested", ", ".join(f"{x.name} ({x.duration_s:.0f} s)" for x in added))
        self.host.state.logs_changed()

    def download_labels(self, fmt: str) -> None:
        session = self.host.state.session
        with tempfile.TemporaryDirectory() as tmp:
            path = session.export_labels(Path(tmp) / f"labels.{fmt}")
            data = path.read_bytes()
        self.host.client.send_file_download(f"{session.path.name}-labels.{fmt}", data, save_immediately=True)

    def download_bundle(self) -> None:
        from ..export import export_all
        from .torch_lane import LANE

        session = self.host.state.session
        self.host.notify(
            "Exporting",
            "the bundle taught by the session (fitted once after each Retrain), ONNX checked against PyTorch",
            color="blue",
        )
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "export"
            LANE.run(export_all, session, out)
            self.host.state.notify("models")  # the taught version it fitted (or reused) shows in the Train tab
            buf = io.BytesIO()
            with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
                for p in sorted(out.rglob("*")):
                    if p.is_file():
                        z.write(p, p.relative_to(out))
        self.host.client.send_file_download(f"{session.path.name}-model.zip", buf.getvalue(), save_immediately=True)
