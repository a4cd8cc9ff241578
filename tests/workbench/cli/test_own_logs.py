"""What a new user met on their own logs (walls of the "bring your own robot" issue), each reproduced first."""

from __future__ import annotations

import re
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


def test_a_headerless_csv_with_epoch_milliseconds_last_is_timed_by_the_dry_run_and_ingests_as_is(
    tmp_path: Path, capsys
) -> None:
    """Issue 44: a 50 Hz IMU CSV whose last column is a millisecond epoch time got `# time_column = 0` commented
    out, and ingesting with it was refused (`the first column '0' is no time`)."""
    rng = np.random.default_rng(0)
    stamp = 1645154383638 + 20 * np.arange(400) + rng.integers(-2, 3, 400)  # jittered, strictly increasing
    x = rng.normal(size=(400, 6))
    f = tmp_path / "imu.csv"
    f.write_text("\n".join(",".join([*(f"{v:.4f}" for v in row), str(t)]) for row, t in zip(x, stamp, strict=True)))
    assert run("ingest", tmp_path / "s", f, "--dry-run") == 0
    out = capsys.readouterr().out
    assert "# time: column 6 '6' (epoch milliseconds, 50 Hz), found by its steady steps" in out
    assert 'time_column = 6\ntime_unit = "ms"' in out
    (tmp_path / "m.toml").write_text(out)
    assert run("new", tmp_path / "s") == 0 and run("new", tmp_path / "s2") == 0
    assert run("ingest", tmp_path / "s", f, "--mapping", tmp_path / "m.toml") == 0
    assert "+ imu: 8.0 s at 50 Hz, 6 channels" in capsys.readouterr().out
    (log,) = Session.open(tmp_path / "s").logs()
    assert abs(log.t0 - 1645154383.638) < 0.003  # the log keeps its clock: epoch seconds
    assert run("ingest", tmp_path / "s2", f) == 0  # and with no mapping at all, the same log, said in one line
    out = capsys.readouterr().out
    assert "+ imu: 8.0 s at 50 Hz, 6 channels" in out and "note: time: column 6 '6' (epoch milliseconds" in out


def test_two_columns_that_step_like_clocks_are_said_in_one_line_and_the_first_is_time(tmp_path: Path, capsys) -> None:
    t = np.arange(300) / 100.0
    f = tmp_path / "two.csv"
    lines = ["a,recv_ns,b,stamp_s"] + [
        f"{np.sin(x):.4f},{1_700_000_000_000_000_000 + int(x * 1e9) + 5000},{i % 7},{x + 0.0013:.4f}"
        for i, x in enumerate(t)
    ]
    f.write_text("\n".join(lines) + "\n")
    assert run("new", tmp_path / "s") == 0
    assert run("ingest", tmp_path / "s", f) == 0
    out = capsys.readouterr().out
    notes = [ln for ln in out.splitlines() if "could be time" in ln]
    assert len(notes) == 1 and "'recv_ns' (epoch nanoseconds, 100 Hz)" in notes[0]
    assert "'stamp_s' (seconds, 100 Hz)" in notes[0] and "[csv] time_column" in notes[0]
    (log,) = Session.open(tmp_path / "s").logs()
    assert log.channel_names == ("a", "b") and log.rate_hz == 100.0  # the other clock is no channel


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


def test_terrains_are_managed_from_the_command_line_and_label_files(tmp_path: Path, demo_mcap: Path, capsys) -> None:
    """Wall 4: `unknown terrain 'ice'; nothing was imported`, and no command to add, rename or remove terrains."""
    s = tmp_path / "s"
    run("new", s, "--terrains", "grass", "concrete")
    run("ingest", s, demo_mcap)
    labels = tmp_path / "labels.csv"
    labels.write_text("log,terrain,start_s,end_s\nwalk,ice,1.0,5.0\nwalk,snow,10.0,12.0\nwalk,grass,20.0,22.0\n")
    assert run("labels", "import", s, labels) == 2
    assert "unknown terrain 'ice'; nothing was imported (add it with `workbench terrains" in capsys.readouterr().err
    assert run("labels", "import", s, labels, "--create-terrains") == 0
    assert "added terrain(s): ice, snow" in capsys.readouterr().out
    assert run("terrains", s, "remove", "concrete") == 0
    assert run("terrains", s, "remove", "grass") == 2  # labels use it: refused, nothing removed
    assert "labels 1 segment(s)" in capsys.readouterr().err
    assert run("terrains", s, "rename", "snow", "powder") == 0
    assert run("terrains", s, "add", "mud", "--color", "#123456") == 0
    capsys.readouterr()
    assert run("terrains", s) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in out] == ["grass", "ice", "powder", "mud"]
    assert "4.0 s labelled" in out[1] and "#123456" in out[3]
    with Session.open(s) as session:
        assert {seg.terrain for seg in session.segments()} == {"grass", "ice", "powder"}  # the rename followed


def test_reference_truth_is_imported_apart_from_labels(tmp_path: Path, demo_mcap: Path, capsys) -> None:
    """Wall 7, last part: per-row terrain names could not become reference truth."""
    s = tmp_path / "s"
    run("new", s)
    run("ingest", s, demo_mcap)
    truth = tmp_path / "truth.csv"
    truth.write_text("log,terrain,start_s,end_s\nwalk,flooring,0.0,40.0\nwalk,carpet,40.0,80.0\n")
    assert run("labels", "import", s, truth, "--reference", "--create-terrains") == 0
    assert "imported 2 reference row(s)" in capsys.readouterr().out
    with Session.open(s) as session:
        (log,) = session.logs()
        assert session.segments() == [] and [r[2] for r in session.reference(log.id)] == ["flooring", "carpet"]


def test_training_prints_progress_lines_when_its_output_goes_to_a_file(tmp_path: Path, demo_mcap: Path) -> None:
    """Wall 5: `workbench train` printed nothing for 20 minutes when its output went to a file. The paper family's
    LSTM (epochs and a validation loss) in a child whose output is a file; the default family's stages are checked
    in :func:`test_classify_reads_files_as_ingest_does`, whose output is captured."""
    import subprocess
    import sys

    s = tmp_path / "s"
    run("new", s)
    run("ingest", s, demo_mcap)
    code = (
        "import sys; from workbench.cli import model_commands as m; m.PROGRESS_EVERY_S = 0.0; "
        "from workbench.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    with open(tmp_path / "train.log", "w") as out:
        done = subprocess.run(
            [
                sys.executable,
                "-c",
                code,
                "train",
                str(s),
                "--stage",
                "predictor",
                "--model",
                "paper",
                "--max-epochs",
                "2",
                "--hidden",
                "8",
            ],
            stdout=out,
            stderr=subprocess.STDOUT,
            timeout=300,
        )
    text = (tmp_path / "train.log").read_text()
    assert done.returncode == 0, text[-2000:]
    lines = [x for x in text.splitlines() if x.startswith("predictor: ") and "left" in x]
    assert lines and "epoch" in lines[-1] and "loss" in lines[-1] and "spent, about" in lines[-1]
    assert "predictor: done in" in text and "\r" not in text  # lines, not a bar redrawn in place


def _walk_csv(path: Path, freq: float, seed: int, *, hole: bool = False) -> Path:
    """A headerless 3-channel IMU CSV at 100 Hz vibrating at ``freq`` (a terrain), no time column."""
    rng = np.random.default_rng(seed)
    t = np.arange(3000) / 100.0
    x = np.column_stack([np.sin(2 * np.pi * freq * t + k) + 0.3 * rng.normal(size=len(t)) for k in range(3)])
    text = [",".join(f"{v:.4f}" for v in row) for row in x]
    if hole:
        text[1500] = ",".join(["", *text[1500].split(",")[1:]])  # a dropped cell
    path.write_text("\n".join(text) + "\n")
    return path


def test_classify_reads_files_as_ingest_does(tmp_path: Path, capsys, monkeypatch, quick_stage1) -> None:
    """Wall 6: `classify` took none of ingest's options, yet told the user to `use --allow-gaps`, which it refused;
    headerless files could not be classified. (Its `train`, output captured, also shows the default family's
    progress as lines: wall 5 for both of its stages.)"""
    from workbench.cli import model_commands

    monkeypatch.setattr(model_commands, "PROGRESS_EVERY_S", 0.0)
    mapping = tmp_path / "m.toml"
    mapping.write_text('[csv]\nheader = false\ncolumns = ["ax", "ay", "az"]\nsample_rate_hz = 100.0\n')
    logs = [_walk_csv(tmp_path / f"w{i}.csv", (8.0, 25.0)[i % 2], i) for i in range(4)]
    s = tmp_path / "s"
    run("new", s)
    assert run("ingest", s, *logs, "--mapping", mapping) == 0
    labels = tmp_path / "labels.csv"
    labels.write_text(
        "log,terrain,start_s,end_s\n" + "".join(f"w{i},{('soft', 'hard')[i % 2]},2.0,12.0\n" for i in range(4))
    )
    assert run("labels", "import", s, labels, "--create-terrains") == 0
    capsys.readouterr()
    assert run("train", s, "--hidden", "8", "--max-epochs", "1") == 0
    text = capsys.readouterr().out
    for stage in ("predictor", "classifier"):  # the default family's two stages, each as lines with the time left
        lines = [x for x in text.splitlines() if x.startswith(f"{stage}: ") and "left" in x]
        assert lines and "spent, about" in lines[-1] and f"{stage}: done in" in text
    assert "\r" not in text
    assert run("export", s, "--out", tmp_path / "x") == 0
    new = _walk_csv(tmp_path / "new.csv", 25.0, 9, hole=True)
    capsys.readouterr()
    args = ["classify", tmp_path / "x" / "bundle", new, "--out", tmp_path / "p.csv", "--mapping", mapping]
    assert run(*args) == 2
    assert "use --allow-gaps" in capsys.readouterr().err
    assert run(*args, "--allow-gaps") == 0
    import pandas as pd

    pred = pd.read_csv(tmp_path / "p.csv")
    assert len(pred) > 2900 and set(pred["terrain"]) <= {"soft", "hard"}
    assert (pred["terrain"].iloc[200:] == "hard").mean() > 0.9
    assert run(*args, "--allow-gaps", "--rate", "50", "--out", tmp_path / "rate.csv") == 2
    assert "the model runs at 100 Hz" in capsys.readouterr().err
    # the optional HMM: the probabilities written are smoothed, and the line says the robot's causal delay
    assert run(*args, "--allow-gaps", "--smooth", "5", "--out", tmp_path / "smooth.csv") == 0
    said = capsys.readouterr().out
    assert re.search(
        r"new: smoothed \(an HMM, 5 s on a terrain on average\); .* follow a terrain change [\d.]+ s late", said
    )
    smooth = pd.read_csv(tmp_path / "smooth.csv")
    assert len(smooth) == len(pred) and not np.allclose(smooth["p_hard"], pred["p_hard"])
    assert (smooth["terrain"].iloc[200:] == "hard").mean() >= (pred["terrain"].iloc[200:] == "hard").mean()
    for bad in ("0", "-1", "nan", "inf", "1e308"):  # before: inf and 1e308 wrote NaN rows read as the first terrain
        assert run(*args, "--allow-gaps", "--smooth", bad, "--out", tmp_path / f"bad{bad}.csv") == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "above 0 and at most 86400 (a day)" in err[0], err
        assert not (tmp_path / f"bad{bad}.csv").exists()
