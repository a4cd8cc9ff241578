"""The BorealTC protocols for the default family: the authors' partition folds, and folds holding out whole runs.

As :func:`.evaluate_windows.borealtc_protocol` does for the paper family: 5 s partitions, 5 stratified
folds, a labelled share of each fold's training partitions, test windows of 1.7 s every 0.1 s classified on their
own. The default family's unsupervised part (the input normalisation and the front end's channel split) is fitted on
the training partitions of each fold only, and self-training reads the fold's unlabelled training partitions: the
test partitions are seen once, when they are scored.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

import labeling
from training import (
    DRIFTED,
    Normalizer,
    SpectralConfig,
    SpectralSteps,
    WindowFitConfig,
    classification_metrics,
    drift_of_rows,
    expected_accuracy,
    expected_calibration_error,
    fit_window_classifier,
    frame_features,
    log_frames,
    run_classifiers,
    stacked_frames,
)

from ..expectations import SHORTEST_STRETCH_S
from .evaluate_windows import FoldResult, Split, WindowProtocol, labelled_subset, outer_folds, partitions
from .protocol_members import FoldData, Member, cut_windows


def window_inputs(
    parts: Sequence[np.ndarray], window: int, stride: int, config: SpectralConfig, normalizer: Normalizer
) -> tuple[np.ndarray, np.ndarray]:
    """Every ``window``-sample window at ``stride`` of each partition, framed on its own as the classifier sees its
    last step: ``(N, W·F)`` stacked frames and the partition of each."""
    out, owner = [], []
    for i, p in enumerate(parts):
        z = normalizer(p)
        for start in range(0, len(p) - window + 1, stride):
            frames = frame_features(z[start : start + window], config)  # (frames, F)
            out.append(stacked_frames(frames, np.asarray([len(frames) - 1]), config.window)[0])
            owner.append(i)
    return np.asarray(out, np.float32), np.asarray(owner)


def drift_figures(drift: np.ndarray, right: np.ndarray) -> dict:
    """What the drift score says about test windows ``drift (N,)`` whose predictions were ``right (N,)``: the share
    called drifted, the accuracy on either side of the line, and the AUROC of drift for telling errors."""
    drifted = drift > DRIFTED
    wrong = ~right
    auroc = float("nan")
    if wrong.any() and right.any():
        ranks = np.argsort(np.argsort(drift)) + 1.0  # ties are rare on a continuous score
        auroc = float((ranks[wrong].sum() - wrong.sum() * (wrong.sum() + 1) / 2) / (wrong.sum() * right.sum()))
    return {
        "drifted_share": float(drifted.mean()) if len(drift) else float("nan"),
        "accuracy_drifted": float(right[drifted].mean()) if drifted.any() else float("nan"),
        "accuracy_not_drifted": float(right[~drifted].mean()) if (~drifted).any() else float("nan"),
        "drift_error_auroc": auroc,
    }


def run_expectations(
    fit_metrics: dict,
    drift: np.ndarray,
    probs: np.ndarray,
    y_true: np.ndarray,
    run: np.ndarray,
    stretch: np.ndarray | None = None,
    *,
    coarser: dict[float, np.ndarray] | None = None,
    members: np.ndarray | None = None,
) -> list[dict]:
    """Per held-out run, what the fit expected it to score and what it scored: from its windows' drift ``(N,)``,
    probabilities ``(N, K)``, truth ``(N,)`` and run ``(N,)``. ``expected`` is what ``classify`` prints at its drift
    (:func:`training.expected_accuracy`), ``purity`` its windows' share predicted as its most predicted terrain
    (what ``classify`` prints by a file's stretches, each run one terrain and one stretch); ``capped`` the drift's
    figure capped at the card's, ``confidence`` the mean top probability, ``card`` the fit's headline figure: the
    rules they were chosen against. With ``stretch`` ``(N,)`` (each window's stretch of its run, as ``classify``
    cuts a file at its change points), ``stretches`` is the same share per stretch: what ``classify`` prints;
    ``coarser`` maps a shortest stretch in seconds to such an array with shorter stretches merged (a screen), read
    into ``stretches_at``. With ``members`` ``(N,)`` (each window's members' agreement,
    ``labeling.member_agreement``), ``members`` is its mean over the run: what the Data tab shows of a log."""
    card = (fit_metrics.get("estimate") or {}).get("accuracy")
    relation = fit_metrics.get("drift_accuracy")
    out = []
    for r in np.unique(run):
        mine = run == r
        expected = expected_accuracy(relation, drift[mine])
        out.append(
            {
                "run": int(r),
                "windows": int(mine.sum()),
                "accuracy": float((probs[mine].argmax(1) == y_true[mine]).mean()),
                "expected": expected,
                "capped": None if expected is None or card is None else min(expected, card),
                "confidence": float(probs[mine].max(1).mean()),
                "purity": float(np.bincount(probs[mine].argmax(1)).max() / mine.sum()),
                "stretches": None if stretch is None else _agreement(probs, mine, stretch),
                "stretches_at": {s: _agreement(probs, mine, cut) for s, cut in (coarser or {}).items()},
                "members": None if members is None else float(members[mine].mean()),
                "median_drift": float(np.median(drift[mine])),
                "card": card,
            }
        )
    return out


def _agreement(probs: np.ndarray, mine: np.ndarray, stretch: np.ndarray) -> float:
    """The share of the run's windows (``mine``) predicted as their stretch's most predicted terrain."""
    return float(
        sum(np.bincount(probs[mine & (stretch == s)].argmax(1)).max() for s in np.unique(stretch[mine])) / mine.sum()
    )


def _window_stretches(
    runs: Sequence[np.ndarray],
    run_of: np.ndarray,
    test_idx: np.ndarray,
    owner: np.ndarray,
    size: int,
    win: int,
    stride: int,
    rate_hz: float,
    cache: dict[int, np.ndarray],
    *,
    min_length: int = 0,
) -> np.ndarray:
    """Each test window's stretch ``(N,)``: the index, within its run, of the stretch between the run's change
    points (``log_change_points`` on the run's signals, as ``classify`` cuts a file) that holds its last sample;
    with ``min_length`` (samples) no stretch is shorter (``labeling.coarser_points``), as ``classify`` merges them."""
    from ..cycle import log_change_points

    first = {int(r): int(np.argmax(run_of == r)) for r in np.unique(run_of[test_idx])}  # a run's first partition
    out = np.empty(len(owner), np.int64)
    seen: dict[int, int] = {}  # windows so far of each test partition
    cuts: dict[int, np.ndarray] = {}  # per run, its points with no stretch under min_length
    for n, o in enumerate(owner):
        i = int(test_idx[o])
        r = int(run_of[i])
        if r not in cache:
            cache[r] = log_change_points(runs[r], None, rate_hz=rate_hz)
        if r not in cuts:
            cuts[r] = cache[r] if min_length <= 0 else labeling.coarser_points(cache[r], len(runs[r]), min_length)
        j = seen.get(o, 0)
        seen[o] = j + 1
        end = (i - first[r]) * size + j * stride + win - 1  # the window's last sample in its run
        out[n] = np.searchsorted(cuts[r], end, side="right")  # run_expectations reads it within the run
    return out


def _stretch_units(
    runs: Sequence[np.ndarray],
    run_of: np.ndarray,
    unlabelled: Sequence[int],
    size: int,
    rate_hz: float,
    cache: dict[int, np.ndarray],
) -> list[int]:
    """The unit of each unlabelled partition (indices in order): consecutive unlabelled partitions of one run with
    no change point between them (``log_change_points`` on the run, as a session finds them) are one unit, as a
    session's stretch between change points is cut into pieces of 5 s."""
    from ..cycle import log_change_points

    first = {int(r): int(np.argmax(run_of == r)) for r in np.unique(run_of[list(unlabelled)])}  # a run's first part
    units, unit, prev = [], -1, None
    for i in unlabelled:
        r = int(run_of[i])
        if r not in cache:
            cache[r] = log_change_points(runs[r], None, rate_hz=rate_hz)
        start = (i - first[r]) * size  # the partition's first sample in its run
        cut = (
            prev is None
            or prev != i - 1
            or run_of[prev] != r
            or bool(((cache[r] > start - size) & (cache[r] <= start)).any())
        )
        unit += cut
        units.append(unit)
        prev = i
    return units


def _pct(x: float) -> str:
    return "–" if np.isnan(x) else f"{x:.0%}"


def borealtc_window_protocol(
    runs: Sequence[np.ndarray],
    labels: Sequence[int],
    classes: Sequence[str],
    *,
    rate_hz: float,
    labelled: float = 0.1,
    split: Split = "partitions",
    protocol: WindowProtocol | None = None,
    fit: WindowFitConfig | None = None,
    seed: int = 0,
    log: Callable[[str], None] = print,
    train_filter: Callable[[int, np.ndarray, np.ndarray], np.ndarray] | None = None,
    member: Member | None = None,
    screen_stretch_s: Sequence[float] = (),
    device: str = "cpu",
) -> list[FoldResult]:
    """Run the protocol for the default family; one result per outer fold.

    Args:
        runs: One ``(T, C)`` array per run, raw units.
        labels: The terrain (class index) of each run.
        classes: Class names.
        rate_hz: Sample rate of the runs.
        labelled: Fraction of the training partitions whose labels stage 2 sees (stratified by terrain).
        split: ``"partitions"`` (the authors' folds) or ``"runs"`` (whole runs held out).
        protocol: Partition and window sizes, and the number of folds.
        fit: The window classifier's fit settings (self-training on by default).
        seed: Seed of the folds, the labelled subset and the fit.
        log: Where progress lines go.
        train_filter: ``(fold, training partition indices, every partition's class) -> the indices kept``: a
            protocol that trains on less of some terrain (the minority row,
            ``benchmarks/studies/minority_borealtc.py``); the test folds are unchanged.
        member: A second model fitted on the same fold (:class:`.protocol_members.FoldData`) that returns its
            probabilities of the same test windows: scored alone (``metrics["member"]``) and averaged with the
            default family's (``metrics["ensemble"]``).
        screen_stretch_s: Shortest stretches (seconds) to screen the per-stretch figure at, each held-out run's
            shorter stretches merged (``labeling.coarser_points``): ``stretches_at`` in ``metrics["runs"]``.
        device: Where the fits train and the test windows are scored.
    """
    protocol = protocol or WindowProtocol()
    size, win, stride = (round(s * rate_hz) for s in (protocol.partition_s, protocol.window_s, protocol.stride_s))
    parts, y, run_of = partitions(runs, labels, size)
    change_points: dict[int, np.ndarray] = {}  # per run, as `classify` finds them in a file (computed when needed)
    # held-out figures hold out whole runs, as a session whose logs are the runs would: the calibration is fitted
    # on them
    fit = replace(fit or WindowFitConfig(), seed=seed)
    results = []
    for fold, (train_idx, test_idx) in enumerate(
        outer_folds(y, run_of, split=split, folds=protocol.folds, seed=seed), start=1
    ):
        t0 = time.monotonic()
        if train_filter is not None:
            train_idx = np.asarray(train_filter(fold, train_idx, y))
        train = [parts[i] for i in train_idx]
        normalizer = Normalizer.fit(train)
        config = replace(
            SpectralConfig.for_log(np.concatenate(train[:50]), rate_hz),
            frame=round(protocol.frame_s * rate_hz),
            window=protocol.frames,
        )
        features = [SpectralSteps(log_frames(p, config, transform=normalizer), len(p), config) for p in train]
        chosen = set(labelled_subset(train_idx, y, labelled, seed=seed + fold).tolist())
        first = config.span - 1  # the first step whose window holds full frames only
        segments = [(j, first, size, int(y[i])) for j, i in enumerate(train_idx) if i in chosen]
        stretches = [(j, first, size) for j, i in enumerate(train_idx) if i not in chosen]
        groups = [int(run_of[i]) for i in train_idx]
        units = None
        if fit.unit_agree > 0:
            free = [int(i) for i in train_idx if i not in chosen]
            units = _stretch_units(runs, run_of, free, size, rate_hz, change_points)
            log(f"fold {fold}: {len(stretches)} unlabelled partitions in {len(set(units))} units")
        cfit = fit_window_classifier(
            features, segments, classes, config=fit, stretches=stretches, units=units, groups=groups, device=device
        )
        x, owner = window_inputs([parts[i] for i in test_idx], win, stride, config, normalizer)
        # (N, K): the windows as steps, the model is per step
        members = run_classifiers(cfit.models, [x], device=device)[0]  # (M, N, K)
        probs = members.mean(0)
        for model in cfit.models:  # the pass moved them; the drift and the member below read them on the CPU
            model.cpu()
        y_true = y[test_idx][owner]
        m = classification_metrics(y_true, probs.argmax(1), classes)
        m["calibration_error"] = expected_calibration_error(probs, y_true)
        m["temperature"] = cfit.metrics["calibration"]["temperature"]
        m["pseudo_stretches"] = cfit.metrics["pseudo_stretches"]
        drift = drift_of_rows(cfit.drift, cfit.models, x)  # (N,)
        m.update(drift_figures(drift, probs.argmax(1) == y_true))
        cut = (runs, run_of, test_idx, owner, size, win, stride, rate_hz, change_points)
        coarser = {s: _window_stretches(*cut, min_length=round(s * rate_hz)) for s in screen_stretch_s}
        stretch = _window_stretches(*cut, min_length=round(SHORTEST_STRETCH_S * rate_hz))  # as classify cuts
        m["runs"] = run_expectations(
            cfit.metrics,
            drift,
            probs,
            y_true,
            run_of[test_idx][owner],
            stretch,
            coarser=coarser,
            members=labeling.member_agreement(members) if len(members) >= 2 else None,
        )
        del members
        if member is not None:
            test = [normalizer(parts[i]) for i in test_idx]
            raw, raw_owner = cut_windows(test, win, stride)
            assert np.array_equal(raw_owner, owner)  # the same windows as the default family's, in order
            chosen_at = np.asarray([j for j, i in enumerate(train_idx) if i in chosen])
            other = member(
                FoldData(
                    fold,
                    [normalizer(p) for p in train],
                    y[train_idx],
                    chosen_at,
                    run_of[train_idx],
                    raw,
                    len(classes),
                    seed,
                )
            )
            m["member"] = classification_metrics(y_true, other.argmax(1), classes)
            m["ensemble"] = classification_metrics(y_true, (probs + other).argmax(1), classes)
        results.append(FoldResult(fold, m["accuracy"], m["macro_f1"], len(x), len(chosen), time.monotonic() - t0, m))
        log(
            f"fold {fold} ({split}): accuracy {m['accuracy']:.2%}, macro-F1 {m['macro_f1']:.3f} on {len(x)} windows "
            f"({len(chosen)} labelled partitions, {m['pseudo_stretches']:.0f} pseudo-labelled, "
            f"calibration error {m['calibration_error']:.3f} at temperature {m['temperature']:.2f}, "
            f"drifted {m['drifted_share']:.0%} of windows: accuracy {_pct(m['accuracy_drifted'])} there, "
            f"{_pct(m['accuracy_not_drifted'])} elsewhere; {time.monotonic() - t0:.0f} s)"
            + (
                f"; member {m['member']['accuracy']:.2%}, ensemble {m['ensemble']['accuracy']:.2%}"
                if member is not None
                else ""
            )
        )
    return results
