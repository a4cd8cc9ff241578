"""``workbench evaluate loop``: the labelling cycle as a person runs it, on a copy of the session, judged on the logs
nobody had labelled.

Folds over labels placed beforehand say what a model learns from them; a person's day is another thing: today's runs
are ingested beside labelled ones, the person follows the suggestions, labels, presses R, and expects the model to
get *those runs* right. Here each strategy starts from the same copy of the session (its labels, its stage 1, a
classifier fitted from scratch on them), and every round takes the session's own suggestion queue
(``cycle.suggest_for_session``, what the Suggest tab lists), labels each suggestion from the reference as a person
would (``piece``: the suggested segment; ``stretch``: also the model's stretch around it for as long as the
reference agrees, as a range or ``Y`` does), and fits as the Retrain ends (stage 2 from scratch on every label,
``RETRAIN``). After each fit the logs that had no label at the start are scored against the reference, on their time
nobody labelled. The session itself is never changed.
"""

from __future__ import annotations

import contextlib
import json
import re
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np

import labeling
from sessions import IngestOptions, LogInfo, ModelVersion, Session, WorkbenchError, new_file, read_frame, write_frame
from training import load_bundle

from ..cycle import (
    SessionScores,
    active_bundle,
    answer_change,
    checks_summary,
    classifier_family,
    compute_scores,
    keep_answers,
    record_check,
    shipped_version,
    signal_change_points,
    suggest_for_session,
    train_classifier,
    train_stage1,
)
from ..retrain import RETRAIN
from ..scratch_folders import scratch_folder
from ..user_errors import USER_ERRORS
from .far_runs import FarRuns, far_runs_of, score_far
from .loop_arms import ABLATIONS, loop_arm
from .loop_report import loop_report
from .loop_said import said_of_logs
from .loop_verify import Verified, verify_session

Person = Literal["piece", "stretch"]


AUTHOR = "evaluate loop"
STRETCH_WINDOW_S, STRETCH_MIN_S = 1.0, 2.0  # the model's stretches as the page draws them (ui.state)


@dataclass(frozen=True)
class LoopSettings:
    """How the simulated person works.

    Attributes:
        rounds: Rounds of labelling, each followed by a fit.
        per_round: Suggestions labelled per round.
        person: ``piece`` labels the suggested segment; ``stretch`` also the model's stretch around it where the
            reference agrees.
        strategies: Suggestion strategies compared, each from the same start (``labeling.STRATEGIES``, and the
            ablations of ``ABLATIONS``: a lever left out).
        seed: Seed of the ``random`` strategy (each round draws anew).
        verify: Verification checks before the first round and after each (:mod:`.loop_verify`): uniform pieces of
            the new runs' time nobody labelled, checked and never labelled, counted apart from the rounds'; 0: none.
    """

    rounds: int = 4
    per_round: int = 12
    person: Person = "piece"
    strategies: tuple[str, ...] = ("combined", "random")
    seed: int = 0
    verify: int = 0


@dataclass(frozen=True)
class LoopRound:
    """One round's figures (round 0: before any suggestion).

    Attributes:
        round: 0 for the start, then 1 to ``rounds``.
        labelled_s: Seconds labelled by the loop so far, in every log.
        new_s: Of those, the seconds in the logs that had no label at the start.
        picks: Suggestions labelled this round.
        picks_new: Of those, in the new logs.
        picks_worst: Of those, in the new log the model scored worst before the round.
        worst: That log's name.
        accuracy: Accuracy on the new logs' time nobody labelled (every step counts the same).
        balanced: The mean of the reference terrains' recalls on that time.
        per_log: Accuracy per new log.
        estimate: The fitted model's own headline estimate (the card's), ``None`` when it has none.
        seconds: Seconds this round took (suggest, label, fit, score).
        checks: Right and counted checks in the new logs so far (``cycle.checks_summary``: each the model of its
            round, before the label trained it).
        spot: The same over spot checks only.
        majority: Always answering the most common labelled terrain on the same time: its name and accuracy.
        said: Per new log, what the workbench says of it (:func:`.loop_said.said_of_logs`).
        far: The shipped model on the far runs (runs kept out of the session, ``far_runs``): accuracy and balanced
            accuracy; ``None`` without far runs. The shipped model is what ``export`` would write at that round:
            the round's fit taught by the session (``cycle.shipped_version``), or as it is in an arm that ships it
            untaught.
        far_per_log: Its accuracy per far run.
        verified: With ``LoopSettings.verify``: the session's accuracy from that many uniform checks of the round's
            model and its confidence, with a 90 % interval and the truth (``None``: not asked).
        unseen: The shipped model's figure for a run it never saw (its folds over runs, judged on what the session
            knows of them: ``metrics["unseen_runs"]``): accuracy and the 90 % interval's bounds (``None`` each
            where it has none); without far runs, the round's fit's.
        changed: The share of the new logs' unlabelled time whose answer changed this round (``answer_change``).
    """

    round: int
    labelled_s: float
    new_s: float
    picks: int
    picks_new: int
    picks_worst: int
    worst: str | None
    accuracy: float
    balanced: float
    per_log: dict[str, float] = field(default_factory=dict)
    estimate: float | None = None
    seconds: float = 0.0
    checks: tuple[int, int] = (0, 0)
    spot: tuple[int, int] = (0, 0)
    majority: tuple[str, float] = ("", float("nan"))
    said: dict[str, dict] = field(default_factory=dict)
    far: tuple[float, float] | None = None
    far_per_log: dict[str, float] = field(default_factory=dict)
    unseen: tuple[float | None, float | None, float | None] = (None, None, None)
    verified: Verified | None = None
    changed: float | None = None


@dataclass(frozen=True)
class Measured:
    """The new logs scored against the reference, on their time nobody labelled."""

    accuracy: float
    balanced: float
    per_log: dict[str, float]
    majority: tuple[str, float]  # always answering the most common labelled terrain: its name and accuracy


def _truth(session: Session, logs: Sequence[LogInfo], classes: Sequence[str]) -> dict[int, np.ndarray]:
    """Per log, ``(T,)`` the reference's terrain index among ``classes`` per sample (``-1``: no reference)."""
    out = {}
    for x in logs:
        y = np.full(x.n_samples, -1, np.int64)
        for a, b, terrain in session.reference(x.id):
            if terrain in classes:
                y[a:b] = classes.index(terrain)
        out[x.id] = y
    return out


def _covered(session: Session, log: LogInfo) -> np.ndarray:
    """``(T,)`` true where the log is labelled."""
    mask = np.zeros(log.n_samples, bool)
    for s in session.segments(log.id):
        mask[s.start : s.stop] = True
    return mask


def measure(
    session: Session,
    scores: SessionScores,
    new: Sequence[LogInfo],
    truth: dict[int, np.ndarray],
    classes: Sequence[str],
) -> Measured:
    """The new logs' accuracy and balanced accuracy on their unlabelled time with reference, and per log.

    Args:
        session: The working copy (its labels say which time is labelled now).
        scores: Its scores with the fitted classifier.
        new: The logs that had no label at the start.
        truth: Per log id, ``(T,)`` reference index among ``classes``.
        classes: The session's terrains.
    """
    index = np.array([classes.index(c) for c in scores.classes])  # the model's class -> the session's
    true_all, pred_all, per_log = [], [], {}
    for x in new:
        probs = scores.scores[x.id].probs
        if probs is None:
            raise WorkbenchError(f"{session.path}: log {x.name} was not scored by a classifier")
        keep = (truth[x.id] >= 0) & ~_covered(session, x)
        t, p = truth[x.id][keep], index[probs.argmax(axis=1)][keep]
        if len(t):
            per_log[x.name] = float((t == p).mean())
            true_all.append(t)
            pred_all.append(p)
    t = np.concatenate(true_all) if true_all else np.zeros(0, np.int64)
    p = np.concatenate(pred_all) if pred_all else np.zeros(0, np.int64)
    recalls = [float((p[t == c] == c).mean()) for c in np.unique(t)]
    counts = np.zeros(len(classes))
    for s in session.segments():
        counts[classes.index(s.terrain)] += s.length
    common = int(counts.argmax())
    return Measured(
        float((t == p).mean()) if len(t) else float("nan"),
        float(np.mean(recalls)) if recalls else float("nan"),
        per_log,
        (classes[common], float((t == common).mean()) if len(t) else float("nan")),
    )


def person_labels(
    picks: Sequence[tuple[LogInfo, labeling.Suggestion]],
    scores: SessionScores,
    truth: dict[int, np.ndarray],
    *,
    person: Person,
) -> list[tuple[LogInfo, int, int, int]]:
    """What the simulated person labels for each suggestion: ``(log, start, stop, class)`` from the reference."""
    out = []
    for log, s in picks:
        y = [truth[log.id]]
        if person == "stretch" and scores.scores[log.id].probs is not None:
            rate = log.rate_hz
            stretches = labeling.predicted_stretches(
                scores.scores[log.id].probs,
                window=max(1, round(STRETCH_WINDOW_S * rate)),
                min_len=max(1, round(STRETCH_MIN_S * rate)),
            )
            middle = (s.start + s.stop) // 2
            around = next(x for x in stretches if x.start <= middle < x.stop)
            given = labeling.stretch_oracle((0, s.start, s.stop), y, (around.start, around.stop))
        else:
            given = labeling.oracle((0, s.start, s.stop), y)
        out += [(log, a, b, c) for _, a, b, c in given]
    return out


def _label(session: Session, given: Sequence[tuple[LogInfo, int, int, int]], classes: Sequence[str]) -> int:
    """Add the person's labels, never over a label already there (as the page's range and ``Y`` do). Returns the
    samples labelled."""
    done = 0
    for log, a, b, c in given:
        taken = [(s.start, s.stop) for s in session.segments(log.id)]
        for x, y in labeling.uncovered(a, b, taken):
            session.add_segment(log.id, x, y, classes[c], author=AUTHOR, source="loop")
            done += y - x
    return done


def _check(
    session: Session,
    scores: SessionScores,
    picks: Sequence[tuple[LogInfo, labeling.Suggestion]],
    truth: dict[int, np.ndarray],
    classes: Sequence[str],
) -> None:
    """Each suggested piece, before its label is made, as a check of the model scored (as the page keeps one)."""
    for log, pick in picks:
        taken = [(g.start, g.stop) for g in session.segments(log.id)]
        for _, a, b, c in labeling.oracle((0, pick.start, pick.stop), [truth[log.id]]):
            for x, y in labeling.uncovered(a, b, taken):
                record_check(session, scores, log.id, x, y, classes[c], kind=pick.kind, author=AUTHOR)


def _fit(
    session: Session, *, scores: SessionScores | None = None, teach: bool = RETRAIN.teach, scoring: dict | None = None
) -> None:
    """Stage 2 as the Retrain ends: from scratch on every label, the session's family, its held-out runs judged on
    what ``scores`` (the round's, as the page showed them) knew of their unlabelled time; with ``teach``, taught by
    the session's scores made again with the round's labels (their votes included), as the screen measured it."""
    if teach:
        scores = compute_scores(session, **(scoring or {}))
    p = session.active_model("predictor")
    hidden = int(p.config.get("hidden", RETRAIN.hidden)) if p is not None else RETRAIN.hidden
    train_classifier(session, config=RETRAIN.classifier, warm_start=False, hidden=hidden, scores=scores, teach=teach)


def _estimate(session: Session) -> float | None:
    version = session.active_model("classifier")
    value = ((version.metrics if version is not None else {}).get("estimate") or {}).get("accuracy")
    return None if value is None or value != value else float(value)


def _unseen(version: ModelVersion | None) -> tuple[float | None, float | None, float | None]:
    """The figure ``version`` (the model that ships) states for a run it never saw: accuracy, low, high."""
    got = (version.metrics if version is not None else {}).get("unseen_runs") or {}
    return got.get("accuracy"), got.get("low"), got.get("high")


def run_arm(
    start: Path,
    folder: Path,
    strategy: str,
    new_ids: set[int],
    settings: LoopSettings,
    *,
    log: Callable[[str], None],
    far: FarRuns | None = None,
) -> list[LoopRound]:
    """One strategy's rounds on its own copy of ``start`` (made at ``folder``); with ``far``, the bundle the copy
    would export scored on those runs after every round."""
    with Session.open(start) as s0:
        s0.copy_to(folder)
    arm = loop_arm(strategy)
    scoring = {} if arm.votes else {"votes": False}
    with Session.open(folder) as s:
        classes = [t.name for t in s.terrains()]
        scores = compute_scores(s, **scoring)
        logs = [x for x in s.logs() if x.id in scores.scores]
        new = [x for x in logs if x.id in new_ids]
        rate = new[0].rate_hz
        truth = _truth(s, logs, classes)
        points = {x.id: signal_change_points(s, x) for x in logs}
        rounds: list[LoopRound] = []
        labelled, picks, picks_new, picks_worst, worst = 0, [], 0, 0, None
        t0 = time.monotonic()
        for r in range(settings.rounds + 1):
            if r > 0:
                scores = compute_scores(s, **scoring)
            keep_answers(s, scores)
            change = answer_change(s, scores, log_ids=new_ids) if r > 0 else None
            measured = measure(s, scores, new, truth, classes)
            ships = s.active_model("classifier")
            if far is not None:  # what `export` would write now
                ships = shipped_version(s, taught=arm.ships_taught, passes=arm.teach_passes)[0]
            shipped = None if far is None else score_far(load_bundle(s.path / ships.path), far)
            in_new = sum(g.length for g in s.segments() if g.log_id in new_ids and g.author == AUTHOR)
            checked = checks_summary(s, log_ids=new_ids)
            rounds.append(
                LoopRound(
                    r,
                    labelled / rate,
                    in_new / rate,
                    len(picks),
                    picks_new,
                    picks_worst,
                    worst,
                    measured.accuracy,
                    measured.balanced,
                    measured.per_log,
                    _estimate(s),
                    time.monotonic() - t0,
                    (checked.all.right, checked.all.n) if checked.all else (0, 0),
                    (checked.spot.right, checked.spot.n) if checked.spot else (0, 0),
                    measured.majority,
                    said_of_logs(s, scores, new, points, covered=_covered),
                    None if shipped is None else (shipped.accuracy, shipped.balanced),
                    {} if shipped is None else shipped.per_log,
                    _unseen(ships),
                    verify_session(
                        s, scores, new, truth, classes, _covered, k=settings.verify, seed=settings.seed * 1000 + 900 + r
                    )
                    if settings.verify
                    else None,
                    changed=None if change is None else change.changed,
                )
            )
            far_said = "" if shipped is None else f"; the shipped model on far runs {100 * shipped.accuracy:.1f} %"
            log(
                f"{strategy} round {r}: {labelled / rate:.0f} s labelled ({in_new / rate:.0f} s in new logs), "
                f"accuracy {100 * measured.accuracy:.1f} %, balanced {100 * measured.balanced:.1f} %{far_said}"
            )
            if r == settings.rounds:
                break
            t0 = time.monotonic()
            worst = min(measured.per_log, key=measured.per_log.__getitem__) if measured.per_log else None
            policy = replace(arm.policy, seed=settings.seed * 1000 + r)
            picks = suggest_for_session(s, scores, points, logs=logs, n=settings.per_round, policy=policy)
            if not picks:
                raise WorkbenchError(f"{s.path}: round {r + 1} of {strategy} found nothing left to suggest")
            picks_new = sum(x.id in new_ids for x, _ in picks)
            picks_worst = sum(x.name == worst for x, _ in picks)
            _check(s, scores, picks, truth, classes)
            labelled += _label(s, person_labels(picks, scores, truth, person=settings.person), classes)
            _fit(s, scores=scores, scoring=scoring, teach=arm.teach or (arm.teach_last and r + 1 == settings.rounds))
    return rounds


def evaluate_loop(
    session: Session,
    *,
    reference: Path | None = None,
    settings: LoopSettings = LoopSettings(),
    out: Path | None = None,
    workdir: Path | None = None,
    log: Callable[[str], None] = print,
    far: Sequence[Path] = (),
    far_options: IngestOptions | None = None,
) -> str:
    """Run the loop for each strategy from the same start; returns a Markdown report.

    Args:
        session: The session, with labels of at least two terrains on some logs, none on others, and reference
            labels for those others (or ``reference``). It is never changed.
        reference: A label file stored as the reference of the logs it names, in the copy only.
        settings: Rounds, suggestions per round, the person, the strategies.
        out: Also write every round's figures as JSON here.
        workdir: Where the copies are made (default: the system's temporary folder).
        log: Where progress lines go.
        far: Log files of runs kept out of the session (their truth in ``reference``): after every round the bundle
            the session would export scores them as ``classify`` does, the figure of what ships to the robot.
        far_options: How the far runs' files are read (a mapping, a rate, gaps allowed), as the session's logs were
            ingested; default: ``ingest``'s defaults.

    Raises:
        WorkbenchError: No log without labels has reference labels, or the labels cover fewer than two terrains.
    """
    known = (*labeling.STRATEGIES, *ABLATIONS)
    unknown = [x for x in settings.strategies if x not in known]
    if unknown:
        raise WorkbenchError(f"unknown strategy {unknown[0]!r}; choose among {', '.join(known)}")
    if settings.rounds < 1 or settings.per_round < 1:
        raise WorkbenchError("--rounds and --per-round must be at least 1")
    t0 = time.monotonic()
    with scratch_folder("workbench-loop-", folder=workdir) as tmp, _named_as(session.path, tmp):
        start = session.copy_to(Path(tmp) / "start")
        with Session.open(start) as s:
            if reference is not None:
                n = s.import_reference(_session_rows(reference, s, Path(tmp)) if far else reference)
                log(f"reference: {n} row(s) from {reference}, in a copy of the session")
            labelled_logs = {g.log_id for g in s.segments()}
            new = [x for x in s.logs() if x.id not in labelled_logs and s.reference(x.id)]
            if not new:
                raise WorkbenchError(
                    f"{session.path}: no log without labels has reference labels; the loop is judged on logs nobody "
                    "labelled (give their truth with --reference FILE)"
                )
            if s.active_model("predictor") is None:
                log("stage 1: training it first (the session has none)")
                train_stage1(s)
            log(f"start: stage 2 from scratch on the session's {len(s.segments())} label segment(s)")
            _fit(s)
            family = classifier_family(s)
            total_new = sum(x.duration_s for x in new)
            far_runs = None
            if far:
                if reference is None:
                    raise WorkbenchError("--far: the far runs' truth comes from --reference FILE; give it")
                far_runs = far_runs_of(s, far, reference, active_bundle(s)[1], options=far_options)
                log(f"far runs: {len(far_runs.names)} kept out of the session ({', '.join(far_runs.names)})")
        arms = {
            strategy: run_arm(
                start, Path(tmp) / strategy, strategy, {x.id for x in new}, settings, log=log, far=far_runs
            )
            for strategy in settings.strategies
        }
    took = time.monotonic() - t0
    if out is not None:
        data = {
            "settings": asdict(settings),
            "family": family,
            "arms": {k: [asdict(r) for r in v] for k, v in arms.items()},
        }
        with new_file(out) as tmp:
            tmp.write_text(json.dumps(data, indent=1))
    first = next(iter(arms.values()))[0]
    names = [x.name for x in new]
    return loop_report(
        session.path.name,
        arms,
        settings,
        family=family,
        new=names,
        new_s=total_new,
        seconds=took,
        majority=first.majority,
    )


def _session_rows(reference: Path, session: Session, folder: Path) -> Path:
    """The rows of ``reference`` that name the session's logs, as a label file in ``folder``: the far runs' rows
    are their truth, never the session's."""
    frame = read_frame(reference)
    if "log" not in frame.columns:
        raise WorkbenchError(f"{reference}: a reference file needs the column log")
    mine = frame[frame["log"].astype(str).isin({x.name for x in session.logs()})]
    return write_frame(mine, folder / "session-reference.csv")


@contextlib.contextmanager
def _named_as(path: Path, copies: Path) -> Iterator[None]:
    """A person's error raised inside the loop's copies of a session names the session, not a copy in the temporary
    folder the person never made."""
    try:
        yield
    except USER_ERRORS as exc:
        copy = re.compile(re.escape(str(copies)) + r"/[^/\s:;,]+")
        raise WorkbenchError(copy.sub(str(path).replace("\\", "\\\\"), str(exc))) from None
