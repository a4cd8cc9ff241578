"""The default family's own stage 1: an unsupervised predictor of the next spectral frame from the frames before it.

The paper's stage 1 predicts each raw sample with two 200-unit LSTMs over every sample at 100 Hz; this one reads the
front end's 5 Hz frames (:mod:`.spectra`), which the default classifier reads too, so it trains on an hour of logs
in seconds. Its shape is the paper's: trained on all logs without labels, mean squared error plus an elastic-net
penalty on its weights, frozen afterwards; its prediction error per frame is the surprise highlight and its hidden
features are the embedding the suggestions cluster before a classifier exists.

The network is causal: each frame standardised, a 1x1 convolution (which bins of which channels matter), two causal
convolutions over time (kernel 3, dilations 1 and 2: seven frames, 1.4 s of context), and a linear read-out of the
next frame. Config dataclass plus module; fitted by :func:`fit_frame_predictor`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from ..running import CancelFn, Cancelled, Progress, ProgressFn, never
from .kinds import FRAME_PREDICTOR_KIND
from .spectra import drop_pages, frame_moments

RESIDUAL_FRAMES = 4096  # frames of each log that measure the features' residuals after training


@dataclass(frozen=True)
class FramePredictorConfig:
    """Sizes of the frame predictor.

    Attributes:
        n_features: Features per frame (``SpectralConfig.width``).
        hidden: Channels of its convolutions: the embedding's width.
        kind: Always ``"next-frame"``: tells a bundle which module to rebuild.
    """

    n_features: int
    hidden: int = 64
    kind: str = FRAME_PREDICTOR_KIND


@dataclass(frozen=True)
class FramePredictorFit:
    """How the frame predictor is trained.

    Attributes:
        steps: AdamW steps (a fixed budget: an hour of logs or ten take the same time).
        batch: Crops per step.
        crop: Frames per crop (the first ``context`` of each are read, not scored).
        lr: AdamW learning rate.
        lam: Elastic-net weight ``λ`` on the convolutions' and read-out's weights (the paper's eq. 1).
        gamma: Share of the L1 term in the elastic net.
        seed: Seed of the crops and initial weights.
    """

    steps: int = 600
    batch: int = 32
    crop: int = 64
    lr: float = 3e-3
    lam: float = 1e-6
    gamma: float = 0.5
    seed: int = 0


class FramePredictor(nn.Module):
    """Frames ``(B, T, F)`` -> the next frame's estimate ``(B, T, F)`` (standardised units) and hidden ``(B, T, H)``."""

    context = 7  # frames the causal convolutions read: 1 + 2·1 + 2·2

    def __init__(self, config: FramePredictorConfig) -> None:
        super().__init__()
        self.config = config
        f, h = config.n_features, config.hidden
        self.register_buffer("in_mean", torch.zeros(f))
        self.register_buffer("in_scale", torch.ones(f))
        # 1 / each feature's mean squared residual on the training logs: the surprise weighs a feature by how well
        # it is predicted, so bins of pure noise do not drown the few that change with the terrain
        self.register_buffer("residual_inv", torch.ones(f))
        self.mix = nn.Conv1d(f, h, 1)
        self.conv1 = nn.Conv1d(h, h, 3, dilation=1)
        self.conv2 = nn.Conv1d(h, h, 3, dilation=2)
        self.out = nn.Linear(h, f)

    def standardise(self, frames: torch.Tensor) -> torch.Tensor:
        """Raw frames ``(B, T, F)`` in the units the loss and the surprise are measured in."""
        return (frames - self.in_mean) * self.in_scale

    def forward(self, frames: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        z = self.standardise(frames).transpose(1, 2)  # (B, F, T)
        h = F.gelu(self.mix(z))  # (B, H, T)
        h = F.gelu(self.conv1(F.pad(h, (2, 0))))  # (B, H, T) causal: frame t reads t-2..t
        h = h + F.gelu(self.conv2(F.pad(h, (4, 0))))  # (B, H, T) t-4..t of the layer below
        hidden = h.transpose(1, 2)  # (B, T, H)
        return self.out(hidden), hidden  # estimate of frame t + 1 from frames <= t

    def penalised(self) -> list[torch.Tensor]:
        """The weights the elastic net covers (biases and the standardisation are not)."""
        return [self.mix.weight, self.conv1.weight, self.conv2.weight, self.out.weight]

    def set_standardisation(self, mean: np.ndarray, std: np.ndarray) -> None:
        """Standardise each frame's features with ``mean`` and ``std`` ``(F,)``."""
        std = np.where(std > 1e-8, std, 1.0)
        self.in_mean.copy_(torch.as_tensor(mean, dtype=torch.float32))
        self.in_scale.copy_(torch.as_tensor(1.0 / std, dtype=torch.float32))


def fit_frame_predictor(
    logs: Sequence[np.ndarray],
    *,
    config: FramePredictorConfig | None = None,
    fit: FramePredictorFit | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
    device: str = "cpu",
) -> tuple[FramePredictor, list[float]]:
    """Train the predictor on every log's frames, no labels.

    Args:
        logs: Per log, ``(N, F)`` frames (``spectra.log_frames``; memory-mapped arrays are read a log at a time for
            the standardisation, a crop at a time while training).
        config: Sizes; default from the frames' width.
        fit: Training settings.
        progress: Called every 50 steps.
        cancel: Polled every 50 steps.
        device: Where it trains (``"cuda"``: the crops are cut on the CPU, each step runs on the GPU); it comes back
            on the CPU either way.

    Returns:
        The frozen predictor and its loss (mean squared error, standardised units) every 50 steps.
    """
    fit = fit or FramePredictorFit()
    usable = [x for x in logs if len(x) >= 2]
    if not usable:
        raise ValueError("no log is long enough for two frames: nothing to train the frame predictor on")
    config = config or FramePredictorConfig(usable[0].shape[1])
    torch.manual_seed(fit.seed)
    model = FramePredictor(config)
    model.set_standardisation(*frame_moments(usable))
    model.to(device)
    rng = np.random.default_rng(fit.seed)
    lengths = np.asarray([len(x) for x in usable], np.float64)
    opt = torch.optim.AdamW(model.parameters(), lr=fit.lr, weight_decay=0.0)  # the elastic net is the penalty
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, fit.lr, total_steps=fit.steps, pct_start=0.1)
    crop = fit.crop
    history, running, t0 = [], [], time.monotonic()
    model.train()
    for step in range(1, fit.steps + 1):
        which = rng.choice(len(usable), size=fit.batch, p=lengths / lengths.sum())  # a log in proportion to its time
        batch = np.zeros((fit.batch, crop, config.n_features), np.float32)
        mask = np.zeros((fit.batch, crop - 1), np.float32)
        for b, i in enumerate(which):
            n = min(crop, len(usable[i]))
            start = int(rng.integers(0, len(usable[i]) - n + 1))
            batch[b, :n] = usable[i][start : start + n]
            mask[b, : n - 1] = 1.0
        x = torch.from_numpy(batch).to(device)  # (B, L, F)
        estimate, _ = model(x)
        target = model.standardise(x[:, 1:])  # (B, L - 1, F)
        err = (estimate[:, :-1] - target).pow(2).mean(dim=2)  # (B, L - 1)
        mask[:, : FramePredictor.context - 1] = 0.0  # a crop's first frames lack their context: zero-padded
        m = torch.from_numpy(mask).to(device)
        mse = (err * m).sum() / m.sum().clamp_min(1.0)
        params = model.penalised()
        penalty = fit.lam * (
            fit.gamma * sum(p.abs().sum() for p in params) + (1 - fit.gamma) * sum(p.pow(2).sum() for p in params)
        )
        opt.zero_grad()
        (mse + penalty).backward()
        opt.step()
        sched.step()
        running.append(float(mse.detach()))
        if step % 50 == 0 or step == fit.steps:
            if not np.isfinite(running[-1]):
                raise ValueError("the frame predictor's training diverged (a non-finite loss)")
            history.append(float(np.mean(running)))
            running = []
            for x in usable:  # the crops read from mapped frames leave the resident set (a fleet's hours)
                drop_pages(x)
            if progress:
                progress(
                    Progress(
                        "predictor",
                        fold=0,
                        folds=1,
                        epoch=1,
                        max_epochs=1,
                        step=step,
                        steps=fit.steps,
                        train_loss=history[-1],
                        val_loss=None,
                        best_val_loss=None,
                        elapsed_s=time.monotonic() - t0,
                    )
                )
            if cancel():
                raise Cancelled("frame predictor training cancelled")
    model.cpu().eval()  # the residuals below, the passes and the bundle read it on the CPU
    residual = np.zeros(config.n_features, np.float64)
    count = 0
    for x in usable:  # each log's first RESIDUAL_FRAMES frames: every log counts, a fleet's cost stays bounded
        part = np.asarray(x[:RESIDUAL_FRAMES], np.float32)
        sq = _squared_errors(model, part)[1:]  # (N - 1, F)
        residual += sq.sum(0)
        count += len(sq)
    model.residual_inv.copy_(torch.as_tensor(1.0 / np.maximum(residual / max(count, 1), 1e-6), dtype=torch.float32))
    return model, history


@torch.inference_mode()
def _squared_errors(model: FramePredictor, frames: np.ndarray) -> np.ndarray:
    """``(N, F)`` squared standardised error of each frame's estimate from the frames before it (row 0: zeros)."""
    x = torch.from_numpy(np.array(frames, np.float32))[None]  # (1, N, F) a copy: frames may be a read-only map
    estimate, _ = model(x)
    out = np.zeros(x.shape[1:], np.float32)
    out[1:] = (estimate[0, :-1] - model.standardise(x[0, 1:])).pow(2).numpy()
    return out


@torch.inference_mode()
def frame_surprise(
    model: FramePredictor, frames: np.ndarray, *, raw: bool = False, chunk: int = 8192
) -> tuple[np.ndarray, np.ndarray]:
    """Per frame of one log ``(N, F)``: how badly the frames before it predicted it ``(N,)``, and the hidden
    features after it ``(N, H)``.

    The surprise is the mean over features of the squared standardised error, each feature's divided by its mean
    on the training logs, and 0 for the log's first ``FramePredictor.context`` frames: predicted from zeros before
    the log began, they were the highest of every log and drew a "predictor surprised" highlight at each start.
    ``raw``: the loss's own units, not divided, and only the first frame 0 (what the fit's reported error and the
    copy-last-frame baseline are measured on). The log is read in chunks that overlap by the predictor's context, so
    a 10-hour log never goes through the network at once and the numbers equal one pass.
    """
    n, ctx = len(frames), FramePredictor.context
    weight = torch.ones_like(model.residual_inv) if raw else model.residual_inv
    error = np.zeros(n, np.float32)
    hidden = np.zeros((n, model.config.hidden), np.float32)
    for a in range(0, n, chunk):
        lo, hi = max(0, a - ctx), min(n, a + chunk)
        x = torch.from_numpy(np.array(frames[lo:hi], np.float32))[None]  # (1, L, F) a copy of a read-only map
        estimate, h = model(x)
        hidden[a:hi] = h[0, a - lo :].numpy()
        sq = (estimate[0, :-1] - model.standardise(x[0, 1:])).pow(2)  # (L - 1, F) row j: frame lo + j + 1
        first = max(a, 1)
        error[first:hi] = (sq * weight).mean(dim=1).numpy()[first - lo - 1 :]
    if not raw:
        error[:ctx] = 0.0
    return error, hidden


def copy_last_error(model: FramePredictor, frames: np.ndarray) -> np.ndarray:
    """The baseline the predictor must beat: each frame estimated as the one before it, ``(N,)`` squared error in
    the predictor's standardised units (as ``frame_surprise(..., raw=True)``; the first frame: 0)."""
    with torch.inference_mode():
        z = model.standardise(torch.from_numpy(np.array(frames, np.float32))).numpy()  # (N, F)
    out = np.zeros(len(z), np.float32)
    out[1:] = np.square(z[1:] - z[:-1]).mean(axis=1)
    return out
