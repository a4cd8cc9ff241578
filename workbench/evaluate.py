"""``workbench evaluate``: the model against published tables, on data read with the session's own readers."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Literal

import numpy as np

from sessions import IngestError, IngestOptions, WorkbenchError
from sessions.ingest import align, plan_sources, read_source
from training.config import TrainConfig
from training.evaluate import FoldResult, borealtc_protocol

BOREALTC_PUBLISHED = {"CNN (spectrograms)": 93.96, "Mamba": 93.51, "LSTM": 82.47, "SVM": 78.04}


def load_runs(folder: Path) -> tuple[list[np.ndarray], list[str], list[str]]:
    """Every recording under ``folder`` with its reference terrain, aligned, on the most common channel set.

    Returns:
        Arrays, their terrains, and notes on what was left out.
    """
    sources, errors = plan_sources([folder])
    loaded, notes = [], [f"refused: {e}" for e in errors]
    for src in sources:
        try:
            parsed, _ = read_source(src, IngestOptions())
            for p in parsed:
                a = align(p, IngestOptions())
                loaded.append((tuple(c.name for c in a.channels), a.data, p.reference_terrain or "?"))
        except IngestError as exc:
            notes.append(f"refused: {exc}")
    if not loaded:
        raise WorkbenchError(f"{folder}: no recordings found")
    channels = Counter(c for c, _, _ in loaded).most_common(1)[0][0]
    keep = [(d, t) for c, d, t in loaded if c == channels]
    if len(keep) < len(loaded):
        notes.append(f"left out {len(loaded) - len(keep)} recording(s) without the channels {', '.join(channels)}")
    return [d for d, _ in keep], [t for _, t in keep], notes


def summarize(results: list[FoldResult]) -> tuple[float, float, float, float]:
    acc = np.array([r.accuracy for r in results]) * 100
    f1 = np.array([r.macro_f1 for r in results])
    return float(acc.mean()), float(acc.std()), float(f1.mean()), float(f1.std())


def evaluate_borealtc(
    folder: Path,
    *,
    labelled: float = 0.1,
    variant: Literal["both", "shared", "strict"] = "both",
    hidden: int = 200,
    seed: int = 0,
    stage1_epochs: int = 40,
    stage2_epochs: int = 150,
    out: Path | None = None,
) -> str:
    """Run the BorealTC protocol and return the report (Markdown)."""
    runs, terrains, notes = load_runs(folder)
    classes = sorted(set(terrains))
    labels = [classes.index(t) for t in terrains]
    for n in notes:
        print(n)
    print(f"{len(runs)} runs, {sum(len(r) for r in runs) / 100 / 60:.1f} min, classes: {', '.join(classes)}")
    variants = ["shared", "strict"] if variant == "both" else [variant]
    rows, detail = [], {}
    for v in variants:
        print(
            f"--- stage 1 {'never sees test partitions' if v == 'strict' else 'trained on all partitions (no labels)'}"
        )
        res = borealtc_protocol(
            runs, labels, classes, rate_hz=100.0, labelled=labelled, strict=v == "strict", hidden=hidden, seed=seed,
            stage1=TrainConfig(max_epochs=stage1_epochs, patience=5, seed=seed),
            stage2=TrainConfig(max_epochs=stage2_epochs, patience=15, seed=seed),
        )  # fmt: skip
        a, a_sd, f, f_sd = summarize(res)
        name = f"this work, {labelled:.0%} labels, stage 1 " + ("strict" if v == "strict" else "on all signals")
        rows.append((name, a, a_sd, f, f_sd, res))
        detail[v] = [vars(r) for r in res]
    lines = ["| method | labels | accuracy (%) | macro-F1 |", "| --- | --- | --- | --- |"]
    for name, a, a_sd, f, f_sd, _ in rows:
        lines.append(f"| {name} | {labelled:.0%} | {a:.2f} ± {a_sd:.2f} | {f:.3f} ± {f_sd:.3f} |")
    for name, acc in BOREALTC_PUBLISHED.items():
        lines.append(f"| {name} (published) | 100% of training partitions | {acc:.2f} | |")
    per_fold = ["", "| variant | fold | accuracy (%) | macro-F1 | test windows | labelled partitions | s |",
                "| --- | --- | --- | --- | --- | --- | --- |"]  # fmt: skip
    for name, *_, res in rows:
        per_fold += [f"| {name} | {r.fold} | {r.accuracy * 100:.2f} | {r.macro_f1:.3f} | {r.windows} | "
                     f"{r.labelled_partitions} | {r.seconds:.0f} |" for r in res]  # fmt: skip
    report = "\n".join(lines + per_fold)
    if out is not None:
        out.write_text(json.dumps(detail, indent=1, default=str))
    return report
