"""Suggestions: never on labelled time, never overlapping, deterministic, with reasons and guesses."""

import itertools
from collections.abc import Callable
from dataclasses import fields

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from labeling import (
    STRATEGIES,
    Evidence,
    LogScores,
    QueuePolicy,
    Suggestion,
    candidates,
    class_weights,
    coverage,
    oracle,
    suggest,
)

EVIDENCE = {f.name for f in fields(Evidence)}


def ranked(
    scores: list[LogScores], *, n: int = 10, stop: Callable[[], bool] = lambda: False, **named
) -> list[Suggestion]:
    """``suggest`` with its options named flat: each goes to ``Evidence`` or ``QueuePolicy`` by its field's name (an
    unknown name fails in ``QueuePolicy``)."""
    evidence = Evidence(**{k: v for k, v in named.items() if k in EVIDENCE})
    policy = QueuePolicy(**{k: v for k, v in named.items() if k not in EVIDENCE})
    return suggest(scores, evidence, policy=policy, n=n, stop=stop)


def make_scores(lengths: list[int], k: int, seed: int, *, cold: bool = False) -> list[LogScores]:
    rng = np.random.default_rng(seed)
    out = []
    for n in lengths:
        err = rng.gamma(2.0, 1.0, n)
        if cold:
            out.append(LogScores(err))
        else:
            out.append(LogScores(err, rng.dirichlet(np.ones(k) * 0.5, n), rng.random(n) * 0.3))
    return out


@st.composite
def situations(draw):
    seed = draw(st.integers(0, 10_000))
    lengths = draw(st.lists(st.integers(50, 1500), min_size=1, max_size=4))
    labelled = []
    for log, n in enumerate(lengths):
        for _ in range(draw(st.integers(0, 3))):
            a = draw(st.integers(0, n - 1))
            labelled.append((log, a, min(n, a + draw(st.integers(1, 400)))))
    points = [np.array(sorted(draw(st.lists(st.integers(1, n - 1), max_size=5)))) for n in lengths]
    return seed, lengths, labelled, points


@settings(max_examples=60, deadline=None)
@given(situations(), st.sampled_from(STRATEGIES), st.booleans(), st.integers(1, 12), st.booleans())
def test_suggestions_never_overlap_labels_or_each_other(situation, strategy, cold, n, with_embeddings) -> None:
    seed, lengths, labelled, points = situation
    scores = make_scores(lengths, 3, seed, cold=cold)
    rng = np.random.default_rng(seed)
    embeddings = [rng.normal(size=(m, 4)) for m in lengths] if with_embeddings else None
    kwargs = dict(
        labelled=labelled,
        label_counts=np.array([100, 5, 0]),
        change_points=points,
        classes=["a", "b", "c"],
        strategy=strategy,
        n=n,
        max_len=200,
        min_len=20,
        window=9,
        seed=seed,
    )
    kwargs["embeddings"] = embeddings
    got = ranked(scores, **kwargs)
    assert len(got) <= n
    cov = coverage(lengths, labelled)
    for s in got:
        assert 20 <= s.stop - s.start <= 200 and 0 <= s.start < s.stop <= lengths[s.log]
        assert not cov[s.log][s.start : s.stop].any(), "suggested labelled time"
    for i, s in enumerate(got):
        for t in got[i + 1 :]:
            assert s.log != t.log or s.stop <= t.start or t.stop <= s.start, "suggestions overlap"
    assert [s.rank for s in got] == list(range(len(got)))
    assert all(s.reason for s in got)
    assert all((s.guess is None) == cold for s in got)
    # deterministic for a fixed seed
    assert ranked(scores, **kwargs) == got


def test_ranking_follows_the_strategy() -> None:
    n = 2000
    probs = np.tile([0.98, 0.01, 0.01], (n, 1))
    probs[1200:1400] = [0.4, 0.35, 0.25]  # unsure here
    err = np.ones(n)
    err[300:500] = 10.0  # surprised here
    scores = [LogScores(err, probs, np.zeros(n))]
    top = ranked(scores, strategy="entropy", n=1, max_len=200, min_len=50, classes=["a", "b", "c"])[0]
    assert top.start >= 1100 and top.stop <= 1500
    assert top.reason == "classifier unsure between a and b"
    top = ranked(scores, strategy="surprise", n=1, max_len=200, min_len=50)[0]
    assert top.start >= 200 and top.stop <= 600 and top.reason == "predictor surprised"


def test_random_depends_on_the_seed_only() -> None:
    scores = make_scores([3000], 3, 0)
    a = ranked(scores, strategy="random", n=5, max_len=100, min_len=50, seed=1)
    assert a == ranked(scores, strategy="random", n=5, max_len=100, min_len=50, seed=1)
    assert a != ranked(scores, strategy="random", n=5, max_len=100, min_len=50, seed=2)


def test_combined_spreads_over_logs_and_favours_rare_classes() -> None:
    scores = make_scores([3000, 3000, 3000], 3, 4)
    got = ranked(scores, strategy="combined", n=6, max_len=200, min_len=50)
    assert len({s.log for s in got}) == 3
    np.testing.assert_allclose(class_weights(np.array([100.0, 100.0, 100.0])), 1.0)
    w = class_weights(np.array([300.0, 100.0, 0.0]))
    assert w[2] > w[1] > w[0]


def test_cold_start_suggests_from_surprise() -> None:
    scores = make_scores([1000], 3, 0, cold=True)
    got = ranked(scores, strategy="combined", n=3, max_len=200, min_len=50)
    assert len(got) == 3 and all(s.guess is None and s.reason == "predictor surprised" for s in got)


def test_candidates_cover_unlabelled_time_only() -> None:
    tracks = [{"surprise": np.linspace(0, 1, 1000)}]
    got = candidates([1000], [(0, 100, 300)], [np.array([500])], tracks, max_len=250, min_len=10)
    assert all(b <= 100 or a >= 300 for _, a, b in got)
    assert (0, 0, 100) in got and (0, 300, 500) in got


def test_oracle_splits_at_terrain_changes_and_skips_unknown() -> None:
    truth = [np.array([0, 0, 1, 1, 1, -1, 2])]
    assert oracle((0, 1, 7), truth) == [(0, 1, 2, 0), (0, 2, 5, 1), (0, 6, 7, 2)]


def test_combined_with_embeddings_covers_distinct_regimes_first() -> None:
    # three regimes of feature space in one log; surprise is flat, so only the clusters can spread the picks
    n = 3000
    emb = np.zeros((n, 2))
    emb[1000:2000] = [5.0, 0.0]
    emb[2000:] = [0.0, 5.0]
    emb += np.random.default_rng(0).normal(scale=0.1, size=emb.shape)
    scores = [LogScores(np.ones(n))]
    got = ranked(
        scores,
        strategy="combined",
        n=3,
        max_len=200,
        min_len=50,
        embeddings=[emb],
        change_points=[np.array([1000, 2000])],
    )
    assert sorted(s.start // 1000 for s in got) == [0, 1, 2]
    assert all(s.reason == "typical of many unlabelled stretches" for s in got)
    # with the first regime labelled, the first pick is in another
    again = ranked(
        scores,
        strategy="combined",
        n=1,
        max_len=200,
        min_len=50,
        embeddings=[emb],
        labelled=[(0, 0, 300)],
        change_points=[np.array([1000, 2000])],
    )
    assert again[0].start >= 1000


def test_combined_offers_the_drifted_log_first_and_says_why() -> None:
    # three logs the model is equally unsure about; the middle one is unlike anything labelled
    scores = make_scores([2000, 2000, 2000], 3, 7)
    drift = [np.full(2000, 0.4), np.full(2000, 1.8), np.full(2000, 0.5)]
    scores = [LogScores(s.surprise, s.probs, s.disagreement, d) for s, d in zip(scores, drift, strict=True)]
    got = ranked(scores, strategy="combined", n=4, max_len=200, min_len=50, classes=["a", "b", "c"])
    assert got[0].log == 1
    assert got[0].reason.startswith("unlike anything labelled (drift 1.8)")
    assert all(s.reason.startswith("unlike anything labelled") == (s.log == 1) for s in got)
    # the other strategies do not read drift; nor does combined when nothing is drifted
    calm = [LogScores(s.surprise, s.probs, s.disagreement, np.full(2000, 0.3)) for s in scores]
    assert not any("unlike" in s.reason for s in ranked(calm, strategy="combined", n=4, max_len=200, min_len=50))
    assert [s.log for s in ranked(scores, strategy="entropy", n=3, max_len=200, min_len=50)] == [
        s.log for s in ranked(make_scores([2000, 2000, 2000], 3, 7), strategy="entropy", n=3, max_len=200, min_len=50)
    ]


def test_combined_asks_for_a_terrain_the_model_misses_and_names_it() -> None:
    # three logs; in the last the model is surer (a, 0.75) than in the others (a or b), but gives the rest to c, a
    # terrain it misses (20 % recall): that log is offered first, and the reason says what it may be
    n, surprise = 2000, np.ones(2000)
    plain = np.tile([0.5, 0.5, 0.0], (n, 1))
    maybe_c = np.tile([0.75, 0.0, 0.25], (n, 1))
    scores = [LogScores(surprise, p, np.full(n, 0.1)) for p in (plain, plain, maybe_c)]
    kw = dict(strategy="combined", n=3, max_len=200, min_len=50, classes=["a", "b", "c"])
    assert ranked(scores, **kw)[0].log != 2  # without the recalls, the surer log comes last
    got = ranked(scores, recall=np.array([0.9, 0.8, 0.2]), **kw)
    assert got[0].log == 2, got
    assert got[0].reason.endswith("may be c, which the model misses (20 % recall)"), got[0].reason
    assert not any("misses" in s.reason for s in got if s.log != 2)
    # recalls all above one half (or unmeasured), or another strategy: no terrain is missed, nothing is named
    for recall in (np.array([0.9, 0.8, 0.7]), np.array([0.9, np.nan, np.nan])):
        assert not any("misses" in s.reason for s in ranked(scores, recall=recall, **kw))
    entropy = ranked(scores, recall=np.array([0.9, 0.8, 0.2]), **{**kw, "strategy": "entropy"})
    assert not any("misses" in s.reason for s in entropy)


def test_logs_nobody_labelled_are_suggested_first_spread_over_them() -> None:
    """Issue 65, item 2: the new runs before more time of runs already checked, each of them before a second pick
    in any; without the rule the queue goes where the scores are highest."""
    scores = make_scores([3000, 3000, 3000, 3000], 3, 4)
    scores[0] = LogScores(scores[0].surprise * 3, scores[0].probs, scores[0].disagreement + 0.5)  # the busiest log
    labelled = [(0, 100, 200), (1, 100, 200)]  # logs 0 and 1 are checked; 2 and 3 are new
    kwargs = dict(labelled=labelled, classes=["a", "b", "c"], n=6, max_len=200, min_len=50)
    picks = ranked(scores, **kwargs)
    assert [p.log for p in picks[:4]].count(2) == 2 and [p.log for p in picks[:4]].count(3) == 2
    assert {p.log for p in picks[:2]} == {2, 3}  # one in each new log before a second in either
    flat = ranked(scores, unchecked_first=False, **kwargs)
    assert [p.log for p in flat].count(0) > [p.log for p in picks].count(0)


def test_one_new_log_among_checked_ones_is_asked_first_even_beside_drifted_time() -> None:
    """Issue 65, item 2: a new run's candidates come before a checked run's drifted ones (scored up to 5, above a
    fixed lead of 2): one new run among checked ones drew 1 of 12 picks on BorealTC before the lead was a tier."""
    scores = make_scores([3000, 3000, 3000], 3, 7)
    drift = np.full(3000, 3.0)  # all of log 0 far from anything labelled
    scores[0] = LogScores(scores[0].surprise, scores[0].probs, scores[0].disagreement, drift)
    for g in (1, 2):
        scores[g] = LogScores(scores[g].surprise, scores[g].probs, scores[g].disagreement, np.zeros(3000))
    labelled = [(0, 100, 200), (1, 100, 200)]  # log 2 is the new one
    kwargs = dict(labelled=labelled, classes=["a", "b", "c"], n=6, max_len=200, min_len=50)
    picks = ranked(scores, **kwargs)
    assert [p.log for p in picks] == [2] * 6, picks
    flat = ranked(scores, unchecked_first=False, **kwargs)  # without the rule the drifted log leads
    assert flat[0].log == 0 and flat[0].reason.startswith("unlike anything labelled"), flat[0]


def test_spot_checks_are_drawn_uniformly_from_unlabelled_time_and_placed_last() -> None:
    scores = make_scores([2000, 6000], 3, 5)
    labelled = [(0, 0, 1900)]
    kwargs = dict(labelled=labelled, classes=["a", "b", "c"], max_len=100, min_len=50)
    picks = ranked(scores, n=6, spot_checks=2, **kwargs)
    assert [p.kind for p in picks] == ["suggestion"] * 4 + ["spot check"] * 2
    assert all(p.guess is not None and p.reason.startswith("spot check") for p in picks[4:])
    spans = sorted((p.log, p.start, p.stop) for p in picks)
    assert all(a[0] != b[0] or a[2] <= b[1] for a, b in itertools.pairwise(spans))  # no overlap
    assert all(not (p.log == 0 and p.start < 1900) for p in picks)  # never on labels
    # uniform over the unlabelled time: log 1 holds 6000 of its 6100 steps, so nearly every draw lands there
    logs = [p.log for seed in range(40) for p in ranked(scores, n=1, spot_checks=1, seed=seed, **kwargs)]
    assert logs.count(1) >= 36


def test_a_checked_log_whose_checks_found_the_model_wrong_is_asked_again() -> None:
    """Issue 65: once every run is checked, the runs where the checks found the model wrong keep coming first."""
    scores = make_scores([3000, 3000, 3000], 3, 6)
    scores[0] = LogScores(scores[0].surprise * 3, scores[0].probs, scores[0].disagreement + 0.5)  # the busiest log
    labelled = [(0, 100, 200), (1, 100, 200), (2, 100, 200)]  # every log checked once
    kwargs = dict(labelled=labelled, classes=["a", "b", "c"], n=6, max_len=200, min_len=50)
    asked = ranked(scores, wrong=[(0, 4), (3, 4), (0, 4)], **kwargs)
    assert [p.log for p in asked].count(1) >= 4  # the log with 3 of 4 checks wrong
    plain = ranked(scores, **kwargs)
    assert [p.log for p in plain].count(1) < [p.log for p in asked].count(1)


def test_novelty_is_the_nearest_labelled_distance_found_a_block_at_a_time(monkeypatch) -> None:
    # candidates times labels grew with the hours squared as one matrix (469 MB at 10 h); the nearest labelled
    # segment is now found in blocks, with the same distances as the whole matrix
    import sys
    import tracemalloc

    import sklearn.metrics  # noqa: F401  (imported before tracing: the import is not what is measured)

    from labeling.suggest import _novelty

    monkeypatch.setattr(sys.modules["labeling.suggest"], "NEAREST_MIB", 4)  # the package's `suggest` is a function
    rng = np.random.default_rng(0)
    emb = rng.normal(size=(12_000, 8))  # one log, a step per row
    cands = [(0, i, i + 2) for i in range(0, 8_000, 2)]  # 4,000 candidates
    labelled = [(0, i, i + 2) for i in range(8_000, 12_000, 2)]  # 2,000 labelled pieces: 61 MiB as one matrix
    tracemalloc.start()
    got, novelty = _novelty(cands, labelled, [emb])
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 30 * 2**20, f"{peak / 2**20:.0f} MiB"

    def means(spans: list) -> np.ndarray:
        return np.stack([emb[a:b].mean(0) for _, a, b in spans])

    mu, sd = means(cands).mean(0), means(cands).std(0) + 1e-9
    a, b = (means(cands) - mu) / sd, (means(labelled) - mu) / sd
    nearest = np.sqrt(np.maximum((a * a).sum(1)[:, None] + (b * b).sum(1)[None] - 2 * a @ b.T, 0)).min(1)
    np.testing.assert_allclose(got, a, atol=1e-9)
    np.testing.assert_allclose(novelty, np.minimum(nearest / np.median(nearest), 1.0), atol=1e-6)
    assert 0.0 < novelty.mean() < 1.0


def test_each_new_log_is_first_asked_its_main_answer_and_stays_in_the_tier_after() -> None:
    """Issue 65: a run the model reads confidently as one terrain is asked about its bulk (the middle of the longest
    predicted stretch) before the unsure places; that check does not take the run out of the new runs' tier."""
    rng = np.random.default_rng(8)
    scores = make_scores([3000, 3000, 3000], 3, 8)
    sure = np.full((3000, 3), 0.05)
    sure[:, 1] = 0.9
    sure[:1000] = rng.dirichlet(np.ones(3) * 0.5, 1000)  # unsure for the first third, sure of b after it
    scores[2] = LogScores(scores[2].surprise, sure, scores[2].disagreement)
    labelled = [(0, 100, 200), (1, 100, 200)]  # log 2 is the new one
    kwargs = dict(classes=["a", "b", "c"], n=4, max_len=200, min_len=50)
    picks = ranked(scores, labelled=labelled, main_answer="new", **kwargs)
    first = picks[0]
    assert (first.kind, first.log, first.guess) == ("main answer", 2, 1), first
    assert first.start >= 1000 and first.stop <= 3000 and first.stop - first.start == 200
    assert abs((first.start + first.stop) / 2 - 2000) < 200  # the middle of the sure stretch
    assert "main answer" in first.reason and " b over " in first.reason
    assert all(p.kind == "suggestion" and p.log == 2 for p in picks[1:])  # the tier's unsure picks follow
    assert all(not (p.start < first.stop and first.start < p.stop) for p in picks[1:])
    assert "main answer" not in [p.kind for p in ranked(scores, labelled=labelled, **kwargs)]  # off by default
    # once answered: asked no more, and the log keeps the tier (its only label is that check)
    again = ranked(
        scores,
        labelled=[*labelled, (2, first.start, first.stop)],
        answered=[(2, first.start, first.stop)],
        main_answer="new",
        **kwargs,
    )
    assert [p.kind for p in again] == ["suggestion"] * 4 and [p.log for p in again] == [2] * 4
    plain = ranked(scores, labelled=[*labelled, (2, first.start, first.stop)], main_answer="new", **kwargs)
    assert [p.log for p in plain].count(2) < 4  # a label that was not a main answer checks the log


def test_a_checked_log_is_asked_its_main_answer_once_its_checks_found_the_model_mostly_right() -> None:
    """``checked-right``: where the model was right where it doubted, its sure bulk is the question left; where it
    was wrong there, the queue goes on asking where it doubts."""
    scores = make_scores([3000, 3000, 3000], 3, 9)
    labelled = [(0, 100, 200), (1, 100, 200), (2, 100, 200)]
    kwargs = dict(labelled=labelled, classes=["a", "b", "c"], n=4, max_len=200, min_len=50, main_answer="checked-right")
    picks = ranked(scores, wrong=[(0, 0), (1, 3), (2, 3)], **kwargs)  # log 0 unchecked, 1 mostly right, 2 wrong
    mains = [p for p in picks if p.kind == "main answer"]
    assert [p.log for p in mains] == [1] and picks[0] is mains[0]
    answered = ranked(scores, wrong=[(0, 0), (1, 3), (2, 3)], answered=[(1, mains[0].start, mains[0].stop)], **kwargs)
    assert "main answer" not in [p.kind for p in answered]  # asked once
    assert all(p.kind == "suggestion" for p in ranked(scores, wrong=[(0, 0), (2, 3), (3, 3)], **kwargs))


def test_a_main_answer_never_lies_on_labelled_time() -> None:
    """A checked log's labels may sit at the middle of the model's longest stretch: the main answer is then the
    unlabelled piece of that stretch nearest its middle, and a stretch labelled whole gives none."""
    sure = np.full((3000, 3), 0.05)
    sure[:, 1] = 0.9  # one stretch of b over the whole log: its middle is 1500
    scores = [LogScores(np.ones(3000), sure, np.zeros(3000))]
    kwargs = dict(classes=["a", "b", "c"], n=3, max_len=200, min_len=50, main_answer="checked-right", wrong=[(0, 2)])
    picks = ranked(scores, labelled=[(0, 1400, 1700)], **kwargs)
    (main,) = [p for p in picks if p.kind == "main answer"]
    assert main.stop <= 1400 or main.start >= 1700, main
    assert min(abs(main.stop - 1400), abs(main.start - 1700)) == 0  # beside the labels, nearest the middle
    assert main.stop - main.start == 200
    whole = ranked(scores, labelled=[(0, 0, 3000)], **kwargs)
    assert whole == []  # nothing unlabelled: no main answer, no pick


class _FrameRows:
    """A per-step embedding that answers its own span means, as stage 1's per-frame rows do: 10 steps a row."""

    def __init__(self, rows: np.ndarray) -> None:
        self.rows, self.calls = rows, 0

    @property
    def shape(self) -> tuple[int, int]:
        return (10 * len(self.rows), self.rows.shape[1])

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, key: slice) -> np.ndarray:
        return np.repeat(self.rows, 10, axis=0)[key]

    def segment_means(self, starts: np.ndarray, stops: np.ndarray) -> np.ndarray:
        self.calls += 1
        steps = np.repeat(self.rows, 10, axis=0).astype(np.float64)
        return np.array([steps[a:b].mean(axis=0) for a, b in zip(starts, stops, strict=True)])


def test_span_means_match_each_spans_own_mean_and_use_an_embeddings_own_means() -> None:
    from labeling.span_means import embedding_means

    rng = np.random.default_rng(3)
    plain = [rng.normal(size=(n, 4)).astype(np.float32) for n in (70_000, 500, 90)]  # the first: two read blocks
    spans = np.array([(0, 0, 70_000), (0, 65_530, 65_560), (0, 3, 4), (1, 0, 500), (1, 480, 600), (2, 10, 60)])
    got = embedding_means(spans, plain)
    want = [np.asarray(plain[g][a:b], np.float64).mean(axis=0) for g, a, b in spans]  # a span past the end: clipped
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
    framed = _FrameRows(rng.normal(size=(40, 3)))
    spans = np.array([(0, 0, 400), (0, 5, 17), (0, 390, 400)])
    np.testing.assert_allclose(embedding_means(spans, [framed]), [framed[a:b].mean(axis=0) for _, a, b in spans])
    assert framed.calls == 1  # one call for the log's spans, no step read


def test_suggest_stops_when_asked_and_ranks_the_same_otherwise() -> None:
    from labeling import Interrupted

    scores = make_scores([2000, 1500], 3, 4)
    rng = np.random.default_rng(4)
    kwargs = dict(
        n=4,
        max_len=200,
        min_len=50,
        labelled=[(0, 100, 300)],
        embeddings=[rng.normal(size=(2000, 5)), rng.normal(size=(1500, 5))],
    )
    asked = []
    with pytest.raises(Interrupted):
        ranked(scores, stop=lambda: asked.append(1) or len(asked) > 1, **kwargs)  # the second pass is stopped
    assert ranked(scores, stop=lambda: False, **kwargs) == ranked(scores, **kwargs)


def test_the_queue_is_asked_with_its_evidence_and_a_policy() -> None:
    """Eight parameters at most: what is known (``Evidence``) and how to rank (``QueuePolicy``) are values."""
    import inspect

    assert len(inspect.signature(suggest).parameters) <= 8
    scores = make_scores([2000, 2000], 3, 4)
    evidence = Evidence(labelled=[(0, 0, 300)], classes=["a", "b", "c"])
    picks = suggest(scores, evidence, policy=QueuePolicy(max_len=200, min_len=50, spot_checks=1), n=4)
    assert [p.kind for p in picks][-1] == "spot check" and len(picks) == 4
    assert all(p.log == 1 for p in picks[:2])  # log 1 nobody labelled comes first


def test_verification_checks_past_what_the_time_holds_are_capped_there() -> None:
    """Issue 99, item 5: ``suggest --verify --n 10000000`` drew 50 times per piece asked (minutes); a count past the
    pieces the unlabelled time holds now gets those pieces, none overlapping each other or a label."""
    from labeling import verification_checks

    picks = verification_checks([1000, 600], [(0, 0, 100)], 10_000_000, max_len=50, min_len=25, seed=3)
    assert 0 < len(picks) <= (900 + 600) // 25
    cov = [np.zeros(1000, bool), np.zeros(600, bool)]
    cov[0][:100] = True
    for p in picks:
        assert p.stop - p.start >= 25 and not cov[p.log][p.start : p.stop].any()
        cov[p.log][p.start : p.stop] = True
    # what is left holds no piece of 25 steps
    for c in cov:
        runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[1], c.astype(np.int8), [1]]))))[::2]
        assert (runs < 25).all()
