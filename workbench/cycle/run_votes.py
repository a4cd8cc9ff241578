"""Corrections that stick: wherever a run holds labels, its scores are the model's handed to the vote of those
labels over the run's own frames, as far as the model is unsure there (``labeling.run_votes``,
``labeling.blend_votes``), and, until a Retrain has learned every label of the run, as far as the person's checks
there found it wrong. Once the active classifier trained on all of them, its confidence alone decides: the checks were
of the models before the labels that fixed them (on a run that changes terrain every few seconds they held the trust
at 0.55 after a Retrain that named 83 % of the run right, and the blend lost 4 to 18 points to the model alone;
``benchmarks/results/loop.md``).

Every scoring of a session's logs goes through here (the page's highlights, stretches and suggestions, and the
export's predictions of those logs), so what a person labels in a run changes what the workbench says around it in
that run at once, before any fit, and stays so after one. A log nobody labelled keeps the model's answer, and so does
``workbench classify`` on files outside the session. The vote reads the default family's stage-1 embedding per
frame; a session whose stage 1 is the paper's LSTM (per-sample states, no frames) keeps the model's answer.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

import labeling
from sessions import COUNTED_KINDS, LogInfo, Session
from training import FrameOutputs

from .fold_record import new_labels

DEFAULT_TRUST = 0.8  # a model that reports no estimate is trusted as one estimated at 80 % on new runs


def with_run_votes(
    session: Session,
    logs: Sequence[LogInfo],
    outs: Mapping[int, object],
    scored: Sequence[labeling.LogScores],
    classes: Sequence[str],
    *,
    estimate: float | None = None,
    learned: Mapping | None = None,
) -> list[labeling.LogScores]:
    """``scored`` (per log of ``logs``) with the probabilities of each labelled log blended with its labels' vote,
    as far as the model is unsure there or untrusted on that run by the person's checks.

    Args:
        session: Its labels are what vote.
        logs: The logs scored, in ``scored``'s order.
        outs: Per log id, its stage-1 outputs (``FrameOutputs`` votes; anything else keeps the model's answer).
        scored: The model's scores.
        classes: The classifier's terrains, in the order of the probabilities' columns (a label of another terrain
            does not vote).
        estimate: The model's estimated accuracy on new runs (the card's): what a run with no check trusts it to.
        learned: The active classifier's record of the labels it trained on (its config's ``labels``: their ids
            and newest change): a run whose every label it learned trusts the model's own confidence.
    """
    prior = DEFAULT_TRUST if estimate is None or estimate != estimate else float(estimate)
    checks: dict[int, list[bool]] = {}
    for c in session.checks():
        if c.kind in COUNTED_KINDS:
            checks.setdefault(c.log_id, []).append(c.right)
    by_log: dict[int, list] = {}
    voting = [g for g in session.segments() if g.terrain in classes]
    for g in voting:
        by_log.setdefault(g.log_id, []).append(g)
    fresh = new_labels(voting, learned)  # the labels the active classifier has not learned (None: no record)
    unlearned = None if fresh is None else {voting[i].id for i in fresh}
    out = []
    for log, s in zip(logs, scored, strict=True):
        o = outs.get(log.id)
        if s.probs is None or not by_log.get(log.id) or not isinstance(o, FrameOutputs) or not len(o.frame_hidden):
            out.append(s)
            continue
        steps = np.full(log.n_samples, -1, np.int64)  # (T,) each step's labelled class
        for g in by_log[log.id]:
            steps[g.start : g.stop] = classes.index(g.terrain)
        frame_of = o.step_frames()  # (T,)
        n = len(o.frame_hidden)
        low, high = np.full(n, np.iinfo(np.int64).max), np.full(n, -2)
        np.minimum.at(low, frame_of, steps)
        np.maximum.at(high, frame_of, steps)
        frames = np.where((low == high) & (low >= 0), low, -1)  # (N,) a frame is labelled when all its steps agree
        times = np.arange(n) * o.config.hop / log.rate_hz
        votes = labeling.run_votes(np.asarray(o.frame_hidden), frames, len(classes), times_s=times)
        if votes is None:
            out.append(s)
            continue
        if unlearned is not None and not any(g.id in unlearned for g in by_log[log.id]):
            trust = 1.0  # every label of the run learned: the model's own confidence decides
        else:
            mine = checks.get(log.id, [])
            trust = labeling.run_trust(sum(mine), len(mine), prior=prior)
        out.append(replace(s, probs=labeling.blend_votes(s.probs, votes.rows(frame_of), trust=trust)))
    return out
