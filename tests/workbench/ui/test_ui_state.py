"""The state every browser shares, and the Retrain job, without a browser: events, suggestions, snapping, jobs."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from sessions import Session, WorkbenchError
from tests.conftest import new_session
from tests.workbench.cycle.test_cycle import TINY, demo_logs, trained, trained_once  # noqa: F401  (fixtures)
from workbench.cycle import SUGGESTION_S, compute_scores
from workbench.demo import seed_labels
from workbench.ui.jobs import JobStatus, TrainJob, needs_predictor
from workbench.ui.state import SharedState


def wait_for(check, timeout: float = 60.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if check():
            return
        time.sleep(0.05)
    raise AssertionError("timed out")


@pytest.fixture
def state(trained: Session):  # noqa: F811
    st = SharedState(trained, on_error=lambda msg: pytest.fail(msg))
    wait_for(lambda: st.scored and not st.busy)
    yield st
    st.stop()


def test_scores_and_a_queue_that_avoids_labelled_time(state: SharedState) -> None:
    assert state.scores.predictor is not None and state.scores.classifier is not None
    assert state.queue, "a trained session has suggestions"
    labelled = {(s.log_id, s.start, s.stop) for s in state.session.segments()}
    for q in state.queue:
        assert not any(g == q.log.id and a < q.stop and q.start < b for g, a, b in labelled)
        assert q.guess in [t.name for t in state.terrains()]
        assert SUGGESTION_S / 2 <= (q.stop - q.start) / q.log.rate_hz <= SUGGESTION_S
    keys = [q.key for q in state.queue]
    assert len(set(keys)) == len(keys)


def test_a_saved_label_is_committed_before_views_hear_of_it_and_the_queue_follows(state: SharedState) -> None:
    heard: list[tuple[str, int]] = []
    state.subscribe(lambda e: heard.append((e, len(state.session.segments()))))
    n = len(state.session.segments())
    q = state.queue[0]
    state.add_label(q.log.id, q.start, q.stop, "grass", author="browser-1", source="suggestion")
    wait_for(lambda: ("labels", n + 1) in heard)  # the view redraws from the store, which already holds the label
    assert ("labels", n) not in heard
    wait_for(lambda: all(x.key != q.key for x in state.queue) and ("suggestions", n + 1) in heard)
    assert state.undo(author="browser-1") == "add"
    assert len(state.session.segments()) == n


def test_terrains_are_added_renamed_and_removed_from_the_page(state: SharedState) -> None:
    heard: list[str] = []
    state.subscribe(heard.append)
    state.change_terrains("add", "ice")
    wait_for(lambda: "labels" in heard)
    assert [t.name for t in state.terrains()][-1] == "ice"
    state.change_terrains("rename", "ice", "black ice")
    used = state.session.segments()[0].terrain
    with pytest.raises(WorkbenchError, match="relabel or delete them first"):
        state.change_terrains("remove", used)  # labels use it: refused, kept
    assert used in [t.name for t in state.terrains()]
    state.change_terrains("remove", "black ice")
    assert "black ice" not in [t.name for t in state.terrains()]


def test_the_strategy_reranks_the_shared_queue(state: SharedState) -> None:
    heard: list[str] = []
    state.subscribe(heard.append)
    combined = [q.key for q in state.queue]
    state.set_strategy("random")
    wait_for(lambda: "suggestions" in heard and not state.busy)
    assert state.strategy == "random"
    assert [q.key for q in state.queue] != combined
    assert all(q.reason == "random pick" for q in state.queue)
    with pytest.raises(WorkbenchError, match="unknown strategy 'best'"):
        state.set_strategy("best")
    assert state.strategy == "random"


def test_one_broken_view_does_not_stop_the_others(trained: Session) -> None:  # noqa: F811
    errors: list[str] = []
    st = SharedState(trained, on_error=errors.append)
    try:
        got = threading.Event()
        st.subscribe(lambda e: 1 / 0)
        st.subscribe(lambda e: got.set())
        st.notify("labels")
        assert st.flush()
        assert got.is_set() and any("ZeroDivisionError" in e for e in errors)
    finally:
        st.stop()


def test_snap_moves_edges_to_change_points_only_nearby(state: SharedState, monkeypatch) -> None:
    from workbench.ui import state as state_module

    log = state.logs()[0]
    cps = state.change_points(log.id)
    assert len(cps) > 0
    p = int(cps[len(cps) // 2])
    snap = state.snap(log.id, p - 30, p + 700)  # start 0.3 s from a change point
    assert snap.start == p and snap.moved_start
    far = state.snap(log.id, 0, 1)
    assert far.stop > far.start
    # before the worker has the log's change points, a snap looks only around the range, and finds the same edge
    seen: list[int] = []
    real = state_module.log_change_points
    monkeypatch.setattr(state_module, "log_change_points", lambda x, *a, **k: seen.append(len(x)) or real(x, *a, **k))
    state._change_points.clear()
    local = state.snap(log.id, p - 30, p + 700)
    assert local.moved_start and abs(local.start - p) <= 25
    assert min(seen) <= 730 + 2 * 10 * round(log.rate_hz)  # the window around the range, not the log


def test_a_logs_change_points_are_read_from_its_file_not_through_a_map(state: SharedState, monkeypatch) -> None:
    """Issue 66: the worker found each log's change points over its memory-mapped samples, whose pages then stayed
    resident: a first start at 102 h (change points not yet kept for a new predictor) held 3.1 GiB of raw logs."""
    import numpy as np

    from workbench.ui import state as state_module

    log = state.logs()[0]
    surprise = state.scores.scores[log.id].surprise
    expected = state_module.log_change_points(state.session.array(log.id), surprise, rate_hz=log.rate_hz)
    monkeypatch.setattr(type(state.session), "array", lambda *a: pytest.fail("the whole log was mapped"))
    monkeypatch.setattr(state_module, "kept_change_points", lambda *a: None)  # found again, not read back
    state._change_points.clear()
    assert np.array_equal(state.change_points(log.id), expected)


def test_retrain_job_runs_in_the_background_and_reports(state: SharedState) -> None:
    job = TrainJob(state, hidden=8, predictor_config=TINY, classifier_config=TINY, refine=False)
    statuses: list[JobStatus] = []
    state.subscribe(lambda e: statuses.append(job.status) if e == "job" else None)
    before = len(state.session.model_versions("classifier"))
    assert not needs_predictor(state)
    assert job.start() == "classifier"
    with pytest.raises(WorkbenchError, match="already"):
        job.start()
    wait_for(lambda: not job.running, timeout=120)
    assert job.status.state == "done", job.status.message
    assert len(state.session.model_versions("classifier")) == before + 1
    assert any(s.state == "running" for s in statuses)
    wait_for(lambda: state.scores.classifier == state.session.active_model("classifier").id)


def test_a_quick_retrain_is_followed_by_one_from_scratch_that_replaces_it(state: SharedState) -> None:
    job = TrainJob(state, hidden=8, predictor_config=TINY, classifier_config=TINY, warm_epochs=1)
    statuses: list[JobStatus] = []
    state.subscribe(lambda e: statuses.append(job.status) if e == "job" else None)
    before = [v.id for v in state.session.model_versions("classifier")]
    job.start()
    wait_for(lambda: not job.running, timeout=120)
    assert job.status.state == "done", job.status.message
    quick, full = [v for v in state.session.model_versions("classifier") if v.id not in before]
    assert quick.config["warm_start"] is True and full.config["warm_start"] is False
    assert state.session.active_model("classifier").id == full.id
    assert f"replaced the quick v{quick.id}" in job.status.message
    seen = [s.state for s in statuses]
    assert seen.index("running") < seen.index("refining")
    # the quick model's highlights were drawn before the retrain from scratch began
    refining = [s for s in statuses if s.state == "refining"]
    assert refining[0].fraction == 0.0 and any(s.fraction > 0 for s in refining)
    wait_for(lambda: state.scores.classifier == full.id)


def test_retrain_while_refining_stops_the_retrain_from_scratch_and_starts_a_quick_one(state: SharedState) -> None:
    slow = TINY.__class__(**{**TINY.__dict__, "max_epochs": 500, "patience": 500})
    job = TrainJob(state, hidden=8, predictor_config=TINY, classifier_config=slow, warm_epochs=1)
    before = [v.id for v in state.session.model_versions("classifier")]
    job.start()
    wait_for(lambda: job.status.state == "refining" and job.status.fraction > 0, timeout=120)
    assert job.start() == "classifier"  # not refused: the refining phase gives way
    assert job.status.state == "running"
    wait_for(lambda: job.status.state == "refining" and job.status.fraction > 0, timeout=120)
    job.cancel()
    wait_for(lambda: not job.running, timeout=60)
    assert job.status.state == "done" and "stopped" in job.status.message
    added = [v for v in state.session.model_versions("classifier") if v.id not in before]
    assert [v.config["warm_start"] for v in added] == [True, True]  # two quick ones; neither refining run saved
    assert state.session.active_model("classifier").id == added[-1].id
    runs = state.session._read("SELECT kind, status FROM runs ORDER BY id")[-4:]
    assert runs == [("classifier", "done"), ("classifier", "cancelled")] * 2


def test_after_a_retrain_the_logs_on_screen_are_rescored_first(state: SharedState, monkeypatch) -> None:
    from workbench.ui import state as state_module

    logs = state.logs()
    assert len(logs) >= 2
    shown = logs[-1].id
    state.set_viewed("browser-1", shown)
    job = TrainJob(state, hidden=8, predictor_config=TINY, classifier_config=TINY, refine=False)
    scored: list[tuple[int | None, tuple[int, ...]]] = []  # (active classifier, logs scored) per scoring pass
    real = state_module.compute_scores

    def recorded(session, **kw):
        out = real(session, **kw)
        scored.append((out.classifier, tuple(out.scores)))
        return out

    monkeypatch.setattr(state_module, "compute_scores", recorded)
    job.start()
    wait_for(lambda: not job.running, timeout=120)
    new = state.session.active_model("classifier").id
    everything = {x.id for x in logs}
    wait_for(lambda: any(v == new and set(k) == everything for v, k in scored))
    fresh = [keys for version, keys in scored if version == new]
    assert fresh[0] == (shown,), "the log on screen is scored before the others"
    assert set(fresh[-1]) == everything, "then the whole session"
    state.set_viewed("browser-1", None)
    assert state.viewed_logs() == set()


def test_retrain_can_be_cancelled_and_saves_nothing(state: SharedState) -> None:
    slow = TINY.__class__(**{**TINY.__dict__, "max_epochs": 500, "patience": 500})
    job = TrainJob(state, hidden=8, predictor_config=slow, classifier_config=slow, warm_epochs=None)
    before = len(state.session.model_versions())
    job.start()
    wait_for(lambda: job.status.fraction > 0 or not job.running)
    job.cancel()
    wait_for(lambda: not job.running, timeout=60)
    assert job.status.state == "cancelled"
    assert len(state.session.model_versions()) == before


def test_retrain_needs_two_terrains_and_stage1_follows_new_logs(tmp_path: Path, demo_logs, quick_stage1) -> None:  # noqa: F811
    with new_session(tmp_path / "s") as s:
        s.ingest(demo_logs[:1])
        st = SharedState(s)
        try:
            assert needs_predictor(st)  # no predictor yet
            job = TrainJob(st, hidden=8, predictor_config=TINY, classifier_config=TINY)
            assert job.start() == "predictor + classifier"  # stage 1 alone when there are no labels yet
            wait_for(lambda: not job.running, timeout=120)
            assert s.active_model("predictor") is not None and s.active_model("classifier") is None
            with pytest.raises(WorkbenchError, match="two terrains"):
                job.start()
            s.ingest(demo_logs[1:])
            st.logs_changed()
            assert needs_predictor(st)
            seed_labels(s, 0.2, seed=0)
        finally:
            st.stop()


def test_each_label_is_first_a_check_of_the_model_on_screen_and_the_check_survives_a_restart(
    state: SharedState,
) -> None:
    """Issue 65, item 4 (test then train): a label saved in the page keeps what the scored classifier said on the
    unlabelled part of it, with the queue's kind; undoing the label keeps the check (the test happened)."""
    q = next(x for x in state.queue if x.kind == "suggestion")
    spot = [x for x in state.queue if x.kind == "spot check"]
    assert len(spot) == 1 and spot[0].reason.startswith("spot check")  # one fair pick in every ranked queue
    said = state.scores.scores[q.log.id].probs[q.start : q.stop].argmax(axis=1)
    majority = state.scores.classes[int(__import__("numpy").bincount(said).argmax())]
    state.add_label(q.log.id, q.start, q.stop, "grass", author="browser-1", source="manual")
    state.add_label(spot[0].log.id, spot[0].start, spot[0].stop, "sand", author="browser-1", source="manual")
    (first, second) = state.session.checks()
    assert (first.log_id, first.start, first.stop, first.kind) == (q.log.id, q.start, q.stop, "suggestion")
    assert first.predicted == majority and first.classifier == state.scores.classifier and first.terrain == "grass"
    assert second.kind == "spot check" and second.terrain == "sand"
    state.undo(author="browser-1")
    path = state.session.path
    state.stop()
    state.session.close()
    with Session.open(path) as again:
        assert [(c.id, c.kind) for c in again.checks()] == [(first.id, "suggestion"), (second.id, "spot check")]


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="a process per core needs two cores")
def test_the_servers_scoring_of_hours_runs_in_processes_and_shows_what_one_process_computes(
    trained: Session,  # noqa: F811
    tmp_path: Path,
    monkeypatch,
) -> None:
    from workbench.cycle import forked_scores
    from workbench.ui import state as state_module

    whole = compute_scores(trained)
    monkeypatch.setattr(forked_scores, "FORK_STEPS", 1)  # the test's minutes of logs scored as hours are
    pids = tmp_path / "pids"
    pids.mkdir()

    def recorded(session, **kw):
        (pids / str(os.getpid())).touch()
        return compute_scores(session, **kw)

    monkeypatch.setattr(state_module, "compute_scores", recorded)
    st = SharedState(trained, on_error=lambda msg: pytest.fail(msg))
    try:
        wait_for(lambda: st.scored and not st.busy, timeout=120)
        assert {int(p.name) for p in pids.iterdir()} - {os.getpid()}, "the logs were scored in forked processes"
        assert set(st.scores.scores) == set(whole.scores)
        for log_id, s in whole.scores.items():
            np.testing.assert_allclose(st.scores.scores[log_id].probs, s.probs, rtol=1e-6, atol=1e-7)
            for kind, track in whole.tracks[log_id].items():
                np.testing.assert_allclose(st.scores.tracks[log_id][kind], track, rtol=1e-6, atol=1e-7)
        assert st.queue, "the queue is ranked from them"
    finally:
        st.stop()
