"""The model that ships, on runs it never saw: a time-weighted figure with an interval over runs."""

from __future__ import annotations

import numpy as np

from training import runs_low, unseen_fell, unseen_runs_figure, unseen_words


def test_the_figure_weights_runs_by_their_time_and_its_interval_resamples_runs() -> None:
    right = {1: 90.0, 2: 10.0, 3: 300.0}
    scored = {1: 100.0, 2: 100.0, 3: 300.0}
    got = unseen_runs_figure(right, scored)
    assert got is not None
    assert got.accuracy == 400 / 500 and got.runs == 3 and got.samples == 500
    assert got.per_run == {1: 0.9, 2: 0.1, 3: 1.0}
    # a resample of runs can only land between the worst run and the best: run 2 alone, run 3 alone
    assert 0.1 <= got.low < got.accuracy < got.high <= 1.0
    assert unseen_runs_figure(right, scored) == got  # seeded: the same figure on every call


def test_runs_that_agree_give_a_narrow_interval_and_runs_that_differ_a_wide_one() -> None:
    rng = np.random.default_rng(0)
    alike = {k: 0.8 * 100 + rng.normal(0, 1) for k in range(10)}
    apart = {k: (100.0 if k % 2 else 60.0) for k in range(10)}
    scored = dict.fromkeys(range(10), 100.0)
    narrow, wide = unseen_runs_figure(alike, scored), unseen_runs_figure(apart, scored)
    assert narrow.high - narrow.low < 0.02
    assert wide.high - wide.low > 0.15 and wide.low < 0.8 < wide.high


def test_one_run_has_no_interval_and_no_time_no_figure() -> None:
    one = unseen_runs_figure({4: 30.0}, {4: 40.0})
    assert one.accuracy == 0.75 and one.low is None and one.high is None and one.runs == 1
    assert unseen_runs_figure({}, {}) is None
    assert unseen_runs_figure({1: 0.0}, {1: 0.0}) is None
    assert unseen_runs_figure({}, {7: 50.0}).accuracy == 0.0  # a run scored and never right


def test_a_fall_is_said_only_below_the_last_versions_interval() -> None:
    before = {"accuracy": 0.8, "low": 0.7, "high": 0.9, "runs": 5}
    assert unseen_fell(before, {"accuracy": 0.72}) is None  # inside the interval: noise as far as runs tell
    said = unseen_fell(before, {"accuracy": 0.66})
    assert said is not None and "≈ 66 %" in said and "(70–90 %)" in said
    assert unseen_fell({**before, "low": None, "high": None}, {"accuracy": 0.1}) is None  # one run: no interval
    assert unseen_fell(None, {"accuracy": 0.1}) is None and unseen_fell(before, None) is None


def test_the_figure_in_words() -> None:
    assert unseen_words({"accuracy": 0.724, "low": 0.61, "high": 0.8, "runs": 6}) == (
        "≈ 72 % (90 % interval 61–80 %, 6 runs held out)"
    )
    one = {"accuracy": 0.5, "low": None, "high": None, "runs": 1}
    assert unseen_words(one) == "≈ 50 % (1 run held out: no interval)"
    assert unseen_words(None) is None and unseen_words({}) is None


def test_a_terrain_in_two_runs_only_is_said_to_run_low() -> None:
    got = {"accuracy": 0.29, "low": 0.1, "high": 0.56, "runs": 10, "fewest_runs": 2}
    assert runs_low(got) and "expect more of the model that ships" in unseen_words(got)
    assert not runs_low({**got, "fewest_runs": 3}) and "expect more" not in unseen_words({**got, "fewest_runs": 3})
    assert not runs_low({**got, "fewest_runs": 0}) and not runs_low(None)  # a version from before: not said
