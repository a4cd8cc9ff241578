"""Stage 1 of a session by family: the default family's next-frame predictor, trained in seconds on the frames
its stage 2 reads too, or the paper family's LSTM (:func:`.train_stages.train_predictor`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from sessions import ModelVersion, Session
from training import (
    FRAME_PREDICTOR_KIND,
    CancelFn,
    FramePredictor,
    FramePredictorConfig,
    FramePredictorFit,
    ModelBundle,
    Normalizer,
    Progress,
    ProgressFn,
    TrainConfig,
    copy_last_error,
    fit_frame_predictor,
    frame_surprise,
    never,
    to_dict,
)

from .front_end import choose_front_end, log_frame_files
from .train_stages import model_logs, recorded_run, save_version, stage1_family, train_predictor

RESIDUAL_FRAMES = 4096  # frames of each log the next-frame predictor's reported errors are measured on


def train_frame_predictor(
    session: Session,
    *,
    fit: FramePredictorFit | None = None,
    hidden: int = FramePredictorConfig.hidden,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
    device: str = "cpu",
) -> ModelVersion:
    """The default family's stage 1 on every log of the session's main channel set: the next spectral frame from
    the ones before (``training.FramePredictor``); saved as a new, active predictor version.

    Reads the logs twice: once for the input normalisation, once for the frames, which are cached per log (a run
    stopped while computing them goes on from the logs already done). The fit itself is a fixed number of steps
    (``fit.steps``, seconds) whatever the hours of logs, so it keeps no checkpoint.

    Args:
        session: The session.
        fit: Training settings (``FramePredictorFit()``).
        hidden: Channels of its convolutions: the width of the suggestions' embedding.
        progress: Called after each log's frames (epoch 1 of 2) and every 50 steps of the fit (epoch 2 of 2).
        cancel: Polled between logs and every 50 steps.
        device: Where the fit's steps run (the frames are computed on the CPU).
    """
    fit = fit or FramePredictorFit()
    logs = model_logs(session)
    started = time.monotonic()

    def report(epoch: int, step: int, steps: int, loss: float) -> None:
        if progress:
            elapsed = time.monotonic() - started
            progress(Progress("predictor", 0, 1, epoch, 2, step, steps, loss, None, None, elapsed))

    params = {"kind": FRAME_PREDICTOR_KIND, "fit": to_dict(fit), "hidden": hidden, "logs": [x.id for x in logs]}
    with recorded_run(session, "predictor", params) as result:
        normalizer = Normalizer.fit([session.rows(x.id) for x in logs])
        front = choose_front_end(session, logs)
        frames = log_frame_files(
            session,
            normalizer,
            logs,
            front,
            progress=lambda done, todo: report(1, done, todo, float("nan")),
            cancel=cancel,
        )
        model, history = fit_frame_predictor(
            frames,
            config=FramePredictorConfig(front.width, hidden=hidden),
            fit=fit,
            progress=lambda p: report(2, p.step, p.steps, p.train_loss),
            cancel=cancel,
            device=device,
        )
        own, copy = _frame_errors(model, frames)
        bundle = ModelBundle(
            model,
            normalizer,
            logs[0].channel_names,
            logs[0].rate_hz,
            metrics={"train_mse": own, "copy_last_mse": copy, "steps": fit.steps},
            info={
                "logs": len(logs),
                "timesteps": int(sum(x.n_samples for x in logs)),
                "frames": int(sum(len(f) for f in frames)),
                "history": history,
                "seconds": round(time.monotonic() - started, 2),
            },
            spectral=front,
        )
        version = save_version(session, "predictor", bundle, params)
        result["version"] = version.id
    return version


def _frame_errors(model: FramePredictor, frames: Sequence[np.ndarray]) -> tuple[float, float]:
    """Mean squared error (standardised units) of the predictor and of copying the last frame, over the first
    ``RESIDUAL_FRAMES`` frames of each log (every log counts, a fleet's cost stays bounded)."""
    own, copy, n = 0.0, 0.0, 0
    for f in frames:
        part = np.asarray(f[:RESIDUAL_FRAMES], np.float32)
        if len(part) < 2:
            continue
        own += float(frame_surprise(model, part, raw=True)[0][1:].sum())
        copy += float(copy_last_error(model, part)[1:].sum())
        n += len(part) - 1
    return own / max(n, 1), copy / max(n, 1)


def train_stage1(
    session: Session,
    *,
    model: str | None = None,
    config: TrainConfig | None = None,
    hidden: int = 200,
    frame_fit: FramePredictorFit | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
    on_resume: Callable[[int, int], None] | None = None,
    on_other: Callable[[str], None] | None = None,
) -> ModelVersion:
    """Stage 1 of a family (``model``; ``None``: the active classifier's, ``"default"`` before any): the next-frame
    predictor (:func:`train_frame_predictor`) or the paper's LSTM (:func:`train_predictor`, with ``config``,
    ``hidden``, ``on_resume`` and ``on_other``); either on ``config.device``."""
    if stage1_family(session, model).stage1 == FRAME_PREDICTOR_KIND:
        device = (config or TrainConfig()).device
        return train_frame_predictor(session, fit=frame_fit, progress=progress, cancel=cancel, device=device)
    return train_predictor(
        session,
        config=config,
        hidden=hidden,
        progress=progress,
        cancel=cancel,
        on_resume=on_resume,
        on_other=on_other,
    )
