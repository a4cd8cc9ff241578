"""Small files, big decoded sizes: every bomb is refused in one line with exit 2 (a hostile camera frame costs the
frame, exit 0), the CLI's peak memory stays under ``PEAK_LIMIT_MB`` (measured in a child process) and the session
is byte-identical after a refusal. The limits: ``sessions/limits.py``. ``make test`` runs the issue's two files, a
bag, a label file and an upload; ``make stress`` every variant and the 1.6 GB ones."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from sessions import Session
from tests.conftest import new_session
from tests.fork_client import run_cli

from .bomb_files import (
    camera_log,
    chunk_bomb,
    jpeg_bomb,
    png_bomb,
    ros1_chunk_bomb,
    ros1_count_lie,
    ros2_message_bomb,
)

PEAK_LIMIT_MB = 1024.0
PEAKS: list[float] = []


def _measured(args: list[str]) -> tuple[int, list[str], float]:
    """``workbench ARGS`` in a child process of its own (``tests/fork_client.run_cli``): exit code, its output's lines
    and its own peak resident memory."""
    rc, out, err, _, peak = run_cli(args, timeout=300)
    PEAKS.append(peak)
    assert peak < PEAK_LIMIT_MB, f"workbench {args}: peak RSS {peak:.0f} MB"  # each case, whatever runs last
    return rc, [x for x in (out + err).splitlines() if x.strip()], peak


def ingest_measured(session: Path, *files: Path, dry_run: bool = False) -> tuple[int, list[str], float]:
    """``workbench ingest`` in a child process: its exit code, its output's lines and its peak resident memory."""
    return _measured(["ingest", str(session), *map(str, files), *(["--dry-run"] if dry_run else [])])


def fingerprint(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.fixture
def session(tmp_path: Path) -> Path:
    new_session(tmp_path / "s").close()
    return tmp_path / "s"


def refused(session: Path, bomb: Path, *needles: str) -> float:
    before = fingerprint(session)
    rc, lines, peak = ingest_measured(session, bomb)
    errors = [x for x in lines if x.startswith("error:")]
    assert rc == 2 and len(errors) == 1 and lines == ["ingested 0 log(s), refused 1 file(s)", *errors], lines
    assert bomb.name in errors[0] and all(n in errors[0] for n in needles), errors[0]
    assert peak < PEAK_LIMIT_MB, f"peak {peak:.0f} MB"
    assert fingerprint(session) == before  # nothing written, nothing lost
    return peak


def test_a_52_kb_mcap_whose_chunk_declares_1_6_gb_is_refused_before_it_is_decoded(session: Path, tmp_path) -> None:
    """The issue's first file: one zstd chunk of four 400 MB ``sensor_msgs/Imu`` messages of zeros."""
    bomb = chunk_bomb(tmp_path / "zstd-bomb.mcap")
    assert bomb.stat().st_size < 64_000
    refused(session, bomb, "declares 1,600,000,124 decoded bytes", "MAX_CHUNK_BYTES", "chunk ending at byte")


@pytest.mark.parametrize("compression", [pytest.param("zstd", marks=pytest.mark.slow), "lz4"])
def test_a_chunk_that_decodes_to_more_than_it_declares_stops_at_the_declaration(
    session: Path, tmp_path: Path, compression: str
) -> None:
    """The header says 4 KB, the frame holds 1.6 GB: decompression stops one byte past the 4 KB."""
    bomb = chunk_bomb(tmp_path / f"{compression}-liar.mcap", compression=compression, declared=4096)
    peak = refused(session, bomb, "decodes to more bytes than the 4,096 it declares")
    assert peak < 400, f"a bounded decode should not come near the 1.6 GB: {peak:.0f} MB"


@pytest.mark.slow
def test_a_sensor_message_far_larger_than_its_schema_is_refused_with_its_topic(session: Path, tmp_path) -> None:
    bomb = chunk_bomb(tmp_path / "big-imu.mcap", messages=1, size=20_000_000)  # under the chunk limit
    refused(session, bomb, "message of 20,000,000 bytes, over the limit of 1,048,576", "topic /imu")


def test_a_ros1_bag_chunk_that_decodes_past_the_limit_is_refused(session: Path, tmp_path: Path) -> None:
    """10 KB on disk, a bz2 chunk of half a second of IMU and 300 MB of zeros: decoding stops at the limit."""
    bomb = ros1_chunk_bomb(tmp_path / "bz2-bomb.bag")
    assert bomb.stat().st_size < 20_000
    refused(session, bomb, "a bag chunk decodes to more than 134,217,728 bytes, the limit")


@pytest.mark.slow
def test_a_ros2_bag_message_that_decodes_past_the_limit_is_refused(session: Path, tmp_path: Path) -> None:
    """A zstd-compressed message of a ``.db3`` holding 300 MB of zeros in a few KB."""
    refused(session, ros2_message_bomb(tmp_path / "bag2"), "a bag message decodes to more than 134,217,728 bytes")


@pytest.mark.slow
@pytest.mark.parametrize("field", ["chunk_count", "conn_count"])
def test_a_ros1_bag_whose_index_counts_lie_is_refused(session: Path, tmp_path: Path, field: str) -> None:
    """A header claiming four billion chunks or connections: the index is read from the file, which ends first."""
    refused(session, ros1_count_lie(tmp_path / f"{field}.bag", field=field), "bag")


@pytest.mark.slow
def test_the_long_bombs_a_1_6_gb_bag_chunk_and_a_1_6_gb_lz4_liar(session: Path, tmp_path: Path) -> None:
    """``make stress``: the issue's 1.6 GB in a ROS 1 bz2 chunk (about 17 s to build), and an lz4 chunk declaring
    the truth, 1.6 GB: both refused without decoding past the limit."""
    refused(session, ros1_chunk_bomb(tmp_path / "bz2-1600.bag", zeros=1_600_000_000), "a bag chunk decodes to more")
    refused(session, chunk_bomb(tmp_path / "lz4-1600.mcap", compression="lz4"), "declares 1,600,000,124 decoded bytes")


@pytest.mark.parametrize("kind", ["png", pytest.param("jpeg", marks=pytest.mark.slow)])
def test_a_pixel_bomb_frame_costs_the_frame_and_the_log_is_ingested(session: Path, tmp_path, kind: str) -> None:
    """The issue's second file: a camera frame declaring 30,000 × 30,000 pixels beside a good IMU."""
    hostile = png_bomb() if kind == "png" else jpeg_bomb()
    log = camera_log(tmp_path / f"{kind}-bomb.mcap", hostile, fmt=kind)
    rc, lines, peak = ingest_measured(session, log, dry_run=True)
    assert rc == 0 and any("1 unreadable (a frame over the limit of 40,000,000 pixels" in x for x in lines), lines
    rc, lines, peak = ingest_measured(session, log)
    assert rc == 0, lines
    assert peak < PEAK_LIMIT_MB
    with Session.open(session) as s:
        (info,) = s.logs()
        (cam,) = s.cameras(info.id)
        # 15 frames at 5 Hz, 2 a second kept: 6; the hostile first frame skipped and the next one taken in its place
        assert info.n_samples >= 290 and cam.frames == 6
    warning = "warning: camera /camera/compressed: skipped 1 camera frame (a frame over the limit of 40,000,000 pixels"
    assert any(warning in x for x in lines), lines


def labels_measured(session: Path, label_file: Path) -> tuple[int, list[str], float]:
    """``workbench labels import`` in a child process: exit code, output lines, peak resident memory."""
    return _measured(["labels", "import", str(session), str(label_file)])


def billion_row_parquet(path: Path) -> Path:
    """1.6 MB whose metadata claims a billion rows (a column of nulls has no buffers to write)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({"log": pa.nulls(10**9)}), path, row_group_size=10**9)
    return path


@pytest.mark.parametrize(
    "name, build, needle",
    [
        pytest.param(
            "nested.json",
            lambda p: p.write_text("[" * 100_000 + "]" * 100_000),
            "nested deeper than",
            marks=pytest.mark.slow,
        ),
        ("records.json", lambda p: p.write_text('[{"log": {"a": [1, 2]}, "terrain": "ice"}]'), "nested deeper than 2"),
        ("billion.parquet", billion_row_parquet, "claims 1,000,000,000 rows, over the limit of 5,000,000"),
    ],
)
def test_label_file_bombs_are_refused_before_they_are_decoded(session: Path, tmp_path: Path, name, build, needle):
    label_file = tmp_path / name
    build(label_file)
    before = fingerprint(session)
    rc, lines, peak = labels_measured(session, label_file)
    assert rc == 2 and len(lines) == 1 and name in lines[0] and needle in lines[0], lines
    assert peak < PEAK_LIMIT_MB, f"peak {peak:.0f} MB"
    assert fingerprint(session) == before


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def test_a_bomb_uploaded_through_the_page_ends_in_one_line_and_the_server_stays_small(tmp_path: Path, detail) -> None:
    """The Data tab's upload goes through the same readers: the 52 KB chunk bomb is refused in one notification,
    nothing is kept, and the server (this process) does not grow by what the chunk declares."""
    import uuid

    import msgspec
    from viser import _messages

    from tests.safety.viser_client import ViserClient
    from workbench.ui import MAX_UPLOAD_MB, WorkbenchApp

    bomb = chunk_bomb(tmp_path / "zstd-bomb.mcap").read_bytes()
    with new_session(tmp_path / "s") as s:
        app = WorkbenchApp(s, port=0, hidden=8)
        client = ViserClient(app.url)
        try:
            button = client.wait_widget(f"Upload MCAP / CSV (≤ {MAX_UPLOAD_MB} MB)")
            transfer = uuid.uuid4().hex
            start = _messages.FileTransferStartUpload(button, transfer, "zstd-bomb.mcap", "", 1, len(bomb))
            before = _rss_mb()
            client.ws.send(msgspec.msgpack.encode(start.as_serializable_dict()))
            part = _messages.FileTransferPart(button, transfer, 0, bomb)
            client.ws.send(msgspec.msgpack.encode(part.as_serializable_dict()))
            note = client.wait_for(lambda m: m["type"] == "NotificationShowMessage", timeout=60)["props"]
            grew = _rss_mb() - before
        finally:
            client.close()
            app.stop()
        assert note["title"] == "Not done" and "\n" not in note["body"], note
        assert "zstd-bomb.mcap" in note["body"] and "MAX_CHUNK_BYTES" in note["body"], note
        assert s.logs() == [] and not list((s.path / "uploads").glob("*"))
    assert grew < 256, f"the server grew by {grew:.0f} MB for a chunk declaring 1.6 GB"
    detail(f"the 52 KB chunk bomb uploaded through the page: one line, the server grew by {grew:.0f} MB")


def test_every_bomb_stayed_under_the_memory_bound(detail) -> None:
    """The module's last test: the promise line's figures (``make stress`` prints it)."""
    if not PEAKS:
        pytest.skip("no bomb case ran")
    assert max(PEAKS) < PEAK_LIMIT_MB
    detail(f"{len(PEAKS)} files through the CLI, largest peak RSS {max(PEAKS):.0f} MB (bound {PEAK_LIMIT_MB:.0f} MB)")
