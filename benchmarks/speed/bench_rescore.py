"""Rescoring every log after a retrain, at QCAT scale: 2,880 sequences of 100–660 samples × 22 channels (≈ 1 M steps).

After a stage-2 retrain only stage 2 reruns (stage-1 features are cached); after a stage-1 change both stages do.
Reference beside each: a bare ``torch.nn.LSTM`` forward of the same layers over the same padded batches (the same
timesteps and FLOPs), with nothing around it. Signals are slices of demo walks; weights are untrained (speed does not
depend on them), so the accuracy column compares the timed path's argmax with the unoptimised path's (one sequence
at a time, float32) instead of with a truth.
"""

from __future__ import annotations

import time

import numpy as np
import torch
from speed_common import Row, fmt_s, parse_args, qcat_like, record

from training import (
    Classifier,
    ClassifierConfig,
    Normalizer,
    Predictor,
    PredictorConfig,
    padded_groups,
    run_classifiers,
    run_predictor,
)

HIDDEN, MEMBERS, K = 200, 5, 6


def bare_forward(lstms: list[torch.nn.LSTM], arrays: list[np.ndarray], batch: int) -> float:
    """Seconds for the bare layers over the same padded batches as the timed path."""
    t = time.perf_counter()
    with torch.inference_mode():
        for group in padded_groups([len(a) for a in arrays], batch):
            n = max(len(arrays[i]) for i in group)
            x = torch.zeros(len(group), n, arrays[group[0]].shape[1])
            for j, i in enumerate(group):
                x[j, : len(arrays[i])] = torch.from_numpy(arrays[i])
            for lstm in lstms:
                lstm(x)
    return time.perf_counter() - t


def main() -> None:
    args = parse_args(__doc__)
    torch.manual_seed(0)
    n_seq = 288 if args.quick else 2880
    logs = qcat_like(n_seq)
    steps = sum(len(x) for x in logs)
    predictor = Predictor(PredictorConfig(22, HIDDEN)).eval()
    members = [Classifier(ClassifierConfig(HIDDEN, K, HIDDEN)).eval() for _ in range(MEMBERS)]
    norm = Normalizer.fit(logs)
    dev = args.device
    print(f"{n_seq} sequences, {steps:,} timesteps, {torch.get_num_threads()} threads, {dev}")

    t = time.perf_counter()
    feats = [o.features("hidden") for o in run_predictor(predictor, norm, logs, device=dev)]
    t_stage1 = time.perf_counter() - t
    t = time.perf_counter()
    probs = run_classifiers(members, feats, device=dev)
    t_stage2 = time.perf_counter() - t

    bare1 = bare_forward([predictor.lstm.to(dev)], [norm(x) for x in logs], 64)
    bare2 = bare_forward([m.lstm.to(dev) for m in members], feats, 64)

    # unoptimised path on a sample: one sequence at a time
    sample = np.random.default_rng(1).choice(n_seq, 50, replace=False)
    ref = [run_classifiers(members, [feats[i]], batch=1)[0].mean(0).argmax(-1) for i in sample]
    got = [probs[i].mean(0).argmax(-1) for i in sample]
    agree = float(np.mean(np.concatenate([a == b for a, b in zip(got, ref, strict=True)])))
    acc = f"argmax = one-at-a-time pass on {agree:.2%} of {sum(len(r) for r in ref):,} steps"

    rows = []
    for name, t_ours, t_bare, target_s in (
        ("all logs rescored after a stage-2 retrain (stage 2 on cached features)", t_stage2, bare2, 60.0),
        ("all logs rescored after a stage-1 change (both stages)", t_stage1 + t_stage2, bare1 + bare2, 60.0),
    ):
        ratio = t_bare / t_ours  # our timesteps/s over the bare forward's
        rows.append(
            Row(
                f"{name}, {steps / 1e6:.2f} M steps",
                f"{fmt_s(t_ours)} ({steps / t_ours:,.0f} steps/s)",
                f"bare nn.LSTM forward: {fmt_s(t_bare)} ({steps / t_bare:,.0f} steps/s)",
                f"{ratio:.2f}× the bare forward's steps/s",
                f"≤ {target_s:.0f} s; ≥ 0.8×",
                bool(t_ours <= target_s and ratio >= 0.8) if not args.quick else None,
                acc,
            )
        )
    record("rescore", rows, device=dev)


if __name__ == "__main__":
    main()
