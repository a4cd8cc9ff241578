"""The session's suggestion queue: what to label next, from the session's scores and change points."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

import labeling
from sessions import COUNTED_KINDS, Check, LogInfo, Session
from training import terrain_recalls

from .checks_record import names_now
from .scores import SessionScores
from .session_figure import DEFAULT_WIDTH, session_figures

# Suggestions are short: a labelled second from many places teaches stage 2 more than the same seconds in a few
# longer stretches. On the demo logs, 140 s labelled at random reached 80-81 % held-out accuracy as 1 s pieces and
# 56-71 % as 3 s pieces (docs/design-notes.md, "A pick is one classifier window long").
SUGGESTION_S = 1.0
# Of a queue of 4 or more, this many are spot checks, drawn uniformly from the unlabelled time: what the person's
# checks of them say of the model is a fair sample, which the ranked suggestions' is not
SPOT_CHECKS = 1
# Which logs are asked the model's main answer there (``labeling.suggest``): a log once the person's checks
# there found the model right at least as often as wrong. `evaluate loop`, 4 x 12 suggestions, same code: BorealTC with
# one run per terrain new, 87.1 -> 91.4 % (seed 1) and 81.7 -> 93.8 % (seed 2, never used for the choice); demo walks
# whose terrain changes every 5-36 s, 95.5 -> 94.0 % and 93.9 -> 91.3 % (random: 92.7 and 86.3 %). Asking every
# new log first ("new") gained as much on BorealTC (92.7 %) and lost 4.9 points on the walks.
MAIN_ANSWER: labeling.MainAnswer = "checked-right"
# The queue the page, `workbench suggest` and `evaluate loop` rank with; each takes its strategy and seed from it
# (`dataclasses.replace`), and `evaluate loop`'s ablation arms are this policy with one lever left out. The pick's
# length comes from the session (its rate and the classifier's span), and spot checks are left out where they cannot
# be a fair sample (a `random` queue is one already; no classifier yet; a queue under 4).
SESSION_POLICY = labeling.QueuePolicy(main_answer=MAIN_ANSWER, spot_checks=SPOT_CHECKS)


VERIFY = "verify"  # the queue of verification checks, beside the ranking strategies
QUEUE_MODES: tuple[str, ...] = (*labeling.STRATEGIES, VERIFY)


def verification_queue(
    session: Session,
    scores: SessionScores,
    *,
    logs: list[LogInfo],
    width: float = DEFAULT_WIDTH,
    n: int | None = None,
    seed: int = 0,
) -> list[tuple[LogInfo, labeling.Suggestion]]:
    """Uniform checks of the scores' classifier over the time nobody labelled, stratified by log in proportion to
    it (``labeling.verification_checks``): ``n`` more, or as many more as bring the session's interval to ``width``
    (``SessionFigure.plan``; none once it is there, at most ``labeling.MOST_CHECKS``). Each carries the model's
    guess; labelled, each is a spot check of this version.

    The draw is the version's: made over the time nobody had labelled when its checks began, so labelling one piece
    leaves the others where they were and the queue only shrinks (each log's draws come in one seeded order, so
    asking for more adds pieces after the ones drawn before).
    """
    logs = [x for x in logs if x.id in scores.scores]
    if not logs or scores.classifier is None:
        return []
    figure = session_figures(session, scores).session
    have = 0 if figure.figure is None else figure.figure.checks
    more = n if n is not None else min(figure.plan(width=width), labeling.MOST_CHECKS)
    if more <= 0:
        return []
    index = {x.id: i for i, x in enumerate(logs)}
    mine = [
        (index[c.log_id], c.start, c.stop)
        for c in session.checks()
        if c.kind == "spot check" and c.classifier == scores.classifier and c.log_id in index
    ]

    def overlaps(g: int, a: int, b: int) -> bool:
        return any(g == h and a < d and c < b for h, c, d in mine)

    now = [(index[g.log_id], g.start, g.stop) for g in session.segments() if g.log_id in index]
    before = [x for x in now if not overlaps(*x)]  # the labels but those this version's checks made
    max_len, min_len = suggestion_lengths(logs[0].rate_hz, span=scores.span)
    picks = labeling.verification_checks(
        [x.n_samples for x in logs],
        before,
        have + more,
        max_len=max_len,
        min_len=min_len,
        seed=seed * 100_003 + scores.classifier,
    )
    covered = labeling.coverage([x.n_samples for x in logs], now)
    out = []
    for p in picks:
        if overlaps(p.log, p.start, p.stop) or covered[p.log][p.start : p.stop].any():
            continue  # checked already, or labelled since
        probs = scores.scores[logs[p.log].id].probs
        guess = None if probs is None else int(np.asarray(probs[p.start : p.stop]).mean(axis=0).argmax())
        out.append((logs[p.log], labeling.Suggestion(p.log, p.start, p.stop, 0.0, p.reason, guess, len(out), p.kind)))
    return out[:more]


def suggestion_lengths(rate_hz: float, *, seconds: float = SUGGESTION_S, span: int = 0) -> tuple[int, int]:
    """``(max_len, min_len)`` in samples of suggestions ``seconds`` long: pieces of half to all of it, and never
    shorter than ``span``, the samples one prediction of the classifier reads (``SessionScores.span``): at 6.5 Hz a
    second is 6 samples, under the 10 of a 1.6 s window, and a pick that short taught the model nothing."""
    longest = max(round(seconds * rate_hz), span)
    return longest, max(1, longest // 2, span)


def _wrong_checks(checks: list[Check], log_ids: list[int]) -> list[tuple[int, int]]:
    """Per log, ``(wrong, checks)`` of the person's counted checks there; a main answer found right is neither (it
    says the run's bulk is right, nothing of the places where the model is unsure)."""
    tally = {i: [0, 0] for i in log_ids}
    for c in checks:
        if c.kind in COUNTED_KINDS and c.log_id in tally and not (c.kind == "main answer" and c.right):
            tally[c.log_id][0] += not c.right
            tally[c.log_id][1] += 1
    return [(tally[i][0], tally[i][1]) for i in log_ids]


def suggest_for_session(
    session: Session,
    scores: SessionScores,
    change_points: dict[int, np.ndarray],
    *,
    logs: list[LogInfo],
    n: int = 12,
    policy: labeling.QueuePolicy = SESSION_POLICY,
    stop: Callable[[], bool] = lambda: False,
) -> list[tuple[LogInfo, labeling.Suggestion]]:
    """The session's suggestion queue: ``n`` segments to label next, with the log each lies in.

    Args:
        session: The session whose labels, checks and terrains are the queue's evidence.
        scores: Its scores (the tracks they carry are ranked, not computed again, when they cover ``logs``).
        change_points: Per log id, change points where candidates are cut.
        logs: The logs to rank (those the scores hold).
        n: How many, spot checks included.
        policy: The queue's policy (``SESSION_POLICY`` with a strategy and seed of the caller's); its lengths are
            replaced by the session's (``suggestion_lengths``), and its spot checks dropped where they cannot be a
            fair sample (a ``random`` queue, no classifier yet, a queue under 4).
        stop: Polled between the ranking's passes (``labeling.Interrupted`` raised when it says so).
    """
    logs = [x for x in logs if x.id in scores.scores]
    if not logs:
        return []
    index = {x.id: i for i, x in enumerate(logs)}
    labelled = [(index[s.log_id], s.start, s.stop) for s in session.segments() if s.log_id in index]
    checks = session.checks()
    answered = [(index[c.log_id], c.start, c.stop) for c in checks if c.kind == "main answer" and c.log_id in index]
    terrains = [t.name for t in session.terrains()]
    classes = names_now(session, scores) or terrains  # as the session calls them now: the labels' names
    counts = np.zeros(len(classes))
    for s in session.segments():
        if s.terrain in classes:
            counts[classes.index(s.terrain)] += s.length
    max_len, min_len = suggestion_lengths(logs[0].rate_hz, span=scores.span)
    classifier = session.active_model("classifier")
    fair = policy.strategy != "random" and scores.classifier is not None and n >= 4
    policy = replace(
        policy, max_len=max_len, min_len=min_len, window=scores.window, spot_checks=policy.spot_checks if fair else 0
    )
    # the metrics name the classes as they were called when the classifier was trained: the scores' names
    recall = terrain_recalls(
        classifier.metrics.get("estimate") if classifier is not None else None, list(scores.classes) or terrains
    )
    evidence = labeling.Evidence(
        labelled=labelled,
        label_counts=counts,
        change_points=[change_points.get(x.id, np.zeros(0, np.int64)) for x in logs],
        classes=classes,
        embeddings=[scores.embeddings[x.id] for x in logs],
        recall=recall,
        wrong=_wrong_checks(checks, [x.id for x in logs]),
        answered=answered,
        # the tracks the scores carry, where they were ranked over exactly these logs: taken, not computed again
        tracks=[scores.tracks[x.id] for x in logs] if set(scores.tracks) == {x.id for x in logs} else None,
    )
    out = labeling.suggest([scores.scores[x.id] for x in logs], evidence, policy=policy, n=n, stop=stop)
    return [(logs[s.log], s) for s in out]
