"""Stage 1 side by side: does its surprise find terrain changes, and what does it cost to train? The default family's
frame predictor (next spectral frame from the frames before) against the paper's LSTM predictor (next sample, 200
units, 30 epochs at most), both trained without labels on the same logs, as stage 1 is.

Two sets of logs: ``demo``, four generated walks of 4 minutes (22 channels at 100 Hz, terrain patches inside each
walk, each walk a run of its own); ``borealtc``, BorealTC's runs joined end to end in a shuffled order into four logs
(a change where two runs of different terrains meet; skipped with the reason when ``../shared/data/borealtc`` is
absent). The figure: the AUROC of each predictor's surprise, averaged over the last second (the track the UI
smooths), for telling the frames within 1 s of a terrain change from the others; the LSTM's, measured in the same
run, is the reference, and copying the last frame the floor. Seconds are each fit's wall time here.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from sklearn.metrics import roc_auc_score

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from speed_common import Row, parse_args, record

from training import (
    Normalizer,
    SpectralConfig,
    TrainConfig,
    copy_last_error,
    fit_frame_predictor,
    fit_predictor,
    frame_ends,
    frame_surprise,
    log_frames,
    run_predictor,
)

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "borealtc"
RATE = 100.0
NEAR_S = 1.0


def demo_logs(walks: int, seconds: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Walks as ``(T, 22)`` arrays and the samples where their terrain changes."""
    from workbench.demo import generate_walk

    arrays, changes = [], []
    for seed in range(walks):
        w = generate_walk(seed, seconds)
        arrays.append(
            np.concatenate([w.forces.reshape(len(w.times), -1), w.gyro, w.accel, w.quat], axis=1).astype(np.float32)
        )
        edges = [round(a * RATE) for (a, _, t), (_, _, u) in zip(w.truth[1:], w.truth[:-1], strict=True) if t != u]
        changes.append(np.asarray(edges))
    return arrays, changes


def borealtc_logs(folder: Path, logs: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """BorealTC's runs in a shuffled order, joined into ``logs`` logs; a change where two terrains meet."""
    from workbench.evaluation import load_runs

    runs, terrains, _ = load_runs(folder)
    order = np.random.default_rng(0).permutation(len(runs))
    arrays, changes = [], []
    for part in np.array_split(order, logs):
        lengths = np.cumsum([len(runs[i]) for i in part])
        arrays.append(np.concatenate([runs[i] for i in part]).astype(np.float32))
        changes.append(
            np.asarray([lengths[j] for j in range(len(part) - 1) if terrains[part[j]] != terrains[part[j + 1]]])
        )
    return arrays, changes


def trailing(x: np.ndarray, n: int) -> np.ndarray:
    """Mean of the last ``n`` values at each position (fewer at the start)."""
    c = np.cumsum(np.concatenate([[0.0], x]))
    idx = np.arange(1, len(x) + 1)
    return (c[idx] - c[np.maximum(idx - n, 0)]) / np.minimum(idx, n)


def auroc(scores: list[np.ndarray], ends: list[np.ndarray], changes: list[np.ndarray], skip: int) -> float:
    """AUROC of per-frame scores for frames whose end lies within ``NEAR_S`` of a change (the first ``skip`` frames of
    each log left out: no context)."""
    y, s = [], []
    for sc, e, ch in zip(scores, ends, changes, strict=True):
        near = (np.abs(e[:, None] - ch[None, :]) <= NEAR_S * RATE).any(axis=1) if len(ch) else np.zeros(len(e), bool)
        y.append(near[skip:])
        s.append(sc[skip:])
    return float(roc_auc_score(np.concatenate(y), np.concatenate(s)))


def compare(name: str, arrays: list[np.ndarray], changes: list[np.ndarray], *, epochs: int, device: str) -> Row:
    """Both predictors trained on ``arrays`` and scored against ``changes``: the table's row."""
    minutes = sum(len(a) for a in arrays) / RATE / 60
    what = (
        f"{len(arrays)} logs, {minutes:.1f} min, {arrays[0].shape[1]} channels, {sum(len(c) for c in changes)} changes"
    )
    print(f"{name}: {what}", flush=True)
    second = round(RATE / round(0.2 * RATE))  # frames per second
    normalizer = Normalizer.fit(arrays)
    config = SpectralConfig.for_log(np.concatenate([a[: int(600 * RATE)] for a in arrays[:5]]), RATE)
    frames = [log_frames(a, config, transform=normalizer) for a in arrays]
    t0 = time.monotonic()
    model, _ = fit_frame_predictor(frames)
    t_fit = time.monotonic() - t0
    ends = [frame_ends(len(a), config) for a in arrays]
    skip = 2 * second
    ours = auroc([trailing(frame_surprise(model, f)[0], second) for f in frames], ends, changes, skip)
    floor = auroc([trailing(copy_last_error(model, f), second) for f in frames], ends, changes, skip)
    t0 = time.monotonic()
    fit = fit_predictor(arrays, config=TrainConfig(max_epochs=epochs, patience=5, device=device), hidden=200)
    t_lstm = time.monotonic() - t0
    outs = run_predictor(fit.model, fit.normalizer, arrays, device=device)
    lstm = auroc(
        [trailing(o.surprise(), round(RATE))[e] for o, e in zip(outs, ends, strict=True)], ends, changes, skip
    )  # the LSTM's per-sample track read at the frames' ends
    return Row(
        f"stage-1 surprise: AUROC for terrain changes (±{NEAR_S:.0f} s), {name} ({what})",
        f"frame predictor {ours:.3f} (fit {t_fit:.1f} s)",
        f"LSTM predictor {lstm:.3f} ({len(fit.history)} epochs, fit {t_lstm:.1f} s)",
        f"{ours - lstm:+.3f} AUROC, fit {t_lstm / t_fit:.0f}× faster",
        "≥ the LSTM's",
        bool(ours >= lstm),
        f"floor (copy the last frame): {floor:.3f}",
    )


def main() -> None:
    args = parse_args(__doc__)
    walks, seconds, epochs = (2, 60.0, 2) if args.quick else (4, 240.0, 30)
    rows = [compare("demo walks", *demo_logs(walks, seconds), epochs=epochs, device=args.device)]
    if DATA.is_dir():
        rows.append(compare("BorealTC runs joined", *borealtc_logs(DATA, 4), epochs=epochs, device=args.device))
    else:
        print(f"stage-1 surprise on BorealTC: skipped: no BorealTC data at {DATA}")
    record("stage1_surprise", rows, device=args.device)


if __name__ == "__main__":
    main()
