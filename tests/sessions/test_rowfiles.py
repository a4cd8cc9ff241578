"""Rows on disk: the writer, the reader, the ingest spill buffer, and chunked alignment equal to one pass."""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest

from sessions import FileRows, IngestOptions, NpyWriter
from sessions.ingest import ParsedLog, Stream, align, spill

align_module = importlib.import_module("sessions.ingest.align")  # the package exports the function under its name


def test_npy_writer_writes_a_file_numpy_reads_and_file_rows_slice_it(tmp_path: Path) -> None:
    data = np.arange(70, dtype=np.float32).reshape(10, 7)
    w = NpyWriter(tmp_path / "a.npy", (10, 7), np.float32)
    w[0:4] = data[:4]
    with pytest.raises(ValueError, match="in order"):
        w[5:6] = data[5:6]
    w[4:10] = data[4:]
    w.close()
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), data)
    rows = FileRows.open_npy(tmp_path / "a.npy")
    assert rows.shape == (10, 7) and len(rows) == 10 and rows.dtype == np.float32
    np.testing.assert_array_equal(rows[3:8], data[3:8])
    np.testing.assert_array_equal(rows[8:100], data[8:])  # clipped like an array
    np.testing.assert_array_equal(rows[:], data)
    np.testing.assert_array_equal(rows[2:5, 1], data[2:5, 1])
    np.testing.assert_array_equal(rows.select([6, 0])[1:3], data[1:3][:, [6, 0]])
    assert rows[2:5].flags.writeable  # torch.from_numpy takes it without a warning
    with pytest.raises(TypeError):
        rows[::2]


def test_a_writer_that_did_not_get_every_row_removes_its_file(tmp_path: Path) -> None:
    w = NpyWriter(tmp_path / "b.npy", (5, 2), np.float16)
    w[0:3] = np.ones((3, 2))
    with pytest.raises(ValueError, match="3 of 5 rows"):
        w.close()
    assert not (tmp_path / "b.npy").exists()


def test_a_truncated_file_is_a_clear_error(tmp_path: Path) -> None:
    np.save(tmp_path / "c.npy", np.ones((100, 3), np.float32))
    rows = FileRows.open_npy(tmp_path / "c.npy")
    with open(tmp_path / "c.npy", "r+b") as f:
        f.truncate(200)
    with pytest.raises(OSError, match="short read"):
        rows[0:100]


def test_the_spill_buffer_returns_what_was_appended_across_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(spill, "BLOCK_ROWS", 16)
    rng = np.random.default_rng(0)
    values = rng.normal(size=(100, 3))
    times = np.cumsum(rng.uniform(0.5, 1.5, 100))
    buf = spill.RowBuffer(3)
    for t, v in zip(times, values, strict=True):
        buf.append(t, v.tolist())
    assert len(buf) == 100
    np.testing.assert_array_equal(buf.times(), times)
    np.testing.assert_array_equal(buf.values()[:], values)
    order = rng.permutation(100)
    np.testing.assert_array_equal(spill.reorder(buf.values(), order)[:], values[order])
    assert buf.values().column_any().tolist() == [True, True, True]


def _stream(name: str, times: np.ndarray, values: np.ndarray, *, on_disk: bool) -> Stream:
    if on_disk:
        buf = spill.RowBuffer(values.shape[1])
        for t, v in zip(times, values, strict=True):
            buf.append(t, v.tolist())
        vals = buf.values()
    else:
        vals = values
    k = values.shape[1]
    return Stream(name, times, vals, tuple(f"{name}/{i}" for i in range(k)), ("",) * k, ("s",) * k)


@pytest.mark.parametrize("allow_gaps", [True, False])
def test_chunked_alignment_from_disk_equals_one_pass_in_memory(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, allow_gaps: bool
) -> None:
    """Small chunks, streams read from spill files, duplicate stamps and a gap that crosses a chunk boundary."""
    rng = np.random.default_rng(1)
    t_fast = np.arange(0, 10, 0.01)
    t_slow = np.concatenate([np.arange(0, 4, 0.05), np.arange(4.9, 10, 0.05)])  # silent 4-4.9 s: a gap
    t_slow = np.sort(np.concatenate([t_slow, t_slow[::7]]))  # duplicate stamps
    fast, slow = rng.normal(size=(len(t_fast), 2)), rng.normal(size=(len(t_slow), 3))
    options = IngestOptions(allow_gaps=allow_gaps)

    def run(on_disk: bool):
        streams = (_stream("fast", t_fast, fast, on_disk=on_disk), _stream("slow", t_slow, slow, on_disk=on_disk))
        parsed = ParsedLog("x", "x.mcap", ("x.mcap",), "mcap", streams)
        if on_disk:
            writers = []

            def allocate(shape):
                writers.append(NpyWriter(tmp_path / "aligned.npy", shape, np.float32))
                return writers[-1]

            out = align(parsed, options, allocate=allocate)
            writers[0].close()
            return out, np.load(tmp_path / "aligned.npy")
        out = align(parsed, options)
        return out, out.data

    if not allow_gaps:
        with pytest.raises(Exception, match="no data for") as one_pass:
            run(False)
        monkeypatch.setattr(align_module, "ALIGN_ROWS", 37)
        with pytest.raises(Exception, match="no data for") as chunked:
            run(True)
        assert str(chunked.value) == str(one_pass.value)
        return
    whole, whole_data = run(False)
    monkeypatch.setattr(align_module, "ALIGN_ROWS", 37)  # the gap (rows 400-490) crosses several chunks
    chunked, chunked_data = run(True)
    np.testing.assert_array_equal(chunked_data, whole_data)
    assert chunked.gaps == whole.gaps and len(whole.gaps) == 1
    assert chunked.t0 == whole.t0 and chunked.rate_hz == whole.rate_hz
