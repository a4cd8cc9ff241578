"""Issue 98, item 3's test-time adaptation, screened on stand-in D before building it into `classify` and the
streaming runtime: the bundle re-standardising its input to a new run's own first minutes (AdaBN's idea: the
statistics a network normalises with, taken from the data it now meets).

On D's split (`loop_dogsurf.py --seed S`: 7 session runs, 7 far runs, one floor per run), two bundles of the default
family: the session's first fit (its 10 % of labels in 5 s pieces) and the ceiling's (every step of the session's
runs labelled with its truth, `loop_ceiling.py`'s rule). Each scores the far runs as `classify` does, and then with
the far run's first ``--minutes`` adapted, in three ways:

- ``raw offset``: each channel's mean over those minutes moved to the session's (an IMU's bias, a mounting's tilt);
- ``raw offset+scale``: mean and spread both (also a gain);
- ``frames``: the network's own standardisation of each frame's spectral features (``WindowClassifier.in_mean`` and
  ``in_scale``) from those minutes' frames (AdaBN at the network's input).

Far runs, one floor each, are scored over their whole time (the minutes adapted on included, as a robot would).

    python benchmarks/studies/adaptation_screen.py --seed S [--minutes 2]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from loop_dogsurf import DATA, build  # noqa: E402

import labeling  # noqa: E402
from sessions import Session  # noqa: E402
from training import log_frames  # noqa: E402
from workbench.cycle import active_bundle, train_classifier, train_stage1  # noqa: E402
from workbench.evaluation import read_far_runs  # noqa: E402
from workbench.export import score_arrays  # noqa: E402

VARIANTS = ("as shipped", "raw offset", "raw offset+scale", "frames")


def adapted(bundle, samples: np.ndarray, variant: str, n: int) -> tuple[object, np.ndarray]:
    """The bundle and samples a variant scores a run with, adapted on its first ``n`` samples."""
    head = samples[:n].astype(np.float64)
    norm = bundle.normalizer
    if variant == "raw offset":
        return bundle, (samples - head.mean(0) + norm.mean).astype(np.float32)
    if variant == "raw offset+scale":
        std = np.where(head.std(0) > 1e-8, head.std(0), 1.0)
        return bundle, ((samples - head.mean(0)) / std * norm.std + norm.mean).astype(np.float32)
    if variant == "frames":
        frames = log_frames(samples[:n], bundle.spectral, transform=norm).astype(np.float64)  # (N, F)
        mean, std = frames.mean(0), frames.std(0)
        import copy

        members = [copy.deepcopy(c) for c in bundle.classifiers]
        for c in members:
            c.set_standardisation(mean, std)
        return replace(bundle, classifiers=members), samples
    return bundle, samples


def far_figures(bundle, far, minutes: float) -> dict[str, tuple[float, float, float, dict[str, float]]]:
    """Per variant: accuracy over every far step, balanced (the floors' recalls' mean), the mean per far run, and
    per run."""
    out = {}
    index = np.array([far.terrains.index(c) if c in far.terrains else -2 for c in bundle.classes])
    for variant in VARIANTS:
        right = total = 0
        per_run, trues, preds = {}, [], []
        for name, samples, truth in zip(far.names, far.arrays, far.truth, strict=True):
            b, x = adapted(bundle, samples, variant, round(minutes * 60 * bundle.rate_hz))
            (scored,) = score_arrays(b, [x])
            keep = truth >= 0
            pred = index[np.asarray(scored.probs).argmax(1)][keep]
            per_run[name] = float((pred == truth[keep]).mean())
            right += int((pred == truth[keep]).sum())
            total += int(keep.sum())
            trues.append(truth[keep])
            preds.append(pred)
        true, pred = np.concatenate(trues), np.concatenate(preds)
        balanced = float(np.mean([(pred[true == c] == c).mean() for c in np.unique(true)]))
        out[variant] = (right / total, balanced, float(np.mean(list(per_run.values()))), per_run)
    return out


def _short(name: str) -> str:
    """``External_data_38_600_seconds_ice`` -> ``38 ice``."""
    parts = name.split("_")
    return f"{parts[2]} {name.split('seconds_')[-1][:5]}" if len(parts) > 4 else name


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--minutes", type=float, default=2.0, help="the far run's first minutes the adaptation reads")
    opts = p.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (DogSurf is not shipped with the project)")
        return 0
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        folder, reference, far_files, options = build(Path(tmp) / "s", seed=opts.seed)
        with Session.open(folder) as s:
            train_stage1(s)
            rows = {}
            train_classifier(s, warm_start=False)
            start = active_bundle(s)[1]
            far = read_far_runs(far_files, reference, start, session_logs=[x.name for x in s.logs()], options=options)
            rows["first fit (10 % labelled)"] = far_figures(start, far, opts.minutes)
            for log in s.logs():  # the ceiling: the truth over every step nobody labelled
                covered = [(g.start, g.stop) for g in s.segments(log.id)]
                for a, b, terrain in s.reference(log.id):
                    for lo, hi in labeling.uncovered(a, b, covered):
                        s.add_segment(log.id, lo, hi, terrain, author="truth")
            train_classifier(s, warm_start=False)
            rows["ceiling (every step labelled)"] = far_figures(active_bundle(s)[1], far, opts.minutes)
    print(f"\nseed {opts.seed}: far runs scored by the bundle, adapted on each run's first {opts.minutes:g} min\n")
    print("| bundle | input | far runs, every step (%) | balanced (%) | mean per far run (%) | per far run (%) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for bundle_name, figures in rows.items():
        for variant, (acc, balanced, mean, per_run) in figures.items():
            runs = ", ".join(f"{_short(k)} {100 * v:.1f}" for k, v in per_run.items())
            print(f"| {bundle_name} | {variant} | {100 * acc:.1f} | {100 * balanced:.1f} | {100 * mean:.1f} | {runs} |")
    print(f"\n{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
