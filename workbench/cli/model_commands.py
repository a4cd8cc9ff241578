"""CLI commands for models: train, export, classify."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import tyro

from sessions import IngestOptions, ModelVersion, Session, WorkbenchError
from training import FeatureMode, TrainConfig, family_names, recorded_family

from .terminal import shown

Pos = tyro.conf.Positional


ModelName = Literal[(*family_names(), "auto")]  # type: ignore[valid-type]  # --model: the families by name, or auto
PROGRESS_EVERY_S = 10.0  # a progress line this often when the output is not a terminal (a log file, CI)


class _Bar:
    """Training progress: a tqdm bar on a terminal; elsewhere (output to a file) a line every
    ``PROGRESS_EVERY_S`` seconds with the fraction done, epoch, loss and the time left."""

    def __init__(self, desc: str, *, every_s: float | None = None) -> None:
        from tqdm import tqdm

        self.desc, self.every_s = desc, PROGRESS_EVERY_S if every_s is None else every_s
        self.lines = not sys.stdout.isatty()
        self.t0 = self.last = time.monotonic()
        self.post = ""
        self.bar = (
            None
            if self.lines
            else tqdm(total=1000, desc=desc, unit="‰", bar_format="{l_bar}{bar}| {elapsed}<{remaining} {postfix}")
        )

    def __call__(self, p) -> None:
        # a loss not yet known (NaN): the logs are being read, as the next-frame predictor computes its frames
        post = f"epoch {p.epoch} loss {p.train_loss:.4f}" if p.train_loss == p.train_loss else "reading the logs"
        if p.folds > 1:
            post = f"fold {p.fold}/{p.folds} " + post
        if p.val_loss is not None:
            post += f" val {p.val_loss:.4f}"
        self.post = post
        if self.bar is not None:
            self.bar.n = int(p.fraction * 1000)
            self.bar.set_postfix_str(post, refresh=False)
            self.bar.refresh()
            return
        now = time.monotonic()
        if now - self.last >= self.every_s:
            self.last = now
            spent = now - self.t0
            left = spent * (1 - p.fraction) / p.fraction if p.fraction > 0 else float("nan")
            print(
                f"{self.desc}: {p.fraction:.0%} {post}, {_clock(spent)} spent, about {_clock(left)} left",
                flush=True,
            )

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        elif self.post:
            print(f"{self.desc}: done in {_clock(time.monotonic() - self.t0)} ({self.post})", flush=True)


def _clock(seconds: float) -> str:
    if seconds != seconds:  # NaN: nothing done yet to judge by
        return "?"
    m, s = divmod(round(seconds), 60)
    return f"{m // 60}:{m % 60:02d}:{s:02d}" if m >= 60 else f"{m}:{s:02d}"


def check_device(device: str) -> None:
    """Refuse ``--device cuda`` in one line when this machine has no CUDA device."""
    if device == "cuda":
        import torch

        if not torch.cuda.is_available():
            raise WorkbenchError("--device cuda: no CUDA device is available on this machine")


def refuse_family_device(names: Sequence[str], device: str) -> None:
    """Refuse, in one line, a ``--device`` that one of the families ``names`` has no path for (never ignore it)."""
    from training import device_refusal

    for name in names:
        line = device_refusal(name, device)
        if line is not None:
            raise WorkbenchError(line)


def train(
    session: Pos[Path],
    stage: Literal["predictor", "classifier", "all"] = "all",
    model: ModelName | None = None,
    device: Literal["cpu", "cuda"] = "cpu",
    max_epochs: int = 300,
    patience: int = 20,
    feature_mode: FeatureMode = "hidden+surprise",
    hidden: int = 200,
    batch_size: int = 512,
    bf16: bool = True,
    consistency: float = TrainConfig.consistency,
) -> None:
    """Train the predictor (stage 1, all logs, no labels) and/or the classifier (stage 2, labelled segments).

    The paper family's stage 1 runs unchanged under `torchrun --nproc-per-node N [--nnodes M ...] $(which workbench)
    train SESSION --model paper --stage predictor`: every process trains on its share of each batch (gloo on CPU,
    nccl on CUDA). It keeps a checkpoint in the session: run the same command again after a kill and it goes on from
    there. The default family's stage 1 trains in seconds in one process.

    Args:
        session: The session folder (on storage every process can read, for several machines).
        stage: Which stage; "all" trains stage 1, then stage 2 if there are labels of two terrains or more.
        model: The family of both stages: "default" (stage 1 predicts each short-time spectrum of the signals from
            the ones before, in seconds; stage 2 is a small convolutional network over the last few spectra, with
            self-training on the unlabelled logs), "minirocket" (the default's stage 1; stage 2 is MiniRocket's
            fixed convolutions of the last 1.7 s of samples and a ridge classifier, the field's standard baseline)
            or "paper" (the paper's two LSTMs; the options below are their settings). "auto": stage 2 of every
            family over the default's stage 1 (default and minirocket), each a version, the one the session's
            held-out evidence favours (balanced accuracy; another family must lead the default by a point) made
            active, and the figures and the rule printed. Unset: the active classifier's family, "default" for
            the first.
        device: Where to train: "cuda" trains the default family's fits and the paper family's LSTMs there; a
            family without a CUDA path (minirocket, auto's choice among families) refuses it in one line rather
            than train on the CPU unsaid.
        max_epochs: Upper bound on epochs (early stopping on validation loss usually ends sooner).
        patience: Epochs without improvement before stopping.
        feature_mode: Paper family: what stage 1 hands stage 2.
        hidden: LSTM width of each stage (the paper: 200).
        batch_size: Sequences per optimiser step, all processes together (the paper: 512).
        bf16: On CUDA, run the LSTMs under bfloat16 autocast.
        consistency: Stage 2: weight of the term asking unlabelled neighbouring windows of a log for the same
            class (0, the default: labels alone; 3: as BorealTC's simulation; up to 15× slower on long logs).
    """
    from training import distributed

    check_device(device)
    if distributed.launched() and stage != "predictor":
        raise WorkbenchError(
            "under torchrun only the predictor trains (--stage predictor); the classifier learns from a few labels "
            "in one process: run `workbench train SESSION --stage classifier` without torchrun"
        )
    if consistency < 0:
        raise WorkbenchError(f"--consistency must be 0 or more, got {consistency}")
    config = TrainConfig(
        max_epochs=max_epochs,
        patience=patience,
        device=device,
        batch_size=batch_size,
        bf16=bf16,
        consistency=consistency,
    )
    if distributed.launched() and model != "paper":
        raise WorkbenchError(
            "under torchrun only the paper family's LSTM predictor trains (--model paper --stage predictor); the "
            "default family's stage 1 trains in seconds in one process: run `workbench train SESSION` without torchrun"
        )
    if device == "cpu":
        from training import hide_gpus

        hide_gpus()  # a CUDA torch's autograd would otherwise forbid the fits' forked processes their backward pass
    from .. import cycle  # after the refusals: they come without loading the families (seconds)

    world = distributed.join(device)
    try:
        if not world.main:  # another torchrun process: it reads log files, never the session's database
            cycle.follow_predictor_training(config=config, hidden=hidden)
        else:
            with Session.open(session) as s:
                names = cycle.auto_families() if model == "auto" else (cycle.stage1_family(s, model).name,)
                refuse_family_device(names, device)
                _room_for_versions(s)
                if stage in ("predictor", "all"):  # auto's families share one stage 1: the first one's
                    first = cycle.auto_families()[0] if model == "auto" else model
                    _on_free_cpus(lambda: _train_predictor(s, config, hidden, first))
                if stage in ("classifier", "all"):
                    _train_classifier(s, config, hidden, feature_mode, stage, model)
    finally:
        distributed.leave()
    if distributed.launched():
        # Now and then a torchrun process aborts in the interpreter's teardown after all of this succeeded
        # ("terminate called without an active exception": a gloo thread; 1 `make test` in several failed on it,
        # and a `make bench` once). The model is saved, the session closed and the group left: exit without the
        # teardown, so torchrun does not report a finished run as failed.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)


def _room_for_versions(s: Session) -> None:
    """Refuse a fit of minutes whose save the disk has no room for, before the fit: twice the newest version's
    files (a version and its staging copy), 8 MB at least."""
    from sessions import check_room, folder_bytes

    versions = s.model_versions()
    newest = folder_bytes(s.path / versions[-1].path) if versions else 0
    check_room(s.path, max(2 * newest, 8 << 20), what="a new model version")


def _on_free_cpus(fn) -> None:
    """Stage 1 on as many threads as CPUs are free when it starts (``training.use_free_cpus``): on a busy machine
    torch's thread per core waits on the one that is descheduled (the frame predictor beside one busy loop: 4.1x
    its time alone, 1.6x on the free CPUs; ``benchmarks/speed/bench_under_load.py``). Stage 2 keeps torch's count: its
    fits already run one thread each, side by side, and share the cores through the scheduler."""
    import torch

    from training import use_free_cpus

    threads = torch.get_num_threads()
    use_free_cpus()
    try:
        fn()
    finally:
        torch.set_num_threads(threads)


def _train_predictor(s: Session, config: TrainConfig, hidden: int, model: str | None) -> None:
    from .. import cycle

    if cycle.stage1_family(s, model).stage1 == "next-frame":
        bar = _Bar("predictor")
        try:
            v = cycle.train_frame_predictor(s, progress=bar, device=config.device)
        finally:
            bar.close()
        m = v.metrics
        print(
            f"predictor v{v.id} (next spectral frame): error {m['train_mse']:.3f} against {m['copy_last_mse']:.3f} "
            "for copying the last frame (standardised units)"
        )
        return

    def resumed(epoch: int, batch: int) -> None:
        where = f"epoch {epoch}" + (f", batch {batch}" if batch else "")
        print(f"predictor: resuming from the checkpoint at {where}", file=sys.stderr)

    def other(line: str) -> None:
        print(
            f"predictor: a checkpoint of another run is kept ({line}); this run starts at epoch 1, and running again "
            "with those settings resumes that one",
            file=sys.stderr,
        )

    bar = _Bar("predictor")
    try:
        v = cycle.train_predictor(s, config=config, hidden=hidden, progress=bar, on_resume=resumed, on_other=other)
    finally:
        bar.close()
    print(
        f"predictor v{v.id}: validation MSE {v.metrics['val_mse']:.4f} (normalised units), "
        f"best epoch {v.metrics['best_epoch']} of {v.metrics['epochs']}"
    )


def _train_classifier(
    s: Session, config: TrainConfig, hidden: int, feature_mode: FeatureMode, stage: str, model: str | None
) -> None:
    from .. import cycle

    terrains = {seg.terrain for seg in s.segments()}
    if stage == "all" and len(terrains) < 2:
        print("classifier: skipped (label segments of at least two terrains first)")
        return
    if model == "auto":
        _train_auto(s)
        return
    stored = cycle.stored_scores(s)  # what the session knows of its runs, as the page last scored them
    known = stored.scores if stored is not None and stored.scores.classifier is not None else None
    bar = _Bar("classifier")
    try:
        v = cycle.train_classifier(
            s, model=model, config=config, feature_mode=feature_mode, hidden=hidden, progress=bar, scores=known
        )
    finally:
        bar.close()
    _report_classifier(s, v)


def _train_auto(s: Session) -> None:
    from .. import cycle

    bar = _Bar("classifier (auto: each family)")
    try:
        choice = cycle.train_best_classifier(s, progress=bar)
    finally:
        bar.close()
    for v in choice.fitted:
        _report_classifier(s, v)
    print(f"auto: {choice.why}; classifier v{choice.kept.id} is active (the Train tab can make another active)")


def _report_classifier(s: Session, v: ModelVersion) -> None:
    from training import unseen_words

    from .. import cycle

    m = v.metrics
    estimate = m.get("estimate")
    unseen = unseen_words(m.get("unseen_runs"))
    if unseen:  # the model that ships on a run it never saw: not the session's own accuracy
        print(f"classifier v{v.id}: on a run it never saw (folds over the session's runs) {unseen}")
    if fell := cycle.unseen_change(s, v):
        print(f"warning: {fell}", file=sys.stderr)
    if estimate:
        _print_estimate(v.id, recorded_family(v.config), m, estimate)
        checked = cycle.checks_summary(s)
        if checked.all is not None:  # the person's own held-out evidence: each label first tested the model
            spot = f"; spot checks: {checked.spot.words('spot checks')}" if checked.spot else ""
            print(f"  your checks: {checked.all.words()}{spot}")
        print(
            f"  the session: not checked since this Retrain (a check tests the version it was made with); "
            f"`workbench suggest {shown(s.path)} --verify --out FILE` writes the uniform checks that measure v{v.id}"
        )
        return
    held = m.get("held_out_logs")
    if held:
        print(
            f"classifier: accuracy on held-out logs {held['accuracy']:.1%}, macro-F1 {held['macro_f1']:.3f} "
            f"({held['folds']} folds over {held['logs']} labelled logs)"
        )
    print(
        f"classifier v{v.id} ({recorded_family(v.config)} family): out-of-fold accuracy (same logs) "
        f"{m['accuracy']:.1%}, macro-F1 {m['macro_f1']:.3f} on {m['n_segments']} segments "
        f"({m['labelled_seconds']:.0f} s labelled)"
    )


def _print_estimate(version: int, model: str, m: dict, estimate: dict) -> None:
    """The estimate that exists per terrain, saying which it is (``training.figures.estimates``)."""
    from training import estimate_headline, majority_words

    words = estimate_headline(estimate) or "accuracy not measurable"
    balanced = estimate.get("balanced_accuracy")
    baseline = majority_words(estimate)
    print(
        f"classifier v{version} ({model} family): {words} on the labelled pieces"
        + (f", balanced {100 * balanced:.1f} %" if balanced is not None else "")
        + (f" ({baseline})" if baseline else "")
        + f", on {m['n_segments']} segments ({m['labelled_seconds']:.0f} s labelled)"
    )
    if estimate["note"]:
        print(f"  {estimate['note']}")
    read, labelled = m.get("rows_read") or (0, 0)
    if read < labelled:
        print(f"  its heads read {read:,} of the {labelled:,} labelled windows (a draw per terrain: they overlap)")
    per = estimate["per_terrain"]
    width = max(len("terrain"), *(len(shown(n)) for n in per))
    print(f"  {'terrain':<{width}}  recall   measured by     logs")
    for name, e in per.items():
        recall = "   –  " if e["recall"] is None else f"{100 * e['recall']:5.1f} %"
        print(f"  {shown(name):<{width}}  {recall}  {e['by']:<14}  {e['logs']}")
    cal = m.get("calibration") or {}
    if cal.get("on"):
        print(f"  probabilities calibrated on {cal['on']}: logits divided by {cal['temperature']:.2f}")


def export(
    session: Pos[Path],
    out: Path,
    predictions: bool = False,
    mcap: bool = False,
    frames: bool = False,
    untaught: bool = False,
) -> None:
    """Export the model that ships (bundle, ONNX, model card) and the label files for the robot.

    The model that ships is the active classifier taught by what the session knows: stage 2 fitted once more from
    scratch, every label plus the terrain the session is sure of over each unlabelled stretch (its labels' votes
    and the model together, as the page shows them). It is fitted on the first export after a Retrain or a label
    change and kept in the session beside the active version (which it never replaces), so a second export reuses it.

    Args:
        session: The session folder.
        out: Folder to create.
        predictions: Also write per-timestep predictions of every log (predictions.parquet).
        mcap: Also write an MCAP file per log in OUT/mcap: the model's terrain per sample (topic /terrain) and the
            labels (/terrain/labels) on the log's own clock, to open beside the log in Foxglove.
        frames: Also write the camera frames inside labelled segments to OUT/frames, a folder per terrain, with
            their index (frames/index.csv: file, log, camera, time, terrain).
        untaught: Ship the active version as it is, not taught by the session.
    """
    from ..export import export_all

    with Session.open(session) as s:
        written = export_all(s, out, predictions=predictions, mcap=mcap, frames=frames, taught=not untaught, say=print)
    for path, what in written:
        print(f"{shown(path)}  {what}")


def classify(
    bundle: Pos[Path],
    files: Pos[list[Path]],
    out: Path,
    mapping: Path | None = None,
    allow_gaps: bool = False,
    rate: float | None = None,
    smooth: float | None = None,
    jobs: int | None = None,
) -> int:
    """Per-timestep terrain predictions for log files with an exported bundle (no session needed).

    The files are read as `workbench ingest` reads them, with the same options.

    Args:
        bundle: A model bundle folder (from `workbench export`).
        files: Log files (MCAP / CSV) with the channels the model was trained on.
        out: Output table (.csv, .parquet or .json) of every log; or .mcap: one MCAP file per log (topic /terrain,
            on the log's own clock, to open beside it in Foxglove); with several logs each file gets the log's name
            before .mcap. An output that exists is refused, as is one through a link or into a missing folder.
        mapping: TOML or JSON file naming topics/columns to read, as for `workbench ingest` (a headerless CSV's
            `[csv]` section included).
        allow_gaps: Accept NaN/inf samples and dropouts, recording them as gaps instead of refusing the file.
        rate: Rate (Hz) of the aligned time base; default: the fastest stream's median rate.
        smooth: Smooth the probabilities with an HMM whose terrain lasts this many seconds on average
            (forward-backward over each file; each file's line says how late the robot's causal filter would
            follow a change). Off by default.
        jobs: Files read and scored at once, each in a process of its own (default: one per core). A bundle of
            the default family runs in NumPy alone; one of another family scores in the main process.
    """
    from sessions import check_new_target, load_mapping

    if out.suffix.lower() != ".mcap":  # before torch loads (seconds); an MCAP output's names are per log
        check_new_target(out)
    from ..export import classify_files

    options = IngestOptions(
        mapping=load_mapping(mapping) if mapping else IngestOptions().mapping,
        rate_hz=rate,
        allow_gaps=allow_gaps,
        camera_fps=0,  # predictions need no pictures: image topics are not decoded
    )
    code, lines = classify_files(bundle, files, out, options, smooth_s=smooth, jobs=jobs)
    for line in lines:
        print(shown(line), file=sys.stderr if line.startswith(("error:", "warning:")) else sys.stdout)
    return code
