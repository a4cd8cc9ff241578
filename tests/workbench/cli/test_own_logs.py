"""What a new user met on their own logs (walls of the "bring your own robot" issue), each reproduced first."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sessions import Session, load_mapping
from workbench.cli import main


def run(*args: object) -> int:
    return main([str(a) for a in args])


def _headerless(path: Path, rows: int = 500) -> Path:
    """A quadruped's IMU CSV as it came: no header, no time column, signed raw counts."""
    x = np.random.default_rng(0).normal(size=(rows, 4)) * 1000
    np.savetxt(path, x, delimiter=",", fmt="%.0f")
    return path


def test_a_headerless_csv_without_time_gets_a_hint_and_a_mapping_to_start_from(tmp_path: Path, capsys) -> None:
    """Wall 1: was `REFUSED: time goes backwards in column '0' (-1718 after -969) (line 3)` and no mapping."""
    f = _headerless(tmp_path / "quad.csv")
    assert run("ingest", tmp_path / "s", f, "--dry-run") == 2
    out = capsys.readouterr().out
    assert "REFUSED: no time column: the first column '0' is no time" in out
    assert "time_column" in out and "sample_rate_hz" in out  # both ways out are named
    starter = tmp_path / "m.toml"
    starter.write_text(out)
    assert load_mapping(starter).header is False  # the starter loads as it is
    starter.write_text(out.replace("# sample_rate_hz = 100.0", "sample_rate_hz = 100.0"))
    assert run("ingest", tmp_path / "s", f, "--dry-run", "--mapping", starter) == 0
    out = capsys.readouterr().out
    assert "-> log 'quad': 500 samples at 100 Hz (5.0 s), 4 channels" in out


def test_a_dry_run_with_a_mapping_round_trips(tmp_path: Path, capsys) -> None:
    """Wall 2: the dry run dropped the `[csv]` section, so its saved output failed with `missing columns named in
    the mapping`."""
    f = _headerless(tmp_path / "quad.csv")
    mapping = tmp_path / "m.toml"
    mapping.write_text('[csv]\nheader = false\ncolumns = ["ax", "ay", "az", "gz"]\nsample_rate_hz = 50.0\n')
    assert run("ingest", tmp_path / "s", f, "--dry-run", "--mapping", mapping) == 0
    saved = tmp_path / "saved.toml"
    saved.write_text(capsys.readouterr().out)
    again = load_mapping(saved)
    assert again.columns == ("ax", "ay", "az", "gz") and again.sample_rate_hz == 50.0 and again.header is False
    assert [c.source for c in again.channels] == ["ax", "ay", "az", "gz"]
    run("new", tmp_path / "s")
    assert run("ingest", tmp_path / "s", f, "--mapping", saved) == 0
    (log,) = Session.open(tmp_path / "s").logs()
    assert log.channel_names == ("ax", "ay", "az", "gz") and log.rate_hz == 50.0 and log.n_samples == 500


def test_generic_csv_rows_at_the_mapping_rate_without_a_time_column(tmp_path: Path, capsys) -> None:
    """Wall 7, first part: generic CSV ignored `sample_rate_hz`."""
    f = tmp_path / "walk.csv"
    x = np.random.default_rng(1).normal(size=(300, 2))
    f.write_text("ax,ay\n" + "\n".join(f"{a:.4f},{b:.4f}" for a, b in x) + "\n")
    mapping = tmp_path / "m.toml"
    mapping.write_text("[csv]\nsample_rate_hz = 200.0\n")
    run("new", tmp_path / "s")
    assert run("ingest", tmp_path / "s", f, "--mapping", mapping) == 0
    (log,) = Session.open(tmp_path / "s").logs()
    assert log.rate_hz == 200.0 and log.n_samples == 300 and log.channel_names == ("ax", "ay")


def test_a_stream_that_sends_each_sample_twice_is_read_at_its_own_rate(tmp_path: Path, capsys) -> None:
    """Wall 3: every sample repeated 10 ms later with a new stamp read the stream at twice its rate, and gaps were
    judged at that rate."""
    rng = np.random.default_rng(2)
    x = rng.normal(size=(250, 3))  # 5 s at 50 Hz
    t = np.arange(250) / 50.0
    rows = [(tt + d, *v) for tt, v in zip(t, x, strict=True) for d in (0.0, 0.01)]  # each sample again 10 ms later
    keep = [r for r in rows if not 2.0 <= r[0] < 2.1]  # 0.1 s of silence: five samples of the stream at 50 Hz
    f = tmp_path / "imu.csv"
    f.write_text("time,ax,ay,az\n" + "\n".join(",".join(f"{v:.6f}" for v in r) for r in keep) + "\n")
    assert run("ingest", tmp_path / "s", f, "--dry-run") == 0
    out = capsys.readouterr().out
    assert "samples at 50 Hz" in out and "imu 50.0 Hz (" in out and "repeated samples dropped" in out
    run("new", tmp_path / "s")
    assert run("ingest", tmp_path / "s", f) == 0  # 0.1 s is five periods at 50 Hz, not ten: no gap
    (log,) = Session.open(tmp_path / "s").logs()
    assert log.rate_hz == 50.0 and 240 <= log.n_samples <= 250
    got = np.asarray(Session.open(tmp_path / "s").rows(log.id)[:100])
    np.testing.assert_allclose(got, x[:100], atol=1e-5)  # every sample once, on the grid
