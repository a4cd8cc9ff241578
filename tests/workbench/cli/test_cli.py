"""The ``workbench`` command line: subcommands, exit codes, one-line errors, dry-run mappings."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from sessions import Session, load_mapping
from workbench.cli import main


def run(*args: str) -> int:
    return main([str(a) for a in args])


def test_new_ingest_info(tmp_path: Path, demo_mcap: Path, capsys) -> None:
    s = tmp_path / "s"
    assert run("new", s) == 0
    assert "no terrains yet" in capsys.readouterr().out  # nothing imposed on a new session
    assert run("info", s) == 0
    assert "terrains: none yet" in capsys.readouterr().out
    assert run("terrains", s) == 0
    assert "no terrains yet: `workbench terrains" in capsys.readouterr().out
    assert run("new", tmp_path / "t", "--terrains", "ice", "wet floor") == 0
    assert "terrains: ice, wet floor" in capsys.readouterr().out
    assert run("ingest", s, demo_mcap) == 0
    out = capsys.readouterr().out
    assert "+ walk: 90.0 s at 100 Hz, 22 channels" in out and "ingested 1 log(s)" in out
    assert run("terrains", s, "add", "concrete", "grass", "gravel", "mulch", "dirt", "sand") == 0
    assert run("ingest", s, demo_mcap) == 0
    assert "ingested 0 log(s), 1 already in the session" in capsys.readouterr().out
    assert run("info", s) == 0
    out = capsys.readouterr().out
    assert "1 log(s)" in out and "walk" in out and "concrete, grass, gravel, mulch, dirt, sand" in out


def test_bad_files_print_one_line_each_and_exit_2(tmp_path: Path, demo_mcap: Path, capsys) -> None:
    s = tmp_path / "s"
    run("new", s)
    capsys.readouterr()
    (tmp_path / "broken.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\x01" * 50)
    (tmp_path / "bad.csv").write_text("time,a\n0,1\n0.01,x\n")
    code = run("ingest", s, tmp_path / "broken.mcap", demo_mcap, tmp_path / "bad.csv")
    captured = capsys.readouterr()
    assert code == 2
    errors = [ln for ln in captured.err.splitlines() if ln.startswith("error:")]
    assert len(errors) == 2
    assert any("broken.mcap: truncated or corrupt MCAP" in e for e in errors)
    assert any("bad.csv: text 'x' in numeric column 'a' (line 3)" in e for e in errors)
    assert "Traceback" not in captured.err
    assert "ingested 1 log(s), refused 2 file(s)" in captured.out
    assert [x.name for x in Session.open(s).logs()] == ["walk"]


def test_user_errors_exit_2_without_traceback(tmp_path: Path, capsys) -> None:
    assert run("info", tmp_path / "nowhere") == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "not a session folder" in err and "Traceback" not in err
    run("new", tmp_path / "s")
    assert run("new", tmp_path / "s") == 2
    assert "already a session" in capsys.readouterr().err
    (tmp_path / "m.toml").write_text("nonsense = [")
    assert run("ingest", tmp_path / "s", tmp_path / "x.csv", "--mapping", tmp_path / "m.toml") == 2
    assert "m.toml: cannot read mapping file" in capsys.readouterr().err
    assert run("train", tmp_path / "s", "--stage", "classifier", "--consistency", "-1") == 2
    assert "--consistency must be 0 or more, got -1.0" in capsys.readouterr().err


def test_dry_run_writes_nothing_and_prints_a_mapping_that_loads(tmp_path: Path, demo_mcap: Path, capsys) -> None:
    s = tmp_path / "s"
    run("new", s)
    capsys.readouterr()
    assert run("ingest", s, demo_mcap, "--dry-run") == 0
    out = capsys.readouterr().out
    assert "# " + str(demo_mcap) in out and "topic /imu (sensor_msgs/msg/Imu" in out
    assert "-> log 'walk': 8998 samples at 100 Hz" in out
    assert Session.open(s).logs() == []
    mapping_file = tmp_path / "mapping.toml"
    mapping_file.write_text(out)
    mapping = load_mapping(mapping_file)
    assert len(mapping.channels) == 22
    assert mapping.channels[0].source == "/imu" and mapping.channels[0].field == "orientation.x"
    # a user deletes the IMU channels from it and ingests with the result
    kept = [c for c in mapping.channels if c.source != "/imu"]
    mapping_file.write_text(
        "\n".join(
            f'[[channels]]\nsource = "{c.source}"\nfield = "{c.field}"\nname = "{c.name.split("/")[-1]}"\n'
            for c in kept
        )
    )
    assert run("ingest", s, demo_mcap, "--mapping", mapping_file) == 0
    (log,) = Session.open(s).logs()
    assert log.n_channels == 12 and all(n.split("/")[0] in {"fl", "fr", "rl", "rr"} for n in log.channel_names)


def test_dry_run_reports_refusals_with_exit_2(tmp_path: Path, capsys) -> None:
    (tmp_path / "e.csv").write_text("")
    assert run("ingest", tmp_path / "s", tmp_path / "e.csv", "--dry-run") == 2
    assert "REFUSED: empty file" in capsys.readouterr().out


def test_demo_prepares_a_session_without_serving(tmp_path: Path, capsys, quick_stage1) -> None:
    s = tmp_path / "demo"
    assert run("demo", "--session", s, "--logs", "2", "--minutes", "0.5", "--no-serve") == 0
    logs = Session.open(s).logs()
    assert len(logs) == 2 and all(x.n_channels == 22 for x in logs)
    assert all(Session.open(s).reference(x.id) for x in logs)
    assert (tmp_path / "demo-logs" / "walk_000.truth.json").exists()
    assert run("demo", "--session", s, "--no-serve") == 0  # again: reuses the session
    assert "using existing demo session" in capsys.readouterr().out


def test_help_lists_every_command() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "workbench.cli", "--help"], capture_output=True, text=True, check=False
    ).stdout
    for cmd in ("new", "ingest", "info", "serve", "demo"):
        assert cmd in out


@pytest.mark.parametrize("argv", [["ingest"], ["bogus"], ["serve", "--port", "notanumber"]])
def test_bad_arguments_exit_2(argv: list[str]) -> None:
    proc = subprocess.run([sys.executable, "-m", "workbench.cli", *argv], capture_output=True, text=True, check=False)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr


def test_device_cuda_is_refused_for_a_family_without_a_cuda_path(tmp_path: Path, monkeypatch, capsys) -> None:
    """Issue 66: a family with no CUDA path refuses ``--device cuda`` in one line, before any work, instead of
    training on the CPU unsaid; the default and paper families, which have one, are not refused. Run as if CUDA
    were present."""
    import torch

    from training import device_refusal

    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    with Session.create(tmp_path / "s"):
        pass
    for argv in [
        ["train", tmp_path / "s", "--device", "cuda", "--model", "minirocket"],
        ["train", tmp_path / "s", "--device", "cuda", "--model", "auto"],  # auto fits minirocket too
    ]:
        assert run(*argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
        assert err.startswith("error: --device cuda: the minirocket family trains and scores on the CPU only")
        assert "--model default or --model paper trains on cuda" in err
    assert run("evaluate", "loop", tmp_path / "s", "--device", "cuda") == 2  # the loop fits as the Retrain: CPU
    assert (
        capsys.readouterr().err
        == "error: --device: evaluate loop takes no --device (evaluate borealtc, qcat and demo take it)\n"
    )
    assert run("evaluate", "demo", tmp_path, "--simulate", "--device", "cuda") == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --device cuda: evaluate --simulate runs the default family's rounds on the CPU")
    with Session.open(tmp_path / "s") as s:
        assert s.model_versions() == []  # refused before any work
    assert device_refusal("paper", "cuda") is None and device_refusal("default", "cuda") is None
    assert device_refusal("default", "cpu") is None


def test_device_cuda_without_a_gpu_is_one_clear_line(tmp_path: Path, capsys) -> None:
    import torch

    if torch.cuda.is_available():
        pytest.skip("this machine has a CUDA device")
    assert run("evaluate", "demo", tmp_path, "--simulate", "--device", "cuda") == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --device cuda: no CUDA device") and "Traceback" not in err


def test_each_evaluate_protocol_lists_only_its_own_options(capsys) -> None:
    """`workbench evaluate PROTOCOL --help` shows what that protocol takes and nothing else; an option of another
    protocol, or a renamed one, is one line naming where it went (exit 2, nothing run)."""
    for protocol, own, foreign in [
        ("loop", ["--per-round", "--far", "--verify", "--strategies"], ["--variant", "--simulate", "--feature-mode"]),
        ("borealtc", ["--variant", "--simulate", "--per-round", "--split"], ["--far", "--verify", "--person"]),
        ("session", ["--reference", "--folds"], ["--simulate", "--rounds", "--device"]),
        ("qcat", ["--folds", "--hidden"], ["--simulate", "--labelled", "--out"]),
    ]:
        with pytest.raises(SystemExit):
            run("evaluate", protocol, "--help")
        text = capsys.readouterr().out
        assert all(o in text for o in own), (protocol, own)
        assert not [o for o in foreign if o in text], (protocol, foreign)
    assert run("evaluate", "borealtc", "nowhere", "--simulate", "--batch", "10") == 2
    assert capsys.readouterr().err == "error: --batch: now --per-round (workbench evaluate borealtc --help)\n"
    assert run("evaluate", "session", "nowhere", "--simulate") == 2
    assert (
        capsys.readouterr().err
        == "error: --simulate: evaluate session takes no --simulate (evaluate borealtc and demo take it)\n"
    )


def test_two_paths_to_one_file_are_read_once_and_said(tmp_path: Path, capsys) -> None:
    """Issue 99, item 1: two links to one file gave one log without a word."""
    import numpy as np
    import pandas as pd

    first = tmp_path / "run.csv"
    t = np.arange(500) / 50.0
    pd.DataFrame({"time": t, "a": np.sin(t)}).to_csv(first, index=False)
    link = tmp_path / "link.csv"
    link.symlink_to(first)
    assert main(["new", str(tmp_path / "s"), "--terrains", "grass"]) == 0
    assert main(["ingest", str(tmp_path / "s"), str(first), str(link)]) == 0
    out = capsys.readouterr().out
    assert f"note: {link} is {first} (one file): read once" in out and "ingested 1 log(s)" in out, out
