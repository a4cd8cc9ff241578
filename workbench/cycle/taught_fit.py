"""The model that ships: stage 2 taught by what the session knows, fitted once labelling is done.

Inside a session a run's terrain is known from more than the model (its labels vote over the frames that resemble
them, and the page shows that blend); the bundle the robot gets carried none of it. On a legged robot the session
was 99 % right on its runs and its bundle 62 % on the robot's next runs, 74 % when one fit from scratch was taught
by the session's blend after the last round (`evaluate loop --strategies combined-teacher-last`).
Teaching every round's fit fed each round's errors back into the next round's suggestions (the demo walks' far runs
92.4 -> 76.4 %), so the taught fit is never the session's active version: the session keeps scoring and suggesting
with its own model, and the taught version is kept beside it, keyed by that version and the labels, for the export
(the bundle, the page's download, what ``classify`` reads) to ship.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable

from sessions import ModelVersion, Session, WorkbenchError
from training import CancelFn, ProgressFn, family, never, recorded_family

from .scores import compute_scores
from .stage2_fit import train_classifier


def labels_key(session: Session) -> str:
    """A digest of what a taught fit learns from: every label segment, the logs and the terrains' names."""
    rows = sorted((g.log_id, g.start, g.stop, g.terrain) for g in session.segments())
    logs = sorted(x.id for x in session.logs())
    terrains = sorted(t.name for t in session.terrains())
    return hashlib.sha256(json.dumps([rows, logs, terrains]).encode()).hexdigest()[:16]


def teachable(session: Session) -> str | None:
    """Why the active classifier cannot be taught (``None``: it can): no classifier, a family that does not learn
    from unlabelled stretches (the paper's LSTM), or a version taught already."""
    active = session.active_model("classifier")
    if active is None:
        return "no classifier yet"
    if active.config.get("taught"):
        return None
    fam = family(recorded_family(active.config))
    if fam.stage2_inputs == "stage1" or not fam.self_training:
        return f"the {fam.name} family learns from labels alone"
    predictor = session.active_model("predictor")
    if predictor is None or active.config.get("predictor") != predictor.id:
        return "the classifier was trained on another stage 1 than the active one; Retrain first"
    return None


# Taught fits in a row: each after the first taught by the session's scores made with the one before (its votes
# blended in again). One: the measured default (benchmarks/results/loop.md, stand-in D)
TEACH_PASSES = 1


def kept_taught(session: Session, *, passes: int = TEACH_PASSES) -> ModelVersion | None:
    """The taught version made from the active classifier and today's labels in ``passes`` taught fits, if one is
    kept; the active version itself when it was taught."""
    active = session.active_model("classifier")
    if active is None:
        return None
    if active.config.get("taught"):
        return active
    key = labels_key(session)
    return next(
        (
            v
            for v in reversed(session.model_versions("classifier"))
            if v.config.get("taught_from") == active.id
            and v.config.get("labels_key") == key
            and v.config.get("teach_passes", 1) == passes
        ),
        None,
    )


def shipped_version(
    session: Session,
    *,
    taught: bool = True,
    passes: int = TEACH_PASSES,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
    say: Callable[[str], None] | None = None,
) -> tuple[ModelVersion, str]:
    """The classifier version the export ships, and one line saying which it is.

    With ``taught`` (the default), the active version taught by the session: the kept one when the active version
    and the labels are as they were, else stage 2 fitted from scratch on every label with the terrain the session's
    scores are sure of over each unlabelled stretch (``labeling.taught_terrains``) as that stretch's pseudo-label,
    saved as a version beside the active one (never made active); with ``passes`` above one, each fit after the
    first taught by the session's scores made with the one before. A family that learns from labels alone ships its
    active version, and the line says why. ``say`` is told before a fit starts (it takes as long as a Retrain's).

    Raises:
        WorkbenchError: The session has no classifier.
    """
    active = session.active_model("classifier")
    if active is None:
        raise WorkbenchError(f"{session.path}: no classifier yet; label some segments and run `workbench train`")
    if not taught:
        return active, f"v{active.id}, the session's active version (not taught: --untaught)"
    why = teachable(session)
    if why is not None:
        return active, f"v{active.id}, the session's active version (not taught: {why})"
    kept = kept_taught(session, passes=passes)
    if kept is not None:
        said = "taught itself" if kept.id == active.id else f"taught by the session from v{active.id}"
        return kept, f"v{kept.id}, {said}"
    if say is not None:
        say("the model that ships: fitting stage 2 taught by the session (once; kept until the labels change)")
    key, version = labels_key(session), active
    for k in range(1, passes + 1):
        kept = kept_taught(session, passes=k)
        if kept is not None:  # an earlier pass is kept: teach on from it
            version = kept
            continue
        scores = compute_scores(session, tracks=False, classifier=None if version.id == active.id else version)
        if not scores.scores or scores.classifier != version.id:
            return active, f"v{active.id}, the session's active version (not taught: the session has no scores of it)"
        version = train_classifier(
            session,
            model=recorded_family(active.config),
            warm_start=False,
            progress=progress,
            cancel=cancel,
            scores=scores,
            teach=True,
            activate=False,
            recipe={"taught_from": active.id, "labels_key": key, "teach_passes": k},
        )
    return version, f"v{version.id}, taught by the session from v{active.id}"
