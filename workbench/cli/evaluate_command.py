"""CLI command ``workbench evaluate``: dataset protocols and the label-efficiency simulation."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Literal

import tyro

from sessions import WorkbenchError, check_new_target
from training import FeatureMode

from ..retrain import RETRAIN
from .model_commands import check_device, refuse_family_device

STAGE2_EPOCHS = 150  # the protocols' stage 2 (the paper family) when --stage2-epochs is not given

Pos = tyro.conf.Positional


def evaluate(
    dataset: Pos[Literal["borealtc", "qcat", "demo", "session", "loop"]],
    folder: Pos[Path],
    labelled: float = 0.1,
    model: Literal["default", "paper", "both"] = "default",
    split: Literal["partitions", "runs", "both"] = "both",
    variant: Literal["both", "shared", "strict"] = "shared",
    hidden: int = 200,
    seed: int = 0,
    stage1_epochs: int = 40,
    stage2_epochs: int | None = None,
    folds: int = 5,
    out: Path | None = None,
    simulate: bool = False,
    strategies: tuple[str, ...] = ("random", "combined"),
    seeds: int = 3,
    rounds: int | None = None,
    batch: int = 4,
    per_round: int = 12,
    person: Literal["piece", "stretch"] = "piece",
    feature_mode: FeatureMode = "hidden+surprise",
    warm_start: bool = False,
    segment_s: float | None = None,
    members: int = 3,
    stage1: Literal["own", "lstm"] = "own",
    device: Literal["cpu", "cuda"] = "cpu",
    reference: Path | None = None,
    far: tuple[Path, ...] = (),
    verify: int = 0,
) -> None:
    """Evaluate the method on a dataset with its published protocol and print the table beside published figures.

    With ``--simulate``, compare suggestion strategies instead: an oracle labels each suggestion from the truth,
    stage 2 retrains after every batch, and held-out accuracy is printed against labelled time (table + PNG plot).

    Args:
        dataset: Which protocol. borealtc: 5 s partitions, stratified 5-fold CV, 1.7 s windows at 0.1 s stride.
            qcat: the paper's 90 % / 5 % / 5 % split of step sequences, and one holding out whole trials.
            demo: leave-logs-out on demo logs against their truth, for each stage-1 feature mode.
            session: your own session, leave-logs-out: stage 2 retrained per fold on the other logs' labels and
            scored against reference labels (--reference FILE, kept apart from the labels).
            loop: your own session as a person works it, on a copy: each round labels the suggestions from the
            reference and fits as the Retrain ends; accuracy on the logs that had no label at the start, per
            strategy (--strategies, default combined and random), --rounds (4) of --per-round (12).
        folder: The dataset folder (e.g. ../shared/data/borealtc, a QCAT folder, demo logs), or the session.
        labelled: Fraction labelled: of the training partitions (borealtc), of the training logs' time (demo).
        model: The model family ("default": spectral window classifier with self-training; "paper": the paper's
            two LSTMs); borealtc also takes both.
        split: borealtc: the authors' partition folds, folds holding out whole runs, or both (with --simulate:
            runs holds out whole runs, otherwise the partition folds).
        variant: borealtc, paper family: "shared": stage 1 trains once on all partitions' signals (no labels);
            "strict": stage 1 never sees the test partitions; "both".
        hidden: LSTM width of both stages.
        seed: Seed of folds, labelled subset and training.
        stage1_epochs: Most epochs of stage 1 (early stopping on validation loss).
        stage2_epochs: Most epochs of stage 2 (the paper family's LSTM); unset: 150, and for a session the
            Retrain's (100, early stopping on its validation loss).
        folds: Outer folds of the qcat and demo protocols (borealtc keeps the authors' 5).
        out: Also write per-fold details as JSON here (with --simulate: the folder for the plot).
        simulate: Run the label-efficiency simulation (borealtc and demo).
        strategies: Strategies to compare: random, entropy, margin, disagreement, surprise, combined (loop: in this
            order; default combined then random).
        seeds: Seeds per strategy (BorealTC: seed s uses outer fold s + 1).
        rounds: Rounds of labelling, each followed by a retrain (default: 8 with --simulate, 4 for loop).
        per_round: loop: suggestions labelled per round.
        person: loop: how the simulated person labels a suggestion: the suggested piece, or also the model's stretch
            around it where the reference agrees (as a range or Y does).
        batch: Suggestions labelled per round.
        feature_mode: With --simulate, paper family: what stage 1 hands stage 2.
        warm_start: With --simulate, paper family: each round fine-tunes the previous round's models instead of
            training afresh.
        segment_s: With --simulate: length of one suggestion in seconds (default: the UI's 1 s on demo logs, a whole
            5 s partition on borealtc, which then labels 5 / segment_s equal pieces of a partition).
        members: With --simulate: stage-2 ensemble members per retrain (the UI's Retrain trains 5).
        stage1: With --simulate, default family: the stage 1 drawing the surprise and the suggestions' embeddings,
            its own next-frame predictor or the paper's LSTM (as sessions trained before it), to compare the two.
        device: Where both stages train and run: "cuda" for either family's protocol and the paper family's
            simulation (the default family's simulation and the loop and session protocols, which fit as the
            Retrain does on the CPU, refuse it in one line).
        reference: With session or loop: a label file (the columns of `workbench labels export`) stored as the
            reference labels of the logs it names before scoring (loop: in its copy of the session only).
        far: loop: log files of runs kept out of the session, their truth in --reference: after every round the
            bundle the session would export scores them as `workbench classify` does (what ships to the robot).
        verify: loop: before the first round and after each, this many verification checks (uniform pieces of the
            new logs' time nobody labelled, by log, never labelled, counted apart from the rounds'): the session's
            accuracy with its 90 % interval as the page shows it, and whether it covers the truth.
    """
    if out is not None:  # before anything loads (torch takes seconds): a refused target is told at once
        _check_out(out, dataset=dataset, simulate=simulate)
    if not strategies:
        raise WorkbenchError("--strategies: name at least one (random, combined, entropy, margin, ...)")
    if rounds is not None and rounds < 1:
        raise WorkbenchError(f"--rounds {rounds}: at least one round of labelling")
    if far and dataset != "loop":
        raise WorkbenchError(f"--far: evaluate {dataset} has no far runs; --far is for evaluate loop")
    if verify and dataset != "loop":
        raise WorkbenchError(f"--verify: evaluate {dataset} checks nothing; --verify is for evaluate loop")
    if verify < 0:
        raise WorkbenchError(f"--verify {verify}: a number of checks, 0 or more")
    from ..evaluation import protocols as ev

    check_device(device)
    if device == "cpu":
        from training import hide_gpus

        hide_gpus()  # a CUDA torch's autograd would otherwise forbid the fits' forked processes their backward pass
    if dataset in ("loop", "session") and device != "cpu":  # both fit as the session's Retrain does: on the CPU
        raise WorkbenchError(
            f"--device {device}: evaluate {dataset} fits as the Retrain does, on the CPU; leave --device out"
        )
    if simulate or dataset == "borealtc":
        refuse_family_device(("default", "paper") if model == "both" else (model,), device)
    if simulate and model in ("default", "both") and device != "cpu":  # its rounds fit and score as a Retrain does
        raise WorkbenchError(
            f"--device {device}: evaluate --simulate runs the default family's rounds on the CPU, as the Retrain "
            "does; leave --device out (or --model paper)"
        )
    if dataset == "loop":
        from sessions import Session

        from ..evaluation import LoopSettings, evaluate_loop

        order = strategies if strategies != ("random", "combined") else ("combined", "random")
        settings = LoopSettings(
            rounds=4 if rounds is None else rounds,
            per_round=per_round,
            person=person,
            strategies=order,
            seed=seed,
            verify=verify,
        )
        with Session.open(folder) as s:
            print(evaluate_loop(s, reference=reference, settings=settings, out=out, far=far))
        return
    rounds = 8 if rounds is None else rounds
    if dataset == "session":
        from sessions import Session

        from ..evaluation import evaluate_session

        with Session.open(folder) as s:
            config = None if stage2_epochs is None else replace(RETRAIN.classifier, max_epochs=stage2_epochs)
            print(evaluate_session(s, reference=reference, folds=folds, config=config, seed=seed))
        return
    if simulate:
        print(
            ev.simulate(
                dataset,
                folder,
                strategies=strategies,
                seeds=seeds,
                rounds=rounds,
                batch=batch,
                out=out,
                model=model,
                feature_mode=feature_mode,
                warm_start=warm_start,
                segment_s=segment_s,
                members=members,
                stage1=stage1,
                device=device,
                split=split,
            )
        )
        return

    if dataset == "borealtc":
        report = ev.evaluate_borealtc(
            folder,
            model=model,
            labelled=labelled,
            split=split,
            variant=variant,
            hidden=hidden,
            seed=seed,
            stage1_epochs=stage1_epochs,
            stage2_epochs=stage2_epochs or STAGE2_EPOCHS,
            out=out,
            device=device,
        )
    elif dataset == "qcat":
        report = ev.evaluate_qcat(
            folder,
            hidden=hidden,
            seed=seed,
            folds=folds,
            epochs=(stage1_epochs, stage2_epochs or STAGE2_EPOCHS),
            device=device,
        )
    else:
        report = ev.evaluate_demo(
            folder,
            labelled=labelled,
            hidden=hidden,
            seed=seed,
            folds=folds,
            epochs=(stage1_epochs, stage2_epochs or STAGE2_EPOCHS),
            device=device,
        )
    print(report)


def _check_out(out: Path, *, dataset: str, simulate: bool) -> None:
    """Refuse ``--out`` before any work: a new JSON file, or with ``--simulate`` a folder (new, or one of the
    person's) that does not hold the plot already.

    Raises:
        WorkbenchError: The protocol writes nothing there, or the target could not be written new.
    """
    if simulate:
        if os.path.lexists(out) and (out.is_symlink() or not out.is_dir()):
            raise WorkbenchError(f"{out}: --out with --simulate is a folder for the plot, and this is not one")
        if out.is_dir():
            check_new_target(out / f"simulate-{dataset}.png")
        else:
            check_new_target(out, what="folder")
    elif dataset in ("borealtc", "loop"):
        check_new_target(out)
    else:
        raise WorkbenchError(f"--out: evaluate {dataset} writes no file; --out is for borealtc, loop and --simulate")
