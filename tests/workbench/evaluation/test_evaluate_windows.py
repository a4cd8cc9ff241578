"""Evaluation protocols at tiny sizes: partitioning, windows, splits that never leak, and that they learn."""

from __future__ import annotations

import numpy as np

from training import TrainConfig
from workbench.evaluation.evaluate_sequences import _split_groups, held_out_logs_protocol, qcat_protocol
from workbench.evaluation.evaluate_windows import WindowProtocol, borealtc_protocol, partitions, windows

S1 = TrainConfig(max_epochs=3, patience=2, chunk=32, batch_size=64)
S2 = TrainConfig(max_epochs=40, patience=8, batch_size=64, k_folds=2)


def noisy_runs(n_runs: int = 8, length: int = 600, seed: int = 0) -> tuple[list[np.ndarray], list[int]]:
    """Two terrains told apart by vibration amplitude."""
    rng = np.random.default_rng(seed)
    runs, labels = [], []
    for r in range(n_runs):
        label = r % 2
        runs.append((rng.normal(size=(length, 3)) * (2.0 if label else 0.4) + 1.0).astype(np.float32))
        labels.append(label)
    return runs, labels


def test_partitions_and_windows() -> None:
    runs = [np.arange(23, dtype=np.float32)[:, None], np.arange(10, dtype=np.float32)[:, None]]
    parts, y, run_of = partitions(runs, [0, 1], 5)
    assert [p[0, 0] for p in parts] == [0, 5, 10, 15, 0, 5]  # the 3-sample tail of run 0 is dropped
    assert y.tolist() == [0, 0, 0, 0, 1, 1] and run_of.tolist() == [0, 0, 0, 0, 1, 1]
    wins, owner = windows(parts[:2], 3, 1)
    assert len(wins) == 6 and owner.tolist() == [0, 0, 0, 1, 1, 1]
    np.testing.assert_array_equal(wins[4][:, 0], [6, 7, 8])


def test_group_split_keeps_groups_whole() -> None:
    groups = np.repeat(np.arange(40), 8)
    parts = _split_groups(groups, (0.9, 0.05, 0.05), np.random.default_rng(0))
    assert sorted(np.concatenate(parts).tolist()) == list(range(len(groups)))
    sets = [set(groups[p]) for p in parts]
    assert not (sets[0] & sets[1]) and not (sets[0] & sets[2]) and not (sets[1] & sets[2])
    assert all(len(p) > 0 for p in parts)


def test_borealtc_protocol_learns_easy_terrains() -> None:
    runs, labels = noisy_runs()
    proto = WindowProtocol(partition_s=1.0, window_s=0.3, stride_s=0.1, folds=2, train_stride_s=0.1)
    res = borealtc_protocol(
        runs,
        labels,
        ["calm", "rough"],
        rate_hz=100.0,
        labelled=0.5,
        protocol=proto,
        stage1=S1,
        stage2=S2,
        hidden=8,
        log=lambda _: None,
    )
    assert len(res) == 2
    assert all(r.windows == 24 * 8 for r in res)  # 24 test partitions of 100 samples, 8 windows of 30 each
    assert np.mean([r.accuracy for r in res]) > 0.8


def test_borealtc_strict_variant_trains_stage1_per_fold() -> None:
    runs, labels = noisy_runs(4, 300)
    proto = WindowProtocol(partition_s=1.0, window_s=0.3, stride_s=0.1, folds=2)
    seen = []
    res = borealtc_protocol(
        runs,
        labels,
        ["calm", "rough"],
        rate_hz=100.0,
        labelled=0.5,
        strict=True,
        protocol=proto,
        stage1=S1,
        stage2=S2,
        hidden=8,
        log=seen.append,
    )
    assert len(res) == 2 and not any("on all" in s for s in seen)


def test_qcat_protocol_both_variants() -> None:
    runs, labels = noisy_runs(40, 160)
    seqs = [r[k * 40 : (k + 1) * 40] for r in runs for k in range(4)]
    y = [lab for lab in labels for _ in range(4)]
    g = [i for i in range(len(runs)) for _ in range(4)]
    for leak_free in (False, True):
        res = qcat_protocol(
            seqs,
            y,
            g,
            ["calm", "rough"],
            leak_free=leak_free,
            folds=2,
            stage1=S1,
            stage2=S2,
            hidden=8,
            log=lambda _: None,
        )
        assert len(res) == 2 and all(r["n"] >= 1 for r in res)


def test_held_out_logs_protocol_reports_each_mode() -> None:
    rng = np.random.default_rng(3)
    logs, truth = [], []
    for _ in range(4):
        y = np.repeat(rng.integers(0, 2, 6), 200)
        logs.append((rng.normal(size=(len(y), 3)) * np.where(y[:, None] == 1, 2.0, 0.4)).astype(np.float32))
        truth.append(y)
    res = held_out_logs_protocol(
        logs,
        truth,
        ["calm", "rough"],
        labelled=0.2,
        segment=100,
        folds=2,
        modes=("hidden", "error"),
        stage1=S1,
        stage2=S2,
        hidden=8,
        log=lambda _: None,
    )
    assert set(res) == {"hidden", "error"} and all(len(v) == 2 for v in res.values())


def test_runs_split_never_puts_a_run_on_both_sides() -> None:
    from workbench.evaluation.evaluate_windows import outer_folds

    runs, labels = noisy_runs(10, 500)
    _, y, run_of = partitions(runs, labels, 100)
    for train, test in outer_folds(y, run_of, split="runs", folds=5, seed=0):
        assert not set(run_of[train]) & set(run_of[test])
    leaky = outer_folds(y, run_of, split="partitions", folds=5, seed=0)
    assert any(set(run_of[train]) & set(run_of[test]) for train, test in leaky)  # the authors' folds do share runs


def test_the_default_family_protocol_learns_easy_terrains_on_unseen_runs() -> None:
    from training import WindowFitConfig
    from workbench.evaluation.evaluate_spectral import borealtc_window_protocol

    runs, labels = noisy_runs(10, 1500)
    proto = WindowProtocol(partition_s=5.0, window_s=1.7, stride_s=0.5, folds=2)
    lines: list[str] = []
    res = borealtc_window_protocol(
        runs,
        labels,
        ["calm", "rough"],
        rate_hz=100.0,
        labelled=0.3,
        split="runs",
        protocol=proto,
        fit=WindowFitConfig(k_folds=2),
        log=lines.append,
    )
    assert len(res) == 2 and all("(runs)" in line and "pseudo-labelled" in line for line in lines)
    assert all(r.windows > 0 for r in res) and np.mean([r.accuracy for r in res]) > 0.9
    # per held-out run, what each figure expected beside what it scored: easy runs the members agree on and get right
    runs_said = [r for fold in res for r in fold.metrics["runs"]]
    assert runs_said and all(0 <= r["members"] <= 1 for r in runs_said)
    right = [r for r in runs_said if r["accuracy"] > 0.9]
    assert right and np.mean([r["members"] for r in right]) > 0.8
