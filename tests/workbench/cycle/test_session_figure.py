"""How right the session is: the active version's spot checks corrected by its confidence, "not checked since the last
Retrain" after a new version, the plan that says how many checks a verification takes, and the card's section."""

from __future__ import annotations

import numpy as np
import pytest

import labeling
from tests.conftest import new_session
from workbench.cycle import SessionScores, session_figures
from workbench.demo import generate_demo_logs


def _scores(logs, version: int, *, sure: float, classes=("a", "b")) -> SessionScores:
    """Scores naming the first class everywhere with confidence ``sure``."""
    out = {}
    for x in logs:
        probs = np.zeros((x.n_samples, len(classes)), np.float32)  # (T, K)
        probs[:, 0], probs[:, 1] = sure, 1 - sure
        out[x.id] = labeling.LogScores(np.zeros(x.n_samples, np.float32), probs, np.zeros(x.n_samples, np.float32))
    return SessionScores(1, version, tuple(classes), out)


def _session(tmp_path):
    s = new_session(tmp_path / "s", ("a", "b"))
    s.ingest(generate_demo_logs(tmp_path / "logs", n_logs=2, minutes=0.2, seed=1))
    return s


def test_the_figure_rests_on_this_versions_spot_checks_only(tmp_path) -> None:
    s = _session(tmp_path)
    one, two = s.logs()
    scores = _scores([one, two], 2, sure=0.9)
    nothing = session_figures(s, scores).session
    assert nothing.figure is None and nothing.words() == "not checked yet"
    assert nothing.plan_words() == f"{labeling.checks_needed(0.9, 0.10)} checks would bring it to ±5 points"
    for i in range(8):  # version 1's spot checks, and version 2's ranked suggestions: neither tests version 2 fairly
        s.add_check(one.id, 10 * i, 10 * i + 5, "a", predicted="a", agreement=1.0, classifier=1, kind="spot check",
                    author="t")  # fmt: skip
        s.add_check(two.id, 10 * i, 10 * i + 5, "b", predicted="a", agreement=0.0, classifier=2, kind="suggestion",
                    author="t")  # fmt: skip
    stale = session_figures(s, scores).session
    assert stale.figure is None
    assert stale.words() == "not checked since the last Retrain (v1: right on 8 of 8 spot checks)"
    for i in range(10):  # version 2's spot checks: 9 of 10 right
        log = one if i < 6 else two
        right = i != 3
        s.add_check(log.id, 200 + 10 * i, 205 + 10 * i, "a" if right else "b", predicted="a",
                    agreement=float(right), classifier=2, kind="spot check", author="t")  # fmt: skip
    got = session_figures(s, scores)
    f = got.session.figure
    assert f is not None and f.checks == 10 and f.accuracy == 0.9  # a constant confidence narrows nothing
    words = got.session.words()
    assert words.startswith("≈ 90 % (90 % interval ") and "from 10 checks of this version" in words
    assert (got.per_log[one.id].figure.checks, got.per_log[two.id].figure.checks) == (6, 4)
    assert got.per_log[one.id].figure.accuracy < 1.0 and got.per_log[two.id].figure.accuracy == 1.0
    more = got.session.plan()
    assert more == labeling.checks_needed(0.9, 0.10) - 10 and f"{more} more checks" in got.session.plan_words()
    s.close()


def test_a_confidence_that_tracks_the_mistakes_moves_the_estimate_and_labels_do_not_move_it(tmp_path) -> None:
    s = _session(tmp_path)
    one, two = s.logs()
    scores = _scores([one, two], 3, sure=0.95)
    for log in (one, two):  # the model unsure exactly where it is wrong
        scores.scores[log.id].probs[300:330] = [0.55, 0.45]
    rng = np.random.default_rng(0)
    for i, start in enumerate(rng.choice(np.arange(0, 600, 10), 24, replace=False)):
        log = (one, two)[i % 2]
        wrong = 300 <= start < 330
        s.add_check(log.id, int(start), int(start) + 5, "b" if wrong else "a", predicted="a",
                    agreement=0.0 if wrong else 1.0, classifier=3, kind="spot check", author="t")  # fmt: skip
    f = session_figures(s, scores).session.figure
    share = float(np.mean([c.agreement for c in s.checks()]))
    assert f is not None and f.lam > 0 and 0 < share < 1 and f.accuracy != share  # the confidence moves the estimate
    # and the width is Wilson's at that estimate with the checks' count (labeling.MAX_GAIN)
    assert (f.low, f.high) == pytest.approx(labeling.wilson_bounds(f.accuracy, 24 * labeling.MAX_GAIN))
    # the checked pieces become labels: the time the figure speaks for still holds them, so nothing moves
    for c in s.checks():
        s.add_segment(c.log_id, c.start, c.stop, c.terrain, author="t", source="suggestion")
    again = session_figures(s, scores).session.figure
    assert again is not None and abs(again.accuracy - f.accuracy) < 1e-9
    s.close()


def test_verification_pieces_are_uniform_within_each_run_in_proportion_to_its_unlabelled_time() -> None:
    lengths = [1000, 3000, 2000]
    labelled = [(0, 0, 500), (2, 0, 2000)]  # the third log is all labelled
    got = labeling.verification_checks(lengths, labelled, 10, max_len=50, min_len=25, seed=3)
    per_log = np.bincount([p.log for p in got], minlength=3)
    assert list(per_log) == [1, 9, 0]  # 500 and 3000 free steps: 10 * 500 / 3500 rounds to 1
    assert all(p.kind == "spot check" and p.reason == labeling.VERIFY_REASON for p in got)
    assert all(not (p.log == 0 and p.start < 500) for p in got)  # never on a label
    assert labeling.proportional([0, 0], 5) == [0, 0] and sum(labeling.proportional([3, 1, 1], 7)) == 7
    assert labeling.checks_needed(1.0, 0.10) == 25 and labeling.checks_needed(0.99, 0.10) == 30
    assert labeling.checks_needed(0.99, 0.10, gain=2.0) == 15  # each check counted twice: half as many


def test_the_card_leads_with_the_sessions_figure_and_names_the_labelled_pieces_for_what_they_are() -> None:
    """The card's 76 -> 35 % while the truth went 66 -> 99 %: the figure on the labelled pieces, which a loop drives
    down, is no longer the card's headline; the session's figure from the checks of this version is."""
    from pathlib import Path

    from training import load_bundle
    from workbench.cycle import SessionFigure
    from workbench.export import model_card

    bundle = load_bundle(Path(__file__).parents[2] / "training" / "golden" / "default")
    got = labeling.powered_accuracy(np.ones(24), np.full(24, 0.97), np.full(5000, 0.97))
    checked = model_card(bundle, version=6, session="s", figure=SessionFigure(6, got), logs=8)
    assert "## How right the session is" in checked
    assert "**≈ 100 % (90 % interval 90–100 %, from 24 checks of this version)** of the time nobody labelled" in checked
    assert checked.index("## How right the session is") < checked.index("## Out-of-fold metrics (same logs)")
    stale = model_card(bundle, version=7, session="s", figure=SessionFigure(7, None, confidence=0.95), logs=8)
    assert "**not checked yet**" in stale and "`workbench suggest SESSION --verify --out FILE`" in stale
    assert "checks would bring it to ±5 points" in stale
    assert "## How right the session is" not in model_card(bundle, version=7, session="s")
