"""Nothing reaches the terminal or a mapping raw (issue 52, item 4): file and topic names with control characters
are printed escaped by ``ingest`` and ``info``, and the dry run's mapping ingests as is whatever the topics are named.
Before: a name could clear the screen, set the terminal's title or print a fake line, and a newline in a topic name
put an uncommented ``rate_hz = 3.0`` into the mapping."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from mcap.writer import Writer as RawWriter

from tests.conftest import new_session
from tests.fork_client import run_cli
from workbench.cli.terminal import shown

HOSTILE_TOPICS = (
    "/imu\nrate_hz = 3.0\n#",
    "\x1b]0;owned\x07/feet",
    '/odd"quote\\back\x7f\x9b\u202e',
)


def _json_mcap(path: Path, topics: tuple[str, ...], *, n: int = 300) -> Path:
    """An IMU-shaped JSON channel on each topic at 100 Hz."""
    with open(path, "wb") as f:
        w = RawWriter(f)
        w.start(profile="", library="test")
        schema = w.register_schema("imu", "jsonschema", b"{}")
        channels = [w.register_channel(t, "json", schema) for t in topics]
        for i in range(n):
            for k, ch in enumerate(channels):
                msg = {"angular_velocity": {"x": np.sin(i / 7 + k), "y": 0.1 * k, "z": 0.0}}
                w.add_message(ch, log_time=int(1e9 + i * 1e7), data=json.dumps(msg).encode(), publish_time=0)
        w.finish()
    return path


def test_names_reach_the_terminal_escaped(tmp_path: Path) -> None:
    new_session(tmp_path / "s").close()
    name = "walk\x1b[2J\ningested 5 log(s)\x1b]0;owned\x07"
    log = _json_mcap(tmp_path / f"{name}.mcap", HOSTILE_TOPICS)
    code, out, err, _, _ = run_cli(["ingest", str(tmp_path / "s"), str(log)])
    assert code == 0, err
    code, info, err2, _, _ = run_cli(["info", str(tmp_path / "s")])
    assert code == 0, err2
    for text in (out, err, info, err2):
        assert "\x1b" not in text and "\x07" not in text and "\x9b" not in text and "\u202e" not in text, text
    assert [line for line in out.splitlines() if line.startswith("ingested")] == ["ingested 1 log(s)"]
    assert shown(name) in out and shown(name) in info  # the name, readable: walk\x1b[2J\ningested ...
    assert "\\x1b[2J" in info
    # an error naming the file escapes it too
    bad = tmp_path / f"bad\x1b[2J\n{name}.csv"
    bad.write_text("not,a\nlog\n")
    code, out, err, _, _ = run_cli(["ingest", str(tmp_path / "s"), str(bad)])
    assert code == 2 and "\x1b" not in err and len(err.strip().splitlines()) == 1, err


def test_the_dry_runs_mapping_ingests_as_is_whatever_the_topics_are_named(tmp_path: Path) -> None:
    log = _json_mcap(tmp_path / "walk.mcap", HOSTILE_TOPICS)
    new_session(tmp_path / "s").close()
    code, mapping, err, _, _ = run_cli(["ingest", str(tmp_path / "s"), str(log), "--dry-run"])
    assert code == 0, err
    assert "\x1b" not in mapping and "\x07" not in mapping
    assert not any(line.startswith("rate_hz") for line in mapping.splitlines()), mapping  # stayed in its comment
    (tmp_path / "mapping.toml").write_text(mapping)
    import tomllib

    parsed = tomllib.loads(mapping)
    assert {c["source"] for c in parsed["channels"]} == set(HOSTILE_TOPICS)  # each topic, exactly
    code, _, err, _, _ = run_cli(["ingest", str(tmp_path / "s"), str(log), "--mapping", str(tmp_path / "mapping.toml")])
    assert code == 0, err
    from sessions import Session

    with Session.open(tmp_path / "s") as s:
        (ingested,) = s.logs()
        assert ingested.rate_hz == 100.0 and ingested.n_channels == len(parsed["channels"])
        assert {c.source.rsplit(":", 1)[0] for c in ingested.channels} == set(HOSTILE_TOPICS)


def test_a_terrain_name_is_one_line_of_text_and_an_old_one_prints_escaped(tmp_path: Path, capsys) -> None:
    """Issue 64, item 4: ``labels import --create-terrains`` printed a terrain holding a newline raw (``added
    terrain(s): dirt`` and then a fake ``ingested 9 log(s)``). Such a name is refused where a name enters; one that a
    session of an older workbench holds prints escaped in every command that lists terrains."""
    import sqlite3

    from sessions import Session
    from workbench.cli import main

    fake = "dirt\ningested 9 log(s)"
    assert main(["new", str(tmp_path / "s"), "--terrains", fake]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "control character '\\n'" in err[0], err
    assert main(["new", str(tmp_path / "s"), "--terrains", "grass"]) == 0
    with Session.open(tmp_path / "s") as s:
        s.ingest([_json_mcap(tmp_path / "walk.mcap", ("/imu",))])
    conn = sqlite3.connect(tmp_path / "s" / "session.sqlite")  # as an older workbench could have stored it
    with conn:
        conn.execute("UPDATE terrains SET name = ? WHERE name = 'grass'", (fake,))
    conn.close()
    labels = tmp_path / "l.csv"
    labels.write_text("log,start_s,end_s,terrain\nwalk,0,1,sand\n")
    capsys.readouterr()
    for args in (
        ["terrains", "{s}", "list"],
        ["info", "{s}"],
        ["labels", "import", "{s}", str(labels), "--create-terrains"],
    ):
        assert main([a.replace("{s}", str(tmp_path / "s")) for a in args]) == 0
    out = capsys.readouterr().out
    assert "ingested 9 log(s)" not in out.splitlines() and out.count(shown(fake)) == 2, out
    assert "added terrain(s): sand" in out
    assert main(["terrains", str(tmp_path / "s"), "rename", fake, "dirt\x1b[2J"]) == 2
