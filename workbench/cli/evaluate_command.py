"""CLI command ``workbench evaluate PROTOCOL``: one subcommand per protocol, each with only its own options
(``borealtc`` and ``demo`` also run the label-efficiency simulation with ``--simulate``)."""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable
from dataclasses import dataclass, fields, is_dataclass, replace
from pathlib import Path
from typing import Literal

import tyro

from sessions import MAX_RATE_HZ, WorkbenchError, check_new_target
from training import FeatureMode

from ..retrain import RETRAIN
from .model_commands import check_device, refuse_family_device

STAGE2_EPOCHS = 150  # the protocols' stage 2 (the paper family) when --stage2-epochs is not given

Pos = tyro.conf.Positional


Split = Literal["partitions", "runs", "both"]
Strategies = tuple[str, ...]


@dataclass(frozen=True)
class Simulation:
    """The label-efficiency simulation, as ``evaluate borealtc`` and ``evaluate demo`` run it: an oracle labels each
    suggestion from the truth, stage 2 retrains after every round, and held-out accuracy is printed against labelled
    time (table + PNG plot)."""

    simulate: bool = False
    """Run the simulation instead of the protocol."""
    strategies: Strategies = ("random", "combined")
    """Strategies compared: random, entropy, margin, disagreement, surprise, combined."""
    seeds: int = 3
    """Seeds per strategy (BorealTC: seed s uses outer fold s + 1)."""
    rounds: int = 8
    """Rounds of labelling, each followed by a retrain."""
    per_round: int = 4
    """Suggestions labelled per round."""
    feature_mode: FeatureMode = "hidden+surprise"
    """Paper family: what stage 1 hands stage 2."""
    warm_start: bool = False
    """Paper family: each round fine-tunes the previous round's models instead of training afresh."""
    segment_s: float | None = None
    """Length of one suggestion in seconds (default: the UI's 1 s on demo logs, a whole 5 s partition on BorealTC,
    which then labels 5 / segment_s equal pieces of a partition)."""
    members: int = 3
    """Stage-2 ensemble members per retrain (the UI's Retrain trains 5)."""
    stage1: Literal["own", "lstm"] = "own"
    """Default family: the stage 1 drawing the surprise and the embeddings, its own next-frame predictor or the
    paper's LSTM (as sessions trained before it), to compare the two."""


def borealtc(
    folder: Pos[Path],
    *,
    labelled: float = 0.1,
    model: Literal["default", "paper", "both"] = "default",
    split: Split = "both",
    variant: Literal["both", "shared", "strict"] = "shared",
    hidden: int = 200,
    seed: int = 0,
    stage1_epochs: int = 40,
    stage2_epochs: int | None = None,
    out: Path | None = None,
    device: Literal["cpu", "cuda"] = "cpu",
    simulation: tyro.conf.OmitArgPrefixes[Simulation] = Simulation(),
) -> None:
    """BorealTC's protocol (5 s partitions, stratified 5-fold CV, 1.7 s windows at 0.1 s stride), the table beside
    the published figures; with --simulate, the label-efficiency simulation instead.

    Args:
        folder: The dataset folder (../shared/data/borealtc).
        labelled: Fraction of the training partitions labelled.
        model: The model family ("default": spectral window classifier with self-training; "paper": the paper's two
            LSTMs; "both").
        split: The authors' partition folds, folds holding out whole runs, or both (with --simulate: runs holds out
            whole runs, otherwise the partition folds).
        variant: Paper family: "shared": stage 1 trains once on all partitions' signals (no labels); "strict": stage
            1 never sees the test partitions; "both".
        hidden: LSTM width of both stages (paper family).
        seed: Seed of folds, labelled subset and training.
        stage1_epochs: Most epochs of stage 1 (paper family; early stopping on validation loss).
        stage2_epochs: Most epochs of stage 2 (paper family; unset: 150).
        out: Also write per-fold details as JSON here (with --simulate: the folder for the plot).
        device: Where both stages train and run ("cuda" refused by a family without a CUDA path, in one line).
        simulation: The label-efficiency simulation (--simulate) and its options.
    """
    _before_work(out, protocol="borealtc", simulate=simulation.simulate, device=device)
    from ..evaluation import protocols as ev

    families = ("default", "paper") if model == "both" else (model,)
    refuse_family_device(families, device)
    if simulation.simulate:
        print(_simulate("borealtc", folder, simulation, out=out, model=model, device=device, split=split))
        return
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
    print(report)


def qcat(
    folder: Pos[Path],
    *,
    hidden: int = 200,
    seed: int = 0,
    folds: int = 5,
    stage1_epochs: int = 40,
    stage2_epochs: int | None = None,
    device: Literal["cpu", "cuda"] = "cpu",
) -> None:
    """QCAT's protocol (the paper family): the paper's 90 % / 5 % / 5 % split of step sequences, and one holding out
    whole trials.

    Args:
        folder: A QCAT folder.
        hidden: LSTM width of both stages.
        seed: Seed of the split and training.
        folds: Outer folds of the split holding out trials.
        stage1_epochs: Most epochs of stage 1 (early stopping on validation loss).
        stage2_epochs: Most epochs of stage 2 (unset: 150).
        device: Where both stages train and run.
    """
    _before_work(None, protocol="qcat", simulate=False, device=device)
    from ..evaluation import protocols as ev

    epochs = (stage1_epochs, stage2_epochs or STAGE2_EPOCHS)
    print(ev.evaluate_qcat(folder, hidden=hidden, seed=seed, folds=folds, epochs=epochs, device=device))


def demo(
    folder: Pos[Path],
    *,
    labelled: float = 0.1,
    model: Literal["default", "paper"] = "default",
    hidden: int = 200,
    seed: int = 0,
    folds: int = 5,
    stage1_epochs: int = 40,
    stage2_epochs: int | None = None,
    out: Path | None = None,
    device: Literal["cpu", "cuda"] = "cpu",
    simulation: tyro.conf.OmitArgPrefixes[Simulation] = Simulation(),
) -> None:
    """Leave-logs-out on demo logs against their truth, for each stage-1 feature mode (the paper family); with
    --simulate, the label-efficiency simulation on them instead.

    Args:
        folder: A folder of demo logs (`workbench demo` writes one beside its session).
        labelled: Fraction of the training logs' time labelled.
        model: With --simulate: the model family.
        hidden: LSTM width of both stages.
        seed: Seed of folds, labelled subset and training.
        folds: Outer folds.
        stage1_epochs: Most epochs of stage 1.
        stage2_epochs: Most epochs of stage 2 (unset: 150).
        out: With --simulate: the folder for the plot.
        device: Where both stages train and run (the default family's simulation fits on the CPU, as the Retrain).
        simulation: The label-efficiency simulation (--simulate) and its options.
    """
    _before_work(out, protocol="demo", simulate=simulation.simulate, device=device)
    from ..evaluation import protocols as ev

    if simulation.simulate:
        refuse_family_device((model,), device)
        print(_simulate("demo", folder, simulation, out=out, model=model, device=device, split="partitions"))
        return
    epochs = (stage1_epochs, stage2_epochs or STAGE2_EPOCHS)
    print(
        ev.evaluate_demo(folder, labelled=labelled, hidden=hidden, seed=seed, folds=folds, epochs=epochs, device=device)
    )


def session(
    folder: Pos[Path],
    *,
    reference: Path | None = None,
    folds: int = 5,
    seed: int = 0,
    stage2_epochs: int | None = None,
) -> None:
    """Your own session, leave-logs-out: stage 2 retrained per fold on the other logs' labels, as the Retrain fits,
    and scored against reference labels kept apart from the labels.

    Args:
        folder: The session.
        reference: A label file (the columns of `workbench labels export`) stored as the reference labels of the logs
            it names before scoring; without it, the session's stored reference.
        folds: Folds over the logs.
        seed: Seed of the folds and the fits.
        stage2_epochs: Most epochs of stage 2 (unset: the Retrain's, with early stopping).
    """
    _before_work(None, protocol="session", simulate=False, device="cpu")
    from sessions import Session

    from ..evaluation import evaluate_session

    with Session.open(folder) as s:
        config = None if stage2_epochs is None else replace(RETRAIN.classifier, max_epochs=stage2_epochs)
        print(evaluate_session(s, reference=reference, folds=folds, config=config, seed=seed))


def loop(
    folder: Pos[Path],
    *,
    reference: Path | None = None,
    strategies: Strategies = ("combined", "random"),
    rounds: int = 4,
    per_round: int = 12,
    person: Literal["piece", "stretch"] = "piece",
    far: tuple[Path, ...] = (),
    mapping: Path | None = None,
    rate: float | None = None,
    allow_gaps: bool = False,
    verify: int = 0,
    seed: int = 0,
    out: Path | None = None,
) -> None:
    """Your own session as a person works it, on a copy: each round labels the suggestions from the reference and
    fits as the Retrain ends; accuracy on the logs that had no label at the start, per strategy.

    Args:
        folder: The session.
        reference: A label file stored as the reference labels of the logs it names (in the copy only).
        strategies: Strategies compared, each from the same start: random, entropy, margin, disagreement, surprise,
            combined, and the ablations (combined-no-unchecked, combined-no-votes, combined-no-wrong-first,
            combined-no-main-answer, combined-main-answer-new, combined-teacher, combined-teacher-last,
            combined-untaught: the far runs scored by each round's fit as it is, not taught as `export` ships it).
        rounds: Rounds of labelling, each followed by a fit.
        per_round: Suggestions labelled per round.
        person: How the simulated person labels a suggestion: the suggested piece, or also the model's stretch around
            it where the reference agrees (as a range or Y does).
        far: Log files of runs kept out of the session, their truth in --reference: after every round the bundle the
            session would export (taught by the session, as `export` writes it) scores them as `workbench classify`
            does: what ships to the robot.
        mapping: TOML or JSON file naming topics/columns to read in the --far files, as `workbench ingest` and
            `classify` take it (give the one the session's logs were ingested with).
        rate: Rate (Hz) the --far files are aligned at before the bundle resamples them, as for `ingest`.
        allow_gaps: Accept NaN/inf samples and dropouts in the --far files, as for `ingest`.
        verify: Before the first round and after each, this many verification checks (uniform pieces of the new
            logs' time nobody labelled, never labelled): the session's accuracy with its 90 % interval as the page
            shows it, and whether it covers the truth.
        seed: Seed of the random strategy and the clustering (each round draws anew).
        out: Also write the rounds as JSON here.
    """
    _before_work(out, protocol="loop", simulate=False, device="cpu")
    if not strategies:
        raise WorkbenchError("--strategies: name at least one (combined, random, entropy, margin, ...)")
    if rounds < 1:
        raise WorkbenchError(f"--rounds {rounds}: at least one round of labelling")
    if verify < 0:
        raise WorkbenchError(f"--verify {verify}: a number of checks, 0 or more")
    if (mapping is not None or rate is not None or allow_gaps) and not far:
        raise WorkbenchError("--mapping, --rate and --allow-gaps say how the --far files are read; give --far FILE...")
    if rate is not None and not 0 < rate <= MAX_RATE_HZ:
        raise WorkbenchError(f"--rate {rate:g}: a rate is above 0 and at most {MAX_RATE_HZ:g} Hz")
    from sessions import IngestOptions, Session, load_mapping

    from ..evaluation import LoopSettings, evaluate_loop

    settings = LoopSettings(
        rounds=rounds, per_round=per_round, person=person, strategies=strategies, seed=seed, verify=verify
    )
    options = IngestOptions(
        mapping=load_mapping(mapping) if mapping else IngestOptions().mapping, rate_hz=rate, allow_gaps=allow_gaps
    )
    with Session.open(folder) as s:
        print(evaluate_loop(s, reference=reference, settings=settings, out=out, far=far, far_options=options))


PROTOCOLS = {"borealtc": borealtc, "qcat": qcat, "demo": demo, "session": session, "loop": loop}
# spellings of the single `evaluate` command that mean something else now: one line naming the new one
RENAMED = {"--batch": "--per-round"}


def misplaced_option(protocol: str, args: list[str]) -> str | None:
    """One line for an option this protocol does not take: renamed (``RENAMED``), or another protocol's."""
    own = _flags(PROTOCOLS[protocol])
    for arg in args:
        flag = arg.split("=", 1)[0]
        if not flag.startswith("--") or flag in ("--help",) or flag in own or flag.replace("--no-", "--", 1) in own:
            continue
        if flag in RENAMED:
            return f"{flag}: now {RENAMED[flag]} (workbench evaluate {protocol} --help)"
        others = [p for p, f in PROTOCOLS.items() if flag in _flags(f)]
        if others:
            named = ", ".join(others[:-1]) + (" and " if len(others) > 1 else "") + others[-1]
            return f"{flag}: evaluate {protocol} takes no {flag} (evaluate {named} take{'s' * (len(others) == 1)} it)"
    return None


def _flags(command: Callable[..., None]) -> set[str]:
    """The options a protocol's function takes, a nested dataclass's fields as their own (``OmitArgPrefixes``)."""
    names = []
    for name, parameter in inspect.signature(command).parameters.items():
        nested = parameter.default if is_dataclass(parameter.default) else None
        names += [f.name for f in fields(nested)] if nested is not None else [name]
    return {"--" + name.replace("_", "-") for name in names}


def _simulate(
    dataset: str, folder: Path, sim: Simulation, *, out: Path | None, model: str, device: str, split: Split
) -> str:
    if not sim.strategies:
        raise WorkbenchError("--strategies: name at least one (random, combined, entropy, margin, ...)")
    if sim.rounds < 1:
        raise WorkbenchError(f"--rounds {sim.rounds}: at least one round of labelling")
    if model in ("default", "both") and device != "cpu":  # its rounds fit and score as a Retrain does
        raise WorkbenchError(
            f"--device {device}: evaluate --simulate runs the default family's rounds on the CPU, as the Retrain "
            "does; leave --device out (or --model paper)"
        )
    from ..evaluation import protocols as ev

    return ev.simulate(
        dataset,
        folder,
        strategies=sim.strategies,
        seeds=sim.seeds,
        rounds=sim.rounds,
        batch=sim.per_round,
        out=out,
        model=model,
        feature_mode=sim.feature_mode,
        warm_start=sim.warm_start,
        segment_s=sim.segment_s,
        members=sim.members,
        stage1=sim.stage1,
        device=device,
        split=split,
    )


def _before_work(out: Path | None, *, protocol: str, simulate: bool, device: str) -> None:
    """What is refused before anything loads (torch takes seconds): the output target, and a device the protocol
    cannot use; then the GPUs hidden from a CPU run."""
    if out is not None:
        _check_out(out, dataset=protocol, simulate=simulate)
    check_device(device)
    if device == "cpu":
        from training import hide_gpus

        hide_gpus()  # a CUDA torch's autograd would otherwise forbid the fits' forked processes their backward pass


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
