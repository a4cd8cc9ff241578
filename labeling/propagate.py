"""Corrections that stick: a run's own labels carried to the frames of that run they resemble.

A label a person makes inside a run says more about that run than the fit lets it say: fitted over every run, one
second of labels moves the model little, while the frames of the same run that look like the labelled one are most
likely the same terrain (same robot, same day, same sensor gains). Measured on a BorealTC run with 26 terrain
changes: after 48 labelled seconds the fitted model was right on 54 % of the rest of the run, a nearest-neighbour vote
over the stage-1 embedding within the run on 72 %, 75 % with the time in the run as one more feature.

``run_votes`` is that vote: each frame's ``k`` nearest labelled frames of its own run (standardised embedding, and
the time in the run at ``time_scale_s`` seconds to one standard deviation), weighted by inverse distance.
``blend_votes`` hands each step to the vote as far as it is near a labelled frame and the model is unsure of it or
untrusted on that run: ``(1 - w) p + w q`` with ``w = exp(-(near / NEAR_S)^2) * (1 - trust * max p)``, ``trust`` the
model's accuracy on the run by the person's checks made there (``run_trust``, shrunk towards its estimate for new
runs). A model confident and right keeps its answer; near the labels, where it hesitates or where the person's
checks found it wrong, the run's own labels decide. Screened in
``benchmarks/studies/propagate_screen.py`` (the choice, and the variants it beat, are in ``docs/design-notes.md``).
Arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

K_NEIGHBOURS = 5
TIME_SCALE_S = 60.0  # a minute apart in the run counts as far as one standard deviation of every embedding feature
MAX_LABELLED = 4096  # labelled frames a vote reads at most (drawn evenly when there are more): bounded memory
CHUNK = 2048  # frames per distance block: CHUNK x MAX_LABELLED floats at a time
# How near a labelled frame a frame must be for the vote to count: at the nearest distance NEAR_S the vote's weight
# is 1/e of what it is on the labelled frame. Frames of another terrain than a run's labels lie farther (random
# pairs ~1.4): a run labelled in one terrain only does not paint its other terrains with it.
NEAR_S = 1.0


@dataclass(frozen=True)
class RunVotes:
    """The vote of a run's labelled frames over every frame of the run.

    Attributes:
        votes: ``(N, K)`` each frame's vote (rows sum to 1).
        near: ``(N,)`` each frame's distance to the nearest labelled frame in the standardised embedding (time left
            out), in units where two frames drawn at random from the run lie about 1.4 apart.
    """

    votes: np.ndarray
    near: np.ndarray

    def rows(self, frames: np.ndarray) -> RunVotes:
        """The votes of the frames ``frames`` (``(T,)`` indices: each sample step's frame)."""
        return RunVotes(self.votes[frames], self.near[frames])


def run_votes(
    embedding: np.ndarray,
    labels: np.ndarray,
    n_classes: int,
    *,
    times_s: np.ndarray | None = None,
    time_scale_s: float | None = TIME_SCALE_S,
    k: int = K_NEIGHBOURS,
) -> RunVotes | None:
    """The vote of a run's labelled frames for every frame of the run.

    Args:
        embedding: ``(N, D)`` one row per frame of the run (the stage-1 embedding).
        labels: ``(N,)`` the class index of a labelled frame, ``-1`` elsewhere.
        n_classes: ``K``.
        times_s: ``(N,)`` each frame's time in the run (``None``: time is not a feature of the vote).
        time_scale_s: Seconds of run time that count as one standard deviation of the embedding.
        k: Neighbours voting.

    Returns:
        The votes and distances, or ``None`` when no frame is labelled.
    """
    labelled = np.flatnonzero(labels >= 0)
    if not len(labelled):
        return None
    if len(labelled) > MAX_LABELLED:
        labelled = labelled[np.linspace(0, len(labelled) - 1, MAX_LABELLED).round().astype(int)]
    x = np.asarray(embedding, np.float32)
    z = (x - x.mean(axis=0)) / (x.std(axis=0) + 1e-6) / np.sqrt(x.shape[1])  # (N, D): unit spread in all
    d_embed = z.shape[1]
    if times_s is not None and time_scale_s:
        z = np.concatenate([z, (np.asarray(times_s, np.float32) / time_scale_s)[:, None]], axis=1)
    ref, ref_class = z[labelled], labels[labelled]  # (M, D'), (M,)
    kk = min(k, len(labelled))
    votes = np.zeros((len(z), n_classes), np.float64)
    near = np.empty(len(z), np.float32)
    ref_sq, ref_embed_sq = (ref * ref).sum(axis=1), (ref[:, :d_embed] ** 2).sum(axis=1)
    for c in range(0, len(z), CHUNK):
        q = z[c : c + CHUNK]  # (B, D')
        d = np.sqrt(np.maximum((q * q).sum(axis=1)[:, None] + ref_sq[None] - 2.0 * q @ ref.T, 0.0))  # (B, M)
        near_chunk = np.sqrt(
            np.maximum(
                (q[:, :d_embed] ** 2).sum(axis=1)[:, None]
                + ref_embed_sq[None]
                - 2.0 * q[:, :d_embed] @ ref[:, :d_embed].T,
                0.0,
            )
        )  # (B, M)
        near[c : c + CHUNK] = near_chunk.min(axis=1)
        nearest = np.argpartition(d, kk - 1, axis=1)[:, :kk]  # (B, kk)
        weight = 1.0 / (np.take_along_axis(d, nearest, axis=1) + 1e-3)  # (B, kk)
        rows = np.repeat(np.arange(len(q)), kk)
        np.add.at(votes[c : c + CHUNK], (rows, ref_class[nearest].ravel()), weight.ravel())
    return RunVotes(votes / votes.sum(axis=1, keepdims=True), near)


def blend_votes(probs: np.ndarray, votes: RunVotes, *, trust: float = 1.0) -> np.ndarray:
    """``(T, K)`` the model's probabilities handed to the run's vote (``votes``, one row per step) as far as the
    step is near a labelled frame and the model is unsure of it or untrusted on this run:
    ``(1 - w) p + w q`` with ``w = exp(-(near / NEAR_S)^2) * (1 - trust * max p)``. ``trust`` is the model's accuracy
    on this run as the person's checks there say (:func:`run_trust`): a model confidently wrong on a run is still
    overruled by the labels made in it, near them."""
    p = np.asarray(probs, np.float32)
    near = np.exp(-((np.asarray(votes.near, np.float32) / NEAR_S) ** 2))[:, None]  # (T, 1)
    w = near * (1.0 - float(np.clip(trust, 0.0, 1.0)) * p.max(axis=1, keepdims=True))  # (T, 1)
    return ((1.0 - w) * p + w * np.asarray(votes.votes, np.float32)).astype(np.float32)


PRIOR_CHECKS = 2.0  # the model's estimate counts as this many checks of a run before the run's own


def run_trust(right: int, checks: int, *, prior: float) -> float:
    """The model's accuracy on one run: its ``right`` of ``checks`` there, shrunk towards ``prior`` (the model's
    estimate for new runs) as if that were ``PRIOR_CHECKS`` checks: two checks, both wrong, make a run of a model
    estimated at 90 % trusted at 45 %."""
    return (right + PRIOR_CHECKS * prior) / (checks + PRIOR_CHECKS)
