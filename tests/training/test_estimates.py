"""The estimate per terrain: held-out logs where a terrain has two logs, same run where it has one, and the gap."""

from __future__ import annotations

import numpy as np

from training import (
    HELD_OUT,
    MIXED,
    NOT_MEASURED,
    SAME_RUN,
    estimate_headline,
    estimate_table,
    missed_terrains,
    missed_words,
    terrain_estimate,
)

CLASSES = ("ice", "wet", "carpet")


def _steps(per_class: dict[int, float], n: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """``n`` steps of each class, the first ``recall * n`` right, the rest taken for the next class."""
    true, pred = [], []
    for k, recall in per_class.items():
        right = round(recall * n)
        true.append(np.full(n, k))
        pred.append(np.r_[np.full(right, k), np.full(n - right, (k + 1) % 3)])
    return np.concatenate(true), np.concatenate(pred)


def test_one_run_per_terrain_reports_same_run_and_says_the_drop_is_not_measured() -> None:
    e = terrain_estimate(CLASSES, {0: 1, 1: 1, 2: 1}, _steps({0: 0.9, 1: 0.8, 2: 1.0}))
    assert e["kind"] == SAME_RUN and abs(e["accuracy"] - 0.9) < 1e-9 and e["gap"] is None
    assert "every terrain is labelled in one log only" in e["note"] and "two logs" in e["note"]
    assert estimate_headline(e) == "90 % same run"


def test_mixed_labels_use_held_out_logs_where_they_exist_and_measure_the_gap() -> None:
    same = _steps({0: 0.95, 1: 0.9, 2: 0.8})
    held = _steps({0: 0.75, 1: 0.7})  # "carpet" is in one log: no held-out figure
    e = terrain_estimate(CLASSES, {0: 3, 1: 2, 2: 1}, same, held)
    per = e["per_terrain"]
    assert per["ice"]["by"] == HELD_OUT and per["ice"]["recall"] == 0.75 and per["ice"]["same_run"] == 0.95
    assert per["carpet"]["by"] == SAME_RUN and per["carpet"]["recall"] == 0.8
    assert e["kind"] == MIXED and abs(e["accuracy"] - (0.75 + 0.7 + 0.8) / 3) < 1e-9
    assert abs(e["gap"] - 0.2) < 1e-9 and e["gap_terrains"] == 2
    assert "carpet is labelled in one log only" in e["note"] and "20 points lower" in e["note"]
    assert estimate_headline(e) == "75 % (2 terrains on held-out logs, 1 same run)"
    assert len(estimate_table(e)) == 2 + 3


def test_held_out_logs_everywhere_and_a_terrain_nothing_could_measure() -> None:
    e = terrain_estimate(CLASSES, {0: 2, 1: 2, 2: 1}, _steps({0: 1.0, 1: 1.0}), _steps({0: 0.8, 1: 0.6}))
    assert e["per_terrain"]["carpet"]["by"] == NOT_MEASURED and e["per_terrain"]["carpet"]["recall"] is None
    assert e["kind"] == HELD_OUT and abs(e["balanced_accuracy"] - 0.7) < 1e-9
    assert "carpet: one labelled piece, not measurable" in e["note"]
    nothing = terrain_estimate(CLASSES, {0: 1, 1: 1}, (np.zeros(0), np.zeros(0)))
    assert nothing["accuracy"] is None and nothing["kind"] == NOT_MEASURED and estimate_headline(nothing) is None


def test_a_terrain_under_half_recall_is_named_first_in_the_note() -> None:
    """Issue 54: a minority terrain the model misses is named where a person decides what to label next."""
    e = terrain_estimate(
        CLASSES, {0: 2, 1: 2, 2: 2}, _steps({0: 0.9, 1: 0.9, 2: 0.9}), _steps({0: 0.9, 1: 0.3, 2: 0.45})
    )
    assert missed_terrains(e) == [("wet", 0.3), ("carpet", 0.45)]  # worst first
    assert e["note"].startswith("the model misses wet (30 % recall), carpet (45 %): label more of them;")
    assert missed_words(missed_terrains(e, below=0.4)) == "the model misses wet (30 % recall)"
    fine = terrain_estimate(CLASSES, {0: 2, 1: 2, 2: 2}, _steps({0: 0.9, 1: 0.9, 2: 0.9}), _steps({0: 0.9, 1: 0.5}))
    assert missed_terrains(fine) == [] and "misses" not in fine["note"]  # 50 % is not under half
    # an estimate saved before the names existed still gives them
    assert missed_terrains({"per_terrain": {"sand": {"recall": 0.1}, "ice": {"recall": None}}}) == [("sand", 0.1)]


def test_terrain_recalls_line_up_with_the_classes_and_leave_the_unmeasured_as_nan() -> None:
    import numpy as np

    from training import terrain_recalls

    estimate = {"per_terrain": {"sand": {"recall": 0.2}, "grass": {"recall": None}}}
    got = terrain_recalls(estimate, ["grass", "sand", "ice"])
    assert got[1] == 0.2 and np.isnan(got[0]) and np.isnan(got[2])
    assert np.isnan(terrain_recalls(None, ["a"])).all()


def test_the_majority_baseline_stands_beside_the_estimate_and_a_model_under_it_is_named() -> None:
    """Issue 65, item 5: a gait session's headline (75.3 %) sat under always answering its most common class
    (75.5 %) and nothing said so."""
    from training import majority_words, terrain_estimate

    truth = np.array([0] * 76 + [1] * 24)
    lazy = terrain_estimate(["walk", "stairs"], {0: 3, 1: 3}, (truth, truth), (truth, np.zeros(100, np.int64)))
    assert lazy["majority"] == {"terrain": "walk", "accuracy": 0.76}
    assert lazy["accuracy"] == 0.76 and lazy["note"].startswith("the model is no better than always answering walk")
    assert majority_words(lazy) == "always the most common terrain (walk): 76 %"
    good = terrain_estimate(["walk", "stairs"], {0: 3, 1: 3}, (truth, truth), (truth, truth))
    assert "no better" not in good["note"] and good["majority"]["accuracy"] == 0.76
    assert majority_words({"accuracy": 0.9}) is None  # an estimate saved before the baseline existed
