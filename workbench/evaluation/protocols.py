"""``workbench evaluate``: the model against published tables, on data read with the session's own readers."""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from sessions import IngestError, IngestOptions, WorkbenchError, align, new_file, plan_sources, read_source
from training import FEATURE_MODES, FeatureMode, TrainConfig

from .evaluate_windows import FoldResult, borealtc_protocol

BOREALTC_PUBLISHED = {"CNN (spectrograms)": 93.96, "Mamba": 93.51, "LSTM": 82.47, "SVM": 78.04}


@dataclass(frozen=True)
class Recording:
    """A recording read for evaluation: its aligned samples and reference truth."""

    name: str
    data: np.ndarray  # (T, C)
    terrain: str  # the file's terrain, or the most common one of its truth
    truth: tuple[tuple[int, int, str], ...]  # (start, stop, terrain) in samples


def load_recordings(folder: Path) -> tuple[list[Recording], list[str]]:
    """Every recording under ``folder`` with reference truth, aligned, on the most common channel set.

    Returns:
        The recordings and notes on what was left out.
    """
    sources, errors = plan_sources([folder])
    loaded, notes = [], [f"refused: {e}" for e in errors]
    for src in sources:
        try:
            parsed, _ = read_source(src, IngestOptions())
            for p in parsed:
                a = align(p, IngestOptions())
                truth = a.reference
                if not truth and p.reference_terrain:  # one terrain for the whole file (QCAT, BorealTC)
                    truth = ((0, len(a.data), p.reference_terrain),)
                if not truth:
                    notes.append(f"left out {p.name}: no reference truth")
                    continue
                main = Counter({t: b - s for s, b, t in truth}).most_common(1)[0][0]
                loaded.append((tuple(c.name for c in a.channels), Recording(p.name, a.data, main, tuple(truth))))
        except IngestError as exc:
            notes.append(f"refused: {exc}")
    if not loaded:
        raise WorkbenchError(f"{folder}: no recordings with reference truth found")
    channels = Counter(c for c, _ in loaded).most_common(1)[0][0]
    keep = [r for c, r in loaded if c == channels]
    if len(keep) < len(loaded):
        notes.append(f"left out {len(loaded) - len(keep)} recording(s) without the channels {', '.join(channels)}")
    return keep, notes


def load_runs(folder: Path) -> tuple[list[np.ndarray], list[str], list[str]]:
    """Arrays, their terrains and notes (see :func:`load_recordings`)."""
    recs, notes = load_recordings(folder)
    return [r.data for r in recs], [r.terrain for r in recs], notes


def truth_arrays(recs: list[Recording], classes: list[str]) -> list[np.ndarray]:
    """Per recording, ``(T,)`` class index of each sample (``-1`` where the truth says nothing)."""
    out = []
    for r in recs:
        y = np.full(len(r.data), -1)
        for a, b, t in r.truth:
            y[a:b] = classes.index(t)
        out.append(y)
    return out


def summarize(results: list[FoldResult]) -> tuple[float, float, float, float]:
    acc = np.array([r.accuracy for r in results]) * 100
    f1 = np.array([r.macro_f1 for r in results])
    return float(acc.mean()), float(acc.std()), float(f1.mean()), float(f1.std())


def evaluate_borealtc(
    folder: Path,
    *,
    model: Literal["default", "paper", "both"] = "default",
    labelled: float = 0.1,
    split: Literal["partitions", "runs", "both"] = "both",
    variant: Literal["both", "shared", "strict"] = "shared",
    hidden: int = 200,
    seed: int = 0,
    stage1_epochs: int = 40,
    stage2_epochs: int = 150,
    out: Path | None = None,
    device: str = "cpu",
) -> str:
    """Run the BorealTC protocols and return the report (Markdown).

    Args:
        folder: The BorealTC folder.
        model: Which family (or both).
        labelled: Share of each fold's training partitions labelled.
        split: The authors' partition folds, folds holding out whole runs, or both.
        variant: Paper family: stage 1 on all partitions' signals ("shared"), or never on the test partitions.
        hidden: Paper family: LSTM width of both stages.
        seed: Seed of the folds, the labelled subset and training.
        stage1_epochs: Paper family: most epochs of stage 1.
        stage2_epochs: Paper family: most epochs of stage 2.
        out: Also write per-fold details as JSON here.
        device: Where both families train and score.
    """
    from training import WindowFitConfig

    from .evaluate_spectral import borealtc_window_protocol

    runs, terrains, notes = load_runs(folder)
    classes = sorted(set(terrains))
    labels = [classes.index(t) for t in terrains]
    for n in notes:
        print(n)
    print(f"{len(runs)} runs, {sum(len(r) for r in runs) / 100 / 60:.1f} min, classes: {', '.join(classes)}")
    splits = ["partitions", "runs"] if split == "both" else [split]
    families = ["default", "paper"] if model == "both" else [model]
    variants = ["shared", "strict"] if variant == "both" else [variant]
    where = {"partitions": "authors' partition folds", "runs": "unseen runs (folds by run)"}
    rows, detail = [], {}
    for family, sp in ((f, sp) for f in families for sp in splits):
        if family == "default":
            print(f"--- default family, {where[sp]}")
            res = borealtc_window_protocol(
                runs,
                labels,
                classes,
                rate_hz=100.0,
                labelled=labelled,
                split=sp,
                fit=WindowFitConfig(),
                seed=seed,
                device=device,
            )
            rows.append((f"default family, {where[sp]}", res))
            detail[f"default/{sp}"] = [vars(r) for r in res]
            continue
        for v in variants:
            print(f"--- paper family, {where[sp]}, stage 1 " + ("strict" if v == "strict" else "on all signals"))
            res = borealtc_protocol(
                runs,
                labels,
                classes,
                rate_hz=100.0,
                labelled=labelled,
                strict=v == "strict",
                split=sp,
                hidden=hidden,
                seed=seed,
                stage1=TrainConfig(max_epochs=stage1_epochs, patience=5, seed=seed, device=device),
                stage2=TrainConfig(max_epochs=stage2_epochs, patience=15, seed=seed, device=device),
            )
            stage1 = "stage 1 strict" if v == "strict" else "stage 1 on all signals"
            rows.append((f"paper family, {where[sp]}, {stage1}", res))
            detail[f"paper/{sp}/{v}"] = [vars(r) for r in res]
    lines = ["| method | labels | accuracy (%) | macro-F1 |", "| --- | --- | --- | --- |"]
    for name, res in rows:
        a, a_sd, f, f_sd = summarize(res)
        lines.append(f"| {name} | {labelled:.0%} | {a:.2f} ± {a_sd:.2f} | {f:.3f} ± {f_sd:.3f} |")
    for name, acc in BOREALTC_PUBLISHED.items():
        lines.append(f"| {name} (published, authors' folds) | 100% of training partitions | {acc:.2f} | |")
    per_fold = [
        "",
        "| method | fold | accuracy (%) | macro-F1 | test windows | labelled partitions | s |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name, res in rows:
        per_fold += [
            f"| {name} | {r.fold} | {r.accuracy * 100:.2f} | {r.macro_f1:.3f} | {r.windows} | "
            f"{r.labelled_partitions} | {r.seconds:.0f} |"
            for r in res
        ]
    report = "\n".join(lines + per_fold + _calibration_rows(rows))
    if out is not None:
        with new_file(out) as tmp:
            tmp.write_text(json.dumps(detail, indent=1, default=str))
    return report


def _calibration_rows(rows: list[tuple[str, list[FoldResult]]]) -> list[str]:
    """Per fold of the default family: calibration error and temperature, and what the drift score said of the test
    windows (the share above 1, accuracy on either side, AUROC of drift for telling errors)."""
    out = [
        "",
        "| method | fold | calibration error | temperature | drifted windows | accuracy drifted / not | AUROC of drift "
        "for errors |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name, res in rows:
        for r in res:
            m = r.metrics
            if "drifted_share" not in m:
                continue
            out.append(
                f"| {name} | {r.fold} | {m['calibration_error']:.3f} | {m['temperature']:.2f} | "
                f"{m['drifted_share']:.1%} | {m['accuracy_drifted']:.1%} / {m['accuracy_not_drifted']:.1%} | "
                f"{m['drift_error_auroc']:.2f} |"
            )
    return out if len(out) > 3 else []


def _table(rows: list[tuple[str, list[dict]]], extra: list[str] | None = None) -> str:
    lines = ["| method | accuracy (%) | macro-F1 | folds |", "| --- | --- | --- | --- |"]
    for name, res in rows:
        acc = np.array([r["accuracy"] for r in res]) * 100
        f1 = np.array([r["macro_f1"] for r in res])
        lines.append(f"| {name} | {acc.mean():.2f} ± {acc.std():.2f} | {f1.mean():.3f} ± {f1.std():.3f} | {len(res)} |")
    return "\n".join(lines + (extra or []))


def evaluate_qcat(
    folder: Path,
    *,
    hidden: int = 200,
    seed: int = 0,
    steps: int = 8,
    folds: int = 5,
    epochs: tuple[int, int] = (60, 150),
    device: str = "cpu",
) -> str:
    """The paper's QCAT protocol, and a leak-free variant holding out whole trials."""
    from .evaluate_sequences import qcat_protocol

    recs, notes = load_recordings(folder)
    for n in notes:
        print(n)
    classes = sorted({r.terrain for r in recs})
    seqs, labels, groups = [], [], []
    for g, r in enumerate(recs):  # one recording per trial; each trial is cut into its steps, as QCAT's users do
        size = len(r.data) // steps
        for k in range(steps):
            seqs.append(r.data[k * size : (k + 1) * size])
            labels.append(classes.index(r.terrain))
            groups.append(g)
    print(f"{len(recs)} trials, {len(seqs)} step sequences, classes: {', '.join(classes)}")
    rows = []
    for leak_free in (False, True):
        print("--- " + ("whole trials held out" if leak_free else "the paper's random split of sequences"))
        res = qcat_protocol(
            seqs,
            labels,
            groups,
            classes,
            leak_free=leak_free,
            folds=folds,
            hidden=hidden,
            seed=seed,
            stage1=TrainConfig(max_epochs=epochs[0], patience=8, seed=seed, device=device),
            stage2=TrainConfig(max_epochs=epochs[1], patience=15, seed=seed, device=device),
        )
        rows.append(
            (
                "this work, trials held out"
                if leak_free
                else "this work, paper's split (steps of a trial on both sides)",
                res,
            )
        )
    return _table(rows, ["| paper: proposed method (published) | 89.04 | | |", "| paper: TCN (published) | 87.5 | | |"])


def evaluate_demo(
    folder: Path,
    *,
    labelled: float = 0.05,
    hidden: int = 200,
    seed: int = 0,
    folds: int = 5,
    epochs: tuple[int, int] = (40, 150),
    modes: tuple[str, ...] = FEATURE_MODES,
    device: str = "cpu",
) -> str:
    """Leave-logs-out on demo logs against their sidecar truth, for each way stage 1 can feed stage 2."""
    from .evaluate_sequences import held_out_logs_protocol

    recs, notes = load_recordings(folder)
    for n in notes:
        print(n)
    classes = sorted({t for r in recs for _, _, t in r.truth})
    truth = truth_arrays(recs, classes)
    print(f"{len(recs)} logs, {sum(len(r.data) for r in recs) / 6000:.1f} min, {labelled:.0%} labelled")
    res = held_out_logs_protocol(
        [r.data for r in recs],
        truth,
        classes,
        labelled=labelled,
        modes=modes,
        hidden=hidden,
        seed=seed,
        folds=folds,
        stage1=TrainConfig(max_epochs=epochs[0], patience=5, seed=seed, device=device),
        stage2=TrainConfig(max_epochs=epochs[1], patience=15, seed=seed, device=device),
    )
    return _table([(f"stage 2 on `{m}` features, {labelled:.0%} labels", r) for m, r in res.items()])


def simulate(
    dataset: str,
    folder: Path,
    *,
    strategies: tuple[str, ...],
    seeds: int,
    rounds: int,
    batch: int,
    out: Path | None,
    model: str = "default",
    feature_mode: FeatureMode = "hidden+surprise",
    warm_start: bool = False,
    segment_s: float | None = None,
    members: int = 3,
    stage1: str = "own",
    device: str = "cpu",
    split: str = "partitions",
) -> str:
    """The label-efficiency simulation on ``folder`` (see :mod:`workbench.evaluation.label_efficiency`); BorealTC's
    folds over partitions or (``split="runs"``) holding out whole runs."""
    from labeling import STRATEGIES

    from .label_efficiency import SimSettings, simulate_logs, simulate_partitions

    unknown = [s for s in strategies if s not in STRATEGIES]
    if unknown:
        raise WorkbenchError(f"unknown strategy {', '.join(unknown)}; choose from {', '.join(STRATEGIES)}")
    if model not in ("default", "paper"):
        raise WorkbenchError(f"--simulate runs one family at a time: --model default or --model paper, not {model}")
    settings = SimSettings(
        strategies=tuple(strategies),
        model=model,
        seeds=seeds,
        rounds=rounds,
        batch=batch,
        feature_mode=feature_mode,
        warm_start=warm_start,
        segment_s=segment_s,
        folds=members,
        stage1=stage1,
        device=device,
        split="runs" if split == "runs" else "partitions",
    )
    recs, notes = load_recordings(folder)
    for n in notes:
        print(n)
    if dataset == "borealtc":
        classes = sorted({r.terrain for r in recs})
        labels = [classes.index(r.terrain) for r in recs]
        return simulate_partitions([r.data for r in recs], labels, classes, settings=settings, out=out)
    if dataset == "demo":
        classes = sorted({t for r in recs for _, _, t in r.truth})
        return simulate_logs([r.data for r in recs], truth_arrays(recs, classes), classes, settings=settings, out=out)
    raise WorkbenchError(f"--simulate runs on borealtc or demo data, not {dataset}")
