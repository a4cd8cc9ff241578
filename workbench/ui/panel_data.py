"""The Data tab: the session's logs, uploading MCAP/CSV logs from the browser, downloading label files and the
model bundle through the browser."""

from __future__ import annotations

import io
import re
import tempfile
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

from sessions import IngestError, WorkbenchError

if TYPE_CHECKING:
    from .view import ClientView

MAX_UPLOAD_MB = 512
UPLOAD_SUFFIXES = (".mcap", ".csv")


def safe_name(name: str) -> str:
    """A file name that cannot leave the folder it is written to: the last path part, plain characters only."""
    base = re.split(r"[\\/]", name)[-1]
    base = re.sub(r"[^A-Za-z0-9._-]+", "_", base).lstrip(".")
    return base[:120] or "upload"


class DataPanel:
    def __init__(self, view: ClientView) -> None:
        from ..app import logs_table_html

        self.view = view
        self._table = logs_table_html
        gui = view.client.gui
        self.logs = gui.add_html("")
        self.upload = gui.add_upload_button(f"Upload MCAP / CSV (≤ {MAX_UPLOAD_MB} MB)", icon="upload")
        self.upload.on_upload(lambda _: view._guard(self._uploaded))
        with gui.add_folder("Download"):
            for fmt in ("csv", "parquet", "json"):
                b = gui.add_button(f"Labels ({fmt.upper()})", icon="download")
                b.on_click(lambda _, fmt=fmt: view._guard(lambda: self.download_labels(fmt)))
            self.bundle_button = gui.add_button("Model bundle (zip: PyTorch, ONNX, card)", icon="package")
            self.bundle_button.on_click(lambda _: view._guard(self.download_bundle))
        self.refresh()

    def refresh(self) -> None:
        self.logs.content = self._table(self.view.state.session)

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
        session = self.view.state.session
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
            self.view.notify("Already here", f"{name} is already in the session", color="blue")
            return
        self.view.notify("Ingested", ", ".join(f"{x.name} ({x.duration_s:.0f} s)" for x in added))
        self.view.state.logs_changed()

    def download_labels(self, fmt: str) -> None:
        session = self.view.state.session
        with tempfile.TemporaryDirectory() as tmp:
            path = session.export_labels(Path(tmp) / f"labels.{fmt}")
            data = path.read_bytes()
        self.view.client.send_file_download(f"{session.path.name}-labels.{fmt}", data, save_immediately=True)

    def download_bundle(self) -> None:
        from ..export import export_all

        session = self.view.state.session
        self.view.notify("Exporting", "building the bundle and checking ONNX against PyTorch", color="blue")
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "export"
            export_all(session, out)
            buf = io.BytesIO()
            with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
                for p in sorted(out.rglob("*")):
                    if p.is_file():
                        z.write(p, p.relative_to(out))
        self.view.client.send_file_download(f"{session.path.name}-model.zip", buf.getvalue(), save_immediately=True)
