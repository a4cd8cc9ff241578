"""Kept: the network over the frames with self-training (``cnn_st``) became the default family's stage 2: 86.83 /
84.92 / 86.80 % on the inner folds of outer folds 1-3 against 80.87 / 79.42 / 84.60 for the linear model on window
summaries (benchmarks/results/raw/protocols/notebook-default-family-screens-2026-11-28.md).

A second idea for the default family's stage 2, screened on BorealTC's inner folds only (the outer test folds are
never read): a small convolutional network over the window's spectral frames, as BorealTC's CNN reads
spectrograms, with and without a self-supervised encoder learnt from every training partition (contrastive over
time: two windows of one partition are a pair, other partitions in the batch are negatives).

    python benchmarks/studies/default_family_cnn.py --outer 2 --variants lr cnn cnn_st ssl_ft ssl_lr

Variants: ``lr`` (the shipped stage 2: logistic regression on window summaries, one round of self-training),
``cnn`` (the network on the labelled windows only), ``cnn_st`` (``cnn`` plus one round of self-training over
partitions whose windows agree at 90 %), ``ssl_ft`` (the contrastive encoder, then the network fine-tuned on the
labelled windows), ``ssl_lr`` (the frozen contrastive embedding beside the summaries, then ``lr``), ``mlp`` and
``mlp_st`` (one hidden layer on the summaries), ``cnn_st2`` (two rounds of self-training), ``cnn_st_aNN``
(agreement at NN % instead of 90).
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import GroupKFold, StratifiedGroupKFold
from torch import nn
from torch.nn import functional as F

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from training import Normalizer, SpectralConfig, frame_features, log_frames, summary_windows
from workbench.evaluation import labelled_subset, load_runs, outer_folds, partitions

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "borealtc"
AGREE = 0.9
C_GRID = (0.01, 0.1, 1.0, 10.0)


def linear_self_trained(
    rows: dict[int, np.ndarray], labelled: np.ndarray, unlabelled: np.ndarray, y: np.ndarray
) -> Callable[[np.ndarray], np.ndarray]:
    """The previous default's stage 2 over window summaries ``(N, 2F)``: a logistic regression (``C`` chosen on
    grouped folds of the labelled partitions), then one round of self-training on the unlabelled partitions whose
    windows agree at ``AGREE``."""

    def lr(x: np.ndarray, yy: np.ndarray, c: float) -> LogisticRegression:
        return LogisticRegression(C=c, max_iter=1000).fit(x, yy)

    x = np.concatenate([rows[i] for i in labelled])
    yy = np.concatenate([np.full(len(rows[i]), y[i]) for i in labelled])
    groups = np.concatenate([np.full(len(rows[i]), k) for k, i in enumerate(labelled)])
    folds = list(GroupKFold(3).split(x, yy, groups))
    c = max(C_GRID, key=lambda c: sum((lr(x[tr], yy[tr], c).predict(x[va]) == yy[va]).sum() for tr, va in folds))
    model = lr(x, yy, c)
    picked = []
    for i in unlabelled:
        votes = np.bincount(model.predict(rows[i]), minlength=len(np.unique(y)))
        if votes.max() >= AGREE * len(rows[i]):
            picked.append((i, votes.argmax()))
    xs = [x, *(rows[i] for i, _ in picked)]
    ys = [yy, *(np.full(len(rows[i]), k) for i, k in picked)]
    return lr(np.concatenate(xs), np.concatenate(ys), c).predict


class Encoder(nn.Module):
    """Frames ``(B, T, F)`` -> embedding ``(B, 2H)``: a 1x1 convolution (a per-frame mix of bins and channels), a
    3-frame convolution, then mean and spread over time."""

    def __init__(self, width: int, hidden: int = 64) -> None:
        super().__init__()
        self.mix = nn.Conv1d(width, hidden, 1)
        self.conv = nn.Conv1d(hidden, hidden, 3, padding=1)
        self.drop = nn.Dropout(0.2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = F.gelu(self.mix(self.drop(x.transpose(1, 2))))  # (B, H, T)
        h = F.gelu(self.conv(h))  # (B, H, T)
        return torch.cat([h.mean(2), h.std(2)], dim=1)  # (B, 2H)


class SummaryMLP(nn.Module):
    """Window summaries ``(B, 2F)`` -> logits: one hidden layer, the nonlinearity without the frames' order."""

    def __init__(self, width: int, classes: int, hidden: int = 128) -> None:
        super().__init__()
        self.net = nn.Sequential(nn.Dropout(0.2), nn.Linear(width, hidden), nn.GELU(), nn.Linear(hidden, classes))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class Net(nn.Module):
    def __init__(self, width: int, classes: int, encoder: Encoder | None = None) -> None:
        super().__init__()
        self.encoder = encoder or Encoder(width)
        self.head = nn.Linear(2 * self.encoder.conv.out_channels, classes)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.encoder(x))  # (B, K)


def windows_of(frames: np.ndarray, n: int) -> np.ndarray:
    """Every ``n``-frame window of a partition's frames: ``(W, n, F)``."""
    return np.lib.stride_tricks.sliding_window_view(frames, n, axis=0).transpose(0, 2, 1)


def train_net(net: Net, x: np.ndarray, y: np.ndarray, *, epochs: int, seed: int) -> Net:
    gen = torch.Generator().manual_seed(seed)
    xt, yt = torch.from_numpy(x), torch.from_numpy(y).long()
    opt = torch.optim.AdamW(net.parameters(), lr=3e-3, weight_decay=1e-2)
    net.train()
    for _ in range(epochs):
        for idx in torch.randperm(len(xt), generator=gen).split(128):
            xb = xt[idx] + 0.05 * torch.randn(xt[idx].shape, generator=gen)
            loss = F.cross_entropy(net(xb), yt[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
    net.eval()
    return net


def self_train(
    enc: Encoder | str | None,
    width: int,
    classes: int,
    xl: np.ndarray,
    yl: np.ndarray,
    wins: dict,
    unlabelled,
    *,
    rounds: int,
    seed: int,
    agree: float = AGREE,
) -> Net:
    """The network on the labelled windows, then ``rounds`` times again with the partitions whose windows agree."""

    def make() -> nn.Module:
        return SummaryMLP(width, classes) if enc == "mlp" else Net(width, classes, copy.deepcopy(enc))

    torch.manual_seed(seed)
    net = train_net(make(), xl, yl, epochs=60, seed=seed)
    for _ in range(rounds):
        picked = [
            (i, votes.argmax())
            for i in unlabelled
            for votes in [np.bincount(predict(net, wins[i]), minlength=classes)]
            if votes.max() >= agree * len(wins[i])
        ]
        xs = np.concatenate([xl, *(wins[i] for i, _ in picked)])
        ys = np.concatenate([yl, *(np.full(len(wins[i]), c) for i, c in picked)])
        torch.manual_seed(seed)
        net = train_net(make(), xs, ys, epochs=30, seed=seed)
    return net


@torch.no_grad()
def predict(net: Net, x: np.ndarray) -> np.ndarray:
    net.eval()
    return torch.cat([net(torch.from_numpy(c)).argmax(1) for c in np.array_split(x, max(1, len(x) // 2048))]).numpy()


def pretrain(frames: dict[int, np.ndarray], ids: np.ndarray, width: int, n: int, *, epochs: int, seed: int) -> Encoder:
    """Contrastive over time: two random ``n``-frame windows of one partition, noise and frame dropout on each."""
    rng = np.random.default_rng(seed)
    torch.manual_seed(seed)
    enc = Encoder(width)
    proj = nn.Sequential(nn.Linear(128, 128), nn.GELU(), nn.Linear(128, 64))
    opt = torch.optim.AdamW([*enc.parameters(), *proj.parameters()], lr=3e-3, weight_decay=1e-2)
    enc.train()
    for _ in range(epochs):
        for batch in np.array_split(rng.permutation(ids), max(1, len(ids) // 256)):
            views = []
            for _view in range(2):
                w = np.stack([frames[i][s : s + n] for i in batch for s in [rng.integers(0, len(frames[i]) - n + 1)]])
                wt = torch.from_numpy(w)
                wt = wt + 0.1 * torch.randn_like(wt)
                wt = wt * (torch.rand(wt.shape[0], 1, wt.shape[2]) > 0.1)  # (B, T, F) feature dropout
                views.append(F.normalize(proj(enc(wt)), dim=1))
            a, b = views
            logits = a @ b.T / 0.1  # (B, B)
            target = torch.arange(len(a))
            loss = (F.cross_entropy(logits, target) + F.cross_entropy(logits.T, target)) / 2
            opt.zero_grad()
            loss.backward()
            opt.step()
    enc.eval()
    return enc


@torch.no_grad()
def embed(enc: Encoder, x: np.ndarray) -> np.ndarray:
    return torch.cat([enc(torch.from_numpy(c)) for c in np.array_split(x, max(1, len(x) // 2048))]).numpy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--split", default="partitions", choices=["partitions", "runs"])
    parser.add_argument("--outer", type=int, default=5, help="outer folds whose training partitions are screened")
    parser.add_argument("--labelled", type=float, default=0.1)
    parser.add_argument("--ssl-epochs", type=int, default=60)
    parser.add_argument("--variants", nargs="+", default=["lr", "cnn", "cnn_st", "ssl_ft", "ssl_lr"])
    args = parser.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return
    warnings.simplefilter("ignore", ConvergenceWarning)
    torch.set_num_threads(2)
    runs, terrains, _ = load_runs(DATA)
    classes = sorted(set(terrains))
    parts, y, run_of = partitions(runs, [classes.index(t) for t in terrains], 500)
    results: dict[str, list[float]] = {v: [] for v in args.variants}
    folds = outer_folds(y, run_of, split=args.split, folds=5, seed=0)[: args.outer]
    for fold, (train, _) in enumerate(folds, start=1):
        normalizer = Normalizer.fit([parts[i] for i in train])
        config = SpectralConfig.for_log(np.concatenate([parts[i] for i in train[:50]]), 100.0)
        n = config.window
        raw = {i: log_frames(parts[i], config, transform=normalizer) for i in train}
        every = np.concatenate(list(raw.values()))
        fm, fs = every.mean(0), every.std(0) + 1e-6
        frames = {i: ((f - fm) / fs).astype(np.float32) for i, f in raw.items()}
        summ = {i: summary_windows(f, frames_per_window=n)[n - 1 :] for i, f in frames.items()}
        sm = np.concatenate(list(summ.values()))
        smean, sstd = sm.mean(0), sm.std(0) + 1e-6
        summ = {i: (s - smean) / sstd for i, s in summ.items()}
        wins = {i: windows_of(f, n).astype(np.float32) for i, f in frames.items()}
        groups = run_of[train] if args.split == "runs" else train
        inner = StratifiedGroupKFold(3, shuffle=True, random_state=fold).split(train, y[train], groups)
        for k, (inner_train, inner_val) in enumerate(inner):
            pool, val = train[inner_train], train[inner_val]
            labelled = labelled_subset(pool, y, args.labelled, seed=fold)
            unlabelled = np.setdiff1d(pool, labelled)
            vw, vs, vy = [], [], []
            for i in val:  # 1.7 s windows every 0.5 s, each framed on its own as the classifier sees it
                z = normalizer(parts[i])
                for start in range(0, len(z) - 170 + 1, 50):
                    f = ((frame_features(z[start : start + 170], config) - fm) / fs)[-n:]
                    vw.append(f)
                    vs.append((summary_windows(f, frames_per_window=n)[-1] - smean) / sstd)
                    vy.append(y[i])
            vw, vs, vy = np.asarray(vw, np.float32), np.asarray(vs, np.float32), np.asarray(vy)
            xl = np.concatenate([wins[i] for i in labelled])
            yl = np.concatenate([np.full(len(wins[i]), y[i]) for i in labelled])
            enc = None
            for variant in args.variants:
                t0 = time.perf_counter()
                seed = 100 * fold + k
                if variant == "lr":
                    pred = linear_self_trained(summ, labelled, unlabelled, y)(vs)
                elif variant.startswith("mlp"):
                    sl = np.concatenate([summ[i] for i in labelled])
                    rounds = 0 if variant == "mlp" else 1
                    pred = predict(
                        self_train(
                            "mlp", sl.shape[1], len(classes), sl, yl, summ, unlabelled, rounds=rounds, seed=seed
                        ),
                        vs,
                    )
                elif variant.startswith(("cnn", "ssl_st")):
                    if variant.startswith("ssl") and enc is None:
                        enc = pretrain(frames, pool, config.width, n, epochs=args.ssl_epochs, seed=seed)
                    rounds = 0 if variant == "cnn" else 2 if variant.endswith("st2") else 1
                    agree = int(variant.split("_a")[1]) / 100 if "_a" in variant else AGREE
                    pred = predict(
                        self_train(
                            enc if variant.startswith("ssl") else None,
                            config.width,
                            len(classes),
                            xl,
                            yl,
                            wins,
                            unlabelled,
                            rounds=rounds,
                            seed=seed,
                            agree=agree,
                        ),
                        vw,
                    )
                else:
                    if enc is None:
                        enc = pretrain(frames, pool, config.width, n, epochs=args.ssl_epochs, seed=seed)
                    if variant == "ssl_ft":
                        net = train_net(
                            Net(config.width, len(classes), copy.deepcopy(enc)), xl, yl, epochs=40, seed=seed
                        )
                        pred = predict(net, vw)
                    else:
                        emb = {i: embed(enc, wins[i]) for i in pool}
                        ea = np.concatenate(list(emb.values()))
                        em, es = ea.mean(0), ea.std(0) + 1e-6
                        both = {i: np.concatenate([summ[i], (emb[i] - em) / es], 1) for i in pool}
                        vb = np.concatenate([vs, (embed(enc, vw) - em) / es], 1)
                        pred = linear_self_trained(both, labelled, unlabelled, y)(vb)
                results[variant].append(float((pred == vy).mean()))
                print(
                    f"  outer {fold} inner {k + 1} {variant}: {100 * results[variant][-1]:.2f} "
                    f"({time.perf_counter() - t0:.0f} s)",
                    flush=True,
                )
        print(
            f"outer fold {fold}: " + ", ".join(f"{v} {100 * np.mean(r[-3:]):.2f}" for v, r in results.items()),
            flush=True,
        )
    print("mean over inner folds (%): " + ", ".join(f"{v} {100 * np.mean(r):.2f}" for v, r in results.items()))


if __name__ == "__main__":
    main()
