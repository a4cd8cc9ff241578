"""What the studies share: BorealTC's runs as the issue-54 studies read them (whole, or one outer fold's training
runs for inner folds), labelling runs as a person did before the loop and the loop's options (issue 65), and what
``workbench classify`` predicted per step of demo walks."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from sessions import LogInfo, Session

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data" / "borealtc"
PIECE_S, FRACTION = 5.0, 0.10


def label_runs(session, logs, *, seed: int) -> None:
    """10 % of each run's time in 5 s pieces inside its reference, drawn with ``seed``."""
    rng = np.random.default_rng(seed)
    for x in logs:
        n = round(PIECE_S * x.rate_hz)
        ref = session.reference(x.id)
        starts = [a for a0, b, _ in ref for a in range(a0, b - n + 1, n)]
        want = max(1, round(FRACTION * x.n_samples / n))
        for a in rng.permutation(starts)[:want]:
            terrain = next(t for r0, r1, t in ref if r0 <= a < r1)
            session.add_segment(x.id, int(a), int(a) + n, terrain, author="benchmark", source="seed")


def loop_arguments(description: str) -> argparse.ArgumentParser:
    """The options every loop benchmark takes: ``--seed``, ``--rounds``, ``--per-round``, ``--person``,
    ``--strategies``, ``--verify``, ``--out``."""
    args = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("--seed", type=int, default=0)
    args.add_argument("--rounds", type=int, default=4)
    args.add_argument("--per-round", type=int, default=12)
    args.add_argument("--person", default="piece", choices=["piece", "stretch"])
    args.add_argument("--strategies", nargs="+", default=["combined", "random"])
    args.add_argument("--verify", type=int, default=0, help="verification checks after the last round")
    args.add_argument("--out", type=Path, default=None, help="also write every round's figures as JSON here")
    return args


def loop_settings(opts: argparse.Namespace):
    """The ``workbench.evaluation.LoopSettings`` of the parsed options."""
    from workbench.evaluation import LoopSettings

    return LoopSettings(
        rounds=opts.rounds,
        per_round=opts.per_round,
        person=opts.person,
        strategies=tuple(opts.strategies),
        seed=opts.seed,
        verify=opts.verify,
    )


RATE_HZ = 100.0
BALANCES = ("none", "weights", "sampling", "logits")


def borealtc_arguments(description: str) -> argparse.ArgumentParser:
    """The options every issue-54 benchmark takes: ``--seed``, ``--inner F``, ``--balance``."""
    args = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("--seed", type=int, default=0)
    args.add_argument("--inner", type=int, default=0, help="screen on outer fold F's training runs (1-5; 0: off)")
    args.add_argument("--balance", default=None, choices=BALANCES, help="default: WindowFitConfig's")
    return args


def borealtc_runs(opts: argparse.Namespace) -> tuple[list[np.ndarray], list[int], list[str], object] | None:
    """The runs (``opts.inner``: an outer fold's training runs), their terrain indices, the terrain names and the
    fit's settings (``opts.balance``); ``None`` (with a line saying why) without the data."""
    inner, seed = opts.inner, opts.seed
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return None
    sys.path.insert(0, str(ROOT))
    from training import WindowFitConfig
    from workbench.evaluation import load_runs, outer_folds, partitions

    runs, terrains, _ = load_runs(DATA)
    classes = sorted(set(terrains))
    labels = [classes.index(t) for t in terrains]
    if inner:  # the outer fold's training runs only, as the protocol cuts and splits them
        _, y, run_of = partitions(runs, labels, round(5 * RATE_HZ))
        train_idx, _ = outer_folds(y, run_of, split="runs", folds=5, seed=seed)[inner - 1]
        kept = sorted(set(run_of[train_idx].tolist()))
        runs, labels = [runs[r] for r in kept], [labels[r] for r in kept]
        print(f"inner folds of outer fold {inner}: {len(kept)} training runs", flush=True)
    fit = WindowFitConfig() if opts.balance is None else WindowFitConfig(balance=opts.balance)
    return runs, labels, classes, fit


def classified_walks(session: Session, predictions: Path) -> list[tuple[LogInfo, np.ndarray, np.ndarray]]:
    """Per log of ``session``, the terrain ``workbench classify`` predicted at each step (its CSV ``predictions``,
    column order) and the truth ``(T,)`` in the same indices: -1 where the reference says nothing, -2 for a terrain
    the model does not know (never right)."""
    import pandas as pd

    pred = pd.read_csv(predictions)
    classes = [c[2:] for c in pred.columns if c.startswith("p_")]
    out = []
    for log in session.logs():
        rows = pred[pred["log"] == log.name]
        predicted = rows[[f"p_{c}" for c in classes]].to_numpy().argmax(1)  # (T,)
        truth = np.full(log.n_samples, -1)
        for a, b, t in session.reference(log.id):
            truth[a:b] = classes.index(t) if t in classes else -2
        out.append((log, predicted, truth))
    return out
