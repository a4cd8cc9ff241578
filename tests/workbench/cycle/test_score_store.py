"""The last scoring and queue kept in the session: read back as they were, refused once anything they came from
changed, and used by the shared state so that a restart draws at once instead of scoring every log again."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

from sessions import Session, WorkbenchError
from tests.workbench.cycle.test_cycle import TINY, demo_logs, trained, trained_once  # noqa: F401  (fixtures)
from workbench import cycle
from workbench.cycle import compute_scores, queue_key, store_queue, store_scores, stored_queue, stored_scores
from workbench.demo import generate_demo_logs
from workbench.ui import SharedState, score_and_keep
from workbench.ui import state as state_module


def test_stored_scores_read_back_equal_and_complete(trained: Session) -> None:  # noqa: F811
    assert stored_scores(trained) is None  # nothing kept yet
    scores = compute_scores(trained)
    store_scores(trained, scores)
    back = stored_scores(trained)
    assert back is not None and back.complete
    got = back.scores
    assert (got.predictor, got.classifier, got.classes) == (scores.predictor, scores.classifier, scores.classes)
    assert set(got.scores) == set(scores.scores)
    for log_id, s in scores.scores.items():
        g = got.scores[log_id]
        np.testing.assert_array_equal(g.surprise, s.surprise)
        np.testing.assert_array_equal(g.probs, s.probs)
        np.testing.assert_array_equal(g.disagreement, s.disagreement)
        assert s.agreement is not None and s.agreement.min() >= 0 and s.agreement.max() <= 1  # the Data tab's figure
        np.testing.assert_array_equal(g.agreement, s.agreement)
        assert set(got.tracks[log_id]) == set(scores.tracks[log_id])
        for kind, track in scores.tracks[log_id].items():
            np.testing.assert_array_equal(got.tracks[log_id][kind], track)
        np.testing.assert_array_equal(got.embeddings[log_id][100:140], scores.embeddings[log_id][100:140])
        # a short log's arrays read whole, read-only (a memory map per array held a file open per array)
        assert not isinstance(g.probs, np.memmap) and not g.probs.flags.writeable


def test_hours_of_scores_are_mapped_and_many_logs_hold_no_file_open_each(
    trained: Session,  # noqa: F811
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A session of many short logs: its kept scores held a file open per array (eleven per log), so 300 logs passed
    the 1,024 open files a Linux desktop allows and the scores could no longer be kept or read. Now the files held
    open do not grow with the logs; arrays of an hour's size are still memory-mapped, read lazily."""
    from workbench.cycle import score_files

    def held() -> int:
        return len(os.listdir("/proc/self/fd"))

    before = held()
    store_scores(trained, compute_scores(trained))
    back = stored_scores(trained)
    assert back is not None and len(back.scores.scores) >= 2
    assert held() - before <= 1, held() - before  # 3 logs x 11 arrays + their stage-1 frames held 35 more
    monkeypatch.setattr(score_files, "MAPPED_BYTES", 0)  # every array counts as an hour's
    mapped = stored_scores(trained)
    assert all(isinstance(s.probs, np.memmap) and not s.probs.flags.writeable for s in mapped.scores.scores.values())


def test_a_store_of_the_first_version_is_not_read_and_its_files_go_with_the_next_store(
    trained: Session,  # noqa: F811
) -> None:
    scores = compute_scores(trained)
    store_scores(trained, scores)
    (folder,) = (trained.path / "cache").glob("scores-*")
    meta = json.loads((folder / "meta.json").read_text())
    (folder / "meta.json").write_text(json.dumps({**meta, "version": 1}))
    (folder / "000001.npz").write_bytes(b"PK")  # the first version kept one zip per log
    assert stored_scores(trained) is None  # scored again, as after a model change
    store_scores(trained, scores)
    assert stored_scores(trained) is not None and not list(folder.glob("*.npz"))


def test_a_new_log_makes_the_stored_scores_incomplete(trained: Session, tmp_path: Path) -> None:  # noqa: F811
    store_scores(trained, compute_scores(trained))
    (extra,) = generate_demo_logs(tmp_path / "more", n_logs=1, minutes=0.3, seed=9)
    trained.ingest([extra])
    back = stored_scores(trained)
    assert back is not None and not back.complete  # drawn at once, then the worker scores again
    assert len(back.scores.scores) == len(trained.logs()) - 1


def test_another_active_model_leaves_the_stored_scores_unused(trained: Session) -> None:  # noqa: F811
    store_scores(trained, compute_scores(trained))
    cycle.train_classifier(trained, config=TINY, hidden=8)  # a new version, active
    assert stored_scores(trained) is None
    store_scores(trained, compute_scores(trained))
    assert len(list((trained.path / "cache").glob("scores-*"))) == 1  # the older model's scores are removed
    assert stored_scores(trained) is not None


def test_the_queue_is_stale_once_a_label_changes(trained: Session) -> None:  # noqa: F811
    scores = compute_scores(trained)
    store_scores(trained, scores)
    log = trained.logs()[0]
    key = queue_key(trained, "combined", trained.terrains())
    rows = [(log.id, 10, 60, "uncertain", "grass", 0.5)]
    store_queue(trained, scores, rows, key=key)
    assert stored_queue(trained, scores, key=key) == [tuple(r) for r in rows]
    assert stored_queue(trained, scores, key=queue_key(trained, "random", trained.terrains())) is None
    trained.add_segment(log.id, 200, 260, "grass", author="t", source="manual")
    assert stored_queue(trained, scores, key=queue_key(trained, "combined", trained.terrains())) is None


def test_a_restart_draws_the_stored_scores_and_queue_without_scoring(
    trained: Session,  # noqa: F811
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    first = SharedState(trained, on_error=pytest.fail)
    deadline = time.monotonic() + 120
    while not (first.scored and first.queue and not first.busy) and time.monotonic() < deadline:
        time.sleep(0.05)
    queue = [(q.key, q.reason, q.guess) for q in first.queue]
    first.stop()
    assert queue

    def no_scoring(*args, **kwargs):
        raise AssertionError("scored again though nothing changed")

    monkeypatch.setattr(state_module, "compute_scores", no_scoring)
    monkeypatch.setattr(SharedState, "_compute_queue", no_scoring)
    second = SharedState(trained, on_error=pytest.fail)
    deadline = time.monotonic() + 10
    while not (second.scored and second.queue) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert [(q.key, q.reason, q.guess) for q in second.queue] == queue
    second.stop()


def test_score_and_keep_leaves_a_whole_scoring_and_queue(trained: Session) -> None:  # noqa: F811
    """What `workbench demo` runs before serving, so the page's first screen needs no scoring."""
    assert score_and_keep(trained)
    back = stored_scores(trained)
    assert back is not None and back.complete
    key = queue_key(trained, "combined", trained.terrains())
    assert stored_queue(trained, back.scores, key=key)


def test_a_restart_from_the_kept_queue_finds_the_change_points_the_data_tab_reads(trained: Session) -> None:  # noqa: F811
    """A kept queue is drawn without ranking it again, so nothing else would find the change points: without them
    the Data tab has no figure by stretches."""
    assert score_and_keep(trained)
    state = SharedState(trained)
    try:
        assert state.wait_idle(stop=lambda: False, deadline_s=120)
        assert state.queue  # the kept one
        for log in trained.logs():
            points = state.known_change_points(log.id)
            assert points is not None
            np.testing.assert_array_equal(points, state.change_points(log.id))
    finally:
        state.stop()


def test_change_points_are_kept_per_predictor_and_a_restart_reads_them(
    trained: Session,  # noqa: F811
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Finding them took 25 s of a restart at 100 hours of logs, before the first queue could be ranked."""
    first = SharedState(trained, on_error=pytest.fail)
    try:
        assert first.wait_idle(stop=lambda: False, deadline_s=120)
        found = {x.id: first.change_points(x.id) for x in trained.logs()}
    finally:
        first.stop()
    predictor = trained.active_model("predictor").id
    for log in trained.logs():
        np.testing.assert_array_equal(cycle.kept_change_points(trained, predictor, log), found[log.id])

    def not_again(*args, **kwargs):
        raise AssertionError("change points found again though they were kept")

    monkeypatch.setattr(state_module, "log_change_points", not_again)
    second = SharedState(trained, on_error=pytest.fail)
    try:
        assert second.wait_idle(stop=lambda: False, deadline_s=120)
        for log in trained.logs():
            np.testing.assert_array_equal(second.change_points(log.id), found[log.id])
    finally:
        second.stop()
    log = trained.logs()[0]
    cycle.keep_change_points(trained, predictor + 1, log, np.array([5, 9]))  # a new predictor's replace them
    assert cycle.kept_change_points(trained, predictor, log) is None
    np.testing.assert_array_equal(cycle.kept_change_points(trained, predictor + 1, log), [5, 9])


def test_the_queue_waits_while_a_retrains_quick_phase_trains(trained: Session) -> None:  # noqa: F811
    """Its scores come seconds later and the queue is ranked from them: ranked meanwhile, it took a core from the
    fine-tune (100 hours of logs: the log in view 63 s after Retrain, 37 s without)."""
    state = SharedState(trained, on_error=pytest.fail)
    try:
        assert state.wait_idle(stop=lambda: False, deadline_s=120)
        before = [q.key for q in state.queue]
        state.hold_queue = True
        log = trained.logs()[0]
        state.add_label(log.id, 0, 50, trained.terrains()[0].name, author="test", source="manual")
        assert state.wait_idle(stop=lambda: False, deadline_s=60)
        assert [q.key for q in state.queue] == before  # not ranked while held
        state.hold_queue = False
        state.refresh(scores=False)
        assert state.wait_idle(stop=lambda: False, deadline_s=120)
        assert all(q.key[0] != log.id or q.start >= 50 for q in state.queue)
        assert state._queue_of is not None and state._queue_of[1] == queue_key(trained, "combined", state.terrains())
    finally:
        state.stop()


def test_scoring_a_group_at_a_time_keeps_what_scoring_at_once_computes(trained: Session) -> None:  # noqa: F811
    """At 100 hours of logs, scoring every log in one call held 6.4 GiB of scores; a group at a time, written as it
    comes, holds one group's."""
    whole = compute_scores(trained)
    calls: list[tuple[int, ...]] = []

    def score(session, **kw):
        out = compute_scores(session, **kw)
        calls.append(tuple(out.scores))
        return out

    smallest = min(x.n_samples for x in trained.logs())
    got = cycle.score_and_store(trained, score=score, group_steps=smallest)  # a log per group
    assert got is not None and len(calls) == len(trained.logs()) >= 2
    assert (got.predictor, got.classifier, got.classes) == (whole.predictor, whole.classifier, whole.classes)
    for log_id, s in whole.scores.items():
        g = got.scores[log_id]
        assert not g.probs.flags.writeable and g.probs is not s.probs  # read back from the kept files
        for name in ("surprise", "probs", "disagreement", "drift"):
            if getattr(s, name) is None:
                assert getattr(g, name) is None
            else:
                np.testing.assert_allclose(getattr(g, name), getattr(s, name), rtol=1e-6, atol=1e-7)
        assert set(got.tracks[log_id]) == set(whole.tracks[log_id])
        for kind, track in whole.tracks[log_id].items():  # ranked over the whole session, not per group
            np.testing.assert_allclose(got.tracks[log_id][kind], track, rtol=1e-6, atol=1e-7)
    back = stored_scores(trained)
    assert back is not None and back.complete and set(back.scores.scores) == set(whole.scores)


def test_scoring_a_group_at_a_time_stops_when_asked_and_keeps_nothing_incomplete(trained: Session) -> None:  # noqa: F811
    store_scores(trained, compute_scores(trained))
    assert stored_scores(trained) is not None
    asked = []
    got = cycle.score_and_store(
        trained, score=compute_scores, group_steps=1, stop=lambda: asked.append(1) or len(asked) > 1
    )
    assert got is None and len(asked) == 2  # stopped before the second group
    assert stored_scores(trained) is None  # the folder says it is incomplete until a scoring ends


def test_scoring_in_forked_processes_keeps_what_one_process_computes(trained: Session, tmp_path: Path) -> None:  # noqa: F811
    """The groups scored in two forked children, read back memory-mapped: the same scores, tracks and embeddings as
    one process's, and the children (not this process) did the scoring."""
    whole = compute_scores(trained)
    pids = tmp_path / "pids"
    pids.mkdir()

    def score(session, **kw):
        (pids / str(os.getpid())).touch()
        return compute_scores(session, **kw)

    got = cycle.score_and_store(trained, score=score, jobs=2, group_steps=1)  # a log per group
    assert got is not None
    children = {int(p.name) for p in pids.iterdir()}
    assert os.getpid() not in children and len(children) >= 2
    assert (got.predictor, got.classifier, got.classes, got.span) == (
        whole.predictor,
        whole.classifier,
        whole.classes,
        whole.span,
    )
    assert set(got.scores) == set(whole.scores)
    for log_id, s in whole.scores.items():
        g = got.scores[log_id]
        assert not g.probs.flags.writeable and g.probs is not s.probs  # read back (read-only) from the files
        for name in ("surprise", "probs", "disagreement", "drift", "agreement"):
            if getattr(s, name) is None:
                assert getattr(g, name) is None
            else:
                np.testing.assert_allclose(getattr(g, name), getattr(s, name), rtol=1e-6, atol=1e-7)
        for kind, track in whole.tracks[log_id].items():
            np.testing.assert_allclose(got.tracks[log_id][kind], track, rtol=1e-6, atol=1e-7)
        np.testing.assert_array_equal(got.embeddings[log_id][:50], whole.embeddings[log_id][:50])
    back = stored_scores(trained)
    assert back is not None and back.complete and set(back.scores.scores) == set(whole.scores)
    assert trained.active_model("classifier") is not None  # this process's connection still answers


def test_scoring_in_forked_processes_stops_when_asked_and_passes_a_childs_error_on(trained: Session) -> None:  # noqa: F811
    store_scores(trained, compute_scores(trained))

    def slow(session, **kw):
        time.sleep(30)  # ended by the stop long before
        return compute_scores(session, **kw)

    t0 = time.monotonic()
    asked = []
    stop = lambda: asked.append(1) or len(asked) > 2  # noqa: E731  (during the first batch)
    got = cycle.score_and_store(trained, score=slow, jobs=2, group_steps=1, stop=stop)
    assert got is None and time.monotonic() - t0 < 20
    assert stored_scores(trained) is None  # incomplete until a scoring ends

    def broken(session, **kw):
        raise WorkbenchError("the classifier's files are damaged")

    with pytest.raises(WorkbenchError, match="the classifier's files are damaged"):
        cycle.score_and_store(trained, score=broken, jobs=2, group_steps=1)
    folder = next(trained.path.glob("cache/scores-*"))
    (folder / ".000001.probs.0badc0de.npy").write_bytes(b"cut short")  # what a stopped child can leave
    assert cycle.score_and_store(trained, score=compute_scores, jobs=2, group_steps=1) is not None
    assert not list(folder.glob(".*.npy")), "the next complete scoring removes what a stopped one left"


def test_hours_of_logs_fork_a_process_per_core_where_the_cores_allow(
    trained: Session,  # noqa: F811
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """One process per core, only as many as have their share of samples, and one where the cores are fewer than
    the caller's minimum (the export's: more than two) or forking is off."""
    from workbench.cycle import forked_scores

    logs = trained.logs()
    monkeypatch.setattr(os, "sched_getaffinity", lambda _: {0, 1}, raising=False)
    each = sum(x.n_samples for x in logs) // 2
    assert cycle.scoring_processes(logs, fork_steps=each) == min(2, len(logs))
    assert cycle.scoring_processes(logs, fork_steps=each, min_cores=3) == 1
    assert cycle.scoring_processes(logs, fork_steps=each + 1) == 1  # not two processes' worth of samples
    monkeypatch.setattr(os, "sched_getaffinity", lambda _: set(range(16)), raising=False)
    assert cycle.scoring_processes(logs, fork_steps=1, min_cores=3) == min(16, len(logs))
    monkeypatch.setattr(forked_scores, "FORK_STEPS", 1)
    monkeypatch.setenv("WORKBENCH_FIT_PROCESSES", "0")
    assert cycle.scoring_processes(logs) == 1
