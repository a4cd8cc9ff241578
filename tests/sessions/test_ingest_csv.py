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


def test_a_named_time_column_in_epoch_nanoseconds_is_read_in_its_unit(session: Session, tmp_path: Path) -> None:
    stamps = 1_700_000_000_000_000_000 + np.arange(200) * 5_000_000  # 200 Hz
    path = write(tmp_path / "ns.csv", "timestamp,fz\n" + "".join(f"{t},{i}\n" for i, t in enumerate(stamps)))
    (log,) = session.ingest([path])
    assert log.rate_hz == 200.0 and log.channel_names == ("fz",) and abs(log.t0 - 1.7e9) < 1e-3


def test_a_row_counter_is_no_time_and_steps_that_wander_are_no_clock(session: Session, tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    wander = np.cumsum(rng.uniform(0.001, 0.05, 300))  # increasing, but not in steady steps
    text = "n,w,v\n" + "".join(f"{i},{w:.5f},{rng.normal():.4f}\n" for i, w in enumerate(wander))
    path = write(tmp_path / "counter.csv", text)
    (log,) = session.ingest([path])  # neither column is a clock: the first is tried as before, and it counts
    assert log.channel_names == ("w", "v") and log.rate_hz == 1.0


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


def borealtc_like(folder: Path, imu_header: str, pro_header: str, rows: int = 400) -> Path:
    """A run in BorealTC's format, written by someone else: ``CLASS/imu_00.csv`` at 100 Hz and ``pro_00.csv`` at
    10 Hz, each column filled with its own name's index so that a reordering shows."""
    (folder / "ICE").mkdir(parents=True)
    for name, header, rate in (("imu_00.csv", imu_header, 100.0), ("pro_00.csv", pro_header, 10.0)):
        cols = header.split(",")
        n = rows if rate == 100.0 else rows // 10
        lines = [header] + [
            ",".join(f"{i / rate:.3f}" if c == "time" else str(float(len(c) + ord(c[-1]))) for c in cols)
            for i in range(n)
        ]
        write(folder / "ICE" / name, "\n".join(lines) + "\n")
    return folder / "ICE" / "imu_00.csv"


def test_a_borealtc_format_run_is_read_by_column_name_in_any_order(session: Session, tmp_path: Path) -> None:
    imu = borealtc_like(tmp_path, "time,ax,ay,az,wx,wy,wz,temp", "time,velL,velR,curL,curR")
    (log,) = session.ingest([imu])
    assert log.format == "borealtc" and log.name == "ICE_00" and log.reference_terrain == "ice"
    names = ("wx", "wy", "wz", "ax", "ay", "az", "curL", "curR", "velL", "velR")
    assert log.channel_names == tuple(f"{'imu' if i < 6 else 'pro'}/{c}" for i, c in enumerate(names))
    values = session.samples(log.id, 0, 1)[0]
    np.testing.assert_allclose(values, [float(len(c) + ord(c[-1])) for c in names])  # each column under its name
    assert log.info["notes"] == ["imu_00.csv: column temp not read (not BorealTC's)"]


def test_a_borealtc_format_run_missing_a_column_is_refused_by_name(session: Session, tmp_path: Path) -> None:
    imu = borealtc_like(tmp_path, "time,wx,wy,wz,ax,ay,az", "time,velL,curL,curR")
    with pytest.raises(IngestError) as err:
        session.ingest([imu])
    assert Path(err.value.path).name == "pro_00.csv"
    assert "missing column velR (a BorealTC pro file has time, curL, curR, velL, velR, in any order)" in str(err.value)
    assert session.logs() == []


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
    with pytest.raises(IngestError, match=r"not a ROS 1 bag: no .#ROSBAG V2\.0. header"):  # read as a bag: it is none
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
