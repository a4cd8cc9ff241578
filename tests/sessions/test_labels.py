"""Label segments: add / change / delete, merging, refusing overlaps, history and undo."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sessions import LabelError, Session


@pytest.fixture
def log_id(session: Session, tmp_path: Path) -> int:
    csv = tmp_path / "tiny.csv"
    t = np.arange(2000) / 100.0
    csv.write_text("time,a,b\n" + "\n".join(f"{x:.2f},{np.sin(x):.4f},{np.cos(x):.4f}" for x in t))
    (log,) = session.ingest([csv])
    return log.id


def spans(session: Session) -> list[tuple[int, int, str]]:
    return [(s.start, s.stop, s.terrain) for s in session.segments()]


def test_add_change_delete(session: Session, log_id: int) -> None:
    seg = session.add_segment(log_id, 100, 200, "grass", author="ana", source="manual")
    assert (seg.start, seg.stop, seg.terrain, seg.author, seg.source) == (100, 200, "grass", "ana", "manual")
    moved = session.change_segment(seg.id, author="ana", start=150, stop=300, terrain="gravel")
    assert (moved.id, moved.start, moved.stop, moved.terrain) == (seg.id, 150, 300, "gravel")
    gone = session.delete_segment(seg.id, author="ana")
    assert gone.id == seg.id
    assert session.segments() == []


def test_overlap_with_another_terrain_is_refused_and_changes_nothing(session: Session, log_id: int) -> None:
    session.add_segment(log_id, 100, 200, "grass", author="ana")
    n_ops = len(session.history())
    with pytest.raises(LabelError, match=r"overlaps segment #1 \(grass, samples 100-200\) of another terrain"):
        session.add_segment(log_id, 150, 250, "sand", author="ana")
    assert spans(session) == [(100, 200, "grass")]
    assert len(session.history()) == n_ops  # the refused action left no trace


def test_same_terrain_overlapping_or_touching_merges(session: Session, log_id: int) -> None:
    session.add_segment(log_id, 100, 200, "grass", author="ana")
    session.add_segment(log_id, 300, 400, "grass", author="ana")
    session.add_segment(log_id, 500, 600, "sand", author="ana")
    merged = session.add_segment(log_id, 150, 300, "grass", author="bo")  # overlaps one, touches the other
    assert (merged.start, merged.stop) == (100, 400)
    assert spans(session) == [(100, 400, "grass"), (500, 600, "sand")]
    # adjacent but different terrain: both kept
    session.add_segment(log_id, 400, 450, "dirt", author="bo")
    assert spans(session) == [(100, 400, "grass"), (400, 450, "dirt"), (500, 600, "sand")]


def test_bad_ranges_unknown_logs_and_terrains_are_refused(session: Session, log_id: int) -> None:
    n = session.log(log_id).n_samples
    with pytest.raises(LabelError, match="not inside log"):
        session.add_segment(log_id, 10, n + 1, "grass", author="a")
    with pytest.raises(LabelError, match="not inside log"):
        session.add_segment(log_id, 50, 50, "grass", author="a")
    with pytest.raises(LabelError, match="unknown log"):
        session.add_segment(999, 0, 10, "grass", author="a")
    with pytest.raises(LabelError, match="unknown terrain 'lava'; known terrains: concrete"):
        session.add_segment(log_id, 0, 10, "lava", author="a")
    with pytest.raises(LabelError, match="no segment #42"):
        session.delete_segment(42, author="a")


def test_history_records_who_when_before_after(session: Session, log_id: int) -> None:
    seg = session.add_segment(log_id, 100, 200, "grass", author="ana")
    session.change_segment(seg.id, author="bo", terrain="mulch")
    session.delete_segment(seg.id, author="cy")
    hist = session.history()
    assert [(h.kind, h.author) for h in hist] == [("delete", "cy"), ("change", "bo"), ("add", "ana")]
    (_, before, after) = hist[1].changes[0]
    assert before["terrain_id"] != after["terrain_id"]
    assert (before["start"], before["stop"]) == (after["start"], after["stop"]) == (100, 200)
    assert hist[0].changes[0][2] is None and hist[2].changes[0][1] is None
    assert all(h.at for h in hist)


def test_undo_reverts_add_change_delete_and_merge(session: Session, log_id: int) -> None:
    a = session.add_segment(log_id, 100, 200, "grass", author="ana")
    session.add_segment(log_id, 300, 400, "grass", author="ana")
    session.add_segment(log_id, 150, 350, "grass", author="ana")  # merges the two
    assert spans(session) == [(100, 400, "grass")]
    session.undo(author="ana")
    assert spans(session) == [(100, 200, "grass"), (300, 400, "grass")]
    assert session.segment(a.id).stop == 200  # same id back
    session.change_segment(a.id, author="ana", terrain="sand")
    session.undo(author="ana")
    assert session.segment(a.id).terrain == "grass"
    session.delete_segment(a.id, author="ana")
    session.undo(author="ana")
    assert session.segment(a.id).start == 100
    kinds = [(h.kind, h.undone_by is not None) for h in session.history()]
    assert kinds == [
        ("undo", False),
        ("delete", True),
        ("undo", False),
        ("change", True),
        ("undo", False),
        ("add", True),
        ("add", False),
        ("add", False),
    ]


def test_undo_is_per_author_and_never_clobbers_newer_work(session: Session, log_id: int) -> None:
    a = session.add_segment(log_id, 100, 200, "grass", author="ana")
    session.add_segment(log_id, 500, 600, "sand", author="bo")
    session.undo(author="ana")  # ana's add, not bo's
    assert spans(session) == [(500, 600, "sand")]
    with pytest.raises(LabelError, match="nothing to undo"):
        session.undo(author="ana")
    # bo resizes a segment ana made; ana's undo of her add must not delete bo's newer version
    a = session.add_segment(log_id, 100, 200, "grass", author="ana")
    session.change_segment(a.id, author="bo", stop=250)
    with pytest.raises(LabelError, match="changed by a later action"):
        session.undo(author="ana")
    assert spans(session) == [(100, 250, "grass"), (500, 600, "sand")]


def test_undo_refuses_to_bring_back_a_segment_that_would_overlap(session: Session, log_id: int) -> None:
    a = session.add_segment(log_id, 100, 200, "grass", author="ana")
    session.delete_segment(a.id, author="ana")
    session.add_segment(log_id, 150, 250, "sand", author="bo")
    with pytest.raises(LabelError, match="would overlap"):
        session.undo(author="ana")
    assert spans(session) == [(150, 250, "sand")]


def test_labels_survive_reopening(tmp_path: Path, log_id: int, session: Session) -> None:
    session.add_segment(log_id, 10, 20, "dirt", author="ana")
    path = session.path
    session.close()
    with Session.open(path) as again:
        assert spans(again) == [(10, 20, "dirt")]
        assert len(again.history()) == 1


ops = st.lists(
    st.tuples(
        st.sampled_from(["add", "change", "delete", "undo"]),
        st.integers(0, 1900),
        st.integers(1, 300),
        st.sampled_from(["grass", "sand", "gravel"]),
        st.sampled_from(["ana", "bo"]),
        st.integers(0, 10),
    ),
    max_size=25,
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(script=ops)
def test_random_edits_keep_segments_disjoint_and_every_action_in_history(
    session: Session, log_id: int, script: list
) -> None:
    """Whatever people do, segments of a log never overlap, and each accepted action is one history entry."""
    for seg in session.segments():  # hypothesis reuses the fixture: start from no labels
        session.delete_segment(seg.id, author="reset")
    accepted = len(session.history())
    for kind, start, length, terrain, author, pick in script:
        existing = session.segments()
        try:
            if kind == "add":
                session.add_segment(log_id, start, min(start + length, 2000), terrain, author=author)
            elif kind == "change" and existing:
                seg = existing[pick % len(existing)]
                session.change_segment(seg.id, author=author, start=start, stop=min(start + length, 2000))
            elif kind == "delete" and existing:
                session.delete_segment(existing[pick % len(existing)].id, author=author)
            elif kind == "undo":
                session.undo(author=author)
            else:
                continue
            accepted += 1
        except LabelError:
            pass
        segs = session.segments()
        for x, y in pairwise(segs):
            assert x.stop <= y.start, f"overlap: {x} {y}"
            if x.stop == y.start:
                assert x.terrain != y.terrain, "touching same-terrain segments must have merged"
        assert len(session.history()) == accepted


def test_several_ranges_saved_as_one_action_and_undone_together(session: Session, log_id: int) -> None:
    session.add_segment(log_id, 100, 200, "sand", author="ana")
    session.add_segment(log_id, 300, 320, "grass", author="ana")
    accepted = session.add_segments(
        log_id, [(0, 100), (200, 300), (320, 500)], "grass", author="ana", source="accepted"
    )
    # the grass pieces touching the grass label merge with it; the sand label is left alone
    assert spans(session) == [(0, 100, "grass"), (100, 200, "sand"), (200, 500, "grass")]
    assert {s.source for s in accepted} == {"accepted"}
    assert session.history(limit=1)[0].kind == "accept"
    session.undo(author="ana")
    assert spans(session) == [(100, 200, "sand"), (300, 320, "grass")]
    with pytest.raises(LabelError, match="another terrain"):  # all or nothing
        session.add_segments(log_id, [(0, 50), (150, 160)], "dirt", author="ana", source="accepted")
    assert spans(session) == [(100, 200, "sand"), (300, 320, "grass")]
