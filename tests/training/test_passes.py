"""Offline passes: chunked, batched and written anywhere, they equal one pass over each whole log."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from training import (
    FEATURE_MODES,
    Classifier,
    ClassifierConfig,
    Normalizer,
    Predictor,
    PredictorConfig,
    Stage1Outputs,
    ensemble_pass,
    passes,
    predictor_pass,
    run_classifiers,
    run_predictor,
)
from training.paper_lstm import feature_moments


@pytest.fixture
def models() -> tuple[Predictor, list[Classifier], list[np.ndarray], Normalizer]:
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    logs = [rng.normal(size=(n, 3)).astype(np.float32) for n in (700, 90, 333)]
    pred = Predictor(PredictorConfig(3, 8)).eval()
    clfs = [Classifier(ClassifierConfig(11, 4, 6)).eval() for _ in range(3)]
    return pred, clfs, logs, Normalizer.fit(logs)


def whole(pred: Predictor, norm: Normalizer, log: np.ndarray) -> Stage1Outputs:
    """One call over the whole log, no batching, no chunks: the reference."""
    with torch.inference_mode():
        x = torch.from_numpy(norm(log))[None]
        e, h, _ = pred(x)
    err = np.zeros_like(log)
    err[1:] = x[0, 1:].numpy() - e[0, :-1].numpy()
    return Stage1Outputs(h[0].numpy(), err, e[0].numpy())


def test_predictor_pass_in_small_chunks_into_any_sink_equals_one_whole_pass(models, monkeypatch) -> None:
    pred, _, logs, norm = models
    monkeypatch.setattr(passes, "STEPS_PER_CALL", 2)  # the batch-wide cap on chunk length bottoms out at 256
    outs = run_predictor(pred, norm, logs, chunk=4096, batch=2)
    small = run_predictor(pred, norm, logs, chunk=50, batch=3)
    for log, a, b in zip(logs, outs, small, strict=True):
        ref = whole(pred, norm, log)
        for name in ("hidden", "error", "estimate"):
            np.testing.assert_allclose(getattr(a, name), getattr(ref, name), atol=1e-5)
            np.testing.assert_allclose(getattr(b, name), getattr(ref, name), atol=1e-5)
    assert outs[0].error[0].tolist() == [0.0, 0.0, 0.0]  # the first step has no estimate
    np.testing.assert_allclose(outs[0].surprise(chunk=64), np.square(outs[0].error).mean(1), rtol=1e-6)

    written: list[list[tuple[int, int]]] = [[] for _ in logs]

    class Recorder:  # a sink that only takes rows in order, as a file writer does
        def __init__(self, i: int, width: int) -> None:
            self.i, self.rows = i, np.zeros((len(logs[i]), width), np.float32)

        def __setitem__(self, key: slice, value: np.ndarray) -> None:
            written[self.i].append((key.start, key.stop))
            self.rows[key] = value

    sinks = [Stage1Outputs(Recorder(i, 8), Recorder(i, 3), Recorder(i, 3)) for i in range(len(logs))]
    predictor_pass(pred, norm, logs, sinks, chunk=64)
    for i, log in enumerate(logs):
        starts = [a for a, _ in written[i][::3]]
        assert starts == sorted(starts) and starts[0] == 0 and written[i][-1][1] == len(log)
        np.testing.assert_allclose(sinks[i].hidden.rows, outs[i].hidden, atol=1e-5)


def test_lazy_features_and_ensemble_pass_equal_the_arrays_in_memory(models) -> None:
    pred, clfs, logs, norm = models
    outs = run_predictor(pred, norm, logs)
    arrays = [o.features("hidden+surprise") for o in outs]
    lazy = [o.lazy("hidden+surprise") for o in outs]
    assert lazy[0].shape == arrays[0].shape == (700, 11) and len(lazy[1]) == 90
    np.testing.assert_array_equal(lazy[0][100:250], arrays[0][100:250])
    np.testing.assert_array_equal(lazy[2][300:9999], arrays[2][300:])
    with pytest.raises(TypeError):
        lazy[0][5]
    for a, b in zip(feature_moments(lazy, chunk=64), feature_moments(arrays), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
    ref = run_classifiers(clfs, arrays)
    chunks: list[tuple[int, int, int]] = []

    def sink(i: int, a: int, b: int, probs: np.ndarray) -> None:
        chunks.append((i, a, b))
        np.testing.assert_allclose(probs, ref[i][:, a:b], atol=1e-5)

    ensemble_pass(clfs, lazy, sink, chunk=100, batch=2)
    for i, log in enumerate(logs):
        spans = [(a, b) for j, a, b in chunks if j == i]
        assert spans[0][0] == 0 and spans[-1][1] == len(log)
        assert all(b0 == a1 for (_, b0), (a1, _) in itertools.pairwise(spans))  # every step, in order


@pytest.mark.parametrize("mode", FEATURE_MODES)
def test_lazy_features_know_their_width_without_computing_a_row(models, mode) -> None:
    pred, _, logs, norm = models
    out = run_predictor(pred, norm, logs[:1])[0]
    assert out.lazy(mode).shape == out.features(mode).shape


def test_the_ensemble_pass_gives_back_what_each_chunk_read_where_its_rows_can(models) -> None:
    """Issue 66: scoring a fleet's logs left every log's mapped frames resident (1.8 GiB at 100 h); rows that can
    give back their pages (``release``) are told after each chunk read from them, and the results do not change."""
    _, clfs, logs, _ = models
    arrays = [np.random.default_rng(i).normal(size=(len(x), 11)).astype(np.float32) for i, x in enumerate(logs)]

    class Releasing:
        def __init__(self, a: np.ndarray) -> None:
            self.a, self.shape, self.read, self.released = a, a.shape, 0, 0

        def __len__(self) -> int:
            return len(self.a)

        def __getitem__(self, key: slice) -> np.ndarray:
            self.read += 1
            return self.a[key]

        def release(self) -> None:
            assert self.read > self.released, "told to give back pages it never read"
            self.released = self.read

    rows = [Releasing(a) for a in arrays]
    ref = run_classifiers(clfs, arrays)
    out = [np.zeros_like(r) for r in ref]

    def sink(i: int, a: int, b: int, probs: np.ndarray) -> None:
        out[i][:, a:b] = probs

    ensemble_pass(clfs, rows, sink, chunk=100, batch=2)
    for r, o, x in zip(ref, out, rows, strict=True):
        np.testing.assert_allclose(o, r, atol=1e-5)
        assert x.read == -(-len(x) // 100) == x.released  # each chunk read once, and given back


def test_members_of_a_window_family_share_one_search_for_repeated_rows_with_the_same_numbers(monkeypatch) -> None:
    """The rows that repeat the one before are found once per chunk for every member (``per_row``); the
    probabilities are bit for bit those of each member searching its chunk itself, and of one pass over each log
    within float rounding."""
    from training.spectral_cnn import WindowClassifier, WindowClassifierConfig

    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    members = [WindowClassifier(WindowClassifierConfig(7 * 5, 3, window=7, hidden=8)).eval() for _ in range(3)]
    assert all(type(m).per_row for m in members)
    logs = []
    for n in (400, 95, 260):  # a new row every 20 steps, as frames complete at 100 Hz; a log's tail padded in a batch
        rows = rng.normal(size=(n // 20 + 1, 7 * 5)).astype(np.float32)
        logs.append(np.repeat(rows, 20, axis=0)[:n])

    def run() -> list[np.ndarray]:
        got = [np.empty((3, len(x), 3), np.float32) for x in logs]

        def keep(i: int, a: int, b: int, probs: np.ndarray) -> None:
            got[i][:, a:b] = probs

        ensemble_pass(members, logs, keep, chunk=128, batch=2)
        return got

    shared = run()
    monkeypatch.setattr(WindowClassifier, "per_row", False)  # each member searches its chunk itself
    alone = run()
    assert all(np.array_equal(a, b) for a, b in zip(shared, alone, strict=True))
    with torch.inference_mode():
        for x, g in zip(logs, shared, strict=True):
            for m, member in enumerate(members):
                whole_log = torch.softmax(member(torch.from_numpy(x)[None], None)[0], -1)[0].numpy()  # (T, K)
                np.testing.assert_allclose(g[m], whole_log, atol=1e-6)
