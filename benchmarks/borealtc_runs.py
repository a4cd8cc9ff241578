"""BorealTC's runs for the issue-54 benchmarks, whole or (``--inner F``) only outer fold F's training runs: the
protocol then splits those into 5 inner folds by run, and F's test runs are never read, as settings are chosen."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "borealtc"
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
