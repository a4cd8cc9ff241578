"""Inputs that hung, exhausted memory or printed an internal error (issue 52, item 3), each with the CLI command a
user would run on it and what must come out: refused in one line naming the file (exit 2, the session unchanged),
or, where the input is legitimate, read correctly. Run by ``test_hostile_cli.py`` in a child process each."""

from __future__ import annotations

import sqlite3
import struct
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Case:
    """One hostile input: the command's arguments (``{session}`` stands for the session's folder), what the one
    error line must name (the file) and say, or ``check``, run on the session when the input is legitimate."""

    name: str
    args: list[str]
    names: str = ""  # the file the refusal must name
    says: str = ""  # a part of the reason
    check: Callable[[Path, str], None] | None = None  # (session, stdout) for a legitimate input
    code: int = 2


def _csv(path: Path, seconds: float = 30.0, rate: float = 100.0, *, last_time: float | None = None) -> Path:
    t = np.arange(int(seconds * rate)) / rate
    if last_time is not None:
        t[-1] = last_time
    rows = "\n".join(f"{x:.6f},{np.sin(x):.5f},{np.cos(x):.5f}" for x in t)
    path.write_text("time,a,b\n" + rows + "\n")
    return path


def time_jump(tmp: Path) -> list[Case]:
    csv = _csv(tmp / "jump.csv", last_time=1e9)
    return [
        Case("a CSV whose last time is 1e9", ["ingest", "{session}", str(csv)], str(csv), "no data for"),
        Case("... as a dry run", ["ingest", "{session}", str(csv), "--dry-run"], "", "REFUSED: no data for", code=2),
        Case(
            "... with --allow-gaps",
            ["ingest", "{session}", str(csv), "--allow-gaps"],
            str(csv),
            "samples from 3,000 read",
        ),
    ]


def rates(tmp: Path) -> list[Case]:
    csv = _csv(tmp / "rate.csv")
    mapping = tmp / "rate.toml"
    mapping.write_text("rate_hz = 1e7\n")
    return [
        Case("--rate 1e7", ["ingest", "{session}", str(csv), "--rate", "1e7"], "--rate", "100000 Hz"),
        Case(
            "--rate 1e9, dry run", ["ingest", "{session}", str(csv), "--rate", "1e9", "--dry-run"], "--rate", "100000"
        ),
        Case("rate_hz = 1e7", ["ingest", "{session}", str(csv), "--mapping", str(mapping)], str(mapping), "100000"),
    ]


def deep_mappings(tmp: Path) -> list[Case]:
    toml, js = tmp / "deep.toml", tmp / "deep.json"
    toml.write_text("x = " + "[" * 100_000 + "]" * 100_000 + "\n")
    js.write_text("[" * 100_000 + "]" * 100_000)
    csv = _csv(tmp / "d.csv", 2.0)
    return [
        Case(
            "a TOML mapping nested 100,000 deep",
            ["ingest", "{session}", str(csv), "--mapping", str(toml)],
            str(toml),
            "nested",
        ),
        Case(
            "a JSON mapping nested 100,000 deep",
            ["ingest", "{session}", str(csv), "--mapping", str(js)],
            str(js),
            "nested",
        ),
    ]


def wide_mappings(tmp: Path) -> list[Case]:
    csv = tmp / "small.csv"
    t = np.arange(1000) / 100
    csv.write_text("\n".join(f"{x:.2f},{np.sin(x):.4f},{np.cos(x):.4f}" for x in t) + "\n")  # 27 KB, no header
    columns = tmp / "columns.toml"
    names = ", ".join(f'"c{i}"' for i in range(100_000))
    columns.write_text(f"[csv]\nheader = false\ntime_column = 0\ncolumns = [{names}]\n")
    channels = tmp / "channels.toml"
    channels.write_text('[[channels]]\nsource = "a"\n' * 100_000)
    return [
        Case(
            "a mapping naming 100,000 columns",
            ["ingest", "{session}", str(csv), "--mapping", str(columns)],
            str(columns),
            "columns",
        ),
        Case(
            "100,000 [[channels]] on one column",
            ["ingest", "{session}", str(csv), "--mapping", str(channels)],
            str(channels),
            "channels",
        ),
    ]


def header_no(tmp: Path) -> list[Case]:
    csv = tmp / "h.csv"
    t = np.arange(1000) / 100
    csv.write_text("\n".join(f"{x:.2f},{np.sin(x):.4f}" for x in t) + "\n")
    mapping = tmp / "h.toml"
    mapping.write_text('[csv]\nheader = "no"\n')
    return [
        Case(
            'mapping header = "no"',
            ["ingest", "{session}", str(csv), "--mapping", str(mapping)],
            str(mapping),
            "header must be true or false",
        )
    ]


def label_files(tmp: Path) -> list[Case]:
    big = tmp / "ten-million.csv"
    row = b"walk,0,10,grass\n"
    with open(big, "wb") as f:
        f.write(b"log,start_sample,end_sample,terrain\n")
        block = row * 1_000_000
        for _ in range(10):
            f.write(block)
    bad = tmp / "bad-row-2.csv"
    with open(bad, "wb") as f:
        f.write(b"log,start_sample,end_sample,terrain\nwalk,zero,10,grass\n")
        block = row * 1_000_000
        for _ in range(10):
            f.write(block)
    under = tmp / "bad-row-2-under-the-cap.csv"
    with open(under, "wb") as f:
        f.write(b"log,start_sample,end_sample,terrain\nwalk,zero,10,grass\n")
        block = row * 1_000_000
        for _ in range(4):
            f.write(block)
        f.write(row * 900_000)
    nan_time = tmp / "nan-time.csv"
    nan_time.write_text("log,start_s,end_s,terrain\nwalk,nan,1.0,grass\n")
    return [
        Case("a 10-million-row label CSV", ["labels", "import", "{session}", str(big)], str(big), "rows"),
        Case("... with a bad value in row 2", ["labels", "import", "{session}", str(bad)], str(bad), "rows"),
        Case(
            "4.9 million rows, a bad value in row 2",
            ["labels", "import", "{session}", str(under)],
            str(under),
            "row 2: start_sample is 'zero', not a number",
        ),
        Case(
            "a label file with nan as a time",
            ["labels", "import", "{session}", str(nan_time)],
            str(nan_time),
            "row 2: start_s is 'nan', not a number",
        ),
    ]


def na_terrains(tmp: Path) -> list[Case]:
    path = tmp / "na.csv"
    path.write_text("log,start_sample,end_sample,terrain\nwalk,0,100,NA\nwalk,100,200,null\nwalk,200,300,NaN\n")

    def check(session: Path, out: str) -> None:
        from sessions import Session

        with Session.open(session) as s:
            assert sorted(x.terrain for x in s.segments()) == ["NA", "NaN", "null"], out

    return [
        Case(
            "terrains named NA, null, NaN",
            ["labels", "import", "{session}", str(path), "--create-terrains"],
            check=check,
            code=0,
        )
    ]


def _ros1_bag(path: Path, seconds: float = 2.0, *, chunk: int | None = None) -> Path:
    from rosbags.rosbag1 import Writer as BagWriter
    from rosbags.typesys import Stores, get_typestore

    from tests.sessions.test_ingest_bag import _write

    ts = get_typestore(Stores.ROS1_NOETIC)
    writer = BagWriter(path)
    if chunk is not None:
        writer.chunk_threshold = chunk
    with writer as w:
        _write(w, ts.serialize_ros1, ts, seconds)
    return path


def repeated_chunk_infos(tmp: Path) -> list[Case]:
    from tests.safety.bomb_files import _ros1_record, _ros1_records

    path = _ros1_bag(tmp / "repeated.bag", 4.0, chunk=4096)
    raw = path.read_bytes()
    magic = raw.index(b"\n") + 1
    h_start, h_end, h_fields, h_data = _ros1_records(raw, magic)[0]
    (index_pos,) = struct.unpack("<Q", h_fields["index_pos"])
    records = _ros1_records(raw, index_pos)
    connections = [raw[a:b] for a, b, f, _ in records if f["op"] == b"\x07"]
    infos = [raw[a:b] for a, b, f, _ in records if f["op"] == b"\x06"]
    times = 1000
    count = struct.pack("<I", len(infos) * times)
    header = _ros1_record({**h_fields, "chunk_count": count}, h_data)
    assert len(header) == h_end - h_start
    path.write_bytes(raw[:magic] + header + raw[h_end:index_pos] + b"".join(connections) + b"".join(infos) * times)
    return [
        Case(
            f"a ROS 1 bag with its {len(infos)} chunk infos repeated 1000x",
            ["ingest", "{session}", str(path)],
            str(path),
            "more than once",
        )
    ]


def garbage_definition(tmp: Path) -> list[Case]:
    from tests.safety.bomb_files import _ros1_record, _ros1_records

    path = _ros1_bag(tmp / "garbage-def.bag", 1.0)
    raw = path.read_bytes()
    h_fields = _ros1_records(raw, raw.index(b"\n") + 1)[0][2]
    (index_pos,) = struct.unpack("<Q", h_fields["index_pos"])
    out = bytearray(raw[:index_pos])  # the index's connection records are what rosbags reads: nothing moves
    for start, end, fields, data in _ros1_records(raw, index_pos):
        if fields["op"] != b"\x07":
            out += raw[start:end]
            continue
        inner, at = {}, 0
        while at < len(data):
            (flen,) = struct.unpack_from("<I", data, at)
            k, _, v = data[at + 4 : at + 4 + flen].partition(b"=")
            inner[k.decode()] = v
            at += 4 + flen
        inner["message_definition"] = b"float64 x y z\n)))garbage(((\nint32[ q\n"
        body = b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v for k, v in inner.items())
        out += _ros1_record(fields, body)
    path.write_bytes(bytes(out))
    return [Case("a garbage ROS 1 message definition", ["ingest", "{session}", str(path)], str(path), "")]


def compressed_ros2(tmp: Path) -> list[Case]:
    import zstandard
    from rosbags.rosbag2 import Writer as Bag2Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    from rosbags.typesys import Stores, get_typestore

    from tests.sessions.test_ingest_bag import _write

    ts = get_typestore(Stores.ROS2_HUMBLE)
    plain = tmp / "plain"
    with Bag2Writer(plain, version=8) as w:
        _write(w, ts.serialize_cdr, ts, 1.0)
    db3 = next(plain.glob("*.db3"))
    renamed = tmp / "whole.db3"
    renamed.write_bytes(zstandard.ZstdCompressor().compress(db3.read_bytes()))
    filed = tmp / "filed"
    writer = Bag2Writer(filed, version=8)
    writer.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
    with writer as w:
        _write(w, ts.serialize_cdr, ts, 1.0)
    inside = next(p for p in filed.iterdir() if p.name.endswith(".db3.zstd"))
    return [
        Case(
            "a whole-file compressed ROS 2 bag renamed .db3",
            ["ingest", "{session}", str(renamed)],
            str(renamed),
            "compressed",
        ),
        Case(
            "a file-compressed bag written by rosbags", ["ingest", "{session}", str(filed)], str(inside), "compressed"
        ),
    ]


def recursive_view(tmp: Path) -> list[Case]:
    from tests.conftest import new_session

    session = tmp / "tampered"
    s = new_session(session)
    s.ingest([_csv(tmp / "v.csv", 2.0)])
    s.close()
    conn = sqlite3.connect(session / "session.sqlite")
    conn.executescript(
        "PRAGMA foreign_keys = OFF; ALTER TABLE logs RENAME TO logs_old;"
        "CREATE VIEW logs AS WITH RECURSIVE r(n) AS (SELECT 1 UNION ALL SELECT n + 1 FROM r) "
        "SELECT logs_old.* FROM r, logs_old;"
    )
    conn.close()
    return [
        Case(
            "a session.sqlite whose logs is a recursive view",
            ["info", str(session)],
            str(session / "session.sqlite"),
            "view",
        )
    ]


def skipped_camera_frame(tmp: Path) -> list[Case]:
    from tests.safety.bomb_files import camera_log

    path = camera_log(tmp / "cam.mcap", b"not an image at all", fmt="png")

    def check(session: Path, out: str) -> None:
        assert "BytesIO" not in out and "object at 0x" not in out, out

    return [Case("a skipped camera frame", ["ingest", "{session}", str(path)], check=check, code=0)]


def _tiny_bundle(folder: Path) -> Path:
    """An untrained bundle of the paper family that reads ``_csv``'s channels ``a, b``: enough for ``classify``."""
    import torch

    from training import Classifier, ClassifierConfig, ModelBundle, Normalizer, Predictor, PredictorConfig
    from training.runtime.bundle import save_bundle

    torch.manual_seed(0)
    logs = [np.random.default_rng(0).normal(size=(500, 2)).astype(np.float32)]
    clfs = [Classifier(ClassifierConfig(4, 2, 4, 0.2)).eval() for _ in range(2)]
    bundle = ModelBundle(
        Predictor(PredictorConfig(2, 4)).eval(), Normalizer.fit(logs), ("a", "b"), 100.0, clfs, ("grass", "sand")
    )
    return save_bundle(bundle, folder)


def bundles(tmp: Path) -> list[Case]:
    """Issue 64, items 2 and 4: a bundle's files are plain, bounded and finite, and --smooth is a finite time."""
    import os

    from safetensors.torch import load_file, save_file

    log = _csv(tmp / "run.csv", 10.0)
    out = str(tmp / "out.csv")
    good = _tiny_bundle(tmp / "good")
    nan = _tiny_bundle(tmp / "nan")
    weights = load_file(nan / "classifier.safetensors")
    save_file({k: v.fill_(float("nan")) for k, v in weights.items()}, nan / "classifier.safetensors")
    fifo = _tiny_bundle(tmp / "fifo")
    (fifo / "predictor.safetensors").unlink()
    os.mkfifo(fifo / "predictor.safetensors")
    deep = _tiny_bundle(tmp / "deep")
    (deep / "model.json").write_text("[" * 100_000 + "]" * 100_000)
    huge = _tiny_bundle(tmp / "huge")
    with open(huge / "model.json", "r+b") as f:
        f.truncate(300 << 20)  # sparse: 300 MB to a reader, nothing on the disk
    dangling = tmp / "dangling"
    dangling.symlink_to(tmp / "nowhere" / "export")

    return [
        Case(
            "classify --smooth inf",
            ["classify", str(good), str(log), "--out", out, "--smooth", "inf"],
            "--smooth",
            "at most 86400",
        ),
        Case(
            "a bundle of NaN weights",
            ["classify", str(nan), str(log), "--out", out],
            str(nan),
            "NaN or infinite value(s); the bundle is damaged",
        ),
        Case(
            "a bundle's predictor.safetensors a FIFO",
            ["classify", str(fifo), str(log), "--out", out],
            "predictor.safetensors",
            "not a regular file",
        ),
        Case(
            "a bundle's model.json nested 100,000 deep",
            ["classify", str(deep), str(log), "--out", out],
            "model.json",
            "nested deeper",
        ),
        Case(
            "a bundle's model.json of 300 MB",
            ["classify", str(huge), str(log), "--out", out],
            "model.json",
            "314,572,800 bytes",
        ),
        Case(
            "export --out a dangling symbolic link",
            ["export", "{session}", "--out", str(dangling)],
            str(dangling),
            "a symbolic link",
        ),
    ]


def long_names(tmp: Path) -> list[Case]:
    """Issue 64, item 4: one limit on names in every label reader; a terrain name is one line of text."""
    import json

    import pandas as pd

    name = "g" * (50 << 20)
    rows = [{"log": "walk", "start_s": 0.0, "end_s": 1.0, "terrain": name}]
    js, pq, csv = tmp / "long.json", tmp / "long.parquet", tmp / "long.csv"
    js.write_text(json.dumps(rows))
    pd.DataFrame(rows).to_parquet(pq)
    csv.write_text(f"log,start_s,end_s,terrain\nwalk,0,1,grass\nwalk,1,2,{name}\n")
    studio = tmp / "studio.json"
    task = {
        "data": {"log": "walk"},
        "annotations": [
            {"result": [{"type": "timeserieslabels", "value": {"start": 0.0, "end": 1.0, "timeserieslabels": [name]}}]}
        ],
    }
    studio.write_text(json.dumps([task]))
    newline = tmp / "newline.csv"
    newline.write_text('log,start_s,end_s,terrain\nwalk,0,1,"dirt\ningested 9 log(s)"\n')
    create = ["--create-terrains"]
    return [
        Case(
            "a JSON label file with a 50 MB terrain name",
            ["labels", "import", "{session}", str(js), *create],
            str(js),
            "characters long; a name is at most 300",
        ),
        Case(
            "a Parquet label file with a 50 MB terrain name",
            ["labels", "import", "{session}", str(pq), *create],
            str(pq),
            "a name is at most 300",
        ),
        Case(
            "a Label Studio export with a 50 MB terrain name",
            ["labels", "import", "{session}", str(studio), *create],
            str(studio),
            "a name is at most 300",
        ),
        Case(
            "a CSV label file with a 50 MB terrain name",
            ["labels", "import", "{session}", str(csv), *create],
            str(csv),
            "row 3 is longer than 65,536 bytes",
        ),
        Case(
            "a label file's terrain holding a newline",
            ["labels", "import", "{session}", str(newline), *create],
            str(newline),
            "row 2: the terrain name holds a control character",
        ),
        Case(
            "terrains add a 400-character name",
            ["terrains", "{session}", "add", "t" * 400],
            "",
            "a terrain name of 400 characters",
        ),
    ]


def writes(tmp: Path) -> list[Case]:
    """Issue 81, items 1 and 2: every writer checks its target before any work: never through a link (a dangling
    one made ``outside/x.csv`` exit 0), never over a file, never into a missing folder."""
    outside = tmp / "outside"
    outside.mkdir()
    dangling = tmp / "d.csv"
    dangling.symlink_to(outside / "x.csv")
    kept = tmp / "kept.csv"
    kept.write_text("somebody's file\n")
    to_file = tmp / "to-kept.csv"
    to_file.symlink_to(kept)
    log = _csv(tmp / "run.csv", 10.0)
    good = _tiny_bundle(tmp / "good")

    def untouched(path: Path) -> Callable[[Path, str], None]:
        def check(session: Path, out: str) -> None:
            assert not (outside / "x.csv").exists() and kept.read_text() == "somebody's file\n", out

        return check

    # one row per kind of target, each through another writer (every writer meets every target in
    # tests/workbench/cli/test_writes_and_checks.py, in one process)
    cases = [
        (
            "suggest --out a dangling link",
            ["suggest", "{session}", "--out", str(dangling)],
            dangling,
            "a symbolic link",
        ),
        ("classify --out a link to a file", ["classify", str(good), str(log), "--out", str(to_file)], to_file, "link"),
        ("labels export --out a file", ["labels", "export", "{session}", "--out", str(kept)], kept, "exists already"),
        (
            "suggest --out a missing folder",
            ["suggest", "{session}", "--out", str(tmp / "no" / "x.csv")],
            tmp / "no",
            "",
        ),
        ("evaluate loop --out a file", ["evaluate", "loop", "{session}", "--out", str(kept)], kept, "exists already"),
    ]
    return [Case(name, args, str(target), says) for name, args, target, says in cases] + [
        Case(
            "labels export --out a file, read after",
            ["labels", "export", "{session}", "--out", str(kept)],
            check=untouched(kept),
            code=2,
        )
    ]


def check_rows(tmp: Path) -> list[Case]:
    """Issue 81, items 3 and 5: a label file imported twice labels once; a suggestion file's check fields name a
    classifier version the session has and a kind of check, or the file is refused naming the row."""
    twice = tmp / "twice.csv"
    twice.write_text("log,start_s,end_s,terrain\n" + "walk,1,2,grass\n" * 50)

    def once(session: Path, out: str) -> None:
        from sessions import Session

        with Session.open(session) as s:
            assert [(g.start, g.stop) for g in s.segments()] == [(100, 200)], out
        assert "1 new label(s), 49 already labelled so" in out, out

    cases = [
        Case("a label file of 50 identical rows", ["labels", "import", "{session}", str(twice)], check=once, code=0)
    ]
    for version, kind in (("999", "suggestion"), ("true", "suggestion"), ("1e400", "spot check"), ("nan", "manual")):
        path = tmp / f"forged-{len(cases)}.csv"
        path.write_text(f"log,start_s,end_s,terrain,guess,kind,classifier\nwalk,1,2,grass,grass,{kind},{version}\n")
        cases.append(
            Case(
                f"a suggestion file's classifier {version}",
                ["labels", "import", "{session}", str(path)],
                str(path),
                "is not a classifier version of this session",
            )
        )
    bogus = tmp / "bogus-kind.csv"
    bogus.write_text("log,start_s,end_s,terrain,guess,kind,classifier\nwalk,1,2,grass,grass,bogus,1\n")
    cases.append(
        Case("a check of kind bogus", ["labels", "import", "{session}", str(bogus)], str(bogus), "kind 'bogus'")
    )
    return cases


def one_name_one_run(tmp: Path) -> list[Case]:
    """Issue 99, items 1 and 6: a second run of the template's name is named apart, not merged into ``walk``; the
    same file reached through a link is the log the session has; a label row whose ``source_file`` the session
    never saw (a colleague's paths) lands on the one log its name names."""
    (tmp / "other").mkdir()
    other = _csv(tmp / "other" / "walk.csv", 20.0)
    link = tmp / "link.csv"
    link.symlink_to(other)
    mixed = tmp / "mixed.csv"
    mixed.write_text(f"log,source_file,start_s,end_s,terrain\nwalk,{other},1,2,grass\n")

    def named_apart(session: Path, out: str) -> None:
        from sessions import Session

        with Session.open(session) as s:
            names = [x.name for x in s.logs()]
        assert names == ["walk", "walk-2"] and "named walk-2: the session has another log named walk" in out, out

    def one_log(session: Path, out: str) -> None:
        from sessions import Session

        with Session.open(session) as s:
            assert [x.name for x in s.logs()] == ["walk", "walk-2"], out
        assert "(one file): read once" in out and "ingested 1 log(s)" in out, out

    def on_walk(session: Path, out: str) -> None:  # a file from another machine names paths the session never saw
        from sessions import Session

        with Session.open(session) as s:
            assert [(s.log(g.log_id).name, g.start, g.stop) for g in s.segments()] == [("walk", 100, 200)], out

    return [
        Case("another folder's walk.csv", ["ingest", "{session}", str(other)], check=named_apart, code=0),
        Case(
            "... then the same file through a link",
            ["ingest", "{session}", str(other), str(link)],
            check=one_log,
            code=0,
        ),
        Case(
            "a label row whose source_file is no log of the session",
            ["labels", "import", "{session}", str(mixed)],
            check=on_walk,
            code=0,
        ),
    ]


BUILDERS = (
    time_jump,
    rates,
    deep_mappings,
    wide_mappings,
    header_no,
    label_files,
    na_terrains,
    repeated_chunk_infos,
    garbage_definition,
    compressed_ros2,
    recursive_view,
    skipped_camera_frame,
    bundles,
    long_names,
    writes,
    check_rows,
    one_name_one_run,
)
