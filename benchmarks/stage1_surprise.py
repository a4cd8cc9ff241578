"""Stage 1 side by side: does its surprise find terrain changes, and what does it cost to train? The default family's
frame predictor (next spectral frame from the frames before) against the paper's LSTM predictor (next sample), both
trained without labels on the same logs, as stage 1 is.

    python benchmarks/stage1_surprise.py --data demo --lstm-epochs 30
    python benchmarks/stage1_surprise.py --data borealtc --lstm-epochs 0

``demo``: generated walks (22 channels at 100 Hz, terrain patches inside each walk, each walk a run of its own).
``borealtc``: the BorealTC runs joined end to end in a shuffled order, one log per terrain mix (a change where two runs
of different terrains meet). The score: the AUROC of each predictor's surprise, averaged over the last second (the
track the UI smooths), for telling the frames within 1 s of a terrain change from the others; a copy-the-last-frame
predictor's is the floor. Seconds are the fit's wall time on this machine, beside the time of computing the frames.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from sklearn.metrics import roc_auc_score

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

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

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "borealtc"
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", choices=["demo", "borealtc"], default="demo")
    parser.add_argument("--walks", type=int, default=6, help="demo: walks")
    parser.add_argument("--seconds", type=float, default=240.0, help="demo: seconds per walk")
    parser.add_argument("--logs", type=int, default=4, help="borealtc: logs the runs are joined into")
    parser.add_argument("--lstm-epochs", type=int, default=30, help="the paper predictor's epochs (0: not trained)")
    args = parser.parse_args()
    if args.data == "borealtc" and not DATA.is_dir():
        print(f"stage1_surprise: skipped: no BorealTC data at {DATA}")
        return
    arrays, changes = demo_logs(args.walks, args.seconds) if args.data == "demo" else borealtc_logs(DATA, args.logs)
    minutes = sum(len(a) for a in arrays) / RATE / 60
    print(
        f"{args.data}: {len(arrays)} logs, {minutes:.1f} min, {arrays[0].shape[1]} channels, "
        f"{sum(len(c) for c in changes)} terrain changes"
    )
    second = round(RATE / round(0.2 * RATE))  # frames per second

    t0 = time.monotonic()
    normalizer = Normalizer.fit(arrays)
    config = SpectralConfig.for_log(np.concatenate([a[: int(600 * RATE)] for a in arrays[:5]]), RATE)
    frames = [log_frames(a, config, transform=normalizer) for a in arrays]
    t_frames = time.monotonic() - t0
    t0 = time.monotonic()
    model, _ = fit_frame_predictor(frames)
    t_fit = time.monotonic() - t0
    ends = [frame_ends(len(a), config) for a in arrays]
    surprise = [trailing(frame_surprise(model, f)[0], second) for f in frames]
    copy = [trailing(copy_last_error(model, f), second) for f in frames]
    skip = 2 * second
    print(f"| predictor | AUROC for terrain changes (±{NEAR_S:.0f} s) | fit seconds | reference: frames computed |")
    print("| --- | --- | --- | --- |")
    print(f"| copy the last frame (floor) | {auroc(copy, ends, changes, skip):.3f} | – | |")
    score = auroc(surprise, ends, changes, skip)
    print(f"| frame predictor (default family) | {score:.3f} | {t_fit:.1f} | {t_frames:.1f} |")
    if args.lstm_epochs:
        t0 = time.monotonic()
        fit = fit_predictor(arrays, config=TrainConfig(max_epochs=args.lstm_epochs, patience=5), hidden=200)
        t_lstm = time.monotonic() - t0
        outs = run_predictor(fit.model, fit.normalizer, arrays)
        lstm = [trailing(o.surprise(), round(RATE))[e] for o, e in zip(outs, ends, strict=True)]  # at frame ends
        name = f"LSTM predictor (paper, {len(fit.history)} epochs, best {fit.best_epoch})"
        print(f"| {name} | {auroc(lstm, ends, changes, skip):.3f} | {t_lstm:.1f} | |")


if __name__ == "__main__":
    main()
