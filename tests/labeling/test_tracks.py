"""Highlight tracks on small hand-made cases."""

import numpy as np
import pytest

from labeling import (
    DRIFT_TRACK_AT_1,
    LogScores,
    drift_track,
    drifted_share,
    entropy,
    highlight_intervals,
    intervals,
    margin_uncertainty,
    member_agreement,
    mutual_information,
    normalised_tracks,
    session_normaliser,
    smooth,
)


def test_entropy_margin_and_mutual_information_by_hand() -> None:
    probs = np.array([[1.0, 0.0], [0.5, 0.5], [0.75, 0.25]])
    np.testing.assert_allclose(
        entropy(probs), [0.0, np.log(2), -(0.75 * np.log(0.75) + 0.25 * np.log(0.25))], atol=1e-9
    )
    np.testing.assert_allclose(margin_uncertainty(probs), [0.0, 1.0, 0.5])
    # three classes: only the two largest count
    np.testing.assert_allclose(margin_uncertainty(np.array([[0.5, 0.3, 0.2]])), [0.8])
    # two members certain of different classes: MI = ln 2; members agreeing: 0
    members = np.array([[[1.0, 0.0], [0.5, 0.5]], [[0.0, 1.0], [0.5, 0.5]]])  # (M=2, T=2, K=2)
    np.testing.assert_allclose(mutual_information(members), [np.log(2), 0.0], atol=1e-9)


def test_member_agreement_counts_the_pairs_naming_the_same_class() -> None:
    # four members, three steps: all name class 0; three name 0 and one 1 (3 of 6 pairs agree); two and two (2 of 6)
    top = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 1], [0, 1, 1]])  # (M=4, T=3) each member's top class
    members = np.eye(3)[top] * 0.8 + 0.2 / 3  # (M, T, K=3): the top class first, the rest shared
    np.testing.assert_allclose(member_agreement(members), [1.0, 0.5, 2 / 6])
    assert member_agreement(members[:1]).tolist() == [1.0, 1.0, 1.0]  # one member has no pair: nothing against it


def test_smooth_is_a_centred_mean_that_shrinks_at_the_ends() -> None:
    x = np.array([0.0, 0.0, 3.0, 0.0, 0.0])
    np.testing.assert_allclose(smooth(x, 3), [0.0, 1.0, 1.0, 1.0, 0.0])
    np.testing.assert_allclose(smooth(x, 1), x)
    np.testing.assert_allclose(smooth(np.ones(4), 10), np.ones(4))
    rng = np.random.default_rng(0)
    for n in (1, 2, 5, 24, 25, 26, 300):
        for window in (2, 3, 4, 25, 26, 400):
            y = rng.normal(size=n)
            want = [y[max(0, t - window // 2) : max(0, t - window // 2 + window)].mean() for t in range(n)]
            np.testing.assert_allclose(smooth(y, window), want, err_msg=f"T={n}, window={window}")


def test_session_normaliser_ranks_across_logs() -> None:
    norm = session_normaliser([np.array([1.0, 2.0]), np.array([3.0, 4.0])])
    np.testing.assert_allclose(norm(np.array([1.0, 4.0, 0.0, 9.0])), [0.125, 0.875, 0.0, 1.0])
    flat = session_normaliser([np.zeros(10)])
    np.testing.assert_allclose(flat(np.zeros(3)), 0.5)  # a flat track is not highlighted at 0.9


def test_intervals_threshold_merge_and_min_len() -> None:
    t = np.array([0, 0.95, 0.96, 0, 0.99, 0, 0, 0, 0.91, 0.92, 0.93])
    got = intervals(t, 0.9, log=3, kind="entropy")
    assert [(i.start, i.stop) for i in got] == [(1, 3), (4, 5), (8, 11)]
    assert got[0].log == 3 and got[0].kind == "entropy" and got[1].score == pytest.approx(0.99)
    merged = intervals(t, 0.9, log=0, kind="entropy", gap=1)
    assert [(i.start, i.stop) for i in merged] == [(1, 5), (8, 11)]
    assert [(i.start, i.stop) for i in intervals(t, 0.9, log=0, kind="entropy", min_len=3)] == [(8, 11)]
    assert intervals(t, 1.5, log=0, kind="entropy") == []


def test_normalised_tracks_leave_out_what_the_model_cannot_give() -> None:
    rng = np.random.default_rng(0)
    cold = [LogScores(rng.random(50)), LogScores(rng.random(30))]
    tracks = normalised_tracks(cold, window=5)
    assert all(set(t) == {"surprise"} for t in tracks)
    assert all(t["surprise"].min() >= 0 and t["surprise"].max() <= 1 for t in tracks)
    probs = rng.dirichlet(np.ones(3), 50)
    warm = [LogScores(rng.random(50), probs, rng.random(50))]
    (t,) = normalised_tracks(warm, window=5)
    assert set(t) == {"surprise", "entropy", "margin", "disagreement"}
    assert all(len(v) == 50 for v in t.values())


def test_the_drift_track_keeps_its_own_scale_so_nothing_drifted_highlights_nothing() -> None:
    np.testing.assert_allclose(drift_track(np.array([0.0, 1.0, 2.0])), [0.0, DRIFT_TRACK_AT_1, 0.99], atol=1e-6)
    calm = [LogScores(np.ones(300), drift=np.full(300, 0.6)), LogScores(np.ones(200), drift=np.full(200, 0.2))]
    tracks = normalised_tracks(calm, window=5)
    assert all(t["drift"].max() < DRIFT_TRACK_AT_1 for t in tracks)  # ranks would have lit the top 10 %
    assert not [iv for iv in highlight_intervals(tracks, DRIFT_TRACK_AT_1) if iv.kind == "drift"]
    shifted = np.full(300, 0.2)
    shifted[100:180] = 2.5
    (t,) = normalised_tracks([LogScores(np.ones(300), drift=shifted)], window=5)
    drifted = [iv for iv in highlight_intervals([t], DRIFT_TRACK_AT_1) if iv.kind == "drift"]
    (iv,) = drifted  # the stretch, give or take the smoothing's half window
    assert abs(iv.start - 100) <= 2 and abs(iv.stop - 180) <= 2
    assert drifted_share(shifted) == pytest.approx(80 / 300) and drifted_share(None) is None


def test_highlight_intervals_find_the_surprising_stretch() -> None:
    err = np.full(400, 0.1)
    err[200:240] = 5.0
    (t,) = normalised_tracks([LogScores(err)], window=5)
    got = highlight_intervals([t], 0.9)
    assert len(got) == 1 and got[0].kind == "surprise"
    assert 195 <= got[0].start <= 200 and 240 <= got[0].stop <= 245


def test_the_session_rank_is_the_mid_rank_of_ties_and_the_plain_rank_elsewhere() -> None:
    norm = session_normaliser([np.array([1.0, 2.0, 2.0, 2.0, 3.0]), np.array([4.0])])
    # six reference values: 2.0 ties over ranks 1..4 -> (1 + 4) / 12; a value between two ranks sits at its edge
    np.testing.assert_allclose(norm(np.array([2.0, 2.5, 0.0, 9.0, 1.0])), [5 / 12, 4 / 6, 0.0, 1.0, 1 / 12])
    rng = np.random.default_rng(1)
    ref = np.sort(np.round(rng.normal(size=3000), 1))  # many ties
    x = np.round(rng.normal(size=5000), 2)
    want = (np.searchsorted(ref, x, "left") + np.searchsorted(ref, x, "right")) / (2.0 * len(ref))
    np.testing.assert_array_equal(session_normaliser([ref])(x), want)
