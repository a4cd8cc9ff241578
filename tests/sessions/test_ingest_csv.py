"""CSV ingest: generic files, the QCAT layout, a real BorealTC run, and refusing bad files cleanly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sessions import IngestError, IngestOptions, Mapping, Session
from tests.conftest import shared_data, snapshot


def write(path: Path, text: str, *, encoding: str = "utf-8") -> Path:
    path.write_bytes(text.encode(encoding))
    return path


def generic(n: int = 300, *, rate: float = 100.0, header: str = "time,ax,ay") -> str:
    t = np.arange(n) / rate
    return header + "\n" + "\n".join(f"{x:.4f},{np.sin(x):.5f},{i}" for i, x in enumerate(t)) + "\n"


def test_generic_csv_with_header(session: Session, tmp_path: Path) -> None:
    (log,) = session.ingest([write(tmp_path / "walk.csv", generic())])
    assert log.format == "csv" and log.name == "walk"
    assert log.channel_names == ("ax", "ay") and log.rate_hz == 100.0 and log.n_samples == 300
    np.testing.assert_allclose(session.samples(log.id)[:, 1], np.arange(300))


def test_generic_csv_without_header_uses_the_mapping(session: Session, tmp_path: Path) -> None:
    t = np.arange(200) * 5  # milliseconds, 200 Hz
    path = write(tmp_path / "raw.csv", "\n".join(f"{i},{x}" for i, x in zip(range(200), t, strict=True)))
    mapping = Mapping(header=False, columns=("v", "t_ms"), time_column="t_ms", time_unit="ms")
    (log,) = session.ingest([path], options=IngestOptions(mapping=mapping))
    assert log.rate_hz == 200.0 and log.channel_names == ("v",)


def test_bom_crlf_and_a_timestamp_column(session: Session, tmp_path: Path) -> None:
    text = generic(header="sample,timestamp,fz").replace("\n", "\r\n")
    lines = text.split("\r\n")
    # make the first column a counter and the second the time
    body = [f"{i},{ln.split(',')[0]},{ln.split(',')[1]}" for i, ln in enumerate(lines[1:-1])]
    path = write(tmp_path / "bom.csv", "\ufeff" + "\r\n".join([lines[0], *body]) + "\r\n")
    (log,) = session.ingest([path])
    assert log.channel_names == ("sample", "fz") and log.rate_hz == 100.0


def qcat_fixture(folder: Path, *, terrain: str = "2", speed: int = 3, trials: int = 2, rows: int = 120) -> list[Path]:
    """Files in the QCAT layout: 4 bookkeeping columns (the 4th the trial), then 12 forces / 10 IMU values."""
    rng = np.random.default_rng(0)
    out = []
    for kind, width in (("raw", 12), ("imu", 10)):
        header = ["idx", "stamp_time", "speed", "trial"] + [f"c{i}" for i in range(width)]
        lines = [",".join(header)]
        i = 0
        for trial in range(trials):
            for r in range(rows):
                values = rng.normal(size=width)
                lines.append(
                    ",".join([str(i), f"{r / 100:.2f}", str(speed), str(trial)] + [f"{v:.4f}" for v in values])
                )
                i += 1
        out.append(write(folder / f"{terrain}_{speed}_legSensors_{kind}.csv", "\n".join(lines) + "\n"))
    return out


def test_qcat_layout_splits_trials_and_keeps_terrain_as_reference_only(session: Session, tmp_path: Path) -> None:
    raw, imu = qcat_fixture(tmp_path)
    logs = session.ingest([raw])  # the partner _imu file is found beside it
    assert [x.name for x in logs] == ["gravel_3_trial0", "gravel_3_trial1"]
    log = logs[0]
    assert log.format == "qcat" and log.n_channels == 22 and log.rate_hz == 100.0
    assert log.channel_names[:3] == ("fr/force.x", "fr/force.y", "fr/force.z")
    assert log.channel_names[12:15] == (
        "imu/linear_acceleration.x",
        "imu/linear_acceleration.y",
        "imu/linear_acceleration.z",
    )
    assert log.channel_names[-1] == "imu/orientation.w"
    assert log.reference_terrain == "gravel"
    assert session.reference(log.id) == [(0, log.n_samples, "gravel")]
    assert session.segments() == []  # reference truth never becomes user labels
    assert len(session.ingest([raw, imu])) == 2 and len(session.logs()) == 2  # same files again: nothing new


def test_borealtc_run_pairs_imu_and_wheel_files(session: Session) -> None:
    imu = shared_data("borealtc", "ASPHALT", "imu_00.csv")
    (log,) = session.ingest([imu])
    assert log.format == "borealtc" and log.name == "ASPHALT_00"
    assert log.channel_names == (
        "imu/wx",
        "imu/wy",
        "imu/wz",
        "imu/ax",
        "imu/ay",
        "imu/az",
        "pro/curL",
        "pro/curR",
        "pro/velL",
        "pro/velR",
    )
    assert log.rate_hz == 100.0 and log.reference_terrain == "asphalt"
    assert {c.unit for c in log.channels} == {"rad/s", "m/s²", "A", "m/s"}
    assert 6.0 < log.info["stream_rates_hz"]["pro"] < 7.0
    first = np.loadtxt(imu, delimiter=",", skiprows=1, max_rows=5)
    np.testing.assert_allclose(session.samples(log.id, 0, 5)[:, :6], first[:, 1:], rtol=1e-6)


def test_borealtc_run_without_imu_ingests_its_wheel_data(session: Session) -> None:
    (log,) = session.ingest([shared_data("borealtc", "FLOORING", "pro_04.csv")])
    assert log.channel_names == ("pro/curL", "pro/curR", "pro/velL", "pro/velR")


BAD_CSV = {
    "empty": ("", "empty file", None),
    "header only": ("time,a\n", "no data rows", None),
    "nan": ("time,a\n0,1\n0.01,nan\n0.02,3\n", r"'nan' in column 'a' \(use --allow-gaps", "line 3"),
    "inf": ("time,a\n0,1\n0.01,2\n0.02,inf\n", "'inf' in column 'a'", "line 4"),
    "empty cell": ("time,a,b\n0,1,2\n0.01,,2\n", "empty cell in column 'a'", "line 3"),
    "text": ("time,a\n0,1\n0.01,hello\n", "text 'hello' in numeric column 'a'", "line 3"),
    "backwards": ("time,a\n0,1\n0.02,2\n0.01,3\n", "time goes backwards in column 'time'", "line 4"),
    "columns": ("time,a\n0,1\n0.01,2,3\n", "malformed CSV: Error tokenizing data", None),
    "time only": ("time\n0\n0.01\n", "no channel columns besides the time column", None),
    "latin1": (None, "not UTF-8 text", "byte 6"),
}


@pytest.mark.parametrize("case", sorted(BAD_CSV))
def test_bad_csv_is_refused_with_file_reason_and_line(session: Session, tmp_path: Path, case: str) -> None:
    text, match, where = BAD_CSV[case]
    path = tmp_path / "bad.csv"
    if text is None:
        path.write_bytes("time,d\u00e9bit\n0,1\n".encode("latin-1"))
    else:
        write(path, text)
    before = snapshot(session.path)
    with pytest.raises(IngestError, match=match) as err:
        session.ingest([path])
    assert str(err.value).startswith(str(path))
    assert err.value.where == where
    assert snapshot(session.path) == before


def test_allow_gaps_turns_nan_rows_into_recorded_gaps(session: Session, tmp_path: Path) -> None:
    lines = ["time,a"] + [f"{i / 100:.2f},{'nan' if 100 <= i < 120 else i}" for i in range(300)]
    path = write(tmp_path / "holes.csv", "\n".join(lines))
    with pytest.raises(IngestError):
        session.ingest([path])
    (log,) = session.ingest([path], options=IngestOptions(allow_gaps=True))
    (gap,) = log.gaps
    assert (gap.start, gap.stop) == (99, 120)
    assert np.isfinite(session.samples(log.id)).all()


def test_missing_file_and_unsupported_type(session: Session, tmp_path: Path) -> None:
    with pytest.raises(IngestError, match="no such file"):
        session.ingest([tmp_path / "nope.csv"])
    with pytest.raises(IngestError, match=r"unsupported file type '\.txt'"):
        session.ingest([write(tmp_path / "x.txt", "x")])
    with pytest.raises(IngestError, match="not a readable ROS bag"):  # a .bag is read as a bag: this one is none
        session.ingest([write(tmp_path / "x.bag", "x")])
    (tmp_path / "sub").mkdir()
    with pytest.raises(IngestError, match=r"folder holds no \.mcap, \.bag, \.db3 or \.csv files"):
        session.ingest([tmp_path / "sub"])


def test_qcat_file_with_missing_columns(session: Session, tmp_path: Path) -> None:
    raw, _ = qcat_fixture(tmp_path)
    lines = raw.read_text().splitlines()
    write(raw, "\n".join(",".join(ln.split(",")[:-1]) for ln in lines))
    with pytest.raises(IngestError, match=r"expected 16 columns \(4 bookkeeping \+ 12 raw values\), found 15"):
        session.ingest([raw])
