"""A run's labels carried to the frames of the run they resemble (issue 65, item 3), and the checks' estimates."""

import numpy as np

from labeling import RunVotes, blend_votes, check_estimate, run_trust, run_votes, wilson


def _run(seed: int = 0, *, spread: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """400 frames of a run: the first half one terrain (one cluster of the embedding), the second another."""
    rng = np.random.default_rng(seed)
    centres = rng.normal(0.0, 3.0, (2, 16))
    truth = np.repeat([0, 1], 200)
    return centres[truth] + rng.normal(0.0, spread, (400, 16)), truth


def test_the_vote_follows_the_labels_of_its_own_run() -> None:
    emb, truth = _run()
    labels = np.full(400, -1)
    labels[[10, 20, 250, 300]] = truth[[10, 20, 250, 300]]
    votes = run_votes(emb, labels, 2, times_s=np.arange(400) * 0.2)
    assert isinstance(votes, RunVotes) and votes.votes.shape == (400, 2)
    np.testing.assert_allclose(votes.votes.sum(axis=1), 1.0, rtol=1e-6)
    assert (votes.votes.argmax(axis=1) == truth).mean() > 0.95
    assert votes.near[labels >= 0].max() < 1e-3 and np.median(votes.near) > 0.1
    assert run_votes(emb, np.full(400, -1), 2) is None


def test_a_confident_wrong_model_is_overruled_near_the_labels_and_one_terrain_does_not_paint_the_other() -> None:
    emb, _ = _run(1, spread=0.3)  # a terrain's frames close together, as a run's are
    wrong = np.zeros((400, 2), np.float32)
    wrong[:, 1] = 0.95  # confident, and wrong on the first half
    wrong[:, 0] = 0.05
    labels = np.full(400, -1)
    labels[[10, 60, 120]] = 0  # the person labelled the first terrain only
    votes = run_votes(emb, labels, 2)
    trusted = blend_votes(wrong, votes, trust=0.9)  # the model's estimate, no check of this run
    checked = blend_votes(wrong, votes, trust=run_trust(0, 3, prior=0.9))  # three checks here, all wrong
    assert run_trust(0, 3, prior=0.9) < 0.4
    first, second = slice(0, 200), slice(200, 400)
    assert (checked[first].argmax(axis=1) == 0).mean() > 0.9  # overruled where the labels are
    assert (trusted[first].argmax(axis=1) == 0).mean() < (checked[first].argmax(axis=1) == 0).mean()
    assert (checked[second].argmax(axis=1) == 1).mean() > 0.9  # the other terrain keeps the model's answer


def test_wilson_and_check_estimates() -> None:
    lo, hi = wilson(9, 12)
    assert abs(lo - 0.4677) < 1e-3 and abs(hi - 0.9111) < 1e-3  # the textbook interval of 9 of 12
    assert wilson(0, 0) == (0.0, 1.0)
    est = check_estimate([True] * 9 + [False] * 3)
    assert est is not None and est.right == 9 and est.n == 12 and est.accuracy == 0.75
    assert est.words() == "right on 9 of 12 checks (75 %, 95 % interval 47–91 %)"
    assert check_estimate([]) is None
