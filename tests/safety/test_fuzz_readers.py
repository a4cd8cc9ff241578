"""Fuzz targets for the log readers: whatever bytes come in, a reader returns streams or raises ``IngestError``;
and for Label Studio's import: whatever JSON a task holds, its labels come in or one ``LabelError`` line, nothing.

Hypothesis mutates a real MCAP file (cuts, flipped bytes, inserted and deleted runs) and writes CSV text from the
tokens that break parsers (NaN, inf, empty cells, quotes, BOM, CR, stray commas). ``make test`` runs a few dozen
examples of each; ``make stress`` sets ``WORKBENCH_FUZZ_EXAMPLES`` for thousands.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sessions import IngestError, IngestOptions, LabelError
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


@pytest.fixture(scope="module")
def labelled_session(tmp_path_factory: pytest.TempPathFactory):
    from tests.conftest import new_session

    root = tmp_path_factory.mktemp("ls")
    t = 1_700_000_000.0 + np.arange(1000) / 100.0
    (root / "run.csv").write_text("time,a\n" + "\n".join(f"{x:.2f},{np.sin(x):.3f}" for x in t) + "\n")
    s = new_session(root / "s")
    s.ingest([root / "run.csv"])
    yield s
    s.close()


json_leaf = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**20), 10**20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(["run", "grass", "lava", "", "timeserieslabels", "/data/upload/1/0badc0de-run.csv", "1e3"]),
)
json_value = st.recursive(
    json_leaf,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=12,
)
number = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-(10**20), 10**20), json_value)
inside = st.one_of(st.floats(0, 10), st.floats(1_700_000_000.0, 1_700_000_010.0))  # from its start, on its clock
span = st.one_of(
    st.lists(inside, min_size=2, max_size=2).map(sorted).map(lambda p: {"start": p[0], "end": p[1]}),
    st.fixed_dictionaries({"start": number, "end": number}),
)
# Mostly well formed, so that imports succeed too and the fuzz reaches the segments, not only the first check
terrains = st.sampled_from([["grass"], ["sand"], ["grass"], ["lava"], [], ["grass", "sand"]])
ls_value = st.builds(
    lambda where, what: {**where, **what},
    span,
    st.fixed_dictionaries(
        {"timeserieslabels": st.one_of(terrains, terrains, json_value)},
        optional={"instant": st.one_of(st.just(False), json_value)},
    ),
)
well_formed = st.fixed_dictionaries({"type": st.just("timeserieslabels"), "value": ls_value})
ls_result = st.one_of(
    well_formed,
    well_formed,
    st.fixed_dictionaries({"type": st.just("timeserieslabels"), "value": json_value}),
    st.fixed_dictionaries({"type": st.sampled_from(["choices", "textarea"]), "value": json_value}),
    json_value,
)
ls_task = st.fixed_dictionaries(
    {
        "data": st.one_of(
            st.just({"log": "run"}),
            st.just({"csv": "/data/upload/1/0badc0de-run.csv"}),
            st.dictionaries(st.text(max_size=5), json_value, max_size=2),
        ),
        "annotations": st.one_of(
            st.lists(
                st.fixed_dictionaries(
                    {"result": st.lists(ls_result, max_size=4)},
                    optional={"completed_by": json_value, "was_cancelled": json_value},
                ),
                max_size=2,
            ),
            json_value,
        ),
    }
)


good_value = st.builds(
    lambda p, terrain: {"start": p[0], "end": p[1], "instant": False, "timeserieslabels": [terrain]},
    st.lists(inside, min_size=2, max_size=2, unique=True).map(sorted),
    st.sampled_from(["grass", "sand"]),
)
good_task = st.fixed_dictionaries(
    {
        "data": st.sampled_from([{"log": "run"}, {"csv": "/data/upload/1/0badc0de-run.csv"}]),
        "annotations": st.lists(
            st.fixed_dictionaries(
                {
                    "result": st.lists(
                        st.fixed_dictionaries({"type": st.just("timeserieslabels"), "value": good_value}), max_size=2
                    )
                },
                optional={"completed_by": st.one_of(st.integers(1, 9), st.just({"email": "a@b.c"}))},
            ),
            max_size=1,
        ),
    }
)


@pytest.mark.fuzz
@FUZZ
@given(tasks=st.lists(st.one_of(good_task, good_task, good_task, ls_task), min_size=1, max_size=3))
def test_label_studio_import_survives_hostile_json(labelled_session, tasks: list[dict]) -> None:
    """Whatever a Label Studio export holds: its labels imported, or one ``LabelError`` line naming the file and
    nothing imported."""
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "export.json"
        path.write_text(json.dumps(tasks))
        before = labelled_session.segments()
        try:
            labelled_session.import_labels(path, author="fuzz")
            for seg in labelled_session.segments():  # back to an empty log: the next example starts as this one did
                labelled_session.delete_segment(seg.id, author="fuzz")
        except LabelError as exc:
            assert "\n" not in str(exc) and str(exc).startswith(str(path))
            assert labelled_session.segments() == before
