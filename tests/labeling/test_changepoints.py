"""Change points and snapping."""

import itertools
import subprocess
import sys

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from labeling import block_summary, change_points, coarser_points, snap_range, spans, stretch_agreement


def steps(seed: int = 0) -> tuple[np.ndarray, list[int]]:
    rng = np.random.default_rng(seed)
    means = [0.0, 2.0, -1.0, 1.5]
    lengths = [600, 400, 800, 500]
    x = np.concatenate([rng.normal(m, 1.0, (n, 3)) for m, n in zip(means, lengths, strict=True)])
    return x, np.cumsum(lengths)[:-1].tolist()


def test_block_summary_shapes_and_values() -> None:
    x = np.arange(10.0)[:, None]
    z = block_summary(x, 4)  # two blocks, tail of 2 dropped
    np.testing.assert_allclose(z, [[1.5, np.std([0, 1, 2, 3])], [5.5, np.std([4, 5, 6, 7])]])
    assert block_summary(x, 20).shape == (0, 2)


def test_change_points_find_the_steps_within_a_block() -> None:
    x, truth = steps()
    got = change_points(x, block=25)
    assert len(got) == len(truth)
    assert np.all(np.abs(got - np.array(truth)) <= 25)


def test_change_points_on_noise_and_short_signals() -> None:
    rng = np.random.default_rng(1)
    assert len(change_points(rng.normal(size=(3000, 4)), block=25)) <= 1
    assert len(change_points(np.zeros((50, 2)), block=25)) == 0


def test_snap_moves_edges_to_nearby_change_points_only() -> None:
    pts = np.array([100, 500, 900])
    assert snap_range(120, 480, pts, radius=50) == snap_range(120, 480, pts, radius=50)
    s = snap_range(120, 480, pts, radius=50)
    assert (s.start, s.stop, s.moved) == (100, 500, True)
    s = snap_range(250, 700, pts, radius=50)
    assert (s.start, s.stop, s.moved_start, s.moved_stop) == (250, 700, False, False)
    s = snap_range(480, 520, pts, radius=50)  # both edges near 500: never an empty proposal
    assert s.start < s.stop


@given(
    st.lists(st.integers(0, 2000), max_size=10),
    st.integers(0, 1900),
    st.integers(1, 300),
    st.integers(0, 200),
)
def test_snap_is_never_empty_and_moves_at_most_radius(points: list[int], start: int, length: int, radius: int) -> None:
    stop = start + length
    s = snap_range(start, stop, np.array(points, dtype=np.int64), radius=radius)
    assert s.start < s.stop
    assert abs(s.start - start) <= radius and abs(s.stop - stop) <= radius
    assert s.moved_start == (s.start != start) and s.moved_stop == (s.stop != stop)


@given(st.integers(1, 3000), st.lists(st.integers(-10, 3010), max_size=12), st.integers(1, 700), st.integers(1, 50))
def test_spans_tile_the_log_without_overlap(length: int, points: list[int], max_len: int, min_len: int) -> None:
    got = spans(length, np.array(points), max_len=max_len, min_len=min_len)
    # at most max_len, unless pieces that short would fall under min_len: then under 2 * min_len
    assert all(0 <= a < b <= length and min_len <= b - a <= max(max_len, 2 * min_len - 1) for a, b in got)
    assert all(b1 <= a2 for (_, b1), (a2, _) in itertools.pairwise(got))
    if min_len == 1:
        assert sum(b - a for a, b in got) == length


def test_a_stretch_of_min_len_or_more_always_yields_pieces() -> None:
    """Picks no shorter than one classifier window (``max_len == min_len``): a stretch 2.5 windows long is two
    pieces, not three too short to keep (a run that changes terrain every few seconds lost most of its candidates)."""
    assert spans(25, np.zeros(0, np.int64), max_len=10, min_len=10) == [(0, 12), (12, 25)]
    assert spans(19, np.zeros(0, np.int64), max_len=10, min_len=10) == [(0, 19)]
    assert spans(9, np.zeros(0, np.int64), max_len=10, min_len=10) == []
    assert spans(40, np.zeros(0, np.int64), max_len=10, min_len=5) == [(0, 10), (10, 20), (20, 30), (30, 40)]


def test_stretch_agreement_counts_the_steps_of_each_stretchs_most_frequent_label() -> None:
    labels = np.asarray([0, 0, 1, 0, 2, 2, 2, 1, 1, 1])
    assert stretch_agreement(labels, np.asarray([4, 7])) == (3 + 3 + 3) / 10  # [0,4) three 0s; [4,7); [7,10)
    assert stretch_agreement(labels, np.asarray([])) == 4 / 10  # one stretch: its most frequent label, 1 (four)
    assert stretch_agreement(labels, np.arange(1, 10)) == 1.0  # every step its own stretch
    assert stretch_agreement(labels, np.asarray([-3, 0, 10, 40])) == 4 / 10  # points outside the steps cut nothing
    assert stretch_agreement(np.asarray([], int), np.asarray([2])) is None


def test_coarser_points_merge_each_short_stretch_into_the_one_before() -> None:
    points = np.asarray([3, 20, 24, 50, 95])  # stretches of 3, 17, 4, 26, 45 and 5 steps over 100
    assert coarser_points(points, 100, 10).tolist() == [20, 50]  # 3 joins the next; 4 and 45+5 join the one before
    assert coarser_points(points, 100, 0).tolist() == points.tolist()
    assert coarser_points(points, 100, 60).tolist() == []  # no cut leaves 60 steps on both sides: one stretch
    assert coarser_points(np.asarray([-5, 0, 100, 120]), 100, 1).tolist() == []  # only points inside the steps cut


@given(st.integers(0, 3000), st.lists(st.integers(-10, 3010), max_size=12), st.integers(1, 700), st.integers(1, 50))
def test_spans_cut_each_stretch_into_equal_pieces_as_linspace_does(
    length: int, points: list[int], max_len: int, min_len: int
) -> None:
    # the pieces computed without a loop (a fleet's hours: hundreds of thousands) are those of a loop over stretches
    edges = [0, *sorted(p for p in points if 0 < p < length), length]
    want = []
    for a, b in itertools.pairwise(edges):
        n = max(1, min(-(-(b - a) // max_len), (b - a) // min_len))  # never pieces under min_len from a stretch
        cuts = np.linspace(a, b, n + 1).round().astype(int)
        want += [(int(x), int(y)) for x, y in itertools.pairwise(cuts) if y - x >= min_len]
    assert spans(length, np.array(points, np.int64), max_len=max_len, min_len=min_len) == want


def test_the_cuts_are_ruptures_kernel_cpd_s_without_importing_ruptures_or_scipy_stats() -> None:
    """The compiled search is loaded alone (ruptures' package imports scipy.stats: 1.3 s of a short classify); its
    cuts are those of ``KernelCPD(kernel="linear").predict(pen=...)`` on the same summaries."""
    import ruptures as rpt

    from labeling.changepoints import _robust_scale

    rng = np.random.default_rng(3)
    for _ in range(12):
        x = rng.normal(size=(int(rng.integers(300, 4000)), 3))
        for start in rng.integers(0, len(x), 4):
            x[start:] += rng.normal(size=3) * 1.5
        z = _robust_scale(block_summary(x, 5))
        pen = 3.0 * z.shape[1] * np.log(len(z))
        expected = np.asarray(rpt.KernelCPD(kernel="linear", min_size=4).fit(z).predict(pen=pen)[:-1]) * 5
        np.testing.assert_array_equal(change_points(x, block=5), expected)
    code = (
        "import sys, numpy as np, labeling\n"
        "x = np.r_[np.zeros((400, 2)), np.ones((400, 2))] + np.random.default_rng(0).normal(size=(800, 2)) * 0.1\n"
        "print(labeling.change_points(x, block=10).tolist(), 'scipy.stats' in sys.modules, 'ruptures' in sys.modules)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["[400]", "False", "False"]
