"""Settings of the default family screened on inner folds that hold out whole runs (BorealTC; the outer test runs are
never read): what keeps terrain and drops the run.

    python benchmarks/runs_screen.py --outer 2 --variants base gain=0.3 warp=0.1 detrend --out screen.jsonl

For each of the first ``--outer`` outer folds by run, the outer training runs are split into ``--inner`` folds by
run; a variant is fitted on 10 % of the inner training partitions (labels; the rest of them are unlabelled
stretches for self-training) and scored on every 1.7 s window (0.5 s stride) of the inner held-out runs. Each line
of ``--out`` is one (variant, inner fold): its accuracy, macro-F1 and calibration error; the summary prints each
variant's mean and its paired difference from the first variant.

A variant is ``base`` or ``+``-joined settings:
``gain=S``, ``tilt=S``, ``warp=S``, ``level=S``, ``drop=P``, ``mix=P`` (:class:`training.RowAugment`);
``wd=X``, ``noise=X``, ``epochs=N``, ``k=N`` (members) (the fit); ``seed=N`` (the noise floor: the same fit,
other initial weights and batches); ``detrend`` (the frames' level removed: gravity's direction and steady turns);
``nolevel`` (each slow channel taken from its partition's mean: the level that tells a run's speed is gone, the
change inside stays); ``newruns`` (the held-out runs are in the session unlabelled: self-training reads them, as a
session's Retrain does); ``runmembers`` (the ensemble's members hold out different labelled runs, not blocks).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from sklearn.model_selection import GroupKFold, StratifiedGroupKFold

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from training import (
    Normalizer,
    RowAugment,
    SpectralConfig,
    SpectralSteps,
    WindowFitConfig,
    classification_metrics,
    expected_calibration_error,
    fit_window_classifier,
    log_frames,
    run_classifiers,
)
from workbench.evaluation import labelled_subset, load_runs, outer_folds, partitions, window_inputs

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "borealtc"
RATE = 100.0
AUGMENTS = ("gain", "tilt", "warp", "level", "drop", "mix")
FITS = {
    "wd": ("weight_decay", float),
    "noise": ("noise", float),
    "epochs": ("epochs", int),
    "seed": ("seed", int),
    "k": ("k_folds", int),
}


def parse(variant: str) -> tuple[WindowFitConfig, dict]:
    """A variant's fit settings and its front-end / protocol switches."""
    fit = WindowFitConfig(held_out=False, calibrate=False)
    aug: dict[str, float] = {}
    switches = {"detrend": False, "nolevel": False, "newruns": False, "runmembers": False}
    for part in variant.split("+"):
        if part == "base":
            continue
        if part in switches:
            switches[part] = True
            continue
        key, _, value = part.partition("=")
        if key in AUGMENTS:
            aug[key] = float(value)
        elif key in FITS:
            name, kind = FITS[key]
            fit = replace(fit, **{name: kind(value)})
        else:
            raise SystemExit(f"runs_screen: unknown setting {part!r} in variant {variant!r}")
    return replace(fit, augment=RowAugment(**aug)), switches


def without_level(config: SpectralConfig, parts: list[np.ndarray]) -> tuple[SpectralConfig, list[np.ndarray]]:
    """The slow channels' levels left out: each slow channel becomes its deviation from its own partition's mean,
    so the frames' mean, minimum and maximum carry the change inside a partition only (the spread is unchanged)."""
    slow = list(config.slow)
    out = []
    for p in parts:
        q = p.copy()
        q[:, slow] -= q[:, slow].mean(axis=0)
        out.append(q)
    return config, out


def members_by_run(feats, segments, classes, fit, stretches, runs) -> tuple[list, float]:
    """An ensemble whose members hold out different runs (the labelled runs dealt to ``fit.k_folds`` groups), not
    blocks of every run: each member is a one-fold fit on the others' labels, self-training as usual."""
    run = np.asarray([runs[s[0]] for s in segments])
    folds = GroupKFold(fit.k_folds).split(run, groups=run)
    models, pseudo = [], []
    for m, (keep, _) in enumerate(folds):
        one = fit_window_classifier(
            feats,
            [segments[i] for i in keep],
            classes,
            config=replace(fit, k_folds=1, seed=fit.seed + m),
            stretches=stretches,
        )
        models += one.models
        pseudo.append(one.metrics["pseudo_stretches"])
    return models, float(np.mean(pseudo))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--outer", type=int, default=2, help="outer folds by run whose training runs are screened")
    parser.add_argument("--inner", type=int, default=3)
    parser.add_argument("--labelled", type=float, default=0.1)
    parser.add_argument("--variants", nargs="+", default=["base"])
    parser.add_argument("--out", type=Path, default=None, help="JSON lines, appended: one per variant and fold")
    parser.add_argument("--resume", action="store_true", help="skip the (variant, fold) rows --out already holds")
    parser.add_argument("--data", type=Path, default=DATA)
    args = parser.parse_args()
    if not args.data.is_dir():
        print(f"runs_screen: skipped: no BorealTC data at {args.data}")
        return
    specs = {v: parse(v) for v in args.variants}
    runs, terrains, _ = load_runs(args.data)
    classes = sorted(set(terrains))
    labels = [classes.index(t) for t in terrains]
    size, win, stride = round(5 * RATE), round(1.7 * RATE), round(0.5 * RATE)
    parts, y, run_of = partitions(runs, labels, size)
    rows: dict[str, list[dict]] = {v: [] for v in args.variants}
    done = {}
    if args.resume and args.out and args.out.exists():
        for line in args.out.read_text().splitlines():
            r = json.loads(line)
            done[(r["variant"], r["outer"], r["inner"])] = r
    for outer, (train_idx, _) in enumerate(outer_folds(y, run_of, split="runs", folds=5, seed=0)[: args.outer], 1):
        inner = StratifiedGroupKFold(args.inner, shuffle=True, random_state=outer)
        for k, (tr, va) in enumerate(inner.split(train_idx, y[train_idx], run_of[train_idx]), 1):
            tr_idx, va_idx = train_idx[tr], train_idx[va]
            chosen = set(labelled_subset(tr_idx, y, args.labelled, seed=outer * 10 + k).tolist())
            for variant, (fit, sw) in specs.items():
                if (variant, outer, k) in done:
                    rows[variant].append(done[(variant, outer, k)])
                    continue
                t0 = time.monotonic()
                own = [parts[i] for i in tr_idx]
                held = [parts[i] for i in va_idx]
                normalizer = Normalizer.fit(own)
                config = SpectralConfig.for_log(np.concatenate(own[:50]), RATE, detrend=sw["detrend"])
                if sw["nolevel"]:
                    config, own = without_level(config, own)
                    _, held = without_level(config, held)
                session = own + held if sw["newruns"] else own
                feats = [SpectralSteps(log_frames(p, config, transform=normalizer), len(p), config) for p in session]
                first = config.span - 1
                segments = [(j, first, size, int(y[i])) for j, i in enumerate(tr_idx) if i in chosen]
                unlabelled = [j for j in range(len(session)) if j >= len(tr_idx) or tr_idx[j] not in chosen]
                stretches = [(j, first, size) for j in unlabelled]
                if sw["runmembers"]:
                    models, pseudo = members_by_run(feats, segments, classes, fit, stretches, run_of[tr_idx])
                else:
                    cfit = fit_window_classifier(feats, segments, classes, config=fit, stretches=stretches)
                    models, pseudo = cfit.models, cfit.metrics["pseudo_stretches"]
                x, owner = window_inputs(held, win, stride, config, normalizer)
                probs = run_classifiers(models, [x])[0].mean(0)  # (N, K)
                truth = y[va_idx][owner]
                m = classification_metrics(truth, probs.argmax(1), classes)
                row = {
                    "variant": variant,
                    "outer": outer,
                    "inner": k,
                    "accuracy": m["accuracy"],
                    "macro_f1": m["macro_f1"],
                    "ece": expected_calibration_error(probs, truth),
                    "windows": len(x),
                    "pseudo": pseudo,
                    "seconds": round(time.monotonic() - t0, 1),
                }
                rows[variant].append(row)
                print(json.dumps(row), flush=True)
                if args.out:
                    with args.out.open("a") as f:
                        f.write(json.dumps(row) + "\n")
    base = args.variants[0]
    print(f"\n| variant | mean accuracy over {len(rows[base])} inner folds | paired difference from {base} |")
    print("| --- | --- | --- |")
    for variant, rs in rows.items():
        acc = np.asarray([r["accuracy"] for r in rs])
        diff = acc - np.asarray([r["accuracy"] for r in rows[base]])
        print(f"| {variant} | {acc.mean():.2%} | {diff.mean():+.2%} (min {diff.min():+.2%}, max {diff.max():+.2%}) |")


if __name__ == "__main__":
    main()
