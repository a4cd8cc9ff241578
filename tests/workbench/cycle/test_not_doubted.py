"""Which labels the fit's figures count (issue 65): all but those a ranked suggestion placed where it doubted."""

from __future__ import annotations

from pathlib import Path

from tests.conftest import new_session
from workbench.cycle.checks_record import not_doubted
from workbench.demo import generate_demo_logs


def test_a_label_a_ranked_suggestion_placed_is_left_out_of_the_figures_and_the_others_count(tmp_path: Path) -> None:
    s = new_session(tmp_path / "s")
    s.ingest(generate_demo_logs(tmp_path / "logs", n_logs=2, minutes=0.3, seed=1))
    one, two = s.logs()
    a, b = [t.name for t in s.terrains()][:2]
    for log, start, kind in [(one, 100, "suggestion"), (one, 400, "spot check"), (two, 100, "main answer")]:
        s.add_check(log.id, start, start + 100, a, predicted=b, agreement=0.0, classifier=1, kind=kind, author="t")
    segs = [
        s.add_segment(one.id, 150, 250, a, author="t"),  # overlaps the suggestion's check: doubted
        s.add_segment(one.id, 400, 500, a, author="t"),  # a spot check: a fair sample
        s.add_segment(two.id, 100, 200, a, author="t"),  # a main answer counts
        s.add_segment(two.id, 600, 700, b, author="seed"),  # no check at all: seed and manual labels count
        s.add_segment(one.id, 260, 360, b, author="t"),  # after the suggestion's piece [100, 200): counts
    ]
    assert not_doubted(s, segs) == [False, True, True, True, True]
    s.close()
