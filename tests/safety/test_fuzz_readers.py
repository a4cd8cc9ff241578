"""Fuzz targets for the log readers: whatever bytes come in, a reader returns streams or raises ``IngestError``.

Hypothesis mutates a real MCAP file (cuts, flipped bytes, inserted and deleted runs) and writes CSV text from the
tokens that break parsers (NaN, inf, empty cells, quotes, BOM, CR, stray commas). ``make test`` runs a few dozen
examples of each; ``make stress`` sets ``WORKBENCH_FUZZ_EXAMPLES`` for thousands.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sessions import IngestError, IngestOptions
from sessions.ingest import align
from sessions.ingest.csv_reader import read_generic_csv
from sessions.ingest.mcap_reader import read_mcap

EXAMPLES = int(os.environ.get("WORKBENCH_FUZZ_EXAMPLES", "40"))
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=EXAMPLES <= 100,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


@pytest.fixture(scope="module")
def small_mcap(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    from workbench.demo import generate_walk, write_walk

    return write_walk(generate_walk(4, 6.0), tmp_path_factory.mktemp("fuzz") / "w.mcap", seed=4).read_bytes()


def _read(reader, name: str, data: bytes) -> None:
    """The promise: streams, aligned to finite samples, or an ``IngestError`` naming the file on one line."""
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / name
        path.write_bytes(data)
        try:
            parsed = reader(path, IngestOptions())
            parsed = parsed[0] if isinstance(parsed, tuple) else parsed
            out = align(parsed, IngestOptions(allow_gaps=True))
            assert np.isfinite(out.data).all()
        except IngestError as exc:
            assert "\n" not in str(exc) and str(exc).startswith(str(path))


mutation = st.one_of(
    st.tuples(st.just("cut"), st.floats(0, 1)),
    st.tuples(st.just("flip"), st.floats(0, 1), st.integers(1, 255)),
    st.tuples(st.just("insert"), st.floats(0, 1), st.binary(min_size=1, max_size=64)),
    st.tuples(st.just("delete"), st.floats(0, 1), st.integers(1, 64)),
)


def mutate(data: bytes, ops: list[tuple]) -> bytes:
    b = bytearray(data)
    for op in ops:
        at = int(op[1] * max(len(b) - 1, 0))
        if op[0] == "cut":
            del b[at:]
        elif op[0] == "flip" and b:
            b[at] ^= op[2]
        elif op[0] == "insert":
            b[at:at] = op[2]
        elif op[0] == "delete":
            del b[at : at + op[2]]
    return bytes(b)


@pytest.mark.fuzz
@FUZZ
@given(ops=st.lists(mutation, min_size=1, max_size=6))
def test_mcap_reader_survives_mutations(small_mcap: bytes, ops: list[tuple]) -> None:
    _read(read_mcap, "fuzz.mcap", mutate(small_mcap, ops))


cell = st.one_of(
    st.sampled_from(["", "nan", "NaN", "inf", "-inf", "1e309", "x", '"', '""', "1,2", " ", "\r", "0x10", "1e-3"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**20), 10**20).map(str),
)
row = st.lists(cell, min_size=0, max_size=5).map(",".join)


@pytest.mark.fuzz
@FUZZ
@given(
    header=st.sampled_from(["time,a,b", "t,x", "a,b,c", "", "\ufefftime,a"]),
    rows=st.lists(row, max_size=30),
    newline=st.sampled_from(["\n", "\r\n", "\r"]),
)
def test_csv_reader_survives_hostile_text(header: str, rows: list[str], newline: str) -> None:
    _read(read_generic_csv, "fuzz.csv", newline.join([header, *rows]).encode("utf-8"))
