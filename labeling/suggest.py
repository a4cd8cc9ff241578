"""Suggestions: a ranked queue of unlabelled segments worth labelling next, each with its reason and a guess.

Candidates are the log cut at its change points (long stretches cut into pieces of at most ``max_len``) and the
highlighted intervals of the strategy's tracks, minus labelled time. Each candidate gets the mean of the strategy's
normalised track over it; the combined default mixes uncertainty, disagreement and surprise and favours classes with
few labels, and offers time unlike anything labelled (a drift score above 1) before the rest. Selection is greedy
and never overlaps labelled time or an earlier suggestion; the combined strategy offers the logs nobody has labelled
first, and spreads picks over logs and over guessed classes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace

import numpy as np

from .changepoints import span_array
from .placed_picks import Span, Suggestion, coverage, main_answers, spot_guess, unlabelled_runs
from .placed_picks import spot_checks as place_spot_checks
from .queue_policy import Evidence, QueuePolicy, Strategy
from .span_means import embedding_means, log_span_means, per_log
from .tracks import DRIFT_TRACK_AT_1, Kind, LogScores, normalised_tracks

# weights of the combined score; renormalised over the kinds the model can give
WEIGHTS: dict[str, float] = {"unsure": 0.45, "disagreement": 0.3, "surprise": 0.25}
LOG_DECAY, CLASS_DECAY, NEIGHBOUR_DECAY = 0.7, 0.8, 0.5
NOVELTY_FLOOR, CLUSTER_DECAY, PREFILTER = 0.25, 0.05, 10
DRIFT_PRIORITY = 1.0  # added to a drifted candidate's score (others lie in [0, 1]): drifted time is offered first
# A log nobody has labelled yet ranks in a tier above every candidate's own score (drifted and missed-terrain ones
# included): a person's new runs are checked before more time of runs already checked, spread over the new runs
# first (LOG_DECAY), then over time (NEIGHBOUR_DECAY). Measured: a run the model got 40 points worse than the rest drew
# 5 of 45 picks; with a fixed +2 (drifted candidates reach 5) one new run among 66 checked ones still drew 1 of 12. A
# log whose checks found the model wrong keeps ``wrong / (checks + 1)`` of the tier: a run the model gets wrong is
# asked about again once checked, not left after its first pick. Lifting such a run level with the new ones (from a
# third wrong), or a tier above every run whose checks did not find the model wrong, kept a changing run's picks
# (84.5 -> 93 %) and cost a robot's first day 9 points (99.5 -> 90.2 %: its confidently wrong run lost its picks).
DRIFT_CAP = 4.0  # a drifted candidate's own score is weighted by its drift, up to this
MISSED_RECALL = 0.5  # a terrain measured under this recall is one the model misses (training.MISSED_RECALL)
MISSED_BOOST = 6.0  # a candidate with all its probability on a fully missed terrain counts (1 + this) times
NEAREST_MIB = 64  # scikit-learn's working memory for the candidates' nearest labelled segment, a block at a time
MISSED_SAY = 0.1  # the pull (missed share x probability) from which the reason names the missed terrain


def _kinds_for(strategy: Strategy) -> tuple[Kind, ...]:
    if strategy in ("random", "surprise"):
        return ("surprise",)
    if strategy == "combined":
        return ("surprise", "entropy", "margin", "disagreement", "drift")
    return (strategy, "surprise")  # surprise is the fallback before a classifier exists


def candidates(
    lengths: Sequence[int],
    labelled: Sequence[Span],
    change_points: Sequence[np.ndarray] | None,
    tracks: Sequence[dict[Kind, np.ndarray]],
    *,
    max_len: int,
    min_len: int,
    threshold: float = 0.9,
) -> list[Span]:
    """Unlabelled candidate segments, deduplicated and sorted; they may overlap each other (selection will not)."""
    found = _candidate_array(
        lengths, labelled, change_points, tracks, max_len=max_len, min_len=min_len, threshold=threshold
    )
    return [(int(g), int(a), int(b)) for g, a, b in found]


def _candidate_array(
    lengths: Sequence[int],
    labelled: Sequence[Span],
    change_points: Sequence[np.ndarray] | None,
    tracks: Sequence[Mapping[Kind, np.ndarray]],
    *,
    max_len: int,
    min_len: int,
    threshold: float = 0.9,
) -> np.ndarray:
    """:func:`candidates` as an ``(N, 3)`` int64 array of ``(log, start, stop)``, sorted. A fleet's hours hold half a
    million candidates: only a piece that touches labelled time is cut in Python, the rest stay arrays."""
    cov = coverage(lengths, labelled)
    found = []
    for log, n in enumerate(lengths):
        pts = change_points[log] if change_points is not None else np.zeros(0, np.int64)
        pieces = [span_array(n, pts, max_len=max_len, min_len=min_len)]  # (P, 2)
        for track in tracks[log].values():
            above = np.asarray(track) >= threshold
            edges = np.flatnonzero(np.diff(np.concatenate([[0], above.astype(np.int8), [0]])))
            runs = np.stack([edges[::2], edges[1::2]], axis=1).astype(np.int64)  # (R, 2) highlighted stretches
            runs = runs[runs[:, 1] - runs[:, 0] >= min_len]
            for i in np.flatnonzero(runs[:, 1] - runs[:, 0] > max_len):  # a long one is centred on its peak
                a, b = (int(v) for v in runs[i])
                peak = a + int(np.argmax(track[a:b]))
                runs[i, 0] = min(max(peak - max_len // 2, a), b - max_len)
                runs[i, 1] = runs[i, 0] + max_len
            pieces.append(runs)
        both = np.concatenate(pieces)
        done = np.concatenate([[0], np.cumsum(cov[log], dtype=np.int64)])  # (n + 1,) labelled steps before each
        free = done[both[:, 1]] == done[both[:, 0]]
        keep = [both[free & (both[:, 1] - both[:, 0] >= min_len)]]
        for a, b in both[~free]:  # the few that touch labelled time: their unlabelled parts
            keep.append(np.array(unlabelled_runs(int(a), int(b), cov[log], min_len=min_len), np.int64).reshape(-1, 2))
        spans_ = np.concatenate(keep)
        found.append(np.concatenate([np.full((len(spans_), 1), log, np.int64), spans_], axis=1))
    if not found:
        return np.zeros((0, 3), np.int64)
    return np.unique(np.concatenate(found), axis=0)  # sorted by log, start, stop, as sorted tuples are


def class_weights(label_counts: np.ndarray) -> np.ndarray:
    """``(K,)`` label counts (samples per class) -> ``(K,)`` weights favouring rare classes, in ``[0.5, 3]``."""
    counts = np.asarray(label_counts, np.float64)
    return np.clip(np.sqrt((counts.mean() + 1.0) / (counts + 1.0)), 0.5, 3.0)


def suggest(
    scores: Sequence[LogScores],
    evidence: Evidence = Evidence(),
    *,
    policy: QueuePolicy = QueuePolicy(),
    n: int = 10,
    stop: Callable[[], bool] = lambda: False,
) -> list[Suggestion]:
    """The next ``n`` segments to label.

    Args:
        scores: Per log, the model's scores (``probs`` ``None`` before a classifier exists).
        evidence: What is labelled and checked, per log in the order of ``scores`` (:class:`Evidence`).
        policy: Which tiers in which order, how long a pick, how many spot checks (:class:`QueuePolicy`).
        n: How many suggestions (spot checks included).
        stop: Polled between the ranking's passes; when it returns True, :class:`Interrupted` is raised (a fleet's
            hours take seconds a pass, and a caller with newer work has no use for this ranking).

    Returns:
        At most ``n`` suggestions, best first, overlapping neither labelled time nor each other.
    """
    labelled, label_counts, change_points = evidence.labelled, evidence.label_counts, evidence.change_points
    classes, embeddings, recall, wrong = evidence.classes, evidence.embeddings, evidence.recall, evidence.wrong
    answered, tracks = evidence.answered, evidence.tracks
    strategy, max_len, min_len, window, seed = (
        policy.strategy,
        policy.max_len,
        policy.min_len,
        policy.window,
        policy.seed,
    )
    unchecked_first, wrong_first, main_answer = policy.unchecked_first, policy.wrong_first, policy.main_answer
    spot_checks = policy.spot_checks
    lengths = [len(s) for s in scores]
    spot_checks = min(max(spot_checks, 0), n)
    n -= spot_checks
    kinds = _kinds_for(strategy)
    if tracks is None:
        tracks = normalised_tracks(scores, window=window, kinds=kinds)
    else:
        tracks = [{k: t[k] for k in kinds if k in t} for t in tracks]
    cands = _candidate_array(lengths, labelled, change_points, tracks, max_len=max_len, min_len=min_len)  # (N, 3)
    if not len(cands) or n == 0:
        return place_spot_checks(lengths, labelled, [], spot_checks, max_len=max_len, min_len=min_len, seed=seed)
    logs, starts, stops = cands[:, 0], cands[:, 1], cands[:, 2]
    _check(stop)
    parts, mean_probs = _components(cands, tracks, scores)
    base, why = _base_scores(strategy, parts, len(cands), seed)
    guess = None if mean_probs is None else mean_probs.argmax(axis=1)
    rare = np.ones(len(cands))
    if strategy == "combined" and guess is not None and label_counts is not None and len(label_counts):
        rare = class_weights(label_counts)[guess]
    base = base * rare
    pull, pulled = _missed_pull(mean_probs, recall) if strategy == "combined" else (None, None)
    if pull is not None:
        base = base * (1.0 + MISSED_BOOST * pull)

    cluster = np.full(len(cands), -1)
    if strategy == "combined" and embeddings is not None:
        _check(stop)
        emb, novelty = _novelty(cands, labelled, embeddings, stop=stop)
        # With a classifier: informative, unlike what is labelled, and representative of many candidates (Zhdanov
        # 2019: k-means weighted by informativeness over the top candidates, the member nearest each centre first).
        # Before one: typicality alone (TypiClust, Hacohen et al. 2022: with a tiny budget the typical member of each
        # cluster beats informative outliers; surprise-weighted picks lost to random on BorealTC's first rounds).
        weight = (NOVELTY_FLOOR + base) * novelty if mean_probs is not None else novelty
        cluster, typical = _clusters(emb, weight, n, prefilter=mean_probs is not None, seed=seed)
        base = weight * typical
        if mean_probs is None:
            why = ["typical"] * len(cands)
    drift = _mean_drift(cands, scores) if strategy == "combined" and "drift" in parts else None
    if drift is not None:
        # the model's uncertainty means little where its inputs are unlike the labels: a person's label there is
        # worth most (the smoothed track, so a lone drifted frame does not count)
        drifted = parts["drift"] >= DRIFT_TRACK_AT_1
        # among drifted candidates the farther first: a new robot's log before the odd stretch of a known one
        base = np.where(drifted, DRIFT_PRIORITY + base * np.minimum(drift, DRIFT_CAP), base)
        why = ["drift" if d else w for d, w in zip(drifted, why, strict=True)]

    chosen: list[int] = []
    alive = np.ones(len(cands), bool)
    factor = np.ones(len(cands))
    asked = set(answered)
    checked = {g for g, a, b in labelled if b > a and (g, a, b) not in asked}
    priority = None
    if strategy == "combined" and unchecked_first:
        tier = 1.0 + float(base.max(initial=0.0))  # above any candidate's own score
        per_log = np.zeros(len(scores))
        for g, (bad, n_checks) in enumerate((wrong or ()) if wrong_first else ()):
            per_log[g] = tier * bad / (n_checks + 1)
        per_log[[g for g in range(len(scores)) if g not in checked]] = tier
        priority = per_log[logs]  # (N,) each candidate's log's
    firsts: list[Suggestion] = []
    if main_answer != "off" and priority is not None:
        done = {g for g, _, _ in asked}
        if main_answer == "new":
            skip = checked | done
        else:  # "checked-right": checked logs whose checks found the model right at least half the time
            tally = list(wrong or ())
            skip = done | {
                g
                for g in range(len(scores))
                if g >= len(tally) or not (tally[g][1] > 0 and 2 * tally[g][0] <= tally[g][1])
            }
        covered = coverage(lengths, labelled)
        firsts = main_answers(scores, skip, classes, covered, window=max_len, min_len=min_len)[:n]

    def after_pick(log: int, start: int, stop: int, cls: int | None) -> None:
        """A pick's effect on the rest: no overlap with it; its log, its neighbours and its class count less."""
        nonlocal alive, factor
        alive &= (stops <= start) | (starts >= stop) | (logs != log)
        if strategy == "combined":
            same_log = logs == log
            factor = factor * np.where(same_log, LOG_DECAY, 1.0)
            near = same_log & (np.minimum(np.abs(starts - stop), np.abs(stops - start)) < max_len)
            factor = factor * np.where(near, NEIGHBOUR_DECAY, 1.0)
            if guess is not None and cls is not None:
                factor = factor * np.where(guess == cls, CLASS_DECAY, 1.0)

    for x in firsts:
        after_pick(x.log, x.start, x.stop, x.guess)
    while len(chosen) + len(firsts) < n and alive.any():
        adjusted = np.where(alive, base * factor, -np.inf)
        if priority is not None:  # the logs nobody labelled first, then those where checks found the model wrong
            adjusted = adjusted + priority
        # the candidates are sorted by log, then start: the first of the best scores is the deterministic pick
        best = int(np.argmax(np.where(np.isnan(adjusted), -np.inf, adjusted)))
        chosen.append(best)
        after_pick(int(logs[best]), int(starts[best]), int(stops[best]), None if guess is None else int(guess[best]))
        if strategy == "combined" and cluster[best] >= 0:  # one pick per cluster before a second
            factor = factor * np.where(cluster == cluster[best], CLUSTER_DECAY, 1.0)
    out = [replace(x, rank=rank) for rank, x in enumerate(firsts)]
    for rank, i in enumerate(chosen, start=len(firsts)):
        g = None if guess is None else int(guess[i])
        reason = _reason(why[i], mean_probs[i] if mean_probs is not None else None, classes, rare[i])
        if why[i] == "drift" and drift is not None:
            reason = f"unlike anything labelled (drift {drift[i]:.1f})" + reason[len("unlike anything labelled") :]
        if pull is not None and pulled is not None and recall is not None and pull[i] >= MISSED_SAY:
            k = int(pulled[i])
            missed = classes[k] if k < len(classes) else f"class {k}"
            reason += f"; may be {missed}, which the model misses ({100 * recall[k]:.0f} % recall)"
        out.append(Suggestion(int(logs[i]), int(starts[i]), int(stops[i]), float(base[i] * factor[i]), reason, g, rank))
    taken = [(x.log, x.start, x.stop) for x in out]
    spots = place_spot_checks(lengths, labelled, taken, spot_checks, max_len=max_len, min_len=min_len, seed=seed)
    return out + [replace(x, guess=spot_guess(scores, x), rank=len(out) + j) for j, x in enumerate(spots)]


class Interrupted(Exception):
    """:func:`suggest` was asked to stop (its ``stop``) before it finished ranking."""


def _check(stop: Callable[[], bool]) -> None:
    if stop():
        raise Interrupted("the suggestions' ranking was stopped")


def _novelty(
    cands: np.ndarray,
    labelled: Sequence[Span],
    embeddings: Sequence[np.ndarray],
    *,
    stop: Callable[[], bool] = lambda: False,
) -> tuple[np.ndarray, np.ndarray]:
    """Standardised mean embedding of each candidate ``(N, D)`` (``cands``: ``(N, 3)`` of ``(log, start, stop)``),
    and ``(N,)`` novelty in ``[0, 1]``.

    Novelty is the distance to the nearest labelled segment over the median such distance, capped at 1: it only
    holds back candidates like what is labelled (an uncapped distance would chase outliers). 1 with no labels.
    """

    from sklearn import config_context
    from sklearn.metrics import pairwise_distances_argmin_min

    cands = np.asarray(cands, np.int64).reshape(-1, 3)
    emb = embedding_means(cands, embeddings)  # (N, D)
    mu, sd = emb.mean(axis=0), emb.std(axis=0) + 1e-9
    emb = (emb - mu) / sd
    done = np.array([(g, a, b) for g, a, b in labelled if b > a], np.int64).reshape(-1, 3)
    if not len(done):
        return emb, np.ones(len(cands))
    order = np.lexsort((done[:, 1], done[:, 0]))  # grouped by log for the means, then back in their order
    means = np.empty((len(done), emb.shape[1]))
    means[order] = embedding_means(done[order], embeddings)
    # the nearest labelled segment of each candidate, a block of candidates at a time: the whole (N, M) matrix grew
    # with the hours squared (candidates times labels: 469 MB at 10 hours of logs, 5 % labelled)
    # in float32: half the time of float64 over a fleet's half a million candidates (12 s at 100 hours of logs), and
    # a distance only ever read over the median one
    _check(stop)
    with config_context(working_memory=NEAREST_MIB):
        _, dist = pairwise_distances_argmin_min(emb.astype(np.float32), ((means - mu) / sd).astype(np.float32))
    ref = float(np.median(dist)) or 1.0
    return emb, np.minimum(dist / ref, 1.0)


def _clusters(
    emb: np.ndarray, weight: np.ndarray, n: int, *, prefilter: bool, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted k-means with ``n`` clusters over the candidates (the top ``PREFILTER · n`` by weight if
    ``prefilter``).

    Returns:
        ``(N,)`` cluster of each candidate (``-1`` outside the prefiltered set) and ``(N,)`` typicality in
        ``(0, 1]``: 1 at a cluster centre, falling with distance (0.1 outside the prefiltered set).
    """
    from sklearn.cluster import KMeans
    from threadpoolctl import threadpool_limits

    idx = np.argsort(-weight, kind="stable")[: PREFILTER * n] if prefilter else np.arange(len(emb))
    cluster, typical = np.full(len(emb), -1), np.full(len(emb), 0.1)
    k = min(n, len(idx))
    if k < 2:
        typical[idx] = 1.0
        cluster[idx] = 0
        return cluster, typical
    # One thread: a few thousand points take milliseconds, and OpenMP's workers spin while they wait; with a
    # retrain on the same 2 cores a stack dump caught the simulation here, with half the CPU time in the kernel.
    with threadpool_limits(1):
        km = KMeans(k, n_init=3, random_state=seed).fit(emb[idx], sample_weight=np.maximum(weight[idx], 1e-9))
    d = np.linalg.norm(emb[idx] - km.cluster_centers_[km.labels_], axis=1)
    ref = float(np.median(d)) or 1.0
    cluster[idx] = km.labels_
    typical[idx] = 1.0 / (1.0 + d / ref)
    return cluster, typical


def _components(
    cands: np.ndarray, tracks: Sequence[Mapping[Kind, np.ndarray]], scores: Sequence[LogScores]
) -> tuple[dict[str, np.ndarray], np.ndarray | None]:
    """Mean normalised track of each kind over each candidate (``(N, 3)``, grouped by log), and ``(N, K)`` mean
    probabilities (or ``None``)."""
    kinds = sorted({k for t in tracks for k in t})
    parts = {k: np.zeros(len(cands)) for k in kinds}
    has_probs = not any(s.probs is None for s in scores)
    probs = np.zeros((len(cands), scores[0].probs.shape[1])) if has_probs and len(scores) else None
    for g, rows in per_log(cands):  # one log's prefix sums at a time: a fleet's would be gigabytes at once
        a, b = cands[rows, 1], cands[rows, 2]
        for k, t in tracks[g].items():
            parts[k][rows] = log_span_means(t, a, b)
        if probs is not None:
            probs[rows] = log_span_means(scores[g].probs, a, b)  # (n, K)
    return parts, probs


def _mean_drift(cands: np.ndarray, scores: Sequence[LogScores]) -> np.ndarray | None:
    """``(N,)`` mean drift score over each candidate (``(N, 3)``, grouped by log), or ``None`` when a log has none."""
    if any(s.drift is None for s in scores):
        return None
    out = np.zeros(len(cands))
    for g, rows in per_log(cands):
        out[rows] = log_span_means(np.asarray(scores[g].drift, np.float64), cands[rows, 1], cands[rows, 2])
    return out


def _base_scores(strategy: Strategy, parts: dict[str, np.ndarray], n: int, seed: int) -> tuple[np.ndarray, list[str]]:
    """``(N,)`` score of each candidate and the name of the component that drives it."""
    if strategy == "random":
        return np.random.default_rng(seed).random(n), ["random"] * n
    if strategy != "combined":
        kind = strategy if strategy in parts else "surprise"
        return parts[kind], [kind] * n
    comps = {"surprise": parts["surprise"]}
    if "entropy" in parts:
        comps["unsure"] = np.maximum(parts["entropy"], parts["margin"])
    if "disagreement" in parts:
        comps["disagreement"] = parts["disagreement"]
    total = sum(WEIGHTS[k] for k in comps)
    weighted = {k: WEIGHTS[k] / total * v for k, v in comps.items()}
    names = list(weighted)
    stack = np.stack([weighted[k] for k in names])  # (kinds, N)
    return stack.sum(axis=0), [names[i] for i in stack.argmax(axis=0)]


def _missed_pull(
    mean_probs: np.ndarray | None, recall: np.ndarray | None
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Per candidate, how strongly it may hold a missed class (``(N,)``: the largest of each missed class's
    probability times how far its recall is under ``MISSED_RECALL``, as a share of it) and which class that is
    ``(N,)``; ``(None, None)`` without probabilities or a missed class."""
    if mean_probs is None or recall is None or len(recall) != mean_probs.shape[1]:
        return None, None
    r = np.asarray(recall, np.float64)
    missing = np.where(np.isfinite(r), np.clip((MISSED_RECALL - r) / MISSED_RECALL, 0.0, 1.0), 0.0)  # (K,)
    if not missing.any():
        return None, None
    weighted = mean_probs * missing  # (N, K)
    return weighted.max(axis=1), weighted.argmax(axis=1)


def _reason(driver: str, probs: np.ndarray | None, classes: Sequence[str], rarity: float) -> str:
    def name(i: int) -> str:
        return classes[i] if i < len(classes) else f"class {i}"

    if probs is not None:
        order = np.argsort(probs)[::-1]
        first, second = name(int(order[0])), name(int(order[1])) if len(order) > 1 else ""
    text = {
        "random": "random pick",
        "surprise": "predictor surprised",
        "disagreement": "models disagree",
        "entropy": "classifier unsure",
        "margin": "classifier unsure",
        "unsure": "classifier unsure",
        "typical": "typical of many unlabelled stretches",
        "drift": "unlike anything labelled",
    }[driver]
    if probs is not None and driver in ("entropy", "margin", "unsure") and second:
        text = f"classifier unsure between {first} and {second}"
    elif probs is not None and driver == "disagreement":
        text = f"models disagree (guess {first})"
    if probs is not None and rarity >= 1.5:
        text += f"; few labels of {first}"
    return text
