"""Small files, big decoded sizes: every bomb is refused in one line with exit 2 (a hostile camera frame costs the
frame, exit 0), the CLI's peak memory stays under ``PEAK_LIMIT_MB`` (measured in a child process) and the session
is byte-identical after a refusal. The limits: ``sessions/limits.py``."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

from sessions import Session
from tests.conftest import REPO

from .bomb_files import camera_log, chunk_bomb, jpeg_bomb, png_bomb, ros1_chunk_bomb

PEAK_LIMIT_MB = 1024.0
MEASURE = (
    "import json, resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
    "print(json.dumps({'rc': r.returncode, 'out': r.stdout + r.stderr, "
    "'peak_mb': resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}))"
)
PEAKS: list[float] = []


def ingest_measured(session: Path, *files: Path, dry_run: bool = False) -> tuple[int, list[str], float]:
    """``workbench ingest`` in a child process: its exit code, its output's lines and its peak resident memory."""
    cli = [sys.executable, "-m", "workbench.cli", "ingest", str(session), *map(str, files)]
    out = subprocess.run(
        [sys.executable, "-c", MEASURE, *cli, *(["--dry-run"] if dry_run else [])],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
        check=True,
    )
    res = json.loads(out.stdout)
    PEAKS.append(res["peak_mb"])
    return res["rc"], [x for x in res["out"].splitlines() if x.strip()], res["peak_mb"]


def fingerprint(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.fixture
def session(tmp_path: Path) -> Path:
    Session.create(tmp_path / "s").close()
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


@pytest.mark.parametrize("compression", ["zstd", "lz4"])
def test_a_chunk_that_decodes_to_more_than_it_declares_stops_at_the_declaration(
    session: Path, tmp_path: Path, compression: str
) -> None:
    """The header says 4 KB, the frame holds 1.6 GB: decompression stops one byte past the 4 KB."""
    bomb = chunk_bomb(tmp_path / f"{compression}-liar.mcap", compression=compression, declared=4096)
    peak = refused(session, bomb, "decodes to more bytes than the 4,096 it declares")
    assert peak < 400, f"a bounded decode should not come near the 1.6 GB: {peak:.0f} MB"


def test_a_sensor_message_far_larger_than_its_schema_is_refused_with_its_topic(session: Path, tmp_path) -> None:
    bomb = chunk_bomb(tmp_path / "big-imu.mcap", messages=1, size=20_000_000)  # under the chunk limit
    refused(session, bomb, "message of 20,000,000 bytes, over the limit of 1,048,576", "topic /imu")


def test_a_ros1_bag_chunk_that_decodes_past_the_limit_is_refused(session: Path, tmp_path: Path) -> None:
    """10 KB on disk, a bz2 chunk of half a second of IMU and 300 MB of zeros: decoding stops at the limit."""
    bomb = ros1_chunk_bomb(tmp_path / "bz2-bomb.bag")
    assert bomb.stat().st_size < 20_000
    refused(session, bomb, "a bag chunk decodes to more than 134,217,728 bytes, the limit")


@pytest.mark.parametrize("kind", ["png", "jpeg"])
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
    cli = [sys.executable, "-m", "workbench.cli", "labels", "import", str(session), str(label_file)]
    out = subprocess.run(
        [sys.executable, "-c", MEASURE, *cli], capture_output=True, text=True, cwd=REPO, timeout=300, check=True
    )
    res = json.loads(out.stdout)
    PEAKS.append(res["peak_mb"])
    return res["rc"], [x for x in res["out"].splitlines() if x.strip()], res["peak_mb"]


def billion_row_parquet(path: Path) -> Path:
    """1.6 MB whose metadata claims a billion rows (a column of nulls has no buffers to write)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({"log": pa.nulls(10**9)}), path, row_group_size=10**9)
    return path


@pytest.mark.parametrize(
    "name, build, needle",
    [
        ("nested.json", lambda p: p.write_text("[" * 100_000 + "]" * 100_000), "nested deeper than"),
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


def test_bomb_summary(promise) -> None:
    """The promise line, after the cases above ran in this module."""
    if not PEAKS:
        pytest.skip("no bomb case ran")
    promise(f"promise 8 (bombs: decoded sizes bounded): {len(PEAKS)} files, largest peak RSS {max(PEAKS):.0f} MB "
            f"(limit {PEAK_LIMIT_MB:.0f} MB)")  # fmt: skip
