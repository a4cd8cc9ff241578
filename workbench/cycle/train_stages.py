"""Stage 1 of the cycle and what both stages share: the logs a model uses, a version saved and recorded, the
paper family's LSTM predictor (``frame_stage1`` trains the next-frame one), the active predictor and family. Stage 2
is ``stage2_fit``. Composes ``sessions`` (data, labels, versions) and ``training`` (models, arrays only).
"""

from __future__ import annotations

import contextlib
import shutil
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from sessions import FileRows, LogInfo, ModelVersion, Session, WorkbenchError
from training import (
    CancelFn,
    Cancelled,
    Family,
    ModelBundle,
    ProgressFn,
    SpectralConfig,
    TrainConfig,
    distributed,
    family,
    family_names,
    fit_predictor,
    load_bundle,
    never,
    recorded_family,
    save_bundle,
    to_dict,
)

from .front_end import (
    choose_front_end,
)

MODEL_FAMILIES = family_names()  # `--model`: the registry's names (training.registry), the default first


def model_logs(session: Session, channels: Sequence[str] | None = None) -> list[LogInfo]:
    """The logs a model uses: those with ``channels``, or with the most common channel set of the session."""
    logs = session.logs()
    if not logs:
        raise WorkbenchError(f"{session.path}: no logs yet; ingest some first")
    if channels is None:
        channels = Counter(log.channel_names for log in logs).most_common(1)[0][0]
    return [log for log in logs if log.channel_names == tuple(channels)]


def save_version(
    session: Session, stage: str, bundle: ModelBundle, extra: dict, *, activate: bool = True
) -> ModelVersion:
    path = session.next_model_dir()
    if path.exists():  # a crashed save that got as far as the rename but not the catalog
        shutil.rmtree(path)
    try:
        save_bundle(bundle, path)  # whole or not at all: written under a temporary name
    except OSError as exc:
        raise WorkbenchError(
            f"{session.path}: cannot save the {stage} model ({exc.strerror or exc}); the active models are unchanged"
        ) from None
    except Exception as exc:  # safetensors' own error wraps the OS's ("No space left on device")
        if "No space left" not in str(exc):
            raise
        raise WorkbenchError(
            f"{session.path}: cannot save the {stage} model (no space left on the disk); the active models are "
            "unchanged"
        ) from None
    try:
        return session.register_model(stage, path, config=extra, metrics=bundle.metrics, activate=activate)
    except BaseException:
        shutil.rmtree(path, ignore_errors=True)
        raise


@contextlib.contextmanager
def recorded_run(session: Session, kind: str, params: dict) -> Iterator[dict]:
    """Record a training run in the session: "done" with the result the block fills in, else why it ended."""
    run = session.start_run(kind, params)
    result: dict = {}
    try:
        yield result
    except BaseException as exc:
        session.finish_run(run, "cancelled" if isinstance(exc, Cancelled) else "failed", {"error": str(exc)})
        raise
    session.finish_run(run, "done", result)


PREDICTOR_CHECKPOINT = "predictor.safetensors"  # in the session's cache/checkpoints/


def train_predictor(
    session: Session,
    *,
    config: TrainConfig | None = None,
    hidden: int = 200,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
    on_resume: Callable[[int, int], None] | None = None,
    on_other: Callable[[str], None] | None = None,
    checkpoint_every: int = 100,
) -> ModelVersion:
    """The paper family's stage 1 (its LSTM predictor of the next sample) on every log of the session's main channel
    set; saved as a new, active predictor version. :func:`train_stage1` picks a family's stage 1.

    Resumable: training keeps a checkpoint in the session (every ``checkpoint_every`` batches and every epoch), and
    a run with the same settings on the same logs goes on from it (``on_resume`` hears where). Under ``torchrun``
    this runs in the main process, the only one that opens the session; the others run
    :func:`follow_predictor_training` and train on their share of each batch.
    """
    config = config or TrainConfig()
    world = distributed.current()
    logs = model_logs(session)
    checkpoint = session.cache_dir("checkpoints") / PREDICTOR_CHECKPOINT
    rows = [session.rows(x.id) for x in logs]  # read a batch at a time, never whole
    # the other processes never open the database (SQLite's WAL needs one machine): they are told the files
    distributed.broadcast_json({"files": [str(session.path / x.file) for x in logs], "checkpoint": str(checkpoint)})
    params = {"config": to_dict(config), "hidden": hidden, "logs": [x.id for x in logs], "processes": world.size}
    with recorded_run(session, "predictor", params) as result:
        fit = fit_predictor(
            rows,
            config=config,
            hidden=hidden,
            progress=progress,
            cancel=cancel,
            checkpoint=checkpoint,
            checkpoint_every=checkpoint_every,
            on_resume=on_resume,
            on_other=on_other,
        )
        info = {
            "logs": len(logs),
            "timesteps": int(sum(x.n_samples for x in logs)),
            "history": fit.history,
            "processes": world.size,
            "resumed_from": fit.resumed_from,
        }
        bundle = ModelBundle(
            fit.model,
            fit.normalizer,
            logs[0].channel_names,
            logs[0].rate_hz,
            metrics={
                "val_mse": min(h["val_loss"] for h in fit.history),
                "best_epoch": fit.best_epoch,
                "epochs": len(fit.history),
            },
            info=info,
        )
        version = save_version(
            session, "predictor", bundle, {"train": to_dict(config), "hidden": hidden, "logs": [x.id for x in logs]}
        )
        result["version"] = version.id
    if fit.checkpoint is not None:
        with contextlib.suppress(OSError):
            fit.checkpoint.unlink()  # the version holds the result now
    distributed.broadcast_json({"version": version.id})
    return version


def stage1_family(session: Session, model: str | None) -> Family:
    """The family ``model`` names, or the active classifier's (``"default"`` before any)."""
    try:
        return family(model or classifier_family(session))
    except KeyError as exc:
        raise WorkbenchError(str(exc.args[0])) from None


def front_end_of(session: Session, bundle: ModelBundle, logs: Sequence[LogInfo]) -> SpectralConfig:
    """The spectral front end of a frames or windows family: the next-frame predictor's (its frames are what it
    learned), else chosen from the logs (a session whose stage 1 is the LSTM)."""
    return bundle.spectral if bundle.spectral is not None else choose_front_end(session, logs)


def require_stage1(session: Session, fam: Family, version: ModelVersion, bundle: ModelBundle) -> None:
    """Refuse a family's stage 2 that reads stage 1's outputs over another family's kind of stage 1, in one line
    with what to run."""
    if fam.stage2_inputs == "stage1" and bundle.stage1_kind != fam.stage1:
        raise WorkbenchError(
            f"{session.path}: the {fam.name} family reads its own stage 1's outputs ({fam.stage1}), and the active "
            f"predictor v{version.id} is another kind ({bundle.stage1_kind}); run `workbench train {session.path} "
            f"--model {fam.name}` to train both stages of the {fam.name} family (labels are kept)"
        )


def follow_predictor_training(
    *, config: TrainConfig | None = None, hidden: int = 200, checkpoint_every: int = 100, cancel: CancelFn = never
) -> int:
    """What every ``torchrun`` process but the main one runs beside :func:`train_predictor`: it trains on its share
    of the logs the main process names, reading their files only, and returns the id of the version the main
    process saved. It never opens the session's database: on several machines that is a shared file system, where
    SQLite's write-ahead log would not be safe."""
    told = distributed.broadcast_json()
    assert isinstance(told, dict)
    rows = [FileRows.open_npy(f) for f in told["files"]]
    fit_predictor(
        rows,
        config=config or TrainConfig(),
        hidden=hidden,
        cancel=cancel,
        checkpoint=Path(told["checkpoint"]),
        checkpoint_every=checkpoint_every,
    )
    done = distributed.broadcast_json()
    assert isinstance(done, dict)
    return int(done["version"])


def active_predictor(session: Session) -> tuple[ModelVersion, ModelBundle]:
    version = session.active_model("predictor")
    if version is None:
        raise WorkbenchError(
            f"{session.path}: no predictor yet; run `workbench train {session.path} --stage predictor`"
        )
    return version, load_bundle(session.path / version.path)


def classifier_family(session: Session) -> str:
    """The family of the active classifier (what a Retrain trains again), ``"default"`` before any."""
    active = session.active_model("classifier")
    return recorded_family(None if active is None else active.config)


def active_bundle(session: Session) -> tuple[ModelVersion, ModelBundle]:
    """The active classifier version and its full bundle (both stages)."""
    version = session.active_model("classifier")
    if version is None:
        raise WorkbenchError(f"{session.path}: no classifier yet; label some segments and run `workbench train`")
    return version, load_bundle(session.path / version.path)
